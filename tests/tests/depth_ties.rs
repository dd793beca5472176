//! Coplanar faces of two buildings: the same one wins the depth test whatever the order they are
//! drawn in (`tie_broken_clip` in `shaders/wgsl/shared/scene.wgsl`), in the colour pass and in
//! the oracle's id pass alike. Culling changes the draw order from frame to frame; before the
//! tie rule such faces flickered and the culling modes differed from brute force there.

use citywalk_runtime::camera::Camera;
use citywalk_runtime::oracle::Oracle;
use citywalk_runtime::render::BruteRenderer;
use citywalk_runtime::scene_gpu::{SceneGeometry, SceneGpu};
use citywalk_shaders::{ID_OFFSET, depth_tie_factor};
use citywalk_tests::city_builder::boxes;
use citywalk_tests::gpu::gpu_or_skip;
use glam::Vec3;

/// Two buildings on one footprint with one height, every face of one coplanar with the other's
/// (an OSM building mapped twice), and a third overlapping them with the same roof height.
fn twins() -> citywalk_scenes::City {
    boxes(&[
        (0.0, 0.0, 20.0, 15.0, 12.0),
        (0.0, 0.0, 20.0, 15.0, 12.0),
        (10.0, 5.0, 30.0, 25.0, 12.0),
    ])
}

/// The scene of `twins`, its buildings drawn in the order `order` (indices of its records).
fn scene_in_order(gpu: &citywalk_runtime::gpu::GpuContext, order: &[usize]) -> SceneGpu {
    let mut geometry = SceneGeometry::from_city(&twins());
    let records = geometry.records.clone();
    geometry.records = order.iter().map(|&i| records[i]).collect();
    SceneGpu::upload(gpu, &geometry).expect("the scene fits the GPU")
}

#[test]
fn coplanar_buildings_look_the_same_in_every_draw_order() {
    let Some(gpu) = gpu_or_skip("coplanar_buildings_look_the_same_in_every_draw_order") else {
        return;
    };
    // South-west of the buildings, above their roofs, looking at them: walls and roofs tie.
    let camera = Camera::new(
        Vec3::new(-30.0, -40.0, 30.0),
        50f32.to_radians(),
        -25f32.to_radians(),
    );
    let (w, h) = (160, 120);
    let oracle = Oracle::new(&gpu);
    let renderer = BruteRenderer::new(&gpu, BruteRenderer::PNG_FORMAT);
    let orders: [&[usize]; 3] = [&[0, 1, 2], &[2, 1, 0], &[1, 2, 0]];
    let frames: Vec<(Vec<u32>, Vec<u8>)> = orders
        .iter()
        .map(|order| {
            let scene = scene_in_order(&gpu, order);
            let ids = oracle
                .id_image(&gpu, &scene, &camera, w, h)
                .expect("id pass");
            let rgba = renderer
                .render_rgba(&gpu, &scene, &camera, w, h)
                .expect("render");
            (ids.pixels, rgba)
        })
        .collect();
    for (order, frame) in orders.iter().zip(&frames).skip(1) {
        let ids_differ = frame.0.iter().zip(&frames[0].0).filter(|(a, b)| a != b);
        assert_eq!(ids_differ.count(), 0, "id image, order {order:?}");
        let px_differ = frame
            .1
            .chunks(4)
            .zip(frames[0].1.chunks(4))
            .filter(|(a, b)| a != b);
        assert_eq!(px_differ.count(), 0, "colour, order {order:?}");
    }
    // Of the twins, only the one whose depth is pushed less is seen.
    let seen = |id: u32| frames[0].0.iter().filter(|&&p| p == id + ID_OFFSET).count();
    let (near, far) = if depth_tie_factor(0) > depth_tie_factor(1) {
        (0, 1)
    } else {
        (1, 0)
    };
    assert!(seen(near) > 500, "{} pixels of the nearer twin", seen(near));
    assert_eq!(seen(far), 0, "the farther twin shows");
    assert!(seen(2) > 100, "{} pixels of the third building", seen(2));
}
