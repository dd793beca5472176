//! The preprocessing pipeline: city → blocks → occluders → cluster tree → B-Quadtree → scene
//! package, each stage timed.
//!
//! Blocks come from the street network ([`crate::blocks`], Pina et al. §3). A city without any
//! block-bounding street face takes its blocks from the first cut of the cluster tree (DESIGN.md
//! step 3): the tree is built over the whole city as one block, and the blocks are the nodes of
//! the shallowest level cut with at least `⌈n / PreprocessParams::buildings_per_block⌉` nodes
//! (a citywalk choice: 20 buildings per block on average, about a city block). The nodes'
//! `block` fields are then recomputed for those blocks.
//!
//! With street blocks, the city is cut into tiles along the B-Quadtree ([`city_tiles`]) and
//! the cluster tree built tile by tile ([`crate::cluster::tiled`]); tile jobs
//! ([`crate::tile_jobs`]) hand the pipeline their occluders and tiles' trees instead
//! ([`preprocess_with`]).

use std::path::Path;
use std::time::Instant;

use citywalk_scenes::blocks::{UrbanBlock, UrbanBlocks};
use citywalk_scenes::cluster_tree::{ClusterParams, ClusterTree};
use citywalk_scenes::ground_surfaces::GroundSurfaces;
use citywalk_scenes::occluder::Occluder;
use citywalk_scenes::occluder_draws::{OccluderArrays, OccluderArraysSpill, SpilledOccluderArrays};
use citywalk_scenes::package::{
    GpuScene, InputFile, PackageError, Provenance, ScenePackage, SceneStore,
    SpilledOccluderSection, SpilledSection, StageTiming, sha256_file,
};
use citywalk_scenes::quadtree::BQuadtree;
use citywalk_scenes::{BuildingId, City, LoadOptions};
use serde::{Deserialize, Serialize};

use crate::blocks::{BlockParams, BlockReport, build_blocks_with};
use crate::cluster::tiled::tree_above_tiles;
use crate::cluster::{ClusterError, build_cluster_tree, build_cluster_tree_tiled};
use crate::memory_budget::MemoryBudget;
use crate::occluders::{OccluderParams, build_occluders, build_occluders_into};
use crate::quadtree::build_quadtree;
use crate::tile_occluders::TileOccluders;
use crate::tiles::plan_tiles;

/// The stages, in order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    Blocks,
    Occluders,
    ClusterTree,
    Quadtree,
    /// Streets and ground areas as drawn surfaces ([`GroundSurfaces::build`]).
    GroundSurfaces,
    /// The GPU-ready scene the runtime uploads in place ([`GpuScene::build`]).
    GpuScene,
    Package,
}

impl Stage {
    pub const ALL: [Stage; 7] = [
        Stage::Blocks,
        Stage::Occluders,
        Stage::ClusterTree,
        Stage::Quadtree,
        Stage::GroundSurfaces,
        Stage::GpuScene,
        Stage::Package,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Stage::Blocks => "blocks",
            Stage::Occluders => "occluders",
            Stage::ClusterTree => "cluster tree",
            Stage::Quadtree => "quadtree",
            Stage::GroundSurfaces => "ground surfaces",
            Stage::GpuScene => "gpu scene",
            Stage::Package => "package",
        }
    }
}

/// Receives stage progress (the CLI shows progress bars; tests pass [`NoProgress`]).
pub trait ProgressSink {
    fn stage_started(&self, stage: Stage);
    fn stage_finished(&self, stage: Stage, seconds: f64, summary: &str);

    /// The parallel work so far has freed its working memory and what follows may run on
    /// other threads (or on one): where the process's allocator keeps freed memory per
    /// thread, this is the moment to have it given back. Called after every stage, and
    /// between the cluster tree's tiles and the tree above them.
    fn settle(&self) {}

    /// The resident-memory budget the cluster tree's tile jobs are admitted under
    /// ([`MemoryBudget`]); `None`: as many tiles at once as there are threads.
    fn memory_budget(&self) -> Option<&MemoryBudget> {
        None
    }
}

/// A sink that ignores progress.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoProgress;

impl ProgressSink for NoProgress {
    fn stage_started(&self, _stage: Stage) {}
    fn stage_finished(&self, _stage: Stage, _seconds: f64, _summary: &str) {}
}

