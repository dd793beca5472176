//! Cluster-tree construction (clustering, rebalancing, hull merging, simplification, depth
//! reduction, node data and meshes) on synthetic cities of 1k / 10k / 100k buildings.
//!
//! `cargo bench -p citywalk-preprocess --bench cluster` (ten samples each; filter with
//! `-- cluster/10000` for one size, `-- cluster-stage` for the stages of a 10k city, e.g.
//! `-- cluster-stage/yang/hull-merging`).

use std::hint::black_box;

use std::time::Duration;

use citywalk_preprocess::cluster::leaves::{VertexStore, build_leaves};
use citywalk_preprocess::cluster::linkage::single_link;
use citywalk_preprocess::cluster::merge::merge_rings;
use citywalk_preprocess::cluster::rebalance::rebalance;
use citywalk_preprocess::cluster::{
    ClusterParams, assemble_nodes, build_cluster_tree, build_meshes, merge_hulls, simplify_hull,
};
use citywalk_scenes::cluster_tree::{ClusterDistance, ClusterStats, HullMerge, HullSimplify};
use citywalk_scenes::{Building, BuildingId, BuildingPart, City, Frame, HeightSource, LoadReport};
use criterion::{BatchSize, BenchmarkId, Criterion, criterion_group, criterion_main};
use geo::{LineString, MultiPolygon, Polygon};

/// A synthetic city: rows of houses with jittered sizes (a fixed LCG, no randomness crate),
/// some touching their neighbour, in blocks of 10 × 10 lots separated by 20 m streets.
pub fn synthetic_city(n: usize) -> (City, Vec<u32>) {
    let side = (n as f64).sqrt().ceil() as usize;
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut rnd = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut buildings = Vec::with_capacity(n);
    let mut blocks = Vec::with_capacity(n);
    for k in 0..n {
        let (i, j) = (k % side, k / side);
        let x = i as f64 * 15.0 + (i / 10) as f64 * 20.0;
        let y = j as f64 * 22.0 + (j / 10) as f64 * 20.0;
        let w = if rnd() < 0.3 { 15.0 } else { 8.0 + 5.0 * rnd() };
        let h = 10.0 + 8.0 * rnd();
        let ring = vec![(x, y), (x + w, y), (x + w, y + h), (x, y + h), (x, y)];
        let fp = MultiPolygon(vec![Polygon::new(LineString::from(ring), Vec::new())]);
        let top_m = 6.0 + 30.0 * rnd() as f32;
        buildings.push(Building {
            id: BuildingId(k as u32),
            source_id: format!("synthetic/{k}"),
            footprint: fp.clone(),
            parts: vec![BuildingPart {
                source_id: format!("synthetic/{k}"),
                footprint: fp,
                base_m: 0.0,
                top_m,
            }],
            base_m: 0.0,
            top_m,
            height_source: HeightSource::Tagged,
            mesh: None,
            tags: Default::default(),
        });
        blocks.push(((j / 10) * side.div_ceil(10) + i / 10) as u32);
    }
    let report = LoadReport {
        buildings_found: n,
        buildings_loaded: n,
        ..LoadReport::default()
    };
    (
        City {
            frame: Frame::local(),
            buildings,
            streets: Vec::new(),
            ground_areas: Vec::new(),
            report,
        },
        blocks,
    )
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("cluster");
    group.sample_size(10);
    for n in [1_000usize, 10_000, 100_000] {
        let (city, blocks) = synthetic_city(n);
        let params = ClusterParams::default();
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| black_box(build_cluster_tree(&city, &blocks, &params).map(|t| t.nodes.len())))
        });
    }
    group.finish();
}

