//! Dynamics-aided propagation: with the spacecraft's inertia the filter carries the body
//! rate `w` and a residual magnetic dipole `m` as states and integrates Euler's equations
//! (the gravity gradient of the orbit the filter already has, plus the dipole's torque in
//! the reference field) between samples, the paper's Section V alternative to the
//! gyro-driven MEKF ("a dynamic model and no rate gyroscope", its references [32]-[33]).
//! The gyro, when there is one, becomes a measurement of `w + beta`.
//!
//! # Error dynamics
//!
//! With the attitude error `a` of [`pdcal_attitude::mekf`] (`A(q_true) = A(dq(a)) A(q)`),
//! `dbeta = beta_true - beta`, `dw = w_true - w`, `dm = m_true - m` and the unknown torque
//! `eta` (white, spectral density `S` per axis, N^2 m^2 s):
//!
//! ```text
//! a'     = -[w x] a + dw
//! dbeta' = eta_u
//! dw'    = J^-1 ([(J w) x] - [w x] J) dw + J^-1 (T_a + M_a) a - J^-1 [b x] dm + J^-1 eta
//! dm'    = eta_m
//! T_a    = k ([u x] J - [(J u) x]) [u x],   k = 3 mu / r^3,  u = A(q) r_gcrf / r
//! M_a    = [m x] [b x],                     b = A(q) B_gcrf (in tesla)
//! ```
//!
//! (`T_a` and `M_a` are the torques' partials in the attitude error: `u_true = u + [u x] a`,
//! `d(u x J u)/du = [u x] J - [(J u) x]`, and `m x b` is linear in both.) The dipole is a
//! constant with a small random walk `eta_m` (currents that change). Over a step the
//! nominal state is integrated by the rigid-body RK4 of [`pdcal_attitude::dynamics`]; the
//! transition `Phi` and process noise `Qd` of the 12 error states `[a, dbeta, dw, dm]` are
//! accumulated over the same substeps, `Phi_h = exp(F_mid h)` (Taylor to 4th order, `|F h|`
//! is at most about [`MAX_SUBSTEP_ROTATION_RAD`]) with `F_mid` the mean of `F` at the
//! substep's ends, and `Qd <- Phi_h Qd Phi_h^T + (Phi_h M Phi_h^T + M) h / 2` (trapezoid),
//! `M = diag(0, sigma_u^2 I, J^-1 S J^-1, sigma_m^2 I)`.
//!
//! # Uncertain inertia
//!
//! An error `dJ` of the inertia acts as a torque `w x (dJ w) - dJ w'` the model lacks, of
//! size `f |J| |w|^2` for a fractional error `f`, whose direction in the body turns with the
//! rotation (time scale `1 / |w|`). It enters `S` as white noise of that power over that
//! time: `S = S_0 + (f |J| |w|^2)^2 / |w|` at the substep's rate, `|J|` the largest principal
//! moment.

use nalgebra::{DMatrix, Matrix3, SMatrix, Vector3};
use pdcal_attitude::dynamics::{
    AttitudeState, MU_EARTH_KM3_S2, RigidBody, gravity_gradient_torque, magnetic_dipole_torque,
    rk4_step,
};
use pdcal_attitude::{Quat, skew};

/// Number of error states the dynamics propagate: `[a, dbeta, dw, dm]`.
pub const RATE_STATES: usize = 12;

/// 12x12 matrix of the error states `[a, dbeta, dw, dm]`.
pub type Matrix12 = SMatrix<f64, RATE_STATES, RATE_STATES>;

/// Indices of the error states `[a, dbeta, dw, dm]` in the filter's state.
pub type RateIndex = [usize; RATE_STATES];

/// Largest rotation of the body in one integration substep, rad: the RK4 local error of
/// the nominal state is then `~(0.05)^5 / 120`; the transition, second order in the
/// substep, stays within 1e-4 of its largest entry (a test holds it to finite differences).
pub const MAX_SUBSTEP_ROTATION_RAD: f64 = 0.05;

/// Longest integration substep, s (the gravity gradient and the field change on the
/// orbit's time scale; one second resolves them to far below the torque noise).
pub const MAX_SUBSTEP_S: f64 = 1.0;

