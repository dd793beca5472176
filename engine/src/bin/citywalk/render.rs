//! `citywalk render` (placeholder until it lands in this session).

/// Arguments of `citywalk render`.
#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`citywalk render` is not built yet")
}
