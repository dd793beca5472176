//! The options of raw inputs that do not say how to read them (OBJ names neither CRS nor up
//! axis nor building class), shared by every command that loads raw inputs and turned into
//! [`LoadOptions`] here only. An option no input reads is refused rather than ignored, so a
//! misplaced `--up y` is never silently without effect.

use std::path::PathBuf;

use anyhow::Context;
use citywalk_scenes::LoadOptions;
use citywalk_scenes::load::{InputFormat, UpAxis, detect_format, parse_crs};

use crate::scene_input::is_package;

/// Reading options for OBJ inputs.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct InputArgs {
    /// OBJ inputs: their projected CRS, EPSG:NNNN (OBJ names none; default: a local frame in
    /// metres). Geographic CRSs (degrees) are refused.
    #[arg(long, value_name = "EPSG:NNNN", value_parser = parse_crs)]
    crs: Option<String>,
    /// OBJ inputs: the axis that points up, z (3dfier, default) or y (glTF, Blender: north is
    /// -z).
    #[arg(long, value_name = "z|y", value_parser = UpAxis::parse)]
    up: Option<UpAxis>,
    /// OBJ inputs: an object is a building when its name, a group or a material contains NAME
    /// (any case); repeatable or comma-separated; replaces the default `building`.
    #[arg(
        long = "obj-building-marker",
        value_name = "NAME",
        value_delimiter = ','
    )]
    obj_building_markers: Vec<String>,
}

impl InputArgs {
    /// The options given, by their flag names.
    fn given(&self) -> Vec<&'static str> {
        [
            (self.crs.is_some(), "--crs"),
            (self.up.is_some(), "--up"),
            (
                !self.obj_building_markers.is_empty(),
                "--obj-building-marker",
            ),
        ]
        .into_iter()
        .filter_map(|(given, flag)| given.then_some(flag))
        .collect()
    }

    /// The load options for `inputs`. Refused: an empty marker, and any of these options when
    /// no input is a raw OBJ file (a scene package was loaded when it was made; the other
    /// formats name their CRS and up axis, and mark their buildings, themselves).
    pub fn load_options(&self, inputs: &[PathBuf]) -> anyhow::Result<LoadOptions> {
        let mut options = LoadOptions::default();
        let given = self.given();
        if given.is_empty() {
            return Ok(options);
        }
        if let Some(empty) = self
            .obj_building_markers
            .iter()
            .find(|m| m.trim().is_empty())
        {
            anyhow::bail!("--obj-building-marker: empty marker {empty:?} would match every object");
        }
        let mut kinds = Vec::new();
        let mut any_obj = false;
        for path in inputs {
            let kind = if is_package(path)? {
                "a scene package, loaded when it was made".to_string()
            } else {
                let format = detect_format(path)
                    .with_context(|| format!("cannot load {}", path.display()))?;
                any_obj |= format == InputFormat::Obj;
                format!("{format:?}")
            };
            kinds.push(format!("{} ({kind})", path.display()));
        }
        if !any_obj {
            anyhow::bail!(
                "{} appl{} to OBJ inputs only, and no input is OBJ: {}",
                given.join(", "),
                if given.len() == 1 { "ies" } else { "y" },
                kinds.join(", ")
            );
        }
        if let Some(crs) = &self.crs {
            options.source_crs = Some(crs.clone());
        }
        if let Some(up) = self.up {
            options.up_axis = up;
        }
        if !self.obj_building_markers.is_empty() {
            options.obj_building_markers = self
                .obj_building_markers
                .iter()
                .map(|m| m.trim().to_string())
                .collect();
        }
        Ok(options)
    }
}
