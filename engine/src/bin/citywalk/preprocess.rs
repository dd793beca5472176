//! `citywalk preprocess` (placeholder until it lands in this session).

/// Arguments of `citywalk preprocess`.
#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`citywalk preprocess` is not built yet")
}
