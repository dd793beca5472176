//! The sphere around a city: the centre and diameter of its buildings' bounding box. It is the
//! unit of "far" for views of the whole city — Chang et al. 2008 §9, Fig. 14, whose overview
//! camera "starts far away from the city", where a legible simplification draws a small share
//! of the polygons — so the overview path that flies there and the benchmark that reports those
//! frames measure distance the same way.

use glam::Vec3;

use crate::city::City;

/// The sphere through the corners of a city's bounding box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CitySphere {
    /// The centre of the bounding box (mid-height), what an overview looks at.
    pub centre: Vec3,
    /// The bounding box's diagonal (metres), at least the city's diameter (the largest distance
    /// between two of its points; √2 times it for a round city): a camera farther than this
    /// from the centre sees every building at least half a diameter away.
    pub diameter_m: f32,
}

impl CitySphere {
    /// The sphere of the box `lo`..`hi` (metres, local frame).
    pub fn of_bounds(lo: Vec3, hi: Vec3) -> CitySphere {
        CitySphere {
            centre: 0.5 * (lo + hi),
            diameter_m: (hi - lo).length(),
        }
    }

    /// The sphere of `city`'s buildings; a 1 m sphere at the origin for a city without any.
    pub fn of(city: &City) -> CitySphere {
        match city.bounds() {
            Some((lo, hi)) => CitySphere::of_bounds(lo, hi),
            None => CitySphere {
                centre: Vec3::ZERO,
                diameter_m: 1.0,
            },
        }
    }

    /// How far `eye` is from the centre, in diameters (0 for a city of no extent).
    pub fn distance_in_diameters(&self, eye: Vec3) -> f32 {
        if self.diameter_m > 0.0 {
            eye.distance(self.centre) / self.diameter_m
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_diameter_and_distance() {
        let s = CitySphere::of_bounds(Vec3::new(0.0, 0.0, 0.0), Vec3::new(300.0, 400.0, 0.0));
        assert_eq!(s.centre, Vec3::new(150.0, 200.0, 0.0));
        assert_eq!(s.diameter_m, 500.0);
        assert_eq!(
            s.distance_in_diameters(Vec3::new(150.0, 200.0, 1000.0)),
            2.0
        );
        assert_eq!(s.distance_in_diameters(s.centre), 0.0);
        let point = CitySphere::of_bounds(Vec3::ONE, Vec3::ONE);
        assert_eq!(point.distance_in_diameters(Vec3::ZERO), 0.0);
    }
}
