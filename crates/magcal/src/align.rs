//! The magnetometer's rotation against the body frame, which the field magnitude cannot see
//! (docs/magcal.md, "The rotation against the body"): a weighted Wahba problem between the
//! corrected magnetometer and the reference field carried into the body frame by an
//! attitude estimate.
//!
//! Convention: `m_corrected = Q B_body`, `Q = exp([phi x])` (rotation vector `phi`, rad);
//! the alignment removes it, `B_body = Q^T m_corrected`.

use nalgebra::{Matrix3, Rotation3, Vector3};

use crate::MagCalError;

/// One row for [`solve`].
#[derive(Debug, Clone, PartialEq)]
pub struct AlignSample {
    /// The corrected magnetometer reading, nT, sensor axes.
    pub measured_nt: Vector3<f64>,
    /// The reference field in the body frame (`A(q) B_ref`), nT.
    pub predicted_nt: Vector3<f64>,
    /// Variance of each axis of `measured - Q predicted`, nT^2: the magnetometer's noise and
    /// the attitude estimate's error times the field.
    pub variance_nt2: f64,
}

/// The estimated rotation `Q` with its covariance.
#[derive(Debug, Clone, PartialEq)]
pub struct Misalignment {
    /// `Q`, sensor axes from body axes.
    pub rotation: Matrix3<f64>,
    /// `Q`'s rotation vector, rad.
    pub angles_rad: Vector3<f64>,
    /// Covariance of `angles_rad` from the rows' independent errors, rad^2.
    pub covariance_rad2: Matrix3<f64>,
    /// Rows used.
    pub rows: usize,
    /// RMS of `|measured - Q predicted|` per axis after the fit, nT.
    pub residual_rms_nt: f64,
}

impl Misalignment {
    /// Rotates a corrected reading into the body frame, `Q^T m`.
    pub fn to_body(&self, measured_nt: &Vector3<f64>) -> Vector3<f64> {
        self.rotation.transpose() * measured_nt
    }

    /// One sigma of each rotation-vector component, rad.
    pub fn sigma_rad(&self) -> Vector3<f64> {
        self.covariance_rad2.diagonal().map(f64::sqrt)
    }
}

