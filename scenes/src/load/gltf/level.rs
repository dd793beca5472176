//! The up direction of building meshes read without a georeference.
//!
//! A b3dm tile (or its glTF) copied out of its tileset folder loses the tileset's root
//! transform, and with it where "up" is: pg2b3dm, for one, writes content as ECEF offsets from a
//! root translation, so at Amsterdam (latitude 52.4°) the buildings of a lone tile lean 37.6°
//! from the content's z axis, a building 80 m long spans 80 m of z and a whole tile hundreds:
//! every height judged in that frame is wrong, and some are "absurd".
//!
//! Buildings carry their own vertical: walls stand upright, floors and flat roofs lie level, and
//! a city is far thinner along up than across. The content's own z stays up while it aligns
//! (level or upright, within [`ALIGNED_DEG`]) at least half the area the best direction does
//! ([`UPRIGHT_SHARE`]). Otherwise up is, among the directions that align nearly as much as the
//! best (the mean normals of the fullest bins of directions: every flat roof shares one), the
//! one along which the content is thinnest: a street of gable roofs aligns more area about
//! their common ridge than about up, but is hundreds of metres long along it. The choice is
//! refined as the direction the walls are most nearly perpendicular to. A closed box is the
//! same upside down; pitched roofs, which face up, tell up from down, and without them the side
//! nearest +z is up.
//!
//! A single building written tilted is levelled as well as it can be: its thinnest aligned
//! direction may be a wall's (a tower would lie down); the warning that comes with levelling
//! says so much.

use std::collections::HashMap;

use glam::{DMat3, DMat4, DQuat, DVec3};

/// A face is level or upright when its normal is within this angle of the up direction or of
/// the horizontal plane (degrees): walls of real buildings are not exactly upright, and an
/// ECEF tile's floors lean by the earth's curvature across it (0.02° over 2 km).
const ALIGNED_DEG: f64 = 2.0;

/// The content counts as upright, and is left as it is, when its up direction is within this
/// angle of its z axis (degrees).
pub(super) const UPRIGHT_DEG: f64 = 1.0;

/// Candidate directions tried: the mean normals of this many of the fullest direction bins.
const CANDIDATES: usize = 64;

/// The width of a direction bin (degrees of latitude and longitude on the sphere of normals).
const BIN_DEG: f64 = 2.0;

/// At most this many triangles are scored per candidate (evenly spaced through the content), so
/// that a large lone file costs well under a second.
const SCORED: usize = 50_000;

/// Content stays as written (z up) while its z axis aligns at least this share of what the
/// best direction aligns: an upright gable-roofed house aligns less about z than about its
/// ridge, but not half as much; a tile written in ECEF axes aligns a third or less.
const UPRIGHT_SHARE: f64 = 0.5;

/// Directions aligning within this share of the best are weighed by thickness.
const GOOD_MARGIN: f64 = 0.15;

/// Below this share of its area level or upright about any direction, content has no walls
/// and floors to level by (terrain, a sculpture) and is left as it is.
const MIN_ALIGNED_SHARE: f64 = 0.5;

/// The slanted faces decide which way is up when the sum of their area along it is over this
/// share of the whole area (otherwise the side nearest +z is up).
const SLANTED_SIGN: f64 = 0.01;

/// How content was found to stand.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Uprightness {
    /// The up direction, in content z-up coordinates (unit length).
    pub up: DVec3,
    /// Its angle from the content's z axis (degrees).
    pub tilt_deg: f64,
    /// Share of the triangle area level or upright about `up`.
    pub aligned_share: f64,
}

impl Uprightness {
    /// The rotation that stands the content upright: `up` to +z, the shortest way.
    pub fn levelling(&self) -> DMat4 {
        DMat4::from_quat(DQuat::from_rotation_arc(self.up, DVec3::Z))
    }

    /// Whether the content leans enough to be levelled.
    pub fn leans(&self) -> bool {
        self.tilt_deg > UPRIGHT_DEG
    }
}

/// One triangle's unit normal and area.
#[derive(Debug, Clone, Copy)]
struct Face {
    normal: DVec3,
    area: f64,
}

/// The face of a triangle; `None` for a degenerate or non-finite one.
fn face([a, b, c]: &[DVec3; 3]) -> Option<Face> {
    let cross = (*b - *a).cross(*c - *a);
    let twice = cross.length();
    (twice.is_finite() && twice > 1e-12).then(|| Face {
        normal: cross / twice,
        area: twice * 0.5,
    })
}

/// `n` or `-n`, whichever lies in the upper half of the sphere (a normal and its opposite are
/// one direction here).
fn upper(n: DVec3) -> DVec3 {
    if (n.z, n.y, n.x) < (0.0, 0.0, 0.0) {
        -n
    } else {
        n
    }
}

