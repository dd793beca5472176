//! The street network: a warped, jittered lattice of intersections with major, minor and
//! residential streets, diagonal avenues, and the blocks between them.
//!
//! The lattice has columns `i` and rows `j`; node `(i, j)` is placed by
//! 1. per-column and per-row offsets (blocks of different lengths, straight streets),
//! 2. a small per-node jitter (streets bend a little at each crossing),
//! 3. a smooth displacement field, a sum of three long sine waves (streets curve over
//!    kilometres: curved avenues),
//! 4. a rotation that grows with the distance from the centre (outer districts are turned
//!    against the centre's grid, up to about 30° at 15 km).
//!
//! Every deformation has a gradient well below one, so the lattice stays a planar, convex
//! quadrilateral mesh; [`Layout::blocks`] checks convexity anyway and drops a block that is not.
//! Diagonal avenues follow lattice diagonals, through nodes, so they meet the other streets at
//! nodes and split the quads they cross into two triangles.

use std::collections::{BTreeMap, BTreeSet};

use geo::{Coord, LineString};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::polygon::{ConvexPoly, EdgeTag, cross, dot, length, perp, snap};
use crate::city::{Street, StreetClass};

/// Width between building lines of a street of each class (metres), carriageway and pavements.
/// Values chosen to match common urban cross-sections (two-lane residential street with
/// pavements ≈ 14 m, four-lane avenue with pavements ≈ 30 m).
pub fn street_width_m(class: StreetClass) -> f64 {
    match class {
        StreetClass::Major => 30.0,
        StreetClass::Minor => 20.0,
        StreetClass::Residential => 14.0,
        StreetClass::Service => 8.0,
        StreetClass::Pedestrian => 6.0,
        StreetClass::Other => 10.0,
    }
}

/// Extra distance between a street's corridor and any building (metres).
pub(crate) const CORRIDOR_MARGIN_M: f64 = 0.5;

/// SplitMix64 finaliser: a well-mixed 64-bit hash.
pub(crate) fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Hash of a seed, a salt and two lattice indices.
pub(crate) fn hash(seed: u64, salt: u64, a: i64, b: i64) -> u64 {
    mix(
        mix(mix(seed ^ salt.wrapping_mul(0xD6E8_FEB8_6659_FD93)) ^ a as u64)
            ^ (b as u64).rotate_left(32),
    )
}

/// A hash as a number in `[0, 1)`.
pub(crate) fn unit(h: u64) -> f64 {
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

const SALT_COLUMN: u64 = 1;
const SALT_ROW: u64 = 2;
const SALT_NODE_X: u64 = 3;
const SALT_NODE_Y: u64 = 4;
const SALT_CLASS: u64 = 5;

/// How a quad is cut by a diagonal avenue.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Split {
    None,
    /// Along `(i, j) → (i + 1, j + 1)`.
    Rising,
    /// Along `(i + 1, j) → (i, j + 1)`.
    Falling,
}

#[derive(Debug, Clone)]
struct Wave {
    amplitude_m: f64,
    wave: Coord<f64>,
    phase: f64,
    direction: Coord<f64>,
}

/// A lattice node index `(column, row)`.
pub(crate) type Node = (i64, i64);

/// The street lattice of one city.
#[derive(Debug, Clone)]
pub(crate) struct Layout {
    seed: u64,
    /// Mean column spacing (metres).
    column_m: f64,
    /// Mean row spacing (metres).
    row_m: f64,
    rotation: f64,
    swirl: f64,
    swirl_length_m: f64,
    waves: Vec<Wave>,
    major_column: i64,
    major_row: i64,
    /// Rising diagonal through the nodes with `i - j = a`.
    rising: Option<i64>,
    /// Falling diagonal through the nodes with `i + j = b`.
    falling: Option<i64>,
}

