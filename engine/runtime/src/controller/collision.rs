//! What a walking viewer collides with: the walls of building footprints, in 2D.
//!
//! Every ring edge of every building part that stands on the ground becomes a [`Wall`]. The
//! walls are stored in `f32` (millimetres at 30 km from the origin), a part's in runs of up to
//! [`WALLS_PER_GROUP`], and the runs' boxes go into an R-tree (`rstar`): at a million buildings
//! an R-tree of the 4.8 M walls themselves in `f64` took about 300 MB, as much as the viewer was
//! over its 3 GB. The walker is a vertical cylinder of radius `radius_m`; moving it pushes its
//! centre out of every wall closer than the radius, which slides it along walls, and the move is
//! sub-stepped so that no step is longer than half the radius (no tunnelling at any speed).
//!
//! Parts whose base is well above their building's base (bridges, overhangs, upper
//! `building:part`s) do not block: one can walk under them. The ground under the walker is the
//! lowest building base nearby ([`CollisionWorld::ground_z_m`]); 2.5D scenes stand at z = 0.

use citywalk_scenes::City;
use geo::MultiPolygon;
use glam::DVec2;
use rstar::{AABB, RTree, RTreeObject};

/// A part whose base is this far or more above its building's base does not block walking
/// (metres): a 2 m door height fits under it.
pub const HEADROOM_M: f32 = 2.0;

/// Longest sub-step of a collision move, as a fraction of the walker's radius. A step shorter
/// than the radius cannot carry the centre across a wall before the push-out sees it.
const MAX_STEP_FRACTION: f64 = 0.5;

/// Push-out iterations per sub-step; corners need two, acute corners a few more.
const PUSH_ITERATIONS: usize = 8;

/// One footprint edge that blocks walking.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wall {
    pub a: DVec2,
    pub b: DVec2,
    /// Index of the building part (over all buildings, in order) whose ring holds this edge.
    pub part: u32,
    /// Base of the building the part belongs to (metres).
    pub building_base_m: f32,
}

impl Wall {
    /// The point of the wall closest to `p`.
    pub fn closest_point(&self, p: DVec2) -> DVec2 {
        let ab = self.b - self.a;
        let len2 = ab.length_squared();
        if len2 <= 0.0 {
            return self.a;
        }
        let t = ((p - self.a).dot(ab) / len2).clamp(0.0, 1.0);
        self.a + ab * t
    }
}

/// Walls in one R-tree entry at most: a footprint's edges are few, and a long run of them
/// (a block-long facade) is split so that a query near one end does not test the other.
const WALLS_PER_GROUP: usize = 16;

/// More than the rounding of a query point to `f32` anywhere within 100 km of the origin.
const QUERY_SLACK_M: f64 = 0.01;

/// A wall's ends as stored.
#[derive(Debug, Clone, Copy, PartialEq)]
struct StoredWall {
    a: [f32; 2],
    b: [f32; 2],
}

/// Consecutive walls of one part: the R-tree's entry.
#[derive(Debug, Clone, Copy, PartialEq)]
struct WallGroup {
    envelope: AABB<[f32; 2]>,
    /// Its walls: `count` of [`CollisionWorld::walls`] from `first`.
    first: u32,
    count: u32,
    part: u32,
    building_base_m: f32,
}

impl WallGroup {
    fn wall(&self, stored: &StoredWall) -> Wall {
        let point = |p: [f32; 2]| DVec2::new(f64::from(p[0]), f64::from(p[1]));
        Wall {
            a: point(stored.a),
            b: point(stored.b),
            part: self.part,
            building_base_m: self.building_base_m,
        }
    }
}

impl RTreeObject for WallGroup {
    type Envelope = AABB<[f32; 2]>;

    fn envelope(&self) -> Self::Envelope {
        self.envelope
    }
}

/// `p` as stored.
fn stored_point(p: DVec2) -> [f32; 2] {
    p.as_vec2().to_array()
}

/// The box from `a` to `b` as the R-tree's envelopes, grown by [`QUERY_SLACK_M`].
fn stored_box(a: DVec2, b: DVec2) -> AABB<[f32; 2]> {
    let slack = DVec2::splat(QUERY_SLACK_M);
    AABB::from_corners(
        stored_point(a.min(b) - slack),
        stored_point(a.max(b) + slack),
    )
}

