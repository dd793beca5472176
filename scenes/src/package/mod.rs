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
use crate::city::{Building, City, GroundArea, Street};
use crate::cluster_texture::baked::ClusterTextures;
use crate::cluster_tree::ClusterTree;
use crate::frame::Frame;
use crate::ground_surfaces::GroundSurfaces;
use crate::occluder::OccluderSet;
use crate::quadtree::BQuadtree;
use crate::report::LoadReport;
use geo::BoundingRect;

mod error;
pub mod format;
pub mod gpu_scene;
mod map;
pub(crate) mod scratch;
pub(crate) use map::{MappedPages, map_read_only, release_resident};

pub use error::PackageError;
pub use format::{BuildingDetails, Decode, FORMAT_VERSION, MAGIC, SectionKind};
pub use gpu_scene::{GpuScene, GpuSceneView, SceneStore};
pub use map::PackageFile;
pub use scratch::{SpilledOccluderSection, SpilledSection};

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
    pub ground_areas: Vec<GroundArea>,
    /// The streets and ground areas as drawn surfaces ([`GroundSurfaces::build`]).
    pub ground_surfaces: GroundSurfaces,
    pub blocks: UrbanBlocks,
    pub quadtree: BQuadtree,
    /// `None` when the occluder stage was not run.
    pub occluders: Option<OccluderSet>,
    /// `None` when the cluster-tree stage was not run.
    pub cluster_tree: Option<ClusterTree>,
    /// The cluster meshes' baked textures (Chang et al. 2008 §7); `None` unless preprocessing
    /// was asked to bake them.
    pub cluster_textures: Option<ClusterTextures>,
    pub provenance: Provenance,
    /// Stage timings; written only with [`WriteOptions::include_timings`].
    pub timings: Vec<StageTiming>,
    /// The GPU-ready buildings and cluster meshes ([`GpuScene::build`] of the buildings and
    /// the tree), read in place from a mapped package.
    pub gpu_scene: GpuScene,
    /// Sections encoded ahead of the write to keep their values out of memory while later
    /// stages ran (preprocessing into a scratch folder spills the occluders); each is written
    /// in place of its field, which whoever spilled it left empty (`None`). A decoded package
    /// has none.
    pub spilled: Vec<SpilledSection>,
}