impl Layout {
    /// Draws a layout. `diagonals` is how many diagonal avenues to lay (0, 1 or 2).
    pub fn new(rng: &mut ChaCha8Rng, seed: u64, block_m: f64, diagonals: usize) -> Layout {
        let aspect = rng.random_range(1.2..1.9);
        let waves = (0..3)
            .map(|_| {
                let wavelength_m = rng.random_range(2_500.0..9_000.0);
                let angle: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                let turn: f64 = rng.random_range(0.0..std::f64::consts::TAU);
                let k = std::f64::consts::TAU / wavelength_m;
                // Gradient amplitude·k ≤ 0.08 per wave.
                let amplitude_m = rng.random_range(0.03..0.08) / k;
                Wave {
                    amplitude_m,
                    wave: Coord {
                        x: angle.cos() * k,
                        y: angle.sin() * k,
                    },
                    phase: rng.random_range(0.0..std::f64::consts::TAU),
                    direction: Coord {
                        x: turn.cos(),
                        y: turn.sin(),
                    },
                }
            })
            .collect();
        let rotation = rng.random_range(0.0..std::f64::consts::PI);
        let swirl = rng.random_range(0.08..0.2) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        let swirl_length_m = rng.random_range(1_000.0..3_000.0);
        let major_column = rng.random_range(0..8);
        let major_row = rng.random_range(0..6);
        // The two diagonals cross at a node when a + b is even, so no quad is cut twice.
        let a = rng.random_range(-2..=2i64);
        let b = a + 2 * rng.random_range(-1..=1i64);
        Layout {
            seed,
            column_m: block_m,
            row_m: block_m * aspect,
            rotation,
            swirl,
            swirl_length_m,
            waves,
            major_column,
            major_row,
            rising: (diagonals >= 1).then_some(a),
            falling: (diagonals >= 2).then_some(b),
        }
    }

    /// Mean column and row spacing (metres).
    pub fn spacing_m(&self) -> (f64, f64) {
        (self.column_m, self.row_m)
    }

    /// Position of node `(i, j)` in the local frame (metres).
    pub fn node(&self, (i, j): Node) -> Coord<f64> {
        let s = self.seed;
        let column_jitter = unit(hash(s, SALT_COLUMN, i, 0)) - 0.5;
        let row_jitter = unit(hash(s, SALT_ROW, j, 0)) - 0.5;
        let node_x = unit(hash(s, SALT_NODE_X, i, j)) - 0.5;
        let node_y = unit(hash(s, SALT_NODE_Y, i, j)) - 0.5;
        // Spacing between neighbouring columns ranges over (1 ± 0.36) · mean.
        let q = Coord {
            x: (i as f64 + 0.36 * column_jitter + 0.12 * node_x) * self.column_m,
            y: (j as f64 + 0.36 * row_jitter + 0.12 * node_y * self.column_m / self.row_m)
                * self.row_m,
        };
        let mut p = q;
        for w in &self.waves {
            p = p + w.direction * (w.amplitude_m * (dot(w.wave, q) + w.phase).sin());
        }
        let r = length(p);
        let angle = self.rotation + self.swirl * (1.0 + r / self.swirl_length_m).ln();
        let (sa, ca) = angle.sin_cos();
        Coord {
            x: ca * p.x - sa * p.y,
            y: sa * p.x + ca * p.y,
        }
    }

    /// Class of the street along column `i`.
    pub fn column_class(&self, i: i64) -> StreetClass {
        match (i - self.major_column).rem_euclid(8) {
            0 => StreetClass::Major,
            4 => StreetClass::Minor,
            _ if unit(hash(self.seed, SALT_CLASS, i, 0)) < 0.12 => StreetClass::Minor,
            _ => StreetClass::Residential,
        }
    }

    /// Class of the street along row `j`.
    pub fn row_class(&self, j: i64) -> StreetClass {
        match (j - self.major_row).rem_euclid(6) {
            0 => StreetClass::Major,
            3 => StreetClass::Minor,
            _ if unit(hash(self.seed, SALT_CLASS, 0, j)) < 0.12 => StreetClass::Minor,
            _ => StreetClass::Residential,
        }
    }

    fn split(&self, (i, j): Node) -> Split {
        if self.rising == Some(i - j) {
            Split::Rising
        } else if self.falling == Some(i + j + 1) {
            Split::Falling
        } else {
            Split::None
        }
    }