/// The rigid body and the process noise of the dynamics.
#[derive(Debug, Clone, PartialEq)]
pub struct RateModel {
    /// The spacecraft's mass properties (the filter's belief of them).
    pub body: RigidBody,
    /// Spectral density of the unknown torque per body axis, N^2 m^2 s.
    pub torque_psd: f64,
    /// Gyro-bias random-walk variance per second, rad^2/s^3.
    pub bias_walk_var_per_s: f64,
    /// Residual-dipole random-walk variance per second, A^2 m^4 / s.
    pub dipole_walk_var_per_s: f64,
    /// Fractional sigma of the inertia (module docs, "Uncertain inertia").
    pub inertia_sigma_fraction: f64,
}

impl RateModel {
    /// Torque spectral density per axis at body rate `w_body_rad_s`, N^2 m^2 s: the
    /// unknown torque's plus the uncertain inertia's (module docs).
    pub fn torque_psd_at(&self, w_body_rad_s: &Vector3<f64>) -> f64 {
        let w = w_body_rad_s.norm();
        let largest = self.body.inertia_kg_m2().symmetric_eigenvalues().max();
        let inertia_torque = self.inertia_sigma_fraction * largest * w * w;
        self.torque_psd + inertia_torque * inertia_torque / w.max(1e-12)
    }
}

/// The nominal states the dynamics carry besides the attitude.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Motion {
    /// Body rate, rad/s.
    pub w_body_rad_s: Vector3<f64>,
    /// Residual magnetic dipole, body frame, A m^2.
    pub dipole_body_a_m2: Vector3<f64>,
}

/// Where the spacecraft is over one step: position and reference field at its start and
/// end, moving linearly in between (both change on the orbit's time scale).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepEnvironment {
    /// Position at the start and end, GCRF, km.
    pub r_gcrf_km: [Vector3<f64>; 2],
    /// Reference geomagnetic field at the start and end, GCRF, nT.
    pub b_gcrf_nt: [Vector3<f64>; 2],
}

impl StepEnvironment {
    /// Position and field at the fraction `f` of the step.
    fn at(&self, f: f64) -> (Vector3<f64>, Vector3<f64>) {
        (
            self.r_gcrf_km[0].lerp(&self.r_gcrf_km[1], f),
            self.b_gcrf_nt[0].lerp(&self.b_gcrf_nt[1], f),
        )
    }
}

/// The nominal state after a step and the error transition over it.
#[derive(Debug, Clone, PartialEq)]
pub struct RateStep {
    /// Attitude at the end.
    pub q: Quat,
    /// Body rate at the end, rad/s.
    pub w_body_rad_s: Vector3<f64>,
    /// `Phi` of `[a, dbeta, dw, dm]`.
    pub phi: Matrix12,
    /// `Qd` of `[a, dbeta, dw, dm]`.
    pub qd: Matrix12,
}

/// Gravity-gradient plus dipole torque at attitude `q`, position `r_gcrf_km` and field
/// `b_gcrf_nt`, body frame, N m.
fn torque(
    body: &RigidBody,
    dipole_body_a_m2: &Vector3<f64>,
    q: &Quat,
    (r_gcrf_km, b_gcrf_nt): (&Vector3<f64>, &Vector3<f64>),
) -> Vector3<f64> {
    gravity_gradient_torque(body.inertia_kg_m2(), &q.to_body(r_gcrf_km))
        + magnetic_dipole_torque(dipole_body_a_m2, &q.to_body(b_gcrf_nt))
}