/// Parameters of the whole preprocessing; stored (as JSON) in the package's provenance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PreprocessParams {
    /// How the city's inputs were read (CRS, up axis and building markers of OBJ, heights):
    /// recorded so a package says how it was made; the stages do not read it.
    pub load: LoadOptions,
    pub blocks: BlockParams,
    pub occluders: OccluderParams,
    pub cluster: ClusterParams,
    /// Run the occluder stage (Germs & Jansen).
    pub build_occluders: bool,
    /// Run the cluster-tree stage (Chang et al., Yang et al.).
    pub build_cluster_tree: bool,
    /// Without street faces: the mean block size aimed at by the cluster-tree cut.
    pub buildings_per_block: usize,
    /// The most buildings of a tile of the cluster tree's tiled build ([`plan_tiles`]); a
    /// city of no more, or without street faces, is one tile.
    #[serde(default = "default_tile_buildings")]
    pub tile_buildings: usize,
}

/// [`PreprocessParams::tile_buildings`] by default: big enough that the tree above the tiles
/// stays small (a 100k city has about 16 tiles, a 1M city about 150), small enough that
/// tiles are built on every thread.
pub const DEFAULT_TILE_BUILDINGS: usize = 16_384;

fn default_tile_buildings() -> usize {
    DEFAULT_TILE_BUILDINGS
}

impl Default for PreprocessParams {
    fn default() -> Self {
        PreprocessParams {
            load: LoadOptions::default(),
            blocks: BlockParams::default(),
            occluders: OccluderParams::default(),
            cluster: ClusterParams::default(),
            build_occluders: true,
            build_cluster_tree: true,
            buildings_per_block: 20,
            tile_buildings: DEFAULT_TILE_BUILDINGS,
        }
    }
}

