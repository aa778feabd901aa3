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
    /// Variance of each axis of `measured - Q predicted` that is not the attitude's, nT^2:
    /// the magnetometer's noise (and, where no attitude covariance is given, the attitude
    /// estimate's error times the field).
    pub variance_nt2: f64,
    /// Covariance of the attitude estimate's error about the body axes, rad^2 (zero when
    /// `variance_nt2` already holds it): a body-frame error `delta` moves the prediction by
    /// `[p x] delta`, so the residual's covariance is
    /// `variance_nt2 I + Q [p x] P [p x]^T Q^T`.
    pub attitude_cov_rad2: Matrix3<f64>,
}

impl AlignSample {
    /// The residual's covariance at the rotation `q`, nT^2.
    fn residual_cov(&self, q: &Matrix3<f64>) -> Matrix3<f64> {
        let px = q * self.predicted_nt.cross_matrix();
        Matrix3::identity() * self.variance_nt2 + px * self.attitude_cov_rad2 * px.transpose()
    }

    /// The residual's variance per axis for a scalar weight (Wahba's SVD), nT^2.
    fn scalar_variance(&self) -> f64 {
        self.residual_cov(&Matrix3::identity()).trace() / 3.0
    }
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
    /// Rows left out as outliers by [`solve_gated`] (0 from [`solve`]).
    pub rows_rejected: usize,
    /// Mean of `r^T C^-1 r / 3` over the rows used: 1 when the residuals are what the noise
    /// and the attitude covariance say, larger when they are not.
    pub normalized_residual: f64,
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

/// The polar decomposition `T = S Q` of a sensor matrix: `S = (T T^T)^(1/2)` symmetric
/// positive definite (what the field magnitude determines, pdcal's convention for `T`) and
/// `Q = S^-1 T` the rotation it cannot see; `None` for a singular `T`.
pub fn polar(t: &Matrix3<f64>) -> Option<(Matrix3<f64>, Matrix3<f64>)> {
    let e = (t * t.transpose()).symmetric_eigen();
    let s = e.eigenvectors
        * Matrix3::from_diagonal(&e.eigenvalues.map(|v| v.max(0.0).sqrt()))
        * e.eigenvectors.transpose();
    let q = s.try_inverse()? * t;
    Some((s, q))
}

/// The rotation minimizing `sum r^T C^-1 r`, `r = measured - Q predicted` and `C` each
/// row's residual covariance: Wahba's problem with scalar weights `tr C / 3`, solved by the
/// SVD of the attitude profile matrix (Markley's method), then Gauss-Newton steps with the
/// whole `C` (a small rotation `delta` of `Q` changes a residual by `[Q p x] delta`). The
/// covariance is the inverse Fisher information `F = sum [Q p x]^T C^-1 [Q p x]`.
pub fn solve(samples: &[AlignSample]) -> Result<Misalignment, MagCalError> {
    let used = vec![true; samples.len()];
    solve_rows(samples, &used)
}

/// Median of chi-square with 3 degrees of freedom: the robust scale of `r^T C^-1 r`.
const CHI2_3_MEDIAN: f64 = 2.365_973_884_375_338;

/// `r^T C^-1 r` beyond which a row is an outlier: chi-square with 3 degrees of freedom at the
/// two-sided 5-sigma tail of a normal (5.7e-7), the gate the magnitude fit uses.
const GATE_CHI2_3: f64 = 31.81;

/// [`solve`] for rows in time order with outlier rows (an attitude estimate far from the
/// truth, a spike) left out, and a covariance that counts errors correlated in time: rows
/// whose `r^T C^-1 r`, scaled by its median over the rows (against chi-square's median with
/// 3 degrees of freedom), lies beyond [`GATE_CHI2_3`] are dropped and the rotation solved
/// again, until the rows left out no longer change (at most 8 passes); then
/// [`with_batch_covariance`].
pub fn solve_gated(samples: &[AlignSample]) -> Result<Misalignment, MagCalError> {
    let mut used = vec![true; samples.len()];
    let mut fit = solve_rows(samples, &used)?;
    for _ in 0..8 {
        let d2: Vec<f64> = samples
            .iter()
            .map(|s| distance2(s, &fit.rotation))
            .collect();
        let mut sorted = d2.clone();
        sorted.sort_by(f64::total_cmp);
        let scale = sorted[sorted.len() / 2] / CHI2_3_MEDIAN;
        let next: Vec<bool> = d2.iter().map(|d| *d <= GATE_CHI2_3 * scale).collect();
        if next == used {
            break;
        }
        used = next;
        fit = solve_rows(samples, &used)?;
    }
    Ok(with_batch_covariance(samples, &used, fit))
}

/// Blocks of consecutive rows for [`with_batch_covariance`].
pub const BATCHES: usize = 8;

/// `fit` (of the `used` rows of `samples`, in time order) with a covariance that also holds errors correlated in
/// time: the Fisher covariance treats every row's attitude error as independent, but an
/// estimated attitude's errors last as long as the geometry that caused them. The rows kept
/// are cut into [`BATCHES`] blocks of consecutive rows, each solved alone; the scatter of
/// the blocks' rotations over `BATCHES (BATCHES - 1)` is the method of batch means' covariance
/// of their mean, which counts correlations shorter than a block. The larger of the two (by
/// trace) is kept. A block the data do not determine alone leaves the Fisher covariance.
fn with_batch_covariance(
    samples: &[AlignSample],
    used: &[bool],
    mut fit: Misalignment,
) -> Misalignment {
    let kept: Vec<usize> = (0..samples.len()).filter(|&k| used[k]).collect();
    let block = kept.len() / BATCHES;
    if block < 2 {
        return fit;
    }
    let mut angles = Vec::with_capacity(BATCHES);
    for b in 0..BATCHES {
        let mut used = vec![false; samples.len()];
        for &k in &kept[b * block..(b + 1) * block] {
            used[k] = true;
        }
        let Ok(part) = solve_rows(samples, &used) else {
            return fit;
        };
        // The block's rotation relative to the whole fit's, as a small rotation vector.
        let relative = Rotation3::from_matrix_unchecked(part.rotation * fit.rotation.transpose());
        angles.push(relative.scaled_axis());
    }
    let mean = angles.iter().sum::<Vector3<f64>>() / BATCHES as f64;
    let batch: Matrix3<f64> = angles
        .iter()
        .map(|a| (a - mean) * (a - mean).transpose())
        .sum::<Matrix3<f64>>()
        / (BATCHES * (BATCHES - 1)) as f64;
    if batch.trace() > fit.covariance_rad2.trace() {
        fit.covariance_rad2 = batch;
    }
    fit
}

/// `r^T C^-1 r` of one row at `q`.
fn distance2(s: &AlignSample, q: &Matrix3<f64>) -> f64 {
    let r = s.measured_nt - q * s.predicted_nt;
    let c = s.residual_cov(q);
    c.try_inverse()
        .map_or(f64::INFINITY, |ci| (r.transpose() * ci * r)[0])
}

fn solve_rows(samples: &[AlignSample], used: &[bool]) -> Result<Misalignment, MagCalError> {
    let rows: Vec<&AlignSample> = (samples.iter().zip(used))
        .filter(|(_, u)| **u)
        .map(|(s, _)| s)
        .collect();
    if rows.len() < 2 {
        return Err(MagCalError::TooFewRows {
            rows: rows.len(),
            parameters: 3,
            needed: 2,
        });
    }
    let not_determined = || MagCalError::NotDetermined("the magnetometer's rotation".into());
    let profile: Matrix3<f64> = rows
        .iter()
        .map(|s| s.measured_nt * s.predicted_nt.transpose() / s.scalar_variance())
        .sum();
    let svd = profile.svd(true, true);
    let (u, v_t) = svd.u.zip(svd.v_t).ok_or_else(not_determined)?;
    let d = (u.determinant() * v_t.determinant()).signum();
    let mut rotation = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * v_t;
    let mut information = Matrix3::zeros();
    for _ in 0..10 {
        let (f, g) = normal_equations(&rows, &rotation);
        information = f;
        // One field direction (or one plane's worth of rows that all agree) leaves a
        // rotation about it unseen: the information is then singular to rounding.
        let eigen = information.symmetric_eigenvalues();
        let inverse = information
            .try_inverse()
            .filter(|_| eigen.min() > 1e-9 * eigen.max())
            .ok_or_else(not_determined)?;
        let delta = -(inverse * g);
        rotation = Rotation3::new(delta).matrix() * rotation;
        if delta.norm() < 1e-12 {
            break;
        }
    }
    let covariance_rad2 = information.try_inverse().ok_or_else(not_determined)?;
    let sum_sq: f64 = rows
        .iter()
        .map(|s| (s.measured_nt - rotation * s.predicted_nt).norm_squared())
        .sum();
    let normalized: f64 = rows.iter().map(|s| distance2(s, &rotation)).sum::<f64>();
    let angles_rad = Rotation3::from_matrix_unchecked(rotation).scaled_axis();
    Ok(Misalignment {
        rotation,
        angles_rad,
        covariance_rad2,
        rows: rows.len(),
        residual_rms_nt: (sum_sq / (3 * rows.len()) as f64).sqrt(),
        rows_rejected: samples.len() - rows.len(),
        normalized_residual: normalized / (3 * rows.len()) as f64,
    })
}

/// The Gauss-Newton normal equations at `q`: the information `sum J^T C^-1 J` and the
/// gradient `sum J^T C^-1 r`, `J = [Q p x]` the residual's derivative with respect to a
/// small rotation `delta` of `Q` (`r(delta) = r + J delta`).
fn normal_equations(rows: &[&AlignSample], q: &Matrix3<f64>) -> (Matrix3<f64>, Vector3<f64>) {
    let mut f = Matrix3::zeros();
    let mut g = Vector3::zeros();
    for s in rows {
        let qp = q * s.predicted_nt;
        let j = qp.cross_matrix();
        let Some(ci) = s.residual_cov(q).try_inverse() else {
            continue;
        };
        let r = s.measured_nt - qp;
        f += j.transpose() * ci * j;
        g += j.transpose() * ci * r;
    }
    (f, g)
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
                    attitude_cov_rad2: Matrix3::zeros(),
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
                attitude_cov_rad2: Matrix3::zeros(),
            })
            .collect();
        assert!(solve(&s).is_err());
    }

    /// Rows whose prediction carries an attitude error drawn from an anisotropic covariance
    /// (large about one axis, as a Sun-only attitude about the Sun line): the fit with the
    /// whole covariance recovers the rotation and its covariance describes the scatter.
    #[test]
    fn an_anisotropic_attitude_covariance_is_weighed_and_covered() {
        let phi = Vector3::new(-0.012, 0.009, 0.02);
        let q = *Rotation3::new(phi).matrix();
        let sigma = 300.0;
        let attitude_cov = Matrix3::from_diagonal(&Vector3::new(1e-6, 1e-6, 4e-4));
        let chol = attitude_cov.cholesky().unwrap().l();
        let mut chi2 = 0.0;
        let seeds = 200;
        for seed in 0..seeds {
            let mut rng = ChaCha8Rng::seed_from_u64(1000 + seed);
            let normal = Normal::new(0.0, 1.0).unwrap();
            let mut s = samples(&q, sigma, 300, seed);
            for x in &mut s {
                let delta = chol * Vector3::from_fn(|_, _| normal.sample(&mut rng));
                // The estimate's attitude is off by delta: its prediction of the true
                // (body-frame) field moves by [p x] delta.
                x.predicted_nt += x.predicted_nt.cross_matrix() * delta;
                x.attitude_cov_rad2 = attitude_cov;
            }
            let m = solve(&s).unwrap();
            let e = m.angles_rad - phi;
            chi2 += (e.transpose() * m.covariance_rad2.try_inverse().unwrap() * e)[0];
            assert!(
                (m.normalized_residual - 1.0).abs() < 0.15,
                "{}",
                m.normalized_residual
            );
        }
        let mean = chi2 / seeds as f64;
        assert!((mean - 3.0).abs() < 0.6, "mean chi2 {mean}");
    }

    /// A tenth of the rows with a wrong attitude (half a turn about a random axis) are left
    /// out, counted, and the rotation is the one the other rows give.
    #[test]
    fn rows_with_a_wrong_attitude_are_left_out() {
        let phi = Vector3::new(0.01, 0.015, -0.02);
        let q = *Rotation3::new(phi).matrix();
        let mut s = samples(&q, 300.0, 400, 11);
        let wrong = *Rotation3::new(Vector3::new(0.3, -2.0, 1.2)).matrix();
        for x in s.iter_mut().step_by(10) {
            x.predicted_nt = wrong * x.predicted_nt;
        }
        let plain = solve(&s).unwrap();
        let gated = solve_gated(&s).unwrap();
        assert_eq!(gated.rows_rejected, 40);
        let z = (gated.angles_rad - phi).component_div(&gated.sigma_rad());
        assert!(z.abs().max() < 4.0, "{z}");
        assert!(plain.normalized_residual > 10.0 * gated.normalized_residual);
    }

    /// `T = S Q` with `S` symmetric and `Q` a rotation, for a `T` built that way.
    #[test]
    fn polar_splits_a_symmetric_factor_and_a_rotation() {
        let s0 = Matrix3::new(1.03, 0.02, -0.01, 0.02, 0.98, 0.04, -0.01, 0.04, 1.05);
        let q0 = *Rotation3::new(Vector3::new(0.01, -0.02, 0.015)).matrix();
        let (s, q) = polar(&(s0 * q0)).unwrap();
        assert!((s - s0).abs().max() < 1e-12);
        assert!((q - q0).abs().max() < 1e-12);
    }
}
