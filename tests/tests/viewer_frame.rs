//! The viewer's frame without a window (`engine::viewer::draw::FrameDrawer`), on a generated,
//! preprocessed city: at street level (the viewer's walk start) every culling path gives the
//! brute-force image and reports the counts of the stages that ran, with buildings really
//! culled; from the overview camera a coarse LOD cut draws clusters and fewer triangles through
//! both LOD paths; every debug view replaces or tints the frame and says what it shows.

use citywalk_preprocess::pipeline::{NoProgress, PreprocessParams, preprocess};
use citywalk_runtime::camera::Camera;
use citywalk_runtime::controller::{CameraRig, CollisionWorld, Mode};
use citywalk_runtime::render::BruteRenderer;
use citywalk_runtime::render::targets::OffscreenTarget;
use citywalk_scenes::generate::{GenerateParams, generate_city};
use citywalk_tests::gpu::gpu_or_skip;
use citywalk_viewer::draw::{Drawn, FrameDrawer};
use citywalk_viewer::settings::SceneFeatures;
use citywalk_viewer::{DebugView, FramePlan, RenderSettings, ViewerScene};
use glam::Vec3;

const SIZE: (u32, u32) = (192, 120);

/// Share of pixels that differ between two RGBA frames.
fn differing_share(a: &[u8], b: &[u8]) -> f64 {
    let n = a
        .chunks_exact(4)
        .zip(b.chunks_exact(4))
        .filter(|(p, q)| p != q)
        .count();
    n as f64 / (a.len() / 4) as f64
}

#[test]
fn every_stage_combination_and_debug_view_renders_and_reports_its_counts() {
    let Some(gpu) = gpu_or_skip("viewer_frame") else {
        return;
    };
    let city = generate_city(&GenerateParams::new(300, 11)).expect("generate");
    let package = preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess");
    let scene = ViewerScene {
        city: package.city(),
        cluster_tree: package.cluster_tree.clone(),
        blocks: Some((package.blocks.clone(), package.quadtree.clone())),
        // As `citywalk view` opens a package: the geometry uploaded from its GPU section.
        gpu_scene: Some(package.gpu_scene.clone()),
        ground_surfaces: Some(package.ground_surfaces.clone()),
    };
    let features = scene.features();
    assert_eq!(
        features,
        SceneFeatures {
            occluders: true,
            cluster_tree: true,
            quadtree: true
        },
        "a package brings every structure"
    );
    let n = scene.city.buildings.len() as u32;
    let (lo, hi) = scene.city.buildings.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), b| {
            let (a, c) = b.bounds();
            (lo.min(a), hi.max(c))
        },
    );
    let overview = Camera::overview(lo, hi);
    let street = CameraRig::for_city(
        &scene.city,
        &CollisionWorld::from_city(&scene.city),
        Mode::Walk,
    )
    .camera();
    let format = BruteRenderer::PNG_FORMAT;
    let mut drawer = FrameDrawer::new(&gpu, format, scene).expect("the scene fits the GPU");
    drawer.wait_for_reports = true;
    let target = OffscreenTarget::new(&gpu, SIZE.0, SIZE.1, format).expect("target");
    let mut frame = |settings: &RenderSettings, camera: &Camera| -> (Drawn, Vec<u8>) {
        let drawn = drawer
            .draw(
                &gpu,
                &target.colour_view,
                &target.depth,
                SIZE,
                camera,
                settings,
                features,
            )
            .expect("frame");
        (drawn, target.read_colour(&gpu).expect("read the frame"))
    };
    let with = |stages: FramePlan| RenderSettings {
        stages,
        auto: false,
        ..RenderSettings::default()
    };

    let (brute, brute_image) = frame(&with(FramePlan::NONE), &street);
    let (brute_above, brute_above_image) = frame(&with(FramePlan::NONE), &overview);
    assert_eq!(brute.counts.renderer, FramePlan::NONE.describe());
    assert_eq!(brute.counts.buildings_drawn, n);
    assert_eq!(brute.counts.frustum_culled, None);
    assert_eq!(brute.counts.occlusion_culled, None);
    assert_eq!(brute.ids.len() as u32, n);

    let frustum_only = FramePlan {
        frustum: true,
        ..FramePlan::NONE
    };
    let hzb = FramePlan {
        lod: false,
        ..FramePlan::ALL
    };
    let ungated = FramePlan {
        occluder_gate: false,
        ..hzb
    };
    for stages in [frustum_only, hzb, ungated] {
        // Twice: the HZB frame starts from last frame's visible set the second time.
        for _ in 0..2 {
            let (drawn, image) = frame(&with(stages), &street);
            let c = &drawn.counts;
            let share = differing_share(&brute_image, &image);
            assert!(
                share < 0.01,
                "{}: {:.2} % of pixels differ",
                c.renderer,
                share * 100.0
            );
            assert!(c.buildings_drawn < n && c.buildings_drawn > 0, "{c:?}");
            assert!(c.frustum_culled.is_some_and(|k| k > 0), "{c:?}");
            assert!(
                c.triangles > 0 && c.draw_calls > 0 && c.cpu_ms > 0.0,
                "{c:?}"
            );
            assert_eq!(c.occlusion_culled.is_some(), stages.hzb, "{c:?}");
            assert_eq!(c.occluders_drawn.is_some(), stages.hzb, "{c:?}");
            assert_eq!(
                c.gate_culled.is_some(),
                stages.hzb && stages.occluder_gate,
                "{c:?}"
            );
            if stages.hzb {
                assert!(c.occlusion_culled.is_some_and(|k| k > 0), "{c:?}");
            }
        }
    }

    // A coarse cut (Chang ε = 10⁵, τ = 100) draws clusters and fewer triangles, alone and as
    // the HZB frame's candidates.
    let mut coarse = with(FramePlan::ALL);
    coarse.lod.epsilon_px = 1e5;
    coarse.lod.tau_px = 100.0;
    let lod_alone = RenderSettings {
        stages: FramePlan {
            lod: true,
            frustum: true,
            ..FramePlan::NONE
        },
        ..coarse
    };
    for settings in [lod_alone, coarse] {
        let (drawn, image) = frame(&settings, &overview);
        let c = &drawn.counts;
        assert!(drawn.lod_scene, "{c:?}");
        assert!(c.clusters_drawn.is_some_and(|k| k > 0), "{c:?}");
        assert!(
            drawn.ids.iter().any(|&id| id >= n),
            "cluster draw ids follow the buildings"
        );
        assert!(c.triangles < brute_above.counts.triangles, "{c:?}");
        assert!(
            differing_share(&brute_above_image, &image) > 0.0,
            "{}",
            c.renderer
        );
    }

    // Debug views: the pyramid and cluster views replace the frame, the occluder view tints it.
    for (view, min_share, max_share, says) in [
        (DebugView::Pyramid, 0.5, 1.0, "pyramid level 2"),
        (DebugView::Clusters, 0.5, 1.0, "entries coloured"),
        (DebugView::Occluders, 0.001, 0.95, "selected"),
    ] {
        let settings = RenderSettings {
            debug_view: view,
            mip_level: 2,
            ..with(hzb)
        };
        let (drawn, image) = frame(&settings, &street);
        let share = differing_share(&brute_image, &image);
        assert!(
            (min_share..=max_share).contains(&share),
            "{}: {:.1} % of pixels changed",
            view.name(),
            share * 100.0
        );
        let debug = drawn.counts.debug.clone().unwrap_or_default();
        assert!(debug.contains(says), "{}: {debug:?}", view.name());
        if view == DebugView::Occluders {
            // The occluders highlighted are the ones the frame drew into its pyramid.
            let drawn_by_frame = drawn.counts.occluders_drawn.unwrap_or(0);
            assert!(drawn_by_frame > 0, "{:?}", drawn.counts);
            assert!(
                debug.contains(&format!(", {drawn_by_frame} selected")),
                "{debug:?} vs {drawn_by_frame} occluders drawn"
            );
        }
    }
}