/// Why preprocessing failed.
#[derive(Debug, thiserror::Error)]
pub enum PreprocessError {
    #[error("the city is invalid: {0}")]
    InvalidCity(String),
    #[error("cluster tree: {0}")]
    Cluster(#[from] ClusterError),
    #[error("package: {0}")]
    Package(#[from] PackageError),
    #[error("a scratch file: {0}")]
    Scratch(std::io::Error),
}

/// What tile jobs ([`crate::tile_jobs`]) made, which the pipeline takes instead of making
/// it: the tiles' occluders and each tile's tree ([`crate::cluster::tiled::tile_tree`]), in
/// the order of [`city_tiles`].
#[derive(Debug)]
pub struct FromTiles {
    pub occluders: Option<TileOccluders>,
    pub trees: Vec<ClusterTree>,
}

/// Runs the pipeline on `city` and returns the scene package (not yet written).
pub fn preprocess(
    city: City,
    params: &PreprocessParams,
    progress: &dyn ProgressSink,
) -> Result<ScenePackage, PreprocessError> {
    preprocess_with(city, params, progress, None, SceneStore::Memory)
}

/// A city's B-Quadtree and its tiles (each tile's buildings, [`plan_tiles`]).
pub type Tiling = (BQuadtree, Vec<Vec<u32>>);

/// The blocks of `city` and, when streets bound some of them, its quadtree and tiles
/// ([`plan_tiles`]); the one place the pipeline and the tile jobs cut a city into tiles.
pub fn city_tiles(
    city: &City,
    params: &PreprocessParams,
) -> (UrbanBlocks, BlockReport, Option<Tiling>) {
    let (blocks, report) = build_blocks_with(city, &params.blocks);
    let tiles = (report.street_blocks > 0 && !city.buildings.is_empty()).then(|| {
        let quadtree = build_quadtree(&blocks);
        let tiles = plan_tiles(&quadtree, &blocks, params.tile_buildings);
        (quadtree, tiles)
    });
    (blocks, report, tiles)
}

/// [`preprocess`], the occluders and the tiles' trees taken from `from_tiles` when given, the
/// GPU scene laid out where `store` says (a scratch file keeps the largest section out of
/// resident memory until the package is written).
pub fn preprocess_with(
    city: City,
    params: &PreprocessParams,
    progress: &dyn ProgressSink,
    from_tiles: Option<FromTiles>,
    store: SceneStore<'_>,
) -> Result<ScenePackage, PreprocessError> {
    let (mut tile_occluders, mut tile_trees) = match from_tiles {
        Some(f) => (f.occluders, Some(f.trees)),
        None => (None, None),
    };
    city.check_invariants()
        .map_err(PreprocessError::InvalidCity)?;
    let mut timings = Vec::new();
    let mut provenance = Provenance {
        tool_version: format!("citywalk {}", env!("CARGO_PKG_VERSION")),
        parameters_json: serde_json::to_string(params).unwrap_or_default(),
        ..Provenance::default()
    };
    let mut run = |stage: Stage, f: &mut dyn FnMut() -> String| {
        progress.stage_started(stage);
        let start = Instant::now();
        let summary = f();
        progress.settle();
        let seconds = start.elapsed().as_secs_f64();
        tracing::info!(stage = stage.name(), seconds, "{summary}");
        progress.stage_finished(stage, seconds, &summary);
        timings.push(StageTiming {
            stage: stage.name().into(),
            seconds,
        });
    };

    let mut blocks = UrbanBlocks::default();
    let mut block_report = BlockReport::default();
    // The quadtree the tiles were planned on and the tiles; the blocks do not change after it.
    let mut tiling = None;
    run(Stage::Blocks, &mut || {
        (blocks, block_report, tiling) = city_tiles(&city, params);
        blocks_summary(&blocks, &block_report)
    });

    // The occluder set stays in memory, or, preprocessing into a scratch folder, is spilled
    // there as it is built or, from tile jobs, read back (its section and its drawable
    // arrays, the GPU scene's): whole, the set is a gigabyte at a million buildings.
    let mut occluders = None;
    let mut occluder_arrays = None;
    let mut occluder_counts = None;
    let mut spilled = Vec::new();
    let mut spill_error = None;
    if params.build_occluders {
        run(Stage::Occluders, &mut || {
            let given = tile_occluders.take();
            let built = match store {
                SceneStore::Memory => given
                    .map_or_else(
                        || Ok(build_occluders(&city, &params.occluders)),
                        TileOccluders::into_set,
                    )
                    .map(|set| {
                        let counts = (set.occluders.len(), set.triangle_count());
                        occluders = Some(set);
                        counts
                    }),
                SceneStore::ScratchFileIn(dir) => {
                    spill_occluders(&city, &params.occluders, given, dir).map(
                        |(arrays, section, counts)| {
                            occluder_arrays = Some(arrays);
                            spilled.push(section);
                            counts
                        },
                    )
                }
            };
            match built {
                Ok(counts) => {
                    occluder_counts = Some(counts);
                    format!("{} occluders, {} triangles", counts.0, counts.1)
                }
                Err(e) => {
                    let s = format!("failed: {e}");
                    spill_error = Some(e);
                    s
                }
            }
        });
    } else {
        provenance
            .skipped_stages
            .push("occluders: disabled by the parameters".into());
    }

    let mut cluster_tree = None;
    let mut cluster_error = None;
    if params.build_cluster_tree && !city.buildings.is_empty() {
        let no_street_faces = block_report.street_blocks == 0;
        let settle = || progress.settle();
        let unlimited = MemoryBudget::unlimited();
        let budget = progress.memory_budget().unwrap_or(&unlimited);
        run(Stage::ClusterTree, &mut || {
            let result = if no_street_faces {
                let one_block = vec![0u32; city.buildings.len()];
                build_cluster_tree(&city, &one_block, &params.cluster).map(|mut tree| {
                    blocks = blocks_from_tree_cut(&city, &mut tree, params.buildings_per_block);
                    tree
                })
            } else {
                let tiles = tiling.as_ref().map_or(&[][..], |(_, tiles)| &tiles[..]);
                match tile_trees.take() {
                    Some(mut trees) if trees.len() == 1 => Ok(trees.remove(0)),
                    Some(trees) => tree_above_tiles(&city, trees, &params.cluster, &settle),
                    None => build_cluster_tree_tiled(
                        &city,
                        &blocks.block_of_building,
                        tiles,
                        &params.cluster,
                        budget,
                        &settle,
                    ),
                }
            };
            match result {
                Ok(tree) => {
                    let s = format!(
                        "{} nodes, depth {}{}{}",
                        tree.nodes.len(),
                        tree.max_depth(),
                        match &tiling {
                            Some((_, tiles)) if tiles.len() > 1 && !no_street_faces => {
                                format!(", {} tiles", tiles.len())
                            }
                            _ => String::new(),
                        },
                        if no_street_faces {
                            format!("; {} blocks from its first cut", blocks.blocks.len())
                        } else {
                            String::new()
                        }
                    );
                    cluster_tree = Some(tree);
                    s
                }
                Err(e) => {
                    let s = format!("failed: {e}");
                    cluster_error = Some(e);
                    s
                }
            }
        });
    } else if !params.build_cluster_tree {
        provenance
            .skipped_stages
            .push("cluster tree: disabled by the parameters".into());
    } else {
        provenance
            .skipped_stages
            .push("cluster tree: the city has no buildings".into());
    }
    if let Some(e) = spill_error {
        return Err(e);
    }
    if let Some(e) = cluster_error {
        return Err(e.into());
    }

    let mut quadtree = Default::default();
    run(Stage::Quadtree, &mut || {
        quadtree = match tiling.take() {
            Some((planned, _)) if block_report.street_blocks > 0 => planned,
            _ => build_quadtree(&blocks),
        };
        format!(
            "{} nodes, {} leaves, depth {}",
            quadtree.nodes.len(),
            quadtree.leaf_count(),
            quadtree.max_depth()
        )
    });

    let mut ground_surfaces = GroundSurfaces::default();
    run(Stage::GroundSurfaces, &mut || {
        ground_surfaces = GroundSurfaces::build(&city);
        format!(
            "{} draws, {} triangles from {} streets and {} ground areas; {} skipped",
            ground_surfaces.draws.len(),
            ground_surfaces.triangle_count(),
            city.streets.len(),
            city.ground_areas.len(),
            ground_surfaces.skipped.len()
        )
    });
    for skipped in &ground_surfaces.skipped {
        provenance.warnings.push(format!(
            "ground surface of {}: {}",
            skipped.source_id, skipped.reason
        ));
    }

    let mut gpu_scene = None;
    let mut scratch_error = None;
    run(Stage::GpuScene, &mut || {
        // The spilled arrays' mappings go with them once the scene is laid out.
        let spilt = occluder_arrays.take();
        let in_memory = match (&spilt, &occluders) {
            (None, Some(set)) => OccluderArrays::of(set),
            _ => OccluderArrays::default(),
        };
        let arrays = spilt.as_ref().map_or(in_memory.view(), |a| a.view());
        let scene = match GpuScene::build_in(&city, cluster_tree.as_ref(), arrays, store) {
            Ok(scene) => scene,
            Err(e) => {
                let s = format!("failed: {e}");
                scratch_error = Some(e);
                return s;
            }
        };
        let view = scene.view();
        let s = format!(
            "{} records, {} vertices, {} triangles, {} cull parts, {} MB",
            view.records.len(),
            view.vertices.len(),
            view.indices.len() / 3,
            view.parts.len(),
            scene.bytes().len() >> 20
        );
        gpu_scene = Some(scene);
        s
    });
    if let Some(e) = scratch_error {
        return Err(PreprocessError::Scratch(e));
    }
    let gpu_scene = gpu_scene.expect("the gpu scene stage ran");

    let mut inputs = Vec::new();
    run(Stage::Package, &mut || {
        inputs = city
            .report
            .files
            .iter()
            .map(|p| {
                let hashed = sha256_file(p).ok();
                InputFile {
                    path: p.display().to_string(),
                    size_bytes: hashed.as_ref().map_or(0, |h| h.0),
                    sha256: hashed.map(|h| h.1),
                }
            })
            .collect();
        format!("{} input files hashed", inputs.len())
    });

    provenance.inputs = inputs;
    let counts = &mut provenance.counts;
    let mut count = |name: &str, v: usize| {
        counts.insert(name.to_string(), v as u64);
    };
    count("buildings", city.buildings.len());
    count("streets", city.streets.len());
    count("ground_areas", city.ground_areas.len());
    count("ground_surface_triangles", ground_surfaces.triangle_count());
    count("blocks", blocks.blocks.len());
    count("block_street_faces", block_report.faces);
    count("blocks_from_streets", block_report.street_blocks);
    count("blocks_leftover_cells", block_report.leftover_blocks);
    count(
        "buildings_outside_street_faces",
        block_report.leftover_buildings,
    );
    count("street_graph_edges", block_report.graph_edges);
    count("quadtree_nodes", quadtree.nodes.len());
    count("quadtree_leaves", quadtree.leaf_count());
    count("quadtree_depth", quadtree.max_depth() as usize);
    if let Some((occluders, triangles)) = occluder_counts {
        count("occluders", occluders);
        count("occluder_triangles", triangles);
    }
    if let Some(tree) = &cluster_tree {
        count("cluster_tree_nodes", tree.nodes.len());
        count("cluster_tree_depth", tree.max_depth() as usize);
    }
    if block_report.street_blocks == 0 && !city.buildings.is_empty() {
        provenance.warnings.push(if cluster_tree.is_some() {
            "no block-bounding street faces: blocks are the first cut of the cluster tree".into()
        } else {
            format!(
                "no block-bounding street faces: blocks are grid cells of {} m",
                params.blocks.leftover_cell_m
            )
        });
    }
    provenance.load_report = city.report.clone();

    Ok(ScenePackage {
        frame: city.frame,
        buildings: city.buildings,
        streets: city.streets,
        ground_areas: city.ground_areas,
        ground_surfaces,
        blocks,
        quadtree,
        occluders,
        cluster_tree,
        cluster_textures: None,
        provenance,
        timings,
        gpu_scene,
        spilled,
    })
}

/// The occluder set spilled to scratch files in `dir` as it is built (or, from tile jobs, as
/// `given`): its drawable arrays and its section, with its numbers of occluders and triangles.
fn spill_occluders(
    city: &City,
    params: &OccluderParams,
    given: Option<TileOccluders>,
    dir: &Path,
) -> Result<(SpilledOccluderArrays, SpilledSection, (usize, usize)), PreprocessError> {
    let scratch = |e: std::io::Error| {
        let named = format!("{}: {e}", dir.display());
        PreprocessError::Scratch(std::io::Error::new(e.kind(), named))
    };
    let mut arrays = OccluderArraysSpill::new_in(dir).map_err(scratch)?;
    let mut section = SpilledOccluderSection::new_in(dir)?;
    let (mut count, mut triangles) = (0, 0);
    let mut take = |occluders: &[Occluder]| -> Result<(), PreprocessError> {
        count += occluders.len();
        triangles += occluders
            .iter()
            .map(|o| o.mesh.triangle_count())
            .sum::<usize>();
        arrays.push(occluders).map_err(scratch)?;
        Ok(section.push(occluders)?)
    };
    let per_building = match given {
        Some(tiles) => tiles.drain(&mut take)?,
        None => build_occluders_into(city, params, &mut take)?,
    };
    Ok((
        arrays.finish().map_err(scratch)?,
        section.finish(&per_building)?,
        (count, triangles),
    ))
}

fn blocks_summary(blocks: &UrbanBlocks, report: &BlockReport) -> String {
    let sizes = blocks
        .size_stats()
        .map(|(lo, med, hi)| format!("; buildings per block min {lo} / median {med} / max {hi}"))
        .unwrap_or_default();
    format!(
        "{} blocks ({} street faces of {}, {} leftover cells){sizes}",
        blocks.blocks.len(),
        report.street_blocks,
        report.faces,
        report.leftover_blocks
    )
}

/// Blocks from the shallowest cut of `tree` with at least `⌈n / per_block⌉` nodes (module
/// documentation); sets every node's `block` to the block holding all its buildings.
fn blocks_from_tree_cut(city: &City, tree: &mut ClusterTree, per_block: usize) -> UrbanBlocks {
    let n = city.buildings.len();
    let wanted = n.div_ceil(per_block.max(1)).max(1);
    let mut cut = tree.cut_at_level(0);
    for level in 1..=tree.max_depth() {
        if cut.len() >= wanted {
            break;
        }
        cut = tree.cut_at_level(level);
    }
    let mut blocks = UrbanBlocks {
        blocks: Vec::new(),
        block_of_building: vec![0; n],
    };
    for &node in &cut {
        let Some((s, e)) = tree.nodes.get(node as usize).map(|nd| nd.buildings) else {
            continue;
        };
        let mut members: Vec<BuildingId> = tree
            .building_order
            .get(s as usize..e as usize)
            .unwrap_or(&[])
            .to_vec();
        if members.is_empty() {
            continue;
        }
        members.sort_unstable();
        let index = blocks.blocks.len() as u32;
        let mut lo = [f32::MAX; 3];
        let mut hi = [f32::MIN; 3];
        for id in &members {
            blocks.block_of_building[id.index()] = index;
            let (blo, bhi) = city.buildings[id.index()].bounds();
            for k in 0..3 {
                lo[k] = lo[k].min(blo[k]);
                hi[k] = hi[k].max(bhi[k]);
            }
        }
        blocks.blocks.push(UrbanBlock {
            outline: None,
            buildings: members,
            bounds_min: lo,
            bounds_max: hi,
        });
    }
    for node in &mut tree.nodes {
        let (s, e) = node.buildings;
        let of = |b: &BuildingId| blocks.block_of_building[b.index()];
        let range = tree
            .building_order
            .get(s as usize..e as usize)
            .unwrap_or(&[]);
        let first = range.first().map(of);
        node.block = first.filter(|&f| range.iter().all(|b| of(b) == f));
    }
    blocks
}
