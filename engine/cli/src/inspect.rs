//! `citywalk inspect`: summaries and invariant checks of scenes and packages.
//!
//! `citywalk inspect SCENE [--json] [--check]` summarises a package or input;
//! `citywalk inspect occluders SCENE` reports virtual-occluder quality;
//! `citywalk inspect tree SCENE --level K -o map.png [--gltf OUT.glb]` draws the cluster tree
//! at one level (a package's own tree) and can export that level's meshes;
//! `citywalk inspect textures PACKAGE -o DIR` writes a package's baked cluster textures.

use clap::Subcommand;

mod occluders;
mod summary;
mod textures;
mod tree;

/// Arguments of `citywalk inspect`.
#[derive(Debug, clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
#[group(skip)]
pub struct Args {
    #[command(subcommand)]
    what: Option<What>,
    #[command(flatten)]
    summary: summary::Args,
}

#[derive(Debug, Subcommand)]
enum What {
    /// Virtual occluders: polygon counts, area gain and occlusion-preserving quality.
    Occluders(occluders::Args),
    /// The legibility cluster tree: a top-down map of one level.
    Tree(tree::Args),
    /// The baked cluster textures of a package: one PNG per page and view, and a table of the bins.
    Textures(textures::Args),
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.what {
        Some(What::Occluders(a)) => occluders::run(a),
        Some(What::Tree(a)) => tree::run(a),
        Some(What::Textures(a)) => textures::run(a),
        None => summary::run(args.summary),
    }
}
