//! Occluder quality as Germs & Jansen measure it (§4.1, §4.2, Table 1).
//!
//! *Occlusion-preserving quality* (§4.1): binary images of the original model and of its
//! facade are rendered "from viewpoints uniformly distributed along the edge of a horizontal
//! circle, located at half the height of the original model", at a fixed radius such that the
//! whole model is visible; the quality is O_facade / O_model with both normalised by the
//! model's largest sample, that is Σ facade pixels / Σ model pixels over the views. The images
//! are rasterised here on the CPU (perspective, edge functions, pixel centres, a boolean mask
//! per image). Pixels the facade covers and the model does not are counted as *leak*: a
//! contained facade has none beyond rasterisation noise at shared edges. The quality counts
//! only facade pixels inside the model's silhouette, so it never exceeds 100 %: a facade that
//! reaches outside its building shows as a leak ([`PixelCounts::leaks`]), never as a quality
//! above the building's own.
//!
//! *Efficiency* (§4.2): polygon counts and average polygon area, before and after. A polygon
//! is a planar face as in the paper's Table 1 (a wall quad is one polygon; see
//! [`super::polygons`]); triangle counts are reported beside them.

use citywalk_scenes::extrude::building_mesh;
use citywalk_scenes::occluder::OccluderSet;
use citywalk_scenes::{City, TriangleMesh};
use glam::{DVec3, Vec3};

use super::polygons::planar_face_count;
use serde::{Deserialize, Serialize};

/// How quality is sampled.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct QualityParams {
    /// Viewpoints on the circle (the paper does not say how many). Default 16.
    pub views: u32,
    /// Width and height of each binary image in pixels. Default 128.
    pub resolution_px: u32,
    /// Circle radius as a multiple of the model's bounding-sphere radius (≥ 1.5 so the sphere
    /// is in front of the camera). Default 3.
    pub distance_factor: f64,
    /// Angle of the first viewpoint as a fraction of the step between viewpoints. Default 0
    /// (the first view looks along −x). Level selection samples with an offset so that it does
    /// not choose levels on the very views the benchmark reports.
    #[serde(default)]
    pub view_offset: f64,
}

impl Default for QualityParams {
    fn default() -> Self {
        QualityParams {
            views: 16,
            resolution_px: 128,
            distance_factor: 3.0,
            view_offset: 0.0,
        }
    }
}

/// Pixel counts summed over all views.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PixelCounts {
    pub model_px: u64,
    pub facade_px: u64,
    /// Facade pixels outside the model's silhouette.
    pub leak_px: u64,
}

/// Share of a facade's pixels outside its building's silhouette that rasterisation alone
/// gives (pixel centres on the shared edges of a contained facade); above it, a facade leaks.
pub const LEAK_NOISE: f64 = 0.005;

impl PixelCounts {
    /// Occlusion-preserving quality in [0, 1]: the facade's pixels inside the model's
    /// silhouette over the model's; `None` when the model covers no pixel. Leaked pixels are
    /// not counted here but in [`PixelCounts::leak_fraction`].
    pub fn quality(&self) -> Option<f64> {
        (self.model_px > 0)
            .then(|| self.facade_px.saturating_sub(self.leak_px) as f64 / self.model_px as f64)
    }

    /// Whether the facade covers more of the view outside its building than rasterisation
    /// noise ([`LEAK_NOISE`]): it would hide what the building does not.
    pub fn leaks(&self) -> bool {
        self.leak_fraction() > LEAK_NOISE
    }

    /// Share of the facade's pixels that the model does not cover.
    pub fn leak_fraction(&self) -> f64 {
        if self.facade_px == 0 {
            0.0
        } else {
            self.leak_px as f64 / self.facade_px as f64
        }
    }
}

/// A boolean image.
#[derive(Debug, Clone)]
pub struct Mask {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<bool>,
}

impl Mask {
    pub fn new(width: usize, height: usize) -> Mask {
        Mask {
            width,
            height,
            pixels: vec![false; width * height],
        }
    }

    pub fn count(&self) -> u64 {
        self.pixels.iter().filter(|p| **p).count() as u64
    }

