//! The visibility oracle on hand-built scenes with known answers.

use citywalk_runtime::camera::Camera;
use citywalk_runtime::oracle::{Oracle, VisibleSet};
use citywalk_runtime::scene_gpu::{SceneGeometry, SceneGpu};
use citywalk_scenes::extrude::building_mesh;
use citywalk_scenes::{BuildingId, TriangleMesh};
use citywalk_tests::city_builder::boxes;
use citywalk_tests::gpu::gpu_or_skip;
use glam::Vec3;

/// Camera at the origin, eye height 1.7 m, looking east (+x), level.
fn eye_east() -> Camera {
    Camera::new(Vec3::new(0.0, 0.0, 1.7), 0.0, 0.0)
}

#[test]
fn building_behind_a_wall_is_hidden_and_one_seen_through_a_gap_is_visible() {
    let Some(gpu) = gpu_or_skip("oracle_walls") else {
        return;
    };
    // 0, 1: two walls 20 m east, 40 m tall, leaving a 2 m gap between y = -1 and y = 1.
    // 2: a building directly behind the gap, lower than the walls (seen only through the gap).
    // 3: a building behind the south wall, lower than it and off the gap's sight lines.
    // 4: a building behind the camera.
    let city = boxes(&[
        (20.0, -200.0, 21.0, -1.0, 40.0),
        (20.0, 1.0, 21.0, 200.0, 40.0),
        (60.0, -3.0, 70.0, 3.0, 20.0),
        (60.0, -60.0, 70.0, -40.0, 30.0),
        (-50.0, -10.0, -40.0, 10.0, 30.0),
    ]);
    let scene = SceneGpu::upload_city(&gpu, &city).expect("the scene fits the GPU");
    let oracle = Oracle::new(&gpu);
    let set = oracle
        .visible_set(&gpu, &scene, &eye_east(), 640, 480)
        .expect("oracle");
    assert!(
        set.contains(BuildingId(0)) && set.contains(BuildingId(1)),
        "{set:?}"
    );
    assert!(
        set.contains(BuildingId(2)),
        "building behind the gap not seen: {set:?}"
    );
    assert!(
        !set.contains(BuildingId(3)),
        "building behind the wall seen: {set:?}"
    );
    assert!(
        !set.contains(BuildingId(4)),
        "building behind the camera seen: {set:?}"
    );
    assert_eq!(
        set.visible,
        vec![BuildingId(0), BuildingId(1), BuildingId(2)]
    );
    // The gap is narrow: far fewer pixels of building 2 than of either wall.
    assert!(set.pixel_counts[2] < set.pixel_counts[0] / 4);

    // Turning around shows building 4 and nothing else.
    let back = Camera::new(Vec3::new(0.0, 0.0, 1.7), 180f32.to_radians(), 0.0);
    let set = oracle
        .visible_set(&gpu, &scene, &back, 640, 480)
        .expect("oracle");
    assert_eq!(set.visible, vec![BuildingId(4)]);
}

#[test]
fn pixel_counts_add_up_at_odd_sizes() {
    let Some(gpu) = gpu_or_skip("oracle_pixel_counts") else {
        return;
    };
    let city = boxes(&[
        (10.0, -30.0, 25.0, -5.0, 15.0),
        (12.0, 5.0, 30.0, 20.0, 25.0),
        (45.0, -10.0, 60.0, 10.0, 40.0),
        (80.0, -50.0, 100.0, 50.0, 8.0),
    ]);
    let scene = SceneGpu::upload_city(&gpu, &city).expect("the scene fits the GPU");
    let oracle = Oracle::new(&gpu);
    let camera = Camera::new(Vec3::new(-20.0, 0.0, 5.0), 0.0, 5f32.to_radians());
    for (w, h) in [(1001, 777), (97, 61), (1, 1), (257, 3)] {
        let image = oracle
            .id_image(&gpu, &scene, &camera, w, h)
            .expect("id image");
        assert_eq!(image.pixels.len(), (w * h) as usize);
        let set = VisibleSet::from_id_image(&image, scene.building_count());
        assert_eq!(
            set.total_pixels() as usize,
            image.building_pixel_count(),
            "{w}x{h}"
        );
        // Every id written names a building of the scene.
        assert!(
            image
                .pixels
                .iter()
                .all(|&v| v as usize <= scene.building_count())
        );
        if w * h > 1000 {
            assert!(set.len() >= 3, "{w}x{h}: {set:?}");
        }
    }
    // The odd-size id image agrees with itself across rows: the row padding was removed
    // correctly, so the horizon row (ground below, buildings at the centre) is continuous.
    let image = oracle
        .id_image(&gpu, &scene, &camera, 1001, 777)
        .expect("id image");
    let centre = image.building_at(500, 388);
    assert!(centre.is_some(), "no building at the image centre");
    assert!(oracle.id_image(&gpu, &scene, &camera, 0, 10).is_err());
}

