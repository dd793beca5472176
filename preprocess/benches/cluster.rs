//! Cluster-tree construction (clustering, hull merging, simplification, depth reduction, node
//! data and meshes) on synthetic cities of 1k / 10k / 100k buildings.
//!
//! `cargo bench -p citywalk-preprocess --bench cluster` (ten samples each; filter with
//! `-- cluster/10000` for one size).

use std::collections::BTreeMap;
use std::hint::black_box;

use citywalk_preprocess::cluster::{ClusterParams, build_cluster_tree};
use citywalk_scenes::{Building, BuildingId, BuildingPart, City, Frame, HeightSource, LoadReport};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
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
            tags: BTreeMap::new(),
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

criterion_group!(benches, bench);
criterion_main!(benches);
