//! A scene package handed on to the 3D Tiles ecosystem: a 3D Tiles 1.1 tileset whose hierarchy
//! is the package's legibility cluster tree as HLOD (inner tiles hold the simplified cluster
//! meshes, leaves the buildings; [`hlod`]), with glTF 2.0 binary contents carrying per-building
//! identity ([`glb`]), placed on the globe by a root transform ([`georef`]); or one GLB of the
//! whole city at full detail or at one level of the tree.
//!
//! A tile's `geometricError` is the tree's own error in metres (the larger of the geometric and
//! the colour error of its clusters, the quantity citywalk's default LOD criterion projects), so
//! a client refining at N pixels draws what citywalk draws at N pixels.

pub mod georef;
pub mod glb;
pub mod hlod;
mod tileset;

use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::city::HeightSource;
use crate::package::ScenePackage;
pub use georef::PlacementError;
use glb::{BuildingFeature, ClusterFeature, FeatureMesh, GlbContent};

/// Triangles a tile holds at most by default (the tree allows more in a tile of one cluster
/// mesh or of buildings only): contents of 10k–30k triangles load in one request and draw in
/// one call in a client.
pub const DEFAULT_TILE_TRIANGLES: u64 = 32_768;

/// Options of an export.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportOptions {
    /// Triangles a tile holds at most where the tree allows ([`DEFAULT_TILE_TRIANGLES`]).
    pub max_tile_triangles: u64,
    /// Longitude and latitude (degrees) of the origin of a scene without geographic placement.
    pub place: Option<(f64, f64)>,
    /// The data's attribution, written into every content's `asset.copyright` and the
    /// tileset's `asset.extras` (OpenStreetMap's is added for OSM inputs).
    pub attribution: Option<String>,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            max_tile_triangles: DEFAULT_TILE_TRIANGLES,
            place: None,
            attribution: None,
        }
    }
}

/// What an export wrote.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ExportReport {
    pub tiles: usize,
    pub contents: usize,
    pub triangles: u64,
    pub bytes: u64,
    /// Buildings and cluster meshes written (a building counts once per content holding it).
    pub buildings_written: u64,
    pub clusters_written: u64,
}

/// Why an export failed.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    #[error(
        "the package has no cluster tree (its preprocessing skipped that stage): a 3D Tiles HLOD is made from it; re-run `preprocess` with the tree, or export --format glb"
    )]
    NoClusterTree,
    #[error("{0}")]
    Placement(#[from] PlacementError),
    #[error("--level {level}: the cluster tree has levels 0 to {max}")]
    Level { level: u32, max: u32 },
    #[error(
        "{}: the folder is not empty and holds no tileset citywalk wrote; export into a new or empty folder",
        .0.display()
    )]
    NotEmpty(PathBuf),
    #[error("cannot write {}: {source}", .path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    std::fs::write(path, bytes).map_err(|source| ExportError::Write {
        path: path.to_path_buf(),
        source,
    })
}

/// One draw of the GPU scene, as triangles over its own positions.
struct DrawMesh {
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
}

/// Reads what the export needs from a package: draw meshes and features.
struct Source<'a> {
    package: &'a ScenePackage,
    attribution: Option<String>,
}

