//! Building blocks of the multiplicative extended Kalman filter (MEKF) for attitude
//! and gyro bias: the attitude-error vector and its reset, discrete quaternion
//! propagation, and the 6x6 discrete state-transition and process-noise matrices.
//!
//! Sources: Lefferts, Markley & Shuster, "Kalman Filtering for Spacecraft Attitude
//! Estimation", JGCD 5(5), 1982 (the multiplicative error and the 6-state filter);
//! Markley & Crassidis, *Fundamentals of Spacecraft Attitude Determination and
//! Control*, 2014, Sec. 6.2 (written MC below); Crassidis & Junkins, *Optimal
//! Estimation of Dynamic Systems*, 2nd ed., 2012, Sec. 7.2 (written CJ below).
//!
//! # Error convention
//!
//! The true attitude is the estimate rotated by a small error rotation:
//!
//! ```text
//! q_true = dq(a) ⊗ q_est,        A(q_true) = A(dq(a)) A(q_est),
//! ```
//!
//! with `⊗` Markley's product ([`Quat::compose`]). The error vector `a` is the
//! **rotation vector** (axis times angle, radians, body frame):
//! `dq(a) = [sin(|a|/2) a/|a|, cos(|a|/2)]`, so `A(dq(a)) = exp(-[a x])` and the
//! error rotation angle is exactly `|a|`. To first order this equals MC's `2 x Gibbs
//! vector` and CJ's `2 dq_v`, so the linear matrices below are the same for all three
//! choices. With this definition `A(q_true) s ≈ (I - [a x]) A(q_est) s`, hence
//! `d(A s)/d a = [(A s) x]` ([`body_vector_partial`]), the form of paper Eq. (20).
//!
//! The multiplicative reset after a measurement update is `q+ = dq(a+) ⊗ q-`
//! ([`apply_error`]), after which `a` is set back to zero.
//!
//! # Error dynamics (MC Sec. 6.2; CJ Sec. 7.2.1)
//!
//! With the gyro model `omega_meas = omega + beta + eta_v`, `beta' = eta_u` and
//! `omega_est = omega_meas - beta_est`, the state `x = [a; dbeta]` with
//! `dbeta = beta_true - beta_est` obeys
//!
//! ```text
//! x' = F x + G w,   F = [ -[omega_est x]  -I ],   G = [ -I  0 ],   w = [eta_v; eta_u],
//!                       [  0               0 ]        [  0  I ]
//! E[w w^T] = diag(sigma_v^2 I, sigma_u^2 I).
//! ```

use nalgebra::{Matrix3, Matrix6, Vector3};
use serde::{Deserialize, Serialize};

use crate::{Quat, skew};

/// Below this value of `|omega| dt` (radians) the trigonometric coefficients are
/// evaluated by their Taylor series. The direct forms lose about `eps / x^4` in
/// relative precision (the worst one, [`process_noise`]'s `Q11` coefficient, cancels to
/// `x^5 / 60`), i.e. 2e-15 at `x = 0.5`; the series kept to `x^12` is exact to
/// rounding there (first neglected term below 1e-16 relative).
pub const SERIES_THRESHOLD_RAD: f64 = 0.5;

/// Gyro noise densities of the standard (Farrenkopf) model used by the MEKF.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GyroNoise {
    /// Angle random walk `sigma_v`, rad/s^0.5 (rate white-noise density).
    pub sigma_v_rad_sqrt_s: f64,
    /// Bias (rate) random walk `sigma_u`, rad/s^1.5.
    pub sigma_u_rad_s_sqrt_s: f64,
}

/// The error quaternion `dq(a)` of a rotation-vector error `a` (radians):
/// `[sin(|a|/2) a/|a|, cos(|a|/2)]`, exact for any size, `A(dq(a)) = exp(-[a x])`.
pub fn error_quat(a: &Vector3<f64>) -> Quat {
    let half_angle = 0.5 * a.norm();
    // sin(h) / (2 h) written as 0.5 * sinc(h) so that a = 0 is regular.
    let scale = 0.5 * alternating_series_or(half_angle, 1, |h| h.sin() / h);
    Quat {
        x: scale * a.x,
        y: scale * a.y,
        z: scale * a.z,
        w: half_angle.cos(),
    }
}

