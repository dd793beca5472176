//! Fly mode: free movement in all directions, through buildings, with an adjustable speed.

use glam::Vec3;

use super::{InputState, apply_mouse_look};
use crate::camera::Camera;

/// Tunables of fly mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlyParams {
    /// Speed multiplier with the run key held.
    pub run_factor: f32,
    /// Speed factor per scroll-wheel step.
    pub scroll_factor: f32,
    pub min_speed_mps: f32,
    pub max_speed_mps: f32,
}

impl Default for FlyParams {
    fn default() -> Self {
        FlyParams {
            run_factor: 4.0,
            scroll_factor: 1.25,
            min_speed_mps: 0.5,
            max_speed_mps: 5000.0,
        }
    }
}

/// A free-flying eye.
#[derive(Debug, Clone, PartialEq)]
pub struct FlyController {
    pub position: Vec3,
    pub yaw_rad: f32,
    pub pitch_rad: f32,
    /// Current speed (metres per second), changed by the scroll wheel.
    pub speed_mps: f32,
    pub params: FlyParams,
}

impl FlyController {
    /// Flies from `camera`'s pose at `speed_mps`.
    pub fn new(camera: &Camera, speed_mps: f32) -> FlyController {
        let params = FlyParams::default();
        FlyController {
            position: camera.position,
            yaw_rad: camera.yaw_rad,
            pitch_rad: camera.pitch_rad,
            speed_mps: speed_mps.clamp(params.min_speed_mps, params.max_speed_mps),
            params,
        }
    }

    /// A speed that crosses a city of the given bounds in about 20 seconds.
    pub fn speed_for_bounds_mps(bounds_min: Vec3, bounds_max: Vec3) -> f32 {
        ((bounds_max - bounds_min).truncate().length() / 20.0).max(10.0)
    }

    /// Advances by `dt_s` seconds of `input`: forward follows the view direction, right is
    /// horizontal, up is the world's z.
    pub fn update(&mut self, dt_s: f32, input: &InputState) {
        let dt_s = if dt_s.is_finite() { dt_s.max(0.0) } else { 0.0 };
        (self.yaw_rad, self.pitch_rad) =
            apply_mouse_look(self.yaw_rad, self.pitch_rad, input.look_delta_px);
        if input.scroll_steps.is_finite() {
            self.speed_mps = (self.speed_mps * self.params.scroll_factor.powf(input.scroll_steps))
                .clamp(self.params.min_speed_mps, self.params.max_speed_mps);
        }
        let camera = self.camera();
        let wish =
            camera.forward() * input.forward + camera.right() * input.right + Vec3::Z * input.up;
        let wish = if wish.length_squared() > 1.0 {
            wish.normalize()
        } else {
            wish
        };
        let run = if input.run {
            self.params.run_factor
        } else {
            1.0
        };
        let delta = wish * self.speed_mps * run * dt_s;
        if delta.is_finite() {
            self.position += delta;
        }
    }

    /// The camera at the eye.
    pub fn camera(&self) -> Camera {
        Camera::new(self.position, self.yaw_rad, self.pitch_rad)
    }
}