/// Where `triangles` (content z-up coordinates) find up; `None` when they have no area or too
/// little of it is level or upright about any direction ([`MIN_ALIGNED_SHARE`]).
pub(super) fn uprightness<'a>(
    triangles: impl Iterator<Item = &'a [DVec3; 3]>,
) -> Option<Uprightness> {
    let triangles: Vec<&[DVec3; 3]> = triangles.collect();
    let faces: Vec<Face> = triangles.iter().copied().filter_map(face).collect();
    let level_cos = ALIGNED_DEG.to_radians().cos();
    let upright_sin = ALIGNED_DEG.to_radians().sin();
    let step = faces.len().div_ceil(SCORED).max(1);
    let scored: Vec<Face> = faces.iter().step_by(step).copied().collect();
    let scored_total: f64 = scored.iter().map(|f| f.area).sum();
    if !(scored_total.is_finite() && scored_total > 0.0) {
        return None;
    }
    let share = |up: DVec3| {
        let aligned: f64 = (scored.iter())
            .filter(|f| {
                let d = f.normal.dot(up).abs();
                d >= level_cos || d <= upright_sin
            })
            .map(|f| f.area)
            .sum();
        aligned / scored_total
    };
    let scores: Vec<(DVec3, f64)> = (candidates(&faces).into_iter())
        .map(|c| (c, share(c)))
        .collect();
    let as_written = share(DVec3::Z);
    let best = scores.iter().map(|s| s.1).fold(as_written, f64::max);
    if best < MIN_ALIGNED_SHARE {
        return None;
    }
    if as_written >= UPRIGHT_SHARE * best {
        return Some(Uprightness {
            up: DVec3::Z,
            tilt_deg: 0.0,
            aligned_share: as_written,
        });
    }
    // A city is far thinner along up than across it: among the directions nearly as well
    // aligned as the best, the one along which the content is thinnest. (A pitched roof's
    // ridge, shared by a street of houses, can align more area than up does.)
    let corners: Vec<DVec3> = (triangles.iter().step_by(step))
        .flat_map(|t| t.iter().copied())
        .filter(|p| p.is_finite())
        .collect();
    let thickness = |c: DVec3| {
        let mut along: Vec<f64> = corners.iter().map(|p| p.dot(c)).collect();
        if along.is_empty() {
            return 0.0;
        }
        let (lo, hi) = (along.len() / 100, along.len() - 1 - along.len() / 100);
        let top = *along.select_nth_unstable_by(hi, f64::total_cmp).1;
        let bottom = *along.select_nth_unstable_by(lo, f64::total_cmp).1;
        top - bottom
    };
    let (candidate, _) = (scores.into_iter())
        .filter(|s| s.1 >= best - GOOD_MARGIN)
        .map(|(c, _)| (c, thickness(c)))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    // Refined by the walls about the candidate: the direction they are all most nearly
    // perpendicular to, the least eigenvector of their area-weighted normal scatter (extruded
    // and LoD2 walls stand exactly upright, where a flat roof may slope by a degree). Without
    // walls in two directions, the mean normal of the level faces.
    let mut walls = DMat3::ZERO;
    let mut level = DVec3::ZERO;
    for f in &faces {
        let d = f.normal.dot(candidate);
        if d.abs() <= upright_sin {
            walls += DMat3::from_cols(
                f.normal * f.normal.x,
                f.normal * f.normal.y,
                f.normal * f.normal.z,
            ) * f.area;
        } else if d.abs() >= level_cos {
            level += f.normal * f.area * d.signum();
        }
    }
    let refined = least_eigenvector(walls)
        .filter(|u| u.dot(candidate).abs() >= level_cos)
        .or_else(|| level.try_normalize())
        .unwrap_or(candidate);
    let mut up = upper(refined);
    // A closed box looks the same upside down; pitched roofs do not: the slanted faces of
    // buildings are roofs, and face up.
    let slanted: f64 = (faces.iter())
        .map(|f| (f.normal.dot(up), f.area))
        .filter(|(d, _)| d.abs() > upright_sin && d.abs() < level_cos)
        .map(|(d, area)| d * area)
        .sum();
    if slanted < -SLANTED_SIGN * scored_total * step as f64 {
        up = -up;
    }
    Some(Uprightness {
        up,
        tilt_deg: up.z.clamp(-1.0, 1.0).acos().to_degrees(),
        aligned_share: share(up),
    })
}