/// The multiplicative reset `q+ = dq(a) ⊗ q-` (Lefferts, Markley & Shuster 1982;
/// MC Sec. 6.2 with the rotation vector in place of `2 x Gibbs`), renormalised.
pub fn apply_error(q_est: &Quat, a: &Vector3<f64>) -> Quat {
    normalized(&error_quat(a).compose(q_est))
}

/// Largest `|a|` (radians) for which [`apply_small_error`] uses its short series.
pub const SMALL_ERROR_RAD: f64 = 0.1;

/// [`apply_error`] for the small corrections of one scalar measurement update, cheaper: for
/// `|a| < SMALL_ERROR_RAD` the half-angle sine and cosine come from their Taylor series to
/// `h^8` (`h = |a|/2 < 0.05`: the first neglected terms, `h^10/10!` and `h^10/11!`, are below
/// 3e-20, far under the rounding of the product), the product `dq(a) ⊗ q` is written out and
/// normalised once (no libm call, one square root). Agrees with [`apply_error`] to rounding
/// (a test holds them to 1e-15 per component); larger or non-finite `a` go to
/// [`apply_error`] itself.
#[inline]
pub fn apply_small_error(q_est: &Quat, a: &Vector3<f64>) -> Quat {
    let h2 = 0.25 * a.norm_squared();
    // NaN fails the comparison and goes to the exact form too.
    let small = h2 < 0.25 * SMALL_ERROR_RAD * SMALL_ERROR_RAD;
    // sin(h)/h and cos(h) of the half angle.
    let Some((sinc, cos)) = crate::series::sinc_and_cos(h2).filter(|_| small) else {
        return apply_error(q_est, a);
    };
    let s = 0.5 * sinc;
    let (dx, dy, dz, dw) = (s * a.x, s * a.y, s * a.z, cos);
    let q = q_est;
    // Markley's dq ⊗ q is the Hamilton product q dq ([`Quat::compose`]).
    let product = Quat {
        x: q.w * dx + dw * q.x + (q.y * dz - q.z * dy),
        y: q.w * dy + dw * q.y + (q.z * dx - q.x * dz),
        z: q.w * dz + dw * q.z + (q.x * dy - q.y * dx),
        w: q.w * dw - (q.x * dx + q.y * dy + q.z * dz),
    };
    normalized(&product)
}

/// The rotation-vector error `a` with `A(q_true) = A(dq(a)) A(q_est)`, the inverse of
/// [`apply_error`]; `|a|` is in `[0, pi]` (the short way round).
pub fn error_vector(q_true: &Quat, q_est: &Quat) -> Vector3<f64> {
    let dq = q_true.compose(&q_est.inverse()).canonical();
    let sin_half = dq.vector().norm();
    let angle = 2.0 * sin_half.atan2(dq.w);
    if sin_half > 0.0 {
        dq.vector() * (angle / sin_half)
    } else {
        Vector3::zeros()
    }
}

/// Sensitivity of a body-frame vector to the attitude error:
/// `d(A(q) v_I)/d a = [(A(q) v_I) x]`, evaluated at `a = 0` (the matrix in paper Eq. 20).
pub fn body_vector_partial(q_est: &Quat, v_inertial: &Vector3<f64>) -> Matrix3<f64> {
    skew(&q_est.to_body(v_inertial))
}

/// Propagates the attitude over `dt_s` for a body rate constant over the step:
/// `q(t + dt) = dq(omega dt) ⊗ q(t)`, the closed-form solution of
/// `A' = -[omega x] A` (MC Sec. 6.2.4; CJ Sec. 7.2.1 writes the same product as
/// `Omega-bar(omega) q`). Exactly norm preserving; the result is renormalised
/// against rounding drift. A non-finite rate gives a non-finite quaternion.
pub fn propagate(q: &Quat, rate_body_rad_s: &Vector3<f64>, dt_s: f64) -> Quat {
    apply_error(q, &(rate_body_rad_s * dt_s))
}

/// Continuous error-dynamics matrix `F` of the module docs (MC Sec. 6.2; CJ Sec. 7.2.1),
/// for the bias-corrected rate estimate `omega_est`.
pub fn error_dynamics_matrix(rate_body_rad_s: &Vector3<f64>) -> Matrix6<f64> {
    let mut f = Matrix6::zeros();
    f.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-skew(rate_body_rad_s)));
    f.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(-Matrix3::identity()));
    f
}

