//! Tests of the whole occluder pipeline: hand-made and random stepped buildings (height fields
//! on rectilinear grids, as closed meshes), random footprints for the simplifier.

use citywalk_scenes::occluder::FacadeKind;
use citywalk_scenes::{
    Building, BuildingId, BuildingPart, City, Frame, HeightSource, LoadReport, TriangleMesh,
};
use geo::{
    Area, Coord, Covers, Line, LineString, MultiPolygon, Polygon, Rect, Validation, coord,
    unary_union,
};
use glam::Vec3;
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

use super::quality::{QualityParams, measure};
use super::simplify::simplify_polygon;
use super::zlevels::LevelDecision;
use super::{OccluderParams, build_occluders, occluders_for_building};

/// A 2.5D building as a height field on a rectilinear grid: `xs`, `ys` are the grid lines,
/// `heights[j][i]` the height of cell (i, j) (0 = no building).
#[derive(Debug, Clone)]
pub(crate) struct HeightField {
    pub xs: Vec<f64>,
    pub ys: Vec<f64>,
    pub heights: Vec<Vec<f32>>,
}

impl HeightField {
    fn cell(&self, i: usize, j: usize) -> Polygon<f64> {
        Rect::new(
            coord! {x: self.xs[i], y: self.ys[j]},
            coord! {x: self.xs[i + 1], y: self.ys[j + 1]},
        )
        .to_polygon()
    }

    fn height(&self, i: isize, j: isize) -> f32 {
        if i < 0 || j < 0 {
            return 0.0;
        }
        self.heights
            .get(j as usize)
            .and_then(|row| row.get(i as usize))
            .copied()
            .unwrap_or(0.0)
    }

    /// The ground region under which the building is at least `z` tall.
    pub fn region_at(&self, z: f32) -> MultiPolygon<f64> {
        let mut cells = Vec::new();
        for (j, row) in self.heights.iter().enumerate() {
            for (i, &h) in row.iter().enumerate() {
                if h > 0.0 && h >= z {
                    cells.push(self.cell(i, j));
                }
            }
        }
        unary_union(cells.iter())
    }

    /// A closed mesh (outward counter-clockwise): roofs, floor, and walls wherever a cell is
    /// taller than its neighbour.
    pub fn mesh(&self) -> TriangleMesh {
        let mut m = TriangleMesh::default();
        let quad = |m: &mut TriangleMesh, q: [Vec3; 4]| {
            let i = m.positions.len() as u32;
            m.positions.extend_from_slice(&q);
            m.indices
                .extend_from_slice(&[i, i + 1, i + 2, i, i + 2, i + 3]);
        };
        for (j, row) in self.heights.iter().enumerate() {
            for (i, &h) in row.iter().enumerate() {
                if h <= 0.0 {
                    continue;
                }
                let (x0, x1) = (self.xs[i] as f32, self.xs[i + 1] as f32);
                let (y0, y1) = (self.ys[j] as f32, self.ys[j + 1] as f32);
                let v = Vec3::new;
                quad(
                    &mut m,
                    [v(x0, y0, h), v(x1, y0, h), v(x1, y1, h), v(x0, y1, h)],
                );
                quad(
                    &mut m,
                    [
                        v(x0, y0, 0.0),
                        v(x0, y1, 0.0),
                        v(x1, y1, 0.0),
                        v(x1, y0, 0.0),
                    ],
                );
                let (ii, jj) = (i as isize, j as isize);
                // South, east, north, west walls from the neighbour's height up to h.
                let sides = [
                    (self.height(ii, jj - 1), [v(x0, y0, 0.0), v(x1, y0, 0.0)]),
                    (self.height(ii + 1, jj), [v(x1, y0, 0.0), v(x1, y1, 0.0)]),
                    (self.height(ii, jj + 1), [v(x1, y1, 0.0), v(x0, y1, 0.0)]),
                    (self.height(ii - 1, jj), [v(x0, y1, 0.0), v(x0, y0, 0.0)]),
                ];
                for (nh, [a, b]) in sides {
                    if nh < h {
                        let lo = nh.max(0.0);
                        quad(
                            &mut m,
                            [
                                Vec3::new(a.x, a.y, lo),
                                Vec3::new(b.x, b.y, lo),
                                Vec3::new(b.x, b.y, h),
                                Vec3::new(a.x, a.y, h),
                            ],
                        );
                    }
                }
            }
        }
        m
    }

