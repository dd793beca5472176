//! `citywalk inspect` (placeholder until it lands in this session).

/// Arguments of `citywalk inspect`.
#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`citywalk inspect` is not built yet")
}
