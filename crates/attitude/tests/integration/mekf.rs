//! MEKF building blocks: error vector and reset, the Eq. (20) partial, propagation,
//! and the discrete Phi and Qd against the matrix exponential and quadrature.

use crate::common;

use nalgebra::{Matrix6, UnitQuaternion, Vector3, Vector6};
use pdcal_attitude::mekf::{
    SERIES_THRESHOLD_RAD, apply_error, body_vector_partial, error_dynamics_matrix, error_quat,
    error_vector, noise_gain, process_noise, propagate, state_transition,
};
use pdcal_attitude::{GyroNoise, Quat};

/// Products of a few unit-size numbers: tens of ulps.
const ROUNDING: f64 = 1e-14;

fn max_abs(m: &Matrix6<f64>) -> f64 {
    m.iter().fold(0.0, |acc, x| acc.max(x.abs()))
}

#[test]
fn reset_rotates_by_the_error_angle() {
    let mut rng = common::rng(21);
    for _ in 0..1000 {
        let q = common::quat(&mut rng);
        // Small errors (the filter's regime) and large ones up to just below pi.
        for scale in [1e-9, 1e-4, 1e-2, 0.3, 3.0] {
            let a = common::unit3(&mut rng) * scale * common::uniform(&mut rng, 0.1, 1.0);
            let q_plus = apply_error(&q, &a);
            // angle_to uses acos: near zero it resolves only ~1e-8 rad, so compare the
            // exact |sin(angle/2)| through the error quaternion for the small cases.
            let dq = q_plus.compose(&q.inverse());
            let half_sin = dq.vector().norm();
            assert!(((0.5 * a.norm()).sin() - half_sin).abs() < ROUNDING);
            assert!((q_plus.norm() - 1.0).abs() < ROUNDING);
            // error_vector is the inverse: relative 1e-12 covers atan2 rounding near 0.
            let back = error_vector(&q_plus, &q);
            assert!(
                (back - a).norm() <= 1e-12 * a.norm().max(1e-3),
                "{back} vs {a}"
            );
        }
    }
    // The angle itself, for a moderately small error where acos is well conditioned.
    let q = common::quat(&mut rng);
    let a = Vector3::new(0.01, -0.02, 0.015);
    assert!((apply_error(&q, &a).angle_to(&q) - a.norm()).abs() < 1e-12);
    assert_eq!(error_quat(&Vector3::zeros()), Quat::IDENTITY);
}

#[test]
fn error_definition_gives_paper_eq_20_partial() {
    // d(A(dq(a) ⊗ q) s)/d a at a = 0 must be [(A s) x]: central differences.
    // Step 1e-6: truncation ~h^2 = 1e-12, rounding ~eps/h = 2e-10; tolerance 1e-8.
    let h = 1e-6;
    let mut rng = common::rng(22);
    let mut worst: f64 = 0.0;
    for _ in 0..200 {
        let q = common::quat(&mut rng);
        let s = common::unit3(&mut rng);
        let analytic = body_vector_partial(&q, &s);
        for k in 0..3 {
            let step = Vector3::ith(k, h);
            let plus = apply_error(&q, &step).to_body(&s);
            let minus = apply_error(&q, &-step).to_body(&s);
            let numeric = (plus - minus) / (2.0 * h);
            worst = worst.max((numeric - analytic.column(k)).norm());
            assert!((numeric - analytic.column(k)).norm() < 1e-8);
        }
    }
    eprintln!("Eq. 20 partial vs finite differences: worst {worst:e}");
}

#[test]
fn propagation_direction_golden() {
    // Spinning about +z at w: an inertially fixed x_I is seen turning the other way,
    // v_B(t) = (cos wt, -sin wt, 0).
    let w = 0.3;
    let mut q = Quat::IDENTITY;
    for _ in 0..10 {
        q = propagate(&q, &Vector3::new(0.0, 0.0, w), 0.5);
    }
    let v = q.to_body(&Vector3::x());
    let t: f64 = 5.0;
    assert!((v - Vector3::new((w * t).cos(), -(w * t).sin(), 0.0)).norm() < ROUNDING);
}