/// The continuous error-dynamics matrix `F` of the module docs at the nominal attitude `q`,
/// motion `motion`, position `r_gcrf_km` and field `b_gcrf_nt`.
pub fn error_dynamics(
    body: &RigidBody,
    q: &Quat,
    motion: &Motion,
    (r_gcrf_km, b_gcrf_nt): (&Vector3<f64>, &Vector3<f64>),
) -> Matrix12 {
    let j = body.inertia_kg_m2();
    let j_inv = j.try_inverse().unwrap_or_else(Matrix3::zeros);
    let w = &motion.w_body_rad_s;
    let r = r_gcrf_km.norm();
    let u = q.to_body(r_gcrf_km) / r;
    let k = 3.0 * MU_EARTH_KM3_S2 / (r * r * r);
    let b_skew = skew(&(q.to_body(b_gcrf_nt) * 1e-9));
    let t_a = (skew(&u) * j - skew(&(j * u))) * skew(&u) * k;
    let m_a = skew(&motion.dipole_body_a_m2) * b_skew;
    let mut f = Matrix12::zeros();
    f.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-skew(w)));
    f.fixed_view_mut::<3, 3>(0, 6)
        .copy_from(&Matrix3::identity());
    f.fixed_view_mut::<3, 3>(6, 0)
        .copy_from(&(j_inv * (t_a + m_a)));
    f.fixed_view_mut::<3, 3>(6, 6)
        .copy_from(&(j_inv * (skew(&(j * w)) - skew(w) * j)));
    f.fixed_view_mut::<3, 3>(6, 9).copy_from(&(-j_inv * b_skew));
    f
}

/// `exp(X)` by its Taylor series to 4th order (for `|X|` of a few hundredths).
fn exp_small(x: &Matrix12) -> Matrix12 {
    let x2 = x * x;
    let x3 = x2 * x;
    Matrix12::identity() + x + x2 * 0.5 + x3 * (1.0 / 6.0) + x3 * x * (1.0 / 24.0)
}

/// The continuous process noise `M` of the module docs at body rate `w_body_rad_s`.
fn noise_density(model: &RateModel, w_body_rad_s: &Vector3<f64>) -> Matrix12 {
    let j_inv = model
        .body
        .inertia_kg_m2()
        .try_inverse()
        .unwrap_or_else(Matrix3::zeros);
    let mut m = Matrix12::zeros();
    m.fixed_view_mut::<3, 3>(3, 3)
        .copy_from(&(Matrix3::identity() * model.bias_walk_var_per_s));
    m.fixed_view_mut::<3, 3>(6, 6)
        .copy_from(&(j_inv * j_inv.transpose() * model.torque_psd_at(w_body_rad_s)));
    m.fixed_view_mut::<3, 3>(9, 9)
        .copy_from(&(Matrix3::identity() * model.dipole_walk_var_per_s));
    m
}

/// Propagates the nominal state `(q, motion)` over `dt_s` through `env`, and the error
/// transition and process noise with it (module docs).
pub fn propagate(
    model: &RateModel,
    q: &Quat,
    motion: &Motion,
    env: &StepEnvironment,
    dt_s: f64,
) -> RateStep {
    let body = &model.body;
    let dipole = &motion.dipole_body_a_m2;
    let max_h =
        (MAX_SUBSTEP_ROTATION_RAD / motion.w_body_rad_s.norm().max(1e-12)).min(MAX_SUBSTEP_S);
    let n = (dt_s.abs() / max_h).ceil().max(1.0) as usize;
    let h = dt_s / n as f64;
    let place = |t: f64| env.at(if dt_s != 0.0 { t / dt_s } else { 0.0 });
    let torque_at = |t: f64, q: &Quat| {
        let (r, b) = place(t);
        torque(body, dipole, q, (&r, &b))
    };
    // The rate changes little over a step: its noise at the start serves the whole step.
    let m = noise_density(model, &motion.w_body_rad_s);
    let mut state = AttitudeState {
        q: *q,
        w_body_rad_s: motion.w_body_rad_s,
    };
    let linearised = |s: &AttitudeState, t: f64| {
        let (r, b) = place(t);
        let at = Motion {
            w_body_rad_s: s.w_body_rad_s,
            dipole_body_a_m2: *dipole,
        };
        error_dynamics(body, &s.q, &at, (&r, &b))
    };
    let mut phi = Matrix12::identity();
    let mut qd = Matrix12::zeros();
    let mut f0 = linearised(&state, 0.0);
    for i in 0..n {
        let t = i as f64 * h;
        state = rk4_step(body, &state, t, h, &torque_at);
        let f1 = linearised(&state, t + h);
        let phi_h = exp_small(&((f0 + f1) * (0.5 * h)));
        phi = phi_h * phi;
        qd = phi_h * (qd + m * (0.5 * h)) * phi_h.transpose() + m * (0.5 * h);
        f0 = f1;
    }
    RateStep {
        q: state.q,
        w_body_rad_s: state.w_body_rad_s,
        phi,
        qd: 0.5 * (qd + qd.transpose()),
    }
}

