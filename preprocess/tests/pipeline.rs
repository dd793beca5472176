//! Blocks, B-Quadtree and the whole pipeline on a generated city and on Chelsea (OSM), and the
//! package round trip and determinism of preprocessing.

use std::path::PathBuf;

use citywalk_preprocess::blocks::{BlockParams, build_blocks_with};
use citywalk_preprocess::pipeline::{NoProgress, PreprocessParams, preprocess};
use citywalk_preprocess::quadtree::build_quadtree;
use citywalk_scenes::frustum::Frustum;
use citywalk_scenes::generate::{GenerateParams, generate_city};
use citywalk_scenes::package::{Decode, ScenePackage, WriteOptions};
use citywalk_scenes::{City, LoadOptions, load_cities};
use glam::Vec3;

const CHELSEA: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/osm_nyc_chelsea/nyc.osm.pbf"
);

fn generated(buildings: usize, seed: u64) -> City {
    generate_city(&GenerateParams {
        buildings,
        seed,
        ..GenerateParams::default()
    })
    .expect("generate")
}

fn chelsea() -> City {
    load_cities(&[PathBuf::from(CHELSEA)], &LoadOptions::default()).expect("load Chelsea")
}

/// All of the package's invariants, the cluster tree's included.
fn check_package(pkg: &ScenePackage) {
    assert_eq!(pkg.check_invariants(), Ok(()));
}

fn check_blocks_and_quadtree(city: &City) -> (usize, usize) {
    let (blocks, report) = build_blocks_with(city, &BlockParams::default());
    assert_eq!(blocks.check_invariants(city.buildings.len()), Ok(()));
    let tree = build_quadtree(&blocks);
    assert_eq!(tree.check_invariants(), Ok(()));
    assert_eq!(tree.block_bounds.len(), blocks.blocks.len());
    let (lo, med, hi) = blocks.size_stats().expect("blocks");
    eprintln!(
        "{} buildings -> {} blocks ({report:?}); per block min {lo} median {med} max {hi}; \
         quadtree {} nodes, depth {}",
        city.buildings.len(),
        blocks.blocks.len(),
        tree.nodes.len(),
        tree.max_depth()
    );
    (report.street_blocks, report.leftover_buildings)
}

#[test]
fn a_generated_city_has_every_building_in_one_street_block() {
    let city = generated(2_000, 3);
    let (street_blocks, leftover) = check_blocks_and_quadtree(&city);
    // The generator places buildings inside the blocks between its streets.
    assert!(street_blocks > 20, "{street_blocks} street blocks");
    assert!(
        leftover * 10 < city.buildings.len(),
        "{leftover} buildings outside street faces"
    );
}

#[test]
fn chelsea_has_every_building_in_one_block() {
    let city = chelsea();
    assert!(city.buildings.len() > 100);
    let (street_blocks, _) = check_blocks_and_quadtree(&city);
    assert!(
        street_blocks > 10,
        "{street_blocks} street blocks in Chelsea"
    );
}

#[test]
fn hierarchical_culling_over_chelsea_equals_testing_every_block() {
    let city = chelsea();
    let (blocks, _) = build_blocks_with(&city, &BlockParams::default());
    let tree = build_quadtree(&blocks);
    let (lo, hi) = city.bounds().expect("bounds");
    let mut culled_some = false;
    // Street-level cameras on a fixed 6 × 6 grid over the city, eight headings each.
    for i in 0..6 {
        for j in 0..6 {
            let eye = Vec3::new(
                lo.x + (hi.x - lo.x) * (i as f32 + 0.5) / 6.0,
                lo.y + (hi.y - lo.y) * (j as f32 + 0.5) / 6.0,
                1.7,
            );
            for k in 0..8 {
                let yaw = k as f32 * std::f32::consts::FRAC_PI_4;
                let dir = Vec3::new(yaw.cos(), yaw.sin(), -0.05);
                let view = glam::camera::rh::view::look_to_mat4(eye, dir, Vec3::Z);
                let proj =
                    glam::camera::rh::proj::directx::perspective_infinite_reverse(1.0, 1.6, 0.3);
                let frustum = Frustum::from_view_proj(proj * view);
                let mut hierarchical = tree.cull(&frustum);
                hierarchical.sort_unstable();
                let brute = tree.cull_brute_force(&frustum);
                culled_some |= brute.len() < blocks.blocks.len();
                assert_eq!(hierarchical, brute);
            }
        }
    }
    assert!(culled_some, "no camera culled anything");
}