#[test]
fn constant_rate_thousand_steps_matches_closed_form() {
    let mut rng = common::rng(23);
    let q0 = common::quat(&mut rng);
    // About 21 deg/s for 100 s: several full turns, so errors would accumulate visibly.
    let rate = Vector3::new(0.1, -0.25, 0.2);
    let dt = 0.1;
    let mut q = q0;
    let mut worst_norm: f64 = 0.0;
    for _ in 0..1000 {
        q = propagate(&q, &rate, dt);
        worst_norm = worst_norm.max((q.norm() - 1.0).abs());
    }
    // Independent closed form through nalgebra: R(t) = A(t)^T = R0 exp([w t x]).
    let exact =
        Quat::from_nalgebra(&(q0.to_nalgebra() * UnitQuaternion::from_scaled_axis(rate * 100.0)));
    let angle = error_vector(&q, &exact).norm();
    eprintln!("1000 steps: angle error {angle:e} rad, worst |norm - 1| {worst_norm:e}");
    assert!(angle < 1e-9, "angle error {angle:e}");
    assert!(worst_norm < 1e-12, "norm drift {worst_norm:e}");
}

/// Rates and steps that exercise the series branch, both sides of its threshold and
/// large angles (|w| dt from 1e-9 to 3 rad).
fn cases() -> Vec<(Vector3<f64>, f64)> {
    let axis = Vector3::new(0.3, -0.5, 0.8).normalize();
    let mut out = vec![(Vector3::zeros(), 0.1)];
    for x in [
        1e-9,
        1e-4,
        0.1,
        SERIES_THRESHOLD_RAD * (1.0 - 1e-9),
        SERIES_THRESHOLD_RAD * (1.0 + 1e-9),
        0.9,
        2.0,
        3.0,
    ] {
        out.push((axis * (x / 0.2), 0.2));
    }
    out
}

#[test]
fn phi_equals_matrix_exponential() {
    for (rate, dt) in cases() {
        let phi = state_transition(&rate, dt);
        let reference = (error_dynamics_matrix(&rate) * dt).exp();
        // Pade exp and the closed form both reach ~1e-15; entries are O(1) and O(dt).
        let diff = max_abs(&(phi - reference));
        eprintln!("Phi vs exp(F dt), |w|dt = {:e}: {diff:e}", rate.norm() * dt);
        assert!(diff < 1e-13, "|w|dt = {}: diff {diff:e}", rate.norm() * dt);
    }
}

#[test]
fn phi_equals_finite_differences_of_error_dynamics() {
    // Propagate a true and an estimated attitude with their own bias-corrected rates and
    // difference the resulting error vector with respect to the initial [a; dbeta].
    // Step 1e-6 rad: truncation ~1e-12, rounding of the error extraction ~1e-16/1e-6;
    // tolerance 1e-8.
    let h = 1e-6;
    let mut rng = common::rng(24);
    let mut worst: f64 = 0.0;
    for _ in 0..50 {
        let q_est = common::quat(&mut rng);
        let rate_meas = common::gaussian3(&mut rng) * 0.5;
        let bias_est = common::gaussian3(&mut rng) * 0.01;
        let dt = common::uniform(&mut rng, 0.05, 2.0);
        let rate_est = rate_meas - bias_est;
        let q_est_next = propagate(&q_est, &rate_est, dt);
        let next_error = |x: &Vector6<f64>| {
            let a0 = x.fixed_rows::<3>(0).into_owned();
            let dbeta = x.fixed_rows::<3>(3).into_owned();
            let q_true = apply_error(&q_est, &a0);
            let q_true_next = propagate(&q_true, &(rate_meas - bias_est - dbeta), dt);
            let a1 = error_vector(&q_true_next, &q_est_next);
            Vector6::new(a1.x, a1.y, a1.z, dbeta.x, dbeta.y, dbeta.z)
        };
        let phi = state_transition(&rate_est, dt);
        for k in 0..6 {
            let step = Vector6::ith(k, h);
            let numeric = (next_error(&step) - next_error(&-step)) / (2.0 * h);
            let diff = (numeric - phi.column(k)).norm();
            worst = worst.max(diff);
            assert!(diff < 1e-8, "column {k}: diff {diff:e}");
        }
    }
    eprintln!("Phi vs finite differences: worst column error {worst:e}");
}

