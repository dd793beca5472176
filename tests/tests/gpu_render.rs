//! GPU rendering tests: the brute-force renderer against a golden image, and sanity checks of
//! the frame's content.

use citywalk_runtime::camera::Camera;
use citywalk_runtime::render::BruteRenderer;
use citywalk_runtime::scene_gpu::SceneGpu;
use citywalk_tests::city_builder::boxes;
use citywalk_tests::gpu::{assert_matches_golden, gpu_or_skip};
use glam::Vec3;

/// A few boxes of different heights around a little square.
fn small_town() -> citywalk_scenes::City {
    boxes(&[
        (0.0, 0.0, 20.0, 15.0, 12.0),
        (30.0, 0.0, 45.0, 25.0, 30.0),
        (0.0, 25.0, 15.0, 45.0, 6.0),
        (25.0, 35.0, 50.0, 50.0, 18.0),
        (60.0, 10.0, 70.0, 20.0, 45.0),
    ])
}

fn town_camera() -> Camera {
    // South-west of the town, 25 m up, looking north-east and slightly down.
    Camera::new(
        Vec3::new(-40.0, -50.0, 25.0),
        45f32.to_radians(),
        -12f32.to_radians(),
    )
}

/// Golden image of the small town at an odd size (rows not a multiple of the copy alignment).
/// Tolerance: per-channel difference ≤ 8 on ≥ 99.5 % of pixels; the golden was set on lavapipe
/// (llvmpipe, Mesa 22.3.6, Vulkan). Regenerate with `CITYWALK_UPDATE_GOLDEN=1`.
#[test]
fn small_town_matches_golden() {
    let Some(gpu) = gpu_or_skip("small_town_matches_golden") else {
        return;
    };
    let scene = SceneGpu::upload_city(&gpu, &small_town()).expect("the scene fits the GPU");
    let renderer = BruteRenderer::new(&gpu, BruteRenderer::PNG_FORMAT);
    let (w, h) = (161, 97);
    let rgba = renderer
        .render_rgba(&gpu, &scene, &town_camera(), w, h)
        .expect("render");
    let image = image::RgbaImage::from_raw(w, h, rgba).expect("size");
    assert_matches_golden("small_town_161x97.png", &image, 8, 0.995);
}

/// The frame has sky at the top, ground at the bottom corners and lit buildings in between,
/// and buildings differ in colour.
#[test]
fn frame_shows_sky_ground_and_buildings() {
    let Some(gpu) = gpu_or_skip("frame_shows_sky_ground_and_buildings") else {
        return;
    };
    let scene = SceneGpu::upload_city(&gpu, &small_town()).expect("the scene fits the GPU");
    let renderer = BruteRenderer::new(&gpu, BruteRenderer::PNG_FORMAT);
    let (w, h) = (320, 180);
    let camera = Camera::new(Vec3::new(-60.0, -70.0, 8.0), 45f32.to_radians(), 0.0);
    let rgba = renderer
        .render_rgba(&gpu, &scene, &camera, w, h)
        .expect("render");
    let image = image::RgbaImage::from_raw(w, h, rgba).expect("size");
    let sky = image.get_pixel(w / 2, 0).0;
    let ground = image.get_pixel(2, h - 1).0;
    assert!(sky[2] > sky[0] && sky[2] > 150, "sky pixel {sky:?}");
    assert!(
        ground[1] >= ground[2] && ground[1] < 160,
        "ground pixel {ground:?}"
    );
    let distinct: std::collections::BTreeSet<[u8; 4]> = image
        .pixels()
        .map(|p| p.0)
        .filter(|p| *p != sky && p[2] <= p[0].max(p[1]))
        .collect();
    assert!(
        distinct.len() > 10,
        "only {} building colours",
        distinct.len()
    );
    // Looking straight away from the town shows no building: sky above the horizon, ground below.
    let away = Camera::new(camera.position, 225f32.to_radians(), 0.0);
    let rgba = renderer
        .render_rgba(&gpu, &scene, &away, w, h)
        .expect("render");
    let image = image::RgbaImage::from_raw(w, h, rgba).expect("size");
    for y in [0, h / 4, 3 * h / 4, h - 1] {
        let row: std::collections::BTreeSet<[u8; 4]> =
            (0..w).map(|x| image.get_pixel(x, y).0).collect();
        assert!(
            row.len() <= 3,
            "row {y} has {} colours: a building?",
            row.len()
        );
    }
}

/// Issue 14 (GPU faults): a city whose arrays exceed the GPU's storage binding limit is refused
/// at upload with an error naming the array and the limit, instead of a wgpu panic when a
/// frame's bind group binds it. The adapter's own device, whose limit the city is within,
/// draws it.
#[test]
fn a_city_past_the_storage_binding_limit_is_an_error_naming_the_array() {
    use citywalk_runtime::drawable::DrawableScene;
    use citywalk_runtime::gpu::GpuContext;
    use citywalk_scenes::generate::{GenerateParams, generate_city};

    let Some(gpu) = gpu_or_skip("a_city_past_the_storage_binding_limit") else {
        return;
    };
    let mut limits = gpu.adapter.limits();
    limits.max_storage_buffer_binding_size = 16 << 10;
    let small = GpuContext::headless_with_limits(limits).expect("a device with lower limits");
    assert_eq!(
        small.device.limits().max_storage_buffer_binding_size,
        16 << 10
    );
    // 2,000 buildings: their cull parts and records are about 100 kB each.
    let city = generate_city(&GenerateParams::new(2000, 3)).expect("generate");
    let error = DrawableScene::upload_city(&small, &city, None, None)
        .expect_err("over the storage binding limit");
    let text = error.to_string();
    assert!(
        text.contains("building") && text.contains("max_storage_buffer_binding_size of 16384"),
        "{text}"
    );
    assert!(
        small.lost().is_none(),
        "a refused upload leaves the device working"
    );
    DrawableScene::upload_city(&gpu, &city, None, None).expect("within the adapter's limits");
}