    pub fn building(&self, id: u32) -> Building {
        let footprint = self.region_at(f32::MIN_POSITIVE);
        let top_m = self
            .heights
            .iter()
            .flatten()
            .copied()
            .fold(0.0f32, f32::max);
        Building {
            id: BuildingId(id),
            source_id: format!("field-{id}"),
            footprint: footprint.clone(),
            parts: vec![BuildingPart {
                source_id: format!("field-{id}"),
                footprint,
                base_m: 0.0,
                top_m,
            }],
            base_m: 0.0,
            top_m,
            height_source: HeightSource::Geometry,
            mesh: Some(Box::new(self.mesh())),
            tags: Default::default(),
        }
    }
}

pub(crate) fn city_of(buildings: Vec<Building>) -> City {
    City {
        frame: Frame::local(),
        buildings,
        streets: Vec::new(),
        ground_areas: Vec::new(),
        report: LoadReport::default(),
    }
}

/// A podium (30 × 20 m, 8 m) with a tower (10 × 10 m, 40 m) and a chimney (1 × 1 m, 9 m).
pub(crate) fn podium_tower() -> HeightField {
    HeightField {
        xs: vec![0.0, 10.0, 11.0, 20.0, 30.0],
        ys: vec![0.0, 5.0, 6.0, 15.0, 20.0],
        heights: vec![
            vec![8.0, 8.0, 8.0, 8.0],
            vec![8.0, 9.0, 8.0, 8.0],
            vec![8.0, 8.0, 40.0, 8.0],
            vec![8.0, 8.0, 8.0, 8.0],
        ],
    }
}

/// A small city of hand-made buildings (used by other modules' tests too).
pub(crate) fn stepped_city() -> City {
    let mut b0 = podium_tower().building(0);
    b0.id = BuildingId(0);
    let flat = HeightField {
        xs: vec![50.0, 62.0],
        ys: vec![0.0, 9.0],
        heights: vec![vec![12.0]],
    };
    city_of(vec![b0, flat.building(1)])
}

/// Checks that every occluder of `b` stands inside the height field: its footprint within the
/// region at least `z_m` tall, every wall within the region at least as tall as its top.
fn assert_contained(field: &HeightField, b: &Building, params: &OccluderParams) {
    let built = occluders_for_building(b, params);
    for o in &built.occluders {
        assert!(o.base_m >= 0.0, "base {}", o.base_m);
        let truth = field.region_at(o.z_m);
        assert!(
            truth.covers(&o.footprint),
            "level at {} m not inside the building: {:?} vs {:?}",
            o.z_m,
            o.footprint,
            truth
        );
        for [a, b, c] in o.mesh.triangles() {
            let top = a.z.max(b.z).max(c.z);
            let region = field.region_at(top - 1e-4);
            for p in [a, b, c] {
                let q = coord! {x: f64::from(p.x), y: f64::from(p.y)};
                assert!(
                    region.covers(&q),
                    "facade vertex {p} above the building ({top})"
                );
            }
            // The wall's ground edge lies within the region as tall as the wall.
            let ground: Vec<Vec3> = [a, b, c].into_iter().filter(|p| p.z < top).collect();
            if let [g0, g1] = ground[..] {
                let line = Line::new(
                    coord! {x: f64::from(g0.x), y: f64::from(g0.y)},
                    coord! {x: f64::from(g1.x), y: f64::from(g1.y)},
                );
                if line.start != line.end {
                    assert!(region.covers(&line), "wall {line:?} up to {top} m outside");
                }
            }
        }
    }
}

#[test]
fn podium_tower_keeps_podium_and_tower_and_deletes_the_chimney() {
    // Both level selections agree here: the benefit rule (gain 0) and silhouette gain.
    for gain in [
        0.0,
        OccluderParams::default().min_silhouette_gain_per_polygon,
    ] {
        podium_tower_with_gain(gain);
    }
}

