//! Urban blocks: the groups of buildings that the street network encloses.
//!
//! Pina et al., *Accelerating urban scenes visualization using a quadtree decomposition of
//! urban blocks* (§2–3): an urban block is a face of the street graph; every building belongs
//! to exactly one block. The blocks are the leaves of the B-Quadtree ([`crate::quadtree`]) and
//! the first cut of the cluster tree. Built by `citywalk_preprocess::blocks::build_blocks`.

use serde::{Deserialize, Serialize};

use crate::city::BuildingId;

/// One urban block.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct UrbanBlock {
    /// The face of the street network that bounds the block, in the local frame; `None` for a
    /// block that is not a street face (a leftover region, a fallback grid cell, a cluster).
    pub outline: Option<geo::Polygon<f64>>,
    /// The buildings of the block, ascending.
    pub buildings: Vec<BuildingId>,
    /// Axis-aligned bounds of the block's buildings (local frame, metres).
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
}

impl UrbanBlock {
    /// Centre of the block's bounding box.
    pub fn centre(&self) -> [f32; 3] {
        [
            0.5 * (self.bounds_min[0] + self.bounds_max[0]),
            0.5 * (self.bounds_min[1] + self.bounds_max[1]),
            0.5 * (self.bounds_min[2] + self.bounds_max[2]),
        ]
    }
}

/// The partition of a city's buildings into urban blocks.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct UrbanBlocks {
    pub blocks: Vec<UrbanBlock>,
    /// For each building (by [`BuildingId`] index), the index of its block in `blocks`.
    pub block_of_building: Vec<u32>,
}

impl UrbanBlocks {
    /// Checks that every building of a city of `building_count` buildings is in exactly one
    /// block, that `block_of_building` agrees with the blocks' lists, that no block is empty,
    /// and that bounds are ordered and finite. Returns the first violation found.
    pub fn check_invariants(&self, building_count: usize) -> Result<(), String> {
        if self.block_of_building.len() != building_count {
            return Err(format!(
                "block_of_building has {} entries for {} buildings",
                self.block_of_building.len(),
                building_count
            ));
        }
        let mut seen = vec![false; building_count];
        for (bi, block) in self.blocks.iter().enumerate() {
            if block.buildings.is_empty() {
                return Err(format!("block {bi} is empty"));
            }
            if !block.buildings.windows(2).all(|w| w[0] < w[1]) {
                return Err(format!("block {bi}: buildings are not strictly ascending"));
            }
            for axis in 0..3 {
                let (lo, hi) = (block.bounds_min[axis], block.bounds_max[axis]);
                if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                    return Err(format!("block {bi}: bad bounds on axis {axis}"));
                }
            }
            for id in &block.buildings {
                let i = id.index();
                if i >= building_count {
                    return Err(format!("block {bi}: building {i} out of range"));
                }
                if seen[i] {
                    return Err(format!("building {i} is in more than one block"));
                }
                seen[i] = true;
                if self.block_of_building[i] as usize != bi {
                    return Err(format!(
                        "building {i} is listed in block {bi} but block_of_building says {}",
                        self.block_of_building[i]
                    ));
                }
            }
        }
        if let Some(i) = seen.iter().position(|s| !s) {
            return Err(format!("building {i} is in no block"));
        }
        Ok(())
    }

    /// Buildings per block: `(min, median, max)`, or `None` without blocks.
    pub fn size_stats(&self) -> Option<(usize, usize, usize)> {
        let mut sizes: Vec<usize> = self.blocks.iter().map(|b| b.buildings.len()).collect();
        sizes.sort_unstable();
        Some((*sizes.first()?, sizes[sizes.len() / 2], *sizes.last()?))
    }
}
