//! The viewer's debug views on the GPU (`engine::render::debug`), each against the CPU twin of
//! its shader: the pyramid view shows level K of a real pyramid texel for texel in the grey of
//! `pyramid_grey`; the cluster view paints each drawn entry in `cluster_colour` (distinct
//! colours, nothing for entries not drawn); the occluder view blends the occluders where they
//! project, highlighted when selected, and leaves the rest of the frame alone.

use citywalk_runtime::camera::Camera;
use citywalk_runtime::frame::OccluderMeshes;
use citywalk_runtime::gpu::GpuContext;
use citywalk_runtime::render::debug::clusters::cluster_colour;
use citywalk_runtime::render::debug::pyramid::{GreyRange, pyramid_grey};
use citywalk_runtime::render::debug::{
    ClusterView, DepthPyramid, OccluderOverlay, OccluderOverlayMeshes, PyramidView,
};
use citywalk_runtime::render::targets::OffscreenTarget;
use citywalk_runtime::scene_gpu::SceneGpu;
use citywalk_scenes::BuildingId;
use citywalk_scenes::extrude::building_mesh;
use citywalk_scenes::occluder::{FacadeKind, Occluder, OccluderSet};
use citywalk_shaders::constants::{
    DEBUG_GROUND_GREY, DEBUG_OCCLUDER_ALPHA, DEBUG_OCCLUDER_RGB, DEBUG_OCCLUDER_SELECTED_RGB,
    DEBUG_WALL_SHADE,
};
use citywalk_tests::city_builder::{box_building, boxes};
use citywalk_tests::gpu::gpu_or_skip;
use glam::Vec3;

/// Linear colours are written as they are (no sRGB encoding), so bytes are `round(255 · c)`.
const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

fn byte(c: f32) -> u8 {
    (c.clamp(0.0, 1.0) * 255.0).round() as u8
}

fn pixel(texels: &[u8], width: u32, (x, y): (u32, u32)) -> [u8; 3] {
    let i = ((y * width + x) * 4) as usize;
    [texels[i], texels[i + 1], texels[i + 2]]
}

fn close(a: [u8; 3], b: [u8; 3], tolerance: u8) -> bool {
    a.iter().zip(b).all(|(x, y)| x.abs_diff(y) <= tolerance)
}

fn submit(gpu: &GpuContext, encoder: wgpu::CommandEncoder) {
    gpu.queue.submit([encoder.finish()]);
}

fn encoder(gpu: &GpuContext) -> wgpu::CommandEncoder {
    gpu.device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("debug view test"),
        })
}

/// The pixel `p` (world, metres) projects to, on a `width × height` viewport.
fn project(camera: &Camera, (width, height): (u32, u32), p: Vec3) -> (u32, u32) {
    let ndc = camera
        .view_proj(width as f32 / height as f32)
        .project_point3(p);
    let x = ((ndc.x * 0.5 + 0.5) * width as f32).floor();
    let y = ((0.5 - ndc.y * 0.5) * height as f32).floor();
    assert!(
        (0.0..width as f32).contains(&x) && (0.0..height as f32).contains(&y),
        "{p} projects off screen"
    );
    (x as u32, y as u32)
}

#[test]
fn pyramid_view_shows_level_k_texel_for_texel_in_the_reference_grey() {
    let Some(gpu) = gpu_or_skip("pyramid_view") else {
        return;
    };
    // A wall 20 m ahead filling the left half of the view (looking along +x, +y is left), sky
    // above the right half, ground below. A viewport that is not a power of two.
    let city = boxes(&[(20.0, 0.0, 30.0, 400.0, 300.0)]);
    let scene = SceneGpu::upload_city(&gpu, &city).expect("the scene fits the GPU");
    let camera = Camera::new(Vec3::new(0.0, 0.0, 10.0), 0.0, 0.0);
    let size = (96, 60);
    let mut source = DepthPyramid::new(&gpu);
    let view = PyramidView::new(&gpu, FORMAT);
    let target = OffscreenTarget::new(&gpu, size.0, size.1, FORMAT).expect("target");
    let range = GreyRange {
        near_m: camera.near_m,
        white_m: 5.0,
        black_m: 500.0,
    };
    let mut seen_levels = Vec::new();
    for level in [0, 3, 40] {
        let mut enc = encoder(&gpu);
        let pyramid = source
            .encode(&gpu, &mut enc, &scene, &camera, &[0], size)
            .expect("pyramid");
        let shown = view.encode(&gpu, &mut enc, pyramid, level, &range, &target.colour_view);
        submit(&gpu, enc);
        let reference = pyramid.read_back(&gpu).expect("read the pyramid");
        assert_eq!(
            shown,
            level.min(reference.levels.len() as u32 - 1),
            "level clamped"
        );
        let texels = target.read_colour(&gpu).expect("read the view");
        let k = &reference.levels[shown as usize];
        for y in 0..size.1 {
            for x in 0..size.0 {
                let d = k.depth[((y >> shown) * k.width + (x >> shown)) as usize];
                let g = byte(pyramid_grey(d, &range));
                let got = pixel(&texels, size.0, (x, y));
                assert!(
                    close(got, [g; 3], 1),
                    "level {shown} pixel ({x}, {y}): {got:?}, reference grey {g} (depth {d})"
                );
            }
        }
        seen_levels.push((shown, texels));
    }
    // Level 0 in the middle of the wall is the wall's depth, near / 20 m: grey
    // 1 − ln(20 / 5) / ln(500 / 5) in this range; the sky is black.
    let (_, level0) = &seen_levels[0];
    let wall_grey = pyramid_grey(camera.near_m / 20.0, &range);
    assert!((wall_grey - (1.0 - 4f32.ln() / 100f32.ln())).abs() < 1e-5);
    let wall = byte(wall_grey);
    assert!(close(pixel(level0, size.0, (20, 20)), [wall; 3], 1));
    assert_eq!(pixel(level0, size.0, (80, 2)), [0; 3], "sky");
    // Level 3: each 8 × 8 block of pixels shows one texel.
    let (_, level3) = &seen_levels[1];
    for y in 0..size.1 {
        for x in 0..size.0 {
            let corner = pixel(level3, size.0, (x & !7, y & !7));
            assert_eq!(pixel(level3, size.0, (x, y)), corner, "({x}, {y})");
        }
    }
    assert_ne!(level0, level3, "a coarser level looks coarser");
}

