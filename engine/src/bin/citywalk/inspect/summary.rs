//! `citywalk inspect` (summary; placeholder until it lands in this session).

/// Arguments of this inspection.
#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`citywalk inspect` (summary) is not built yet")
}
