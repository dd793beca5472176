//! Walk mode: a pedestrian's eye 1.7 m above the ground, moving on the ground plane, stopped and
//! slid along by building walls.

use citywalk_scenes::City;
use glam::{DVec2, Vec3};

use super::collision::CollisionWorld;
use super::{InputState, apply_mouse_look};
use crate::camera::Camera;

/// Tunables of walk mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WalkParams {
    /// Eye height above the ground (metres): a standing adult.
    pub eye_height_m: f32,
    /// Radius of the walker's body for collision (metres).
    pub body_radius_m: f64,
    /// Walking speed (metres per second); brisker than a stroll, since a city is large.
    pub walk_speed_mps: f32,
    /// Speed with the run key held (metres per second).
    pub run_speed_mps: f32,
    /// How far around the walker buildings count for the ground height (metres).
    pub ground_search_m: f64,
    /// Time constant with which the eye follows a change of ground height (seconds).
    pub ground_settle_s: f32,
}

impl Default for WalkParams {
    fn default() -> Self {
        WalkParams {
            eye_height_m: 1.7,
            body_radius_m: 0.3,
            walk_speed_mps: 2.5,
            run_speed_mps: 10.0,
            ground_search_m: 30.0,
            ground_settle_s: 0.25,
        }
    }
}

/// A walker: position on the ground, heading and pitch of the eye.
#[derive(Debug, Clone, PartialEq)]
pub struct WalkController {
    /// Position on the ground plane (metres, local frame).
    pub position_xy: DVec2,
    /// Height of the ground under the walker (metres), followed smoothly.
    pub ground_z_m: f32,
    pub yaw_rad: f32,
    pub pitch_rad: f32,
    pub params: WalkParams,
}

impl WalkController {
    /// A walker standing at `position_xy` on the ground `world` finds there.
    pub fn new(position_xy: DVec2, yaw_rad: f32, world: &CollisionWorld) -> WalkController {
        let params = WalkParams::default();
        WalkController {
            position_xy,
            ground_z_m: world.ground_z_m(position_xy, params.ground_search_m),
            yaw_rad,
            pitch_rad: 0.0,
            params,
        }
    }

    /// A walker on a street (with buildings beside it) near the centre of `city`, looking along
    /// the street towards more buildings; without streets, at the free point nearest to the
    /// centre.
    pub fn start_in(city: &City, world: &CollisionWorld) -> WalkController {
        let params = WalkParams::default();
        // The mean of the buildings' centres: unlike the centre of the bounds, it is not in a
        // river or a park when the city is lopsided.
        let centres = city.buildings.iter().map(|b| {
            let (lo, hi) = b.bounds();
            ((lo + hi) * 0.5).truncate().as_dvec2()
        });
        let centre = centres.sum::<DVec2>() / city.buildings.len().max(1) as f64;
        let centre = if centre.is_finite() {
            centre
        } else {
            DVec2::ZERO
        };
        // Keep a little more than the body radius free, so the first step is not into a wall.
        let clearance_m = params.body_radius_m + 0.5;
        let (position_xy, along) = street_start(city, world, centre, clearance_m)
            .or_else(|| {
                world
                    .find_free_point(centre, clearance_m, 2.0, search_limit_m(city))
                    .map(|p| (p, None))
            })
            .unwrap_or((centre, None));
        let yaw_rad = best_heading(world, position_xy, along);
        WalkController::new(position_xy, yaw_rad, world)
    }

