//! Small hand-built cities for tests: boxes and walls with known geometry.

use citywalk_scenes::{Building, BuildingId, BuildingPart, City, Frame, HeightSource, LoadReport};
use geo::{MultiPolygon, Rect};

/// An axis-aligned box building `[x0, x1] × [y0, y1] × [0, height_m]` with id `id` (metres).
pub fn box_building(id: u32, x0: f64, y0: f64, x1: f64, y1: f64, height_m: f32) -> Building {
    let footprint = MultiPolygon::new(vec![
        Rect::new((x0.min(x1), y0.min(y1)), (x0.max(x1), y0.max(y1))).to_polygon(),
    ]);
    let source_id = format!("test/{id}");
    Building {
        id: BuildingId(id),
        source_id: source_id.clone(),
        footprint: footprint.clone(),
        parts: vec![BuildingPart {
            source_id: source_id.clone(),
            footprint,
            base_m: 0.0,
            top_m: height_m,
        }],
        base_m: 0.0,
        top_m: height_m,
        height_source: HeightSource::Tagged,
        mesh: None,
        tags: Default::default(),
    }
}

/// A city of the given buildings (renumbered in order) in a local frame, with a balanced
/// report.
pub fn city_of(buildings: Vec<Building>) -> City {
    let n = buildings.len();
    let mut city = City {
        frame: Frame::local(),
        buildings,
        streets: Vec::new(),
        ground_areas: Vec::new(),
        report: LoadReport {
            buildings_found: n,
            buildings_loaded: n,
            buildings_with_height: n,
            ..LoadReport::default()
        },
    };
    city.renumber();
    city
}

/// A city of boxes `(x0, y0, x1, y1, height_m)`, ids in order.
pub fn boxes(specs: &[(f64, f64, f64, f64, f32)]) -> City {
    city_of(
        specs
            .iter()
            .enumerate()
            .map(|(i, &(x0, y0, x1, y1, h))| box_building(i as u32, x0, y0, x1, y1, h))
            .collect(),
    )
}
