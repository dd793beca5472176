//! Districts: how dense and how tall the city is at each place.
//!
//! Intensity is 1 at the main centre and falls off as a Gaussian of the distance; larger cities
//! get a few secondary centres. Each district (a cell of [`DISTRICT_CELL_M`]) scales its heights
//! by its own factor, so neighbouring districts of the same intensity still differ. The typical
//! height grows with the square of the intensity: a dense tall centre (≈ 80 m), mid-rise
//! inner districts and a low periphery (≈ 7 m), which is what gives street-level occlusion
//! culling something to do.

use geo::Coord;
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::layout::{hash, unit};
use super::polygon::length;

/// Side of a district cell (metres).
pub const DISTRICT_CELL_M: f64 = 600.0;
/// Typical height at zero intensity (metres): two storeys.
const PERIPHERY_HEIGHT_M: f64 = 7.0;
/// Typical height added at full intensity (metres).
const CENTRE_EXTRA_HEIGHT_M: f64 = 75.0;
const SALT_DISTRICT: u64 = 17;

#[derive(Debug, Clone)]
struct Centre {
    at: Coord<f64>,
    weight: f64,
    sigma_m: f64,
}

/// The intensity and height fields of one city.
#[derive(Debug, Clone)]
pub(crate) struct Districts {
    seed: u64,
    centres: Vec<Centre>,
}

impl Districts {
    /// Centres for a city of about `radius_m`.
    pub fn new(rng: &mut ChaCha8Rng, seed: u64, radius_m: f64) -> Districts {
        let mut centres = vec![Centre {
            at: Coord { x: 0.0, y: 0.0 },
            weight: 1.0,
            sigma_m: (0.42 * radius_m).max(150.0),
        }];
        // Secondary centres only where the city is large enough to have room for them.
        let secondary = if radius_m > 2_500.0 {
            rng.random_range(2..=5)
        } else {
            0
        };
        for _ in 0..secondary {
            let angle: f64 = rng.random_range(0.0..std::f64::consts::TAU);
            let distance_m = radius_m * rng.random_range(0.4..0.8);
            centres.push(Centre {
                at: Coord {
                    x: angle.cos() * distance_m,
                    y: angle.sin() * distance_m,
                },
                weight: rng.random_range(0.45..0.75),
                sigma_m: radius_m * rng.random_range(0.07..0.14),
            });
        }
        Districts { seed, centres }
    }

    /// Urban intensity in `[0, 1]` at `p`.
    pub fn intensity(&self, p: Coord<f64>) -> f64 {
        self.centres
            .iter()
            .map(|c| {
                let d = length(p - c.at) / c.sigma_m;
                c.weight * (-d * d).exp()
            })
            .fold(0.0, f64::max)
    }

    /// The height factor of the district containing `p`, in `[0.75, 1.3]`.
    pub fn factor(&self, p: Coord<f64>) -> f64 {
        let cx = (p.x / DISTRICT_CELL_M).floor() as i64;
        let cy = (p.y / DISTRICT_CELL_M).floor() as i64;
        0.75 + 0.55 * unit(hash(self.seed, SALT_DISTRICT, cx, cy))
    }

    /// The typical building height at `p` (metres): the "local height" landmarks are measured
    /// against.
    pub fn typical_height_m(&self, p: Coord<f64>) -> f64 {
        let i = self.intensity(p);
        (PERIPHERY_HEIGHT_M + CENTRE_EXTRA_HEIGHT_M * i * i) * self.factor(p)
    }
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;

    use super::*;

    #[test]
    fn centre_is_taller_than_periphery() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let d = Districts::new(&mut rng, 5, 5_000.0);
        let centre = d.typical_height_m(Coord { x: 10.0, y: 10.0 });
        let far = d.typical_height_m(Coord {
            x: 30_000.0,
            y: 0.0,
        });
        assert!(centre > 50.0 && far < 10.0, "{centre} {far}");
        assert!(d.intensity(Coord { x: 0.0, y: 0.0 }) > 0.99);
        assert!(d.centres.len() >= 3);
    }
}
