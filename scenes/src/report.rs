//! What a load found, kept and rejected, and the errors that stop a load.
//!
//! A malformed *file* is a [`LoadError`] naming the file. A malformed *building* is a
//! [`Rejection`] naming the file, the building's source id and the [`RejectReason`]; the other
//! buildings still load, and `loaded + rejected = found` always holds.

use std::fmt;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

/// Why one building (or part) was not loaded.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, thiserror::Error)]
pub enum RejectReason {
    #[error("non-finite coordinate")]
    NonFiniteCoordinate,
    #[error("coordinate out of range ({0})")]
    CoordinateOutOfRange(String),
    #[error("fewer than 3 distinct points")]
    TooFewPoints,
    #[error("zero area")]
    ZeroArea,
    #[error("self-intersection that cannot be repaired")]
    SelfIntersection,
    #[error("absurd height: {0}")]
    AbsurdHeight(String),
    #[error("missing geometry: {0}")]
    MissingGeometry(String),
    #[error("invalid geometry: {0}")]
    InvalidGeometry(String),
}

/// One rejected building.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Rejection {
    pub file: PathBuf,
    pub source_id: String,
    pub reason: RejectReason,
}

impl fmt::Display for Rejection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: building {}: {}",
            self.file.display(),
            self.source_id,
            self.reason
        )
    }
}

/// Something worth telling about a building that still loaded (a repaired ring, an estimated
/// height, a part that fell back to its building's outline, ...).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LoadWarning {
    pub file: PathBuf,
    pub source_id: String,
    pub message: String,
}

impl fmt::Display for LoadWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.source_id.is_empty() {
            // A warning about the file as a whole (skipped features, an ignored tileset).
            write!(f, "{}: {}", self.file.display(), self.message)
        } else {
            write!(
                f,
                "{}: {}: {}",
                self.file.display(),
                self.source_id,
                self.message
            )
        }
    }
}

/// The account of one load.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LoadReport {
    /// Input files read.
    pub files: Vec<PathBuf>,
    /// Buildings found in the input (building parts are counted separately).
    pub buildings_found: usize,
    /// Buildings in the city.
    pub buildings_loaded: usize,
    /// Building parts found in the input.
    pub parts_found: usize,
    /// Buildings whose height was tagged in metres (not estimated, not from levels).
    pub buildings_with_height: usize,
    /// Buildings whose height was estimated with the default.
    pub buildings_estimated_height: usize,
    /// Street lines found in the input (one per line of a multi-line street).
    pub streets_found: usize,
    /// Streets loaded.
    pub streets_loaded: usize,
    pub rejected: Vec<Rejection>,
    /// Street lines that could not be used (too few points, zero length, a coordinate out of
    /// range), with their source id and reason: `streets_loaded + streets_rejected =
    /// streets_found`.
    pub streets_rejected: Vec<Rejection>,
    /// Ground areas (water, parks, squares, ...) found in the input.
    pub ground_areas_found: usize,
    /// Ground areas loaded.
    pub ground_areas_loaded: usize,
    /// Ground areas that could not be used, with their source id and reason:
    /// `ground_areas_loaded + ground_areas_rejected = ground_areas_found`.
    pub ground_areas_rejected: Vec<Rejection>,
    pub warnings: Vec<LoadWarning>,
}

impl LoadReport {
    /// `loaded + rejected = found`, for buildings and for streets.
    pub fn is_balanced(&self) -> bool {
        self.buildings_loaded + self.rejected.len() == self.buildings_found
            && self.streets_loaded + self.streets_rejected.len() == self.streets_found
            && self.ground_areas_loaded + self.ground_areas_rejected.len()
                == self.ground_areas_found
    }

    /// Folds another file's report into this one.
    pub fn merge(&mut self, other: LoadReport) {
        self.files.extend(other.files);
        self.buildings_found += other.buildings_found;
        self.buildings_loaded += other.buildings_loaded;
        self.parts_found += other.parts_found;
        self.buildings_with_height += other.buildings_with_height;
        self.buildings_estimated_height += other.buildings_estimated_height;
        self.streets_found += other.streets_found;
        self.streets_loaded += other.streets_loaded;
        self.rejected.extend(other.rejected);
        self.streets_rejected.extend(other.streets_rejected);
        self.ground_areas_found += other.ground_areas_found;
        self.ground_areas_loaded += other.ground_areas_loaded;
        self.ground_areas_rejected
            .extend(other.ground_areas_rejected);
        self.warnings.extend(other.warnings);
    }
}

impl fmt::Display for LoadReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} buildings found, {} loaded, {} rejected; {} parts; {} with tagged height, {} \
             estimated; {} streets ({} rejected); {} ground areas ({} rejected); {} warnings",
            self.buildings_found,
            self.buildings_loaded,
            self.rejected.len(),
            self.parts_found,
            self.buildings_with_height,
            self.buildings_estimated_height,
            self.streets_loaded,
            self.streets_rejected.len(),
            self.ground_areas_loaded,
            self.ground_areas_rejected.len(),
            self.warnings.len()
        )
    }
}

impl LoadReport {
    /// Logs every rejection and warning, each with its file, source id and reason (the
    /// counts alone do not say which building to look at).
    pub fn log_items(&self) {
        for r in &self.rejected {
            tracing::warn!("rejected: {r}");
        }
        for r in &self.streets_rejected {
            let file = r.file.display();
            tracing::warn!("rejected: {file}: street {}: {}", r.source_id, r.reason);
        }
        for r in &self.ground_areas_rejected {
            let file = r.file.display();
            tracing::warn!(
                "rejected: {file}: ground area {}: {}",
                r.source_id,
                r.reason
            );
        }
        for w in &self.warnings {
            tracing::warn!("{w}");
        }
    }
}

impl LoadError {
    /// The error of a file whose every building was rejected: names the first rejection (and
    /// logs them all).
    pub fn nothing_loaded(path: &Path, report: &LoadReport) -> LoadError {
        report.log_items();
        let first = report
            .rejected
            .first()
            .map(|r| format!("{}: {}", r.source_id, r.reason))
            .unwrap_or_else(|| "none".into());
        LoadError::NothingLoaded {
            path: path.to_path_buf(),
            found: report.buildings_found,
            first,
        }
    }
}

/// An error that stops the load of a whole file.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    #[error("{path}: cannot read: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: not a valid {format} file: {reason}")]
    Malformed {
        path: PathBuf,
        format: &'static str,
        reason: String,
    },
    #[error("{path}: unsupported input: {reason}")]
    Unsupported { path: PathBuf, reason: String },
    #[error("{path}: no buildings could be loaded ({found} found, all rejected; first: {first})")]
    NothingLoaded {
        path: PathBuf,
        found: usize,
        first: String,
    },
}