    /// Fills the pixels whose centres lie in the closed triangle (screen coordinates, pixels).
    pub fn fill_triangle(&mut self, tri: [[f64; 2]; 3]) {
        let [mut a, mut b, c] = tri;
        let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        if area.is_nan() || area.abs() <= 1e-12 {
            return;
        }
        if area < 0.0 {
            std::mem::swap(&mut a, &mut b);
        }
        let edges = [(a, b), (b, c), (c, a)];
        let y_lo = tri.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min);
        let y_hi = tri.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max);
        let row_lo = ((y_lo - 0.5).ceil().max(0.0)) as usize;
        let row_hi = (y_hi - 0.5).floor().min(self.height as f64 - 1.0);
        if row_hi < 0.0 {
            return;
        }
        for row in row_lo..=row_hi as usize {
            let yc = row as f64 + 0.5;
            let (mut xl, mut xr) = (f64::NEG_INFINITY, f64::INFINITY);
            let mut empty = false;
            for (p, q) in edges {
                // Inside when (q − p) × (x − p) ≥ 0: k · x + m ≥ 0.
                let k = -(q[1] - p[1]);
                let m = (q[0] - p[0]) * (yc - p[1]) + (q[1] - p[1]) * p[0];
                if k > 0.0 {
                    xl = xl.max(-m / k);
                } else if k < 0.0 {
                    xr = xr.min(-m / k);
                } else if m < 0.0 {
                    empty = true;
                }
            }
            if empty || xl > xr {
                continue;
            }
            let col_lo = (xl - 0.5).ceil().max(0.0);
            let col_hi = (xr - 0.5).floor().min(self.width as f64 - 1.0);
            if col_hi < col_lo {
                continue;
            }
            let start = row * self.width;
            self.pixels[start + col_lo as usize..=start + col_hi as usize].fill(true);
        }
    }
}

/// A pinhole camera at `eye` looking at `target`, z up, square image.
#[derive(Debug, Clone, Copy)]
struct Camera {
    eye: DVec3,
    right: DVec3,
    up: DVec3,
    forward: DVec3,
    tan_half_fov: f64,
    size_px: f64,
}

impl Camera {
    /// Screen position in pixels, or `None` behind the near plane.
    fn project(&self, p: Vec3) -> Option<[f64; 2]> {
        let d = p.as_dvec3() - self.eye;
        let z = d.dot(self.forward);
        if z < 1e-6 {
            return None;
        }
        let u = d.dot(self.right) / (z * self.tan_half_fov);
        let v = d.dot(self.up) / (z * self.tan_half_fov);
        Some([
            (u + 1.0) * 0.5 * self.size_px,
            (1.0 - v) * 0.5 * self.size_px,
        ])
    }

    fn render(&self, mesh: &TriangleMesh, mask: &mut Mask) {
        for t in mesh.indices.chunks_exact(3) {
            let mut s = [[0.0; 2]; 3];
            let mut ok = true;
            for (k, &i) in t.iter().enumerate() {
                match mesh
                    .positions
                    .get(i as usize)
                    .and_then(|p| self.project(*p))
                {
                    Some(q) => s[k] = q,
                    None => ok = false,
                }
            }
            if ok {
                mask.fill_triangle(s);
            }
        }
    }
}

/// The viewpoints of §4.1 for one model: `params.views` cameras evenly spaced on a horizontal
/// circle at half the model's height around its centre, far enough that the whole model is
/// in every image, and the model's silhouette from each.
#[derive(Debug, Clone)]
pub struct Silhouettes {
    cameras: Vec<Camera>,
    size: usize,
    model: Vec<Mask>,
}

impl Silhouettes {
    /// Renders `model`; `None` when it is empty or not finite.
    pub fn new(model: &TriangleMesh, params: &QualityParams) -> Option<Silhouettes> {
        let (lo, hi) = model.bounds()?;
        if !(lo.is_finite() && hi.is_finite()) {
            return None;
        }
        let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
        let centre = (lo + hi) * 0.5;
        let radius = ((hi - lo) * 0.5).length().max(1e-3);
        let distance = radius * params.distance_factor.max(1.5);
        let tan_half_fov = radius / (distance * distance - radius * radius).sqrt();
        let size = params.resolution_px.clamp(8, 4096) as usize;
        let views = params.views.max(1);
        let offset = if params.view_offset.is_finite() {
            params.view_offset
        } else {
            0.0
        };
        let cameras: Vec<Camera> = (0..views)
            .map(|k| {
                let angle = std::f64::consts::TAU * (f64::from(k) + offset) / f64::from(views);
                let eye = centre + DVec3::new(angle.cos(), angle.sin(), 0.0) * distance;
                let forward = (centre - eye).normalize();
                let right = forward.cross(DVec3::Z).normalize();
                Camera {
                    eye,
                    right,
                    up: right.cross(forward),
                    forward,
                    tan_half_fov,
                    size_px: size as f64,
                }
            })
            .collect();
        let mut out = Silhouettes {
            cameras,
            size,
            model: Vec::new(),
        };
        out.model = out.render(model);
        Some(out)
    }