/// The walls of a city, indexed for circle collision, point-in-footprint tests and ray casts.
#[derive(Debug, Clone)]
pub struct CollisionWorld {
    walls: Vec<StoredWall>,
    groups: RTree<WallGroup>,
    /// Largest x of any wall, for the point-in-footprint ray.
    max_x: f64,
    /// Lowest building base in the world (metres), the ground where no building is near.
    lowest_base_m: f32,
}

impl Default for CollisionWorld {
    fn default() -> Self {
        CollisionWorld::from_walls(Vec::new())
    }
}

impl CollisionWorld {
    /// Collects the walls of every building part of `city` that stands on the ground.
    pub fn from_city(city: &City) -> CollisionWorld {
        let parts = city.buildings.iter().flat_map(|b| {
            b.parts
                .iter()
                .map(move |p| (&p.footprint, p.base_m, b.base_m))
        });
        CollisionWorld::from_parts(parts)
    }

    /// Collects walls from `(footprint, part base, building base)` triples (metres). A part whose
    /// base is [`HEADROOM_M`] or more above its building's base does not block.
    pub fn from_parts<'a>(
        parts: impl IntoIterator<Item = (&'a MultiPolygon<f64>, f32, f32)>,
    ) -> CollisionWorld {
        let mut walls = Vec::new();
        for (index, (footprint, part_base_m, building_base_m)) in parts.into_iter().enumerate() {
            let raise_m = part_base_m - building_base_m;
            if raise_m.is_nan() || raise_m >= HEADROOM_M {
                continue;
            }
            let rings = footprint
                .iter()
                .flat_map(|poly| std::iter::once(poly.exterior()).chain(poly.interiors()));
            for line in rings.flat_map(|ring| ring.lines()) {
                let (a, b) = (
                    DVec2::new(line.start.x, line.start.y),
                    DVec2::new(line.end.x, line.end.y),
                );
                if a != b && a.is_finite() && b.is_finite() {
                    walls.push(Wall {
                        a,
                        b,
                        part: index as u32,
                        building_base_m,
                    });
                }
            }
        }
        CollisionWorld::from_walls(walls)
    }

