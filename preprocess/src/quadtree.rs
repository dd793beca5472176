//! Building the B-Quadtree over urban blocks.
//!
//! This work is based on Pina, Serón, Cerezo, *Accelerating urban scenes visualization using a
//! quadtree decomposition of urban blocks* (§3): start from the smallest rectangle bounding
//! the city; split a quadrant into four equal quadrants while it holds two or more blocks; a
//! block crossing a split goes whole to the quadrant holding the centre of its box; empty
//! quadrants are not stored; leaves keep their block's box, inner nodes the bounding sphere of
//! their descendants' boxes. The data type, keys and culling are in
//! [`citywalk_scenes::quadtree`].

use citywalk_scenes::blocks::UrbanBlocks;
use citywalk_scenes::quadtree::{Aabb, BQuadtree, MAX_DEPTH, QuadNode, QuadNodeKind};
use glam::Vec3;

/// Builds the B-Quadtree of `blocks`.
pub fn build_quadtree(blocks: &UrbanBlocks) -> BQuadtree {
    let boxes: Vec<Aabb> = blocks
        .blocks
        .iter()
        .map(|b| Aabb {
            min: b.bounds_min,
            max: b.bounds_max,
        })
        .collect();
    build_quadtree_from_boxes(boxes)
}

/// Builds the B-Quadtree of blocks given by their boxes (block `i` is `boxes[i]`).
pub fn build_quadtree_from_boxes(boxes: Vec<Aabb>) -> BQuadtree {
    let mut tree = BQuadtree {
        root_min: [0.0; 2],
        root_max: [0.0; 2],
        nodes: Vec::new(),
        block_bounds: boxes,
    };
    if tree.block_bounds.is_empty() {
        return tree;
    }
    let mut lo = [f64::MAX; 2];
    let mut hi = [f64::MIN; 2];
    for b in &tree.block_bounds {
        for k in 0..2 {
            lo[k] = lo[k].min(f64::from(b.min[k]));
            hi[k] = hi[k].max(f64::from(b.max[k]));
        }
    }
    tree.root_min = lo;
    tree.root_max = hi;
    let centres: Vec<[f64; 2]> = tree
        .block_bounds
        .iter()
        .map(|b| {
            let c = b.centre();
            [f64::from(c[0]), f64::from(c[1])]
        })
        .collect();
    let all: Vec<u32> = (0..tree.block_bounds.len() as u32).collect();
    let mut nodes = Vec::new();
    split(&tree, &centres, 1, lo, hi, all, &mut nodes);
    tree.nodes = nodes;
    tree
}

/// Appends the node for quadrant `key` (rectangle `lo..hi`) holding `blocks` and its subtree
/// in pre-order; returns its index.
fn split(
    tree: &BQuadtree,
    centres: &[[f64; 2]],
    key: u64,
    lo: [f64; 2],
    hi: [f64; 2],
    blocks: Vec<u32>,
    nodes: &mut Vec<QuadNode>,
) -> u32 {
    let index = nodes.len() as u32;
    let first = centres[blocks[0] as usize];
    let inseparable = blocks.iter().all(|&b| centres[b as usize] == first);
    if blocks.len() < 2 || inseparable || QuadNode::depth_of_key(key) >= MAX_DEPTH {
        let bounds = blocks
            .iter()
            .map(|&b| tree.block_bounds[b as usize])
            .reduce(|a, b| a.union(&b))
            .unwrap_or(Aabb {
                min: [0.0; 3],
                max: [0.0; 3],
            });
        nodes.push(QuadNode {
            key,
            kind: QuadNodeKind::Leaf { blocks, bounds },
        });
        return index;
    }
    nodes.push(QuadNode {
        key,
        kind: QuadNodeKind::Inner {
            children: Vec::new(),
            sphere_centre: [0.0; 3],
            sphere_radius: 0.0,
        },
    });
    let mid = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
    let mut quadrants: [Vec<u32>; 4] = Default::default();
    let mut union: Option<Aabb> = None;
    for &b in &blocks {
        let c = centres[b as usize];
        let q = usize::from(c[0] >= mid[0]) | (usize::from(c[1] >= mid[1]) << 1);
        quadrants[q].push(b);
        let bb = tree.block_bounds[b as usize];
        union = Some(union.map_or(bb, |u| u.union(&bb)));
    }
    let mut children = Vec::new();
    for (q, members) in quadrants.into_iter().enumerate() {
        if members.is_empty() {
            continue;
        }
        let (east, north) = (q & 1 == 1, q & 2 == 2);
        let qlo = [
            if east { mid[0] } else { lo[0] },
            if north { mid[1] } else { lo[1] },
        ];
        let qhi = [
            if east { hi[0] } else { mid[0] },
            if north { hi[1] } else { mid[1] },
        ];
        children.push(split(
            tree,
            centres,
            4 * key + q as u64,
            qlo,
            qhi,
            members,
            nodes,
        ));
    }
    // The sphere centred on the box of everything below, with radius reaching the farthest
    // corner of any block box, widened by a little more than f32 rounding so that "sphere
    // outside / inside a plane" implies the same for every box below.
    let union = union.unwrap_or(Aabb {
        min: [0.0; 3],
        max: [0.0; 3],
    });
    let centre = Vec3::from_array(union.centre());
    let mut radius = 0.0f32;
    for &b in &blocks {
        for corner in tree.block_bounds[b as usize].corners() {
            radius = radius.max(corner.distance(centre));
        }
    }
    radius += 1e-5 * (centre.abs().max_element() + radius) + 1e-3;
    nodes[index as usize].kind = QuadNodeKind::Inner {
        children,
        sphere_centre: centre.to_array(),
        sphere_radius: radius,
    };
    index
}

