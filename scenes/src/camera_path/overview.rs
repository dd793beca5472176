//! The overview path: from far away in to a circle around the whole city, once round, and away.

use std::f32::consts::TAU;

use glam::Vec3;

use super::{CameraPath, CameraPose, DEFAULT_FOV_Y_DEG, GeneratedPath, spread};
use crate::city::City;
use crate::city_sphere::CitySphere;

/// Where the overview starts and ends, in city diameters from the centre ([`CitySphere`]):
/// beyond one diameter, the benchmark's far views, and far enough that the city's sphere spans
/// about 19° of the 60° view, a city seen whole from afar as Chang et al.'s overview begins.
pub const FAR_DIAMETERS: f32 = 3.0;
/// The circle's horizontal radius, in city diameters: outside the buildings' box (whose corners
/// are at most half a diameter from the centre), so the camera circles the city, not over it.
pub const CIRCLE_RADIUS_DIAMETERS: f32 = 0.75;
/// The circle's elevation seen from the centre (degrees). Below half the vertical field of view,
/// so a camera looking at the centre keeps the horizon in frame: the far skyline stands against
/// the sky, legible, while the near half of the city is seen from above.
const CIRCLE_ELEVATION_DEG: f32 = 15.0;
/// The elevation the camera climbs to as it flies away (degrees): it leaves looking down on the
/// whole city, a view unlike the low approach.
const AWAY_ELEVATION_DEG: f32 = 40.0;
/// Where the path starts, seen from the centre (degrees counter-clockwise from east): the
/// south-west, as `render`'s default camera.
const START_AZIMUTH_DEG: f32 = 225.0;
/// Share of the path spent zooming in, and again flying away; the half between circles.
const ZOOM_SHARE: f64 = 0.25;
/// Metres the circle keeps above the highest roof, as a share of the city's diameter: the eye is
/// above every building (the LOD's roof-level tolerance) and never passes through one.
const ROOF_CLEARANCE_DIAMETERS: f32 = 0.02;

/// Chang et al. 2008 §9, Fig. 14: "The camera used in these tests starts far away from the city
/// and slowly zooms in. It then rotates around the city and flies away." Far frames are where a
/// hierarchical simplification pays most (the paper's frames 1 to 100).
///
/// In the city's [`CitySphere`] (centre `c`, diameter `d`), over `frames` evenly spread steps
/// `t` from 0 to 1, continuous at the joins:
/// - `t` in [0, ¼): zoom in from [`FAR_DIAMETERS`]·`d` along one ray from the south-west at the
///   circle's elevation, the distance falling geometrically (the city grows by the same factor
///   every frame);
/// - `t` in [¼, ¾]: one counter-clockwise turn at [`CIRCLE_RADIUS_DIAMETERS`]·`d` from the
///   centre, 15° up seen from it, and at least a fiftieth of `d` above the highest roof;
/// - `t` in (¾, 1]: fly away along the start's azimuth, climbing to 40° of elevation, back out
///   to [`FAR_DIAMETERS`]·`d`.
///
/// Every pose looks at `c`. Deterministic: it depends on the buildings' bounds alone.
pub fn overview(city: &City, frames: usize) -> CameraPath {
    let sphere = CitySphere::of(city);
    let (c, d) = (sphere.centre, sphere.diameter_m);
    let top = city.bounds().map_or(c.z, |(_, hi)| hi.z);
    let radius = CIRCLE_RADIUS_DIAMETERS * d;
    let height = (radius * CIRCLE_ELEVATION_DEG.to_radians().tan())
        .max(top + ROOF_CLEARANCE_DIAMETERS * d - c.z);
    let circle_elevation = height.atan2(radius);
    let (near, far) = (radius.hypot(height), FAR_DIAMETERS * d);
    let start = START_AZIMUTH_DEG.to_radians();
    let poses = (0..frames)
        .map(|i| {
            let t = spread(i, frames);
            let (azimuth, elevation, distance) = if t < ZOOM_SHARE {
                let s = (t / ZOOM_SHARE) as f32;
                (start, circle_elevation, far * (near / far).powf(s))
            } else if t <= 1.0 - ZOOM_SHARE {
                let u = ((t - ZOOM_SHARE) / (1.0 - 2.0 * ZOOM_SHARE)) as f32;
                (start + TAU * u, circle_elevation, near)
            } else {
                let s = ((t - (1.0 - ZOOM_SHARE)) / ZOOM_SHARE) as f32;
                let climb = AWAY_ELEVATION_DEG.to_radians() - circle_elevation;
                (
                    start,
                    circle_elevation + climb * s,
                    near * (far / near).powf(s),
                )
            };
            looking_at_centre(c, azimuth, elevation, distance)
        })
        .collect();
    CameraPath {
        name: GeneratedPath::Overview.name().into(),
        fov_y_deg: DEFAULT_FOV_Y_DEG,
        poses,
    }
}

