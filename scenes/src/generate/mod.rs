//! Procedural cities: an irregular street network, blocks, lots and multi-level buildings, for
//! tests, benchmarks and demos at any scale (100 to 1,000,000 buildings).
//!
//! # What is generated
//!
//! - **Streets** on a warped, jittered lattice ([`layout`]): columns and rows of uneven spacing,
//!   bent at each crossing, curving over kilometres and turning with the distance from the
//!   centre; every 8th column and 6th row is a major avenue (30 m), some others minor streets
//!   (20 m), the rest residential (14 m); one or two diagonal avenues ("Broadway") cross the
//!   city through lattice nodes.
//! - **Blocks**: the faces between streets (quads, or two triangles where a diagonal cuts),
//!   shrunk so that every building stays at least half the street width plus 0.5 m from every
//!   street centre line.
//! - **Lots**: blocks split along their frontage (Parish & Müller 2001, see [`lots`]); lots
//!   without street access are left empty as yards.
//! - **Buildings** on lots ([`building`]): low-rise, stepped, podium with tower, courtyard
//!   blocks (footprints with a hole), L- and U-shapes, and landmarks (about one per
//!   [`GenerateParams::landmark_every`] buildings, 3.2–8× the local typical height; the first is
//!   always downtown). Heights follow [`districts`]: a dense tall centre, secondary centres in
//!   large cities, a low periphery.
//!
//! Neighbouring buildings never touch (each lot edge shared with another lot is set back by
//! at least 0.3 m); about 3% of blocks outside the two central rings are left empty as parks.
//!
//! Blocks are filled from the centre outwards until exactly [`GenerateParams::buildings`]
//! buildings exist; streets are those around the blocks used. Everything is a function of the
//! seed: the global choices come from a `ChaCha8Rng` seeded with it, each block's from a
//! `ChaCha8Rng` seeded with a hash of the seed and the block, so the same seed gives the same
//! city, byte for byte. Coordinates are snapped to a 1 cm grid in the model too, so the
//! GeoJSON holds exactly the model's coordinates.
//!
//! # GeoJSON contract (read by `crate::load::geojson`)
//!
//! One `FeatureCollection`, coordinates in **local metres** (x east, y north, two decimals),
//! declared with the legacy member `"crs": {"type": "name", "properties": {"name":
//! "citywalk:local"}}`, which a loader must map to `Frame::local()` (not longitude/latitude).
//! Features, in this order:
//!
//! 1. **Building**: `Polygon` or `MultiPolygon` geometry (the outline of the whole building,
//!    holes for courtyards), properties
//!    `{"id": "b<N>", "height": <top m>, "min_height": 0, "building": "yes",
//!    "form": "<form>", "landmark": true}` (`landmark` only on landmarks; `form` is one of
//!    `low_rise`, `stepped`, `podium_tower`, `courtyard`, `l_shape`, `u_shape`, `landmark`).
//!    `N` is the building's index, `0..buildings`.
//! 2. **Building part**, directly after its building, only when the building has more than
//!    one Z-level or wing: one feature per part (all parts, the ground one included: as in
//!    OSM Simple 3D Buildings, the parts replace the outline for rendering), geometry a
//!    `Polygon`, properties `{"kind": "building:part", "id": "b<N>/p<k>", "part_of": "b<N>",
//!    "height": <top m>, "min_height": <base m>}`. `height` is the top above ground, not the
//!    part's own extent. A single-level building has no part features; its one part is the
//!    building itself.
//! 3. **Street**: `LineString` geometry (centre line through the crossings), properties
//!    `{"id": "s<N>", "highway": "primary" | "tertiary" | "residential", "name": "...",
//!    "width": <m>}`; `highway` maps back to [`StreetClass`] with
//!    `StreetClass::from_osm_highway`, `width` is the whole corridor (building line to
//!    building line).
//!
//! Heights are decimetres, so `f32` values read back exactly.
//!
//! # Use
//!
//! ```no_run
//! use citywalk_scenes::generate::{GenerateParams, generate_city, write_geojson_file};
//!
//! let params = GenerateParams::new(10_000, 7);
//! let city = generate_city(&params)?; // in memory, for tests and benches
//! assert_eq!(city.buildings.len(), 10_000);
//! // Streamed to disk: a million buildings take about 5 s and 12 MB (release, 2 cores).
//! write_geojson_file(&params, std::path::Path::new("city.geojson"), &mut |_done| {})?;
//! # Ok::<(), citywalk_scenes::generate::GenerateError>(())
//! ```

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use geo::BoundingRect;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::city::{Building, City, Street, StreetClass};
use crate::frame::Frame;
use crate::report::LoadReport;

