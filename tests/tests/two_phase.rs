//! The two-phase HiZ frame (`citywalk_runtime::frame`) against the exact ID-buffer oracle: every
//! building with a visible pixel is drawn in the same frame, with and without the virtual
//! occluder pre-pass, over random street-level and aerial cameras, after a fast turn, at odd
//! viewport sizes, and with boxes crossing the near plane; and at street level most of the city
//! is culled. The combined frame (B-Quadtree + LOD cut + HiZ + occluders,
//! `CullingRenderer::render_lod`) is held to the same oracle: every visible building drawn
//! itself or through a drawn cluster that contains it, also while the cut changes from frame to
//! frame. Scenes: a generated city, Chelsea (OSM) and Den Haag (CityJSON LoD2 meshes).

use std::path::PathBuf;
use std::sync::OnceLock;

use citywalk_bench::pixel_error::pixel_error;
use citywalk_bench::{BenchConfig, BenchError, BenchRenderers, BenchScene, Mode, run_path};
use citywalk_preprocess::pipeline::{NoProgress, PreprocessParams, preprocess};
use citywalk_runtime::camera::Camera;
use citywalk_runtime::drawable::DrawableScene;
use citywalk_runtime::frame::{
    CullingOptions, CullingRenderer, FrameOutput, FrameScene, OccluderMeshes, Visibility,
};
use citywalk_runtime::gpu::GpuContext;
use citywalk_runtime::lod::LodCriterion;
use citywalk_runtime::lod::scene::{LodFrame, LodScene};
use citywalk_runtime::oracle::{Oracle, VisibleSet};
use citywalk_runtime::render::BruteRenderer;
use citywalk_runtime::render::targets::OffscreenTarget;
use citywalk_runtime::runner::visible_blocks;
use citywalk_runtime::scene_gpu::SceneGpu;
use citywalk_scenes::City;
use citywalk_scenes::camera_path::{flyover, street_walk};
use citywalk_scenes::city_sphere::CitySphere;
use citywalk_scenes::generate::{GenerateParams, generate_city};
use citywalk_scenes::package::ScenePackage;
use citywalk_scenes::{BuildingId, LoadOptions, load_cities};
use citywalk_tests::gpu::gpu_or_skip;
use citywalk_tests::rng::Rng;
use glam::Vec3;

const CHELSEA: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../scenes/data/chelsea.osm.pbf"
);
const DEN_HAAG: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/cityjson_denhaag/DenHaag_01.json"
);

/// A scene with its occluders, LOD scene and culling structures on the GPU.
struct TestScene {
    name: &'static str,
    city: City,
    scene: SceneGpu,
    occluders: OccluderMeshes,
    lod: LodScene,
    package: &'static ScenePackage,
}

fn prepare(gpu: &GpuContext, name: &'static str, package: &'static ScenePackage) -> TestScene {
    let occluders = package.occluders.as_ref().expect("occluders");
    assert!(!occluders.occluders.is_empty(), "{name}: no occluders");
    let tree = package.cluster_tree.clone().expect("cluster tree");
    let city = package.city();
    TestScene {
        name,
        scene: SceneGpu::upload_city(gpu, &city).expect("the scene fits the GPU"),
        occluders: OccluderMeshes::upload(gpu, occluders).expect("the scene fits the GPU"),
        lod: LodScene::upload(gpu, &city, tree).expect("the scene fits the GPU"),
        city,
        package,
    }
}

/// Loads and preprocesses a scene once per test binary (tests share the CPU work).
fn preprocessed(
    cell: &'static OnceLock<ScenePackage>,
    load: fn() -> City,
) -> &'static ScenePackage {
    cell.get_or_init(|| {
        preprocess(load(), &PreprocessParams::default(), &NoProgress).expect("preprocess")
    })
}

fn generated(gpu: &GpuContext) -> TestScene {
    static CELL: OnceLock<ScenePackage> = OnceLock::new();
    let package = preprocessed(&CELL, || {
        generate_city(&GenerateParams::new(1500, 11)).expect("generate")
    });
    prepare(gpu, "generated-1500", package)
}

/// A generated city of 20,000 buildings: deeper trees and wider cuts than the small cities (a
/// tree walk that dropped nodes on wide cuts lost a visible building at 1M buildings).
fn generated_wide(gpu: &GpuContext) -> TestScene {
    static CELL: OnceLock<ScenePackage> = OnceLock::new();
    let package = preprocessed(&CELL, || {
        generate_city(&GenerateParams::new(20_000, 13)).expect("generate")
    });
    prepare(gpu, "generated-20000", package)
}

fn chelsea(gpu: &GpuContext) -> TestScene {
    static CELL: OnceLock<ScenePackage> = OnceLock::new();
    let package = preprocessed(&CELL, || {
        load_cities(&[PathBuf::from(CHELSEA)], &LoadOptions::default()).expect("load Chelsea")
    });
    prepare(gpu, "chelsea", package)
}

fn den_haag(gpu: &GpuContext) -> TestScene {
    static CELL: OnceLock<ScenePackage> = OnceLock::new();
    let package = preprocessed(&CELL, || {
        load_cities(&[PathBuf::from(DEN_HAAG)], &LoadOptions::default()).expect("load Den Haag")
    });
    prepare(gpu, "den-haag", package)
}