/// Picking in the viewer's frame (`FrameDrawer::pick`): a click lands on the building the frame
/// shows under the cursor, not the one hidden behind it, nor anything in the sky; the picked
/// building is tinted in the next frame and nothing else changes.
#[test]
fn a_click_picks_the_building_under_the_cursor_and_tints_it() {
    let Some(gpu) = gpu_or_skip("viewer_frame pick") else {
        return;
    };
    // Two buildings on the view axis (east), the far one taller, and one off to the side.
    let city = citywalk_tests::city_builder::boxes(&[
        (20.0, -5.0, 30.0, 5.0, 10.0),
        (50.0, -5.0, 60.0, 5.0, 25.0),
        (20.0, 40.0, 30.0, 50.0, 10.0),
    ]);
    let scene = ViewerScene {
        city,
        cluster_tree: None,
        blocks: None,
        // A raw input: the viewer meshes it and keeps the arrays for picking.
        gpu_scene: None,
        ground_surfaces: None,
    };
    let features = scene.features();
    let format = BruteRenderer::PNG_FORMAT;
    let mut drawer = FrameDrawer::new(&gpu, format, scene).expect("the scene fits the GPU");
    drawer.wait_for_reports = true;
    let target = OffscreenTarget::new(&gpu, SIZE.0, SIZE.1, format).expect("target");
    let camera = Camera::new(Vec3::new(0.0, 0.0, 5.0), 0.0, 0.0);
    let settings = RenderSettings {
        stages: FramePlan::NONE,
        auto: false,
        ..RenderSettings::default()
    };
    let frame = |drawer: &mut FrameDrawer| -> Vec<u8> {
        drawer
            .draw(
                &gpu,
                &target.colour_view,
                &target.depth,
                SIZE,
                &camera,
                &settings,
                features,
            )
            .expect("frame");
        target.read_colour(&gpu).expect("read the frame")
    };
    let before = frame(&mut drawer);
    let (w, h) = (SIZE.0 as f32, SIZE.1 as f32);
    let centre = drawer
        .pick(&camera, SIZE, (w / 2.0, h / 2.0))
        .expect("a hit");
    assert_eq!(centre.draw, 0);
    assert!((centre.distance_m - 20.0).abs() < 0.5, "{centre:?}");
    // Above the near building's roof: the taller one behind it.
    let above = drawer
        .pick(&camera, SIZE, (w / 2.0, h * 0.2))
        .expect("a hit");
    assert_eq!(above.draw, 1);
    // The sky.
    assert_eq!(drawer.pick(&camera, SIZE, (w / 2.0, 1.0)), None);
    let (bounds, covered) = drawer.draw_facts(0);
    assert_eq!(bounds.1[2], 10.0);
    assert!(covered.is_empty());
    assert_eq!(
        drawer.city().buildings.len(),
        3,
        "a raw input keeps its tags for the panel"
    );

    drawer.set_highlight(Some(centre.draw));
    let tinted = frame(&mut drawer);
    let changed = differing_share(&before, &tinted);
    assert!(changed > 0.02, "the picked building is tinted ({changed})");
    // The pixel at the centre turned amber: more red than blue.
    let at = ((SIZE.1 / 2 * SIZE.0 + SIZE.0 / 2) * 4) as usize;
    assert!(
        tinted[at] > tinted[at + 2] + 40,
        "{:?}",
        &tinted[at..at + 4]
    );
    drawer.set_highlight(None);
    assert_eq!(differing_share(&before, &frame(&mut drawer)), 0.0);
}