fn podium_tower_with_gain(min_silhouette_gain_per_polygon: f64) {
    let field = podium_tower();
    let b = field.building(0);
    let params = OccluderParams {
        min_silhouette_gain_per_polygon,
        ..OccluderParams::default()
    };
    let built = occluders_for_building(&b, &params);
    let decisions: Vec<(f64, LevelDecision)> = built.decisions.clone();
    assert_eq!(
        decisions,
        vec![
            (8.0, LevelDecision::Keep),
            (9.0, LevelDecision::Delete),
            (40.0, LevelDecision::Keep)
        ]
    );
    assert_eq!(built.occluders.len(), 2);
    assert!((built.occluders[0].footprint.unsigned_area() - 600.0).abs() < 1e-6);
    assert!((built.occluders[1].footprint.unsigned_area() - 81.0).abs() < 1e-6);
    assert_contained(&field, &b, &params);
    for kind in [FacadeKind::Open, FacadeKind::Closed] {
        assert_contained(
            &field,
            &b,
            &OccluderParams {
                facade: kind,
                ..params.clone()
            },
        );
    }
    // Far fewer triangles than the source mesh, and close to full quality.
    let facade = {
        let mut m = TriangleMesh::default();
        for o in &built.occluders {
            m.append(&o.mesh);
        }
        m
    };
    assert!(facade.triangle_count() * 3 < b.mesh.as_ref().unwrap().triangle_count());
    let counts = measure(b.mesh.as_ref().unwrap(), &facade, &QualityParams::default());
    let q = counts.quality().unwrap();
    assert!(q > 0.9, "quality {q}");
    assert!(counts.leak_fraction() < 0.01, "{counts:?}");
}

#[test]
fn wall_oriented_walls_rise_where_the_building_is_taller() {
    // Two blocks side by side, 10 m and 20 m, sharing the edge x = 10; with T_B high the 20 m
    // level is deleted, but the walls around the tall block rise to 20 m on its three free
    // sides, while the open facade stays at 10 m.
    let field = HeightField {
        xs: vec![0.0, 10.0, 20.0],
        ys: vec![0.0, 10.0],
        heights: vec![vec![10.0, 20.0]],
    };
    let b = field.building(0);
    let params = OccluderParams {
        benefit_threshold: 10.0,
        min_silhouette_gain_per_polygon: 0.0,
        simplify: false,
        ..OccluderParams::default()
    };
    let built = occluders_for_building(&b, &params);
    assert_eq!(built.occluders.len(), 1);
    let top = built.occluders[0]
        .mesh
        .bounds()
        .map(|(_, hi)| hi.z)
        .unwrap_or(0.0);
    assert_eq!(top, 20.0);
    assert_contained(&field, &b, &params);
    let open = occluders_for_building(
        &b,
        &OccluderParams {
            facade: FacadeKind::Open,
            ..params
        },
    );
    assert_eq!(
        open.occluders[0].mesh.bounds().map(|(_, hi)| hi.z),
        Some(10.0)
    );
}

#[test]
fn build_occluders_reports_every_building() {
    let mut city = stepped_city();
    // A building with a broken mesh and a 2.5D building with a low part.
    let mut broken = city.buildings[1].clone();
    broken.id = BuildingId(2);
    if let Some(m) = broken.mesh.as_mut() {
        m.indices[0] = 9999;
    }
    let mut flat = city.buildings[1].clone();
    flat.id = BuildingId(3);
    flat.mesh = None;
    flat.parts[0].top_m = 0.5;
    flat.top_m = 0.5;
    city.buildings.push(broken);
    city.buildings.push(flat);
    let set = build_occluders(&city, &OccluderParams::default());
    assert_eq!(set.check_invariants(), Ok(()));
    assert_eq!(set.per_building.len(), 4);
    assert!(set.per_building[0].reason_if_none.is_none());
    assert!(set.per_building[1].reason_if_none.is_none());
    assert!(
        set.per_building[2]
            .reason_if_none
            .as_deref()
            .unwrap()
            .contains("index")
    );
    assert!(
        set.per_building[3]
            .reason_if_none
            .as_deref()
            .unwrap()
            .contains("tall")
    );
}

