//! Streets and ground areas as flat surfaces on the ground plane: the triangles a frame draws
//! over the ground, grouped in draws by layer, width band and chunk for the distance LOD.
//!
//! * A street becomes the set of points within half its width of its centre line (the
//!   Minkowski sum of the line and a disc, round joins and caps), cut into pieces of at most
//!   one chunk so a draw's bounds stay local. Pieces of one street, and streets meeting at an
//!   intersection, overlap by construction; the overlap is drawn twice in one colour, which is
//!   what joins them (the surfaces write no depth, so nothing else sees it). Each piece is a
//!   valid polygon of its own (i_overlay's stroke, through `geo::Buffer`).
//! * A ground area keeps its polygon.
//! * Polygons are triangulated by ear clipping (`geo::TriangulateEarcut`).
//! * Layers are drawn in order, later ones on top: ground areas by [`GroundClass`], then
//!   streets from footways up to major roads, so the wider road shows at a crossing.
//! * LOD: each draw holds features of one width band (widths within a factor of two: a street's
//!   width; an area's mean width 2·area/perimeter, the width of a long strip and half the side
//!   of a square) and keeps its narrowest. The runtime skips a draw whose narrowest feature
//!   projects below a pixel threshold at the nearest point of its bounds, so far away only the
//!   major roads and large areas remain; the band keeps a garden from taking the park beside
//!   it along.
//!
//! A piece that cannot be made into triangles (a degenerate line, a geometry kernel failure) is
//! counted in [`GroundSurfaces::skipped`] with its source id, never dropped silently.

use std::collections::BTreeMap;
use std::panic::{AssertUnwindSafe, catch_unwind};

use geo::{
    Area, BoundingRect, Buffer, Coord, Euclidean, Length, LineString, Polygon, TriangulateEarcut,
};
use serde::{Deserialize, Serialize};

use crate::city::{City, GroundArea, GroundClass, Street, StreetClass};

/// Side of the square chunks a layer's triangles are grouped in (metres): a draw's bounds are
/// about this large, so the LOD can drop the far ones.
pub const CHUNK_M: f64 = 256.0;

/// Streets in draw order, after the ground areas: the more important on top.
const STREET_ORDER: [StreetClass; 6] = [
    StreetClass::Other,
    StreetClass::Pedestrian,
    StreetClass::Service,
    StreetClass::Residential,
    StreetClass::Minor,
    StreetClass::Major,
];

// The shader colours a surface by its layer from a table of this size.
const _: () = assert!(SurfaceLayer::COUNT == citywalk_shaders::constants::SURFACE_LAYER_COUNT);

/// What a draw shows: a class of ground area or of street.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum SurfaceLayer {
    Area(GroundClass),
    Street(StreetClass),
}

impl SurfaceLayer {
    /// Number of layers (the shader's colour table has one entry each).
    pub const COUNT: u32 = (GroundClass::ALL.len() + STREET_ORDER.len()) as u32;

    /// The layer's place in the draw order, `0..COUNT` (also what the shader colours by).
    pub fn index(self) -> u32 {
        match self {
            SurfaceLayer::Area(class) => GroundClass::ALL
                .iter()
                .position(|c| *c == class)
                .unwrap_or(0) as u32,
            SurfaceLayer::Street(class) => {
                (GroundClass::ALL.len()
                    + STREET_ORDER.iter().position(|c| *c == class).unwrap_or(0))
                    as u32
            }
        }
    }

    /// The layer of index `i` (inverse of [`SurfaceLayer::index`]).
    pub fn from_index(i: u32) -> Option<SurfaceLayer> {
        let i = i as usize;
        let areas = GroundClass::ALL.len();
        if i < areas {
            Some(SurfaceLayer::Area(GroundClass::ALL[i]))
        } else {
            STREET_ORDER
                .get(i - areas)
                .map(|c| SurfaceLayer::Street(*c))
        }
    }

    /// A short stable name (`street:major`, `area:water`).
    pub fn name(self) -> String {
        match self {
            SurfaceLayer::Area(c) => format!("area:{}", c.name()),
            SurfaceLayer::Street(c) => format!("street:{}", c.name()),
        }
    }
}