#[test]
fn cluster_view_paints_each_drawn_entry_in_its_own_colour() {
    let Some(gpu) = gpu_or_skip("cluster_view") else {
        return;
    };
    // Six 20 m boxes in a 3 × 2 grid seen from straight above: only roofs show.
    let mut specs = Vec::new();
    for j in 0..2 {
        for i in 0..3 {
            let (x, y) = (f64::from(i) * 40.0, f64::from(j) * 40.0);
            specs.push((x, y, x + 20.0, y + 20.0, 10.0));
        }
    }
    let city = boxes(&specs);
    let scene = SceneGpu::upload_city(&gpu, &city).expect("the scene fits the GPU");
    let camera = Camera::new(Vec3::new(50.0, 30.0, 300.0), 0.0, -89f32.to_radians());
    let size = (160, 120);
    let target = OffscreenTarget::new(&gpu, size.0, size.1, FORMAT).expect("target");
    let mut view = ClusterView::new(&gpu, FORMAT);
    let drawn_ids = [0u32, 2, 3, 5];
    let mut enc = encoder(&gpu);
    let draws = view.encode(
        &gpu,
        &mut enc,
        &scene,
        &camera,
        &drawn_ids,
        &target.colour_view,
        size,
    );
    submit(&gpu, enc);
    assert_eq!(draws, drawn_ids.len() as u32 + 1, "entries and the ground");
    let texels = target.read_colour(&gpu).expect("read the view");
    let mut colours = Vec::new();
    for (id, &(x0, y0, x1, y1, h)) in specs.iter().enumerate() {
        let centre = Vec3::new(((x0 + x1) / 2.0) as f32, ((y0 + y1) / 2.0) as f32, h);
        let got = pixel(&texels, size.0, project(&camera, size, centre));
        let want = if drawn_ids.contains(&(id as u32)) {
            colours.push(got);
            cluster_colour(id as u32).map(byte)
        } else {
            [byte(DEBUG_GROUND_GREY); 3]
        };
        assert!(
            close(got, want, 2),
            "entry {id}: {got:?}, expected {want:?}"
        );
    }
    for (i, a) in colours.iter().enumerate() {
        for b in &colours[i + 1..] {
            assert!(!close(*a, *b, 6), "two entries share a colour: {a:?} {b:?}");
        }
    }
}

#[test]
fn occluder_view_blends_occluders_where_they_project_and_highlights_the_selected() {
    let Some(gpu) = gpu_or_skip("occluder_view") else {
        return;
    };
    // One box occluder (building 7) 30 m ahead of the eye, seen face-on.
    let building = box_building(7, 30.0, -5.0, 40.0, 5.0, 20.0);
    let set = OccluderSet {
        occluders: vec![Occluder {
            building: BuildingId(7),
            level: 0,
            kind: FacadeKind::Closed,
            z_m: 20.0,
            base_m: 0.0,
            footprint: building.footprint.clone(),
            mesh: building_mesh(&building),
        }],
        per_building: Vec::new(),
    };
    let frame_meshes = OccluderMeshes::upload(&gpu, &set).expect("the scene fits the GPU");
    let meshes = OccluderOverlayMeshes::of(&frame_meshes);
    assert_eq!(meshes.ranges.len(), 1);
    let camera = Camera::new(Vec3::new(0.0, 0.0, 10.0), 0.0, 0.0);
    let size = (80, 60);
    let target = OffscreenTarget::new(&gpu, size.0, size.1, FORMAT).expect("target");
    let mut overlay = OccluderOverlay::new(&gpu, FORMAT);
    let centre = project(&camera, size, Vec3::new(30.0, 0.0, 10.0));
    let corner = (1, 1);
    let blend = |src: [f32; 3], dst: [f32; 3]| -> [f32; 3] {
        std::array::from_fn(|i| {
            src[i] * DEBUG_WALL_SHADE * DEBUG_OCCLUDER_ALPHA + dst[i] * (1.0 - DEBUG_OCCLUDER_ALPHA)
        })
    };
    let plain = blend(DEBUG_OCCLUDER_RGB, [0.0; 3]);
    for (selected, want) in [
        (&[][..], plain),
        (&[0usize][..], blend(DEBUG_OCCLUDER_SELECTED_RGB, plain)),
        // Not an occluder of the set: ignored.
        (&[3usize][..], plain),
    ] {
        let mut enc = encoder(&gpu);
        // The frame under the overlay: black.
        drop(enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("clear"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &target.colour_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        }));
        let highlighted = overlay.encode(
            &gpu,
            &mut enc,
            &meshes,
            &camera,
            selected,
            &target.colour_view,
            size,
        );
        submit(&gpu, enc);
        assert_eq!(highlighted, u32::from(selected.contains(&0)));
        let texels = target.read_colour(&gpu).expect("read the view");
        let got = pixel(&texels, size.0, centre);
        let want = want.map(byte);
        assert!(
            close(got, want, 3),
            "selected {selected:?}: {got:?} at the occluder, expected {want:?}"
        );
        assert_eq!(pixel(&texels, size.0, corner), [0; 3], "off the occluder");
    }
}