/// A package's city and the structures drawing it uses ([`ScenePackage::into_parts`]).
#[derive(Debug)]
pub struct PackageParts {
    pub city: City,
    pub blocks: UrbanBlocks,
    pub quadtree: BQuadtree,
    pub occluders: Option<OccluderSet>,
    pub cluster_tree: Option<ClusterTree>,
    pub cluster_textures: Option<ClusterTextures>,
    pub gpu_scene: GpuScene,
    pub ground_surfaces: GroundSurfaces,
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
            ground_areas: self.ground_areas.clone(),
            report: self.provenance.load_report.clone(),
        }
    }

    /// The city the package was made from, moved out of it (no copy of the buildings).
    pub fn into_city(self) -> City {
        self.into_parts().city
    }

    /// The package moved apart into its city and the structures drawing it uses (no copy:
    /// at a million buildings each copy is gigabytes).
    pub fn into_parts(self) -> PackageParts {
        PackageParts {
            city: City {
                frame: self.frame,
                buildings: self.buildings,
                streets: self.streets,
                ground_areas: self.ground_areas,
                report: self.provenance.load_report,
            },
            blocks: self.blocks,
            quadtree: self.quadtree,
            occluders: self.occluders,
            cluster_tree: self.cluster_tree,
            cluster_textures: self.cluster_textures,
            gpu_scene: self.gpu_scene,
            ground_surfaces: self.ground_surfaces,
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
        let mut out = std::io::BufWriter::with_capacity(1 << 20, tmp.as_file_mut());
        let length = format::encode_to(self, options, &mut out, io)?;
        std::io::Write::flush(&mut out).map_err(io)?;
        drop(out);
        tmp.as_file().sync_all().map_err(io)?;
        tmp.persist(&target).map_err(|e| io(e.error))?;
        Ok(length)
    }

    /// Reads a package from `path` through a memory map (kept open while the package's GPU
    /// scene is alive).
    pub fn read(path: &Path) -> Result<ScenePackage, PackageError> {
        PackageFile::open(path)?.decode()
    }

    /// [`ScenePackage::read`] of the sections `what` names: to draw ([`Decode::Runtime`]),
    /// `occluders` is left `None` and the runtime draws them from the GPU scene
    /// ([`GpuSceneView::occluders`]).
    pub fn read_as(path: &Path, what: Decode) -> Result<ScenePackage, PackageError> {
        PackageFile::open(path)?.decode_as(what)
    }

    /// The cheap checks that the sections belong together, run whenever a package is opened:
    /// counts and ranges agree across buildings, blocks, quadtree, occluders, cluster tree and
    /// GPU scene, and the boxes the GPU scene draws lie in their buildings' boxes. Linear in the
    /// package (the O(n log n) cluster-tree ranges aside); each finding names its sections.
    pub fn check_sections(&self) -> Result<(), Vec<(&'static str, String)>> {
        let mut errors = Vec::new();
        let n = self.buildings.len();
        let nodes = self.cluster_tree.as_ref().map_or(0, |t| t.nodes.len());
        let view = self.gpu_scene.view();
        if view.building_count as usize != n || view.cluster_count() != nodes {
            errors.push((
                "gpu scene, buildings, cluster tree",
                format!(
                    "{} buildings and {} clusters, the package has {n} and {nodes}",
                    view.building_count,
                    view.cluster_count()
                ),
            ));
        } else if let Some((i, b)) = self
            .buildings
            .iter()
            .enumerate()
            .find(|(i, b)| !record_in_box(&view.records[*i], b.bounds()))
        {
            errors.push((
                "gpu scene, buildings",
                format!("building {i} ({}) is drawn outside its box", b.source_id),
            ));
        }
        if let Some((i, b)) = self
            .buildings
            .iter()
            .enumerate()
            .find(|(i, b)| b.id.index() != *i)
        {
            errors.push(("buildings", format!("building {i} has id {}", b.id.0)));
        }
        if let Err(e) = self.blocks.check_invariants(n) {
            errors.push(("blocks, buildings", e));
        }
        if let Err(e) = self.quadtree.check_invariants() {
            errors.push(("quadtree", e));
        }
        if let Err(e) = self.ground_surfaces.check() {
            errors.push(("ground surfaces", e));
        }
        if self.quadtree.block_bounds.len() != self.blocks.blocks.len() {
            errors.push((
                "quadtree, blocks",
                format!(
                    "{} blocks in the quadtree, {} in the blocks",
                    self.quadtree.block_bounds.len(),
                    self.blocks.blocks.len()
                ),
            ));
        } else if let Some(k) = (self.blocks.blocks.iter().zip(&self.quadtree.block_bounds))
            .position(|(block, bb)| block.bounds_min != bb.min || block.bounds_max != bb.max)
        {
            errors.push((
                "quadtree, blocks",
                format!("the box of block {k} differs from the block's"),
            ));
        }
        if let Some(occ) = &self.occluders
            && let Err(e) = occluder_ranges(occ, &self.buildings)
        {
            errors.push(("occluders, buildings", e));
        }
        if let Some(occ) = &self.occluders
            && view.occluders.records.len() > occ.occluders.len()
        {
            errors.push((
                "gpu scene, occluders",
                format!(
                    "{} occluders drawn, the occluder set has {}",
                    view.occluders.records.len(),
                    occ.occluders.len()
                ),
            ));
        }
        if let Some(tree) = &self.cluster_tree
            && let Err(e) = tree_ranges(tree, &self.buildings)
        {
            errors.push(("cluster tree, buildings", e));
        }
        match (&self.cluster_textures, &self.cluster_tree) {
            (Some(textures), Some(tree)) => {
                if let Err(e) = textures.check(tree) {
                    errors.push(("cluster textures, cluster tree", e));
                }
            }
            (Some(_), None) => errors.push((
                "cluster textures, cluster tree",
                "textures of cluster meshes without a cluster tree".into(),
            )),
            (None, _) => {}
        }
        if errors.is_empty() {
            Ok(())
        } else {
            Err(errors)
        }
    }

    /// Runs every structure's invariant checker: city, blocks, quadtree, occluders and tree,
    /// and the agreement of the sections ([`Self::check_sections`]). Returns every violation
    /// found, one per structure.
    pub fn check_invariants(&self) -> Result<(), Vec<String>> {
        let mut errors: Vec<String> = match self.check_sections() {
            Ok(()) => Vec::new(),
            Err(e) => e.into_iter().map(|(s, r)| format!("{s}: {r}")).collect(),
        };
        let n = self.buildings.len();
        if let Err(e) = self.city().check_invariants() {
            errors.push(format!("city: {e}"));
        }
        if let Some(occ) = &self.occluders
            && let Err(e) = occ.check_invariants()
        {
            errors.push(format!("occluders: {e}"));
        }
        let nodes = self.cluster_tree.as_ref().map_or(0, |t| t.nodes.len());
        if let Err(e) = self.gpu_scene.view().check_invariants(n, nodes) {
            errors.push(format!("gpu scene: {e}"));
        } else if GpuScene::build(
            &self.city(),
            self.cluster_tree.as_ref(),
            self.occluders.as_ref(),
        ) != self.gpu_scene
        {
            errors.push("gpu scene: differs from the one built from the buildings and tree".into());
        }
        if let Some(tree) = &self.cluster_tree
            && let Err(e) = tree.check_invariants(&self.city())
        {
            errors.push(format!("cluster tree: {e}"));
        }
        if errors.is_empty() {
            Ok(())
        } else {
            Err(errors)
        }
    }
}