    /// Advances the walker by `dt_s` seconds of `input`; vertical input is ignored.
    pub fn update(&mut self, dt_s: f32, input: &InputState, world: &CollisionWorld) {
        let dt_s = if dt_s.is_finite() { dt_s.max(0.0) } else { 0.0 };
        (self.yaw_rad, self.pitch_rad) =
            apply_mouse_look(self.yaw_rad, self.pitch_rad, input.look_delta_px);
        let (sy, cy) = self.yaw_rad.sin_cos();
        let forward = DVec2::new(cy as f64, sy as f64);
        let right = DVec2::new(sy as f64, -cy as f64);
        let wish = forward * input.forward as f64 + right * input.right as f64;
        let wish = if wish.length_squared() > 1.0 {
            wish.normalize()
        } else {
            wish
        };
        let speed_mps = if input.run {
            self.params.run_speed_mps
        } else {
            self.params.walk_speed_mps
        };
        let delta = wish * (speed_mps * dt_s) as f64;
        if delta.is_finite() {
            self.position_xy =
                world.move_circle(self.position_xy, delta, self.params.body_radius_m);
        }
        let target_m = world.ground_z_m(self.position_xy, self.params.ground_search_m);
        let follow = 1.0 - (-dt_s / self.params.ground_settle_s.max(1e-3)).exp();
        self.ground_z_m += (target_m - self.ground_z_m) * follow;
    }

    /// The eye position.
    pub fn eye(&self) -> Vec3 {
        self.position_xy
            .as_vec2()
            .extend(self.ground_z_m + self.params.eye_height_m)
    }

    /// The camera at the eye.
    pub fn camera(&self) -> Camera {
        Camera::new(self.eye(), self.yaw_rad, self.pitch_rad)
    }
}

/// How far from the centre to look for a free point: past the city's edge, where all is free.
fn search_limit_m(city: &City) -> f64 {
    city.bounds()
        .map(|(lo, hi)| (hi - lo).truncate().length() as f64)
        .unwrap_or(0.0)
        + 50.0
}

/// A street "has buildings beside it" when a wall is this close to its centre line (metres).
const STREET_SIDE_M: f64 = 25.0;

/// The free midpoint of a street segment nearest to `centre`, with the segment's direction.
fn street_start(
    city: &City,
    world: &CollisionWorld,
    centre: DVec2,
    clearance_m: f64,
) -> Option<(DVec2, Option<DVec2>)> {
    let mut candidates: Vec<(f64, DVec2, DVec2)> = city
        .streets
        .iter()
        .flat_map(|s| s.line.lines())
        .filter_map(|l| {
            let a = DVec2::new(l.start.x, l.start.y);
            let b = DVec2::new(l.end.x, l.end.y);
            let mid = (a + b) * 0.5;
            let dir = (b - a).try_normalize()?;
            mid.is_finite()
                .then(|| (mid.distance_squared(centre), mid, dir))
        })
        .collect();
    candidates.sort_by(|x, y| x.0.total_cmp(&y.0));
    // Prefer a street with buildings beside it (not a bridge or a square), else any free one.
    let lined = |mid: &DVec2| world.clearance_m(*mid, STREET_SIDE_M).is_some();
    let free = |mid: &DVec2| world.is_free(*mid, clearance_m);
    (candidates
        .iter()
        .find(|(_, mid, _)| free(mid) && lined(mid)))
    .or_else(|| candidates.iter().find(|(_, mid, _)| free(mid)))
    .map(|&(_, mid, dir)| (mid, Some(dir)))
}

