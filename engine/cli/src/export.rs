//! `citywalk export SCENE --format 3dtiles|glb -o OUT`: the scene handed on to the 3D Tiles
//! ecosystem (`citywalk_scenes::export`): a 3D Tiles 1.1 tileset whose tiles are the cluster
//! tree as HLOD, or one GLB of the city at full detail (or at one level of the tree).

use std::path::PathBuf;

use anyhow::Context;
use citywalk_scenes::export::{self, ExportOptions};

/// What `export` writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// A 3D Tiles 1.1 tileset: OUT is a folder (`tileset.json`, `tiles/N.glb`).
    #[value(name = "3dtiles")]
    Tiles,
    /// One GLB file of the whole city.
    Glb,
}

/// Arguments of `citywalk export`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene: a package (.cwk) or any input, preprocessed first with the default
    /// parameters.
    pub scene: PathBuf,
    #[command(flatten)]
    pub input: crate::input_args::InputArgs,
    #[arg(long, value_enum)]
    pub format: Format,
    /// Output: a folder for `3dtiles` (new, empty, or an earlier export, whose tiles are
    /// replaced), a file for `glb`.
    #[arg(short, long)]
    pub output: PathBuf,
    /// `glb` only: the cluster tree's cut at this depth (0 = the root's cluster mesh) instead
    /// of every building at full detail.
    #[arg(long)]
    pub level: Option<u32>,
    /// `3dtiles` only: triangles a tile holds at most, where the tree allows.
    #[arg(long, default_value_t = export::DEFAULT_TILE_TRIANGLES,
        value_parser = clap::value_parser!(u64).range(1..))]
    pub max_tile_triangles: u64,
    /// Longitude and latitude in degrees of the origin of a scene that has no geographic
    /// placement (a generated city, an OBJ without --crs).
    #[arg(long, value_name = "LON,LAT", value_parser = parse_place, allow_hyphen_values = true)]
    pub place: Option<(f64, f64)>,
    /// The data's attribution, written into every content (glTF `asset.copyright`) and the
    /// tileset; OpenStreetMap's is added for OSM inputs.
    #[arg(long)]
    pub attribution: Option<String>,
}

fn parse_place(s: &str) -> Result<(f64, f64), String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let [lon, lat] = parts[..] else {
        return Err(format!("expected LON,LAT in degrees, got {s:?}"));
    };
    let number = |v: &str| {
        v.parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("{v:?} is not a number"))
    };
    Ok((number(lon)?, number(lat)?))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.format == Format::Tiles && args.level.is_some() {
        anyhow::bail!("--level applies to --format glb only (a tileset holds every level)");
    }
    let load = args.input.load_options(std::slice::from_ref(&args.scene))?;
    let package = crate::scene_input::load_scene(&args.scene, &load)?;
    let options = ExportOptions {
        max_tile_triangles: args.max_tile_triangles,
        place: args.place,
        attribution: args.attribution,
    };
    let report = match args.format {
        Format::Tiles => export::write_3d_tiles(&package, &args.output, &options),
        Format::Glb => export::write_glb(&package, &args.output, args.level, &options),
    }
    .with_context(|| format!("cannot export {}", args.scene.display()))?;
    println!(
        "wrote {}: {} tiles, {} contents, {} triangles, {} buildings and {} cluster meshes, {:.1} MB",
        args.output.display(),
        report.tiles,
        report.contents,
        report.triangles,
        report.buildings_written,
        report.clusters_written,
        report.bytes as f64 / 1e6
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn place_parses_two_numbers() {
        assert_eq!(parse_place("-0.17, 51.49"), Ok((-0.17, 51.49)));
        assert!(parse_place("4.3").is_err());
        assert!(parse_place("4.3,north").is_err());
        assert!(parse_place("1,2,3").is_err());
    }
}