    /// Indexes the given walls.
    pub fn from_walls(walls: Vec<Wall>) -> CollisionWorld {
        let max_x = walls
            .iter()
            .map(|w| w.a.x.max(w.b.x))
            .fold(f64::NEG_INFINITY, f64::max);
        let lowest_base_m = walls
            .iter()
            .map(|w| w.building_base_m)
            .fold(f32::INFINITY, f32::min);
        let stored: Vec<StoredWall> = walls
            .iter()
            .map(|w| StoredWall {
                a: stored_point(w.a),
                b: stored_point(w.b),
            })
            .collect();
        let mut groups = Vec::new();
        let mut first = 0;
        for run in walls.chunk_by(|x, y| x.part == y.part) {
            for chunk in run.chunks(WALLS_PER_GROUP) {
                let ends = stored[first..first + chunk.len()]
                    .iter()
                    .flat_map(|w| [w.a, w.b]);
                let (lo, hi) = ends.fold(
                    ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]),
                    |(lo, hi), p| {
                        (
                            [lo[0].min(p[0]), lo[1].min(p[1])],
                            [hi[0].max(p[0]), hi[1].max(p[1])],
                        )
                    },
                );
                groups.push(WallGroup {
                    envelope: AABB::from_corners(lo, hi),
                    first: first as u32,
                    count: chunk.len() as u32,
                    part: chunk[0].part,
                    building_base_m: chunk[0].building_base_m,
                });
                first += chunk.len();
            }
        }
        CollisionWorld {
            walls: stored,
            groups: RTree::bulk_load(groups),
            max_x,
            lowest_base_m: if lowest_base_m.is_finite() {
                lowest_base_m
            } else {
                0.0
            },
        }
    }

    /// Number of blocking walls.
    pub fn wall_count(&self) -> usize {
        self.walls.len()
    }

    /// The walls of the groups whose box meets the box from `a` to `b` (a superset of the walls
    /// that meet it).
    fn walls_near(&self, a: DVec2, b: DVec2) -> impl Iterator<Item = Wall> + '_ {
        self.groups
            .locate_in_envelope_intersecting(stored_box(a, b))
            .flat_map(|g| {
                self.walls[g.first as usize..][..g.count as usize]
                    .iter()
                    .map(|w| g.wall(w))
            })
    }

    /// Whether `p` lies inside the footprint of a blocking part (even-odd rule per part, so
    /// holes and overlapping parts are handled).
    pub fn is_inside(&self, p: DVec2) -> bool {
        if p.x.is_nan() || p.x > self.max_x {
            return false;
        }
        let mut crossed: Vec<u32> = self
            .walls_near(p, DVec2::new(self.max_x + 1.0, p.y))
            .filter(|w| {
                (w.a.y > p.y) != (w.b.y > p.y)
                    && w.a.x + (p.y - w.a.y) / (w.b.y - w.a.y) * (w.b.x - w.a.x) > p.x
            })
            .map(|w| w.part)
            .collect();
        crossed.sort_unstable();
        crossed
            .chunk_by(|a, b| a == b)
            .any(|run| run.len() % 2 == 1)
    }

    /// Distance from `p` to the nearest wall, or `None` when there is no wall within `max_m`.
    pub fn clearance_m(&self, p: DVec2, max_m: f64) -> Option<f64> {
        self.walls_within(p, max_m)
            .map(|w| (p - w.closest_point(p)).length())
            .min_by(f64::total_cmp)
    }

    /// The walls within `max_m` of `p`.
    pub fn walls_within(&self, p: DVec2, max_m: f64) -> impl Iterator<Item = Wall> {
        let reach = DVec2::splat(max_m);
        self.walls_near(p - reach, p + reach)
            .filter(move |w| (p - w.closest_point(p)).length_squared() <= max_m * max_m)
    }

    /// Whether a walker of `radius_m` can stand at `p`: outside every footprint and at least the
    /// radius from every wall.
    pub fn is_free(&self, p: DVec2, radius_m: f64) -> bool {
        p.is_finite() && !self.is_inside(p) && self.clearance_m(p, radius_m).is_none()
    }

    /// A free point (see [`CollisionWorld::is_free`]) near `centre`: `centre` itself, or the
    /// first free point on circles `step_m` apart, out to `max_m`.
    pub fn find_free_point(
        &self,
        centre: DVec2,
        radius_m: f64,
        step_m: f64,
        max_m: f64,
    ) -> Option<DVec2> {
        use std::f64::consts::TAU;
        if self.is_free(centre, radius_m) {
            return Some(centre);
        }
        let step_m = step_m.max(0.1);
        let rings = (max_m / step_m).ceil().clamp(0.0, 100_000.0) as usize;
        (1..=rings).find_map(|ring| {
            let r = ring as f64 * step_m;
            let n = ((TAU * r / step_m).ceil() as usize).max(8);
            (0..n)
                .map(|i| centre + DVec2::from_angle(i as f64 * TAU / n as f64) * r)
                .find(|p| self.is_free(*p, radius_m))
        })
    }

    /// Distance along the ray from `origin` in direction `dir` (any length) to the first wall,
    /// or `None` when no wall is hit within `max_m`.
    pub fn ray_distance_m(&self, origin: DVec2, dir: DVec2, max_m: f64) -> Option<f64> {
        let dir = dir.try_normalize()?;
        let end = origin + dir * max_m;
        self.walls_near(origin, end)
            .filter_map(|w| segment_intersection(origin, end, w.a, w.b).map(|(t, _)| t * max_m))
            .min_by(f64::total_cmp)
    }

    /// Height of the ground near `p` (metres): the lowest base of the buildings with a wall
    /// within `search_m`, or the lowest base of the whole world when none is that near.
    pub fn ground_z_m(&self, p: DVec2, search_m: f64) -> f32 {
        self.walls_within(p, search_m)
            .map(|w| w.building_base_m)
            .reduce(f32::min)
            .unwrap_or(self.lowest_base_m)
    }

    /// Moves a walker (a circle of `radius_m`) from `from` by `delta`, sliding along the walls it
    /// meets. The result never lies across a wall from `from`, however long `delta` is.
    pub fn move_circle(&self, from: DVec2, delta: DVec2, radius_m: f64) -> DVec2 {
        let length_m = delta.length();
        if length_m.is_nan()
            || length_m <= 0.0
            || !from.is_finite()
            || !delta.is_finite()
            || radius_m.is_nan()
            || radius_m <= 0.0
        {
            return from;
        }
        let max_step_m = radius_m * MAX_STEP_FRACTION;
        // A cap on the work per call: 100 000 steps of 15 cm is 15 km.
        let steps = (length_m / max_step_m).ceil().clamp(1.0, 100_000.0);
        let step = delta / steps;
        let mut p = from;
        for _ in 0..steps as usize {
            p = self.step_circle(p, step, radius_m);
        }
        p
    }

    /// One sub-step (shorter than the radius): move, push out of the walls, and refuse a result
    /// that crossed a wall or is still stuck in one.
    fn step_circle(&self, p: DVec2, step: DVec2, radius_m: f64) -> DVec2 {
        let mut q = p + step;
        let mut settled = false;
        for _ in 0..PUSH_ITERATIONS {
            let mut pushed = false;
            for wall in self.walls_within(q, radius_m) {
                let c = wall.closest_point(q);
                let away = q - c;
                let dist_m = away.length();
                if dist_m >= radius_m {
                    continue;
                }
                let normal = if dist_m > 1e-9 {
                    away / dist_m
                } else {
                    // The centre is on the wall line: push back to the side it came from.
                    let n = (wall.b - wall.a).perp().normalize_or_zero();
                    if n.dot(p - wall.a) < 0.0 { -n } else { n }
                };
                q = c + normal * radius_m;
                pushed = true;
            }
            if !pushed {
                settled = true;
                break;
            }
        }
        let stuck = !settled && self.clearance_m(q, radius_m * 0.9).is_some();
        if stuck || self.crosses_wall(p, q) {
            p
        } else {
            q
        }
    }

    /// Whether the segment `p`–`q` touches or crosses a wall.
    fn crosses_wall(&self, p: DVec2, q: DVec2) -> bool {
        self.walls_near(p, q)
            .any(|w| segment_intersection(p, q, w.a, w.b).is_some())
    }
}

