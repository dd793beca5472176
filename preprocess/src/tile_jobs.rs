//! Tile jobs (issue 17): a city's preprocessing cut into independent, deterministic jobs, one
//! per tile ([`crate::tiles`]), and a merge that gives the same package as one run.
//!
//! 1. **Plan** ([`plan_and_shard`]): the tiles of the city under the parameters, written as a
//!    small JSON file with the inputs (path, size, SHA-256) and the parameters, and each tile's
//!    buildings as a checksummed shard file ([`TileShard`]).
//! 2. **Tile job** ([`run_tile`]): one tile's occluders and cluster tree
//!    ([`crate::cluster::tiled::tree_of_tile`]) from its shard alone, written as a checksummed
//!    tile file ([`TileResult::write`]). Jobs need nothing of each other nor the input: they
//!    may run on other machines, each holding one tile.
//! 3. **Merge** ([`merge`]): every tile file read in turn and checked (checksum, plan, tile
//!    index, buildings), its occluders put aside in a scratch file ([`TileOccluders`]), and
//!    the pipeline run with their occluders and trees instead of making them
//!    ([`crate::pipeline::preprocess_with`]); the tree above the tiles, the GPU scene and the
//!    rest as in one run, which builds the same tiles' trees itself.
//!
//! The plan and the merge still hold the whole city and the merge every tile's tree; a job
//! holds one tile.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use citywalk_scenes::blocks::UrbanBlocks;
use citywalk_scenes::cluster_tree::ClusterTree;
use citywalk_scenes::occluder::OccluderSet;
use citywalk_scenes::package::{InputFile, ScenePackage, SceneStore};
use citywalk_scenes::{Building, BuildingId, BuildingPart, City, Frame, TriangleMesh};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::cluster::tiled::{tile_city, tree_of_tile};
use crate::occluders::build_occluders_of;
use crate::pipeline::{
    FromTiles, PreprocessError, PreprocessParams, ProgressSink, city_tiles, preprocess_with,
};
use crate::tile_occluders::{TileOccluderError, TileOccluders};

/// The plan file's format name, checked on reading.
pub const PLAN_FORMAT: &str = "citywalk tile plan 1";
/// The first bytes of a tile file.
const TILE_MAGIC: &[u8; 8] = b"CWTILE01";
/// The first bytes of a shard file.
const SHARD_MAGIC: &[u8; 8] = b"CWSHRD01";
/// A tile or shard file larger than this is refused before it is read (a 1M-building city's
/// tiles hold about 100 MB each at the default tile size).
const MAX_FRAMED_FILE_BYTES: u64 = 16 << 30;

/// The plan: what every job and the merge must agree on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TilePlan {
    pub format: String,
    /// The inputs as the plan read them; jobs check theirs against the sizes and digests.
    pub inputs: Vec<InputFile>,
    pub params: PreprocessParams,
    /// The number of buildings of each tile.
    pub tiles: Vec<u32>,
}

impl TilePlan {
    /// The plan as its file holds it.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Reads a plan file.
    pub fn read(path: &Path) -> Result<TilePlan, TileJobError> {
        let text = std::fs::read_to_string(path).map_err(|e| TileJobError::Io {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        let plan: TilePlan = serde_json::from_str(&text).map_err(|e| TileJobError::Plan {
            path: path.display().to_string(),
            reason: e.to_string(),
        })?;
        if plan.format != PLAN_FORMAT {
            return Err(TileJobError::Plan {
                path: path.display().to_string(),
                reason: format!("format {:?}, expected {PLAN_FORMAT:?}", plan.format),
            });
        }
        Ok(plan)
    }

    /// SHA-256 of the plan's JSON: the identity each tile file carries.
    pub fn digest(&self) -> String {
        use sha2::Digest;
        let hash = sha2::Sha256::digest(self.to_json().as_bytes());
        hash.iter().map(|b| format!("{b:02x}")).collect()
    }
}

/// One tile job's output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TileResult {
    /// [`TilePlan::digest`] of the plan it was made for.
    pub plan: String,
    pub tile: u32,
    /// The tile's buildings (indices into the city, ascending).
    pub buildings: Vec<u32>,
    /// The occluders of its buildings (`None` when the parameters leave occluders out).
    pub occluders: Option<OccluderSet>,
    /// Its cluster tree (`None` when the parameters leave the tree out).
    pub tree: Option<ClusterTree>,
    /// The tree's cluster meshes, by node (a package keeps them in its GPU scene, not in the
    /// tree's own encoding).
    pub meshes: Vec<TriangleMesh>,
}

/// One tile's buildings, all a tile job needs of the city.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TileShard {
    /// [`TilePlan::digest`] of the plan it was cut for.
    pub plan: String,
    pub tile: u32,
    /// The tile's buildings (indices into the city, ascending).
    pub buildings: Vec<u32>,
    /// Their blocks.
    pub blocks: Vec<u32>,
    pub frame: Frame,
    /// The tile's buildings, ids their positions here ([`tile_city`]); their parts apart, as
    /// a building's encoding leaves them out.
    pub city: Vec<Building>,
    pub parts: Vec<Vec<BuildingPart>>,
}

