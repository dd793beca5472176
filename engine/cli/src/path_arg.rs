//! `--path` / `--play` arguments: a camera path file, or the name of a default path generated
//! for the scene (`street`, `walk`, `flyover`, `dive`; [`citywalk_scenes::camera_path`]).

use std::path::Path;

use anyhow::Context;
use citywalk_scenes::City;
use citywalk_scenes::camera_path::{self, CameraPath};

/// The names of the generated paths.
pub const GENERATED: [&str; 4] = ["street", "walk", "flyover", "dive"];

/// What a path argument names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PathSource<'a> {
    /// One of [`GENERATED`] (write `./street` for a file of that name).
    Generated(&'a str),
    File(&'a Path),
}

impl PathSource<'_> {
    pub fn of(arg: &Path) -> PathSource<'_> {
        match arg.to_str() {
            Some(name) if GENERATED.contains(&name) => PathSource::Generated(name),
            _ => PathSource::File(arg),
        }
    }

    /// The path: read from its file, or generated for `city` with `frames` poses.
    pub fn load(&self, city: &City, frames: usize) -> anyhow::Result<CameraPath> {
        let path = match self {
            PathSource::Generated("street") => camera_path::street_walk(city, frames),
            PathSource::Generated("walk") => camera_path::walkthrough(city, frames),
            PathSource::Generated("flyover") => camera_path::flyover(city, frames),
            PathSource::Generated(_) => camera_path::dive(city, frames),
            PathSource::File(file) => CameraPath::read(file)
                .with_context(|| format!("cannot read the camera path {}", file.display()))?,
        };
        anyhow::ensure!(
            !path.poses.is_empty(),
            "the camera path {} has no pose",
            path.name
        );
        Ok(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_generate_and_anything_else_is_a_file() {
        assert_eq!(
            PathSource::of(Path::new("flyover")),
            PathSource::Generated("flyover")
        );
        assert_eq!(
            PathSource::of(Path::new("./street")),
            PathSource::File(Path::new("./street"))
        );
        assert_eq!(
            PathSource::of(Path::new("walk.path")),
            PathSource::File(Path::new("walk.path"))
        );
    }
}
