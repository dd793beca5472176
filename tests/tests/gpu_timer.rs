//! Per-phase GPU timestamps ([`GpuTimer`]) over real passes: a scene draw, the HiZ pyramid
//! build and the cull, on whatever adapter the machine has (lavapipe in CI), and the path of a
//! device without `TIMESTAMP_QUERY`.

use citywalk_preprocess::occluders::{OccluderParams, build_occluders};
use citywalk_runtime::camera::Camera;
use citywalk_runtime::frame::{CullingOptions, CullingRenderer, OccluderMeshes, Visibility};
use citywalk_runtime::gpu::{GpuContext, WANTED_FEATURES};
use citywalk_runtime::gpu_timer::{FRAME_PHASES, GpuTimer, GpuTimes};
use citywalk_runtime::hzb::{HzbCull, HzbPyramid};
use citywalk_runtime::render::{BruteRenderer, OffscreenTarget};
use citywalk_runtime::scene_gpu::SceneGpu;
use citywalk_tests::gpu::gpu_or_skip;
use glam::Vec3;

const PHASES: &[&str] = &["draw", "pyramid", "cull", "never"];
const W: u32 = 320;
const H: u32 = 200;

/// A 4 × 4 grid of boxes seen from a street corner.
fn scene(gpu: &GpuContext) -> SceneGpu {
    let mut specs = Vec::new();
    for i in 0..4 {
        for j in 0..4 {
            let (x, y) = (f64::from(i) * 30.0, f64::from(j) * 30.0);
            specs.push((x, y, x + 18.0, y + 18.0, 10.0 + 6.0 * (i + j) as f32));
        }
    }
    SceneGpu::upload_city(gpu, &citywalk_tests::city_builder::boxes(&specs))
        .expect("the scene fits the GPU")
}

/// Draws, builds the pyramid from the depth and culls, timing each pass (the phase `never` has
/// no pass); returns the times and the frame's pixels.
fn timed_frame(gpu: &GpuContext, timer: &mut GpuTimer, scene: &SceneGpu) -> (GpuTimes, Vec<u8>) {
    let renderer = BruteRenderer::new(gpu, BruteRenderer::PNG_FORMAT);
    let target = OffscreenTarget::new(gpu, W, H, BruteRenderer::PNG_FORMAT).expect("target");
    let pyramid = HzbPyramid::new(gpu, W, H).expect("pyramid");
    let n = scene.building_count() as u32;
    let mut cull = HzbCull::new(gpu, n);
    let camera = Camera::new(Vec3::new(-10.0, -10.0, 1.7), 0.8, 0.05);
    let view_proj = camera.view_proj(W as f32 / H as f32);
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
    timer.begin_frame();
    renderer.encode_timed(
        gpu,
        &mut encoder,
        scene,
        &camera,
        &target.colour_view,
        &target.depth,
        timer.render_pass_writes("draw"),
    );
    pyramid.build_timed(
        &mut encoder,
        &target.depth.view,
        timer.compute_pass_writes("pyramid"),
    );
    cull.encode_timed(
        gpu,
        &mut encoder,
        (
            &scene.all.as_ref().expect("a plain scene").records_buffer,
            Some(&scene.parts_buffer),
        ),
        n,
        (&pyramid, view_proj),
        timer.compute_pass_writes("cull"),
    )
    .expect("cull");
    timer.resolve(&mut encoder);
    gpu.queue.submit([encoder.finish()]);
    let times = timer.read(gpu).expect("timer readback");
    let pixels = target.read_colour(gpu).expect("colour readback");
    (times, pixels)
}