/// Loads the Chelsea extract and checks that the oracle sees a plausible number of buildings
/// from the overview camera. (Needs the OSM loader.)
#[test]
fn chelsea_overview_sees_many_buildings() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenes/data/chelsea.osm.pbf"
    );
    let city = citywalk_scenes::load_city(
        std::path::Path::new(path),
        &citywalk_scenes::LoadOptions::default(),
    )
    .expect("load Chelsea");
    let n = city.buildings.len();
    assert!(n > 1000, "Chelsea has only {n} buildings");
    let Some(gpu) = gpu_or_skip("chelsea_overview") else {
        return;
    };
    let geometry = SceneGeometry::from_city(&city);
    geometry.check_invariants().expect("scene layout");
    // Every building has triangles (2.5D extrusion of valid footprints never comes out empty).
    let empty = geometry
        .records
        .iter()
        .filter(|r| r.index_count == 0)
        .count();
    assert_eq!(empty, 0, "{empty} buildings without triangles");
    let scene = SceneGpu::upload(&gpu, &geometry).expect("the scene fits the GPU");
    let camera = Camera::overview(scene.bounds.0, scene.bounds.1);
    let oracle = Oracle::new(&gpu);
    let set = oracle
        .visible_set(&gpu, &scene, &camera, 1280, 720)
        .expect("oracle");
    eprintln!(
        "Chelsea: {} of {n} buildings visible from the overview",
        set.len()
    );
    // From above at 45° most roofs are visible; many small buildings hide behind taller ones
    // or cover less than a pixel.
    assert!(set.len() > n / 4, "only {} of {n} visible", set.len());
    assert!(set.len() < n, "every building visible from the overview");
}

#[test]
fn a_mesh_past_16_bit_indices_draws_as_the_same_mesh_within_them() {
    let Some(gpu) = gpu_or_skip("oracle_index_formats") else {
        return;
    };
    let city = boxes(&[
        (20.0, -5.0, 30.0, 5.0, 20.0),
        (40.0, -20.0, 50.0, -8.0, 30.0),
    ]);
    let meshes: Vec<TriangleMesh> = city.buildings.iter().map(building_mesh).collect();
    let bounds: Vec<(Vec3, Vec3)> = city.buildings.iter().map(|b| b.bounds()).collect();
    // The same triangles, but the second building's vertex range past 16-bit indices (copies
    // of one of its corners, which no triangle uses, so its box is unchanged).
    let mut padded = meshes.clone();
    let corner = padded[1].positions[0];
    padded[1].positions.resize(70_000, corner);
    let within = SceneGeometry::from_meshes(&meshes, &bounds);
    let past = SceneGeometry::from_meshes(&padded, &bounds);
    let within = SceneGpu::upload(&gpu, &within).expect("the scene fits the GPU");
    let past = SceneGpu::upload(&gpu, &past).expect("the scene fits the GPU");
    assert_eq!(within.index_format, wgpu::IndexFormat::Uint16);
    assert_eq!(past.index_format, wgpu::IndexFormat::Uint32);
    let oracle = Oracle::new(&gpu);
    // Both buildings are seen from the street and from above.
    let above = Camera::new(Vec3::new(-40.0, -8.0, 60.0), 0.0, -35f32.to_radians());
    for camera in [eye_east(), above] {
        let a = oracle
            .visible_set(&gpu, &within, &camera, 320, 240)
            .expect("oracle");
        let b = oracle
            .visible_set(&gpu, &past, &camera, 320, 240)
            .expect("oracle");
        assert_eq!(a.visible, [BuildingId(0), BuildingId(1)]);
        assert_eq!((a.visible, a.pixel_counts), (b.visible, b.pixel_counts));
    }
}