/// One draw: a layer's triangles in one chunk.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SurfaceDraw {
    /// [`SurfaceLayer::index`].
    pub layer: u32,
    pub first_index: u32,
    pub index_count: u32,
    /// Bounds of the draw's triangles in plan (metres, local frame).
    pub min_m: [f32; 2],
    pub max_m: [f32; 2],
    /// The narrowest feature drawn (metres): see the module documentation.
    pub feature_m: f32,
}

/// A street or area that gave no surface, and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SkippedSurface {
    pub source_id: String,
    pub reason: String,
}

/// The streets and ground areas of a city as triangles in draws.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GroundSurfaces {
    /// Vertex positions in plan (metres, local frame).
    pub vertices: Vec<[f32; 2]>,
    /// Triangles, three vertex indices each, draw after draw.
    pub indices: Vec<u32>,
    /// Draws in draw order (layer, then chunk).
    pub draws: Vec<SurfaceDraw>,
    /// Streets and areas that gave no surface.
    pub skipped: Vec<SkippedSurface>,
}

impl GroundSurfaces {
    /// The surfaces of `city`'s streets and ground areas.
    pub fn build(city: &City) -> GroundSurfaces {
        Self::of(&city.streets, &city.ground_areas)
    }

    /// The surfaces of `streets` and `areas`.
    pub fn of(streets: &[Street], areas: &[GroundArea]) -> GroundSurfaces {
        // Keyed by layer first: the draws come out in draw order.
        let mut pieces: BTreeMap<(u32, i32, (i64, i64)), ChunkPieces> = BTreeMap::new();
        let mut skipped = Vec::new();
        for area in areas {
            let layer = SurfaceLayer::Area(area.class).index();
            for polygon in &area.polygon.0 {
                let Some(rect) = polygon.bounding_rect() else {
                    continue;
                };
                let feature = mean_width_m(polygon);
                // NaN counts as no area.
                if feature.is_nan() || feature <= 0.0 {
                    skipped.push(SkippedSurface {
                        source_id: area.source_id.clone(),
                        reason: "a polygon of zero area".into(),
                    });
                    continue;
                }
                pieces
                    .entry((layer, width_band(feature), chunk_of(rect.center())))
                    .or_default()
                    .push(polygon.clone(), feature);
            }
        }
        for street in streets {
            let layer = SurfaceLayer::Street(street.class).index();
            let half_width = f64::from(street.width_m()) / 2.0;
            for piece in chunk_pieces(&street.line) {
                let chunk = chunk_of(piece.0[piece.0.len() / 2]);
                match stroke(&piece, half_width) {
                    Ok(polygons) => {
                        let band = width_band(2.0 * half_width);
                        let entry = pieces.entry((layer, band, chunk)).or_default();
                        for polygon in polygons {
                            entry.push(polygon, 2.0 * half_width);
                        }
                    }
                    Err(reason) => skipped.push(SkippedSurface {
                        source_id: street.source_id.clone(),
                        reason,
                    }),
                }
            }
        }
        let mut surfaces = GroundSurfaces {
            skipped,
            ..GroundSurfaces::default()
        };
        for ((layer, ..), chunk) in pieces {
            surfaces.push_draw(layer, chunk);
        }
        surfaces.vertices.shrink_to_fit();
        surfaces.indices.shrink_to_fit();
        surfaces
    }

    /// Total triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Triangulates `chunk`'s polygons into one draw of `layer`.
    fn push_draw(&mut self, layer: u32, chunk: ChunkPieces) {
        let first_index = self.indices.len() as u32;
        let mut lo = [f32::INFINITY; 2];
        let mut hi = [f32::NEG_INFINITY; 2];
        for polygon in &chunk.polygons {
            let raw = polygon.earcut_triangles_raw();
            let base = self.vertices.len() as u32;
            for [x, y] in &raw.vertices {
                let v = [*x as f32, *y as f32];
                lo = [lo[0].min(v[0]), lo[1].min(v[1])];
                hi = [hi[0].max(v[0]), hi[1].max(v[1])];
                self.vertices.push(v);
            }
            self.indices
                .extend(raw.triangle_indices.iter().map(|&i| base + i as u32));
        }
        let index_count = self.indices.len() as u32 - first_index;
        if index_count > 0 {
            self.draws.push(SurfaceDraw {
                layer,
                first_index,
                index_count,
                min_m: lo,
                max_m: hi,
                feature_m: chunk.narrowest_m as f32,
            });
        }
    }

