//! The screen-space LOD cut (Chang et al. 2008 §8, Yang et al. 2011 §4) on a generated,
//! preprocessed city: CPU consistency and monotonicity properties, and on the GPU zero false
//! culls against the ID-buffer oracle, fewer triangles from the air, full detail nearby.

use std::sync::OnceLock;

use citywalk_bench::Mode;
use citywalk_bench::run::{BenchConfig, BenchRenderers, BenchScene, pose_camera, run_path};
use citywalk_preprocess::pipeline::{NoProgress, PreprocessParams, preprocess};
use citywalk_runtime::camera::Camera;
use citywalk_runtime::drawable::DrawableScene;
use citywalk_runtime::lod::scene::{LodFrame, LodScene};
use citywalk_runtime::lod::{LodCriterion, LodCut, LodTree, LodView, distance_to_box};
use citywalk_runtime::oracle::Oracle;
use citywalk_runtime::scene_gpu::SceneGpu;
use citywalk_scenes::City;
use citywalk_scenes::camera_path;
use citywalk_scenes::city_sphere::CitySphere;
use citywalk_scenes::cluster_tree::ClusterTree;
use citywalk_scenes::frustum::Containment;
use citywalk_scenes::generate::{GenerateParams, generate_city};
use citywalk_scenes::package::ScenePackage;
use citywalk_tests::gpu::gpu_or_skip;
use glam::Vec3;
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

/// The 1500-building generated city (seed 7), its package and cluster tree, built once per
/// test binary.
fn prepared() -> &'static (City, ClusterTree, ScenePackage) {
    static CELL: OnceLock<(City, ClusterTree, ScenePackage)> = OnceLock::new();
    CELL.get_or_init(|| {
        let city = generate_city(&GenerateParams::new(1500, 7)).expect("generate");
        let package = preprocess(city.clone(), &PreprocessParams::default(), &NoProgress)
            .expect("preprocess");
        let tree = package.cluster_tree.clone().expect("cluster tree");
        (package.city(), tree, package)
    })
}

fn city_and_tree() -> (&'static City, &'static ClusterTree) {
    let (city, tree, _) = prepared();
    (city, tree)
}

fn lod_tree() -> &'static LodTree {
    static CELL: OnceLock<LodTree> = OnceLock::new();
    CELL.get_or_init(|| LodTree::new(city_and_tree().1.clone()))
}

/// For every building, the depth of the node covering it in `cut` (a drawn cluster containing
/// it, or its own leaf), counting covers; landmarks drawn beside their cluster are not covers.
fn cover_depths(tree: &ClusterTree, cut: &LodCut) -> Vec<(u32, Option<u32>)> {
    let mut out = vec![(0u32, None); tree.building_order.len()];
    for &c in &cut.clusters {
        let node = &tree.nodes[c as usize];
        assert!(!node.is_leaf(), "cluster {c} of the cut is a leaf");
        for b in &tree.building_order[node.buildings.0 as usize..node.buildings.1 as usize] {
            let slot = &mut out[b.index()];
            slot.0 += 1;
            slot.1 = Some(node.depth);
        }
    }
    for node in &tree.nodes {
        if !node.is_leaf() {
            continue;
        }
        let b = tree.building_order[node.buildings.0 as usize];
        if cut.buildings.binary_search(&b.0).is_ok() && cut.landmarks.binary_search(&b.0).is_err() {
            let slot = &mut out[b.index()];
            slot.0 += 1;
            slot.1 = Some(node.depth);
        }
    }
    out
}

/// Landmarks are buildings drawn beside a drawn cluster that lists them.
fn check_landmarks(tree: &ClusterTree, cut: &LodCut) {
    for &l in &cut.landmarks {
        assert!(cut.buildings.binary_search(&l).is_ok());
        assert!(
            cut.clusters
                .iter()
                .any(|&c| tree.nodes[c as usize].landmarks.iter().any(|b| b.0 == l)),
            "landmark {l} drawn without a drawn cluster listing it"
        );
    }
}