pub mod building;
pub mod districts;
pub mod geojson;
pub mod layout;
pub mod lots;
pub mod polygon;

pub use building::Form;
pub use geojson::{GeoJsonWriter, LOCAL_CRS_NAME, highway_value, write_city_geojson};
pub use layout::street_width_m;

use building::{MIN_LANDMARK_LOT_M2, Site};
use districts::Districts;
use layout::{Layout, Node, hash, unit};

/// Most buildings one city may have: beyond this the city would reach past
/// [`crate::validate::MAX_LOCAL_COORDINATE_M`].
pub const MAX_BUILDINGS: usize = 20_000_000;
/// Footprint area per building, streets included, used to size the district field (m²;
/// measured on generated cities, 700–900 m²).
const AREA_PER_BUILDING_M2: f64 = 800.0;
/// Share of quads left as parks (no buildings) outside the first rings.
const PARK_SHARE: f64 = 0.03;
const SALT_QUAD: u64 = 101;
const SALT_PARK: u64 = 102;

/// Parameters of a generated city.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GenerateParams {
    /// Exact number of buildings.
    pub buildings: usize,
    /// Seed of every random choice.
    pub seed: u64,
    /// Mean distance between the centre lines of neighbouring columns (metres); rows are
    /// 1.2–1.9× further apart. 60..=400.
    pub block_size_m: f64,
    /// One landmark per this many buildings (rounded, at least one); 0 for none.
    pub landmark_every: usize,
    /// Whether diagonal avenues cut through the grid (from 300 buildings on).
    pub diagonals: bool,
}

impl Default for GenerateParams {
    fn default() -> Self {
        GenerateParams {
            buildings: 2_000,
            seed: 1,
            block_size_m: 100.0,
            landmark_every: 2_000,
            diagonals: true,
        }
    }
}

impl GenerateParams {
    /// Default parameters for `buildings` buildings from `seed`.
    pub fn new(buildings: usize, seed: u64) -> GenerateParams {
        GenerateParams {
            buildings,
            seed,
            ..GenerateParams::default()
        }
    }

    /// Checks the parameters' ranges.
    pub fn validate(&self) -> Result<(), GenerateError> {
        if !(1..=MAX_BUILDINGS).contains(&self.buildings) {
            return Err(GenerateError::InvalidParameter {
                name: "buildings",
                reason: format!("{} is outside 1..={MAX_BUILDINGS}", self.buildings),
            });
        }
        if !(60.0..=400.0).contains(&self.block_size_m) {
            return Err(GenerateError::InvalidParameter {
                name: "block_size_m",
                reason: format!("{} m is outside 60..=400 m", self.block_size_m),
            });
        }
        Ok(())
    }

    fn landmarks(&self) -> usize {
        if self.landmark_every == 0 || self.buildings == 0 {
            0
        } else {
            ((self.buildings + self.landmark_every / 2) / self.landmark_every)
                .max(1)
                .min(self.buildings)
        }
    }
}

/// Why a city could not be generated or written.
#[derive(Debug, thiserror::Error)]
pub enum GenerateError {
    #[error("invalid parameter {name}: {reason}")]
    InvalidParameter { name: &'static str, reason: String },
    #[error("placed only {placed} of {wanted} buildings within {radius_m:.0} m of the centre")]
    OutOfRoom {
        wanted: usize,
        placed: usize,
        radius_m: f64,
    },
    #[error("writing {path}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

/// Counts and extent of a generated city.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GenerateSummary {
    pub buildings: usize,
    /// All building parts (a single-level building counts one).
    pub parts: usize,
    pub streets: usize,
    pub landmarks: usize,
    /// Bounds of the building footprints `[x, y]` (metres).
    pub min_m: [f64; 2],
    pub max_m: [f64; 2],
    pub max_height_m: f32,
}

impl GenerateSummary {
    fn add(&mut self, b: &Building) {
        if self.buildings == 0 {
            self.min_m = [f64::MAX; 2];
            self.max_m = [f64::MIN; 2];
        }
        self.buildings += 1;
        self.parts += b.parts.len();
        if b.tags.get("landmark").is_some_and(|v| v == "yes") {
            self.landmarks += 1;
        }
        if let Some(r) = b.footprint.bounding_rect() {
            self.min_m = [self.min_m[0].min(r.min().x), self.min_m[1].min(r.min().y)];
            self.max_m = [self.max_m[0].max(r.max().x), self.max_m[1].max(r.max().y)];
        }
        self.max_height_m = self.max_height_m.max(b.top_m);
    }