    /// The street segments at node `n`: the neighbouring node and the class.
    fn incident(&self, (i, j): Node) -> impl Iterator<Item = (Node, StreetClass)> + '_ {
        let grid = [
            ((i + 1, j), self.row_class(j)),
            ((i - 1, j), self.row_class(j)),
            ((i, j + 1), self.column_class(i)),
            ((i, j - 1), self.column_class(i)),
        ];
        let rising = (self.rising == Some(i - j)).then_some([
            ((i + 1, j + 1), StreetClass::Major),
            ((i - 1, j - 1), StreetClass::Major),
        ]);
        let falling = (self.falling == Some(i + j)).then_some([
            ((i + 1, j - 1), StreetClass::Major),
            ((i - 1, j + 1), StreetClass::Major),
        ]);
        grid.into_iter()
            .chain(rising.into_iter().flatten())
            .chain(falling.into_iter().flatten())
    }

    /// The buildable areas of quad `(i, j)` (between nodes `(i, j)` and `(i + 1, j + 1)`):
    /// one, or two where a diagonal avenue cuts it, each kept clear of every street corridor
    /// (half the street's width plus [`CORRIDOR_MARGIN_M`]). Edges facing streets are tagged
    /// [`EdgeTag::Frontage`].
    pub fn blocks(&self, (i, j): Node) -> Vec<ConvexPoly> {
        let n00 = (i, j);
        let n10 = (i + 1, j);
        let n11 = (i + 1, j + 1);
        let n01 = (i, j + 1);
        let faces: Vec<Vec<Node>> = match self.split((i, j)) {
            Split::None => vec![vec![n00, n10, n11, n01]],
            Split::Rising => vec![vec![n00, n10, n11], vec![n00, n11, n01]],
            Split::Falling => vec![vec![n00, n10, n01], vec![n10, n11, n01]],
        };
        faces.iter().filter_map(|face| self.block(face)).collect()
    }

    fn block(&self, face: &[Node]) -> Option<ConvexPoly> {
        let corners: Vec<Coord<f64>> = face.iter().map(|n| self.node(*n)).collect();
        let mut poly = ConvexPoly::from_corners(corners.clone(), EdgeTag::Frontage)?;
        let centre = poly.centre();
        let count = face.len();
        for (k, node) in face.iter().enumerate() {
            let prev = face[(k + count - 1) % count];
            let next = face[(k + 1) % count];
            let at = corners[k];
            let to_prev = corners[(k + count - 1) % count] - at;
            let to_next = corners[(k + 1) % count] - at;
            for (other, class) in self.incident(*node) {
                let dir = self.node(other) - at;
                let len = length(dir);
                if len <= 0.0 {
                    continue;
                }
                let own = other == next || other == prev;
                // A street of another face reaches this block's corner only if it leaves the
                // node within 90° of one of the block's edges.
                let near = dot(dir, to_prev) > 0.0 || dot(dir, to_next) > 0.0;
                if !(own || near) {
                    continue;
                }
                if !own && (cross(to_next, dir) > 0.0 && cross(dir, to_prev) > 0.0) {
                    // Inside the block's corner: impossible on a planar lattice.
                    return None;
                }
                let mut normal = perp(dir) / len;
                if dot(normal, centre - at) < 0.0 {
                    normal = normal * -1.0;
                }
                let clear = street_width_m(class) / 2.0 + CORRIDOR_MARGIN_M;
                poly = poly.clip(normal, dot(normal, at) + clear, EdgeTag::Frontage)?;
            }
        }
        Some(poly)
    }

    /// The streets bordering the given quads, as polylines through lattice nodes: runs of
    /// consecutive used segments along each column, row and diagonal.
    pub fn streets(&self, quads: &[Node]) -> Vec<Street> {
        let mut columns: BTreeMap<i64, BTreeSet<i64>> = BTreeMap::new();
        let mut rows: BTreeMap<i64, BTreeSet<i64>> = BTreeMap::new();
        let mut rising: BTreeSet<i64> = BTreeSet::new();
        let mut falling: BTreeSet<i64> = BTreeSet::new();
        for &(i, j) in quads {
            columns.entry(i).or_default().insert(j);
            columns.entry(i + 1).or_default().insert(j);
            rows.entry(j).or_default().insert(i);
            rows.entry(j + 1).or_default().insert(i);
            match self.split((i, j)) {
                Split::Rising => {
                    rising.insert(i);
                }
                Split::Falling => {
                    falling.insert(i);
                }
                Split::None => {}
            }
        }
        let first_column = columns.keys().next().copied().unwrap_or(0);
        let first_row = rows.keys().next().copied().unwrap_or(0);
        let mut streets = Vec::new();
        let mut push = |class: StreetClass, name: String, nodes: Vec<Node>| {
            let line = LineString::new(nodes.iter().map(|n| snap(self.node(*n))).collect());
            streets.push(Street {
                source_id: format!("s{}", streets.len()),
                class,
                name: Some(name),
                line,
                tagged_width_m: Some(street_width_m(class) as f32),
            });
        };
        for (&i, js) in &columns {
            let class = self.column_class(i);
            let name = format!("{} Avenue", ordinal(i - first_column + 1));
            for (lo, hi) in runs(js) {
                push(class, name.clone(), (lo..=hi + 1).map(|j| (i, j)).collect());
            }
        }
        for (&j, is) in &rows {
            let class = self.row_class(j);
            let name = row_name(j - first_row);
            for (lo, hi) in runs(is) {
                push(class, name.clone(), (lo..=hi + 1).map(|i| (i, j)).collect());
            }
        }
        if let Some(a) = self.rising {
            for (lo, hi) in runs(&rising) {
                push(
                    StreetClass::Major,
                    "Broadway".into(),
                    (lo..=hi + 1).map(|i| (i, i - a)).collect(),
                );
            }
        }
        if let Some(b) = self.falling {
            for (lo, hi) in runs(&falling) {
                push(
                    StreetClass::Major,
                    "Diagonal Avenue".into(),
                    (lo..=hi + 1).map(|i| (i, b - i)).collect(),
                );
            }
        }
        streets
    }
}