/// Why a tile job or the merge failed.
#[derive(Debug, thiserror::Error)]
pub enum TileJobError {
    #[error("{path}: {reason}")]
    Io { path: String, reason: String },
    #[error("tile plan {path}: {reason}")]
    Plan { path: String, reason: String },
    #[error("{path} is damaged: {reason}")]
    Damaged { path: String, reason: String },
    #[error("{0}")]
    Mismatch(String),
    #[error(
        "the city has no blocks bounded by streets, which tiles are made of; preprocess it in one run"
    )]
    NoStreetBlocks,
    #[error(transparent)]
    Preprocess(#[from] PreprocessError),
}

/// The plan of `city` (read from `inputs`) under `params`, each tile's shard written to
/// `shard_path(tile)` on the way.
pub fn plan_and_shard(
    city: &City,
    params: &PreprocessParams,
    inputs: Vec<InputFile>,
    shard_path: &dyn Fn(usize) -> PathBuf,
) -> Result<TilePlan, TileJobError> {
    let (blocks, _, tiling) = city_tiles(city, params);
    let (_, tiles) = tiling.ok_or(TileJobError::NoStreetBlocks)?;
    let plan = TilePlan {
        format: PLAN_FORMAT.into(),
        inputs,
        params: params.clone(),
        tiles: tiles.iter().map(|t| t.len() as u32).collect(),
    };
    let digest = plan.digest();
    for (t, members) in tiles.iter().enumerate() {
        let mut tile = tile_city(city, members);
        let shard = TileShard {
            plan: digest.clone(),
            tile: t as u32,
            buildings: members.clone(),
            blocks: members
                .iter()
                .map(|&i| blocks.block_of_building[i as usize])
                .collect(),
            frame: tile.frame.clone(),
            parts: tile
                .buildings
                .iter_mut()
                .map(|b| std::mem::take(&mut b.parts))
                .collect(),
            city: tile.buildings,
        };
        write_framed(&shard_path(t), SHARD_MAGIC, &shard)?;
    }
    Ok(plan)
}

/// The blocks and tiles of `city` under `plan`, checked against it (the same inputs give the
/// same tiles).
fn planned_tiles(
    city: &City,
    plan: &TilePlan,
) -> Result<(UrbanBlocks, Vec<Vec<u32>>), TileJobError> {
    let (blocks, _, tiling) = city_tiles(city, &plan.params);
    let (_, tiles) = tiling.ok_or(TileJobError::NoStreetBlocks)?;
    let sizes: Vec<u32> = tiles.iter().map(|t| t.len() as u32).collect();
    if sizes != plan.tiles {
        return Err(TileJobError::Mismatch(format!(
            "the inputs give {} tiles of {} buildings, the plan {} of {}: not the plan's inputs",
            sizes.len(),
            sizes.iter().sum::<u32>(),
            plan.tiles.len(),
            plan.tiles.iter().sum::<u32>()
        )));
    }
    Ok((blocks, tiles))
}