impl<'a> Source<'a> {
    fn new(package: &'a ScenePackage, options: &ExportOptions) -> Source<'a> {
        let osm = package.provenance.inputs.iter().any(|i| {
            let p = i.path.to_ascii_lowercase();
            p.ends_with(".osm.pbf") || p.ends_with(".osm")
        });
        let mut parts: Vec<String> = options.attribution.iter().cloned().collect();
        if osm {
            parts.push("© OpenStreetMap contributors, ODbL 1.0".into());
        }
        Source {
            package,
            attribution: (!parts.is_empty()).then(|| parts.join("; ")),
        }
    }

    fn building_count(&self) -> u32 {
        self.package.gpu_scene.view().building_count
    }

    fn triangles(&self, draw: u32) -> u64 {
        let view = self.package.gpu_scene.view();
        view.records
            .get(draw as usize)
            .map_or(0, |r| u64::from(r.index_count / 3))
    }

    fn mesh(&self, draw: u32) -> DrawMesh {
        let view = self.package.gpu_scene.view();
        let Some(r) = view.records.get(draw as usize) else {
            return DrawMesh {
                positions: Vec::new(),
                triangles: Vec::new(),
            };
        };
        let base = r.base_vertex.max(0) as usize;
        let end = (base + r.vertex_count as usize).min(view.vertices.len());
        let positions = view.vertices[base.min(end)..end]
            .iter()
            .map(|v| Vec3::from(v.position_m))
            .collect();
        let first = r.first_index as usize;
        let last = (first + r.index_count as usize).min(view.indices.len());
        let triangles = view.indices[first.min(last)..last]
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect();
        DrawMesh {
            positions,
            triangles,
        }
    }

    fn building(&self, id: u32) -> BuildingFeature {
        let b = &self.package.buildings[id as usize];
        let levels = b
            .levels_tag()
            .and_then(|v| v.trim().parse::<f64>().ok())
            .filter(|l| l.is_finite() && *l >= 1.0 && *l < 65_535.0)
            .map_or(0, |l| l.round() as u16);
        BuildingFeature {
            building_id: id,
            source_id: b.source_id.clone(),
            height_m: b.height_m(),
            levels,
            height_estimated: b.height_source == HeightSource::Estimated,
        }
    }

    fn cluster(&self, node: u32) -> ClusterFeature {
        let tree = self.package.cluster_tree.as_ref().expect("a cluster draw");
        let n = &tree.nodes[node as usize];
        ClusterFeature {
            node,
            building_count: n.building_count() as u32,
            geometric_error_m: n.lod_error_m(),
        }
    }

    /// Writes the GLB of `draws` (building ids and `building_count + node` cluster ids).
    fn glb(&self, draws: &[u32]) -> glb::WrittenGlb {
        let n = self.building_count();
        let meshes: Vec<(u32, DrawMesh)> = draws.iter().map(|&d| (d, self.mesh(d))).collect();
        let mut content = GlbContent {
            buildings: Vec::new(),
            clusters: Vec::new(),
            copyright: self.attribution.clone(),
            generator: format!("citywalk {}", env!("CARGO_PKG_VERSION")),
        };
        for (d, m) in &meshes {
            if *d < n {
                content.buildings.push(FeatureMesh {
                    feature: self.building(*d),
                    positions: &m.positions,
                    triangles: &m.triangles,
                });
            } else {
                content.clusters.push(FeatureMesh {
                    feature: self.cluster(*d - n),
                    positions: &m.positions,
                    triangles: &m.triangles,
                });
            }
        }
        glb::write_glb(&content)
    }
}

/// Writes `package` as a 3D Tiles 1.1 tileset into the folder `out` (`tileset.json` and
/// `tiles/N.glb`).
pub fn write_3d_tiles(
    package: &ScenePackage,
    out: &Path,
    options: &ExportOptions,
) -> Result<ExportReport, ExportError> {
    let tree = package
        .cluster_tree
        .as_ref()
        .ok_or(ExportError::NoClusterTree)?;
    let transform = georef::root_transform(&package.frame, options.place)?;
    prepare_folder(out)?;
    let source = Source::new(package, options);
    let triangles = |d: u32| source.triangles(d);
    let error = |node: u32| tree.nodes[node as usize].lod_error_m();
    let tiles = hlod::tile_tree(
        &hlod::HlodInput {
            tree,
            building_count: source.building_count(),
            triangles: &triangles,
            error_m: &error,
        },
        options.max_tile_triangles.max(1),
    );
    tileset::write(&source, &tiles, transform, out)
}

/// Writes `package` as one GLB at `path`: every building at full detail, or with `level` the
/// tree's cut at that depth (cluster meshes, and the buildings of shallower leaves).
pub fn write_glb(
    package: &ScenePackage,
    path: &Path,
    level: Option<u32>,
    options: &ExportOptions,
) -> Result<ExportReport, ExportError> {
    let source = Source::new(package, options);
    let n = source.building_count();
    let draws: Vec<u32> = match level {
        None => (0..n).collect(),
        Some(level) => {
            let tree = package
                .cluster_tree
                .as_ref()
                .ok_or(ExportError::NoClusterTree)?;
            let max = tree.max_depth();
            if level > max {
                return Err(ExportError::Level { level, max });
            }
            let mut draws = Vec::new();
            let mut stack = tree.cut_at_level(level);
            while let Some(node) = stack.pop() {
                let nd = &tree.nodes[node as usize];
                if nd.is_leaf() {
                    draws.push(tree.building_order[nd.buildings.0 as usize].0);
                } else if source.triangles(n + node) == 0 {
                    // An empty cluster mesh shows none of its buildings: its children instead.
                    stack.extend(&nd.children);
                } else {
                    draws.push(n + node);
                }
            }
            draws.sort_unstable();
            draws
        }
    };
    let written = source.glb(&draws);
    write_file(path, &written.bytes)?;
    let clusters = draws.iter().filter(|&&d| d >= n).count() as u64;
    Ok(ExportReport {
        tiles: 0,
        contents: 1,
        triangles: written.triangles,
        bytes: written.bytes.len() as u64,
        buildings_written: draws.len() as u64 - clusters,
        clusters_written: clusters,
    })
}

/// Makes `out` ready for a tileset: created when missing; an earlier citywalk tileset there is
/// replaced (its `tiles/` removed); any other non-empty folder is refused.
fn prepare_folder(out: &Path) -> Result<(), ExportError> {
    let write_err = |source| ExportError::Write {
        path: out.to_path_buf(),
        source,
    };
    if out.exists() {
        let mut entries = std::fs::read_dir(out).map_err(write_err)?;
        if entries.next().is_some() {
            let ours = std::fs::read(out.join("tileset.json"))
                .ok()
                .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
                .and_then(|j| j["asset"]["generator"].as_str().map(str::to_string))
                .is_some_and(|g| g.starts_with("citywalk"));
            if !ours {
                return Err(ExportError::NotEmpty(out.to_path_buf()));
            }
            let tiles = out.join(tileset::TILES_DIR);
            if tiles.exists() {
                std::fs::remove_dir_all(&tiles).map_err(|source| ExportError::Write {
                    path: tiles,
                    source,
                })?;
            }
        }
    }
    std::fs::create_dir_all(out.join(tileset::TILES_DIR)).map_err(write_err)
}