/// A point on a random street, 1.7 m above the ground, looking along a random heading. A city
/// without streets (Den Haag's CityJSON) gets a random pose of its generated street-level walk
/// (a line through free space) with a random heading.
fn street_camera(rng: &mut Rng, city: &City) -> Camera {
    let streets: Vec<_> = city
        .streets
        .iter()
        .filter(|s| s.line.0.len() >= 2)
        .collect();
    if streets.is_empty() {
        let walk = street_walk(city, 64);
        let pose = walk.poses[rng.next_u64() as usize % walk.poses.len()];
        // CityJSON keeps absolute heights (Den Haag's bases stand 3 m and more above NAP 0): the
        // eye stands 1.7 m above the lowest building base rather than above z = 0.
        let ground_m = city
            .buildings
            .iter()
            .map(|b| b.bounds().0.z)
            .fold(f32::INFINITY, f32::min);
        let mut position = pose.position;
        if ground_m.is_finite() {
            position.z = ground_m + 1.7;
        }
        return Camera::new(
            position,
            rng.range(0.0, std::f32::consts::TAU),
            rng.range(-0.1, 0.25),
        );
    }
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

/// A random street-level (`street`) or aerial camera and the first frame of a short move to it
/// (a few metres and degrees away): `(before, camera)`.
fn short_move(rng: &mut Rng, scene: &TestScene, street: bool) -> (Camera, Camera) {
    let camera = if street {
        street_camera(rng, &scene.city)
    } else {
        aerial_camera(rng, &scene.scene)
    };
    let mut before = camera;
    before.position += Vec3::new(rng.range(-4.0, 4.0), rng.range(-4.0, 4.0), 0.0);
    before.yaw_rad += rng.range(-0.3, 0.3);
    (before, camera)
}

/// The configurations under test: the default, occluders (with the occluder gate, the
/// default), and occluders without the gate (the frustum-only early cull).
fn configurations() -> [(&'static str, CullingOptions); 3] {
    [
        ("hzb", CullingOptions::default()),
        (
            "occluders",
            CullingOptions {
                occluders: true,
                occluder_gate: true,
                ..CullingOptions::default()
            },
        ),
        (
            "occluders ungated",
            CullingOptions {
                occluders: true,
                occluder_gate: false,
                ..CullingOptions::default()
            },
        ),
    ]
}

/// The GPU (or `None`: skip the test), a harness on it and the scene `load` prepares.
fn harness(test: &str, load: fn(&GpuContext) -> TestScene) -> Option<(Harness, TestScene)> {
    let gpu = gpu_or_skip(test)?;
    let scene = load(&gpu);
    Some((Harness::new(gpu), scene))
}

struct Harness {
    gpu: GpuContext,
    renderer: CullingRenderer,
    oracle: Oracle,
    brute: BruteRenderer,
    /// The colour of the last frame (RGBA8 sRGB).
    last_rgba: Vec<u8>,
    /// The combined frame's `CullingOptions::occluder_gate`.
    lod_gate: bool,
    /// The combined frame's cut computed by the GPU (the tree cull) instead of the CPU.
    lod_tree: bool,
}

impl Harness {
    fn new(gpu: GpuContext) -> Harness {
        Harness {
            renderer: CullingRenderer::new(&gpu, BruteRenderer::PNG_FORMAT),
            oracle: Oracle::new(&gpu),
            brute: BruteRenderer::new(&gpu, BruteRenderer::PNG_FORMAT),
            last_rgba: Vec::new(),
            lod_gate: true,
            lod_tree: false,
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

    /// The oracle's exact visible set of `camera`.
    fn visible_set(&self, scene: &TestScene, camera: &Camera, (w, h): (u32, u32)) -> VisibleSet {
        self.oracle
            .visible_set(&self.gpu, &scene.scene, camera, w, h)
            .expect("oracle")
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
        let visible = self.visible_set(scene, camera, size);
        let missing = Undrawn::of(&visible, &out);
        assert!(
            missing.ids.is_empty(),
            "{}, {config}, {}x{}, camera {}: visible buildings {:?} not drawn \
             (pixels {:?})",
            scene.name,
            size.0,
            size.1,
            camera.to_arg_string(),
            missing.ids,
            missing.pixels,
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

/// The oracle-visible buildings a frame did not draw, with their visible pixels (for the failure
/// message).
struct Undrawn {
    ids: Vec<u32>,
    pixels: Vec<u32>,
}

impl Undrawn {
    fn of(visible: &VisibleSet, out: &FrameOutput) -> Undrawn {
        let ids: Vec<u32> = visible
            .visible
            .iter()
            .map(|b| b.0)
            .filter(|b| out.drawn.binary_search(b).is_err())
            .collect();
        Undrawn {
            pixels: ids
                .iter()
                .map(|&b| visible.pixel_counts[b as usize])
                .collect(),
            ids,
        }
    }
}

/// What one combined frame showed about the LOD side.
#[derive(Debug, Default, Clone, Copy)]
struct LodCounts {
    /// Oracle-visible buildings.
    visible: usize,
    /// Oracle-visible buildings drawn only through a drawn cluster (not themselves).
    visible_through_clusters: usize,
    clusters_drawn: u32,
    occlusion_culled: u32,
    early_drawn: u32,
}

impl Harness {
    /// The LOD cut of `camera` under `criterion` (`None`: the scene's altitude preset) after
    /// B-Quadtree culling, as the `all` mode makes it.
    fn cut(
        scene: &TestScene,
        criterion: Option<LodCriterion>,
        camera: &Camera,
        (w, h): (u32, u32),
    ) -> LodFrame {
        let blocks = visible_blocks(
            &scene.package.quadtree,
            scene.package.blocks.blocks.len(),
            camera,
            w,
            h,
        );
        let criterion = criterion.unwrap_or_else(|| scene.lod.default_criterion(camera));
        scene.lod.select(camera, w, h, criterion, Some(&blocks))
    }

    /// Renders the combined frame (LOD cut + HiZ + occluders) of `camera` and asserts that every
    /// oracle-visible building is drawn itself or through a drawn cluster containing it, that
    /// the next frame's visibility holds it, and that the counts add up.
    fn check_lod(
        &mut self,
        scene: &TestScene,
        criterion: Option<LodCriterion>,
        visibility: &mut Visibility,
        camera: &Camera,
        size: (u32, u32),
    ) -> (FrameOutput, LodFrame, LodCounts) {
        let (w, h) = size;
        let cut = Self::cut(scene, criterion, camera, size);
        let options = CullingOptions {
            occluders: true,
            occluder_gate: self.lod_gate,
            ..CullingOptions::default()
        };
        let target =
            OffscreenTarget::new(&self.gpu, w, h, BruteRenderer::PNG_FORMAT).expect("target");
        let out = if self.lod_tree {
            let criterion = criterion.unwrap_or_else(|| scene.lod.default_criterion(camera));
            self.renderer.render_tree(
                &self.gpu,
                &scene.lod,
                criterion,
                Some(&scene.occluders),
                &options,
                visibility,
                camera,
                &target.colour_view,
                size,
            )
        } else {
            self.renderer.render_lod(
                &self.gpu,
                &scene.lod,
                &cut,
                Some(&scene.occluders),
                &options,
                visibility,
                camera,
                &target.colour_view,
                size,
            )
        }
        .expect("combined frame");
        let visible = self.visible_set(scene, camera, size);
        let missing = Undrawn::of(&visible, &out);
        assert!(
            missing.ids.is_empty(),
            "{}, combined {criterion:?}, {w}x{h}, camera {}: visible buildings {:?} not \
             drawn, neither themselves nor through a cluster (pixels {:?}, in the cut {:?})",
            scene.name,
            camera.to_arg_string(),
            missing.ids,
            missing.pixels,
            missing
                .ids
                .iter()
                .map(|b| scene.lod.covered(&cut).binary_search(b).is_ok())
                .collect::<Vec<_>>(),
        );
        // Whatever was seen is early next frame, whichever cut comes next.
        let forgotten: Vec<u32> = visible
            .visible
            .iter()
            .map(|b| b.0)
            .filter(|&b| !visibility.is_visible(b))
            .collect();
        assert!(
            forgotten.is_empty(),
            "{}: visible buildings {forgotten:?} not kept for the next frame",
            scene.name
        );
        let st = &out.stats;
        if self.lod_tree {
            // The GPU's cut: each building is culled (alone or with its subtree) or kept at
            // most once; an early one may also be culled by the walk.
            assert!(
                st.frustum_culled + st.occlusion_culled + st.drawn
                    <= st.building_count + st.early_drawn,
                "{st:?}"
            );
            assert!(st.candidates > 0 || out.drawn.is_empty());
        } else {
            // Drawn only from the cut; the counts add up.
            let covered = scene.lod.covered(&cut);
            assert!(out.drawn.iter().all(|b| covered.binary_search(b).is_ok()));
            assert_eq!(st.candidates as usize, cut.draw_ids.len());
            assert_eq!(
                st.frustum_culled + st.occlusion_culled + st.cull_kept,
                st.candidates
            );
            assert!(
                out.clusters
                    .iter()
                    .all(|c| cut.cut.clusters.binary_search(c).is_ok())
            );
        }
        assert_eq!(st.drawn as usize, out.drawn.len());
        assert_eq!(st.clusters_drawn as usize, out.clusters.len());
        assert!(st.buildings_through_clusters <= st.drawn);
        let visible_through_clusters = visible
            .visible
            .iter()
            .filter(|b| cut.cut.buildings.binary_search(&b.0).is_err())
            .count();
        let counts = LodCounts {
            visible: visible.len(),
            visible_through_clusters,
            clusters_drawn: st.clusters_drawn,
            occlusion_culled: st.occlusion_culled,
            early_drawn: st.early_drawn,
        };
        (out, cut, counts)
    }
}

/// The combined frame over random cameras as [`sweep`] does: each camera as the second frame of
/// a short move, under the altitude preset (Chang ε = τ = 1 px at street level, 2 px above the
/// roofs) and Yang's paper tolerances (coarser, so more clusters), at a small viewport; then a
/// street and an aerial camera at each of the four named sizes. Asserts that clusters were
/// drawn, that some visible buildings were shown only through clusters, and that occlusion
/// culling removed candidates.
fn sweep_lod(h: &mut Harness, scene: &TestScene, seed: u64, cameras: usize) {
    let mut rng = Rng(seed);
    let mut total = LodCounts::default();
    let mut add = |c: LodCounts| {
        total.visible += c.visible;
        total.visible_through_clusters += c.visible_through_clusters;
        total.clusters_drawn += c.clusters_drawn;
        total.occlusion_culled += c.occlusion_culled;
        total.early_drawn += c.early_drawn;
    };
    let criteria = [None, Some(LodCriterion::YANG_PAPER)];
    for i in 0..cameras {
        let (before, camera) = short_move(&mut rng, scene, i % 2 == 0);
        // Every other pair of cameras through the frustum-only early cull (no gate).
        h.lod_gate = i % 4 < 2;
        for criterion in criteria {
            let mut visibility = Visibility::default();
            let size = (320, 200);
            h.check_lod(scene, criterion, &mut visibility, &before, size);
            add(h
                .check_lod(scene, criterion, &mut visibility, &camera, size)
                .2);
        }
    }
    for size in [(1280, 720), (1366, 768), (1001, 777), (640, 480)] {
        let street = street_camera(&mut rng, &scene.city);
        let aerial = aerial_camera(&mut rng, &scene.scene);
        let mut visibility = Visibility::default();
        for camera in [street, aerial] {
            add(h.check_lod(scene, None, &mut visibility, &camera, size).2);
        }
    }
    eprintln!("{}: combined frame {total:?}", scene.name);
    assert!(total.clusters_drawn > 0, "{}: no cluster drawn", scene.name);
    assert!(
        total.visible_through_clusters > 0,
        "{}: no visible building was shown through a cluster",
        scene.name
    );
    assert!(
        total.occlusion_culled > 0,
        "{}: nothing occlusion-culled",
        scene.name
    );
    assert!(total.early_drawn > 0, "{}: nothing drawn early", scene.name);
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
        let (before, camera) = short_move(&mut rng, scene, street);
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
    let Some((mut h, scene)) = harness("two_phase generated", generated) else {
        return;
    };
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
    let Some((mut h, scene)) = harness("two_phase chelsea", chelsea) else {
        return;
    };
    sweep(&mut h, &scene, 0x5eed_0002, 12);
}

#[test]
fn den_haag_is_conservative() {
    let Some((mut h, scene)) = harness("two_phase den haag", den_haag) else {
        return;
    };
    sweep(&mut h, &scene, 0x5eed_0004, 12);
}

#[test]
fn generated_city_combined_frame_is_conservative() {
    let Some((mut h, scene)) = harness("two_phase combined generated", generated) else {
        return;
    };
    sweep_lod(&mut h, &scene, 0x5eed_0101, 16);
}

#[test]
fn chelsea_combined_frame_is_conservative() {
    let Some((mut h, scene)) = harness("two_phase combined chelsea", chelsea) else {
        return;
    };
    sweep_lod(&mut h, &scene, 0x5eed_0102, 10);
}

#[test]
fn den_haag_combined_frame_is_conservative() {
    let Some((mut h, scene)) = harness("two_phase combined den haag", den_haag) else {
        return;
    };
    sweep_lod(&mut h, &scene, 0x5eed_0103, 10);
}

/// A camera diving from high above the city to street level and climbing back, one visibility
/// carried through: the LOD cut changes from frame to frame (clusters refined on the way down,
/// merged on the way up), every frame has zero false culls, and buildings that were visible
/// through a cluster are drawn early as themselves once the cut refines that cluster.
#[test]
fn lod_cut_changes_between_frames_and_nothing_visible_is_dropped() {
    let Some((mut h, scene)) = harness("two_phase lod changes", generated) else {
        return;
    };
    let (lo, hi) = scene.scene.bounds;
    let centre = (lo + hi) * 0.5;
    let size = (400, 240);
    let steps = 9;
    let mut poses: Vec<Camera> = (0..steps)
        .map(|i| {
            let t = i as f32 / (steps - 1) as f32;
            // From 700 m up and 600 m back to 3 m above the ground near the centre.
            let height_m = 700.0 * (1.0 - t).powi(2) + 3.0;
            let back_m = 600.0 * (1.0 - t) + 20.0;
            Camera::new(
                Vec3::new(centre.x - back_m, centre.y - 0.3 * back_m, height_m),
                0.3,
                -0.9 * (1.0 - t) - 0.05,
            )
        })
        .collect();
    let down = poses.clone();
    poses.extend(down.into_iter().rev().skip(1));
    let runs = [None, Some(LodCriterion::YANG_PAPER)]
        .into_iter()
        .flat_map(|c| [(c, false), (c, true)]);
    for (criterion, ungated) in runs {
        h.lod_gate = !ungated;
        let mut visibility = Visibility::default();
        let mut previous: Option<LodFrame> = None;
        let (mut changed, mut inherited, mut inherited_early, mut early) = (0, 0, 0, 0);
        for camera in &poses {
            let before = visibility.fork(&h.gpu);
            let (out, cut, _) = h.check_lod(&scene, criterion, &mut visibility, camera, size);
            if let Some(prev) = &previous {
                if prev.draw_ids != cut.draw_ids {
                    changed += 1;
                }
                let prev_covered = scene.lod.covered(prev);
                // Buildings drawn by a cluster last frame, themselves now, and early because
                // the cluster was visible.
                let heirs: Vec<u32> = cut
                    .cut
                    .buildings
                    .iter()
                    .copied()
                    .filter(|b| prev.cut.buildings.binary_search(b).is_err())
                    .filter(|b| prev_covered.binary_search(b).is_ok() && before.is_visible(*b))
                    .collect();
                inherited += heirs.len();
                // The GPU took them as visible last frame through their cluster's stamp.
                inherited_early += heirs
                    .iter()
                    .filter(|b| out.drawn_early.binary_search(b).is_ok())
                    .count();
                early += out.stats.early_drawn;
            }
            previous = Some(cut);
        }
        eprintln!(
            "{criterion:?}: {} frames, cut changed {changed} times, {inherited} buildings \
             inherited visibility from a cluster ({inherited_early} of them drawn early), \
             {early} drawn early",
            poses.len()
        );
        assert!(
            changed * 2 >= poses.len(),
            "{criterion:?}: the cut changed in only {changed} of {} steps",
            poses.len() - 1
        );
        assert!(
            inherited > 0 && inherited_early > 0,
            "{criterion:?}: no building inherited visibility from a cluster \
             ({inherited} inherited, {inherited_early} drawn early)"
        );
        assert!(early > 0);
    }
}

/// The benchmark's scene of `city` (preprocessed into `package`): its occluders, and its LOD
/// scene when `lod` is set.
fn bench_scene(
    gpu: &GpuContext,
    name: &str,
    city: &City,
    package: &ScenePackage,
    lod: bool,
) -> BenchScene {
    let tree = package.cluster_tree.clone().filter(|_| lod);
    let blocks = (package.blocks.clone(), package.quadtree.clone());
    let mut drawable =
        DrawableScene::upload_city(gpu, city, tree, Some(blocks)).expect("the scene fits the GPU");
    drawable.occluders = package
        .occluders
        .as_ref()
        .map(|set| OccluderMeshes::upload(gpu, set).expect("the scene fits the GPU"));
    BenchScene {
        name: name.into(),
        drawable,
        sphere: CitySphere::of(city),
    }
}

/// The benchmark's configuration for `modes` at 320×200, no frames written.
fn bench_config(modes: Vec<Mode>) -> BenchConfig {
    BenchConfig {
        modes,
        width: 320,
        height: 200,
        frames_dir: None,
        png_every: 0,
    }
}

/// The benchmark's `all` mode on a small generated scene: street walk and flyover, zero false
/// culls on every frame, fewer buildings drawn than brute force, clusters counted as drawing
/// the buildings under them.
#[test]
fn bench_all_mode_on_a_tiny_scene_has_no_false_cull() {
    let Some(gpu) = gpu_or_skip("two_phase bench all") else {
        return;
    };
    let city = generate_city(&GenerateParams::new(300, 5)).expect("generate");
    let package = preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess");
    let city = package.city();
    let mut scene = bench_scene(&gpu, "tiny", &city, &package, true);
    // Yang's paper tolerances (coarser than the 1–2 px defaults), so the small city's flyover
    // draws cluster meshes.
    if let Some(lod) = scene.drawable.lod.as_mut() {
        lod.criterion = Some(LodCriterion::YANG_PAPER);
    }
    let config = bench_config(vec![Mode::Brute, Mode::Lod, Mode::All]);
    let mut renderers = BenchRenderers::new(&gpu);
    let mut all_culled = 0.0;
    // Cluster meshes drawn over the flyover, by mode: both LOD modes draw some from the air
    // (the bench counts them: draw ids from the building count up).
    let mut clusters = std::collections::BTreeMap::<String, usize>::new();
    for path in [street_walk(&city, 6), flyover(&city, 6)] {
        let records = run_path(&gpu, &mut renderers, &scene, &path, &config).expect("run");
        assert_eq!(records.len(), 3 * path.poses.len());
        if path.name == "flyover" {
            for r in &records {
                *clusters.entry(r.mode.clone()).or_default() += r.clusters;
            }
        }
        for r in &records {
            assert_eq!(
                r.false_culls, 0,
                "{} {} frame {}",
                path.name, r.mode, r.frame
            );
            assert!(r.drawn >= r.visible);
            // The ground is always drawn; buildings whenever some are visible.
            assert!(r.draw_calls > 0, "{r:?}");
            assert!(r.visible == 0 || r.triangles > 0, "{r:?}");
            if r.mode == "all" {
                all_culled += r.culled_fraction;
            }
        }
    }
    assert!(all_culled > 0.0, "mode all culls nothing");
    assert_eq!(clusters["brute"], 0);
    assert!(clusters["lod"] > 0, "{clusters:?}");
    assert!(clusters["all"] > 0, "{clusters:?}");
    // Without a cluster tree the mode is refused, not silently degraded.
    let mut bare = scene;
    bare.drawable.lod = None;
    assert!(matches!(
        run_path(&gpu, &mut renderers, &bare, &street_walk(&city, 2), &config),
        Err(BenchError::NoClusterTree(_))
    ));
}

#[test]
fn fast_turn_draws_the_disoccluded_buildings_and_near_boxes_are_kept() {
    let Some((mut h, scene)) = harness("two_phase turn", generated) else {
        return;
    };
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
        // Nothing is drawn early in a fresh stream: what is drawn, the cull kept.
        let out = h.frame(&scene, &options, &mut visibility, &inside, (320, 200));
        assert!(
            out.drawn.contains(&(id as u32)) && visibility.is_visible(id as u32),
            "{config}: near-crossing box culled"
        );
        // The box test must also keep it when other buildings were drawn early.
        let out = h.frame(&scene, &options, &mut visibility, &inside, (320, 200));
        assert!(
            visibility.is_visible(id as u32),
            "{config}: near-crossing box culled in the second frame"
        );
        assert!(
            h.visible_set(&scene, &inside, (320, 200))
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
    let TestScene { city, package, .. } = generated(&gpu);
    let scene = bench_scene(&gpu, "generated", &city, package, false);
    let path = street_walk(&city, 10);
    // `auto` picks among its plans by cost, frame by frame; every pick is held to the oracle.
    let config = bench_config(vec![Mode::Brute, Mode::Hzb, Mode::Occluders, Mode::Auto]);
    let mut renderers = BenchRenderers::new(&gpu);
    let records = run_path(&gpu, &mut renderers, &scene, &path, &config).expect("run");
    assert_eq!(records.len(), 40);
    for r in &records {
        assert_eq!(
            r.false_culls, 0,
            "{} frame {}: false culls",
            r.mode, r.frame
        );
        assert!(r.drawn >= r.visible);
        assert!(r.pixel_error_colour < 0.002, "{} frame {}", r.mode, r.frame);
        // `auto` starts its ladder with brute force, so only its later frames must cull.
        if r.mode != "brute" && r.mode != "auto" {
            assert!(
                r.culled_fraction > 0.0,
                "{} frame {} culls nothing",
                r.mode,
                r.frame
            );
        }
    }
    // `auto` tried every plan of its ladder at the first pose before timing, and runs the one
    // it measured cheapest (on a small city and a software adapter that may be brute force,
    // so whether its timed frames cull depends on the machine's timings).
    let planner = renderers.auto_planner().expect("auto ran");
    assert!(planner.candidates().len() > 2);
    assert!(
        planner.costs_ms().iter().all(Option::is_some),
        "auto measured every plan: {:?}",
        planner.costs_ms()
    );
    // Without occluders a scene refuses the occluders mode rather than silently skipping it.
    let mut bare = scene;
    bare.drawable.occluders = None;
    let config = BenchConfig {
        modes: vec![Mode::Occluders],
        ..config
    };
    assert!(matches!(
        run_path(&gpu, &mut renderers, &bare, &path, &config),
        Err(BenchError::NoOccluders(_))
    ));
}

/// The occluder gate (`CullingOptions::occluder_gate`) after a jump between two random street
/// cameras, so that most of last frame's visible set is stale: the frame draws every building
/// the oracle sees and the image of brute force; it draws a subset of what the same frame with
/// nothing visible before draws (the gate culls against that frame's pyramid, the main cull
/// against more depth); the gate's kept and kept-out candidates add up to last frame's visible
/// buildings in the frustum; and over the jumps the gate keeps some out and draws some early.
/// Generated city and Den Haag, 320 × 200 and 1001 × 777.
#[test]
fn occluder_gate_after_a_jump_draws_a_subset_of_a_cold_frame() {
    let Some((mut h, generated_city)) = harness("two_phase occluder gate", generated) else {
        return;
    };
    let den_haag = den_haag(&h.gpu);
    let gated = CullingOptions {
        occluders: true,
        occluder_gate: true,
        ..CullingOptions::default()
    };
    let ungated = CullingOptions {
        occluder_gate: false,
        ..gated
    };
    let mut rng = Rng(0x5eed_6a7e);
    let (mut kept_out, mut early, mut drawn_gated, mut drawn_ungated, mut drawn_cold) =
        (0u32, 0u32, 0usize, 0usize, 0usize);
    for scene in [&generated_city, &den_haag] {
        for jump in 0..8 {
            let size = if jump % 4 == 3 {
                (1001, 777)
            } else {
                (320, 200)
            };
            let before = street_camera(&mut rng, &scene.city);
            let camera = street_camera(&mut rng, &scene.city);
            let mut visibility = Visibility::default();
            h.check(scene, ("gated", &gated), &mut visibility, &before, size);
            let mut ungated_visibility = visibility.fork(&h.gpu);
            // Last frame's visible buildings in this frame's frustum: the gate's candidates.
            let frustum = citywalk_scenes::frustum::Frustum::from_view_proj(
                camera.view_proj(size.0 as f32 / size.1 as f32),
            );
            let candidates = visibility
                .visible_ids()
                .into_iter()
                .filter(|&b| {
                    let r = &scene.scene.records[b as usize];
                    frustum.classify_aabb(
                        Vec3::from_array(r.bounds_min_m),
                        Vec3::from_array(r.bounds_max_m),
                    ) != citywalk_scenes::frustum::Containment::Outside
                })
                .count() as u32;
            let (out, _) = h.check(scene, ("gated", &gated), &mut visibility, &camera, size);
            let error = h.error_vs_brute(scene, &camera, size);
            assert!(
                error < 0.002,
                "{}, gated, {size:?}: {:.3} % of pixels differ from brute force",
                scene.name,
                100.0 * error
            );
            let s = &out.stats;
            assert_eq!(
                s.early_drawn + s.gate_culled,
                candidates,
                "{}, camera {}: early {} + kept out {} != candidates {candidates}",
                scene.name,
                camera.to_arg_string(),
                s.early_drawn,
                s.gate_culled
            );
            let (cold, _) = h.check(
                scene,
                ("cold", &gated),
                &mut Visibility::default(),
                &camera,
                size,
            );
            let extra: Vec<u32> = out
                .drawn
                .iter()
                .copied()
                .filter(|b| cold.drawn.binary_search(b).is_err())
                .collect();
            assert!(
                extra.is_empty(),
                "{}, camera {} after {}: gated frame drew {extra:?} a cold frame did not",
                scene.name,
                camera.to_arg_string(),
                before.to_arg_string()
            );
            let (plain, _) = h.check(
                scene,
                ("ungated", &ungated),
                &mut ungated_visibility,
                &camera,
                size,
            );
            kept_out += s.gate_culled;
            early += s.early_drawn;
            drawn_gated += out.drawn.len();
            drawn_cold += cold.drawn.len();
            drawn_ungated += plain.drawn.len();
        }
    }
    eprintln!(
        "occluder gate after jumps: {early} drawn early, {kept_out} kept out; drawn: gated \
         {drawn_gated}, ungated {drawn_ungated}, nothing visible before {drawn_cold}"
    );
    assert!(kept_out > 0, "the gate never kept a stale candidate out");
    assert!(early > 0, "the gate never let a candidate through");
}

/// Paths lavapipe would otherwise never take in CI. (1) A frame with no candidate at all: the
/// camera looks away from the city, the LOD cut is empty, the cull pass runs over zero boxes
/// (still timed, so no timestamp query is resolved unwritten) and the late pass is skipped.
/// (2) A device without `MULTI_DRAW_INDIRECT_COUNT`: the late pass walks every command, those
/// past the kept ones empty; the oracle sweeps must hold there too.
#[test]
fn empty_cut_and_devices_without_draw_count_stay_correct() {
    let Some((mut h, scene)) = harness(
        "empty_cut_and_devices_without_draw_count_stay_correct",
        generated,
    ) else {
        return;
    };
    let (lo, hi) = scene.scene.bounds;
    let centre_y = 0.5 * (lo.y + hi.y);
    // East of the city, looking further east.
    let camera = Camera::new(Vec3::new(hi.x + 300.0, centre_y, 30.0), 0.0, 0.0);
    let size = (640, 480);
    let cut = Harness::cut(&scene, None, &camera, size);
    assert!(cut.draw_ids.is_empty(), "cut not empty: {:?}", cut.draw_ids);
    let target =
        OffscreenTarget::new(&h.gpu, size.0, size.1, BruteRenderer::PNG_FORMAT).expect("target");
    let mut visibility = Visibility::default();
    for frame in 0..2 {
        let out = h
            .renderer
            .render_lod(
                &h.gpu,
                &scene.lod,
                &cut,
                Some(&scene.occluders),
                &CullingOptions {
                    occluders: true,
                    ..CullingOptions::default()
                },
                &mut visibility,
                &camera,
                &target.colour_view,
                size,
            )
            .expect("empty frame");
        assert_eq!(
            (out.stats.candidates, out.stats.drawn),
            (0, 0),
            "frame {frame}"
        );
        assert!(out.drawn.is_empty());
        if h.gpu.has(wgpu::Features::TIMESTAMP_QUERY) {
            let gpu = &out.stats.gpu;
            assert!(gpu.phase_ms("cull").is_some(), "frame {frame}: {gpu:?}");
            assert_eq!(gpu.phase_ms("late"), None, "frame {frame}: {gpu:?}");
        }
    }
    assert!(h.visible_set(&scene, &camera, size).is_empty());

    // The same sweeps on a device that lacks the draw-count feature.
    let gpu = GpuContext::headless_with_features(
        citywalk_runtime::gpu::WANTED_FEATURES - wgpu::Features::MULTI_DRAW_INDIRECT_COUNT,
    )
    .expect("the adapter found above");
    assert!(!gpu.has(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT));
    let scene = generated(&gpu);
    let mut h = Harness::new(gpu);
    sweep(&mut h, &scene, 0x5eed_0001, 8);
    sweep_lod(&mut h, &scene, 0x5eed_0101, 16);
}

/// The combined frame with the cut computed on the GPU (the tree cull, which also culls whole
/// subtrees against the pyramid), held to the same oracle sweeps as the CPU cut.
fn sweep_gpu_cut(test: &str, load: fn(&GpuContext) -> TestScene, seed: u64, cameras: usize) {
    let Some((mut h, scene)) = harness(test, load) else {
        return;
    };
    h.lod_tree = true;
    assert!(
        h.renderer.runs_tree(&scene.lod),
        "{}: this adapter cannot run the tree cull",
        scene.name
    );
    sweep_lod(&mut h, &scene, seed, cameras);
}

#[test]
fn generated_city_gpu_cut_frame_is_conservative() {
    sweep_gpu_cut("two_phase gpu cut generated", generated, 0x5eed_0201, 16);
}

#[test]
fn chelsea_gpu_cut_frame_is_conservative() {
    sweep_gpu_cut("two_phase gpu cut chelsea", chelsea, 0x5eed_0202, 10);
}

#[test]
fn den_haag_gpu_cut_frame_is_conservative() {
    sweep_gpu_cut("two_phase gpu cut den haag", den_haag, 0x5eed_0203, 10);
}

/// The tree cull's kept draw ids against its CPU reference
/// (`citywalk_runtime::hzb::reference::tree_cull`) over the pyramid the frame culled against:
/// the GPU keeps everything the reference keeps (its tests are widened for rounding) and at most
/// a few more; on street and aerial cameras of two generated cities (1,500 and 20,000 buildings)
/// and Den Haag, at two sizes,
/// with the walk dispatched with the adapter's workgroup count.
#[test]
fn gpu_cut_matches_its_cpu_reference() {
    use citywalk_runtime::hzb::reference::tree_cull;
    use citywalk_runtime::lod::LodView;
    use citywalk_runtime::lod::gpu_tree::{TreeArrays, tree_params};
    use citywalk_runtime::lod::scene::cull_records;

    let Some((mut h, generated_city)) = harness("two_phase gpu cut reference", generated) else {
        return;
    };
    let den_haag = den_haag(&h.gpu);
    let wide = generated_wide(&h.gpu);
    let mut rng = Rng(0x5eed_0301);
    let (mut compared, mut extra, mut clusters) = (0usize, 0usize, 0usize);
    for scene in [&generated_city, &den_haag, &wide] {
        let lod = &scene.lod;
        let arrays = TreeArrays::build(&lod.tree, lod.building_count);
        // The records the GPU cull tests (on the GPU only), made again as preprocessing does.
        let cull_records = cull_records(&lod.gpu_scene.records, lod.building_count, &lod.tree.tree);
        // The plain and LOD scenes share their parts.
        let parts = &scene.scene.parts;
        for i in 0..8 {
            let size = if i % 2 == 0 { (1001, 777) } else { (320, 200) };
            let camera = if i % 4 < 2 {
                street_camera(&mut rng, &scene.city)
            } else {
                aerial_camera(&mut rng, &scene.scene)
            };
            let criterion = lod.default_criterion(&camera);
            let target = OffscreenTarget::new(&h.gpu, size.0, size.1, BruteRenderer::PNG_FORMAT)
                .expect("target");
            let options = CullingOptions {
                occluders: true,
                occluder_gate: false,
                ..CullingOptions::default()
            };
            // A fresh stream: nothing drawn early, so what the walk keeps is the frame's set.
            let out = h
                .renderer
                .render_tree(
                    &h.gpu,
                    lod,
                    criterion,
                    Some(&scene.occluders),
                    &options,
                    &mut Visibility::default(),
                    &camera,
                    &target.colour_view,
                    size,
                )
                .expect("tree frame");
            assert!(out.drawn_early.is_empty());
            let pyramid = h
                .renderer
                .pyramid()
                .expect("a pyramid")
                .read_back(&h.gpu)
                .expect("pyramid");
            let mut params = tree_params(
                &LodView::new(&camera, size.0, size.1),
                criterion,
                lod.building_count,
            );
            params.root = arrays.root;
            params.node_count = arrays.nodes.len() as u32;
            let view_proj = camera.view_proj(size.0 as f32 / size.1 as f32);
            let reference: Vec<u32> = tree_cull(
                &pyramid,
                &arrays,
                (&cull_records, parts),
                view_proj,
                &params,
            )
            .into_iter()
            // The output lists clusters with a mesh only.
            .filter(|&id| id < lod.building_count || cull_records[id as usize].index_count > 0)
            .collect();
            let mut gpu: Vec<u32> = out.drawn_themselves.clone();
            gpu.extend(out.clusters.iter().map(|&c| lod.building_count + c));
            gpu.sort_unstable();
            let missing: Vec<u32> = reference
                .iter()
                .copied()
                .filter(|id| gpu.binary_search(id).is_err())
                .collect();
            assert!(
                missing.is_empty(),
                "{} camera {} {size:?}: the reference keeps {missing:?}, the GPU does not",
                scene.name,
                camera.to_arg_string()
            );
            let more = gpu.len() - reference.len();
            assert!(
                more <= 2 + reference.len() / 50,
                "{} camera {} {size:?}: the GPU keeps {more} more than the reference's {}",
                scene.name,
                camera.to_arg_string(),
                reference.len()
            );
            compared += reference.len();
            extra += more;
            clusters += out.clusters.len();
        }
    }
    eprintln!(
        "tree cull: {compared} kept by the reference, {extra} more by the GPU, {clusters} clusters"
    );
    assert!(compared > 0 && clusters > 0);
}

/// A polled tree report is whole or none: a frame whose kept or early list outgrew its report
/// slot gives no output when polled (part of the lists would undercount what was drawn) and
/// makes the next reports larger; the next frame's polled output then equals the same frame
/// waited for, which reads the lists whole.
#[test]
fn a_polled_tree_report_is_whole_or_none() {
    let Some((mut h, scene)) = harness("two_phase polled tree report", generated) else {
        return;
    };
    let lod = &scene.lod;
    let size = (320, 200);
    let target =
        OffscreenTarget::new(&h.gpu, size.0, size.1, BruteRenderer::PNG_FORMAT).expect("target");
    let options = CullingOptions {
        occluders: true,
        occluder_gate: false,
        ..CullingOptions::default()
    };
    // One aerial camera twice: the second frame draws the first one's set early.
    let camera = aerial_camera(&mut Rng(0x5eed_0302), &scene.scene);
    let cameras = [camera, camera];
    // Waited for: the reference outputs of the two frames.
    let mut visibility = Visibility::default();
    let waited: Vec<FrameOutput> = cameras
        .iter()
        .map(|camera| {
            h.renderer
                .render_tree(
                    &h.gpu,
                    lod,
                    lod.default_criterion(camera),
                    Some(&scene.occluders),
                    &options,
                    &mut visibility,
                    camera,
                    &target.colour_view,
                    size,
                )
                .expect("tree frame")
        })
        .collect();
    let kept = waited[0].drawn_themselves.len() + waited[0].clusters.len();
    assert!(kept > 1, "the first frame keeps {kept}");
    // Polled, with a one-entry report: the first frame's report is dropped and grows the
    // slot; the second is read whole.
    let mut renderer = CullingRenderer::new(&h.gpu, BruteRenderer::PNG_FORMAT);
    renderer.set_report_entries(1);
    let mut visibility = Visibility::default();
    let polled: Vec<Option<FrameOutput>> = cameras
        .iter()
        .map(|camera| {
            renderer
                .submit_tree(
                    &h.gpu,
                    lod,
                    lod.default_criterion(camera),
                    Some(&scene.occluders),
                    &options,
                    &mut visibility,
                    camera,
                    &target.colour_view,
                    size,
                )
                .expect("tree frame");
            h.gpu.wait_idle();
            renderer
                .poll_report(&h.gpu, (&lod.gpu_scene, Some(lod)))
                .expect("poll")
        })
        .collect();
    assert!(polled[0].is_none(), "a report of one entry read in part");
    assert!(renderer.report_entries() as usize >= kept);
    let second = polled[1].as_ref().expect("the grown report is read");
    let w = &waited[1];
    assert_eq!(second.drawn, w.drawn);
    assert_eq!(second.drawn_early, w.drawn_early);
    assert_eq!(second.drawn_themselves, w.drawn_themselves);
    assert_eq!(second.clusters, w.clusters);
    assert_eq!(
        (second.stats.cull_kept, second.stats.triangles),
        (w.stats.cull_kept, w.stats.triangles)
    );
}

/// The same for a candidate frame (every building culled, its kept and early lists written by
/// the cull passes): a polled report whose lists outgrew its slot gives no output and grows
/// the next; the next frame's polled output equals the same frame waited for. A frame that
/// waits reads lists of any length whole, even from a one-entry slot.
#[test]
fn a_polled_candidate_report_is_whole_or_none() {
    let Some((mut h, scene)) = harness("two_phase polled candidate report", generated) else {
        return;
    };
    let size = (320, 200);
    let target =
        OffscreenTarget::new(&h.gpu, size.0, size.1, BruteRenderer::PNG_FORMAT).expect("target");
    let options = CullingOptions {
        occluders: true,
        occluder_gate: true,
        ..CullingOptions::default()
    };
    let camera = aerial_camera(&mut Rng(0x5eed_0303), &scene.scene);
    let cameras = [camera, camera];
    let frames = |renderer: &mut CullingRenderer| -> Vec<FrameOutput> {
        let mut visibility = Visibility::default();
        cameras
            .iter()
            .map(|camera| {
                renderer
                    .render(
                        &h.gpu,
                        &scene.scene,
                        Some(&scene.occluders),
                        &options,
                        &mut visibility,
                        camera,
                        &target.colour_view,
                        size,
                    )
                    .expect("candidate frame")
            })
            .collect()
    };
    let waited = frames(&mut h.renderer);
    let kept = waited[0].stats.cull_kept as usize;
    assert!(kept > 1, "the first frame keeps {kept}");
    assert!(
        waited[1].stats.early_drawn > 1,
        "the second frame draws early"
    );
    // Waited for through a one-entry slot: read whole all the same.
    let mut small = CullingRenderer::new(&h.gpu, BruteRenderer::PNG_FORMAT);
    small.set_report_entries(1);
    let whole = frames(&mut small);
    for (w, s) in waited.iter().zip(&whole) {
        assert_eq!((&s.drawn, &s.drawn_early), (&w.drawn, &w.drawn_early));
        assert_eq!(s.stats.cull_kept, w.stats.cull_kept);
    }
    // Polled from a one-entry slot: none, then whole.
    let mut renderer = CullingRenderer::new(&h.gpu, BruteRenderer::PNG_FORMAT);
    renderer.set_report_entries(1);
    let mut visibility = Visibility::default();
    let polled: Vec<Option<FrameOutput>> = cameras
        .iter()
        .map(|camera| {
            renderer
                .submit(
                    &h.gpu,
                    FrameScene::Buildings(&scene.scene),
                    Some(&scene.occluders),
                    &options,
                    &mut visibility,
                    camera,
                    &target.colour_view,
                    size,
                )
                .expect("candidate frame");
            h.gpu.wait_idle();
            renderer
                .poll_report(&h.gpu, (&scene.scene, None))
                .expect("poll")
        })
        .collect();
    assert!(polled[0].is_none(), "a report of one entry read in part");
    assert!(renderer.report_entries() as usize >= kept);
    let second = polled[1].as_ref().expect("the grown report is read");
    let w = &waited[1];
    assert_eq!(second.drawn, w.drawn);
    assert_eq!(second.drawn_early, w.drawn_early);
    let (a, b) = (&second.stats, &w.stats);
    assert_eq!(
        (
            a.candidates,
            a.cull_kept,
            a.occlusion_culled,
            a.frustum_culled
        ),
        (
            b.candidates,
            b.cull_kept,
            b.occlusion_culled,
            b.frustum_culled
        )
    );
    assert_eq!(
        (a.early_drawn, a.late_drawn, a.gate_culled, a.triangles),
        (b.early_drawn, b.late_drawn, b.gate_culled, b.triangles)
    );
    assert_eq!(
        a.candidates,
        a.cull_kept + a.occlusion_culled + a.frustum_culled
    );
}
