//! `--path` / `--play` arguments: a camera path file, or the name of a default path generated
//! for the scene ([`GeneratedPath`]: `street`, `walk`, `flyover`, `dive`, `overview`).

use std::path::Path;

use anyhow::Context;
use citywalk_scenes::City;
use citywalk_scenes::camera_path::{CameraPath, GeneratedPath};

/// What a path argument names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum PathSource<'a> {
    /// One of [`GeneratedPath::ALL`] (write `./street` for a file of that name).
    Generated(GeneratedPath),
    File(&'a Path),
}

impl PathSource<'_> {
    pub fn of(arg: &Path) -> PathSource<'_> {
        match arg.to_str().and_then(GeneratedPath::named) {
            Some(generated) => PathSource::Generated(generated),
            None => PathSource::File(arg),
        }
    }

    /// The path: read from its file, or generated for `city` with `frames` poses.
    pub fn load(&self, city: &City, frames: usize) -> anyhow::Result<CameraPath> {
        let path = match self {
            PathSource::Generated(generated) => generated.generate(city, frames),
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
            PathSource::Generated(GeneratedPath::Flyover)
        );
        assert_eq!(
            PathSource::of(Path::new("overview")),
            PathSource::Generated(GeneratedPath::Overview)
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

    /// The help of `argument` of the command whose arguments are `A`.
    fn help_of<A: clap::Args>(argument: &str) -> clap::Arg {
        let command = A::augment_args(clap::Command::new("test"));
        command
            .get_arguments()
            .find(|a| a.get_id() == argument)
            .unwrap_or_else(|| panic!("no argument {argument}"))
            .clone()
    }

    /// Help texts are prose, so they name the generated paths by hand; this keeps them to the
    /// one list, [`GeneratedPath::ALL`].
    #[test]
    fn every_path_argument_names_every_generated_path() {
        let arguments = [
            ("bench --paths", help_of::<crate::bench::Args>("paths")),
            ("view --play", help_of::<crate::view::Args>("play")),
            ("render --path", help_of::<crate::render::Args>("path")),
        ];
        for (name, argument) in arguments {
            let help = argument.get_help().expect("documented").to_string();
            for g in GeneratedPath::ALL {
                assert!(
                    help.contains(g.name()),
                    "{name} does not name {g:?}: {help}"
                );
            }
        }
        let paths = help_of::<crate::bench::Args>("paths");
        let defaults: Vec<&str> = paths
            .get_default_values()
            .iter()
            .filter_map(|v| v.to_str())
            .collect();
        let expected = GeneratedPath::list(&GeneratedPath::DEFAULT);
        assert_eq!(defaults, [expected.as_str()], "bench --paths defaults");
    }
}
