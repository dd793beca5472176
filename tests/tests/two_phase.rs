//! The two-phase HiZ frame (`citywalk_engine::frame`) against the exact ID-buffer oracle: every
//! building with a visible pixel is drawn in the same frame, with and without the virtual
//! occluder pre-pass, over random street-level and aerial cameras, after a fast turn, at odd
//! viewport sizes, and with boxes crossing the near plane; and at street level most of the city
//! is culled.

use std::path::PathBuf;

use citywalk_engine::bench::pixel_error::pixel_error;
use citywalk_engine::bench::{BenchConfig, BenchError, BenchRenderers, BenchScene, Mode, run_path};
use citywalk_engine::camera::Camera;
use citywalk_engine::frame::{
    CullingOptions, CullingRenderer, FrameOutput, OccluderMeshes, Visibility,
};
use citywalk_engine::gpu::GpuContext;
use citywalk_engine::hzb::cull::CULL_VISIBLE;
use citywalk_engine::oracle::Oracle;
use citywalk_engine::render::BruteRenderer;
use citywalk_engine::render::targets::OffscreenTarget;
use citywalk_engine::scene_gpu::SceneGpu;
use citywalk_preprocess::pipeline::{NoProgress, PreprocessParams, preprocess};
use citywalk_scenes::City;
use citywalk_scenes::camera_path::street_walk;
use citywalk_scenes::generate::{GenerateParams, generate_city};
use citywalk_scenes::{BuildingId, LoadOptions, load_cities};
use citywalk_tests::gpu::gpu_or_skip;
use glam::Vec3;

const CHELSEA: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../scenes/data/chelsea.osm.pbf"
);

/// SplitMix64: a small fixed-seed generator for cameras.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
}

/// A scene with its occluders on the GPU.
struct TestScene {
    name: &'static str,
    city: City,
    scene: SceneGpu,
    occluders: OccluderMeshes,
}

fn prepare(gpu: &GpuContext, name: &'static str, city: City) -> TestScene {
    let package = preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess");
    let occluders = package.occluders.as_ref().expect("occluders");
    assert!(!occluders.occluders.is_empty(), "{name}: no occluders");
    let city = package.city();
    TestScene {
        name,
        scene: SceneGpu::upload_city(gpu, &city),
        occluders: OccluderMeshes::upload(gpu, occluders),
        city,
    }
}

fn generated(gpu: &GpuContext) -> TestScene {
    let city = generate_city(&GenerateParams::new(1500, 11)).expect("generate");
    prepare(gpu, "generated-1500", city)
}

fn chelsea(gpu: &GpuContext) -> TestScene {
    let city =
        load_cities(&[PathBuf::from(CHELSEA)], &LoadOptions::default()).expect("load Chelsea");
    prepare(gpu, "chelsea", city)
}

/// A point on a random street, 1.7 m above the ground, looking along a random heading.
fn street_camera(rng: &mut Rng, city: &City) -> Camera {
    let streets: Vec<_> = city
        .streets
        .iter()
        .filter(|s| s.line.0.len() >= 2)
        .collect();
    assert!(!streets.is_empty(), "the city has no streets");
    let street = streets[rng.next_u64() as usize % streets.len()];
    let segment = rng.next_u64() as usize % (street.line.0.len() - 1);
    let (a, b) = (street.line.0[segment], street.line.0[segment + 1]);
    let t = f64::from(rng.unit());
    let position = Vec3::new(
        (a.x + (b.x - a.x) * t) as f32,
        (a.y + (b.y - a.y) * t) as f32,
        1.7,
    );
    Camera::new(
        position,
        rng.range(0.0, std::f32::consts::TAU),
        rng.range(-0.1, 0.25),
    )
}

/// Above the city, looking down at the middle.
fn aerial_camera(rng: &mut Rng, scene: &SceneGpu) -> Camera {
    let (lo, hi) = scene.bounds;
    let position = Vec3::new(
        rng.range(lo.x, hi.x),
        rng.range(lo.y, hi.y),
        hi.z + rng.range(20.0, 300.0),
    );
    Camera::new(
        position,
        rng.range(0.0, std::f32::consts::TAU),
        rng.range(-1.2, -0.2),
    )
}