/// The rows of `phi` that differ from the identity's (the bias and dipole rows are the
/// identity's: only the attitude and rate rows need the product).
fn moving_rows(phi: &Matrix12) -> ([usize; RATE_STATES], usize) {
    let mut rows = [0; RATE_STATES];
    let mut n = 0;
    for r in 0..RATE_STATES {
        let identity = (0..RATE_STATES).all(|j| phi[(r, j)] == if j == r { 1.0 } else { 0.0 });
        if !identity {
            rows[n] = r;
            n += 1;
        }
    }
    (rows, n)
}

/// `P <- Phi P` in place, `Phi` the identity but for rows `idx` (given as `phi`, columns in
/// `idx` order).
pub(crate) fn left_multiply(p: &mut DMatrix<f64>, idx: &RateIndex, phi: &Matrix12) {
    let (rows, n) = moving_rows(phi);
    let rows = &rows[..n];
    let mut x = [0.0; RATE_STATES];
    for mut column in p.column_iter_mut() {
        for (xj, &k) in x.iter_mut().zip(idx) {
            *xj = column[k];
        }
        for &r in rows {
            column[idx[r]] = (0..RATE_STATES).map(|j| phi[(r, j)] * x[j]).sum();
        }
    }
}

/// `P <- P Phi^T` in place, `Phi` as in [`left_multiply`].
pub(crate) fn right_multiply_transpose(p: &mut DMatrix<f64>, idx: &RateIndex, phi: &Matrix12) {
    let (cols, m) = moving_rows(phi);
    let n = p.nrows();
    let mut x = [0.0; RATE_STATES];
    for row in 0..n {
        for (xj, &k) in x.iter_mut().zip(idx) {
            *xj = p[(row, k)];
        }
        for &c in &cols[..m] {
            p[(row, idx[c])] = (0..RATE_STATES).map(|j| phi[(c, j)] * x[j]).sum();
        }
    }
}

/// `P <- Phi P Phi^T + Q`: `Phi` as in [`left_multiply`], `Q` = `qd` on `idx` and
/// `other_noise` on the diagonal elsewhere; made exactly symmetric (`P` and `Q` are).
pub(crate) fn propagate_covariance(
    p: &mut DMatrix<f64>,
    idx: &RateIndex,
    phi: &Matrix12,
    qd: &Matrix12,
    other_noise: &[f64],
) {
    left_multiply(p, idx, phi);
    right_multiply_transpose(p, idx, phi);
    add_noise(p, idx, qd, other_noise);
    // Only the rows and columns `Phi` moved can have lost symmetry to round-off.
    let (rows, m) = moving_rows(phi);
    for &r in &rows[..m] {
        let k = idx[r];
        for j in 0..p.nrows() {
            let mean = 0.5 * (p[(k, j)] + p[(j, k)]);
            p[(k, j)] = mean;
            p[(j, k)] = mean;
        }
    }
}