#[test]
fn quality_rows_count_polygons_and_triangles() {
    let city = stepped_city();
    let set = build_occluders(&city, &OccluderParams::default());
    let rows = super::quality::measure_city(&city, &set, &QualityParams::default());
    // The flat 12 × 9 m box: six faces of two triangles; its facade four wall quads.
    let flat = &rows[1];
    assert_eq!((flat.source_polygons, flat.source_triangles), (6, 12));
    assert_eq!((flat.occluder_polygons, flat.occluder_triangles), (4, 8));
    // The podium with tower: more triangles than faces on both sides.
    let podium = &rows[0];
    assert!(podium.source_polygons < podium.source_triangles);
    assert!(podium.occluder_polygons * 2 == podium.occluder_triangles);
    let s = super::quality::summarise(&rows);
    assert_eq!(
        s.source_polygons,
        u64::from(flat.source_polygons + podium.source_polygons)
    );
    assert!(s.triangle_reduction > 0.0 && s.polygon_reduction > 0.0);
}

#[test]
fn parts_of_25d_buildings_get_one_level_each() {
    let mut b = stepped_city().buildings[1].clone();
    b.mesh = None;
    let tower = Rect::new(coord! {x: 52.0, y: 2.0}, coord! {x: 56.0, y: 6.0}).to_polygon();
    b.parts.push(BuildingPart {
        source_id: "tower".into(),
        footprint: MultiPolygon::new(vec![tower]),
        base_m: 12.0,
        top_m: 30.0,
    });
    b.top_m = 30.0;
    let built = occluders_for_building(&b, &OccluderParams::default());
    assert_eq!(built.occluders.len(), 2);
    assert_eq!(
        (built.occluders[1].base_m, built.occluders[1].z_m),
        (12.0, 30.0)
    );
    assert!(built.source_polygons > 0);
}

/// Random stepped buildings: a grid of 1–5 × 1–5 cells of 2–15 m, 1–4 stacked levels, each
/// level a random subset of the cells of the level below.
fn height_field() -> impl Strategy<Value = HeightField> {
    (1usize..=5, 1usize..=5).prop_flat_map(|(nx, ny)| {
        (
            prop::collection::vec(2.0f64..15.0, nx),
            prop::collection::vec(2.0f64..15.0, ny),
            prop::collection::vec(3.0f32..12.0, 1..=4),
            prop::collection::vec(prop::collection::vec(0u8..5, nx), ny),
        )
            .prop_map(move |(wx, wy, steps, picks)| {
                let lines = |w: &[f64]| {
                    let mut v = vec![0.0];
                    for d in w {
                        v.push(v[v.len() - 1] + d.round());
                    }
                    v
                };
                let mut levels = vec![0.0f32];
                for s in &steps {
                    levels.push(levels[levels.len() - 1] + s.round());
                }
                // Cell level = how many levels it reaches (pick 0 = empty); the first cell is
                // always built so the building is never empty.
                let heights = picks
                    .iter()
                    .enumerate()
                    .map(|(j, row)| {
                        row.iter()
                            .enumerate()
                            .map(|(i, &p)| {
                                let k = (p as usize).min(steps.len());
                                let k = if i == 0 && j == 0 { k.max(1) } else { k };
                                levels[k]
                            })
                            .collect()
                    })
                    .collect();
                HeightField {
                    xs: lines(&wx),
                    ys: lines(&wy),
                    heights,
                }
            })
    })
}