    /// Checks what the runtime relies on: indices in range, draws inside the index array, in
    /// layer order, with finite bounds and a positive feature size.
    pub fn check(&self) -> Result<(), String> {
        let vertices = self.vertices.len() as u32;
        if let Some(i) = self.indices.iter().find(|&&i| i >= vertices) {
            return Err(format!("index {i} beyond {vertices} vertices"));
        }
        if let Some(k) = self
            .vertices
            .iter()
            .position(|v| !v.iter().all(|c| c.is_finite()))
        {
            return Err(format!("vertex {k} not finite"));
        }
        let mut layer = 0;
        for (k, d) in self.draws.iter().enumerate() {
            let end = d.first_index as u64 + d.index_count as u64;
            if end > self.indices.len() as u64 || d.index_count % 3 != 0 {
                return Err(format!("draw {k} outside the indices"));
            }
            if d.layer >= SurfaceLayer::COUNT || d.layer < layer {
                return Err(format!("draw {k}: layer {} out of order", d.layer));
            }
            layer = d.layer;
            let finite = d.min_m.iter().chain(&d.max_m).all(|v| v.is_finite());
            if !finite || !d.feature_m.is_finite() || d.feature_m <= 0.0 {
                return Err(format!("draw {k}: bounds or feature size not finite"));
            }
            if d.min_m.iter().zip(&d.max_m).any(|(lo, hi)| lo > hi) {
                return Err(format!("draw {k}: bounds' minimum above their maximum"));
            }
        }
        Ok(())
    }
}

/// The polygons of one layer in one chunk.
#[derive(Debug, Default)]
struct ChunkPieces {
    polygons: Vec<Polygon<f64>>,
    narrowest_m: f64,
}

impl ChunkPieces {
    fn push(&mut self, polygon: Polygon<f64>, feature_m: f64) {
        self.narrowest_m = if self.polygons.is_empty() {
            feature_m
        } else {
            self.narrowest_m.min(feature_m)
        };
        self.polygons.push(polygon);
    }
}

/// The width band of a feature `width_m` wide: widths in one band differ by less than a factor
/// of two, so a draw's narrowest feature speaks for all of them.
fn width_band(width_m: f64) -> i32 {
    width_m.log2().floor().clamp(-32.0, 32.0) as i32
}

/// The chunk containing `c`.
fn chunk_of(c: Coord<f64>) -> (i64, i64) {
    (
        (c.x / CHUNK_M).floor() as i64,
        (c.y / CHUNK_M).floor() as i64,
    )
}

/// An area's mean width: 2·area / perimeter (a strip's width; half a square's side).
fn mean_width_m(polygon: &Polygon<f64>) -> f64 {
    let perimeter: f64 = std::iter::once(polygon.exterior())
        .chain(polygon.interiors())
        .map(|ring| Euclidean.length(ring))
        .sum();
    if perimeter > 0.0 {
        2.0 * polygon.unsigned_area() / perimeter
    } else {
        0.0
    }
}

/// `line` cut into runs of consecutive segments no longer than [`CHUNK_M`] each (a segment
/// longer than that is a run of its own), sharing their end points.
fn chunk_pieces(line: &LineString<f64>) -> Vec<LineString<f64>> {
    let mut pieces = Vec::new();
    let mut current: Vec<Coord<f64>> = Vec::new();
    let mut length = 0.0;
    for segment in line.lines() {
        let l = Euclidean.length(&segment);
        if !current.is_empty() && length + l > CHUNK_M {
            pieces.push(LineString::new(std::mem::take(&mut current)));
            length = 0.0;
        }
        if current.is_empty() {
            current.push(segment.start);
        }
        current.push(segment.end);
        length += l;
    }
    if current.len() >= 2 {
        pieces.push(LineString::new(current));
    }
    pieces
}