/// The tile job: the occluders and the cluster tree of the tile `shard` holds.
pub fn run_tile(shard: TileShard, plan: &TilePlan) -> Result<TileResult, TileJobError> {
    let digest = plan.digest();
    if shard.plan != digest {
        return Err(TileJobError::Mismatch(format!(
            "the shard of tile {} was cut for another plan",
            shard.tile
        )));
    }
    let n = shard.buildings.len();
    if shard.city.len() != n || shard.parts.len() != n || shard.blocks.len() != n {
        return Err(TileJobError::Mismatch(format!(
            "the shard of tile {} lists {n} buildings but holds {}",
            shard.tile,
            shard.city.len()
        )));
    }
    let mut buildings = shard.city;
    for (b, parts) in buildings.iter_mut().zip(shard.parts) {
        b.parts = parts;
    }
    let tile = City {
        frame: shard.frame,
        buildings,
        streets: Vec::new(),
        ground_areas: Vec::new(),
        report: Default::default(),
    };
    tile.check_invariants()
        .map_err(|e| TileJobError::Mismatch(format!("the shard of tile {}: {e}", shard.tile)))?;
    let params = &plan.params;
    let occluders = params.build_occluders.then(|| {
        let refs: Vec<&Building> = tile.buildings.iter().collect();
        let mut set = build_occluders_of(&refs, &params.occluders);
        // The city's ids, not the tile's.
        let global = |b: &mut BuildingId| *b = BuildingId(shard.buildings[b.index()]);
        set.occluders
            .iter_mut()
            .for_each(|o| global(&mut o.building));
        set.per_building
            .iter_mut()
            .for_each(|o| global(&mut o.building));
        set
    });
    let mut tree = if params.build_cluster_tree {
        Some(
            tree_of_tile(&tile, &shard.blocks, &shard.buildings, &params.cluster)
                .map_err(PreprocessError::from)?,
        )
    } else {
        None
    };
    let meshes = tree.as_mut().map_or_else(Vec::new, |t| {
        t.nodes
            .iter_mut()
            .map(|n| std::mem::take(&mut n.mesh))
            .collect()
    });
    Ok(TileResult {
        plan: digest,
        tile: shard.tile,
        buildings: shard.buildings,
        occluders,
        tree,
        meshes,
    })
}

/// The package of `city` from its tiles' results (any order, each read when the merge comes
/// to it: only one tile's occluders are held at a time, [`TileOccluders`]), as one run of
/// `plan`'s parameters makes it, its GPU scene laid out where `store` says. The tiles'
/// occluders wait in a scratch file in the store's folder (the system's temporary folder for
/// [`SceneStore::Memory`]).
pub fn merge(
    city: City,
    plan: &TilePlan,
    results: impl IntoIterator<Item = Result<(String, TileResult), TileJobError>>,
    progress: &dyn ProgressSink,
    store: SceneStore<'_>,
) -> Result<ScenePackage, TileJobError> {
    let (_, tiles) = planned_tiles(&city, plan)?;
    let digest = plan.digest();
    let scratch_dir = match store {
        SceneStore::ScratchFileIn(dir) => dir.to_path_buf(),
        SceneStore::Memory => std::env::temp_dir(),
    };
    let mut occluders = if plan.params.build_occluders {
        let scratch = |e: std::io::Error| TileJobError::Io {
            path: scratch_dir.display().to_string(),
            reason: format!("cannot hold the tiles' occluders there: {e}"),
        };
        Some(TileOccluders::new_in(&scratch_dir, city.buildings.len()).map_err(scratch)?)
    } else {
        None
    };
    let mut trees: Vec<Option<ClusterTree>> = vec![None; tiles.len()];
    let mut given = vec![false; tiles.len()];
    for read in results {
        let (path, result) = read?;
        let t = result.tile as usize;
        let fail = |reason: String| Err(TileJobError::Mismatch(format!("{path}: {reason}")));
        if result.plan != digest {
            return fail("made for another plan".into());
        }
        if t >= tiles.len() || result.buildings != tiles[t] {
            return fail(format!("tile {t} is not tile {t} of the plan"));
        }
        if std::mem::replace(&mut given[t], true) {
            return fail(format!("tile {t} given twice"));
        }
        if let Some(gathered) = occluders.as_mut() {
            let Some(set) = &result.occluders else {
                return fail(format!("tile {t} has no occluders"));
            };
            // Its outcomes for its buildings, in their order (the order they are read back).
            if !set
                .per_building
                .iter()
                .map(|o| o.building.0)
                .eq(result.buildings.iter().copied())
            {
                return fail(format!("tile {t}'s occluders are not its buildings'"));
            }
            match gathered.add(set) {
                Err(TileOccluderError::Scratch(dir, e)) => {
                    return Err(TileJobError::Io {
                        path: dir,
                        reason: format!("cannot hold the tiles' occluders there: {e}"),
                    });
                }
                Err(e) => return fail(format!("tile {t}: {e}")),
                Ok(()) => {}
            }
        }
        if let Some(mut tree) = result.tree {
            if tree.nodes.len() != result.meshes.len() {
                return fail(format!(
                    "tile {t}: {} meshes for {} nodes",
                    result.meshes.len(),
                    tree.nodes.len()
                ));
            }
            for (node, mesh) in tree.nodes.iter_mut().zip(result.meshes) {
                node.mesh = mesh;
            }
            trees[t] = Some(tree);
        }
    }
    let missing: Vec<String> = (0..tiles.len())
        .filter(|&t| !given[t])
        .map(|t| t.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(TileJobError::Mismatch(format!(
            "no tile file for tiles {}",
            missing.join(", ")
        )));
    }
    if occluders
        .as_ref()
        .is_some_and(|o| !o.covers_every_building())
    {
        return Err(TileJobError::Mismatch(
            "the tiles' occluders do not cover every building once".into(),
        ));
    }
    let trees: Vec<ClusterTree> = trees.into_iter().flatten().collect();
    if plan.params.build_cluster_tree && trees.len() != tiles.len() {
        return Err(TileJobError::Mismatch(
            "a tile file has no cluster tree".into(),
        ));
    }
    let from_tiles = FromTiles {
        occluders,
        trees: if plan.params.build_cluster_tree {
            trees
        } else {
            Vec::new()
        },
    };
    Ok(preprocess_with(
        city,
        &plan.params,
        progress,
        Some(from_tiles),
        store,
    )?)
}

