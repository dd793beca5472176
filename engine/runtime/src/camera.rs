//! The first-person camera: position, yaw and pitch in the city's local frame (x east, y north,
//! z up), with a reversed-Z infinite perspective projection.
//!
//! Reversed Z (depth 1 at the near plane, 0 at infinity) with a `Depth32Float` buffer keeps depth
//! precision nearly uniform over kilometres of city. Every pass that draws with this camera clears
//! depth to [`Camera::DEPTH_CLEAR`] and compares with `Greater` (or `GreaterEqual`).

use glam::{Mat4, Vec3};

/// A camera in the local frame (metres; z up).
///
/// `yaw_rad = 0` looks along +x (east), `yaw_rad = π/2` along +y (north); `pitch_rad` is positive
/// looking up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Eye position (metres, local frame).
    pub position: Vec3,
    /// Heading, counter-clockwise from east (radians).
    pub yaw_rad: f32,
    /// Elevation of the view direction above the horizon (radians), in (-π/2, π/2).
    pub pitch_rad: f32,
    /// Vertical field of view (radians).
    pub fov_y_rad: f32,
    /// Distance of the near plane (metres). There is no far plane.
    pub near_m: f32,
}

/// Why a camera string could not be parsed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CameraParseError {
    #[error(
        "camera {input:?}: expected five comma-separated numbers X,Y,Z,YAW,PITCH (metres, degrees), got {count}"
    )]
    Count { input: String, count: usize },
    #[error("camera {input:?}: {field} is not a finite number ({value:?})")]
    NotANumber {
        input: String,
        field: &'static str,
        value: String,
    },
    #[error("camera {input:?}: pitch {pitch_deg}° is outside (-90°, 90°)")]
    Pitch { input: String, pitch_deg: f32 },
}

impl Camera {
    /// Default vertical field of view: 60°.
    pub const DEFAULT_FOV_Y_RAD: f32 = std::f32::consts::FRAC_PI_3;
    /// Default near plane: 0.5 m (a pedestrian can stand close to a wall).
    pub const DEFAULT_NEAR_M: f32 = 0.5;
    /// Depth value to clear to: reversed Z puts infinity at 0.
    pub const DEPTH_CLEAR: f32 = 0.0;
    /// The depth comparison every reversed-Z pass uses.
    pub const DEPTH_COMPARE: wgpu::CompareFunction = wgpu::CompareFunction::Greater;
    /// Largest |pitch| the camera accepts: just short of straight up or down, where yaw would be
    /// undefined.
    pub const MAX_PITCH_RAD: f32 = 89.0_f32.to_radians();

    /// A camera at `position` with the given heading and pitch (radians), default field of view
    /// and near plane. The pitch is clamped to ±[`Camera::MAX_PITCH_RAD`].
    pub fn new(position: Vec3, yaw_rad: f32, pitch_rad: f32) -> Camera {
        Camera {
            position,
            yaw_rad,
            pitch_rad: pitch_rad.clamp(-Self::MAX_PITCH_RAD, Self::MAX_PITCH_RAD),
            fov_y_rad: Self::DEFAULT_FOV_Y_RAD,
            near_m: Self::DEFAULT_NEAR_M,
        }
    }