/// The unit eigenvector of the least eigenvalue of the symmetric `m`; `None` when that
/// eigenvalue is not single (the walls face one way only, or none). Eigenvalues in closed
/// form (Smith 1961, "Eigenvalues of a symmetric 3 × 3 matrix"); the eigenvector is the largest
/// cross product of two rows of `m - λI`, whose rows span the plane perpendicular to it.
fn least_eigenvector(m: DMat3) -> Option<DVec3> {
    let [a, b, c] = [m.x_axis, m.y_axis, m.z_axis];
    let off = a.y * a.y + a.z * a.z + b.z * b.z;
    let q = (a.x + b.y + c.z) / 3.0;
    let spread = (a.x - q).powi(2) + (b.y - q).powi(2) + (c.z - q).powi(2) + 2.0 * off;
    let p = (spread / 6.0).sqrt();
    if !(p.is_finite() && p > 0.0) {
        return None;
    }
    let shifted = (m - DMat3::from_diagonal(DVec3::splat(q))) * (1.0 / p);
    let r = (shifted.determinant() / 2.0).clamp(-1.0, 1.0);
    let least = q + 2.0 * p * (r.acos() / 3.0 + 2.0 * std::f64::consts::FRAC_PI_3).cos();
    let rows = m - DMat3::from_diagonal(DVec3::splat(least));
    let [r0, r1, r2] = [rows.row(0), rows.row(1), rows.row(2)];
    let crosses = [r0.cross(r1), r0.cross(r2), r1.cross(r2)];
    let largest = crosses
        .into_iter()
        .max_by(|x, y| x.length_squared().total_cmp(&y.length_squared()))?;
    // A second eigenvalue as small leaves the rows parallel: no single direction.
    (largest.length_squared() > 1e-12 * p.powi(4)).then(|| largest.normalize())
}