/// A heading from `p` that faces the city: along `along` (either way) when given, else one of
/// 16 directions; the one with the most walls ahead (within ±35°, up to 300 m).
fn best_heading(world: &CollisionWorld, p: DVec2, along: Option<DVec2>) -> f32 {
    const AHEAD_M: f64 = 300.0;
    let cos_half_cone = 35.0_f64.to_radians().cos();
    let directions: Vec<DVec2> = match along {
        Some(d) => vec![d, -d],
        None => (0..16)
            .map(|i| DVec2::from_angle(i as f64 * std::f64::consts::TAU / 16.0))
            .collect(),
    };
    let near: Vec<DVec2> = world
        .walls_within(p, AHEAD_M)
        .filter_map(|w| ((w.a + w.b) * 0.5 - p).try_normalize())
        .collect();
    let ahead = |d: DVec2| near.iter().filter(|v| v.dot(d) > cos_half_cone).count();
    directions
        .into_iter()
        .max_by_key(|d| ahead(*d))
        .map(|d| d.y.atan2(d.x) as f32)
        .unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use citywalk_scenes::{
        Building, BuildingId, BuildingPart, Frame, HeightSource, LoadReport, Street, StreetClass,
    };
    use geo::{LineString, MultiPolygon, Polygon};

    /// A 3 × 3 grid of 30 m blocks with 20 m streets between them, and a lone tower far east
    /// that pulls the bounds' centre into an empty field.
    fn grid_city() -> City {
        let mut footprints = Vec::new();
        for i in 0..3 {
            for j in 0..3 {
                let (x, y) = (i as f64 * 50.0, j as f64 * 50.0);
                footprints.push((x, y, x + 30.0, y + 30.0));
            }
        }
        footprints.push((600.0, 60.0, 610.0, 70.0));
        let buildings = footprints
            .into_iter()
            .enumerate()
            .map(|(i, (x0, y0, x1, y1))| {
                let footprint = MultiPolygon::new(vec![Polygon::new(
                    LineString::from(vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]),
                    vec![],
                )]);
                Building {
                    id: BuildingId(i as u32),
                    source_id: format!("b{i}"),
                    footprint: footprint.clone(),
                    parts: vec![BuildingPart {
                        source_id: format!("b{i}"),
                        footprint,
                        base_m: 0.0,
                        top_m: 20.0,
                    }],
                    base_m: 0.0,
                    top_m: 20.0,
                    height_source: HeightSource::Tagged,
                    mesh: None,
                    tags: Default::default(),
                }
            })
            .collect();
        let street = |i: usize, a: (f64, f64), b: (f64, f64)| Street {
            source_id: format!("s{i}"),
            class: StreetClass::Residential,
            name: None,
            line: LineString::from(vec![a, b]),
            tagged_width_m: None,
        };
        let streets = vec![
            street(0, (40.0, -20.0), (40.0, 130.0)),
            street(1, (-20.0, 90.0), (130.0, 90.0)),
            // Far from the buildings: not a start.
            street(2, (300.0, 60.0), (400.0, 60.0)),
        ];
        City {
            frame: Frame::local(),
            buildings,
            streets,
            ground_areas: Vec::new(),
            report: LoadReport::default(),
        }
    }

    #[test]
    fn start_is_on_a_free_street_among_buildings() {
        let city = grid_city();
        let world = CollisionWorld::from_city(&city);
        let w = WalkController::start_in(&city, &world);
        assert!(world.is_free(w.position_xy, w.params.body_radius_m + 0.5));
        // The mean building centre is (≈ 115, ≈ 71); the nearest lined street midpoint is on
        // x = 40 or y = 90, not the lone street in the field.
        let on_x40 = (w.position_xy.x - 40.0).abs() < 1e-9;
        let on_y90 = (w.position_xy.y - 90.0).abs() < 1e-9;
        assert!(on_x40 || on_y90, "start {}", w.position_xy);
        // It looks along the street, towards the grid rather than out of it.
        let (s, c) = w.yaw_rad.sin_cos();
        let ahead = w.position_xy + DVec2::new(c as f64, s as f64) * 40.0;
        assert!(
            (0.0..=130.0).contains(&ahead.x) && (0.0..=130.0).contains(&ahead.y),
            "looks towards {ahead}"
        );
        assert_eq!(w.eye().z, 1.7);
    }

    #[test]
    fn start_without_streets_is_a_free_point_near_the_centre() {
        let mut city = grid_city();
        city.streets.clear();
        let world = CollisionWorld::from_city(&city);
        let w = WalkController::start_in(&city, &world);
        assert!(world.is_free(w.position_xy, w.params.body_radius_m + 0.5));
        let centre = DVec2::new(
            city.buildings
                .iter()
                .map(|b| f64::from(b.bounds().0.x + b.bounds().1.x) / 2.0)
                .sum::<f64>()
                / 10.0,
            city.buildings
                .iter()
                .map(|b| f64::from(b.bounds().0.y + b.bounds().1.y) / 2.0)
                .sum::<f64>()
                / 10.0,
        );
        assert!(
            w.position_xy.distance(centre) < 25.0,
            "start {} far from {centre}",
            w.position_xy
        );
    }
}