#[test]
fn preprocessing_round_trips_through_a_package_and_is_deterministic() {
    let city = generated(300, 11);
    let params = PreprocessParams::default();
    let a = preprocess(city.clone(), &params, &NoProgress).expect("preprocess");
    let b = preprocess(city, &params, &NoProgress).expect("preprocess again");
    check_package(&a);
    assert!(a.occluders.is_some() && a.cluster_tree.is_some());
    let bytes_a = a.to_bytes(WriteOptions::default()).expect("encode");
    let bytes_b = b.to_bytes(WriteOptions::default()).expect("encode");
    assert!(bytes_a == bytes_b, "two runs gave different packages");
    let back = ScenePackage::from_bytes(&bytes_a).expect("decode");
    // Timings are not in the file.
    let mut expected = a;
    expected.timings.clear();
    assert!(back == expected, "the package did not round trip");
}

/// Counts the pipeline's calls to [`ProgressSink::settle`].
#[derive(Default)]
struct Settles(std::cell::Cell<usize>);

impl citywalk_preprocess::pipeline::ProgressSink for Settles {
    fn stage_started(&self, _: citywalk_preprocess::pipeline::Stage) {}
    fn stage_finished(&self, _: citywalk_preprocess::pipeline::Stage, _: f64, _: &str) {}
    fn settle(&self) {
        self.0.set(self.0.get() + 1);
    }
}

/// Preprocessing into a scratch folder (as the command line does) spills the occluder set to
/// its section as it is built and lays the GPU scene out in a scratch file: the same package
/// bytes, and nothing left in the folder. The progress sink is asked to settle after every
/// stage and every tile of the cluster tree joined.
#[test]
fn preprocessing_into_a_scratch_folder_gives_the_same_package() {
    use citywalk_preprocess::pipeline::{Stage, preprocess_with};
    use citywalk_scenes::package::{SceneStore, SectionKind};

    let city = generated(1_500, 3);
    let params = PreprocessParams {
        tile_buildings: 400,
        ..PreprocessParams::default()
    };
    let in_memory = preprocess(city.clone(), &params, &NoProgress).expect("preprocess");
    let dir = tempfile::tempdir().expect("temp dir");
    let settles = Settles::default();
    let scratch = preprocess_with(
        city,
        &params,
        &settles,
        None,
        SceneStore::ScratchFileIn(dir.path()),
    )
    .expect("preprocess into a scratch folder");
    let tiles = citywalk_preprocess::tiles::plan_tiles(&scratch.quadtree, &scratch.blocks, 400);
    assert!(tiles.len() >= 3, "{} tiles", tiles.len());
    assert_eq!(settles.0.get(), Stage::ALL.len() + 1 + tiles.len());
    assert!(scratch.occluders.is_none(), "the set was spilled");
    let kinds: Vec<_> = scratch.spilled.iter().map(|s| s.kind()).collect();
    assert_eq!(kinds, [SectionKind::Occluders]);
    assert!(scratch.gpu_scene.is_mapped());
    assert_eq!(scratch.provenance.counts, in_memory.provenance.counts);
    let options = WriteOptions::default();
    assert!(
        scratch.to_bytes(options).expect("encode") == in_memory.to_bytes(options).expect("encode"),
        "the packages differ"
    );
    assert!(
        std::fs::read_dir(dir.path())
            .expect("list")
            .next()
            .is_none()
    );
}