/// Random simple polygons: star-shaped around the origin (radii at sorted angles), some with a
/// star-shaped hole inside the smallest radius.
fn star_polygon() -> impl Strategy<Value = Polygon<f64>> {
    (
        prop::collection::vec((0.0f64..1.0, 5.0f64..30.0), 3..40),
        prop::option::of(prop::collection::vec((0.0f64..1.0, 0.3f64..1.0), 3..12)),
    )
        .prop_map(|(mut outer, hole)| {
            outer.sort_by(|a, b| a.0.total_cmp(&b.0));
            outer.dedup_by(|a, b| (a.0 - b.0).abs() < 1e-3);
            let ring = |pts: &[(f64, f64)], scale: f64| {
                LineString::from(
                    pts.iter()
                        .map(|(a, r)| {
                            let t = a * std::f64::consts::TAU;
                            Coord {
                                x: (r * scale * t.cos() * 100.0).round() / 100.0,
                                y: (r * scale * t.sin() * 100.0).round() / 100.0,
                            }
                        })
                        .collect::<Vec<_>>(),
                )
            };
            let min_r = outer.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
            let holes = hole
                .map(|mut h| {
                    h.sort_by(|a, b| a.0.total_cmp(&b.0));
                    h.dedup_by(|a, b| (a.0 - b.0).abs() < 1e-2);
                    vec![ring(&h, min_r * 0.8)]
                })
                .unwrap_or_default();
            Polygon::new(ring(&outer, 1.0), holes)
        })
        .prop_filter("valid polygon", |p| p.is_valid() && p.unsigned_area() > 1.0)
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
    #![proptest_config(config(96, 3))]

    #[test]
    fn random_stepped_buildings_get_contained_occluders(field in height_field()) {
        let b = field.building(0);
        // Every level selection: silhouette gain (default), the benefit rule alone, and wall
        // selection.
        let default_gain = OccluderParams::default().min_silhouette_gain_per_polygon;
        for (gain, select_walls) in [(default_gain, false), (0.0, false), (1e-6, false), (0.01, true)] {
            for facade in [FacadeKind::WallOriented, FacadeKind::Open, FacadeKind::Closed] {
                let params = OccluderParams {
                    facade,
                    min_silhouette_gain_per_polygon: gain,
                    select_walls,
                    ..OccluderParams::default()
                };
                assert_contained(&field, &b, &params);
            }
        }
        let walls = OccluderParams { select_walls: true, ..OccluderParams::default() };
        let set = build_occluders(&city_of(vec![b.clone()]), &walls);
        prop_assert_eq!(set.check_invariants(), Ok(()));
        let set = build_occluders(&city_of(vec![b]), &OccluderParams::default());
        prop_assert_eq!(set.check_invariants(), Ok(()));
        prop_assert!(set.per_building[0].reason_if_none.is_none(), "{:?}", set.per_building[0]);
    }
}

proptest! {
    #![proptest_config(config(256, 5))]

    #[test]
    fn simplification_is_inward_valid_and_never_grows(polygon in star_polygon()) {
        let params = OccluderParams { max_turn_angle_deg: 20.0, max_edge_shift_m: 2.0, ..OccluderParams::default() };
        let s = simplify_polygon(&polygon, &params);
        prop_assert!(s.is_valid(), "{:?}", s);
        prop_assert!(s.unsigned_area() <= polygon.unsigned_area() + 1e-9);
        prop_assert!(polygon.covers(&s));
        prop_assert!(s.exterior().0.len() <= polygon.exterior().0.len());
    }
}

/// A gabled house: 10 × 8 m, eaves at 6 m, ridge at 10 m along y = 4, as a closed mesh.
fn gabled_house() -> Building {
    let mut mesh = TriangleMesh::default();
    let mut face = |pts: &[[f32; 3]]| {
        let i = mesh.positions.len() as u32;
        mesh.positions
            .extend(pts.iter().map(|p| Vec3::new(p[0], p[1], p[2])));
        for k in 1..pts.len() as u32 - 1 {
            mesh.indices.extend_from_slice(&[i, i + k, i + k + 1]);
        }
    };
    face(&[
        [0.0, 0.0, 0.0],
        [10.0, 0.0, 0.0],
        [10.0, 0.0, 6.0],
        [0.0, 0.0, 6.0],
    ]);
    face(&[
        [10.0, 8.0, 0.0],
        [0.0, 8.0, 0.0],
        [0.0, 8.0, 6.0],
        [10.0, 8.0, 6.0],
    ]);
    face(&[
        [10.0, 0.0, 0.0],
        [10.0, 8.0, 0.0],
        [10.0, 8.0, 6.0],
        [10.0, 4.0, 10.0],
        [10.0, 0.0, 6.0],
    ]);
    face(&[
        [0.0, 8.0, 0.0],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 6.0],
        [0.0, 4.0, 10.0],
        [0.0, 8.0, 6.0],
    ]);
    face(&[
        [0.0, 0.0, 0.0],
        [0.0, 8.0, 0.0],
        [10.0, 8.0, 0.0],
        [10.0, 0.0, 0.0],
    ]);
    face(&[
        [0.0, 0.0, 6.0],
        [10.0, 0.0, 6.0],
        [10.0, 4.0, 10.0],
        [0.0, 4.0, 10.0],
    ]);
    face(&[
        [0.0, 4.0, 10.0],
        [10.0, 4.0, 10.0],
        [10.0, 8.0, 6.0],
        [0.0, 8.0, 6.0],
    ]);
    let mut b = HeightField {
        xs: vec![0.0, 10.0],
        ys: vec![0.0, 8.0],
        heights: vec![vec![10.0]],
    }
    .building(0);
    b.mesh = Some(Box::new(mesh));
    b
}