/// Noise gain `G` of the module docs (CJ Sec. 7.2.1): `diag(-I, I)`.
pub fn noise_gain() -> Matrix6<f64> {
    let mut g = Matrix6::identity();
    g.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(-Matrix3::identity()));
    g
}

/// Discrete state-transition matrix `Phi = exp(F dt)` of `[a; dbeta]` for a rate
/// constant over the step, in closed form (CJ Eqs. 7.43-7.45; MC Sec. 6.2.4). With
/// `W = [omega x]`, `w = |omega|`, `x = w dt`:
///
/// ```text
/// Phi11 = I - W sin(x)/w + W^2 (1 - cos x)/w^2
/// Phi12 = -I dt + W (1 - cos x)/w^2 - W^2 (x - sin x)/w^3
/// Phi21 = 0,  Phi22 = I
/// ```
///
/// Coefficients switch to Taylor series below [`SERIES_THRESHOLD_RAD`].
pub fn state_transition(rate_body_rad_s: &Vector3<f64>, dt_s: f64) -> Matrix6<f64> {
    let w = skew(rate_body_rad_s);
    let w2 = w * w;
    let x = rate_body_rad_s.norm() * dt_s;
    let (c1, c2, c3) = (
        sin_x_over_x(x),
        one_minus_cos_over_x2(x),
        x_minus_sin_over_x3(x),
    );
    let phi11 = Matrix3::identity() - w * (dt_s * c1) + w2 * (dt_s * dt_s * c2);
    let phi12 = -Matrix3::identity() * dt_s + w * (dt_s * dt_s * c2) - w2 * (dt_s.powi(3) * c3);
    let mut phi = Matrix6::identity();
    phi.fixed_view_mut::<3, 3>(0, 0).copy_from(&phi11);
    phi.fixed_view_mut::<3, 3>(0, 3).copy_from(&phi12);
    phi
}

/// Discrete process-noise matrix `Qd = int_0^dt Phi(t) G Q G^T Phi(t)^T dt` in closed
/// form for a constant rate (MC Sec. 6.2.4; CJ Eq. 7.46 gives its rate-free
/// approximation, the `I` terms below). With `W`, `w`, `x` as in [`state_transition`]:
///
/// ```text
/// Q11 = sigma_v^2 dt I + sigma_u^2 [ dt^3/3 I + (x^3/3 + 2 sin x - 2 x)/w^5 W^2 ]
/// Q12 = -sigma_u^2 [ dt^2/2 I - (x - sin x)/w^3 W + (x^2/2 + cos x - 1)/w^4 W^2 ]
/// Q21 = Q12^T,  Q22 = sigma_u^2 dt I
/// ```
///
/// Symmetric by construction; positive definite for `sigma_u > 0`, `dt > 0`.
pub fn process_noise(rate_body_rad_s: &Vector3<f64>, dt_s: f64, noise: &GyroNoise) -> Matrix6<f64> {
    let var_v = noise.sigma_v_rad_sqrt_s.powi(2);
    let var_u = noise.sigma_u_rad_s_sqrt_s.powi(2);
    let w = skew(rate_body_rad_s);
    let w2 = w * w;
    let x = rate_body_rad_s.norm() * dt_s;
    let id = Matrix3::identity();
    let q11 = id * (var_v * dt_s)
        + (id * (dt_s.powi(3) / 3.0) + w2 * (dt_s.powi(5) * q11_coefficient(x))) * var_u;
    let q12 = -(id * (dt_s * dt_s / 2.0) - w * (dt_s.powi(3) * x_minus_sin_over_x3(x))
        + w2 * (dt_s.powi(4) * q12_coefficient(x)))
        * var_u;
    let mut qd = Matrix6::zeros();
    qd.fixed_view_mut::<3, 3>(0, 0).copy_from(&q11);
    qd.fixed_view_mut::<3, 3>(0, 3).copy_from(&q12);
    qd.fixed_view_mut::<3, 3>(3, 0).copy_from(&q12.transpose());
    qd.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(id * (var_u * dt_s)));
    qd
}