/// The pose `distance` metres from `centre` in the direction of `azimuth` (radians
/// counter-clockwise from east) and `elevation` (radians up), looking back at `centre`.
fn looking_at_centre(centre: Vec3, azimuth: f32, elevation: f32, distance: f32) -> CameraPose {
    let (sa, ca) = azimuth.sin_cos();
    let (se, ce) = elevation.sin_cos();
    CameraPose {
        position: centre + distance * Vec3::new(ce * ca, ce * sa, se),
        yaw_deg: (azimuth.to_degrees() + 180.0).rem_euclid(360.0),
        pitch_deg: -elevation.to_degrees(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera_path::tests::city;

    /// The unit view direction of a pose, by the path format's conventions (yaw counter-clockwise
    /// from east, pitch up), as the runtime's camera computes it.
    fn forward(p: &CameraPose) -> Vec3 {
        let (sy, cy) = p.yaw_deg.to_radians().sin_cos();
        let (sp, cp) = p.pitch_deg.to_radians().sin_cos();
        Vec3::new(cy * cp, sy * cp, sp)
    }

    #[test]
    fn has_the_frames_asked_for() {
        let c = city(true);
        for frames in [0, 1, 2, 7, 24] {
            let path = overview(&c, frames);
            assert_eq!(path.poses.len(), frames);
            assert_eq!(path.name, "overview");
        }
        assert_eq!(overview(&c, 1).poses[0], overview(&c, 24).poses[0]);
    }

    #[test]
    fn starts_and_ends_beyond_the_city_diameter_seeing_all_of_it() {
        let c = city(true);
        let sphere = CitySphere::of(&c);
        let path = overview(&c, 24);
        let half_fov = (path.fov_y_deg / 2.0).to_radians();
        for pose in [path.poses[0], path.poses[23]] {
            let far = sphere.distance_in_diameters(pose.position);
            assert!(
                (far - FAR_DIAMETERS).abs() < 1e-3,
                "{far} diameters: {pose:?}"
            );
            // The whole sphere is inside the view cone: the city is seen whole.
            let to_centre = sphere.centre - pose.position;
            let off_axis = forward(&pose).angle_between(to_centre);
            let half_size = (0.5 * sphere.diameter_m / to_centre.length()).asin();
            assert!(off_axis + half_size < half_fov, "{pose:?}");
        }
        // Far away at first, near in the middle: it zooms in and back out.
        let dist: Vec<f32> = path
            .poses
            .iter()
            .map(|p| sphere.distance_in_diameters(p.position))
            .collect();
        assert!(dist[..6].windows(2).all(|w| w[1] < w[0]), "{dist:?}");
        assert!(dist[18..].windows(2).all(|w| w[1] > w[0]), "{dist:?}");
        assert!(dist[11] < 1.0, "{dist:?}");
    }

    #[test]
    fn circles_at_its_radius_above_the_roofs_with_the_horizon_in_view() {
        let c = city(true);
        let sphere = CitySphere::of(&c);
        let top = c.bounds().unwrap().1.z;
        let frames = 41;
        let path = overview(&c, frames);
        let radius = CIRCLE_RADIUS_DIAMETERS * sphere.diameter_m;
        let circling: Vec<&CameraPose> = (0..frames)
            .filter(|&i| (ZOOM_SHARE..=1.0 - ZOOM_SHARE).contains(&spread(i, frames)))
            .map(|i| &path.poses[i])
            .collect();
        assert_eq!(circling.len(), 21);
        let height = circling[0].position.z;
        assert!(height > top, "{height} under the roofs at {top}");
        for p in &circling {
            let across = (p.position - sphere.centre).truncate().length();
            assert!((across - radius).abs() < 1e-3 * radius, "{p:?}");
            assert!((p.position.z - height).abs() < 1e-3, "{p:?}");
            assert!(
                p.pitch_deg < 0.0 && -p.pitch_deg < path.fov_y_deg / 2.0,
                "{p:?}"
            );
        }
        // Once round: the first and last circling poses coincide, the middle one is opposite.
        let (first, last) = (circling[0].position, circling[20].position);
        assert!(first.distance(last) < 1e-2 * radius, "{first} {last}");
        let opposite = circling[10].position - sphere.centre;
        assert!(
            (opposite.truncate() + (first - sphere.centre).truncate()).length() < 1e-2 * radius
        );
    }

    #[test]
    fn every_pose_looks_at_the_city() {
        let c = city(true);
        let sphere = CitySphere::of(&c);
        let path = overview(&c, 24);
        for p in &path.poses {
            // At the centre itself, so well within the field of view.
            let off_axis = forward(p).angle_between(sphere.centre - p.position);
            assert!(off_axis < 1e-3, "{p:?} looks {off_axis} rad off the centre");
        }
    }
}