#[test]
fn timestamps_of_real_passes_are_ordered_and_finite() {
    let Some(gpu) = gpu_or_skip("timestamps_of_real_passes_are_ordered_and_finite") else {
        return;
    };
    let scene = scene(&gpu);
    let mut timer = GpuTimer::new(&gpu, "test timer", PHASES);
    assert_eq!(timer.is_enabled(), gpu.has(wgpu::Features::TIMESTAMP_QUERY));
    eprintln!(
        "TIMESTAMP_QUERY: {}, period {} ns",
        timer.is_enabled(),
        gpu.queue.get_timestamp_period()
    );
    // Twice with the same timer: the readback buffer is mapped and unmapped each frame.
    for frame in 0..2 {
        let (times, _) = timed_frame(&gpu, &mut timer, &scene);
        let names: Vec<&str> = times.phases.iter().map(|p| p.name).collect();
        assert_eq!(names, PHASES);
        if !timer.is_enabled() {
            assert!(times.phases.iter().all(|p| p.span.is_none()));
            assert_eq!(times.total_ms(), None);
            continue;
        }
        eprintln!("frame {frame}: {times:?}");
        let spans: Vec<_> = PHASES[..3]
            .iter()
            .map(|&name| {
                let p = times.phases.iter().find(|p| p.name == name).expect("phase");
                p.span.unwrap_or_else(|| panic!("{name} was not timed"))
            })
            .collect();
        for (name, s) in PHASES.iter().zip(&spans) {
            assert!(
                s.begin_ms.is_finite() && s.end_ms.is_finite(),
                "{name}: {s:?}"
            );
            assert!(s.begin_ms >= 0.0 && s.end_ms >= s.begin_ms, "{name}: {s:?}");
            // A frame of a few hundred pixels does not take a minute.
            assert!(s.duration_ms() < 60_000.0, "{name}: {s:?}");
        }
        // The pyramid reads the draw's depth and the cull reads the pyramid: the passes are
        // ordered by their dependencies, so are their timestamps.
        assert_eq!(spans[0].begin_ms, 0.0);
        for pair in spans.windows(2) {
            assert!(
                pair[1].begin_ms >= pair[0].end_ms,
                "phases out of order: {pair:?}"
            );
        }
        assert_eq!(
            times.phase_ms("never"),
            None,
            "a phase with no pass is None"
        );
        let total = times.total_ms().expect("total");
        let sum: f64 = spans.iter().map(|s| s.duration_ms()).sum();
        assert!((total - sum).abs() < 1e-9);
    }
}

#[test]
fn without_timestamp_queries_every_phase_is_none_and_frames_are_unchanged() {
    let Some(gpu) = gpu_or_skip("without_timestamp_queries_every_phase_is_none") else {
        return;
    };
    let without =
        GpuContext::headless_with_features(WANTED_FEATURES - wgpu::Features::TIMESTAMP_QUERY)
            .expect("a context like the first one");
    assert!(!without.has(wgpu::Features::TIMESTAMP_QUERY));
    let mut timer = GpuTimer::new(&without, "untimed", PHASES);
    assert!(!timer.is_enabled());
    let (times, pixels) = timed_frame(&without, &mut timer, &scene(&without));
    assert_eq!(times.phases.len(), PHASES.len());
    assert!(times.phases.iter().all(|p| p.span.is_none()));
    assert_eq!(times.total_ms(), None);
    // The same frame with timing (where the adapter has it) draws the same pixels.
    let mut timed = GpuTimer::new(&gpu, "timed", PHASES);
    let (_, timed_pixels) = timed_frame(&gpu, &mut timed, &scene(&gpu));
    assert_eq!(pixels.len(), timed_pixels.len());
    assert!(pixels == timed_pixels, "timing changed the image");
}

#[test]
fn the_two_phase_frame_times_its_passes() {
    let Some(gpu) = gpu_or_skip("the_two_phase_frame_times_its_passes") else {
        return;
    };
    let scene = scene(&gpu);
    let target = OffscreenTarget::new(&gpu, W, H, BruteRenderer::PNG_FORMAT).expect("target");
    let mut renderer = CullingRenderer::new(&gpu, BruteRenderer::PNG_FORMAT);
    let mut visibility = Visibility::default();
    let camera = Camera::new(Vec3::new(-10.0, -10.0, 1.7), 0.8, 0.05);
    // The first frame has no early set; the second draws last frame's visible set early.
    for frame in 0..2 {
        let out = renderer
            .render(
                &gpu,
                &scene,
                None,
                &CullingOptions::default(),
                &mut visibility,
                &camera,
                &target.colour_view,
                (W, H),
            )
            .expect("frame");
        let times = &out.stats.gpu;
        let names: Vec<&str> = times.phases.iter().map(|p| p.name).collect();
        assert_eq!(names, FRAME_PHASES);
        if !gpu.has(wgpu::Features::TIMESTAMP_QUERY) {
            assert_eq!(times.total_ms(), None);
            continue;
        }
        eprintln!("frame {frame}: {times:?}, CPU {:.3} ms", out.stats.cpu_ms);
        // No occluders in this frame: that phase has no pass.
        assert_eq!(times.phase_ms("occluders"), None);
        // Without occluders the early set is taken by the frustum-only early cull.
        assert_eq!(times.phase_ms("gate"), None);
        let spans: Vec<_> = ["early_cull", "early", "pyramid", "cull", "late"]
            .iter()
            .map(|&name| {
                let p = times.phases.iter().find(|p| p.name == name).expect("phase");
                p.span
                    .unwrap_or_else(|| panic!("frame {frame}: {name} was not timed"))
            })
            .collect();
        for s in &spans {
            assert!(s.begin_ms.is_finite() && s.begin_ms >= 0.0 && s.end_ms >= s.begin_ms);
        }
        // Each pass reads what the one before wrote (depth, pyramid, commands).
        for pair in spans.windows(2) {
            assert!(pair[1].begin_ms >= pair[0].end_ms, "{pair:?}");
        }
        assert!(times.total_ms().expect("total") > 0.0);
    }
}