/// The two configurations under test.
fn configurations() -> [(&'static str, CullingOptions); 2] {
    [
        ("hzb", CullingOptions::default()),
        (
            "occluders",
            CullingOptions {
                occluders: true,
                ..CullingOptions::default()
            },
        ),
    ]
}

struct Harness {
    gpu: GpuContext,
    renderer: CullingRenderer,
    oracle: Oracle,
    brute: BruteRenderer,
    /// The colour of the last frame (RGBA8 sRGB).
    last_rgba: Vec<u8>,
}

impl Harness {
    fn new(gpu: GpuContext) -> Harness {
        Harness {
            renderer: CullingRenderer::new(&gpu, BruteRenderer::PNG_FORMAT),
            oracle: Oracle::new(&gpu),
            brute: BruteRenderer::new(&gpu, BruteRenderer::PNG_FORMAT),
            last_rgba: Vec::new(),
            gpu,
        }
    }

    fn frame(
        &mut self,
        scene: &TestScene,
        options: &CullingOptions,
        visibility: &mut Visibility,
        camera: &Camera,
        (w, h): (u32, u32),
    ) -> FrameOutput {
        let target =
            OffscreenTarget::new(&self.gpu, w, h, BruteRenderer::PNG_FORMAT).expect("target");
        let out = self
            .renderer
            .render(
                &self.gpu,
                &scene.scene,
                Some(&scene.occluders),
                options,
                visibility,
                camera,
                &target.colour_view,
                (w, h),
            )
            .expect("frame");
        self.last_rgba = target.read_colour(&self.gpu).expect("colour");
        out
    }

    /// Share of pixels of the last frame that differ from the brute-force frame.
    fn error_vs_brute(&self, scene: &TestScene, camera: &Camera, (w, h): (u32, u32)) -> f64 {
        let brute = self
            .brute
            .render_rgba(&self.gpu, &scene.scene, camera, w, h)
            .expect("brute frame");
        pixel_error(&brute, &self.last_rgba).colour_fraction
    }

    /// Renders `camera` and asserts every oracle-visible building was drawn; returns the frame
    /// and the number of visible buildings.
    fn check(
        &mut self,
        scene: &TestScene,
        (config, options): (&str, &CullingOptions),
        visibility: &mut Visibility,
        camera: &Camera,
        size: (u32, u32),
    ) -> (FrameOutput, usize) {
        let out = self.frame(scene, options, visibility, camera, size);
        let visible = self
            .oracle
            .visible_set(&self.gpu, &scene.scene, camera, size.0, size.1)
            .expect("oracle");
        let missing: Vec<u32> = visible
            .visible
            .iter()
            .map(|b| b.0)
            .filter(|b| out.drawn.binary_search(b).is_err())
            .collect();
        assert!(
            missing.is_empty(),
            "{}, {config}, {}x{}, camera {}: visible buildings {missing:?} not drawn \
             (pixels {:?}, status {:?})",
            scene.name,
            size.0,
            size.1,
            camera.to_arg_string(),
            missing
                .iter()
                .map(|&b| visible.pixel_counts[b as usize])
                .collect::<Vec<_>>(),
            missing
                .iter()
                .map(|&b| out.status[b as usize])
                .collect::<Vec<_>>(),
        );
        // The counts add up.
        let s = &out.stats;
        assert_eq!(
            s.frustum_culled + s.occlusion_culled + s.cull_kept,
            s.building_count
        );
        assert_eq!(s.drawn as usize, out.drawn.len());
        assert!(s.drawn >= s.cull_kept && s.drawn <= s.early_drawn + s.cull_kept);
        (out, visible.len())
    }
}

/// Random cameras, each rendered as the second frame of a short move (the first frame a few
/// metres and degrees away seeds the early pass), at a small viewport; then a few cameras at
/// the four named sizes. Returns the street-level culled fractions of the hzb configuration.
fn sweep(h: &mut Harness, scene: &TestScene, seed: u64, cameras: usize) -> Vec<f64> {
    let mut rng = Rng(seed);
    let mut street_culled = Vec::new();
    let (mut occluders_drawn, mut occlusion_culled) = (0u64, 0u64);
    for i in 0..cameras {
        let street = i % 2 == 0;
        let camera = if street {
            street_camera(&mut rng, &scene.city)
        } else {
            aerial_camera(&mut rng, &scene.scene)
        };
        let mut before = camera;
        before.position += Vec3::new(rng.range(-4.0, 4.0), rng.range(-4.0, 4.0), 0.0);
        before.yaw_rad += rng.range(-0.3, 0.3);
        for (config, options) in configurations() {
            let mut visibility = Visibility::default();
            let size = (320, 200);
            h.check(scene, (config, &options), &mut visibility, &before, size);
            let (out, _) = h.check(scene, (config, &options), &mut visibility, &camera, size);
            occluders_drawn += u64::from(out.stats.occluders_drawn);
            occlusion_culled += u64::from(out.stats.occlusion_culled);
            if street && config == "hzb" {
                street_culled
                    .push(1.0 - f64::from(out.stats.drawn) / scene.scene.building_count() as f64);
            }
        }
    }
    for size in [(1280, 720), (1366, 768), (1001, 777), (640, 480)] {
        let camera = street_camera(&mut rng, &scene.city);
        let aerial = aerial_camera(&mut rng, &scene.scene);
        for (config, options) in configurations() {
            let mut visibility = Visibility::default();
            h.check(scene, (config, &options), &mut visibility, &camera, size);
            h.check(scene, (config, &options), &mut visibility, &aerial, size);
            // The image is brute force's: occluders never reach the final depth. Tolerance:
            // coplanar faces of different buildings may z-fight in another order (llvmpipe).
            let error = h.error_vs_brute(scene, &aerial, size);
            assert!(
                error < 0.002,
                "{}, {config}, {size:?}: {:.3} % of pixels differ from brute force",
                scene.name,
                100.0 * error
            );
        }
    }
    eprintln!(
        "{}: occluders drawn {occluders_drawn}, buildings occlusion-culled {occlusion_culled}",
        scene.name
    );
    assert!(
        occluders_drawn > 0,
        "{}: no occluder was ever drawn",
        scene.name
    );
    assert!(
        occlusion_culled > 0,
        "{}: nothing was occlusion-culled",
        scene.name
    );
    street_culled
}

#[test]
fn generated_city_is_conservative_and_culls_most_at_street_level() {
    let Some(gpu) = gpu_or_skip("two_phase generated") else {
        return;
    };
    let scene = generated(&gpu);
    let mut h = Harness::new(gpu);
    let culled = sweep(&mut h, &scene, 0x5eed_0001, 24);
    let mean = culled.iter().sum::<f64>() / culled.len() as f64;
    eprintln!(
        "generated city, street level: mean culled fraction {mean:.3} over {} cameras",
        culled.len()
    );
    assert!(
        mean > 0.5,
        "street level culls only {:.1} % of the buildings",
        100.0 * mean
    );
}

#[test]
fn chelsea_is_conservative() {
    let Some(gpu) = gpu_or_skip("two_phase chelsea") else {
        return;
    };
    let scene = chelsea(&gpu);
    let mut h = Harness::new(gpu);
    sweep(&mut h, &scene, 0x5eed_0002, 12);
}

#[test]
fn fast_turn_draws_the_disoccluded_buildings_and_near_boxes_are_kept() {
    let Some(gpu) = gpu_or_skip("two_phase turn") else {
        return;
    };
    let scene = generated(&gpu);
    let mut h = Harness::new(gpu);
    let mut rng = Rng(0x5eed_0003);
    let mut late_total = 0;
    for _ in 0..4 {
        let mut north = street_camera(&mut rng, &scene.city);
        north.yaw_rad = std::f32::consts::FRAC_PI_2;
        north.pitch_rad = 0.0;
        let mut south = north;
        south.yaw_rad += std::f32::consts::PI;
        for (config, options) in configurations() {
            let mut visibility = Visibility::default();
            h.check(
                &scene,
                (config, &options),
                &mut visibility,
                &north,
                (480, 270),
            );
            let (out, visible) = h.check(
                &scene,
                (config, &options),
                &mut visibility,
                &south,
                (480, 270),
            );
            let error = h.error_vs_brute(&scene, &south, (480, 270));
            assert!(
                error < 0.002,
                "{config}: {:.3} % of pixels differ after the turn",
                100.0 * error
            );
            // After the turn, what is seen comes from the late pass.
            if visible > 0 {
                assert!(
                    out.stats.late_drawn > 0,
                    "{config}: nothing drawn late after a turn"
                );
            }
            late_total += out.stats.late_drawn;
        }
    }
    eprintln!(
        "{} buildings, {} occluders; drawn late after the turns: {late_total}",
        scene.scene.building_count(),
        scene.occluders.occluders.len()
    );
    assert!(late_total > 0);

    // A camera inside a building: its box crosses the near plane and must be kept.
    let (id, record) = scene
        .scene
        .records
        .iter()
        .enumerate()
        .find(|(_, r)| r.index_count > 0 && r.bounds_max_m[2] - r.bounds_min_m[2] > 4.0)
        .expect("a building");
    let lo = Vec3::from_array(record.bounds_min_m);
    let hi = Vec3::from_array(record.bounds_max_m);
    let inside = Camera::new(
        Vec3::new((lo.x + hi.x) * 0.5, (lo.y + hi.y) * 0.5, lo.z + 1.7),
        0.3,
        0.0,
    );
    for (config, options) in configurations() {
        let mut visibility = Visibility::default();
        let out = h.frame(&scene, &options, &mut visibility, &inside, (320, 200));
        assert_eq!(
            out.status[id], CULL_VISIBLE,
            "{config}: near-crossing box culled"
        );
        assert!(out.drawn.contains(&(id as u32)));
        // The box test must also keep it when other buildings were drawn early.
        let out = h.frame(&scene, &options, &mut visibility, &inside, (320, 200));
        assert_eq!(out.status[id], CULL_VISIBLE, "{config}: second frame");
        assert!(
            h.oracle
                .visible_set(&h.gpu, &scene.scene, &inside, 320, 200)
                .expect("oracle")
                .visible
                .iter()
                .all(|b: &BuildingId| out.drawn.binary_search(&b.0).is_ok())
        );
    }
}

#[test]
fn bench_modes_run_a_street_walk_with_no_false_cull() {
    let Some(gpu) = gpu_or_skip("two_phase bench") else {
        return;
    };
    let city = generate_city(&GenerateParams::new(1500, 11)).expect("generate");
    let package = preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess");
    let city = package.city();
    let scene = BenchScene {
        name: "generated".into(),
        gpu_scene: SceneGpu::upload_city(&gpu, &city),
        blocks: package.blocks.clone(),
        quadtree: package.quadtree.clone(),
        lod: None,
        occluders: package
            .occluders
            .as_ref()
            .map(|set| OccluderMeshes::upload(&gpu, set)),
    };
    let path = street_walk(&city, 10);
    let config = BenchConfig {
        modes: vec![Mode::Brute, Mode::Hzb, Mode::Occluders],
        width: 320,
        height: 200,
        frames_dir: None,
        png_every: 0,
    };
    let mut renderers = BenchRenderers::new(&gpu);
    let records = run_path(&gpu, &mut renderers, &scene, &path, &config).expect("run");
    assert_eq!(records.len(), 30);
    for r in &records {
        assert_eq!(
            r.false_culls, 0,
            "{} frame {}: false culls",
            r.mode, r.frame
        );
        assert!(r.drawn >= r.visible);
        if r.mode != "brute" {
            assert!(
                r.culled_fraction > 0.0,
                "{} frame {} culls nothing",
                r.mode,
                r.frame
            );
            assert!(r.pixel_error_colour < 0.002, "{} frame {}", r.mode, r.frame);
        }
    }
    // Without occluders a scene refuses the occluders mode rather than silently skipping it.
    let bare = BenchScene {
        occluders: None,
        ..scene
    };
    let config = BenchConfig {
        modes: vec![Mode::Occluders],
        ..config
    };
    assert!(matches!(
        run_path(&gpu, &mut renderers, &bare, &path, &config),
        Err(BenchError::NoOccluders(_))
    ));
}