impl TileResult {
    /// Writes the tile file (framed as [`write_framed`] says).
    pub fn write(&self, path: &Path) -> Result<(), TileJobError> {
        write_framed(path, TILE_MAGIC, self)
    }

    /// Reads a tile file, refusing one whose length, checksum or encoding is wrong.
    pub fn read(path: &Path) -> Result<TileResult, TileJobError> {
        read_framed(path, TILE_MAGIC)
    }
}

impl TileShard {
    /// Reads a shard file, refusing one whose length, checksum or encoding is wrong.
    pub fn read(path: &Path) -> Result<TileShard, TileJobError> {
        read_framed(path, SHARD_MAGIC)
    }
}

/// Writes `value` framed: `magic`, the payload's length (u64, little-endian), the payload
/// (postcard) and its CRC-32 (u32, little-endian).
fn write_framed<T: Serialize>(path: &Path, magic: &[u8; 8], value: &T) -> Result<(), TileJobError> {
    let io = |e: std::io::Error| TileJobError::Io {
        path: path.display().to_string(),
        reason: e.to_string(),
    };
    let payload = postcard::to_stdvec(value).map_err(|e| TileJobError::Io {
        path: path.display().to_string(),
        reason: format!("cannot encode: {e}"),
    })?;
    let mut file = std::io::BufWriter::new(std::fs::File::create(path).map_err(io)?);
    file.write_all(magic).map_err(io)?;
    file.write_all(&(payload.len() as u64).to_le_bytes())
        .map_err(io)?;
    file.write_all(&payload).map_err(io)?;
    file.write_all(&crc32fast::hash(&payload).to_le_bytes())
        .map_err(io)?;
    file.flush().map_err(io)
}

/// Reads a file [`write_framed`] wrote with `magic`, refusing one whose length, checksum or
/// encoding is wrong.
fn read_framed<T: DeserializeOwned>(path: &Path, magic: &[u8; 8]) -> Result<T, TileJobError> {
    let name = path.display().to_string();
    let damaged = |reason: &str| TileJobError::Damaged {
        path: name.clone(),
        reason: reason.into(),
    };
    let io = |e: std::io::Error| TileJobError::Io {
        path: name.clone(),
        reason: e.to_string(),
    };
    let mut file = std::fs::File::open(path).map_err(io)?;
    let size = file.metadata().map_err(io)?.len();
    if size > MAX_FRAMED_FILE_BYTES {
        return Err(damaged("larger than any tile or shard file"));
    }
    let mut head = [0u8; 16];
    file.read_exact(&mut head)
        .map_err(|_| damaged("shorter than its header"))?;
    if &head[..8] != magic {
        return Err(damaged(&format!(
            "not a citywalk {} file",
            String::from_utf8_lossy(&magic[2..6]).to_lowercase()
        )));
    }
    let length = u64::from_le_bytes(head[8..].try_into().expect("8 bytes"));
    if length.checked_add(20) != Some(size) {
        return Err(damaged(&format!(
            "{size} bytes, its header says {}",
            length.saturating_add(20)
        )));
    }
    let mut payload = vec![0u8; length as usize];
    file.read_exact(&mut payload).map_err(io)?;
    let mut crc = [0u8; 4];
    file.read_exact(&mut crc).map_err(io)?;
    if crc32fast::hash(&payload) != u32::from_le_bytes(crc) {
        return Err(damaged("checksum mismatch"));
    }
    postcard::from_bytes(&payload).map_err(|e| damaged(&format!("cannot decode: {e}")))
}
