//! Camera controllers for the viewer: walk mode (a pedestrian on the ground, stopped by walls)
//! and fly mode (free flight). They are plain structs advanced by
//! `update(dt_s, &InputState, &CollisionWorld)`, with no window in sight, so they are tested
//! like any other code; the viewer only turns window events into an [`InputState`].

pub mod collision;
mod fly;
mod walk;

use citywalk_scenes::City;
use glam::{DVec2, Vec2, Vec3};

pub use collision::{CollisionWorld, Wall};
pub use fly::{FlyController, FlyParams};
pub use walk::{WalkController, WalkParams};

use crate::camera::Camera;

/// Mouse-look sensitivity (radians per pixel of mouse motion): a 1000 px sweep turns ≈ 143°.
pub const LOOK_RAD_PER_PX: f32 = 0.0025;

/// What the user asks for during one update, independent of any window system.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct InputState {
    /// Forward (+1) / backward (−1).
    pub forward: f32,
    /// Right (+1) / left (−1).
    pub right: f32,
    /// Up (+1) / down (−1); fly mode only.
    pub up: f32,
    /// Run (walk mode) or fly faster.
    pub run: bool,
    /// Mouse motion since the last update (pixels; +x right, +y down).
    pub look_delta_px: Vec2,
    /// Scroll-wheel steps since the last update (+ = faster); fly mode only.
    pub scroll_steps: f32,
}

/// Turns the view by a mouse motion: right turns right (yaw decreases, since yaw is
/// counter-clockwise), down looks down; pitch is clamped short of straight up and down.
pub fn apply_mouse_look(yaw_rad: f32, pitch_rad: f32, delta_px: Vec2) -> (f32, f32) {
    if !delta_px.is_finite() {
        return (yaw_rad, pitch_rad);
    }
    let yaw_rad = (yaw_rad - delta_px.x * LOOK_RAD_PER_PX).rem_euclid(std::f32::consts::TAU);
    let pitch_rad = (pitch_rad - delta_px.y * LOOK_RAD_PER_PX)
        .clamp(-Camera::MAX_PITCH_RAD, Camera::MAX_PITCH_RAD);
    (yaw_rad, pitch_rad)
}

/// The viewer's movement mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    Walk,
    Fly,
}

impl Mode {
    pub fn name(self) -> &'static str {
        match self {
            Mode::Walk => "walk",
            Mode::Fly => "fly",
        }
    }
}

/// Both controllers and the mode that drives the camera.
#[derive(Debug, Clone)]
pub struct CameraRig {
    pub mode: Mode,
    pub walk: WalkController,
    pub fly: FlyController,
    /// The overview camera of the city, where fly mode starts.
    pub overview: Camera,
}

impl CameraRig {
    /// Walk mode on a street near the centre of `city`, fly mode at its overview camera.
    pub fn for_city(city: &City, world: &CollisionWorld, mode: Mode) -> CameraRig {
        let (lo, hi) = city
            .bounds()
            .unwrap_or((Vec3::splat(-50.0), Vec3::splat(50.0)));
        let overview = Camera::overview(lo, hi);
        CameraRig {
            mode,
            walk: WalkController::start_in(city, world),
            fly: FlyController::new(&overview, FlyController::speed_for_bounds_mps(lo, hi)),
            overview,
        }
    }

    /// Switches mode. Walk → fly takes off from the walker's eye; fly → walk lands at the free
    /// point nearest below the flyer (the walker stays where it was if there is none nearby).
    pub fn toggle_mode(&mut self, world: &CollisionWorld) {
        match self.mode {
            Mode::Walk => {
                self.fly.position = self.walk.eye();
                self.fly.yaw_rad = self.walk.yaw_rad;
                self.fly.pitch_rad = self.walk.pitch_rad;
                self.mode = Mode::Fly;
            }
            Mode::Fly => {
                let below = self.fly.position.truncate().as_dvec2();
                let clearance_m = self.walk.params.body_radius_m + 0.2;
                if let Some(p) = world.find_free_point(below, clearance_m, 1.0, 200.0) {
                    let yaw_rad = self.fly.yaw_rad;
                    self.walk = WalkController {
                        params: self.walk.params,
                        ..WalkController::new(p, yaw_rad, world)
                    };
                }
                self.mode = Mode::Walk;
            }
        }
    }

