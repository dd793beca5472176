//! `citywalk view` (placeholder until it lands in this session).

/// Arguments of `citywalk view`.
#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`citywalk view` is not built yet")
}
