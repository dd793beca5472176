//! Streets and ground areas drawn over the ground: they show where the ground shows, never
//! hide a building (from the frame, the HZB frame's culling or the oracle), and far away only
//! the wide ones remain.

use citywalk_runtime::camera::Camera;
use citywalk_runtime::drawable::DrawableScene;
use citywalk_runtime::frame::Visibility;
use citywalk_runtime::gpu::GpuContext;
use citywalk_runtime::oracle::Oracle;
use citywalk_runtime::plan::FramePlan;
use citywalk_runtime::render::BruteRenderer;
use citywalk_runtime::render::targets::OffscreenTarget;
use citywalk_runtime::runner::{Completion, FrameReport, FrameRunner, FrameTarget};
use citywalk_scenes::{City, GroundArea, GroundClass, Street, StreetClass};
use citywalk_tests::city_builder::boxes;
use citywalk_tests::gpu::gpu_or_skip;
use geo::{LineString, MultiPolygon, Polygon};
use glam::Vec3;

const SIZE: (u32, u32) = (240, 160);

/// A row of buildings north of an east-west street, a park south of it, a low building
/// standing in the street (OSM streets do run under passages and past kiosks) and a footway.
fn street_scene() -> City {
    let mut city = boxes(&[
        (0.0, 12.0, 20.0, 30.0, 15.0),
        (25.0, 12.0, 45.0, 30.0, 22.0),
        (50.0, 12.0, 70.0, 30.0, 9.0),
        // In the street itself: a kiosk 2 m high.
        (30.0, -2.0, 34.0, 2.0, 2.0),
    ]);
    city.streets = vec![
        Street {
            source_id: "way/1".into(),
            class: StreetClass::Major,
            name: None,
            line: LineString::from(vec![(-200.0, 0.0), (300.0, 0.0)]),
            tagged_width_m: Some(16.0),
        },
        Street {
            source_id: "way/2".into(),
            class: StreetClass::Pedestrian,
            name: None,
            line: LineString::from(vec![(22.5, -60.0), (22.5, 10.0)]),
            tagged_width_m: None,
        },
    ];
    city.ground_areas = vec![GroundArea {
        source_id: "way/3".into(),
        class: GroundClass::Park,
        polygon: MultiPolygon::new(vec![Polygon::new(
            LineString::from(vec![
                (-40.0, -70.0),
                (90.0, -70.0),
                (90.0, -12.0),
                (-40.0, -12.0),
                (-40.0, -70.0),
            ]),
            vec![],
        )]),
    }];
    city
}

/// South of the street at eye height, looking north across it at the buildings.
fn street_camera() -> Camera {
    Camera::new(
        Vec3::new(35.0, -40.0, 1.7),
        90f32.to_radians(),
        -4f32.to_radians(),
    )
}

fn frame(
    gpu: &GpuContext,
    runner: &mut FrameRunner,
    scene: &DrawableScene,
    plan: FramePlan,
    camera: &Camera,
) -> (Vec<u8>, FrameReport) {
    let target =
        OffscreenTarget::new(gpu, SIZE.0, SIZE.1, BruteRenderer::PNG_FORMAT).expect("target");
    let mut visibility = Visibility::default();
    let mut report = None;
    // Twice, so the HZB frame's second frame starts from the first one's visible set.
    for _ in 0..2 {
        report = runner
            .run(
                gpu,
                scene.refs(),
                plan,
                None,
                &mut visibility,
                camera,
                FrameTarget::offscreen(&target),
                (Completion::Wait, true),
            )
            .expect("a frame");
    }
    let rgba = target.read_colour(gpu).expect("readback");
    (rgba, report.expect("a waited frame has its report"))
}

