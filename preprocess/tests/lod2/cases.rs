//! Small LoD2 cities written as CityJSON 1.0 text, the shapes of real LoD2 data that break
//! naive occluder building: gabled and hipped roofs, terraces whose houses share party walls
//! (stored twice, once, or not at all), faces wound the wrong way, and shells with a missing
//! face. Every surface carries its Roof/Wall/Ground semantic as LoD2 data does.

use std::collections::HashMap;

use serde_json::{Value, json};

/// A point in metres.
pub type P = [f64; 3];

/// CityJSON surface semantics used here.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Semantic {
    Roof,
    Wall,
    Ground,
}

impl Semantic {
    fn name(self) -> &'static str {
        match self {
            Semantic::Roof => "RoofSurface",
            Semantic::Wall => "WallSurface",
            Semantic::Ground => "GroundSurface",
        }
    }
}

/// One planar surface: its semantic and its outer ring, counter-clockwise seen from outside.
pub type Surface = (Semantic, Vec<P>);

/// A house of plan `[x0, x1] × [y0, y1]`, eaves at `eaves_m`, as surfaces wound outward.
#[derive(Debug, Clone, Copy)]
pub struct Plan {
    pub x0: f64,
    pub x1: f64,
    pub y0: f64,
    pub y1: f64,
    pub eaves_m: f64,
}

impl Plan {
    pub fn new(x0: f64, y0: f64, width: f64, depth: f64, eaves_m: f64) -> Plan {
        Plan {
            x0,
            x1: x0 + width,
            y0,
            y1: y0 + depth,
            eaves_m,
        }
    }

    fn ym(&self) -> f64 {
        0.5 * (self.y0 + self.y1)
    }

    pub fn ground(&self) -> Surface {
        let Plan { x0, x1, y0, y1, .. } = *self;
        (
            Semantic::Ground,
            vec![[x0, y0, 0.0], [x0, y1, 0.0], [x1, y1, 0.0], [x1, y0, 0.0]],
        )
    }

    /// The wall from plan corner `a` to `b` up to the eaves, wound outward when `a → b` runs
    /// counter-clockwise round the plan.
    fn wall(&self, a: [f64; 2], b: [f64; 2]) -> Surface {
        let e = self.eaves_m;
        let ring = vec![
            [a[0], a[1], 0.0],
            [b[0], b[1], 0.0],
            [b[0], b[1], e],
            [a[0], a[1], e],
        ];
        (Semantic::Wall, ring)
    }

    /// The long walls (south, north) up to the eaves.
    pub fn long_walls(&self) -> [Surface; 2] {
        let Plan { x0, x1, y0, y1, .. } = *self;
        [self.wall([x0, y0], [x1, y0]), self.wall([x1, y1], [x0, y1])]
    }

    /// The short walls (east, west) up to the eaves, for hipped and flat roofs.
    pub fn end_walls(&self) -> [Surface; 2] {
        let Plan { x0, x1, y0, y1, .. } = *self;
        [self.wall([x1, y0], [x1, y1]), self.wall([x0, y1], [x0, y0])]
    }

    /// The gable end at `x` (east when `east`), a pentagon up to the ridge at `ridge_m`.
    pub fn gable_end(&self, east: bool, ridge_m: f64) -> Surface {
        let Plan {
            y0, y1, eaves_m: e, ..
        } = *self;
        let ym = self.ym();
        let ring = if east {
            let x = self.x1;
            vec![
                [x, y0, 0.0],
                [x, y1, 0.0],
                [x, y1, e],
                [x, ym, ridge_m],
                [x, y0, e],
            ]
        } else {
            let x = self.x0;
            vec![
                [x, y1, 0.0],
                [x, y0, 0.0],
                [x, y0, e],
                [x, ym, ridge_m],
                [x, y1, e],
            ]
        };
        (Semantic::Wall, ring)
    }

    /// The two roof planes of a gable roof with its ridge along x at `ridge_m`.
    pub fn gable_roof(&self, ridge_m: f64) -> [Surface; 2] {
        let Plan {
            x0,
            x1,
            y0,
            y1,
            eaves_m: e,
        } = *self;
        let (ym, r) = (self.ym(), ridge_m);
        [
            (
                Semantic::Roof,
                vec![[x0, y0, e], [x1, y0, e], [x1, ym, r], [x0, ym, r]],
            ),
            (
                Semantic::Roof,
                vec![[x0, ym, r], [x1, ym, r], [x1, y1, e], [x0, y1, e]],
            ),
        ]
    }