/// Slack of the box tests between sections (metres): boxes are rounded to `f32`, footprint
/// repairs grow slivers to boxes of a few centimetres.
const BOX_SLACK_M: f32 = 1.0;

/// Whether a draw record's box lies in `bounds` (a building's box) up to [`BOX_SLACK_M`].
fn record_in_box(
    record: &citywalk_shaders::BuildingRecord,
    (lo, hi): (glam::Vec3, glam::Vec3),
) -> bool {
    let (rlo, rhi) = (
        glam::Vec3::from_array(record.bounds_min_m),
        glam::Vec3::from_array(record.bounds_max_m),
    );
    // An empty record (a building without triangles) has an inverted box.
    rlo.cmpgt(rhi).any() || (rlo.cmpge(lo - BOX_SLACK_M).all() && rhi.cmple(hi + BOX_SLACK_M).all())
}

/// One outcome per building in order, contiguous ranges inside the occluders, each occluder
/// of its building and inside its box in plan.
fn occluder_ranges(occ: &OccluderSet, buildings: &[Building]) -> Result<(), String> {
    if occ.per_building.len() != buildings.len() {
        return Err(format!(
            "{} outcomes for {} buildings",
            occ.per_building.len(),
            buildings.len()
        ));
    }
    let mut next = 0u32;
    for (i, (outcome, b)) in occ.per_building.iter().zip(buildings).enumerate() {
        let range = &outcome.occluder_range;
        if outcome.building.index() != i || range.start != next || range.end < range.start {
            return Err(format!(
                "outcome {i}: building {} range {range:?}",
                outcome.building.0
            ));
        }
        next = range.end;
        let Some(these) = occ.occluders.get(range.start as usize..range.end as usize) else {
            return Err(format!(
                "building {i}: range {range:?} beyond {} occluders",
                occ.occluders.len()
            ));
        };
        let (lo, hi) = b.bounds();
        for o in these {
            let inside = o.footprint.bounding_rect().is_none_or(|r| {
                let (rlo, rhi) = (r.min(), r.max());
                rlo.x as f32 >= lo.x - BOX_SLACK_M
                    && rlo.y as f32 >= lo.y - BOX_SLACK_M
                    && rhi.x as f32 <= hi.x + BOX_SLACK_M
                    && rhi.y as f32 <= hi.y + BOX_SLACK_M
            });
            if o.building.index() != i || !inside {
                return Err(format!(
                    "an occluder of building {i} ({}) lies outside it",
                    b.source_id
                ));
            }
        }
    }
    if next as usize != occ.occluders.len() {
        return Err(format!(
            "{} occluders, the ranges cover {next}",
            occ.occluders.len()
        ));
    }
    Ok(())
}

/// `building_order` a permutation of the buildings, the root over all of them, node ranges in
/// it, and each node's outline inside the box of its buildings.
fn tree_ranges(tree: &ClusterTree, buildings: &[Building]) -> Result<(), String> {
    let n = buildings.len();
    if tree.building_order.len() != n {
        return Err(format!(
            "{} buildings in the tree, {n} in the package",
            tree.building_order.len()
        ));
    }
    let mut seen = vec![false; n];
    for b in &tree.building_order {
        match seen.get_mut(b.index()) {
            Some(s) if !*s => *s = true,
            _ => return Err(format!("building {} missing or repeated in the tree", b.0)),
        }
    }
    let boxes: Vec<(glam::Vec3, glam::Vec3)> = tree
        .building_order
        .iter()
        .map(|b| buildings[b.index()].bounds())
        .collect();
    for (k, node) in tree.nodes.iter().enumerate() {
        let (first, end) = (node.buildings.0 as usize, node.buildings.1 as usize);
        let Some(members) = boxes.get(first..end).filter(|m| !m.is_empty()) else {
            return Err(format!("node {k}: buildings {first}..{end} of {n}"));
        };
        let (lo, hi) = members
            .iter()
            .fold((glam::Vec3::MAX, glam::Vec3::MIN), |(a, b), (l, h)| {
                (a.min(*l), b.max(*h))
            });
        let outside = node.footprint.first().into_iter().flatten().any(|&v| {
            tree.vertices.get(v as usize).is_none_or(|&[x, y]| {
                let (x, y) = (x as f32, y as f32);
                x < lo.x - BOX_SLACK_M
                    || y < lo.y - BOX_SLACK_M
                    || x > hi.x + BOX_SLACK_M
                    || y > hi.y + BOX_SLACK_M
            })
        });
        let (nlo, nhi) = (
            glam::Vec3::from_array(node.bounds_min),
            glam::Vec3::from_array(node.bounds_max),
        );
        let box_differs = (nlo - lo).abs().max_element() > BOX_SLACK_M
            || (nhi - hi).abs().max_element() > BOX_SLACK_M;
        if outside || box_differs {
            return Err(format!(
                "node {k}: outline or box not that of its buildings"
            ));
        }
    }
    Ok(())
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