#[test]
fn surfaces_cover_ground_only_and_never_hide_a_building() {
    let Some(gpu) = gpu_or_skip("surfaces_cover_ground_only") else {
        return;
    };
    let city = street_scene();
    let with = DrawableScene::upload_city(&gpu, &city, None, None).expect("the scene fits");
    assert!(
        with.surfaces.is_some(),
        "the street, the footway and the park are drawn"
    );
    let mut without = DrawableScene::upload_city(&gpu, &city, None, None).expect("the scene fits");
    without.surfaces = None;
    let camera = street_camera();
    let oracle = Oracle::new(&gpu);
    let ids = oracle
        .id_image(&gpu, &with.buildings, &camera, SIZE.0, SIZE.1)
        .expect("oracle");
    let mut runner = FrameRunner::new(&gpu, BruteRenderer::PNG_FORMAT);
    for plan in [FramePlan::NONE, FramePlan::ALL] {
        let (bare, _) = frame(&gpu, &mut runner, &without, plan, &camera);
        let (drawn, report) = frame(&gpu, &mut runner, &with, plan, &camera);
        assert!(
            report.surfaces.draws >= 3,
            "{plan:?}: {:?}",
            report.surfaces
        );
        let (mut changed, mut building_px, mut foot_px) = (0, 0, 0);
        for y in 0..SIZE.1 {
            for x in 0..SIZE.0 {
                let i = ((y * SIZE.0 + x) * 4) as usize;
                let differs = bare[i..i + 3] != drawn[i..i + 3];
                let building = ids.building_at(x, y);
                if building.is_some() {
                    building_px += 1;
                    // Tolerance: a surface lies up to 1.6 cm above the ground, so it may cover
                    // a wall's lowest pixel where the wall stands on it; nothing above that.
                    let foot = y + 1 == SIZE.1 || ids.building_at(x, y + 1) != building;
                    assert!(
                        !differs || foot,
                        "{plan:?}: building pixel ({x}, {y}) changed"
                    );
                    foot_px += usize::from(differs);
                } else if differs {
                    changed += 1;
                }
            }
        }
        // At most the foot row of what stands in a street (the kiosk, about 14 px wide here).
        assert!(
            foot_px <= 20,
            "{plan:?}: {foot_px} pixels of building feet covered"
        );
        // The street, footway and park fill most of the lower half of the frame.
        assert!(building_px > 1000, "{building_px}");
        assert!(
            changed > (SIZE.0 * SIZE.1 / 4) as usize,
            "{plan:?}: {changed} ground pixels"
        );
        // The kiosk in the street is seen (the surfaces are not occluders) and every building
        // the oracle sees is drawn.
        let visible = oracle
            .visible_set(&gpu, &with.buildings, &camera, SIZE.0, SIZE.1)
            .expect("oracle");
        let drawn_set = report.drawn.expect("asked for");
        for b in 0..city.buildings.len() as u32 {
            if visible.contains(citywalk_scenes::BuildingId(b)) {
                assert!(drawn_set.contains(&b), "{plan:?}: building {b} culled");
            }
        }
        assert!(
            visible.contains(citywalk_scenes::BuildingId(3)),
            "the kiosk is visible"
        );
    }
}

#[test]
fn far_away_only_the_major_road_is_drawn() {
    let Some(gpu) = gpu_or_skip("far_away_only_the_major_road") else {
        return;
    };
    let city = street_scene();
    let scene = DrawableScene::upload_city(&gpu, &city, None, None).expect("the scene fits");
    let mut runner = FrameRunner::new(&gpu, BruteRenderer::PNG_FORMAT);
    let near = frame(&gpu, &mut runner, &scene, FramePlan::NONE, &street_camera()).1;
    // 1.5 km south, 30 m up, looking north, 160 px high at a 60° view (139 px focal length):
    // the 3 m footway projects to 0.3 px (dropped), the 16 m road to 1.5 px and the park
    // (40 m mean width) to 3.9 px (both kept).
    let far_camera = Camera::new(
        Vec3::new(35.0, -1_500.0, 30.0),
        90f32.to_radians(),
        -1f32.to_radians(),
    );
    let far = frame(&gpu, &mut runner, &scene, FramePlan::NONE, &far_camera).1;
    assert!(near.surfaces.draws >= 3, "{:?}", near.surfaces);
    assert!(
        far.surfaces.draws >= 1,
        "the major road still shows: {:?}",
        far.surfaces
    );
    assert!(
        far.surfaces.draws < near.surfaces.draws
            && far.surfaces.triangles < near.surfaces.triangles,
        "near {:?}, far {:?}",
        near.surfaces,
        far.surfaces
    );
}
