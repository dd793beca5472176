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
        package: None,
        cluster_textures: None,
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
/// building is tinted and outlined in the next frame and nothing else changes.
#[test]
fn a_click_picks_the_building_under_the_cursor_and_tints_and_outlines_it() {
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
        package: None,
        cluster_textures: None,
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
    let frame_of = |drawer: &mut FrameDrawer, settings: &RenderSettings| -> Vec<u8> {
        drawer
            .draw(
                &gpu,
                &target.colour_view,
                &target.depth,
                SIZE,
                &camera,
                settings,
                features,
            )
            .expect("frame");
        target.read_colour(&gpu).expect("read the frame")
    };
    let frame = |drawer: &mut FrameDrawer| frame_of(drawer, &settings);
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

    // A box without a floor: 4 roof, 4 corner and 4 ground edges, no face diagonals.
    assert_eq!(drawer.set_highlight(&gpu, Some(centre.draw)), 12);
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

    // The outline: along the near building's silhouette, the outline colour; inside its front
    // face (where its hidden back edges project) and away from it, the frame as before. The
    // same over the HZB frame, which draws into a depth of its own.
    let hzb = RenderSettings {
        stages: FramePlan {
            lod: false,
            ..FramePlan::ALL
        },
        ..settings
    };
    drawer.set_highlight(&gpu, None);
    // Twice: the second HZB frame starts from the first one's visible set, as the next does.
    frame_of(&mut drawer, &hzb);
    let hzb_before = frame_of(&mut drawer, &hzb);
    drawer.set_highlight(&gpu, Some(centre.draw));
    let hzb_outlined = frame_of(&mut drawer, &hzb);
    let front = screen_box(&camera, [20.0, -5.0, 0.0], [20.0, 5.0, 10.0]);
    for (plan, before, outlined) in [
        ("brute force", &before, &tinted),
        ("hzb", &hzb_before, &hzb_outlined),
    ] {
        check_outline(plan, before, outlined, front);
    }

    drawer.set_highlight(&gpu, None);
    assert_eq!(differing_share(&before, &frame(&mut drawer)), 0.0);
}

/// The pixel box `(x0, y0, x1, y1)` that the box `lo`–`hi` (metres) covers in a [`SIZE`] view
/// from `camera`.
fn screen_box(camera: &Camera, lo: [f32; 3], hi: [f32; 3]) -> (f32, f32, f32, f32) {
    let view_proj = camera.view_proj(SIZE.0 as f32 / SIZE.1 as f32);
    let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
    for i in 0..8 {
        let corner = Vec3::new(
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        );
        let clip = view_proj * corner.extend(1.0);
        let x = (clip.x / clip.w + 1.0) / 2.0 * SIZE.0 as f32;
        let y = (1.0 - clip.y / clip.w) / 2.0 * SIZE.1 as f32;
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
    }
    (x0, y0, x1, y1)
}

/// The outline of the building whose front face covers the pixel box `front` is drawn in
/// `outlined` and not in `before`: its colour on both vertical sides of the box, no pixel of
/// that colour inside it (its back edges are hidden), nothing changed away from it.
fn check_outline(plan: &str, before: &[u8], outlined: &[u8], front: (f32, f32, f32, f32)) {
    // The outline colour as the sRGB target stores it.
    let expected = citywalk_shaders::constants::OUTLINE_RGB.map(|c| {
        let s = if c <= 0.003_130_8 {
            12.92 * c
        } else {
            1.055 * c.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0).round() as i32
    });
    let pixel = |image: &[u8], x: u32, y: u32| {
        let at = ((y * SIZE.0 + x) * 4) as usize;
        [image[at], image[at + 1], image[at + 2]]
    };
    // Within 3 levels per channel: lavapipe writes the colour exactly; slack for rounding on
    // other adapters.
    let is_outline = |p: [u8; 3]| {
        p.iter()
            .zip(expected)
            .all(|(&c, e)| (i32::from(c) - e).abs() <= 3)
    };
    let (x0, y0, x1, y1) = front;
    let mut on_edges = 0;
    for y in 0..SIZE.1 {
        for x in 0..SIZE.0 {
            let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
            let near = |margin: f32| {
                fx > x0 - margin && fx < x1 + margin && fy > y0 - margin && fy < y1 + margin
            };
            let (was, now) = (pixel(before, x, y), pixel(outlined, x, y));
            assert!(
                !is_outline(was),
                "{plan}: ({x}, {y}) outlined before the pick"
            );
            if !near(2.0) {
                assert_eq!(was, now, "{plan}: ({x}, {y}) away from the pick changed");
            } else if near(-3.0) {
                assert!(!is_outline(now), "{plan}: ({x}, {y}) inside the front face");
            } else if is_outline(now) {
                on_edges += 1;
            }
        }
    }
    // Both vertical sides, at mid-height, within a pixel of the projected silhouette.
    let mid = ((y0 + y1) / 2.0) as u32;
    for side in [x0, x1] {
        let hit = (-1..=1).any(|dx: i32| {
            let x = (side as i32 + dx).clamp(0, SIZE.0 as i32 - 1) as u32;
            is_outline(pixel(outlined, x, mid))
        });
        assert!(hit, "{plan}: no outline at x = {side}, y = {mid}");
    }
    let perimeter = 2.0 * ((x1 - x0) + (y1 - y0));
    assert!(
        on_edges as f32 > 0.8 * perimeter,
        "{plan}: {on_edges} outline pixels along a silhouette of {perimeter} px"
    );
}