#[test]
fn the_package_is_the_same_on_one_thread_and_on_four() {
    // Enough buildings for several chunks of the parallel occluder stage, and several tiles
    // of the cluster tree's tiled build.
    let city = generated(9_000, 5);
    let params = PreprocessParams {
        tile_buildings: 2_000,
        ..PreprocessParams::default()
    };
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool");
        let package = pool
            .install(|| preprocess(city.clone(), &params, &NoProgress))
            .expect("preprocess");
        check_package(&package);
        let tiles =
            citywalk_preprocess::tiles::plan_tiles(&package.quadtree, &package.blocks, 2_000);
        assert!(tiles.len() >= 4, "{} tiles", tiles.len());
        package.to_bytes(WriteOptions::default()).expect("encode")
    };
    assert!(on(1) == on(4), "1 and 4 threads gave different packages");
}

/// The GPU scene is written in place, chunk by chunk on every thread, after its arrays are
/// counted ([`GpuScene::build`]); it must be the bytes of the same arrays laid out in growable
/// vectors and copied, with and without a cluster tree and occluders.
#[test]
fn the_gpu_scene_built_in_place_equals_the_arrays_copied() {
    use citywalk_scenes::occluder_draws::OccluderArrays;
    use citywalk_scenes::package::{GpuScene, SceneStore};
    use citywalk_scenes::scene_geometry::{
        SceneGeometry, cull_records, draw_id_parents, lod_geometry,
    };

    let city = generated(4_200, 7);
    let pkg =
        preprocess(city.clone(), &PreprocessParams::default(), &NoProgress).expect("preprocess");
    let (tree, occluders) = (
        pkg.cluster_tree.as_ref().expect("a tree"),
        pkg.occluders.as_ref().expect("occluders"),
    );
    let n = city.buildings.len() as u32;
    let geometry = lod_geometry(&city, tree);
    let cull = cull_records(&geometry.records, n, tree);
    let copied = GpuScene::from_arrays(
        n,
        geometry,
        Some(cull),
        Some(draw_id_parents(tree, n)),
        OccluderArrays::of(occluders),
    );
    let in_place = GpuScene::build(&city, Some(tree), Some(occluders));
    // Several chunks, each laid out on its own.
    assert!(in_place.view().records.len() > citywalk_scenes::scene_geometry::in_place::CHUNK);
    assert!(!in_place.view().occluders.records.is_empty());
    assert!(
        in_place.bytes() == copied.bytes(),
        "with a tree and occluders"
    );
    assert!(
        pkg.gpu_scene.bytes() == copied.bytes(),
        "the pipeline's scene"
    );
    // The same scene laid out in a scratch file, and written out from there.
    let dir = tempfile::tempdir().expect("temp dir");
    let scratch = GpuScene::build_in(
        &city,
        Some(tree),
        OccluderArrays::of(occluders).view(),
        SceneStore::ScratchFileIn(dir.path()),
    )
    .expect("a scratch file");
    assert!(scratch.is_mapped());
    assert!(scratch.bytes() == copied.bytes(), "in a scratch file");
    let mut written = Vec::new();
    scratch.write_payload(&mut written).expect("write");
    assert!(written == copied.bytes(), "written from the scratch file");
    assert!(
        std::fs::read_dir(dir.path())
            .expect("list")
            .next()
            .is_none(),
        "the scratch file has no name"
    );

    let copied = GpuScene::from_arrays(
        n,
        SceneGeometry::from_city(&city),
        None,
        None,
        Default::default(),
    );
    let in_place = GpuScene::build(&city, None, None);
    assert!(in_place.view().records.len() == city.buildings.len());
    assert!(city.buildings.len() > citywalk_scenes::scene_geometry::in_place::CHUNK);
    assert!(in_place.bytes() == copied.bytes(), "buildings alone");
}

#[test]
fn a_city_without_streets_takes_its_blocks_from_the_cluster_tree() {
    let mut city = generated(400, 5);
    city.streets.clear();
    let pkg = preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess");
    check_package(&pkg);
    assert!(
        pkg.blocks.blocks.len() >= 400 / 20,
        "{} blocks",
        pkg.blocks.blocks.len()
    );
    assert!(pkg.blocks.blocks.iter().all(|b| b.outline.is_none()));
    let tree = pkg.cluster_tree.as_ref().expect("tree");
    // Every block is one subtree: some node holds exactly its buildings and says so.
    for (k, block) in pkg.blocks.blocks.iter().enumerate() {
        assert!(
            tree.nodes
                .iter()
                .any(|n| n.block == Some(k as u32) && n.building_count() == block.buildings.len()),
            "block {k} is not a subtree of the cluster tree"
        );
    }
}

