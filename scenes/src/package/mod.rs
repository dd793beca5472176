//! The scene package: one versioned, checksummed, memory-mappable binary file (`.cwk`) holding
//! everything the runtime needs — the city frame, buildings (footprints, parts, heights,
//! meshes, tags), streets, virtual occluders, the cluster tree, urban blocks, the B-Quadtree —
//! and the provenance of the preprocessing (inputs with SHA-256 hashes, parameters, counts,
//! rejected buildings with reasons, warnings, tool version).
//!
//! The byte layout is described in [`format`]. The file is deterministic: the same input and
//! parameters give the same bytes. Wall-clock stage timings are not part of it unless asked for
//! ([`WriteOptions::include_timings`]); they then go to their own section.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::blocks::UrbanBlocks;
use crate::city::{Building, City, Street};
use crate::cluster_tree::ClusterTree;
use crate::frame::Frame;
use crate::occluder::OccluderSet;
use crate::quadtree::BQuadtree;
use crate::report::LoadReport;

mod error;
pub mod format;
pub mod gpu_scene;
mod map;

pub use error::PackageError;
pub use format::{FORMAT_VERSION, MAGIC, SectionKind};
pub use gpu_scene::{GpuScene, GpuSceneView};
pub use map::PackageFile;

/// One input file of the preprocessing.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct InputFile {
    /// The path as given on the command line.
    pub path: String,
    pub size_bytes: u64,
    /// SHA-256 of the file's bytes, lower-case hex; `None` when the file could not be read
    /// (an in-memory city).
    pub sha256: Option<String>,
}

/// Wall-clock time of one preprocessing stage (not deterministic).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageTiming {
    pub stage: String,
    pub seconds: f64,
}

/// How the package was made.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// `citywalk <version>` of the tool that wrote the package.
    pub tool_version: String,
    pub inputs: Vec<InputFile>,
    /// The preprocessing parameters, as JSON (object keys in declaration order).
    pub parameters_json: String,
    /// The load report: buildings found / loaded, rejected buildings with reasons, warnings.
    pub load_report: LoadReport,
    /// Named counts of the stages (blocks, occluders, tree nodes, ...), sorted by name.
    pub counts: BTreeMap<String, u64>,
    /// Stages that were not run, with the reason.
    pub skipped_stages: Vec<String>,
    /// Warnings of the preprocessing stages.
    pub warnings: Vec<String>,
}

/// Everything a scene package holds.
#[derive(Debug, Clone, PartialEq)]
pub struct ScenePackage {
    pub frame: Frame,
    pub buildings: Vec<Building>,
    pub streets: Vec<Street>,
    pub blocks: UrbanBlocks,
    pub quadtree: BQuadtree,
    /// `None` when the occluder stage was not run.
    pub occluders: Option<OccluderSet>,
    /// `None` when the cluster-tree stage was not run.
    pub cluster_tree: Option<ClusterTree>,
    pub provenance: Provenance,
    /// Stage timings; written only with [`WriteOptions::include_timings`].
    pub timings: Vec<StageTiming>,
    /// The GPU-ready buildings and cluster meshes ([`GpuScene::build`] of the buildings and
    /// the tree), read in place from a mapped package.
    pub gpu_scene: GpuScene,
}

/// Options of [`ScenePackage::to_bytes`] / [`ScenePackage::write`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WriteOptions {
    /// Write the (non-deterministic) stage timings in a section of their own.
    pub include_timings: bool,
}

impl ScenePackage {
    /// The city the package was made from (buildings, streets, frame, load report).
    pub fn city(&self) -> City {
        City {
            frame: self.frame.clone(),
            buildings: self.buildings.clone(),
            streets: self.streets.clone(),
            report: self.provenance.load_report.clone(),
        }
    }

    /// Encodes the package.
    pub fn to_bytes(&self, options: WriteOptions) -> Result<Vec<u8>, PackageError> {
        format::encode(self, options)
    }

    /// Decodes a package from bytes, refusing anything that is not an intact package.
    pub fn from_bytes(bytes: &[u8]) -> Result<ScenePackage, PackageError> {
        format::decode(bytes)
    }

    /// Writes the package to `path`: to a temporary file beside it, flushed to disk, then
    /// renamed into place, so a reader never sees half a package. A `path` that exists must be
    /// a writable regular file (a symbolic link is followed to one); anything else (a device,
    /// a folder, a pipe) is refused and left as it was.
    pub fn write(&self, path: &Path, options: WriteOptions) -> Result<u64, PackageError> {
        let target = writable_target(path)?;
        let bytes = self.to_bytes(options)?;
        let io = |source| PackageError::Io {
            path: target.clone(),
            source,
        };
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let mut builder = tempfile::Builder::new();
        builder.prefix(".citywalk-").suffix(".cwk.tmp");
        #[cfg(unix)]
        let mode = match std::fs::metadata(&target) {
            Ok(meta) => meta.permissions(),
            Err(_) => std::os::unix::fs::PermissionsExt::from_mode(0o666),
        };
        #[cfg(unix)]
        builder.permissions(mode);
        let mut tmp = builder.tempfile_in(dir).map_err(io)?;
        std::io::Write::write_all(&mut tmp, &bytes).map_err(io)?;
        tmp.as_file().sync_all().map_err(io)?;
        tmp.persist(&target).map_err(|e| io(e.error))?;
        Ok(bytes.len() as u64)
    }