    /// Every surface of a gabled house, in the order ground, south, north, east, west,
    /// south roof, north roof.
    pub fn gabled_house(&self, ridge_m: f64) -> Vec<Surface> {
        let [south, north] = self.long_walls();
        let [roof_s, roof_n] = self.gable_roof(ridge_m);
        vec![
            self.ground(),
            south,
            north,
            self.gable_end(true, ridge_m),
            self.gable_end(false, ridge_m),
            roof_s,
            roof_n,
        ]
    }

    /// A hipped house: four walls to the eaves, two trapezoid and two triangle roof planes
    /// meeting a ridge along x at `ridge_m`, inset by half the depth at both ends.
    pub fn hipped_house(&self, ridge_m: f64) -> Vec<Surface> {
        let Plan {
            x0,
            x1,
            y0,
            y1,
            eaves_m: e,
        } = *self;
        let (ym, r) = (self.ym(), ridge_m);
        let inset = 0.5 * (y1 - y0);
        let (rx0, rx1) = (x0 + inset, x1 - inset);
        let [south, north] = self.long_walls();
        let [east, west] = self.end_walls();
        vec![
            self.ground(),
            south,
            north,
            east,
            west,
            (
                Semantic::Roof,
                vec![[x0, y0, e], [x1, y0, e], [rx1, ym, r], [rx0, ym, r]],
            ),
            (
                Semantic::Roof,
                vec![[x1, y1, e], [x0, y1, e], [rx0, ym, r], [rx1, ym, r]],
            ),
            (Semantic::Roof, vec![[x1, y0, e], [x1, y1, e], [rx1, ym, r]]),
            (Semantic::Roof, vec![[x0, y1, e], [x0, y0, e], [rx0, ym, r]]),
        ]
    }

    /// A flat-roofed box up to the eaves.
    pub fn flat_box(&self) -> Vec<Surface> {
        let Plan {
            x0,
            x1,
            y0,
            y1,
            eaves_m: e,
        } = *self;
        let [south, north] = self.long_walls();
        let [east, west] = self.end_walls();
        vec![
            self.ground(),
            south,
            north,
            east,
            west,
            (
                Semantic::Roof,
                vec![[x0, y0, e], [x1, y0, e], [x1, y1, e], [x0, y1, e]],
            ),
        ]
    }
}

/// Reverses the winding of a surface (its normal then points inward).
pub fn flipped((semantic, mut ring): Surface) -> Surface {
    ring.reverse();
    (semantic, ring)
}

/// How a terrace stores the walls its houses share.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PartyWalls {
    /// In both houses (each shell closed; the faces coincide, wound oppositely).
    Both,
    /// Only in the house west of the wall (the eastern house's shell is open there).
    Once,
    /// In neither house (inner houses are open at both ends; the row as a whole is closed).
    None,
}

/// The houses of a gabled terrace of `houses` houses of `width` m along x, from `x0`.
pub fn terrace(
    x0: f64,
    y0: f64,
    houses: usize,
    width: f64,
    party: PartyWalls,
) -> Vec<Vec<Surface>> {
    let (depth, eaves, ridge) = (9.0, 6.0, 10.0);
    (0..houses)
        .map(|k| {
            let plan = Plan::new(x0 + width * k as f64, y0, width, depth, eaves);
            let [south, north] = plan.long_walls();
            let [roof_s, roof_n] = plan.gable_roof(ridge);
            let mut s = vec![plan.ground(), south, north, roof_s, roof_n];
            let first = k == 0;
            let last = k + 1 == houses;
            let west = first || party == PartyWalls::Both;
            let east = last || matches!(party, PartyWalls::Both | PartyWalls::Once);
            if west {
                s.push(plan.gable_end(false, ridge));
            }
            if east {
                s.push(plan.gable_end(true, ridge));
            }
            s
        })
        .collect()
}

/// Writes CityJSON 1.0: integer vertices in millimetres with a `transform`, one geometry per
/// object (`MultiSurface` or `Solid`), semantics on every surface.
#[derive(Debug, Default)]
pub struct CityJson {
    vertices: Vec<[i64; 3]>,
    index: HashMap<[i64; 3], usize>,
    objects: serde_json::Map<String, Value>,
}