/// The points within `half_width` of `piece` as valid polygons (round joins and caps).
fn stroke(piece: &LineString<f64>, half_width: f64) -> Result<Vec<Polygon<f64>>, String> {
    if half_width.is_nan() || half_width <= 0.0 {
        return Err(format!("width {} m", 2.0 * half_width));
    }
    // The geometry kernel asserts its own invariants; one bad street must not stop the city.
    let stroked = catch_unwind(AssertUnwindSafe(|| piece.buffer(half_width)))
        .map_err(|_| "the street's outline could not be computed".to_string())?;
    if stroked.0.is_empty() {
        return Err("a street of zero length".into());
    }
    Ok(stroked.0)
}

#[cfg(test)]
mod tests {
    use geo::{Contains, MultiPolygon, Point, Validation};

    use super::*;

    fn street(id: &str, class: StreetClass, points: &[(f64, f64)], width: Option<f32>) -> Street {
        Street {
            source_id: id.into(),
            class,
            name: None,
            line: LineString::from(points.to_vec()),
            tagged_width_m: width,
        }
    }

    fn triangles_area(s: &GroundSurfaces, draw: &SurfaceDraw) -> f64 {
        let ids = &s.indices[draw.first_index as usize..][..draw.index_count as usize];
        ids.chunks(3)
            .map(|t| {
                let [a, b, c] = [0, 1, 2].map(|k| s.vertices[t[k] as usize]);
                let cross = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
                f64::from(cross.abs()) / 2.0
            })
            .sum()
    }

    #[test]
    fn a_street_is_a_valid_strip_of_its_width_with_round_ends() {
        let s = GroundSurfaces::of(
            &[street(
                "s",
                StreetClass::Residential,
                &[(0.0, 0.0), (100.0, 0.0)],
                Some(10.0),
            )],
            &[],
        );
        s.check().expect("consistent");
        assert_eq!(s.draws.len(), 1);
        let area = triangles_area(&s, &s.draws[0]);
        // 100 m × 10 m plus two half discs of radius 5 m (a polygon inscribed in them).
        let expected = 1000.0 + std::f64::consts::PI * 25.0;
        assert!(
            (area - expected).abs() < 0.02 * expected,
            "{area} vs {expected}"
        );
        assert_eq!(s.draws[0].feature_m, 10.0);
        let stroked = stroke(&LineString::from(vec![(0.0, 0.0), (100.0, 0.0)]), 5.0).unwrap();
        for polygon in &stroked {
            assert!(polygon.is_valid(), "{:?}", polygon.validation_errors());
            assert!(polygon.interiors().is_empty());
        }
        let p = MultiPolygon::new(stroked);
        assert!(p.contains(&Point::new(50.0, 4.9)));
        assert!(!p.contains(&Point::new(50.0, 5.1)));
    }

    #[test]
    fn untagged_streets_take_their_class_width_and_majors_draw_last() {
        let s = GroundSurfaces::of(
            &[
                street(
                    "major",
                    StreetClass::Major,
                    &[(0.0, 0.0), (50.0, 0.0)],
                    None,
                ),
                street(
                    "foot",
                    StreetClass::Pedestrian,
                    &[(25.0, -20.0), (25.0, 20.0)],
                    None,
                ),
            ],
            &[],
        );
        assert_eq!(s.draws.len(), 2);
        let [first, last] = [&s.draws[0], &s.draws[1]];
        assert_eq!(
            SurfaceLayer::from_index(first.layer),
            Some(SurfaceLayer::Street(StreetClass::Pedestrian))
        );
        assert_eq!(
            SurfaceLayer::from_index(last.layer),
            Some(SurfaceLayer::Street(StreetClass::Major))
        );
        assert_eq!(last.feature_m, StreetClass::Major.default_width_m());
        assert_eq!(first.feature_m, StreetClass::Pedestrian.default_width_m());
    }