    /// The silhouettes of `mesh` from the same viewpoints, one mask per view.
    pub fn render(&self, mesh: &TriangleMesh) -> Vec<Mask> {
        self.cameras
            .iter()
            .map(|camera| {
                let mut mask = Mask::new(self.size, self.size);
                camera.render(mesh, &mut mask);
                mask
            })
            .collect()
    }

    /// The model's silhouettes.
    pub fn model(&self) -> &[Mask] {
        &self.model
    }

    /// Pixel counts of `facade` (one mask per view, as [`Silhouettes::render`] gives) against
    /// the model.
    pub fn count(&self, facade: &[Mask]) -> PixelCounts {
        let mut counts = PixelCounts::default();
        for (model, facade) in self.model.iter().zip(facade) {
            for (m, f) in model.pixels.iter().zip(&facade.pixels) {
                counts.model_px += u64::from(*m);
                counts.facade_px += u64::from(*f);
                counts.leak_px += u64::from(*f && !*m);
            }
        }
        counts
    }
}

/// Renders `model` and `facade` from `params.views` viewpoints on a horizontal circle at half
/// the model's height around its centre (§4.1) and counts pixels. Empty or non-finite models
/// give zero counts.
pub fn measure(model: &TriangleMesh, facade: &TriangleMesh, params: &QualityParams) -> PixelCounts {
    match Silhouettes::new(model, params) {
        Some(views) => views.count(&views.render(facade)),
        None => PixelCounts::default(),
    }
}

/// Sum of the 3D areas of a mesh's triangles (m²).
pub fn mesh_area_m2(mesh: &TriangleMesh) -> f64 {
    mesh.triangles()
        .map(|[a, b, c]| 0.5 * f64::from((b - a).cross(c - a).length()))
        .sum()
}

/// Quality of one building.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BuildingQuality {
    pub building: u32,
    pub source_id: String,
    pub occluders: u32,
    /// Planar faces of the source geometry (the paper's polygons).
    pub source_polygons: u32,
    /// Planar faces of this building's occluders (counted per occluder, summed).
    pub occluder_polygons: u32,
    /// Triangles of the source geometry.
    pub source_triangles: u32,
    /// Triangles of all this building's occluders.
    pub occluder_triangles: u32,
    /// Mean polygon (planar face) area of the source geometry (m²).
    pub source_mean_polygon_area_m2: f64,
    /// Mean polygon (planar face) area of the occluders (m²); 0 without occluders.
    pub occluder_mean_polygon_area_m2: f64,
    pub pixels: PixelCounts,
    /// Occlusion-preserving quality in [0, 1] ([`PixelCounts::quality`]); `None` when the model
    /// covers no pixel.
    pub quality: Option<f64>,
    pub reason_if_none: Option<String>,
}

/// Totals and the quality distribution over a city.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct QualitySummary {
    pub buildings: usize,
    pub buildings_with_occluders: usize,
    pub occluders: usize,
    /// Planar faces (the paper's polygons) of all source buildings.
    pub source_polygons: u64,
    pub occluder_polygons: u64,
    /// source_polygons / occluder_polygons over the buildings that have occluders.
    pub polygon_reduction: f64,
    pub source_triangles: u64,
    pub occluder_triangles: u64,
    /// source_triangles / occluder_triangles over the buildings that have occluders.
    pub triangle_reduction: f64,
    /// Mean occluder polygon area over mean source polygon area (buildings with occluders).
    pub mean_polygon_area_gain: f64,
    /// Over buildings with a quality (a building without occluders counts as 0).
    pub quality_mean: f64,
    pub quality_min: f64,
    pub quality_p5: f64,
    pub quality_p25: f64,
    pub quality_p50: f64,
    /// Counts of buildings per tenth of quality: [0, 0.1), ..., [0.9, 1.0], last bin > 1
    /// (empty since quality counts only pixels inside the building; kept for the format).
    pub quality_histogram: [usize; 11],
    /// Leaked pixels over facade pixels, all buildings together.
    pub leak_fraction: f64,
    /// Buildings whose occluders leak ([`PixelCounts::leaks`]).
    #[serde(default)]
    pub buildings_with_leaks: usize,
}

