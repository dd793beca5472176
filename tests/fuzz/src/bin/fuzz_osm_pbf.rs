//! AFL target `osm_pbf` (see the crate documentation and tests/fuzz/README.md).

fn main() {
    // No panic hook: a loader may catch a panic of a dependency on purpose; only a panic
    // that escapes the target aborts the process and counts as a crash.
    afl::fuzz_nohook!(|data: &[u8]| citywalk_fuzz::loaders::osm_pbf(data));
}