fn criterion_strategy() -> impl Strategy<Value = LodCriterion> {
    prop_oneof![
        (0.5f32..400.0, 0.5f32..50.0)
            .prop_map(|(epsilon_px, tau_px)| LodCriterion::Chang { epsilon_px, tau_px }),
        (1.0f32..100.0, 10.0f32..2000.0).prop_map(|(delta_h_px, delta_a_px)| {
            LodCriterion::Yang {
                delta_h_px,
                delta_a_px,
            }
        }),
    ]
}

/// A camera somewhere over or around the city, looking anywhere.
fn camera_strategy() -> impl Strategy<Value = Camera> {
    (
        -0.3f32..1.3,
        -0.3f32..1.3,
        1.5f32..1500.0,
        0.0f32..360.0,
        -80.0f32..30.0,
    )
        .prop_map(|(fx, fy, z, yaw, pitch)| {
            let (lo, hi) = root_bounds();
            let p = Vec3::new(lo.x + fx * (hi.x - lo.x), lo.y + fy * (hi.y - lo.y), z);
            Camera::new(p, yaw.to_radians(), pitch.to_radians())
        })
}

fn root_bounds() -> (Vec3, Vec3) {
    let tree = &city_and_tree().1;
    let root = &tree.nodes[tree.root as usize];
    (
        Vec3::from_array(root.bounds_min),
        Vec3::from_array(root.bounds_max),
    )
}

fn config(cases: u32, seed: u64) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

proptest! {
    #![proptest_config(config(48, 0x10d_c07))]

    /// Without culling every building is covered exactly once; with frustum culling at most
    /// once, and exactly once when its own bounds are not outside the frustum.
    #[test]
    fn cut_covers_every_building_once(
        camera in camera_strategy(),
        criterion in criterion_strategy(),
        height_px in 200u32..2000,
    ) {
        let lod = lod_tree();
        let tree = &lod.tree;
        let view = LodView::new(&camera, height_px * 4 / 3, height_px);
        let full = lod.cut(&view.without_culling(), criterion, None);
        check_landmarks(tree, &full);
        for (b, (count, _)) in cover_depths(tree, &full).iter().enumerate() {
            prop_assert_eq!(*count, 1, "building {} covered {} times without culling", b, count);
        }
        let culled = lod.cut(&view, criterion, None);
        check_landmarks(tree, &culled);
        let frustum = view.frustum.expect("frustum");
        let (city, _) = city_and_tree();
        for (b, (count, _)) in cover_depths(tree, &culled).iter().enumerate() {
            prop_assert!(*count <= 1, "building {} covered {} times", b, count);
            let (lo, hi) = city.buildings[b].bounds();
            if frustum.classify_aabb(lo, hi) != Containment::Outside {
                prop_assert_eq!(*count, 1, "building {} in the frustum is not covered", b);
            }
        }
    }

    /// A camera lowered straight down while above every roof is nearer to every node, and a
    /// taller viewport has more pixels per metre: neither makes any building coarser.
    #[test]
    fn closer_camera_is_never_coarser(
        camera in camera_strategy(),
        criterion in criterion_strategy(),
        drop in 0.0f32..1.0,
        height_px in 200u32..1500,
    ) {
        let lod = lod_tree();
        let tree = &lod.tree;
        let (_, hi) = root_bounds();
        let mut high = camera;
        high.position.z = hi.z + 1.0 + camera.position.z;
        let mut low = high;
        low.position.z = hi.z + 1.0 + drop * camera.position.z;
        for node in &tree.nodes {
            let (a, b) = (Vec3::from_array(node.bounds_min), Vec3::from_array(node.bounds_max));
            prop_assert!(distance_to_box(low.position, a, b) <= distance_to_box(high.position, a, b));
        }
        let far = lod.cut(&LodView::new(&high, height_px, height_px).without_culling(), criterion, None);
        let near = lod.cut(&LodView::new(&low, height_px, height_px).without_culling(), criterion, None);
        let big = lod.cut(
            &LodView::new(&high, height_px * 2, height_px * 2).without_culling(),
            criterion,
            None,
        );
        let far_depths = cover_depths(tree, &far);
        for (finer, what) in [(&near, "nearer"), (&big, "larger viewport")] {
            for (b, ((_, d_far), (_, d_fine))) in
                far_depths.iter().zip(cover_depths(tree, finer)).enumerate()
            {
                prop_assert!(d_fine >= *d_far, "building {} coarser with the {} camera", b, what);
            }
        }
    }
}