/// The area-weighted mean normals of the [`CANDIDATES`] direction bins holding the most area:
/// the floors and flat roofs of every building fall in one, while walls spread over many.
fn candidates(faces: &[Face]) -> Vec<DVec3> {
    let mut bins: HashMap<(i32, i32), (DVec3, f64)> = HashMap::new();
    for f in faces {
        let n = upper(f.normal);
        let lat = n.z.clamp(-1.0, 1.0).asin().to_degrees();
        let lon = n.y.atan2(n.x).to_degrees();
        let key = (
            (lat / BIN_DEG).floor() as i32,
            (lon / BIN_DEG).floor() as i32,
        );
        let bin = bins.entry(key).or_insert((DVec3::ZERO, 0.0));
        bin.0 += n * f.area;
        bin.1 += f.area;
    }
    let mut bins: Vec<(DVec3, f64)> = bins.into_values().collect();
    bins.sort_by(|a, b| b.1.total_cmp(&a.1));
    (bins.into_iter().take(CANDIDATES))
        .filter_map(|(sum, _)| sum.try_normalize())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 12 triangles of an axis-aligned box `lo..hi`, wound outward.
    fn cuboid(lo: DVec3, hi: DVec3) -> Vec<[DVec3; 3]> {
        let c = |i: u8| {
            DVec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        };
        // Quads as corner bit patterns, counter-clockwise seen from outside.
        let quads = [
            [0, 2, 3, 1], // bottom (-z)
            [4, 5, 7, 6], // top (+z)
            [0, 1, 5, 4], // -y
            [2, 6, 7, 3], // +y
            [0, 4, 6, 2], // -x
            [1, 3, 7, 5], // +x
        ];
        quads
            .iter()
            .flat_map(|q| [[c(q[0]), c(q[1]), c(q[2])], [c(q[0]), c(q[2]), c(q[3])]])
            .collect()
    }

    /// A small town of boxes turned about z by different angles, so no two share walls.
    fn town() -> Vec<[DVec3; 3]> {
        let mut out = Vec::new();
        for (i, angle_deg) in [0.0f64, 17.0, 33.0, 58.0, 71.0].into_iter().enumerate() {
            let turn = DMat4::from_rotation_z(angle_deg.to_radians())
                * DMat4::from_translation(DVec3::new(40.0 * i as f64, 0.0, 0.0));
            let height = 8.0 + 3.0 * i as f64;
            let mut house = cuboid(DVec3::ZERO, DVec3::new(12.0, 9.0, height));
            // A pyramid roof on the first house: four faces sloping up to its apex.
            if i == 0 {
                let apex = DVec3::new(6.0, 4.5, height + 3.0);
                let eaves = [(0.0, 0.0), (12.0, 0.0), (12.0, 9.0), (0.0, 9.0)]
                    .map(|(x, y)| DVec3::new(x, y, height));
                for k in 0..4 {
                    house.push([eaves[k], eaves[(k + 1) % 4], apex]);
                }
            }
            for t in house {
                out.push(t.map(|p| turn.transform_point3(p)));
            }
        }
        out
    }

    #[test]
    fn an_upright_town_is_found_upright() {
        let town = town();
        let found = uprightness(town.iter()).expect("walls and roofs");
        assert!(found.tilt_deg < 1e-6, "{found:?}");
        assert!(!found.leans());
        assert!(found.aligned_share > 0.95, "{found:?}");
    }

    /// A town tilted as an Amsterdam tile in ECEF axes is: its up is found (the tilt's image of
    /// z), and levelling gives every face back its slope.
    #[test]
    fn a_tilted_town_is_levelled() {
        let tilt = DMat4::from_rotation_x(37.6f64.to_radians())
            * DMat4::from_rotation_z(0.3)
            * DMat4::from_translation(DVec3::new(0.0, 0.0, 1100.0));
        let tilted: Vec<[DVec3; 3]> = town()
            .into_iter()
            .map(|t| t.map(|p| tilt.transform_point3(p)))
            .collect();
        let found = uprightness(tilted.iter()).expect("walls and roofs");
        let true_up = tilt.transform_vector3(DVec3::Z);
        assert!(found.up.dot(true_up) > 1.0 - 1e-9, "{found:?} vs {true_up}");
        assert!((found.tilt_deg - 37.6).abs() < 1e-6, "{found:?}");
        assert!(found.leans());
        // Levelled, every face leans as it did before the tilt (the pitched roof included).
        let level = found.levelling();
        for (t, original) in tilted.iter().zip(town()) {
            let n = face(&t.map(|p| level.transform_point3(p))).unwrap().normal;
            let before = face(&original).unwrap().normal;
            assert!((n.z - before.z).abs() < 1e-9, "{n} vs {before}");
        }
    }

    /// Tilted past the horizontal (up leaning 142.4° from z): the pitched roof, which faces up,
    /// tells up from down. Upright content is left as written, and so is a box alone.
    #[test]
    fn pitched_roofs_tell_up_from_down() {
        let tilt = DMat4::from_rotation_x(142.4f64.to_radians());
        let tilted: Vec<[DVec3; 3]> = town()
            .into_iter()
            .map(|t| t.map(|p| tilt.transform_point3(p)))
            .collect();
        let found = uprightness(tilted.iter()).unwrap();
        let true_up = tilt.transform_vector3(DVec3::Z);
        assert!(found.up.dot(true_up) > 1.0 - 1e-9, "{found:?} vs {true_up}");
        let alone = cuboid(DVec3::ZERO, DVec3::new(3.0, 3.0, 7.0));
        assert_eq!(uprightness(alone.iter()).unwrap().up, DVec3::Z);
    }

    /// The least eigenvector of a diagonal matrix, of the same turned, and none where the least
    /// eigenvalue is double (walls facing one way) or the matrix is zero.
    #[test]
    fn least_eigenvector_of_known_matrices() {
        let d = DMat3::from_diagonal(DVec3::new(3.0, 1.0, 2.0));
        assert!(least_eigenvector(d).unwrap().dot(DVec3::Y).abs() > 1.0 - 1e-12);
        let turn = DMat3::from_quat(DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 0.7));
        let turned = turn * d * turn.transpose();
        let v = least_eigenvector(turned).unwrap();
        assert!(v.dot(turn * DVec3::Y).abs() > 1.0 - 1e-12, "{v}");
        let one_way = DMat3::from_diagonal(DVec3::new(5.0, 0.0, 0.0));
        assert_eq!(least_eigenvector(one_way), None);
        assert_eq!(least_eigenvector(DMat3::ZERO), None);
    }

    /// Nothing level or upright (a fan of slanted faces), no area, non-finite corners: no
    /// direction, no panic.
    #[test]
    fn shapeless_content_is_left_alone() {
        let fan: Vec<[DVec3; 3]> = (0..36)
            .map(|i| {
                let a = f64::from(i) * 10f64.to_radians();
                let b = a + 10f64.to_radians();
                [
                    DVec3::new(0.0, 0.0, 5.0),
                    DVec3::new(a.cos(), a.sin(), 0.0) * 10.0,
                    DVec3::new(b.cos(), b.sin(), 0.0) * 10.0 + DVec3::Z * f64::from(i % 7),
                ]
            })
            .collect();
        assert_eq!(uprightness(fan.iter()), None);
        assert_eq!(uprightness([].iter()), None);
        let nan = [[DVec3::NAN, DVec3::ZERO, DVec3::X]];
        assert_eq!(uprightness(nan.iter()), None);
    }
}
