//! `citywalk generate` (placeholder until it lands in this session).

/// Arguments of `citywalk generate`.
#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`citywalk generate` is not built yet")
}