/// `sin(x)/x`.
fn sin_x_over_x(x: f64) -> f64 {
    alternating_series_or(x, 1, |x| x.sin() / x)
}

/// `(1 - cos x)/x^2`.
fn one_minus_cos_over_x2(x: f64) -> f64 {
    alternating_series_or(x, 2, |x| (1.0 - x.cos()) / (x * x))
}

/// `(x - sin x)/x^3`.
fn x_minus_sin_over_x3(x: f64) -> f64 {
    alternating_series_or(x, 3, |x| (x - x.sin()) / x.powi(3))
}

/// `(x^2/2 + cos x - 1)/x^4`.
fn q12_coefficient(x: f64) -> f64 {
    alternating_series_or(x, 4, |x| (0.5 * x * x + x.cos() - 1.0) / x.powi(4))
}

/// `(x^3/3 + 2 sin x - 2 x)/x^5`, twice the `k = 5` series.
fn q11_coefficient(x: f64) -> f64 {
    if x.abs() < SERIES_THRESHOLD_RAD {
        2.0 * alternating_series(x, 5)
    } else {
        (x.powi(3) / 3.0 + 2.0 * x.sin() - 2.0 * x) / x.powi(5)
    }
}

/// The closed form `direct(|x|)`, or below [`SERIES_THRESHOLD_RAD`] its Taylor series
/// [`alternating_series`] with the same `k`.
fn alternating_series_or(x: f64, k: u32, direct: impl Fn(f64) -> f64) -> f64 {
    if x.abs() < SERIES_THRESHOLD_RAD {
        alternating_series(x, k)
    } else {
        direct(x.abs())
    }
}

/// `sum_{j=0..6} (-1)^j x^(2j) / (2j + k)!`: every coefficient in this module is one
/// of these (`sin x/x` is `k = 1`, `(1 - cos x)/x^2` is `k = 2`, and so on).
fn alternating_series(x: f64, k: u32) -> f64 {
    let x2 = x * x;
    let mut term = 1.0 / (1..=k).map(f64::from).product::<f64>();
    let mut sum = term;
    for j in 1..=6u32 {
        let n = f64::from(2 * j + k);
        term *= -x2 / ((n - 1.0) * n);
        sum += term;
    }
    sum
}

fn normalized(q: &Quat) -> Quat {
    let n = q.norm();
    Quat {
        x: q.x / n,
        y: q.y / n,
        z: q.z / n,
        w: q.w / n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_error_reset_matches_the_exact_one() {
        // Deterministic spread of attitudes and corrections up to the threshold (and past
        // it, where the exact form is used): components agree to rounding. 1e-15 is a few
        // ulps of unit components (the two forms round differently: libm sin/cos and
        // nalgebra's normalised product against the series and one normalisation).
        let mut worst: f64 = 0.0;
        for i in 0..2000 {
            let f = i as f64;
            let q = Quat::new_normalized(
                (0.7 * f).sin(),
                (1.3 * f + 0.4).cos(),
                (2.1 * f).sin() - 0.3,
                (0.37 * f).cos() + 0.2,
            )
            .expect("non-zero");
            let dir = Vector3::new((3.1 * f).sin(), (1.7 * f).cos(), (0.9 * f + 1.0).sin());
            let size = SMALL_ERROR_RAD * 1.2 * ((i % 97) as f64 / 96.0).powi(3);
            let a = dir.normalize() * size;
            let (fast, exact) = (apply_small_error(&q, &a), apply_error(&q, &a));
            let d = [
                fast.x - exact.x,
                fast.y - exact.y,
                fast.z - exact.z,
                fast.w - exact.w,
            ];
            worst = d.iter().fold(worst, |w, x| w.max(x.abs()));
            assert!((fast.norm() - 1.0).abs() < 1e-15);
        }
        assert!(worst < 1e-15, "worst {worst:e}");
        // Zero correction: the same attitude.
        let q = Quat::new_normalized(0.1, -0.3, 0.2, 0.9).expect("non-zero");
        let same = apply_small_error(&q, &Vector3::zeros());
        assert!((same.x - q.x).abs() < 1e-16 && (same.w - q.w).abs() < 1e-16);
    }
}
