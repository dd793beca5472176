//! Placeholder until the cityjson loader lands in this session.

use std::path::Path;

use super::LoadOptions;
use crate::city::City;
use crate::report::LoadError;

/// Loads a cityjson file.
pub fn load(path: &Path, _options: &LoadOptions) -> Result<City, LoadError> {
    Err(LoadError::Unsupported {
        path: path.to_path_buf(),
        reason: "loader not built yet".into(),
    })
}