/// The rotation minimizing `sum |measured - Q predicted|^2 / variance` (Wahba's problem,
/// solved by the SVD of the attitude profile matrix, Markley's method), and its covariance
/// from the Fisher information: a small rotation `delta` of `Q` changes a residual by
/// `[Q p x] delta`, so `F = sum ([Q p x]^T [Q p x]) / variance`.
pub fn solve(samples: &[AlignSample]) -> Result<Misalignment, MagCalError> {
    if samples.len() < 2 {
        return Err(MagCalError::TooFewRows {
            rows: samples.len(),
            parameters: 3,
            needed: 2,
        });
    }
    let profile: Matrix3<f64> = samples
        .iter()
        .map(|s| s.measured_nt * s.predicted_nt.transpose() / s.variance_nt2)
        .sum();
    let svd = profile.svd(true, true);
    let (u, v_t) = svd
        .u
        .zip(svd.v_t)
        .ok_or_else(|| MagCalError::NotDetermined("the magnetometer's rotation".into()))?;
    let d = (u.determinant() * v_t.determinant()).signum();
    let rotation = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    let mut information = Matrix3::zeros();
    let mut sum_sq = 0.0;
    for s in samples {
        let qp = rotation * s.predicted_nt;
        let j = qp.cross_matrix();
        information += j.transpose() * j / s.variance_nt2;
        sum_sq += (s.measured_nt - qp).norm_squared();
    }
    // One field direction (or one plane's worth of rows that all agree) leaves a rotation
    // about it unseen: the information is then singular to rounding.
    let eigen = information.symmetric_eigenvalues();
    let covariance_rad2 = information
        .try_inverse()
        .filter(|_| eigen.min() > 1e-9 * eigen.max())
        .ok_or_else(|| MagCalError::NotDetermined("the magnetometer's rotation".into()))?;
    let angles_rad = Rotation3::from_matrix_unchecked(rotation).scaled_axis();
    Ok(Misalignment {
        rotation,
        angles_rad,
        covariance_rad2,
        rows: samples.len(),
        residual_rms_nt: (sum_sq / (3 * samples.len()) as f64).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand::rngs::ChaCha8Rng;
    use rand_distr::{Distribution, Normal, Uniform, UnitSphere};

    fn samples(q: &Matrix3<f64>, sigma: f64, n: usize, seed: u64) -> Vec<AlignSample> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let noise = Normal::new(0.0, sigma).unwrap();
        let magnitude = Uniform::new(20_000.0, 50_000.0).unwrap();
        (0..n)
            .map(|_| {
                let dir: [f64; 3] = UnitSphere.sample(&mut rng);
                let p = Vector3::from(dir) * magnitude.sample(&mut rng);
                let e = Vector3::from_fn(|_, _| noise.sample(&mut rng));
                AlignSample {
                    measured_nt: q * p + e,
                    predicted_nt: p,
                    variance_nt2: sigma * sigma,
                }
            })
            .collect()
    }

    /// The estimate is unbiased and its covariance describes its scatter: over 200 seeds the
    /// normalized errors have unit mean square per axis (within sampling), and a known rotation
    /// is recovered.
    #[test]
    fn recovers_a_rotation_with_a_covariance_that_covers_it() {
        let phi = Vector3::new(0.02, -0.01, 0.015);
        let q = *Rotation3::new(phi).matrix();
        let mut chi2 = 0.0;
        let seeds = 200;
        for seed in 0..seeds {
            let m = solve(&samples(&q, 300.0, 400, seed)).unwrap();
            let e = m.angles_rad - phi;
            chi2 += (e.transpose() * m.covariance_rad2.try_inverse().unwrap() * e)[0];
        }
        let mean = chi2 / seeds as f64;
        // chi-square with 3 dof: mean 3, the mean of 200 has sigma sqrt(6/200) = 0.17.
        assert!((mean - 3.0).abs() < 0.6, "mean chi2 {mean}");
    }

    /// The covariance is the inverse Fisher information: its diagonal matches the finite
    /// difference curvature of the weighted cost at the solution.
    #[test]
    fn covariance_is_the_cost_curvature() {
        let q = *Rotation3::new(Vector3::new(0.01, 0.02, -0.03)).matrix();
        let s = samples(&q, 300.0, 300, 7);
        let m = solve(&s).unwrap();
        let cost = |delta: Vector3<f64>| -> f64 {
            let r = Rotation3::new(delta).matrix() * m.rotation;
            s.iter()
                .map(|x| (x.measured_nt - r * x.predicted_nt).norm_squared() / x.variance_nt2)
                .sum::<f64>()
                / 2.0
        };
        let h = 1e-5;
        let information = m.covariance_rad2.try_inverse().unwrap();
        for a in 0..3 {
            let e = Vector3::from_fn(|i, _| if i == a { h } else { 0.0 });
            let curvature = (cost(e) - 2.0 * cost(Vector3::zeros()) + cost(-e)) / (h * h);
            let rel = (curvature - information[(a, a)]).abs() / information[(a, a)];
            assert!(
                rel < 1e-3,
                "axis {a}: {curvature} vs {}",
                information[(a, a)]
            );
        }
    }

    /// One field direction only cannot determine a rotation about it.
    #[test]
    fn a_single_direction_is_not_determined() {
        let p = Vector3::new(1.0, 2.0, 3.0) * 1e4;
        let s: Vec<AlignSample> = (0..10)
            .map(|_| AlignSample {
                measured_nt: p,
                predicted_nt: p,
                variance_nt2: 1e4,
            })
            .collect();
        assert!(solve(&s).is_err());
    }
}