    /// Reads a package from `path` through a memory map (kept open while the package's GPU
    /// scene is alive).
    pub fn read(path: &Path) -> Result<ScenePackage, PackageError> {
        PackageFile::open(path)?.decode()
    }

    /// Runs every structure's invariant checker: city, blocks, quadtree, occluders and tree,
    /// and the agreement of their sizes. Returns every violation found, one per structure.
    pub fn check_invariants(&self) -> Result<(), Vec<String>> {
        let mut errors = Vec::new();
        let n = self.buildings.len();
        if let Err(e) = self.city().check_invariants() {
            errors.push(format!("city: {e}"));
        }
        if let Err(e) = self.blocks.check_invariants(n) {
            errors.push(format!("blocks: {e}"));
        }
        if let Err(e) = self.quadtree.check_invariants() {
            errors.push(format!("quadtree: {e}"));
        }
        if self.quadtree.block_bounds.len() != self.blocks.blocks.len() {
            errors.push(format!(
                "quadtree: {} blocks, the package has {}",
                self.quadtree.block_bounds.len(),
                self.blocks.blocks.len()
            ));
        }
        for (k, (block, bb)) in self
            .blocks
            .blocks
            .iter()
            .zip(&self.quadtree.block_bounds)
            .enumerate()
        {
            if block.bounds_min != bb.min || block.bounds_max != bb.max {
                errors.push(format!(
                    "quadtree: box of block {k} differs from the block's"
                ));
                break;
            }
        }
        if let Some(occ) = &self.occluders {
            if let Err(e) = occ.check_invariants() {
                errors.push(format!("occluders: {e}"));
            }
            if occ.per_building.len() != n {
                errors.push(format!(
                    "occluders: {} outcomes for {n} buildings",
                    occ.per_building.len()
                ));
            }
        }
        let nodes = self.cluster_tree.as_ref().map_or(0, |t| t.nodes.len());
        if let Err(e) = self.gpu_scene.view().check_invariants(n, nodes) {
            errors.push(format!("gpu scene: {e}"));
        } else if GpuScene::build(&self.city(), self.cluster_tree.as_ref()) != self.gpu_scene {
            errors.push("gpu scene: differs from the one built from the buildings and tree".into());
        }
        if let Some(tree) = &self.cluster_tree {
            if let Err(e) = tree.check_invariants(&self.city()) {
                errors.push(format!("cluster tree: {e}"));
            }
            if tree.building_order.len() != n {
                errors.push(format!(
                    "cluster tree: {} buildings, the package has {n}",
                    tree.building_order.len()
                ));
            }
        }
        if errors.is_empty() {
            Ok(())
        } else {
            Err(errors)
        }
    }
}

/// Checks, before any work is done, that [`ScenePackage::write`] could write to `path`: it does
/// not exist, or it is a writable regular file (or a symbolic link to one).
pub fn check_output_path(path: &Path) -> Result<(), PackageError> {
    writable_target(path).map(|_| ())
}

/// The file [`ScenePackage::write`] replaces for `path`: `path` itself, or the file a symbolic
/// link at `path` points to. Refuses a target that is not a regular file or is read-only.
fn writable_target(path: &Path) -> Result<std::path::PathBuf, PackageError> {
    let refuse = |reason: String| PackageError::NotWritable {
        path: path.to_path_buf(),
        reason,
    };
    let meta = match std::fs::symlink_metadata(path) {
        Ok(meta) => meta,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(path.to_path_buf()),
        Err(source) => {
            return Err(PackageError::Io {
                path: path.to_path_buf(),
                source,
            });
        }
    };
    let (target, meta) = if meta.file_type().is_symlink() {
        let target = std::fs::canonicalize(path)
            .map_err(|e| refuse(format!("a symbolic link that cannot be followed ({e})")))?;
        let meta = std::fs::metadata(&target).map_err(|source| PackageError::Io {
            path: target.clone(),
            source,
        })?;
        (target, meta)
    } else {
        (path.to_path_buf(), meta)
    };
    if !meta.is_file() {
        return Err(refuse(format!(
            "exists and is {}, not a regular file (left as it is)",
            file_kind(&meta.file_type())
        )));
    }
    if meta.permissions().readonly() {
        return Err(refuse("the file is read-only (left as it is)".into()));
    }
    std::fs::OpenOptions::new()
        .write(true)
        .open(&target)
        .map_err(|e| refuse(format!("cannot be opened for writing ({e})")))?;
    Ok(target)
}

/// "a folder", "a character device", ... for an error message.
fn file_kind(kind: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_char_device() {
            return "a character device";
        }
        if kind.is_block_device() {
            return "a block device";
        }
        if kind.is_fifo() {
            return "a named pipe";
        }
        if kind.is_socket() {
            return "a socket";
        }
    }
    if kind.is_dir() {
        "a folder"
    } else {
        "a special file"
    }
}

/// SHA-256 of a file, lower-case hex, read in chunks.
pub fn sha256_file(path: &Path) -> std::io::Result<(u64, String)> {
    use sha2::Digest;
    use std::io::Read;
    let mut file = std::fs::File::open(path)?;
    let mut hasher = sha2::Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut size = 0u64;
    loop {
        let n = file.read(&mut buf)?;
        if n == 0 {
            break;
        }
        size += n as u64;
        hasher.update(&buf[..n]);
    }
    let digest = hasher.finalize();
    let hex = digest.iter().map(|b| format!("{b:02x}")).collect();
    Ok((size, hex))
}

#[cfg(test)]
mod tests;