/// Measures every building of `city` against its occluders in `set`. Source counts are taken
/// from the building's mesh as [`building_mesh`] gives it (2.5D parts extruded).
pub fn measure_city(
    city: &City,
    set: &OccluderSet,
    params: &QualityParams,
) -> Vec<BuildingQuality> {
    city.buildings
        .iter()
        .map(|b| {
            let outcome = set.per_building.get(b.id.index());
            let occluders = set.occluders_of(b.id);
            let model = building_mesh(b);
            let mut facade = TriangleMesh::default();
            for o in occluders {
                facade.append(&o.mesh);
            }
            let pixels = measure(&model, &facade, params);
            // Faces are counted occluder by occluder: coplanar walls of two levels that share
            // an edge are two polygons to draw, not one.
            let source_faces = planar_face_count(&model);
            let facade_faces: usize = occluders.iter().map(|o| planar_face_count(&o.mesh)).sum();
            let mean = |m: &TriangleMesh, faces: usize| {
                if faces == 0 {
                    0.0
                } else {
                    mesh_area_m2(m) / faces as f64
                }
            };
            BuildingQuality {
                building: b.id.0,
                source_id: b.source_id.clone(),
                occluders: occluders.len() as u32,
                source_polygons: source_faces as u32,
                occluder_polygons: facade_faces as u32,
                source_triangles: model.triangle_count() as u32,
                occluder_triangles: facade.triangle_count() as u32,
                source_mean_polygon_area_m2: mean(&model, source_faces),
                occluder_mean_polygon_area_m2: mean(&facade, facade_faces),
                pixels,
                quality: pixels.quality(),
                reason_if_none: outcome.and_then(|o| o.reason_if_none.clone()),
            }
        })
        .collect()
}

/// Totals and distribution of per-building results.
pub fn summarise(rows: &[BuildingQuality]) -> QualitySummary {
    let with: Vec<&BuildingQuality> = rows.iter().filter(|r| r.occluders > 0).collect();
    let source_polygons: u64 = rows.iter().map(|r| u64::from(r.source_polygons)).sum();
    let occluder_polygons: u64 = rows.iter().map(|r| u64::from(r.occluder_polygons)).sum();
    let with_source: u64 = with.iter().map(|r| u64::from(r.source_polygons)).sum();
    let source_triangles: u64 = rows.iter().map(|r| u64::from(r.source_triangles)).sum();
    let occluder_triangles: u64 = rows.iter().map(|r| u64::from(r.occluder_triangles)).sum();
    let with_source_triangles: u64 = with.iter().map(|r| u64::from(r.source_triangles)).sum();
    let ratio = |a: u64, b: u64| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    let mean_of = |f: &dyn Fn(&BuildingQuality) -> f64| {
        if with.is_empty() {
            0.0
        } else {
            with.iter().map(|r| f(r)).sum::<f64>() / with.len() as f64
        }
    };
    let src_area = mean_of(&|r| r.source_mean_polygon_area_m2);
    let occ_area = mean_of(&|r| r.occluder_mean_polygon_area_m2);
    let mut qualities: Vec<f64> = rows.iter().filter_map(|r| r.quality).collect();
    qualities.sort_by(f64::total_cmp);
    let percentile = |p: f64| {
        if qualities.is_empty() {
            0.0
        } else {
            let i = ((qualities.len() - 1) as f64 * p).round() as usize;
            qualities[i.min(qualities.len() - 1)]
        }
    };
    let mut histogram = [0usize; 11];
    for q in &qualities {
        let bin = if *q > 1.0 {
            10
        } else {
            ((q * 10.0).floor() as usize).min(9)
        };
        histogram[bin] += 1;
    }
    let facade_px: u64 = rows.iter().map(|r| r.pixels.facade_px).sum();
    let leak_px: u64 = rows.iter().map(|r| r.pixels.leak_px).sum();
    QualitySummary {
        buildings: rows.len(),
        buildings_with_occluders: with.len(),
        occluders: rows.iter().map(|r| r.occluders as usize).sum(),
        source_polygons,
        occluder_polygons,
        polygon_reduction: ratio(with_source, occluder_polygons),
        source_triangles,
        occluder_triangles,
        triangle_reduction: ratio(with_source_triangles, occluder_triangles),
        mean_polygon_area_gain: if src_area > 0.0 {
            occ_area / src_area
        } else {
            0.0
        },
        quality_mean: if qualities.is_empty() {
            0.0
        } else {
            qualities.iter().sum::<f64>() / qualities.len() as f64
        },
        quality_min: qualities.first().copied().unwrap_or(0.0),
        quality_p5: percentile(0.05),
        quality_p25: percentile(0.25),
        quality_p50: percentile(0.5),
        quality_histogram: histogram,
        leak_fraction: if facade_px == 0 {
            0.0
        } else {
            leak_px as f64 / facade_px as f64
        },
        buildings_with_leaks: rows.iter().filter(|r| r.pixels.leaks()).count(),
    }
}