/// Maximal runs of consecutive integers `(first, last)`.
fn runs(set: &BTreeSet<i64>) -> Vec<(i64, i64)> {
    let mut out: Vec<(i64, i64)> = Vec::new();
    for &v in set {
        match out.last_mut() {
            Some((_, hi)) if *hi + 1 == v => *hi = v,
            _ => out.push((v, v)),
        }
    }
    out
}

fn ordinal(n: i64) -> String {
    let suffix = match (n % 10, n % 100) {
        (_, 11..=13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    };
    format!("{n}{suffix}")
}

fn row_name(k: i64) -> String {
    const STEMS: [&str; 24] = [
        "Harbour", "Market", "Mill", "Church", "King", "Queen", "River", "Park", "Lake", "Hill",
        "Station", "Union", "Bridge", "Castle", "Garden", "Orchard", "Chapel", "Forge", "Meadow",
        "Quarry", "Spring", "Tower", "Wharf", "Elm",
    ];
    let stem = STEMS[(k.rem_euclid(STEMS.len() as i64)) as usize];
    let round = k.div_euclid(STEMS.len() as i64);
    if round == 0 {
        format!("{stem} Street")
    } else {
        format!("{stem} Street {}", round + 1)
    }
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;

    use super::*;

    fn layout(seed: u64) -> Layout {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        Layout::new(&mut rng, seed, 100.0, 2)
    }

    #[test]
    fn quads_are_convex_and_counter_clockwise_far_out() {
        let l = layout(7);
        for i in (-150..150).step_by(7) {
            for j in (-100..100).step_by(5) {
                let c = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)].map(|n| l.node(n));
                assert!(
                    ConvexPoly::from_corners(c.to_vec(), EdgeTag::Frontage).is_some(),
                    "quad ({i}, {j}) is not convex: {c:?}"
                );
            }
        }
    }

    #[test]
    fn blocks_stay_clear_of_their_streets() {
        let l = layout(3);
        let mut blocks = 0;
        for i in -6..6 {
            for j in -6..6 {
                for b in l.blocks((i, j)) {
                    blocks += 1;
                    let corners = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)];
                    for k in 0..4 {
                        let (a, bn) = (corners[k], corners[(k + 1) % 4]);
                        let class = if k % 2 == 0 {
                            l.row_class(a.1)
                        } else {
                            l.column_class(a.0)
                        };
                        let (pa, pb) = (l.node(a), l.node(bn));
                        let normal = perp(pb - pa) / length(pb - pa);
                        for p in &b.pts {
                            let d = dot(normal, *p - pa);
                            assert!(d >= street_width_m(class) / 2.0, "{d}");
                        }
                    }
                }
            }
        }
        assert!(blocks >= 144, "{blocks}");
    }

    #[test]
    fn diagonals_split_quads_and_streets_are_runs() {
        let l = layout(11);
        let quads: Vec<Node> = (-3..3).flat_map(|i| (-3..3).map(move |j| (i, j))).collect();
        let split = quads.iter().filter(|q| l.split(**q) != Split::None).count();
        assert!(split >= 3, "{split}");
        let streets = l.streets(&quads);
        // 7 columns and 7 rows of 6 segments each, plus the two diagonals.
        assert_eq!(streets.len(), 16);
        assert!(streets.iter().take(14).all(|s| s.line.0.len() == 7));
        assert_eq!(
            runs(&BTreeSet::from([1, 2, 3, 5, 7, 8])),
            vec![(1, 3), (5, 5), (7, 8)]
        );
        assert_eq!(ordinal(1), "1st");
        assert_eq!(ordinal(12), "12th");
        assert_eq!(ordinal(23), "23rd");
    }
}
