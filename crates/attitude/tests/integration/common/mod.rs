//! Seeded random inputs shared by the integration tests.
#![allow(dead_code)]

use nalgebra::Vector3;
use pdcal_attitude::Quat;
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;

/// A seeded generator, so every run draws the same numbers.
pub fn rng(seed: u64) -> StdRng {
    StdRng::seed_from_u64(seed)
}

/// A standard-normal 3-vector.
pub fn gaussian3(rng: &mut StdRng) -> Vector3<f64> {
    Vector3::new(
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
    )
}

/// A direction uniform on the sphere.
pub fn unit3(rng: &mut StdRng) -> Vector3<f64> {
    gaussian3(rng).normalize()
}

/// An attitude uniform on SO(3) (normalised 4-D Gaussian).
pub fn quat(rng: &mut StdRng) -> Quat {
    loop {
        let g = gaussian3(rng);
        let w: f64 = rng.sample(StandardNormal);
        if let Some(q) = Quat::new_normalized(g.x, g.y, g.z, w) {
            return q;
        }
    }
}

/// Uniform in `[lo, hi)`.
pub fn uniform(rng: &mut StdRng, lo: f64, hi: f64) -> f64 {
    rng.random_range(lo..hi)
}