#[cfg(test)]
mod tests {
    use super::*;
    use citywalk_scenes::frustum::Frustum;
    use proptest::prelude::*;
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};

    fn boxes_strategy() -> impl Strategy<Value = Vec<Aabb>> {
        prop::collection::vec(
            (
                -2000.0f32..2000.0,
                -2000.0f32..2000.0,
                1.0f32..150.0,
                1.0f32..150.0,
                0.0f32..5.0,
                3.0f32..120.0,
            )
                .prop_map(|(x, y, w, h, z0, dz)| Aabb {
                    min: [x, y, z0],
                    max: [x + w, y + h, z0 + dz],
                }),
            0..200,
        )
    }

    fn runner() -> TestRunner {
        TestRunner::new_with_rng(
            Config {
                cases: 64,
                failure_persistence: None,
                ..Config::default()
            },
            TestRng::from_seed(RngAlgorithm::ChaCha, &[7; 32]),
        )
    }

    #[test]
    fn random_layouts_satisfy_the_invariants() {
        runner()
            .run(&boxes_strategy(), |boxes| {
                let n = boxes.len();
                let tree = build_quadtree_from_boxes(boxes);
                prop_assert_eq!(tree.check_invariants(), Ok(()));
                // One leaf per block unless centres coincide.
                prop_assert!(tree.leaf_count() <= n);
                Ok(())
            })
            .expect("quadtree invariants");
    }

    #[test]
    fn coincident_and_duplicate_blocks_share_a_leaf() {
        let b = Aabb {
            min: [0.0, 0.0, 0.0],
            max: [10.0, 10.0, 5.0],
        };
        let c = Aabb {
            min: [100.0, 0.0, 0.0],
            max: [110.0, 10.0, 5.0],
        };
        let tree = build_quadtree_from_boxes(vec![b, b, c]);
        assert_eq!(tree.check_invariants(), Ok(()));
        assert_eq!(tree.leaf_count(), 2);
    }

    #[test]
    fn broken_trees_are_caught() {
        let boxes: Vec<Aabb> = (0..20)
            .map(|i| {
                let x = (i * 37 % 200) as f32 * 10.0;
                let y = (i * 91 % 200) as f32 * 10.0;
                Aabb {
                    min: [x, y, 0.0],
                    max: [x + 5.0, y + 5.0, 10.0],
                }
            })
            .collect();
        let good = build_quadtree_from_boxes(boxes);
        assert_eq!(good.check_invariants(), Ok(()));
        let mut small_sphere = good.clone();
        if let QuadNodeKind::Inner { sphere_radius, .. } = &mut small_sphere.nodes[0].kind {
            *sphere_radius *= 0.5;
        }
        assert!(small_sphere.check_invariants().is_err());
        let mut lost_block = good.clone();
        let leaf = lost_block
            .nodes
            .iter_mut()
            .find_map(|n| match &mut n.kind {
                QuadNodeKind::Leaf { blocks, .. } => Some(blocks),
                QuadNodeKind::Inner { .. } => None,
            })
            .expect("a leaf");
        leaf[0] = (leaf[0] + 1) % 20;
        assert!(lost_block.check_invariants().is_err());
        let mut bad_key = good;
        bad_key.nodes[1].key += 100;
        assert!(bad_key.check_invariants().is_err());
    }

    #[test]
    fn hierarchical_culling_equals_brute_force_on_random_frustums() {
        let strategy = (
            boxes_strategy(),
            (-2500.0f32..2500.0, -2500.0f32..2500.0, 1.5f32..400.0),
            (0.0f32..std::f32::consts::TAU, -1.2f32..0.3),
            (0.3f32..2.0, 0.5f32..2.5, any::<bool>()),
        );
        runner()
            .run(
                &strategy,
                |(boxes, (x, y, z), (yaw, pitch), (fov, aspect, reversed))| {
                    let tree = build_quadtree_from_boxes(boxes);
                    let eye = Vec3::new(x, y, z);
                    let dir = Vec3::new(
                        yaw.cos() * pitch.cos(),
                        yaw.sin() * pitch.cos(),
                        pitch.sin(),
                    );
                    let view = glam::camera::rh::view::look_at_mat4(eye, eye + dir, Vec3::Z);
                    let proj = if reversed {
                        glam::camera::rh::proj::directx::perspective_infinite_reverse(
                            fov, aspect, 0.5,
                        )
                    } else {
                        glam::camera::rh::proj::directx::perspective(fov, aspect, 0.5, 1500.0)
                    };
                    let frustum = Frustum::from_view_proj(proj * view);
                    let mut hierarchical = tree.cull(&frustum);
                    hierarchical.sort_unstable();
                    prop_assert_eq!(hierarchical, tree.cull_brute_force(&frustum));
                    Ok(())
                },
            )
            .expect("culling equals brute force");
    }
}