/// Where segments `p`–`q` and `a`–`b` meet, as `(t along p–q, u along a–b)`, ends included;
/// `None` when they do not meet or are parallel.
fn segment_intersection(p: DVec2, q: DVec2, a: DVec2, b: DVec2) -> Option<(f64, f64)> {
    let r = q - p;
    let s = b - a;
    let denom = r.perp_dot(s);
    if denom == 0.0 {
        return None;
    }
    let t = (a - p).perp_dot(s) / denom;
    let u = (a - p).perp_dot(r) / denom;
    ((0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u)).then_some((t, u))
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo::{LineString, Polygon};

    /// An axis-aligned square footprint.
    pub(crate) fn square(x0: f64, y0: f64, x1: f64, y1: f64) -> MultiPolygon<f64> {
        MultiPolygon::new(vec![Polygon::new(
            LineString::from(vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]),
            vec![],
        )])
    }

    #[test]
    fn inside_follows_holes_and_overlaps() {
        let mut courtyard = square(0.0, 0.0, 30.0, 30.0);
        courtyard.0[0].interiors_push(LineString::from(vec![
            (10.0, 10.0),
            (20.0, 10.0),
            (20.0, 20.0),
            (10.0, 20.0),
            (10.0, 10.0),
        ]));
        let overlap = square(25.0, 0.0, 40.0, 5.0);
        let world = CollisionWorld::from_parts([(&courtyard, 0.0, 0.0), (&overlap, 0.0, 0.0)]);
        assert!(world.is_inside(DVec2::new(5.0, 5.0)));
        assert!(
            !world.is_inside(DVec2::new(15.0, 15.0)),
            "courtyard is free"
        );
        assert!(
            world.is_inside(DVec2::new(27.0, 2.0)),
            "overlap of two parts"
        );
        assert!(world.is_inside(DVec2::new(35.0, 2.0)));
        assert!(!world.is_inside(DVec2::new(-5.0, 5.0)));
        assert!(!world.is_inside(DVec2::new(50.0, 5.0)));
        assert!(world.is_free(DVec2::new(15.0, 15.0), 0.3));
        assert!(
            !world.is_free(DVec2::new(15.0, 10.2), 0.3),
            "too close to a wall"
        );
    }

    /// A footprint of `corners` corners on a circle (long runs of walls split into groups).
    fn polygon(cx: f64, cy: f64, r: f64, corners: usize) -> MultiPolygon<f64> {
        let ring: Vec<(f64, f64)> = (0..=corners)
            .map(|i| {
                let t = i as f64 / corners as f64 * std::f64::consts::TAU;
                (cx + r * t.cos(), cy + r * t.sin())
            })
            .collect();
        MultiPolygon::new(vec![Polygon::new(LineString::from(ring), vec![])])
    }

    proptest::proptest! {
        /// The grouped, `f32` index finds exactly the walls a scan of every wall finds.
        #[test]
        fn queries_equal_a_scan_of_every_wall(
            parts in proptest::collection::vec(
                (-200.0..200.0f64, -200.0..200.0f64, 1.0..40.0f64, 3usize..60),
                1..12,
            ),
            probes in proptest::collection::vec((-250.0..250.0f64, -250.0..250.0f64), 1..20),
            reach in 0.1..30.0f64,
        ) {
            let footprints: Vec<MultiPolygon<f64>> = parts
                .iter()
                .map(|&(x, y, r, n)| polygon(x, y, r, n))
                .collect();
            let world = CollisionWorld::from_parts(footprints.iter().map(|f| (f, 0.0, 0.0)));
            let every: Vec<Wall> = world.walls_near(
                DVec2::splat(-1e6),
                DVec2::splat(1e6),
            ).collect();
            proptest::prop_assert_eq!(every.len(), world.wall_count());
            for (x, y) in probes {
                let p = DVec2::new(x, y);
                let mut near: Vec<(u32, [u64; 2])> = world
                    .walls_within(p, reach)
                    .map(|w| (w.part, [w.a.x.to_bits(), w.a.y.to_bits()]))
                    .collect();
                let mut scanned: Vec<(u32, [u64; 2])> = every
                    .iter()
                    .filter(|w| (p - w.closest_point(p)).length() <= reach)
                    .map(|w| (w.part, [w.a.x.to_bits(), w.a.y.to_bits()]))
                    .collect();
                near.sort_unstable();
                scanned.sort_unstable();
                proptest::prop_assert_eq!(near, scanned);
                // Even-odd over every wall of each part.
                let inside = (0..parts.len() as u32).any(|part| {
                    every
                        .iter()
                        .filter(|w| w.part == part)
                        .filter(|w| {
                            (w.a.y > p.y) != (w.b.y > p.y)
                                && w.a.x + (p.y - w.a.y) / (w.b.y - w.a.y) * (w.b.x - w.a.x) > p.x
                        })
                        .count()
                        % 2
                        == 1
                });
                proptest::prop_assert_eq!(world.is_inside(p), inside);
            }
        }
    }

    #[test]
    fn raised_parts_do_not_block() {
        let ground = square(0.0, 0.0, 10.0, 10.0);
        let bridge = square(20.0, 0.0, 30.0, 10.0);
        let world = CollisionWorld::from_parts([(&ground, 0.0, 0.0), (&bridge, 5.0, 0.0)]);
        assert_eq!(world.wall_count(), 4);
        assert!(!world.is_inside(DVec2::new(25.0, 5.0)));
    }

    #[test]
    fn ray_and_ground_queries() {
        let a = square(0.0, 0.0, 10.0, 10.0);
        let b = square(100.0, 0.0, 110.0, 10.0);
        let world = CollisionWorld::from_parts([(&a, -2.0, -2.0), (&b, 3.0, 3.0)]);
        let d = world
            .ray_distance_m(DVec2::new(-5.0, 5.0), DVec2::X * 3.0, 100.0)
            .expect("hits the first square");
        assert!((d - 5.0).abs() < 1e-9);
        assert!(
            world
                .ray_distance_m(DVec2::new(-5.0, 5.0), -DVec2::X, 100.0)
                .is_none()
        );
        assert_eq!(world.ground_z_m(DVec2::new(-5.0, 5.0), 20.0), -2.0);
        assert_eq!(world.ground_z_m(DVec2::new(115.0, 5.0), 20.0), 3.0);
        assert_eq!(world.ground_z_m(DVec2::new(55.0, 500.0), 20.0), -2.0);
    }
}