    /// Width and depth of the building extent (metres).
    pub fn extent_m(&self) -> [f64; 2] {
        if self.buildings == 0 {
            return [0.0; 2];
        }
        [self.max_m[0] - self.min_m[0], self.max_m[1] - self.min_m[1]]
    }
}

/// Generates the city, handing each building to `sink` as soon as it is made (buildings come
/// numbered `0..buildings`), and returns the streets and the summary.
pub fn generate(
    params: &GenerateParams,
    sink: &mut dyn FnMut(Building) -> Result<(), GenerateError>,
) -> Result<(Vec<Street>, GenerateSummary), GenerateError> {
    params.validate()?;
    let wanted = params.buildings;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let diagonals = if params.diagonals && wanted >= 300 {
        rng.random_range(1..=2)
    } else {
        0
    };
    let layout = Layout::new(&mut rng, params.seed, params.block_size_m, diagonals);
    let radius_m = (wanted as f64 * AREA_PER_BUILDING_M2 / std::f64::consts::PI).sqrt();
    let districts = Districts::new(&mut rng, params.seed, radius_m);
    let mut landmarks = landmark_schedule(params, &mut rng);
    landmarks.reverse(); // popped from the back, earliest first

    let mut summary = GenerateSummary::default();
    let mut quads: Vec<Node> = Vec::new();
    let (column_m, row_m) = layout.spacing_m();
    let max_radius_m = crate::validate::MAX_LOCAL_COORDINATE_M * 0.75;
    let mut shell: i64 = 0;
    'shells: while summary.buildings < wanted {
        if shell as f64 * column_m > max_radius_m {
            return Err(GenerateError::OutOfRoom {
                wanted,
                placed: summary.buildings,
                radius_m: max_radius_m,
            });
        }
        for quad in shell_quads(shell, column_m, row_m) {
            if summary.buildings >= wanted {
                break 'shells;
            }
            quads.push(quad);
            let mut quad_rng =
                ChaCha8Rng::seed_from_u64(hash(params.seed, SALT_QUAD, quad.0, quad.1));
            if shell >= 2 && unit(hash(params.seed, SALT_PARK, quad.0, quad.1)) < PARK_SHARE {
                continue;
            }
            for block in layout.blocks(quad) {
                let centre = block.centre();
                let intensity = districts.intensity(centre);
                let max_lot = building::max_lot_m2(intensity, &mut quad_rng);
                for lot in lots::subdivide(&block, max_lot, &mut quad_rng) {
                    if summary.buildings >= wanted {
                        break 'shells;
                    }
                    let index = summary.buildings;
                    let left = wanted - index;
                    let is_landmark = landmarks.last().is_some_and(|&due| {
                        index >= due
                            && (lot.area_m2() >= MIN_LANDMARK_LOT_M2 || left <= landmarks.len())
                    });
                    let at = lot.centre();
                    let site = Site {
                        intensity: districts.intensity(at),
                        typical_height_m: districts.typical_height_m(at),
                    };
                    let Some(plan) = building::plan(&lot, &site, is_landmark, &mut quad_rng) else {
                        continue;
                    };
                    if plan.form == Form::Landmark {
                        landmarks.pop();
                    }
                    let b = plan.into_building(index);
                    summary.add(&b);
                    sink(b)?;
                }
            }
        }
        shell += 1;
    }
    let streets = layout.streets(&quads);
    summary.streets = streets.len();
    Ok((streets, summary))
}

/// The building indices at which landmarks are due: the first downtown (within the first 5%
/// of buildings, which are the central ones), the others anywhere.
fn landmark_schedule(params: &GenerateParams, rng: &mut ChaCha8Rng) -> Vec<usize> {
    let n = params.buildings;
    let count = params.landmarks();
    let mut due = Vec::with_capacity(count);
    for k in 0..count {
        let end = if k == 0 { (n / 20).max(1) } else { n };
        due.push(rng.random_range(0..end));
    }
    due.sort_unstable();
    due
}

/// The quads whose centres lie in ring `shell` around the origin (in units of the column
/// spacing), in a fixed order.
fn shell_quads(shell: i64, column_m: f64, row_m: f64) -> Vec<Node> {
    let i_max = shell + 1;
    let j_max = ((shell + 1) as f64 * column_m / row_m).ceil() as i64;
    let mut out = Vec::new();
    for i in -(i_max + 1)..=i_max {
        for j in -(j_max + 1)..=j_max {
            let x = (i as f64 + 0.5) * column_m;
            let y = (j as f64 + 0.5) * row_m;
            if ((x * x + y * y).sqrt() / column_m).floor() as i64 == shell {
                out.push((i, j));
            }
        }
    }
    out
}

