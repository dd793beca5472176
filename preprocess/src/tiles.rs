//! The city's tiles (issue 17): whole urban blocks grouped along the B-Quadtree (Pina et al.
//! §3), so a tile's cluster tree never needs to cross a street that bounds a block, and a tile
//! is a quadrant, compact on the ground. The tiles are the largest quadtree nodes holding at
//! most a given number of buildings (a leaf's blocks are one tile however many buildings they
//! hold). A citywalk choice, the unit of the tiled build ([`crate::cluster::tiled`]).

use citywalk_scenes::blocks::UrbanBlocks;
use citywalk_scenes::quadtree::{BQuadtree, QuadNodeKind};

/// Each tile's buildings (indices, ascending), tiles in the quadtree's depth-first order; no
/// tile is empty. Buildings of blocks the quadtree does not hold (none, for a quadtree built
/// from `blocks`) form one more tile, so every building is in exactly one.
pub fn plan_tiles(
    quadtree: &BQuadtree,
    blocks: &UrbanBlocks,
    max_buildings: usize,
) -> Vec<Vec<u32>> {
    let buildings_of = |block_ids: &[u32]| -> usize {
        block_ids
            .iter()
            .map(|&b| {
                blocks
                    .blocks
                    .get(b as usize)
                    .map_or(0, |b| b.buildings.len())
            })
            .sum()
    };
    let mut tile_blocks: Vec<Vec<u32>> = Vec::new();
    let mut stack = if quadtree.nodes.is_empty() {
        Vec::new()
    } else {
        vec![0u32]
    };
    while let Some(index) = stack.pop() {
        let mut under = Vec::new();
        quadtree.collect_blocks(index, &mut under);
        match &quadtree.nodes[index as usize].kind {
            QuadNodeKind::Inner { children, .. } if buildings_of(&under) > max_buildings => {
                stack.extend(children.iter().rev());
            }
            _ => tile_blocks.push(under),
        }
    }
    let mut tile_of_block = vec![usize::MAX; blocks.blocks.len()];
    for (t, ids) in tile_blocks.iter().enumerate() {
        for &b in ids {
            if let Some(slot) = tile_of_block.get_mut(b as usize) {
                *slot = t;
            }
        }
    }
    let mut tiles: Vec<Vec<u32>> = vec![Vec::new(); tile_blocks.len() + 1];
    for (i, &block) in blocks.block_of_building.iter().enumerate() {
        let t = tile_of_block
            .get(block as usize)
            .copied()
            .filter(|&t| t != usize::MAX)
            .unwrap_or(tile_blocks.len());
        tiles[t].push(i as u32);
    }
    tiles.retain(|t| !t.is_empty());
    tiles
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blocks::{BlockParams, build_blocks_with};
    use crate::quadtree::build_quadtree;

    #[test]
    fn tiles_are_whole_blocks_of_at_most_the_limit() {
        let city = citywalk_scenes::generate::generate_city(
            &citywalk_scenes::generate::GenerateParams::new(3_000, 7),
        )
        .expect("generated city");
        let (blocks, _) = build_blocks_with(&city, &BlockParams::default());
        let quadtree = build_quadtree(&blocks);
        for limit in [1, 200, 1_000, 10_000] {
            let tiles = plan_tiles(&quadtree, &blocks, limit);
            let mut seen = vec![0u32; city.buildings.len()];
            for tile in &tiles {
                assert!(!tile.is_empty());
                assert!(tile.windows(2).all(|w| w[0] < w[1]), "ascending");
                for &b in tile {
                    seen[b as usize] += 1;
                }
                // Whole blocks: a tile holds every building of each block it touches.
                let mut tile_blocks: Vec<u32> = tile
                    .iter()
                    .map(|&b| blocks.block_of_building[b as usize])
                    .collect();
                tile_blocks.sort_unstable();
                tile_blocks.dedup();
                let whole: usize = tile_blocks
                    .iter()
                    .map(|&b| blocks.blocks[b as usize].buildings.len())
                    .sum();
                assert_eq!(
                    whole,
                    tile.len(),
                    "limit {limit}: a block split across tiles"
                );
                // Over the limit only as one quadtree leaf's blocks.
                assert!(
                    tile.len() <= limit || tile_blocks.len() == 1 || {
                        quadtree.nodes.iter().any(|n| match &n.kind {
                            QuadNodeKind::Leaf { blocks: b, .. } => {
                                let mut b = b.clone();
                                b.sort_unstable();
                                b == tile_blocks
                            }
                            _ => false,
                        })
                    }
                );
            }
            assert!(
                seen.iter().all(|&s| s == 1),
                "limit {limit}: every building once"
            );
            if limit >= city.buildings.len() {
                assert_eq!(tiles.len(), 1);
            } else {
                assert!(tiles.len() > 1, "limit {limit}: {} tiles", tiles.len());
            }
        }
    }
}
