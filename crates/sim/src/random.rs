//! Seeded randomness: one seed, independent streams per purpose.
//!
//! Every stream is ChaCha8 keyed by the user's seed with a fixed stream number (the ChaCha
//! nonce), so streams are independent and drawing more from one (say, a faster gyro) never
//! shifts another (the photodiode noise). ChaCha8 is used rather than `StdRng` because its
//! output is fixed by the algorithm, so the same seed gives the same numbers in every rand
//! version.

use nalgebra::{Vector3, Vector4};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::scenario::Spread;

/// What a stream is for; the discriminant is the ChaCha stream number.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Stream {
    /// True photodiode scale factors and mounting errors.
    TruePhotodiodes = 1,
    /// Initial attitude and rate.
    InitialState = 2,
    /// Initial gyro bias.
    GyroBias = 3,
    /// Gyro white noise.
    GyroNoise = 4,
    /// Gyro bias random walk.
    GyroWalk = 5,
    /// Magnetometer white noise.
    MagNoise = 6,
    /// Photodiode output noise.
    PhotodiodeNoise = 7,
    /// Temperature sensor noise.
    TemperatureNoise = 8,
    /// True magnetometer errors (hardware, like the photodiodes).
    MagHardware = 9,
}

/// Streams per downlink: room for every [`Stream`] with spares.
const STREAMS_PER_DOWNLINK: u64 = 16;

/// A run's randomness: the user's seed, and which downlink of that spacecraft it is.
///
/// The hardware (true scale factors and mountings) comes from the seed alone, so every
/// downlink of a seed flies the same photodiodes; everything else (initial attitude and
/// rate, turn-on gyro bias, every sensor's noise) is drawn afresh per downlink, as for real
/// passes recorded weeks apart. Downlink 0 is the plain seeded run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Seed {
    pub(crate) seed: u64,
    pub(crate) downlink: u64,
}

impl Seed {
    /// The generator of one stream.
    pub(crate) fn stream(self, which: Stream) -> ChaCha8Rng {
        let number = match which {
            Stream::TruePhotodiodes | Stream::MagHardware => which as u64,
            _ => which as u64 + STREAMS_PER_DOWNLINK * self.downlink,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
        rng.set_stream(number);
        rng
    }
}

/// The generator of one stream of downlink 0.
#[cfg(test)]
pub(crate) fn stream(seed: u64, which: Stream) -> ChaCha8Rng {
    Seed { seed, downlink: 0 }.stream(which)
}

/// One standard normal draw.
pub(crate) fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

/// Three independent standard normal draws.
pub(crate) fn normal3(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    Vector3::new(normal(rng), normal(rng), normal(rng))
}

/// A draw from a scenario distribution.
pub(crate) fn draw(spread: &Spread, rng: &mut ChaCha8Rng) -> f64 {
    match *spread {
        Spread::Fixed(v) => v,
        Spread::Uniform { min, max } => {
            let u: f64 = rand::RngExt::random(rng);
            min + (max - min) * u
        }
        Spread::Normal { mean, sigma } => mean + sigma * normal(rng),
    }
}

/// A direction uniform on the unit sphere (normalised Gaussian triple).
pub(crate) fn unit_vector(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    loop {
        // The norm is zero with probability 0; the loop only guards the impossible case.
        if let Some(v) = normal3(rng).try_normalize(1e-12) {
            return v;
        }
    }
}

/// A quaternion uniform on SO(3) (normalised Gaussian 4-vector), `[x, y, z, w]`.
pub(crate) fn uniform_quaternion(rng: &mut ChaCha8Rng) -> Vector4<f64> {
    loop {
        let v = Vector4::new(normal(rng), normal(rng), normal(rng), normal(rng));
        if let Some(q) = v.try_normalize(1e-12) {
            return q;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_numbers_and_streams_differ() {
        let a: Vec<f64> = (0..5)
            .map(|_| normal(&mut stream(7, Stream::GyroNoise)))
            .collect();
        let mut s1 = stream(7, Stream::GyroNoise);
        let mut s2 = stream(7, Stream::GyroNoise);
        let mut other = stream(7, Stream::MagNoise);
        let x: Vec<f64> = (0..5).map(|_| normal(&mut s1)).collect();
        let y: Vec<f64> = (0..5).map(|_| normal(&mut s2)).collect();
        let z: Vec<f64> = (0..5).map(|_| normal(&mut other)).collect();
        assert_eq!(x, y);
        assert_ne!(x, z);
        assert_eq!(a[0], x[0]);
    }

    #[test]
    fn uniform_spread_stays_in_bounds_and_normal_has_its_moments() {
        let mut rng = stream(1, Stream::TruePhotodiodes);
        let u = Spread::Uniform { min: 3.5, max: 3.9 };
        assert!(
            (0..10_000)
                .map(|_| draw(&u, &mut rng))
                .all(|v| (3.5..=3.9).contains(&v))
        );
        // 20 000 draws: the sample mean has sigma 2/sqrt(2e4) = 0.014, the sample sigma
        // ~ 2/sqrt(4e4) = 0.01; 5-sigma bounds.
        let n = Spread::Normal {
            mean: 1.0,
            sigma: 2.0,
        };
        let xs: Vec<f64> = (0..20_000).map(|_| draw(&n, &mut rng)).collect();
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (xs.len() - 1) as f64;
        assert!((mean - 1.0).abs() < 0.07, "{mean}");
        assert!((var.sqrt() - 2.0).abs() < 0.05, "{}", var.sqrt());
    }
}