/// One stage at a time on a 10k synthetic city, each fed with the previous stages' output
/// (computed once outside the timing): clustering, hull merging (the recorded merges'
/// `merge_rings` calls on their simplified children), simplification (of the recorded merged
/// rings), node data with depth reduction and balancing, and cluster meshes. Yang's and
/// Chang's parameter sets.
fn stages(c: &mut Criterion) {
    let mut group = c.benchmark_group("cluster-stage");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(3));
    group.warm_up_time(Duration::from_millis(500));
    let n = 10_000;
    let (city, blocks) = synthetic_city(n);
    let chang = ClusterParams {
        distance: ClusterDistance::ChangSizeWeighted,
        merge: HullMerge::ChangCases,
        simplify: HullSimplify::ChangSmallestArea,
        ..ClusterParams::default()
    };
    for (label, params) in [("yang", ClusterParams::default()), ("chang", chang)] {
        let mut store = VertexStore::default();
        let leaves = build_leaves(&mut store, &city.buildings);
        let single = |store: &VertexStore| {
            single_link(
                &leaves,
                &store.verts,
                &blocks,
                params.distance,
                params.adjacency_lambda,
            )
            .expect("clustering")
        };
        group.bench_function(format!("{label}/clustering"), |b| {
            b.iter(|| black_box(single(&store).len()))
        });
        let binary = single(&store);
        // Rebalancing of long heavy paths (ours, see `cluster::rebalance`), as the pipeline
        // does before hull merging; the later stages work on its merges.
        let centres: Vec<[f64; 2]> = leaves.iter().map(|l| l.centre).collect();
        group.bench_function(format!("{label}/rebalancing"), |b| {
            b.iter(|| black_box(rebalance(leaves.len(), &binary, &blocks, &centres).len()))
        });
        let merges = rebalance(leaves.len(), &binary, &blocks, &centres);
        let mut stats = ClusterStats::default();
        let hulls = merge_hulls(
            &mut store, &leaves, &merges, &blocks, &params, &mut stats, true,
        );
        // Hull merging: every merge of the tree on its recorded (simplified) children, in a
        // fresh copy of the vertex array (intersection points found again get their index).
        let store_after = store.verts.clone();
        group.bench_function(format!("{label}/hull-merging"), |b| {
            b.iter_batched(
                || {
                    let mut s = VertexStore::default();
                    for &p in &store_after {
                        s.intern(p);
                    }
                    s
                },
                |mut s| {
                    let mut total = 0usize;
                    for m in &merges {
                        let (x, y) = (&hulls.rings[m.a as usize], &hulls.rings[m.b as usize]);
                        total += merge_rings(&mut s, x, y, params.merge, params.adjacency_lambda)
                            .ring
                            .len();
                    }
                    black_box(total)
                },
                BatchSize::LargeInput,
            )
        });
        let input_edges: usize = leaves.iter().map(|l| l.ring.len()).sum();
        group.bench_function(format!("{label}/simplification"), |b| {
            b.iter(|| {
                let mut total = 0usize;
                for (ring, child_edges, a_ave) in &hulls.merged {
                    total += simplify_hull(
                        &store.verts,
                        ring,
                        *child_edges,
                        input_edges,
                        *a_ave,
                        &params,
                    )
                    .len();
                }
                black_box(total)
            })
        });
        group.bench_function(format!("{label}/node-data-balancing"), |b| {
            b.iter_batched(
                || hulls.clone(),
                |h| {
                    let assembled =
                        assemble_nodes(&city, &blocks, &store.verts, &leaves, &merges, h, &params);
                    black_box(assembled.nodes.len())
                },
                BatchSize::LargeInput,
            )
        });
        let assembled = assemble_nodes(
            &city,
            &blocks,
            &store.verts,
            &leaves,
            &merges,
            hulls.clone(),
            &params,
        );
        group.bench_function(format!("{label}/meshes"), |b| {
            b.iter_batched(
                || assembled.nodes.clone(),
                |mut ns| {
                    build_meshes(
                        &city,
                        &store.verts,
                        &assembled.building_order,
                        &assembled.plan_slack_m,
                        &mut ns,
                    );
                    black_box(ns.len())
                },
                BatchSize::LargeInput,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, bench, stages);
criterion_main!(benches);