/// Street-level and aerial cameras of the generated paths.
fn cameras(city: &City) -> Vec<(&'static str, Camera)> {
    let street = camera_path::street_walk(city, 4);
    let flyover = camera_path::flyover(city, 3);
    let mut out: Vec<(&'static str, Camera)> = (0..street.poses.len())
        .map(|i| ("street", pose_camera(&street, i)))
        .collect();
    out.extend((0..flyover.poses.len()).map(|i| ("aerial", pose_camera(&flyover, i))));
    let (lo, hi) = root_bounds();
    out.push(("aerial", Camera::overview(lo, hi)));
    out
}

/// Every oracle-visible building is covered by the cut (zero false culls) at two viewport
/// sizes under both criteria, aerial cameras draw fewer triangles than brute force, and the
/// renderer draws the combined scene.
#[test]
fn lod_cut_has_no_false_culls_and_saves_triangles_from_the_air() {
    let Some(gpu) = gpu_or_skip("lod_cut_has_no_false_culls_and_saves_triangles_from_the_air")
    else {
        return;
    };
    let (city, tree) = city_and_tree();
    let scene = SceneGpu::upload_city(&gpu, city).expect("the scene fits the GPU");
    let lod = LodScene::upload(&gpu, city, tree.clone()).expect("the scene fits the GPU");
    let oracle = Oracle::new(&gpu);
    let brute_triangles = scene.triangle_count as u64;
    let criteria = [
        LodCriterion::CHANG_PAPER,
        LodCriterion::YANG_PAPER,
        LodCriterion::CHANG_FLYOVER,
        LodCriterion::CHANG_WALKTHROUGH,
    ];
    let mut aerial_saving = [0u32; 4];
    let mut aerial = 0;
    for (w, h) in [(1001, 777), (640, 480)] {
        for (kind, camera) in cameras(city) {
            let visible = oracle
                .visible_set(&gpu, &scene, &camera, w, h)
                .expect("oracle");
            if kind == "aerial" {
                aerial += 1;
            }
            for (k, &criterion) in criteria.iter().enumerate() {
                let frame: LodFrame = lod.select(&camera, w, h, criterion, None);
                let covered = lod.covered(&frame);
                // The count the viewer shows, in the cut's size, is the set's.
                assert_eq!(frame.cut.covered_count(&lod.tree.tree), covered.len());
                let missed: Vec<u32> = (0..city.buildings.len() as u32)
                    .filter(|&b| visible.contains(citywalk_scenes::BuildingId(b)))
                    .filter(|b| covered.binary_search(b).is_err())
                    .collect();
                assert!(
                    missed.is_empty(),
                    "{kind} camera {camera:?} {w}x{h} {criterion:?}: visible buildings {missed:?} \
                     not drawn"
                );
                if kind == "aerial" && frame.triangles < brute_triangles {
                    aerial_saving[k] += 1;
                }
                eprintln!(
                    "{kind} {w}x{h} {criterion:?}: {} clusters, {} buildings, {} of {brute_triangles} triangles",
                    frame.cut.clusters.len(),
                    frame.cut.buildings.len(),
                    frame.triangles
                );
            }
        }
    }
    // The paper tolerances must save on every aerial frame; the 1-2 px presets may keep full
    // detail where the whole city is in view.
    for k in [0, 1] {
        assert_eq!(
            aerial_saving[k], aerial,
            "{:?}: only {} of {aerial} aerial frames drew fewer triangles than brute force",
            criteria[k], aerial_saving[k]
        );
    }
    // Both criteria really coarsen somewhere: the overview draws clusters.
    let (lo, hi) = root_bounds();
    let overview = Camera::overview(lo, hi);
    for criterion in [LodCriterion::CHANG_PAPER, LodCriterion::YANG_PAPER] {
        let frame = lod.select(&overview, 1001, 777, criterion, None);
        assert!(
            !frame.cut.clusters.is_empty(),
            "{criterion:?} draws no cluster from the overview"
        );
    }
    // The combined scene renders: the LOD frame is not empty sky.
    let mut renderer = citywalk_runtime::render::selected::SelectedRenderer::new(
        &gpu,
        citywalk_runtime::render::BruteRenderer::PNG_FORMAT,
    );
    let target = citywalk_runtime::render::targets::OffscreenTarget::new(
        &gpu,
        320,
        240,
        citywalk_runtime::render::BruteRenderer::PNG_FORMAT,
    )
    .expect("target");
    let frame = lod.select(&overview, 320, 240, LodCriterion::YANG_PAPER, None);
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
    let calls = renderer.encode(
        &gpu,
        &mut encoder,
        &lod.gpu_scene,
        &overview,
        &frame.draw_ids,
        &target.colour_view,
        &target.depth,
    );
    gpu.queue.submit([encoder.finish()]);
    assert_eq!(calls as usize, frame.draw_ids.len() + 1);
    let rgba = target.read_colour(&gpu).expect("read");
    let centre = ((120 * 320 + 160) * 4) as usize;
    let corner = 0usize;
    assert_ne!(
        rgba[centre..centre + 3],
        rgba[corner..corner + 3],
        "the overview's centre looks like the sky"
    );
}

/// At street level, most buildings near the camera are drawn as themselves under both
/// criteria.
#[test]
fn street_level_draws_nearby_buildings_themselves() {
    let (city, _) = city_and_tree();
    let lod = lod_tree();
    for (kind, camera) in cameras(city) {
        if kind != "street" {
            continue;
        }
        let near: Vec<u32> = city
            .buildings
            .iter()
            .enumerate()
            .filter(|(_, b)| {
                let (lo, hi) = b.bounds();
                distance_to_box(camera.position, lo, hi) < 60.0
            })
            .map(|(i, _)| i as u32)
            .collect();
        assert!(!near.is_empty(), "no building within 60 m of {camera:?}");
        for criterion in [LodCriterion::CHANG_WALKTHROUGH, LodCriterion::YANG_PAPER] {
            let cut = lod.cut(
                &LodView::new(&camera, 1001, 777).without_culling(),
                criterion,
                None,
            );
            let themselves = near
                .iter()
                .filter(|b| cut.buildings.binary_search(b).is_ok())
                .count();
            assert!(
                themselves * 10 >= near.len() * 8,
                "{criterion:?}: only {themselves} of {} buildings within 60 m drawn themselves",
                near.len()
            );
        }
    }
}

/// The benchmark's `lod` mode (Chang presets by altitude on top of B-Quadtree culling) runs
/// through the harness with zero false culls, counting buildings drawn through clusters.
#[test]
fn bench_lod_mode_has_no_false_culls() {
    let Some(gpu) = gpu_or_skip("bench_lod_mode_has_no_false_culls") else {
        return;
    };
    let (city, tree, package) = prepared();
    let config = BenchConfig {
        modes: vec![Mode::Quadtree, Mode::Lod],
        width: 640,
        height: 480,
        frames_dir: None,
        png_every: 0,
    };
    let mut renderers = BenchRenderers::new(&gpu);
    for criterion in [None, Some(LodCriterion::YANG_PAPER)] {
        let blocks = (package.blocks.clone(), package.quadtree.clone());
        let mut drawable = DrawableScene::upload_city(&gpu, city, Some(tree.clone()), Some(blocks))
            .expect("the scene fits the GPU");
        if let Some(lod) = &mut drawable.lod {
            lod.criterion = criterion;
        }
        let scene = BenchScene {
            name: "generated".into(),
            drawable,
            sphere: CitySphere::of(city),
        };
        for path in [
            camera_path::street_walk(city, 3),
            camera_path::flyover(city, 3),
        ] {
            let rows = run_path(&gpu, &mut renderers, &scene, &path, &config).expect("run");
            let lod_rows: Vec<_> = rows.iter().filter(|r| r.mode == "lod").collect();
            assert_eq!(lod_rows.len(), path.poses.len());
            for r in &rows {
                assert_eq!(r.false_culls, 0, "{criterion:?} {}: {r:?}", path.name);
            }
            if criterion.is_some() && path.name == "flyover" {
                let quad: u64 = rows
                    .iter()
                    .filter(|r| r.mode == "quadtree")
                    .map(|r| r.triangles)
                    .sum();
                let lod: u64 = lod_rows.iter().map(|r| r.triangles).sum();
                assert!(lod < quad, "Yang flyover: {lod} triangles, quadtree {quad}");
            }
        }
    }
}

/// Chang et al. §8 landmarks: from the overview, with τ = 2 px, the generated city's tall
/// landmarks are drawn beside the clusters that absorbed them; with τ = 10000 px (the paper's
/// Fig. 13(c), "not maintaining landmarks") none is.
#[test]
fn landmarks_are_drawn_beside_their_clusters_under_tau() {
    let lod = lod_tree();
    let (lo, hi) = root_bounds();
    let view = LodView::new(&Camera::overview(lo, hi), 1001, 777);
    let kept = lod.cut(&view, LodCriterion::CHANG_PAPER, None);
    check_landmarks(&lod.tree, &kept);
    assert!(
        !kept.landmarks.is_empty(),
        "no landmark drawn from the overview ({} clusters)",
        kept.clusters.len()
    );
    let dropped = lod.cut(
        &view,
        LodCriterion::Chang {
            epsilon_px: 100.0,
            tau_px: 10_000.0,
        },
        None,
    );
    assert!(dropped.landmarks.is_empty());
    assert_eq!(dropped.clusters, kept.clusters);
}

/// The records the combined frame culls clusters by hold every building under the cluster (a
/// cluster mesh stops at the mean height, below its tallest buildings) and draw its mesh.
#[test]
fn cluster_cull_records_contain_their_buildings() {
    let (city, tree) = city_and_tree();
    let geometry = citywalk_runtime::lod::scene::lod_geometry(city, tree);
    let n = city.buildings.len() as u32;
    let records = citywalk_runtime::lod::scene::cull_records(&geometry.records, n, tree);
    assert_eq!(records.len(), geometry.records.len());
    assert_eq!(records[..n as usize], geometry.records[..n as usize]);
    let mut grown = 0;
    for (i, node) in tree.nodes.iter().enumerate() {
        let r = &records[n as usize + i];
        let mesh = &geometry.records[n as usize + i];
        assert_eq!(
            (r.first_index, r.index_count, r.base_vertex),
            (mesh.first_index, mesh.index_count, mesh.base_vertex),
            "node {i}: the draw is the cluster mesh's"
        );
        let (lo, hi) = (
            Vec3::from_array(r.bounds_min_m),
            Vec3::from_array(r.bounds_max_m),
        );
        let contains = |a: [f32; 3], b: [f32; 3]| {
            lo.cmple(Vec3::from_array(a)).all() && Vec3::from_array(b).cmple(hi).all()
        };
        assert!(contains(node.bounds_min, node.bounds_max), "node {i}");
        assert!(contains(mesh.bounds_min_m, mesh.bounds_max_m), "node {i}");
        let (s, e) = node.buildings;
        for b in &tree.building_order[s as usize..e as usize] {
            let br = &geometry.records[b.index()];
            assert!(
                contains(br.bounds_min_m, br.bounds_max_m),
                "node {i}, building {}",
                b.0
            );
        }
        if r.bounds_max_m[2] > mesh.bounds_max_m[2] {
            grown += 1;
        }
    }
    // Cluster meshes at the mean height are lower than their tallest building somewhere.
    assert!(grown > 0, "no cluster box had to grow above its mesh");
}

/// The scene the runtime uploads from a package's GPU scene, read in place from the file's
/// mapping, is the one it would build from the city and tree: records, cull parts, index
/// counts, cull records and parents.
#[test]
fn the_package_scene_equals_the_scene_built_from_the_city() {
    use citywalk_runtime::lod::scene::{cull_records, draw_id_parents, lod_geometry};
    use citywalk_runtime::scene_gpu::SceneGeometry;
    use citywalk_scenes::package::WriteOptions;

    let (city, tree, package) = prepared();
    let dir = std::env::temp_dir().join(format!("citywalk-lod-package-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("city.cwk");
    package
        .write(&path, WriteOptions::default())
        .expect("write");
    let read = ScenePackage::read(&path).expect("read");
    assert!(read.gpu_scene.is_mapped());
    let view = read.gpu_scene.view();

    // CPU: the stored arrays are the ones built from the city and tree.
    let n = city.buildings.len();
    let lod = lod_geometry(city, tree);
    assert_eq!(read.gpu_scene.geometry(), lod);
    assert_eq!(
        view.cull_records,
        cull_records(&lod.records, n as u32, tree)
    );
    assert_eq!(view.parents, draw_id_parents(tree, n as u32));
    let plain = SceneGeometry::from_city(city);
    assert_eq!(view.records[..n], plain.records[..]);
    assert_eq!(view.parts, plain.parts);
    assert_eq!(
        view.indices[..plain.building_triangle_count() * 3],
        plain.indices[..plain.building_triangle_count() * 3]
    );
    assert_eq!(view.check_invariants(n, tree.nodes.len()), Ok(()));

    // GPU: the uploaded scenes' CPU copies and counts match the ones made from the city.
    let Some(gpu) = gpu_or_skip("the_package_scene_equals_the_scene_built_from_the_city") else {
        std::fs::remove_dir_all(&dir).ok();
        return;
    };
    let from_city = SceneGpu::upload_city(&gpu, city).expect("the scene fits the GPU");
    let from_package = SceneGpu::upload_package(&gpu, &view).expect("the scene fits the GPU");
    assert_eq!(from_package.records, from_city.records);
    assert_eq!(from_package.parts, from_city.parts);
    assert_eq!(from_package.triangle_count, from_city.triangle_count);
    assert_eq!(from_package.bounds, from_city.bounds);
    let lod_from_city = LodScene::upload(&gpu, city, tree.clone()).expect("the scene fits the GPU");
    let lod_from_package = LodScene::upload_package(&gpu, &from_package, &view, tree.clone())
        .expect("the scene fits the GPU");
    assert_eq!(*lod_from_package.gpu_scene.records, lod.records[..]);
    assert_eq!(
        lod_from_package.gpu_scene.records,
        lod_from_city.gpu_scene.records
    );
    // The plain scene's records are a prefix of the LOD scene's one CPU copy.
    assert_eq!(
        from_package.records[..],
        lod_from_package.gpu_scene.records[..n]
    );
    assert_eq!(
        lod_from_package.gpu_scene.triangle_count,
        lod_from_city.gpu_scene.triangle_count
    );
    assert_eq!(lod_from_package.building_count, n as u32);
    std::fs::remove_dir_all(&dir).ok();
}