/// Composite Simpson rule of `Phi(t) G Q G^T Phi(t)^T` over `[0, dt]`, Phi by `exp`.
fn qd_by_quadrature(rate: &Vector3<f64>, dt: f64, noise: &GyroNoise) -> Matrix6<f64> {
    let f = error_dynamics_matrix(rate);
    let g = noise_gain();
    let mut q = Matrix6::zeros();
    let (var_v, var_u) = (
        noise.sigma_v_rad_sqrt_s.powi(2),
        noise.sigma_u_rad_s_sqrt_s.powi(2),
    );
    for i in 0..3 {
        q[(i, i)] = var_v;
        q[(i + 3, i + 3)] = var_u;
    }
    let gqg = g * q * g.transpose();
    let n = 400;
    let h = dt / f64::from(n);
    let mut sum = Matrix6::zeros();
    for i in 0..=n {
        let phi = (f * (h * f64::from(i))).exp();
        let weight = if i == 0 || i == n {
            1.0
        } else if i % 2 == 1 {
            4.0
        } else {
            2.0
        };
        sum += phi * gqg * phi.transpose() * weight;
    }
    sum * (h / 3.0)
}

#[test]
fn qd_equals_quadrature() {
    // Each noise term alone, so the small sigma_u^2 corrections are checked relative
    // to their own size. Simpson with 400 panels: error ~ (|w| dt)^4 / 400^4 / 180,
    // below 1e-11 relative even at 3 rad; tolerance 1e-10 of the largest entry.
    let noises = [
        GyroNoise {
            sigma_v_rad_sqrt_s: 1.0,
            sigma_u_rad_s_sqrt_s: 0.0,
        },
        GyroNoise {
            sigma_v_rad_sqrt_s: 0.0,
            sigma_u_rad_s_sqrt_s: 1.0,
        },
    ];
    for (rate, dt) in cases() {
        for noise in &noises {
            let closed = process_noise(&rate, dt, noise);
            let numeric = qd_by_quadrature(&rate, dt, noise);
            let rel = max_abs(&(closed - numeric)) / max_abs(&numeric);
            eprintln!("Qd vs Simpson, |w|dt = {:e}: rel {rel:e}", rate.norm() * dt);
            assert!(
                rel < 1e-10,
                "|w|dt = {}: rel {rel:e} for {noise:?}",
                rate.norm() * dt
            );
        }
    }
}

#[test]
fn qd_symmetric_positive_definite() {
    // ADIS16405-class gyro: ARW about 2 deg/sqrt(h), bias walk ~1e-5 rad/s^1.5 (tuning).
    let noise = GyroNoise {
        sigma_v_rad_sqrt_s: 5.8e-4,
        sigma_u_rad_s_sqrt_s: 1e-5,
    };
    let mut rng = common::rng(25);
    let mut worst = f64::INFINITY;
    for _ in 0..200 {
        let rate = common::gaussian3(&mut rng) * 0.3;
        let dt = common::uniform(&mut rng, 0.01, 2.0);
        let qd = process_noise(&rate, dt, &noise);
        assert_eq!(qd, qd.transpose());
        let eigen = qd.symmetric_eigen();
        // At zero rate each axis is the 2x2 block [[v dt + u dt^3/3, -u dt^2/2],
        // [-u dt^2/2, u dt]] (v, u the variances) whose smaller eigenvalue is
        // ~ u dt v / (v + u) ~ u dt for v >> u; the rotation only mixes the a-axes.
        let ratio = eigen.eigenvalues.min() / (noise.sigma_u_rad_s_sqrt_s.powi(2) * dt);
        worst = worst.min(ratio);
        assert!(ratio > 0.5, "min eigenvalue / (sigma_u^2 dt) = {ratio}");
        assert!(qd.cholesky().is_some());
    }
    eprintln!("Qd: smallest eigenvalue / (sigma_u^2 dt) over 200 draws: {worst}");
}

#[test]
fn zero_rate_reduces_to_textbook_forms() {
    // |w| = 0: Phi = [I, -dt I; 0, I] and Qd = CJ Eq. 7.46 exactly.
    let dt = 0.25;
    let noise = GyroNoise {
        sigma_v_rad_sqrt_s: 2e-3,
        sigma_u_rad_s_sqrt_s: 3e-4,
    };
    let phi = state_transition(&Vector3::zeros(), dt);
    let qd = process_noise(&Vector3::zeros(), dt, &noise);
    let (v, u) = (4e-6, 9e-8);
    for i in 0..3 {
        assert_eq!(phi[(i, i + 3)], -dt);
        assert!((qd[(i, i)] - (v * dt + u * dt.powi(3) / 3.0)).abs() < 1e-20);
        assert!((qd[(i, i + 3)] + u * dt * dt / 2.0).abs() < 1e-20);
        assert!((qd[(i + 3, i + 3)] - u * dt).abs() < 1e-20);
    }
}