/// The full pipeline on a generated city must give a cluster tree that passes its own check
/// (reported as "node 0: footprint does not contain child 1").
fn pipeline_tree_is_valid(buildings: usize, seed: u64, streets: bool) {
    let mut city = generated(buildings, seed);
    if !streets {
        city.streets.clear();
    }
    let pkg =
        preprocess(city.clone(), &PreprocessParams::default(), &NoProgress).expect("preprocess");
    let tree = pkg.cluster_tree.as_ref().expect("tree");
    assert_eq!(tree.check_invariants(&city), Ok(()));
    check_package(&pkg);
}

#[test]
fn generated_300_seed_11_tree_is_valid() {
    pipeline_tree_is_valid(300, 11, true);
}

#[test]
fn generated_400_seed_5_without_streets_tree_is_valid() {
    pipeline_tree_is_valid(400, 5, false);
}

/// Issue 13: the runtime opens a package without decoding the occluder set or the cluster
/// meshes; it draws both from the GPU scene, which must hold exactly the set's arrays.
#[test]
fn a_package_opened_to_draw_has_the_occluder_sets_arrays_and_no_set() {
    use citywalk_scenes::occluder_draws::OccluderArrays;
    let pkg = preprocess(
        generated(300, 11),
        &PreprocessParams::default(),
        &NoProgress,
    )
    .expect("preprocess");
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("city.cwk");
    pkg.write(&path, WriteOptions::default()).expect("write");
    let full = ScenePackage::read(&path).expect("read");
    let to_draw = ScenePackage::read_as(&path, Decode::Runtime).expect("read to draw");
    let to_walk = ScenePackage::read_as(&path, Decode::RuntimeWithParts).expect("read to walk");
    assert!(
        (to_walk.buildings.iter().zip(&full.buildings))
            .all(|(w, f)| w.parts == f.parts && w.tags.is_empty() && !f.tags.is_empty()),
        "the viewer's buildings have their parts and no tags"
    );
    assert_eq!(to_walk.buildings.len(), full.buildings.len());
    assert_eq!(to_walk.occluders, None);
    assert_eq!(to_walk.cluster_tree, to_draw.cluster_tree);
    let set = full.occluders.as_ref().expect("an occluder set");
    let arrays = OccluderArrays::of(set);
    assert!(!arrays.records.is_empty(), "the city has occluders");
    assert_eq!(to_draw.occluders, None, "the set is not decoded to draw");
    let view = to_draw.gpu_scene.view();
    assert!(to_draw.gpu_scene.is_mapped());
    assert_eq!(view.occluders, arrays.view());
    assert_eq!(
        view.occluders.check_invariants(full.buildings.len() as u32),
        Ok(())
    );
    // Parts and tags are left out to draw; the rest of each building is there.
    let mut buildings = full.buildings.clone();
    for b in &mut buildings {
        assert!(!b.parts.is_empty() && !b.tags.is_empty());
        (b.parts, b.tags) = Default::default();
    }
    assert!(
        to_draw.buildings == buildings,
        "the buildings to draw differ"
    );
    // The cluster meshes are stored once, in the GPU scene: a full read restores them, a read
    // to draw leaves them there, and the footprints out.
    assert_eq!(full.cluster_tree, pkg.cluster_tree);
    let mut tree = full.cluster_tree.expect("a tree");
    assert!(tree.nodes.iter().any(|n| !n.mesh.indices.is_empty()));
    assert!(!tree.vertices.is_empty() && tree.nodes.iter().all(|n| !n.footprint.is_empty()));
    tree.vertices.clear();
    tree.nodes.iter_mut().for_each(|n| {
        n.mesh = Default::default();
        n.footprint.clear();
    });
    assert_eq!(to_draw.cluster_tree, Some(tree));
}
