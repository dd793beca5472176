//! Urban blocks, the B-Quadtree, hierarchical frustum culling and the scene package on
//! generated cities (`citywalk_scenes::generate`) of 10k buildings.
//!
//! `cargo bench -p citywalk-preprocess --bench blocks` (filter with `-- blocks/` etc.).

use std::hint::black_box;

use citywalk_preprocess::blocks::build_blocks;
use citywalk_preprocess::pipeline::{NoProgress, PreprocessParams, preprocess};
use citywalk_preprocess::quadtree::build_quadtree;
use citywalk_scenes::frustum::Frustum;
use citywalk_scenes::generate::{GenerateParams, generate_city};
use citywalk_scenes::package::{ScenePackage, WriteOptions};
use criterion::{Criterion, criterion_group, criterion_main};
use glam::Vec3;

fn bench(c: &mut Criterion) {
    let city = generate_city(&GenerateParams {
        buildings: 10_000,
        seed: 1,
        ..GenerateParams::default()
    })
    .expect("generate");
    let mut group = c.benchmark_group("blocks");
    group.sample_size(10);
    group.bench_function("build_blocks/10000", |b| {
        b.iter(|| build_blocks(black_box(&city)))
    });
    let blocks = build_blocks(&city);
    group.bench_function("build_quadtree/10000", |b| {
        b.iter(|| build_quadtree(black_box(&blocks)))
    });
    let tree = build_quadtree(&blocks);
    let (lo, hi) = city.bounds().expect("bounds");
    let frustums: Vec<Frustum> = (0..64)
        .map(|k| {
            let t = k as f32 / 64.0;
            let eye = Vec3::new(
                lo.x + (hi.x - lo.x) * t,
                lo.y + (hi.y - lo.y) * (1.0 - t),
                1.7,
            );
            let yaw = t * std::f32::consts::TAU * 3.0;
            let view = glam::camera::rh::view::look_to_mat4(
                eye,
                Vec3::new(yaw.cos(), yaw.sin(), 0.0),
                Vec3::Z,
            );
            let proj = glam::camera::rh::proj::directx::perspective_infinite_reverse(1.0, 1.6, 0.3);
            Frustum::from_view_proj(proj * view)
        })
        .collect();
    group.bench_function("cull_hierarchical/64_frustums", |b| {
        b.iter(|| frustums.iter().map(|f| tree.cull(f).len()).sum::<usize>())
    });
    group.bench_function("cull_brute_force/64_frustums", |b| {
        b.iter(|| {
            frustums
                .iter()
                .map(|f| tree.cull_brute_force(f).len())
                .sum::<usize>()
        })
    });
    let params = PreprocessParams {
        build_occluders: false,
        build_cluster_tree: false,
        ..PreprocessParams::default()
    };
    let pkg = preprocess(city.clone(), &params, &NoProgress).expect("preprocess");
    let bytes = pkg.to_bytes(WriteOptions::default()).expect("encode");
    group.bench_function("package_encode/10000", |b| {
        b.iter(|| pkg.to_bytes(WriteOptions::default()).map(|v| v.len()))
    });
    group.bench_function("package_decode/10000", |b| {
        b.iter(|| ScenePackage::from_bytes(black_box(&bytes)).map(|p| p.buildings.len()))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