    /// Puts the flyer back at the overview camera (and switches to fly mode).
    pub fn reset_to_overview(&mut self) {
        self.fly.position = self.overview.position;
        self.fly.yaw_rad = self.overview.yaw_rad;
        self.fly.pitch_rad = self.overview.pitch_rad;
        self.mode = Mode::Fly;
    }

    /// Advances the active controller.
    pub fn update(&mut self, dt_s: f32, input: &InputState, world: &CollisionWorld) {
        match self.mode {
            Mode::Walk => self.walk.update(dt_s, input, world),
            Mode::Fly => self.fly.update(dt_s, input),
        }
    }

    /// The active controller's camera.
    pub fn camera(&self) -> Camera {
        match self.mode {
            Mode::Walk => self.walk.camera(),
            Mode::Fly => self.fly.camera(),
        }
    }

    /// Position of the walker on the ground, or of the flyer projected down.
    pub fn position_xy(&self) -> DVec2 {
        self.camera().position.truncate().as_dvec2()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo::{LineString, MultiPolygon, Polygon};

    fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> MultiPolygon<f64> {
        MultiPolygon::new(vec![Polygon::new(
            LineString::from(vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)]),
            vec![],
        )])
    }

    fn world_of(rects: &[MultiPolygon<f64>]) -> CollisionWorld {
        CollisionWorld::from_parts(rects.iter().map(|r| (r, 0.0, 0.0)))
    }

    fn walker(x: f64, y: f64, yaw_deg: f32, world: &CollisionWorld) -> WalkController {
        WalkController::new(DVec2::new(x, y), yaw_deg.to_radians(), world)
    }

    const FORWARD: InputState = InputState {
        forward: 1.0,
        right: 0.0,
        up: 0.0,
        run: false,
        look_delta_px: Vec2::ZERO,
        scroll_steps: 0.0,
    };

    #[test]
    fn walking_into_a_wall_stops_at_the_wall() {
        let world = world_of(&[rect(0.0, 0.0, 10.0, 10.0)]);
        let mut w = walker(-5.0, 5.0, 0.0, &world);
        let radius = w.params.body_radius_m;
        for _ in 0..200 {
            w.update(1.0 / 60.0, &FORWARD, &world);
            assert!(
                w.position_xy.x <= -radius + 1e-9,
                "entered the wall: {}",
                w.position_xy
            );
        }
        // 200 frames at 2.5 m/s cover 8.3 m: more than the 5 m to the wall.
        assert!(
            (w.position_xy.x + radius).abs() < 1e-6,
            "stopped at {}",
            w.position_xy
        );
        assert!(
            (w.position_xy.y - 5.0).abs() < 1e-9,
            "head-on: no sideways drift"
        );
    }

    #[test]
    fn no_tunnelling_at_high_speed_and_large_steps() {
        // A 5 cm thin wall, far thinner than a step of 10 m/s × 10 s.
        let world = world_of(&[rect(0.0, -50.0, 0.05, 50.0)]);
        let run = InputState {
            run: true,
            ..FORWARD
        };
        for dt_s in [0.5, 3.0, 10.0] {
            let mut w = walker(-20.0, 1.0, 0.0, &world);
            w.update(dt_s, &run, &world);
            assert!(
                w.position_xy.x < 0.0,
                "dt {dt_s}: passed through to {}",
                w.position_xy
            );
            assert!(!world.is_inside(w.position_xy));
        }
        let mut w = walker(-20.0, 1.0, 0.0, &world);
        w.update(10.0, &run, &world);
        assert!((w.position_xy.x + w.params.body_radius_m).abs() < 1e-6);
    }

    #[test]
    fn sliding_along_a_wall_keeps_the_tangential_motion() {
        let world = world_of(&[rect(0.0, -100.0, 10.0, 100.0)]);
        // Heading 45° north of east, into the wall at x = 0.
        let mut w = walker(-1.0, 0.0, 45.0, &world);
        let dt_s = 1.0 / 60.0;
        let frames = 240;
        for _ in 0..frames {
            w.update(dt_s, &FORWARD, &world);
        }
        let radius = w.params.body_radius_m;
        assert!(
            (w.position_xy.x + radius).abs() < 1e-6,
            "at the wall: {}",
            w.position_xy
        );
        // Along the wall the walker keeps (close to) the tangential speed v·sin 45°; before
        // touching the wall it moved at 45° too, so y grows by v·t·sin 45° in total.
        let expected_y = w.params.walk_speed_mps as f64
            * dt_s as f64
            * frames as f64
            * std::f64::consts::FRAC_1_SQRT_2;
        assert!(
            (w.position_xy.y - expected_y).abs() < 0.05 * expected_y,
            "slid to y = {}, expected ≈ {expected_y}",
            w.position_xy.y
        );
    }

    #[test]
    fn sliding_into_a_corner_stops_in_the_corner() {
        // An L of two buildings: walls at x = 0 (y ≥ 0) and y = 10.
        let world = world_of(&[rect(0.0, 0.0, 10.0, 30.0), rect(-20.0, 10.0, 0.0, 30.0)]);
        let mut w = walker(-5.0, 2.0, 30.0, &world);
        for _ in 0..600 {
            w.update(1.0 / 30.0, &FORWARD, &world);
            assert!(world.is_free(w.position_xy, w.params.body_radius_m - 1e-6));
        }
        let r = w.params.body_radius_m;
        assert!(
            w.position_xy.distance(DVec2::new(-r, 10.0 - r)) < 1e-3,
            "{}",
            w.position_xy
        );
    }

    #[test]
    fn random_walks_never_enter_a_footprint() {
        // A deterministic field of buildings and walks (xorshift, fixed seed).
        let mut state = 0x9E37_79B9_7F4A_7C15_u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut rects = Vec::new();
        for i in 0..8 {
            for j in 0..8 {
                let (x, y) = (i as f64 * 20.0, j as f64 * 20.0);
                let (w, h) = (4.0 + next() * 12.0, 0.1 + next() * 14.0);
                rects.push(rect(x, y, x + w, y + h));
            }
        }
        let world = world_of(&rects);
        let mut checks = 0;
        for _ in 0..40 {
            let start = DVec2::new(next() * 160.0, next() * 160.0);
            let Some(p) = world.find_free_point(start, 0.4, 0.5, 50.0) else {
                continue;
            };
            let mut w = WalkController::new(p, 0.0, &world);
            for _ in 0..100 {
                let input = InputState {
                    forward: (next() * 2.0 - 1.0) as f32,
                    right: (next() * 2.0 - 1.0) as f32,
                    run: next() < 0.5,
                    look_delta_px: Vec2::new((next() * 200.0 - 100.0) as f32, 0.0),
                    ..InputState::default()
                };
                let before = w.position_xy;
                w.update((next() * 0.5) as f32, &input, &world);
                assert!(
                    !world.is_inside(w.position_xy),
                    "{before} -> {}",
                    w.position_xy
                );
                // Sliding around a corner is not a straight line, so the check is clearance.
                let r = w.params.body_radius_m;
                assert!(
                    world.clearance_m(w.position_xy, 0.9 * r).is_none(),
                    "in a wall: {before} -> {}",
                    w.position_xy
                );
                checks += 1;
            }
        }
        assert!(checks > 1000, "only {checks} steps checked");
    }

    #[test]
    fn walk_height_stays_at_eye_height() {
        let world = world_of(&[rect(0.0, 0.0, 10.0, 10.0), rect(20.0, 0.0, 30.0, 10.0)]);
        let mut w = walker(15.0, -3.0, 90.0, &world);
        let input = InputState {
            forward: 1.0,
            right: 0.3,
            run: true,
            look_delta_px: Vec2::new(3.0, -200.0),
            ..InputState::default()
        };
        for _ in 0..300 {
            w.update(1.0 / 60.0, &input, &world);
            assert_eq!(w.eye().z, 1.7, "eye height in a flat 2.5D city");
            assert_eq!(w.camera().position, w.eye());
        }
        // Buildings based lower than z = 0: the eye settles 1.7 m above their base.
        let low = rect(0.0, 0.0, 10.0, 10.0);
        let world = CollisionWorld::from_parts([(&low, -4.0, -4.0)]);
        let mut w = WalkController::new(DVec2::new(-5.0, 5.0), 0.0, &world);
        assert!((w.eye().z - (-4.0 + 1.7)).abs() < 1e-6);
        w.update(0.5, &InputState::default(), &world);
        assert!((w.eye().z - (-2.3)).abs() < 1e-6);
    }

    #[test]
    fn fly_mode_passes_through_buildings() {
        let world = world_of(&[rect(0.0, 0.0, 10.0, 10.0)]);
        let camera = Camera::new(Vec3::new(-5.0, 5.0, 2.0), 0.0, 0.0);
        let mut rig = CameraRig {
            mode: Mode::Fly,
            walk: walker(-5.0, 5.0, 0.0, &world),
            fly: FlyController::new(&camera, 10.0),
            overview: camera,
        };
        for _ in 0..30 {
            rig.update(0.1, &FORWARD, &world);
        }
        assert!(
            (rig.camera().position.x - 25.0).abs() < 1e-3,
            "{}",
            rig.camera().position
        );
        // Up and down, and the scroll wheel changes speed.
        let up = InputState {
            up: 1.0,
            scroll_steps: 2.0,
            ..InputState::default()
        };
        rig.update(1.0, &up, &world);
        assert!((rig.fly.speed_mps - 10.0 * 1.25 * 1.25).abs() < 1e-3);
        assert!((rig.camera().position.z - (2.0 + rig.fly.speed_mps)).abs() < 1e-3);
        // Landing puts the walker on free ground near the flyer, at eye height.
        rig.fly.position = Vec3::new(5.0, 5.0, 30.0);
        rig.toggle_mode(&world);
        assert_eq!(rig.mode, Mode::Walk);
        assert!(world.is_free(rig.walk.position_xy, rig.walk.params.body_radius_m));
        assert!(rig.walk.position_xy.distance(DVec2::new(5.0, 5.0)) < 7.0);
        assert_eq!(rig.camera().position.z, 1.7);
        rig.toggle_mode(&world);
        assert_eq!(rig.mode, Mode::Fly);
        assert_eq!(rig.camera().position, rig.walk.eye());
    }

    #[test]
    fn mouse_look_clamps_pitch() {
        let (yaw, pitch) = apply_mouse_look(0.0, 0.0, Vec2::new(0.0, -1.0e6));
        assert_eq!(pitch, Camera::MAX_PITCH_RAD);
        assert_eq!(yaw, 0.0);
        let (_, pitch) = apply_mouse_look(0.0, pitch, Vec2::new(0.0, 2.0e6));
        assert_eq!(pitch, -Camera::MAX_PITCH_RAD);
        // Moving the mouse right turns right (clockwise seen from above).
        let (yaw, _) = apply_mouse_look(1.0, 0.0, Vec2::new(100.0, 0.0));
        assert!((yaw - (1.0 - 100.0 * LOOK_RAD_PER_PX)).abs() < 1e-6);
        let world = CollisionWorld::default();
        let mut w = walker(0.0, 0.0, 0.0, &world);
        let look = InputState {
            look_delta_px: Vec2::new(0.0, 1.0e5),
            ..InputState::default()
        };
        w.update(0.1, &look, &world);
        assert_eq!(w.pitch_rad, -Camera::MAX_PITCH_RAD);
        assert!(w.camera().forward().z > -1.0);
    }
}
