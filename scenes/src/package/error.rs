//! Why a package could not be read or written.

use std::path::PathBuf;

/// An error reading or writing a scene package. Every malformed file gives one of these,
/// never a panic.
#[derive(Debug, thiserror::Error)]
pub enum PackageError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The output path exists and is not a writable regular file (a device, a folder, a
    /// read-only file); it is left untouched.
    #[error("{path}: {reason}")]
    NotWritable { path: PathBuf, reason: String },
    /// The file does not start with the package magic.
    #[error("not a citywalk scene package (no `CWK` magic)")]
    NotAPackage,
    /// The file is a package of another format version (`path` when read from a file).
    #[error(
        "{}package format version {found}; this citywalk reads version {supported}: re-run \
         `citywalk preprocess` on its input to rebuild it",
        path.as_ref().map(|p| format!("{}: ", p.display())).unwrap_or_default()
    )]
    Version {
        path: Option<PathBuf>,
        found: u32,
        supported: u32,
    },
    /// The file ends before the data its header announces.
    #[error("truncated package: {what} needs {needed} bytes, the file has {len}")]
    Truncated { what: String, needed: u64, len: u64 },
    /// A checksum does not match: the header (with its section table) or one section.
    #[error("checksum mismatch in {section}: the package is corrupted")]
    Checksum { section: String },
    /// The header or section table is inconsistent (overlapping or unknown sections, a
    /// missing section, non-zero padding, trailing bytes).
    #[error("malformed package: {0}")]
    Malformed(String),
    /// A section passed its checksum but could not be decoded (written by a faulty writer).
    #[error("section {section}: cannot decode: {reason}")]
    Decode { section: String, reason: String },
    /// Sections that each decode but do not belong together (one taken from another package):
    /// their counts or ranges disagree. `sections` names them.
    #[error("inconsistent package: {sections}: {reason}")]
    Inconsistent { sections: String, reason: String },
    /// A building asked for by index that the package does not have.
    #[error("no building {index}: the package has {count}")]
    NoSuchBuilding { index: usize, count: usize },
    /// The package could not be encoded.
    #[error("cannot encode section {section}: {reason}")]
    Encode { section: String, reason: String },
}