/// How many walls a facade needs just to follow the buildings' outlines: the walls of a
/// single-level open facade on every building's footprint, and on the union of all footprints
/// (adjacent buildings merged into blocks, shared walls gone), both simplified as §3.3 allows.
/// Every footprint vertex gives one wall (§3.3: "each vertex in a footprint accounts for ...
/// one quad"), so these are the polygon counts below which a facade must give up parts of the
/// outline, and with them occlusion.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct OutlineWalls {
    /// Σ over buildings of the edges of the simplified footprint.
    pub per_building: u64,
    /// Connected parts of the union of all footprints (blocks).
    pub blocks: u64,
    /// Edges of the simplified union of all footprints.
    pub merged_blocks: u64,
}

/// Counts [`OutlineWalls`] for `city` with the simplification of `params`.
pub fn outline_walls(city: &City, params: &super::OccluderParams) -> OutlineWalls {
    let edges = |mp: &geo::MultiPolygon<f64>| -> u64 {
        mp.0.iter()
            .flat_map(|p| std::iter::once(p.exterior()).chain(p.interiors()))
            .map(|r| r.0.len().saturating_sub(1) as u64)
            .sum()
    };
    let per_building = city
        .buildings
        .iter()
        .map(|b| edges(&super::simplify::simplify_footprint(&b.footprint, params)))
        .sum();
    let union = geo::unary_union(city.buildings.iter().flat_map(|b| b.footprint.0.iter()));
    let merged = super::simplify::simplify_footprint(&union, params);
    OutlineWalls {
        per_building,
        blocks: merged.0.len() as u64,
        merged_blocks: edges(&merged),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::occluders::facade::facade_mesh;
    use citywalk_scenes::occluder::FacadeKind;
    use geo::{MultiPolygon, Rect, coord};

    #[test]
    fn a_triangle_fills_about_its_area() {
        let mut m = Mask::new(100, 100);
        m.fill_triangle([[0.0, 0.0], [100.0, 0.0], [0.0, 100.0]]);
        let n = m.count() as f64;
        assert!((n - 5000.0).abs() < 150.0, "{n}");
        // Orientation does not matter.
        let mut m2 = Mask::new(100, 100);
        m2.fill_triangle([[0.0, 0.0], [0.0, 100.0], [100.0, 0.0]]);
        assert_eq!(m.pixels, m2.pixels);
        // Off-screen and degenerate triangles are clipped / skipped.
        let mut m3 = Mask::new(10, 10);
        m3.fill_triangle([[-50.0, -50.0], [-40.0, -50.0], [-50.0, -40.0]]);
        m3.fill_triangle([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]);
        assert_eq!(m3.count(), 0);
    }

    fn square(size: f64) -> MultiPolygon<f64> {
        MultiPolygon::new(vec![
            Rect::new(coord! {x: 0.0, y: 0.0}, coord! {x: size, y: size}).to_polygon(),
        ])
    }

    #[test]
    fn a_box_and_its_own_open_facade_match() {
        let model = citywalk_scenes::extrude::extrude_polygon(&square(10.0).0[0], 0.0, 20.0);
        let facade = facade_mesh(&square(10.0), 0.0, 20.0, FacadeKind::Open, |_, _| 0.0);
        let counts = measure(&model, &facade, &QualityParams::default());
        assert!(counts.model_px > 1000);
        let q = counts.quality().unwrap();
        assert!(q > 0.97 && q <= 1.0, "{q}");
        assert!(counts.leak_fraction() < 0.01, "{counts:?}");
    }

    #[test]
    fn a_lower_facade_loses_quality_in_proportion() {
        let model = citywalk_scenes::extrude::extrude_polygon(&square(10.0).0[0], 0.0, 20.0);
        let facade = facade_mesh(&square(10.0), 0.0, 10.0, FacadeKind::Open, |_, _| 0.0);
        let q = measure(&model, &facade, &QualityParams::default())
            .quality()
            .unwrap();
        // Seen from the side at half height, the lower half covers about half the pixels
        // (a little more: the roof of the model adds nothing from a horizontal view).
        assert!(q > 0.4 && q < 0.6, "{q}");
    }

    #[test]
    fn a_facade_outside_the_model_leaks() {
        let model = citywalk_scenes::extrude::extrude_polygon(&square(10.0).0[0], 0.0, 20.0);
        let facade = facade_mesh(&square(12.0), 0.0, 20.0, FacadeKind::Open, |_, _| 0.0);
        let counts = measure(&model, &facade, &QualityParams::default());
        assert!(counts.leak_fraction() > 0.02, "{counts:?}");
        assert!(counts.leaks());
        // The larger facade covers more pixels than the model, yet its quality is that of the
        // model's own silhouette at most, the excess reported as a leak.
        assert!(counts.facade_px > counts.model_px, "{counts:?}");
        let q = counts.quality().unwrap_or(0.0);
        assert!(q > 0.97 && q <= 1.0, "{q}");
    }

    #[test]
    fn outline_walls_of_two_touching_boxes() {
        use citywalk_scenes::{
            Building, BuildingId, BuildingPart, Frame, HeightSource, LoadReport,
        };
        let building = |id: u32, x0: f64| {
            let footprint = MultiPolygon::new(vec![
                Rect::new(coord! {x: x0, y: 0.0}, coord! {x: x0 + 10.0, y: 8.0}).to_polygon(),
            ]);
            Building {
                id: BuildingId(id),
                source_id: id.to_string(),
                parts: vec![BuildingPart {
                    source_id: id.to_string(),
                    footprint: footprint.clone(),
                    base_m: 0.0,
                    top_m: 10.0,
                }],
                footprint,
                base_m: 0.0,
                top_m: 10.0,
                height_source: HeightSource::Geometry,
                mesh: None,
                tags: Default::default(),
            }
        };
        let city = City {
            frame: Frame::local(),
            buildings: vec![building(0, 0.0), building(1, 10.0), building(2, 40.0)],
            streets: Vec::new(),
            ground_areas: Vec::new(),
            report: LoadReport::default(),
        };
        let w = outline_walls(&city, &crate::occluders::OccluderParams::default());
        // Three boxes of four walls; the two touching ones merge into one rectangle.
        assert_eq!(w.per_building, 12);
        assert_eq!(w.blocks, 2);
        assert_eq!(w.merged_blocks, 8);
    }

    #[test]
    fn summary_percentiles_and_histogram() {
        let row = |q: f64| BuildingQuality {
            building: 0,
            source_id: String::new(),
            occluders: 1,
            source_polygons: 100,
            occluder_polygons: 10,
            source_triangles: 300,
            occluder_triangles: 20,
            source_mean_polygon_area_m2: 1.0,
            occluder_mean_polygon_area_m2: 10.0,
            pixels: PixelCounts::default(),
            quality: Some(q),
            reason_if_none: None,
        };
        let rows: Vec<_> = (0..=10).map(|i| row(f64::from(i) / 10.0)).collect();
        let s = summarise(&rows);
        assert_eq!(s.buildings, 11);
        assert!((s.quality_mean - 0.5).abs() < 1e-12);
        assert_eq!(s.quality_min, 0.0);
        assert!((s.quality_p50 - 0.5).abs() < 1e-12);
        assert_eq!(s.quality_histogram.iter().sum::<usize>(), 11);
        assert_eq!(s.quality_histogram[9], 2); // 0.9 and 1.0
        assert!((s.polygon_reduction - 10.0).abs() < 1e-12);
        assert!((s.triangle_reduction - 15.0).abs() < 1e-12);
        assert_eq!((s.source_triangles, s.occluder_triangles), (3300, 220));
        assert!((s.mean_polygon_area_gain - 10.0).abs() < 1e-12);
    }
}