#[test]
fn sloped_roofs_get_sampled_levels_only_when_asked() {
    let b = gabled_house();
    let model = b.mesh.clone().unwrap_or_default();
    let facade_of = |params: &OccluderParams| {
        let built = occluders_for_building(&b, params);
        let mut m = TriangleMesh::default();
        for o in &built.occluders {
            m.append(&o.mesh);
        }
        (built, m)
    };
    let paper = OccluderParams {
        sloped_roof_step_m: 0.0,
        ..OccluderParams::default()
    };
    let (built, paper_mesh) = facade_of(&paper);
    assert_eq!(built.occluders.len(), 1);
    assert_eq!(built.occluders[0].z_m, 6.0);
    let sampled = OccluderParams {
        sloped_roof_step_m: 2.0,
        ..OccluderParams::default()
    };
    let (built, sampled_mesh) = facade_of(&sampled);
    assert_eq!(built.occluders.len(), 2, "{:?}", built.decisions);
    // Where the roof is at least 8 m high: the strip 2 ≤ y ≤ 6.
    let upper = &built.occluders[1];
    assert_eq!(upper.z_m, 8.0);
    assert!((upper.footprint.unsigned_area() - 40.0).abs() < 1e-6);
    let strip = Rect::new(coord! {x: 0.0, y: 2.0}, coord! {x: 10.0, y: 6.0}).to_polygon();
    assert!(strip.covers(&upper.footprint));
    let q = QualityParams::default();
    let q_paper = measure(&model, &paper_mesh, &q).quality().unwrap_or(0.0);
    let q_sampled = measure(&model, &sampled_mesh, &q);
    assert!(
        q_sampled.quality().unwrap_or(0.0) > q_paper + 0.05,
        "{q_paper} {q_sampled:?}"
    );
    assert!(q_sampled.leak_fraction() < 0.01, "{q_sampled:?}");
}

#[test]
fn occluders_handed_on_as_built_make_the_set() {
    // Several chunks of buildings, handed on a few at a time, with an error from the taker at
    // the end of a second run.
    let city =
        citywalk_scenes::generate::generate_city(&citywalk_scenes::generate::GenerateParams {
            buildings: super::BUILDINGS_PER_CHUNK * 2 + 300,
            seed: 3,
            ..Default::default()
        })
        .expect("a generated city");
    let params = OccluderParams::default();
    let set = build_occluders(&city, &params);
    let mut occluders = Vec::new();
    let mut takes = 0;
    let per_building = super::build_occluders_taking(&city, &params, 1000, &mut |o| {
        takes += 1;
        occluders.extend_from_slice(o);
        Ok::<(), ()>(())
    })
    .expect("no error");
    assert!(takes > 2, "{takes} takes");
    assert_eq!(per_building, set.per_building);
    assert!(occluders == set.occluders);
    let mut calls = 0;
    let failed = super::build_occluders_taking(&city, &params, 1000, &mut |_| {
        calls += 1;
        if calls == 2 { Err("full disk") } else { Ok(()) }
    });
    assert_eq!(failed, Err("full disk"));
    assert_eq!(calls, 2, "stops at the first error");
}