    #[test]
    fn a_long_street_is_cut_into_chunks_whose_pieces_overlap() {
        let s = GroundSurfaces::of(
            &[street(
                "long",
                StreetClass::Minor,
                &[(0.0, 0.0), (200.0, 0.0), (400.0, 0.0), (1000.0, 0.0)],
                Some(8.0),
            )],
            &[],
        );
        s.check().expect("consistent");
        assert!(s.draws.len() >= 3, "{}", s.draws.len());
        for d in &s.draws {
            assert!(d.max_m[0] - d.min_m[0] <= 610.0 + 8.0);
        }
        // Every point of the centre line is covered by some draw's bounds.
        for x in (0..=1000).step_by(50) {
            let x = x as f32;
            assert!(s.draws.iter().any(|d| d.min_m[0] <= x && x <= d.max_m[0]));
        }
    }

    #[test]
    fn a_small_area_does_not_take_a_large_one_of_its_chunk_along() {
        let square = |x: f64, side: f64| {
            Polygon::new(
                LineString::from(vec![
                    (x, 0.0),
                    (x + side, 0.0),
                    (x + side, side),
                    (x, side),
                    (x, 0.0),
                ]),
                vec![],
            )
        };
        let park = |id: &str, polygon| GroundArea {
            source_id: id.into(),
            class: GroundClass::Park,
            polygon: MultiPolygon::new(vec![polygon]),
        };
        // One chunk, one class: a 200 m park and a 10 m garden.
        let s = GroundSurfaces::of(
            &[],
            &[
                park("park", square(0.0, 200.0)),
                park("garden", square(210.0, 10.0)),
            ],
        );
        let mut features: Vec<f32> = s.draws.iter().map(|d| d.feature_m).collect();
        features.sort_by(f32::total_cmp);
        // Mean widths: half the side of a square.
        assert_eq!(features, [5.0, 100.0]);
        s.check().unwrap();
    }

    #[test]
    fn areas_keep_their_polygon_and_mean_width() {
        let square = Polygon::new(
            LineString::from(vec![
                (0.0, 0.0),
                (40.0, 0.0),
                (40.0, 40.0),
                (0.0, 40.0),
                (0.0, 0.0),
            ]),
            vec![LineString::from(vec![
                (10.0, 10.0),
                (20.0, 10.0),
                (20.0, 20.0),
                (10.0, 20.0),
                (10.0, 10.0),
            ])],
        );
        let areas = [
            GroundArea {
                source_id: "water".into(),
                class: GroundClass::Water,
                polygon: MultiPolygon::new(vec![square.clone()]),
            },
            GroundArea {
                source_id: "flat".into(),
                class: GroundClass::Park,
                polygon: MultiPolygon::new(vec![Polygon::new(
                    LineString::from(vec![(0.0, 0.0), (10.0, 0.0), (20.0, 0.0), (0.0, 0.0)]),
                    vec![],
                )]),
            },
        ];
        let s = GroundSurfaces::of(&[], &areas);
        s.check().expect("consistent");
        assert_eq!(s.draws.len(), 1);
        let area = triangles_area(&s, &s.draws[0]);
        assert!((area - 1500.0).abs() < 1e-3, "{area}");
        let expected_width = 2.0 * 1500.0 / 200.0;
        assert!((f64::from(s.draws[0].feature_m) - expected_width).abs() < 1e-4);
        assert_eq!(s.skipped.len(), 1);
        assert_eq!(s.skipped[0].source_id, "flat");
    }

    #[test]
    fn layer_indices_round_trip_and_areas_draw_below_streets() {
        for i in 0..SurfaceLayer::COUNT {
            let layer = SurfaceLayer::from_index(i).expect("a layer");
            assert_eq!(layer.index(), i, "{}", layer.name());
        }
        assert!(SurfaceLayer::from_index(SurfaceLayer::COUNT).is_none());
        let water = SurfaceLayer::Area(GroundClass::Water).index();
        let footway = SurfaceLayer::Street(StreetClass::Pedestrian).index();
        assert!(water < footway);
    }

    #[test]
    fn a_zero_length_street_is_reported_not_dropped() {
        let s = GroundSurfaces::of(
            &[street(
                "dot",
                StreetClass::Minor,
                &[(5.0, 5.0), (5.0, 5.0)],
                None,
            )],
            &[],
        );
        // A degenerate line is buffered as a point (a disc) by the kernel, or reported.
        assert!(s.draws.len() == 1 || s.skipped.len() == 1, "{s:?}");
    }
}