    /// Parses `"X,Y,Z,YAW,PITCH"`: position in metres, yaw and pitch in **degrees**.
    pub fn parse(input: &str) -> Result<Camera, CameraParseError> {
        let fields: Vec<&str> = input.split(',').map(str::trim).collect();
        if fields.len() != 5 {
            return Err(CameraParseError::Count {
                input: input.to_string(),
                count: fields.len(),
            });
        }
        const NAMES: [&str; 5] = ["X", "Y", "Z", "YAW", "PITCH"];
        let mut v = [0.0_f32; 5];
        for (i, (field, name)) in fields.iter().zip(NAMES).enumerate() {
            v[i] = field
                .parse::<f32>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| CameraParseError::NotANumber {
                    input: input.to_string(),
                    field: name,
                    value: (*field).to_string(),
                })?;
        }
        if v[4].abs() >= 90.0 {
            return Err(CameraParseError::Pitch {
                input: input.to_string(),
                pitch_deg: v[4],
            });
        }
        Ok(Camera::new(
            Vec3::new(v[0], v[1], v[2]),
            v[3].to_radians(),
            v[4].to_radians(),
        ))
    }

    /// Formats the camera the way [`Camera::parse`] reads it.
    pub fn to_arg_string(&self) -> String {
        format!(
            "{:.2},{:.2},{:.2},{:.3},{:.3}",
            self.position.x,
            self.position.y,
            self.position.z,
            self.yaw_rad.to_degrees(),
            self.pitch_rad.to_degrees()
        )
    }

    /// The default view of a city whose bounds are `(bounds_min, bounds_max)`: from the
    /// south-west, looking north-east, 45° down, framed so that all eight corners of the bounds
    /// fit in a 60° (vertical) view at a 16:9 aspect with a small margin, roughly centred.
    pub fn overview(bounds_min: Vec3, bounds_max: Vec3) -> Camera {
        const ASPECT: f32 = 16.0 / 9.0;
        const MARGIN_NDC: f32 = 0.92;
        let corners: [Vec3; 8] = std::array::from_fn(|i| {
            Vec3::new(
                if i & 1 == 0 {
                    bounds_min.x
                } else {
                    bounds_max.x
                },
                if i & 2 == 0 {
                    bounds_min.y
                } else {
                    bounds_max.y
                },
                if i & 4 == 0 {
                    bounds_min.z
                } else {
                    bounds_max.z
                },
            )
        });
        let centre = (bounds_min + bounds_max) * 0.5;
        let radius = ((bounds_max - bounds_min) * 0.5).length().max(1.0);
        let base = Camera::new(Vec3::ZERO, 45f32.to_radians(), -45f32.to_radians());
        let (forward, right) = (base.forward(), base.right());
        let up = right.cross(forward);
        // The camera looking at `target` from `distance_m`.
        let at = |target: Vec3, distance_m: f32| {
            let mut c = base;
            c.position = target - forward * distance_m;
            c.near_m = (distance_m * 1e-3).max(Self::DEFAULT_NEAR_M);
            c
        };
        // NDC bounding box of the corners, or None when one is behind the near plane.
        let ndc_box = |c: &Camera| {
            let vp = c.view_proj(ASPECT);
            let mut lo = glam::Vec2::splat(f32::INFINITY);
            let mut hi = glam::Vec2::splat(f32::NEG_INFINITY);
            for corner in corners {
                let clip = vp * corner.extend(1.0);
                if clip.w <= c.near_m {
                    return None;
                }
                let p = glam::Vec2::new(clip.x, clip.y) / clip.w;
                lo = lo.min(p);
                hi = hi.max(p);
            }
            Some((lo, hi))
        };
        let fits = |c: &Camera| {
            ndc_box(c).is_some_and(|(lo, hi)| {
                lo.cmpge(-glam::Vec2::splat(MARGIN_NDC)).all()
                    && hi.cmple(glam::Vec2::splat(MARGIN_NDC)).all()
            })
        };
        // The bounding sphere always fits at radius / sin(fov / 2) (with margin); search the
        // distance down from there, then shift the aim to centre the box, and repeat.
        let far_m = radius / (Self::DEFAULT_FOV_Y_RAD * 0.5).sin() / MARGIN_NDC;
        let mut target = centre;
        let mut distance_m = far_m;
        for _ in 0..6 {
            let (mut lo, mut hi) = (0.0_f32, far_m * 2.0);
            if !fits(&at(target, hi)) {
                break;
            }
            for _ in 0..40 {
                let mid = 0.5 * (lo + hi);
                if fits(&at(target, mid)) {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            distance_m = hi;
            let Some((blo, bhi)) = ndc_box(&at(target, distance_m)) else {
                break;
            };
            let offset = (blo + bhi) * 0.5;
            let half_h = distance_m * (Self::DEFAULT_FOV_Y_RAD * 0.5).tan();
            target += right * offset.x * half_h * ASPECT * 0.8 + up * offset.y * half_h * 0.8;
        }
        if !fits(&at(target, distance_m)) {
            (target, distance_m) = (centre, far_m);
        }
        at(target, distance_m)
    }

    /// Unit view direction.
    pub fn forward(&self) -> Vec3 {
        let (sy, cy) = self.yaw_rad.sin_cos();
        let (sp, cp) = self.pitch_rad.sin_cos();
        Vec3::new(cy * cp, sy * cp, sp)
    }

    /// Unit vector to the right of the view direction, horizontal.
    pub fn right(&self) -> Vec3 {
        let (sy, cy) = self.yaw_rad.sin_cos();
        Vec3::new(sy, -cy, 0.0)
    }

    /// World-to-view matrix (right-handed, looking down −z in view space, y up).
    pub fn view(&self) -> Mat4 {
        glam::camera::rh::view::look_to_mat4(self.position, self.forward(), Vec3::Z)
    }

    /// Reversed-Z infinite perspective: view-space depth `near_m` maps to NDC z = 1, infinity to
    /// 0. `aspect` is width / height.
    pub fn proj(&self, aspect: f32) -> Mat4 {
        glam::camera::rh::proj::directx::perspective_infinite_reverse(
            self.fov_y_rad,
            aspect.max(1e-6),
            self.near_m,
        )
    }

    /// `proj(aspect) * view()`: world to clip space.
    pub fn view_proj(&self, aspect: f32) -> Mat4 {
        self.proj(aspect) * self.view()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ndc(m: Mat4, p: Vec3) -> Vec3 {
        let c = m * p.extend(1.0);
        c.truncate() / c.w
    }

    #[test]
    fn reversed_z_maps_near_to_one_and_far_towards_zero() {
        let cam = Camera::new(Vec3::new(10.0, 20.0, 1.7), 0.3, 0.0);
        let vp = cam.view_proj(16.0 / 9.0);
        let near = ndc(vp, cam.position + cam.forward() * cam.near_m);
        assert!((near.z - 1.0).abs() < 1e-5, "near plane depth {}", near.z);
        let mid = ndc(vp, cam.position + cam.forward() * 100.0);
        assert!(
            (mid.z - cam.near_m / 100.0).abs() < 1e-6,
            "depth at 100 m {}",
            mid.z
        );
        let far = ndc(vp, cam.position + cam.forward() * 1.0e7);
        assert!(far.z > 0.0 && far.z < 1e-6, "depth at 10 000 km {}", far.z);
        // Depth decreases monotonically with distance.
        let mut last = 2.0;
        for d in [0.5, 1.0, 10.0, 1e3, 1e5] {
            let z = ndc(vp, cam.position + cam.forward() * d).z;
            assert!(z < last, "depth not decreasing at {d} m");
            last = z;
        }
    }

    #[test]
    fn axes_follow_the_frame() {
        let cam = Camera::new(Vec3::ZERO, 0.0, 0.0);
        assert!((cam.forward() - Vec3::X).length() < 1e-6);
        let vp = cam.view_proj(1.0);
        // Up in the world is up on screen, north is left when looking east.
        let up = ndc(vp, Vec3::new(10.0, 0.0, 1.0));
        assert!(up.y > 0.0 && up.x.abs() < 1e-6);
        let north = ndc(vp, Vec3::new(10.0, 1.0, 0.0));
        assert!(north.x < 0.0);
        let cam = Camera::new(Vec3::ZERO, std::f32::consts::FRAC_PI_2, 0.3);
        let f = cam.forward();
        assert!(f.x.abs() < 1e-6 && f.y > 0.0 && f.z > 0.0);
        // Points behind the camera have w < 0.
        let behind = cam.view_proj(1.0) * (-f * 10.0).extend(1.0);
        assert!(behind.w < 0.0);
    }

    #[test]
    fn parse_reads_degrees_and_rejects_bad_input() {
        let cam = Camera::parse("1, 2,3.5,90,-30").expect("valid");
        assert_eq!(cam.position, Vec3::new(1.0, 2.0, 3.5));
        assert!((cam.yaw_rad - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
        assert!((cam.pitch_rad + 30.0_f32.to_radians()).abs() < 1e-6);
        let round = Camera::parse(&cam.to_arg_string()).expect("round trip");
        assert!((round.position - cam.position).length() < 1e-2);
        assert!(matches!(
            Camera::parse("1,2,3"),
            Err(CameraParseError::Count { .. })
        ));
        assert!(matches!(
            Camera::parse("1,2,x,0,0"),
            Err(CameraParseError::NotANumber { field: "Z", .. })
        ));
        assert!(matches!(
            Camera::parse("1,2,3,0,NaN"),
            Err(CameraParseError::NotANumber { .. })
        ));
        assert!(matches!(
            Camera::parse("1,2,3,0,90"),
            Err(CameraParseError::Pitch { .. })
        ));
    }

    #[test]
    fn overview_sees_every_corner_of_the_bounds() {
        let (lo, hi) = (
            Vec3::new(-800.0, -300.0, 0.0),
            Vec3::new(1200.0, 900.0, 120.0),
        );
        let cam = Camera::overview(lo, hi);
        assert!(cam.pitch_rad < 0.0);
        let centre = (lo + hi) * 0.5;
        assert!(cam.position.x < centre.x && cam.position.y < centre.y && cam.position.z > hi.z);
        let vp = cam.view_proj(16.0 / 9.0);
        for i in 0..8 {
            let corner = Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            );
            let p = ndc(vp, corner);
            assert!(
                p.x.abs() <= 1.0 && p.y.abs() <= 1.0 && p.z > 0.0 && p.z <= 1.0,
                "corner {corner} at NDC {p}"
            );
        }
    }
}
