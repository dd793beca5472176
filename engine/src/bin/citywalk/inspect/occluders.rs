//! `citywalk inspect` (occluders; placeholder until it lands in this session).

/// Arguments of this inspection.
#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`citywalk inspect` (occluders) is not built yet")
}