impl CityJson {
    fn vertex(&mut self, p: P) -> usize {
        let key = p.map(|c| (c * 1000.0).round() as i64);
        let next = self.vertices.len();
        *self.index.entry(key).or_insert_with(|| {
            self.vertices.push(key);
            next
        })
    }

    /// Adds a `Building` of `surfaces` as a `MultiSurface` or (when `solid`) a one-shell
    /// `Solid`, LoD 2.
    pub fn building(&mut self, id: &str, surfaces: &[Surface], solid: bool) {
        let mut kinds: Vec<Semantic> = Vec::new();
        let mut values = Vec::new();
        let mut boundaries = Vec::new();
        for (semantic, ring) in surfaces {
            let ring: Vec<usize> = ring.iter().map(|p| self.vertex(*p)).collect();
            boundaries.push(json!([ring]));
            let k = kinds.iter().position(|s| s == semantic).unwrap_or_else(|| {
                kinds.push(*semantic);
                kinds.len() - 1
            });
            values.push(k);
        }
        let kinds: Vec<Value> = kinds.iter().map(|s| json!({"type": s.name()})).collect();
        let geometry = if solid {
            json!({
                "type": "Solid", "lod": 2,
                "boundaries": [boundaries],
                "semantics": {"surfaces": kinds, "values": [values]},
            })
        } else {
            json!({
                "type": "MultiSurface", "lod": 2,
                "boundaries": boundaries,
                "semantics": {"surfaces": kinds, "values": values},
            })
        };
        self.objects.insert(
            id.to_owned(),
            json!({"type": "Building", "geometry": [geometry]}),
        );
    }

    pub fn to_bytes(&self) -> Vec<u8> {
        let doc = json!({
            "type": "CityJSON",
            "version": "1.0",
            "metadata": {"referenceSystem": "urn:ogc:def:crs:EPSG::7415"},
            "transform": {"scale": [0.001, 0.001, 0.001], "translate": [85000.0, 446000.0, 0.0]},
            "CityObjects": self.objects,
            "vertices": self.vertices,
        });
        serde_json::to_vec(&doc).unwrap_or_default()
    }
}

/// The LoD2 test city: each case with its id, spread over a few hundred metres so that the
/// frame's origin (the centre of the extent) lies far from most buildings.
pub fn lod2_city() -> CityJson {
    let mut c = CityJson::default();
    c.building(
        "box",
        &Plan::new(-300.0, -200.0, 10.0, 8.0, 9.0).flat_box(),
        true,
    );
    c.building(
        "gable",
        &Plan::new(200.0, 150.0, 10.0, 8.0, 6.0).gabled_house(10.0),
        false,
    );
    c.building(
        "hip",
        &Plan::new(-250.0, 180.0, 14.0, 8.0, 6.0).hipped_house(9.5),
        false,
    );
    for (row, party, y) in [
        ("terrace-both", PartyWalls::Both, -100.0),
        ("terrace-once", PartyWalls::Once, -60.0),
        ("terrace-none", PartyWalls::None, -20.0),
    ] {
        for (k, house) in terrace(100.0, y, 4, 6.0, party).iter().enumerate() {
            c.building(&format!("{row}-{k}"), house, false);
        }
    }
    // Wound inconsistently: one roof plane, one gable end and the ground clockwise.
    let mut mixed = Plan::new(280.0, -150.0, 10.0, 8.0, 6.0).gabled_house(10.0);
    for i in [0, 3, 5] {
        mixed[i] = flipped(mixed[i].clone());
    }
    c.building("mixed-orientation", &mixed, false);
    // The same house wound clockwise throughout, as a Solid.
    let inverted: Vec<Surface> = Plan::new(-150.0, -190.0, 10.0, 8.0, 6.0)
        .gabled_house(10.0)
        .into_iter()
        .map(flipped)
        .collect();
    c.building("inside-out", &inverted, true);
    // Open shells: a gabled house without its east gable end, one without its ground.
    let mut open_end = Plan::new(300.0, 100.0, 10.0, 8.0, 6.0).gabled_house(10.0);
    open_end.remove(3);
    c.building("open-gable-end", &open_end, false);
    let mut open_ground = Plan::new(-300.0, 50.0, 10.0, 8.0, 6.0).gabled_house(10.0);
    open_ground.remove(0);
    c.building("open-ground", &open_ground, false);
    c
}