/// With occluders and the occluder gate (the default), every frame times eight passes in frame
/// order: the gate's occluders, pyramid and cull, the early pass, the merge of its depth
/// ("occluders"), the pyramid, the cull and the late pass; the frustum-only early cull does not
/// run. The first frame (nothing visible before) runs the gate over an empty early set.
#[test]
fn the_gated_frame_times_every_phase_in_order() {
    let Some(gpu) = gpu_or_skip("the_gated_frame_times_every_phase_in_order") else {
        return;
    };
    let mut specs = Vec::new();
    for i in 0..4 {
        for j in 0..4 {
            let (x, y) = (f64::from(i) * 30.0, f64::from(j) * 30.0);
            specs.push((x, y, x + 18.0, y + 18.0, 10.0 + 6.0 * (i + j) as f32));
        }
    }
    let city = citywalk_tests::city_builder::boxes(&specs);
    let scene = SceneGpu::upload_city(&gpu, &city).expect("the scene fits the GPU");
    let occluders =
        OccluderMeshes::upload(&gpu, &build_occluders(&city, &OccluderParams::default()))
            .expect("the scene fits the GPU");
    let target = OffscreenTarget::new(&gpu, W, H, BruteRenderer::PNG_FORMAT).expect("target");
    let mut renderer = CullingRenderer::new(&gpu, BruteRenderer::PNG_FORMAT);
    let mut visibility = Visibility::default();
    let camera = Camera::new(Vec3::new(-10.0, -10.0, 1.7), 0.8, 0.05);
    let options = CullingOptions {
        occluders: true,
        ..CullingOptions::default()
    };
    assert!(options.occluder_gate, "the gate is on by default");
    for frame in 0..2 {
        let out = renderer
            .render(
                &gpu,
                &scene,
                Some(&occluders),
                &options,
                &mut visibility,
                &camera,
                &target.colour_view,
                (W, H),
            )
            .expect("frame");
        assert!(
            out.stats.occluders_drawn > 0,
            "frame {frame}: no occluder drawn"
        );
        if frame == 1 {
            assert!(
                out.stats.early_drawn + out.stats.gate_culled > 0,
                "frame 1 has no early candidate"
            );
        }
        let times = &out.stats.gpu;
        if !gpu.has(wgpu::Features::TIMESTAMP_QUERY) {
            assert_eq!(times.total_ms(), None);
            continue;
        }
        eprintln!("gated frame {frame}: {times:?}");
        assert_eq!(times.phase_ms("early_cull"), None, "frame {frame}: gated");
        let spans: Vec<_> = FRAME_PHASES
            .iter()
            // Gated, the occluders are drawn in `gate_occluders`; the pyramid merges their depth
            // with the early pass's, so there is no separate occluder pass.
            .filter(|&&name| name != "early_cull" && name != "occluders")
            .filter(|&&name| name != "late" || out.stats.late_drawn > 0)
            .map(|&name| {
                let p = times.phases.iter().find(|p| p.name == name).expect("phase");
                p.span
                    .unwrap_or_else(|| panic!("gated frame: {name} was not timed"))
            })
            .collect();
        assert!(spans.len() >= 6, "{spans:?}");
        assert_eq!(
            times.phase_ms("occluders"),
            None,
            "frame {frame}: gated, no occluder pass"
        );
        for pair in spans.windows(2) {
            assert!(pair[1].begin_ms >= pair[0].end_ms, "{pair:?}");
        }
    }
}