/// `P += Q` with `Q` as in [`propagate_covariance`].
pub(crate) fn add_noise(p: &mut DMatrix<f64>, idx: &RateIndex, qd: &Matrix12, other: &[f64]) {
    for (r, &i) in idx.iter().enumerate() {
        for (c, &j) in idx.iter().enumerate() {
            p[(i, j)] += qd[(r, c)];
        }
    }
    for (k, v) in other.iter().enumerate() {
        if !idx.contains(&k) {
            p[(k, k)] += v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use pdcal_attitude::mekf::{apply_error, error_vector};

    fn model() -> RateModel {
        RateModel {
            body: RigidBody::new(Matrix3::new(
                0.185, 0.002, -0.001, 0.002, 0.144, 0.0015, -0.001, 0.0015, 0.061,
            ))
            .expect("physical"),
            torque_psd: 1e-14,
            bias_walk_var_per_s: 1e-12,
            dipole_walk_var_per_s: 1e-10,
            inertia_sigma_fraction: 0.1,
        }
    }

    fn motion(w: Vector3<f64>, m: Vector3<f64>) -> Motion {
        Motion {
            w_body_rad_s: w,
            dipole_body_a_m2: m,
        }
    }

    /// A low orbit (the gravity gradient at 7000 km, exaggerated 1e3-fold through the
    /// position so that its column is tested too) and a 40 uT field turning a little.
    fn environment() -> StepEnvironment {
        StepEnvironment {
            r_gcrf_km: [
                Vector3::new(700.0, 300.0, -200.0),
                Vector3::new(705.0, 290.0, -195.0),
            ],
            b_gcrf_nt: [
                Vector3::new(20_000.0, -25_000.0, 24_000.0),
                Vector3::new(21_000.0, -24_000.0, 25_000.0),
            ],
        }
    }

    #[test]
    fn transition_matches_finite_differences_of_the_nonlinear_propagation() {
        // Each error state perturbed by +-h, the true state propagated by the same
        // integrator, the end error against the nominal end: central differences of the
        // map x0 -> x1. The tumble (6 deg/s about a skewed axis), the environment above, a
        // 0.3 A m^2 dipole and 10 s steps make every block of Phi non-trivial.
        let m = model();
        let q0 = Quat::new_normalized(0.3, -0.5, 0.2, 0.78).expect("non-zero");
        let w0 = Vector3::new(0.06, -0.08, 0.05);
        let d0 = Vector3::new(0.1, -0.2, 0.2);
        let env = environment();
        let dt = 10.0;
        let nominal = propagate(&m, &q0, &motion(w0, d0), &env, dt);
        let end = |a: Vector3<f64>, dw: Vector3<f64>, dm: Vector3<f64>| {
            let s = propagate(
                &m,
                &apply_error(&q0, &a),
                &motion(w0 + dw, d0 + dm),
                &env,
                dt,
            );
            let mut x = [0.0; RATE_STATES];
            let da = error_vector(&s.q, &nominal.q);
            let dw1 = s.w_body_rad_s - nominal.w_body_rad_s;
            x[..3].copy_from_slice(da.as_slice());
            x[6..9].copy_from_slice(dw1.as_slice());
            x[9..].copy_from_slice(dm.as_slice());
            x
        };
        let h = 1e-6;
        let mut worst: f64 = 0.0;
        for col in [0, 1, 2, 6, 7, 8, 9, 10, 11] {
            let mut e = Vector3::zeros();
            e[col % 3] = h;
            let z = Vector3::zeros();
            let (plus, minus) = match col {
                0..3 => (end(e, z, z), end(-e, z, z)),
                6..9 => (end(z, e, z), end(z, -e, z)),
                _ => (end(z, z, e), end(z, z, -e)),
            };
            for row in 0..RATE_STATES {
                let fd = (plus[row] - minus[row]) / (2.0 * h);
                worst = worst.max((fd - nominal.phi[(row, col)]).abs());
            }
        }
        // The trapezoidal `exp(F_mid h)` is second order in the substep: its error falls
        // 24-fold when the substep rotation goes from 0.05 to 0.01 rad. At 0.05 rad it is
        // below 1e-4 of the largest entry (`dt` = 10 s in the a-w block); a wrong partial
        // would err by the partial's own size, 1e-2 or more of it.
        let largest = nominal.phi.abs().max();
        assert!(worst < 1e-4 * largest, "worst {worst:e} of {largest}");
        // The dipole's columns reach the attitude: its torque is in the dynamics.
        let dipole_to_attitude = nominal.phi.fixed_view::<3, 3>(0, 9).abs().max();
        assert!(dipole_to_attitude > 1e-3, "{dipole_to_attitude:e}");
        // The bias does not enter the dynamics: its columns are the identity.
        for col in 3..6 {
            for row in 0..RATE_STATES {
                let expected = if row == col { 1.0 } else { 0.0 };
                assert_eq!(nominal.phi[(row, col)], expected);
            }
        }
    }

    #[test]
    fn torque_partials_match_finite_differences() {
        // T_a + M_a and -[b x] of the module docs against central differences of the
        // torque in `a` and in `m`.
        let m = model();
        let q = Quat::new_normalized(0.1, 0.7, -0.2, 0.6).expect("non-zero");
        let d = Vector3::new(0.3, -0.1, 0.4);
        let r = Vector3::new(6900.0, -500.0, 800.0);
        let b = Vector3::new(15_000.0, 30_000.0, -20_000.0);
        let f = error_dynamics(&m.body, &q, &motion(Vector3::zeros(), d), (&r, &b));
        let j_inv = m.body.inertia_kg_m2().try_inverse().expect("invertible");
        let h = 1e-6;
        for col in 0..6 {
            let mut e = Vector3::zeros();
            e[col % 3] = h;
            let (plus, minus) = if col < 3 {
                (
                    torque(&m.body, &d, &apply_error(&q, &e), (&r, &b)),
                    torque(&m.body, &d, &apply_error(&q, &(-e)), (&r, &b)),
                )
            } else {
                (
                    torque(&m.body, &(d + e), &q, (&r, &b)),
                    torque(&m.body, &(d - e), &q, (&r, &b)),
                )
            };
            let fd = j_inv * (plus - minus) / (2.0 * h);
            let fcol = if col < 3 { col } else { 6 + col };
            for row in 0..3 {
                let exact = f[(6 + row, fcol)];
                assert!(
                    (fd[row] - exact).abs() < 1e-6 * exact.abs().max(1e-9),
                    "{row},{col}: {} vs {exact}",
                    fd[row]
                );
            }
        }
    }

    #[test]
    fn process_noise_is_symmetric_positive_definite_and_grows_with_the_step() {
        let m = model();
        let q = Quat::IDENTITY;
        let mo = motion(Vector3::new(0.05, 0.02, -0.09), Vector3::zeros());
        let r = Vector3::new(7000.0, 0.0, 0.0);
        let env = StepEnvironment {
            r_gcrf_km: [r, r],
            b_gcrf_nt: [Vector3::new(0.0, 30_000.0, 0.0); 2],
        };
        let short = propagate(&m, &q, &mo, &env, 1.0).qd;
        let long = propagate(&m, &q, &mo, &env, 10.0).qd;
        for qd in [&short, &long] {
            assert_eq!(qd, &qd.transpose());
            assert!(qd.cholesky().is_some());
        }
        assert!(long[(6, 6)] > 5.0 * short[(6, 6)]);
        // The attitude error accumulates the rate noise: ~ S dt^3 / (3 J^2).
        assert!(long[(0, 0)] > 100.0 * short[(0, 0)]);
    }

    #[test]
    fn indexed_propagation_equals_the_dense_product() {
        let n = 17;
        let idx = [0, 1, 2, 3, 4, 5, 11, 12, 13, 14, 15, 16];
        let a = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 3) % 11) as f64 / 10.0 - 0.4);
        let mut p = &a * a.transpose() + DMatrix::identity(n, n);
        // Rows 3..6 the identity's, as the bias rows are (the product skips them).
        let phi12 = Matrix12::from_fn(|i, j| match i {
            3..6 => (i == j) as u8 as f64,
            _ => ((i + 2 * j) % 5) as f64 * 0.1 + (i == j) as u8 as f64,
        });
        let qd12 = Matrix12::identity() * 0.01;
        let other: Vec<f64> = (0..n).map(|k| 0.001 * k as f64).collect();
        let mut phi = DMatrix::identity(n, n);
        let mut q = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(other.clone()));
        for (r, &i) in idx.iter().enumerate() {
            q[(i, i)] = 0.0;
            for (c, &j) in idx.iter().enumerate() {
                phi[(i, j)] = phi12[(r, c)];
                q[(i, j)] = qd12[(r, c)];
            }
        }
        let expected = &phi * &p * phi.transpose() + q;
        propagate_covariance(&mut p, &idx, &phi12, &qd12, &other);
        assert!((p - expected).abs().max() < 1e-12);
    }
}