/// Generates the city in memory: local frame, tagged heights, multi-level buildings as several
/// parts, streets with their classes.
pub fn generate_city(params: &GenerateParams) -> Result<City, GenerateError> {
    // Checked before the vector is sized by the count.
    params.validate()?;
    let mut buildings = Vec::with_capacity(params.buildings);
    let (streets, summary) = generate(params, &mut |b| {
        buildings.push(b);
        Ok(())
    })?;
    let report = LoadReport {
        files: Vec::new(),
        buildings_found: summary.buildings,
        buildings_loaded: summary.buildings,
        parts_found: summary.parts,
        buildings_with_height: summary.buildings,
        buildings_estimated_height: 0,
        streets_found: streets.len(),
        streets_loaded: streets.len(),
        rejected: Vec::new(),
        streets_rejected: Vec::new(),
        warnings: Vec::new(),
        ..LoadReport::default()
    };
    Ok(City {
        frame: Frame::local(),
        buildings,
        streets,
        ground_areas: Vec::new(),
        report,
    })
}

/// Generates the city straight into GeoJSON (see the module docs), without keeping it in
/// memory. `progress` is called with the number of buildings written, every 4,096 buildings.
/// `path` names the output in errors.
pub fn write_geojson<W: Write>(
    params: &GenerateParams,
    out: W,
    path: &Path,
    progress: &mut dyn FnMut(usize),
) -> Result<(W, GenerateSummary), GenerateError> {
    let io = |source| GenerateError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut writer = GeoJsonWriter::new(out).map_err(io)?;
    let mut written = 0usize;
    let (streets, summary) = generate(params, &mut |b| {
        writer.write_building(&b).map_err(io)?;
        written += 1;
        if written.is_multiple_of(4_096) {
            progress(written);
        }
        Ok(())
    })?;
    for s in &streets {
        writer.write_street(s).map_err(io)?;
    }
    progress(written);
    let out = writer.finish().map_err(io)?;
    Ok((out, summary))
}

/// [`write_geojson`] into a new file at `path` (buffered).
pub fn write_geojson_file(
    params: &GenerateParams,
    path: &Path,
    progress: &mut dyn FnMut(usize),
) -> Result<GenerateSummary, GenerateError> {
    let file = File::create(path).map_err(|source| GenerateError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let (_, summary) = write_geojson(
        params,
        BufWriter::with_capacity(1 << 20, file),
        path,
        progress,
    )?;
    Ok(summary)
}

/// Half the corridor width of a street of `class` (metres): no building comes closer to the
/// street's centre line than this (plus a 0.5 m margin).
pub fn corridor_half_width_m(class: StreetClass) -> f64 {
    street_width_m(class) / 2.0
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeSet;

    use super::*;

    #[test]
    fn shells_cover_each_quad_once_centre_first() {
        let mut seen = BTreeSet::new();
        let mut last_distance = 0.0_f64;
        for shell in 0..12 {
            for (i, j) in shell_quads(shell, 100.0, 150.0) {
                assert!(seen.insert((i, j)), "({i}, {j}) twice");
                let d = ((i as f64 + 0.5) * 100.0).hypot((j as f64 + 0.5) * 150.0);
                assert!(d >= (last_distance / 100.0).floor() * 100.0);
                last_distance = last_distance.max(d);
            }
        }
        // Exactly the quads whose centres are within 12 shells (1,200 m) were visited.
        for i in -14..14 {
            for j in -10..10 {
                let d = ((i as f64 + 0.5) * 100.0).hypot((j as f64 + 0.5) * 150.0);
                assert_eq!(d < 1_200.0, seen.contains(&(i, j)), "({i}, {j}) at {d} m");
            }
        }
    }

    #[test]
    fn parameters_are_checked_and_landmarks_scheduled() {
        let bad = GenerateParams {
            block_size_m: 10.0,
            ..GenerateParams::default()
        };
        assert!(matches!(
            generate_city(&bad),
            Err(GenerateError::InvalidParameter {
                name: "block_size_m",
                ..
            })
        ));
        let too_many = GenerateParams::new(MAX_BUILDINGS + 1, 1);
        assert!(too_many.validate().is_err());
        assert_eq!(GenerateParams::new(100, 1).landmarks(), 1);
        assert_eq!(GenerateParams::new(1_000_000, 1).landmarks(), 500);
        let none = GenerateParams {
            landmark_every: 0,
            ..GenerateParams::new(5_000, 1)
        };
        assert_eq!(none.landmarks(), 0);
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let due = landmark_schedule(&GenerateParams::new(40_000, 3), &mut rng);
        assert_eq!(due.len(), 20);
        assert!(due[0] < 2_000 && due.windows(2).all(|w| w[0] <= w[1]));
    }
}
