//! `citywalk`: the command line for everything.

fn main() {}
