//! Dynamics-aided propagation: with the spacecraft's inertia the filter carries the body
//! rate `w`, a residual magnetic dipole `m` and a correction `c` of the inertia's diagonal
//! moments as states and integrates Euler's equations
//! (the gravity gradient of the orbit the filter already has, plus the dipole's torque in
//! the reference field) between samples, the paper's Section V alternative to the
//! gyro-driven MEKF ("a dynamic model and no rate gyroscope", its references [32]-[33]).
//! The gyro, when there is one, becomes a measurement of `w + beta`.
//!
//! # Error dynamics
//!
//! With the attitude error `a` of [`pdcal_attitude::mekf`] (`A(q_true) = A(dq(a)) A(q)`),
//! `dbeta = beta_true - beta`, `dw = w_true - w`, `dm = m_true - m`, `dc = c_true - c` and
//! the unknown torque `eta` (white, spectral density `S` per axis, N^2 m^2 s):
//!
//! ```text
//! a'     = -[w x] a + dw
//! dbeta' = eta_u
//! dw'    = J^-1 ([(J w) x] - [w x] J) dw + J^-1 (T_a + M_a) a - J^-1 [b x] dm
//!          + J^-1 D dc + J^-1 eta
//! dm'    = eta_m
//! dc'    = 0
//! T_a    = k ([u x] J - [(J u) x]) [u x],   k = 3 mu / r^3,  u = A(q) r_gcrf / r
//! M_a    = [m x] [b x],                     b = A(q) B_gcrf (in tesla)
//! D e_i  = -E_i w' - w x (E_i w) + k u x (E_i u),   E_i = J0_ii e_i e_i^T
//! ```
//!
//! (`T_a` and `M_a` are the torques' partials in the attitude error: `u_true = u + [u x] a`,
//! `d(u x J u)/du = [u x] J - [(J u) x]`, and `m x b` is linear in both. `D` is the partial
//! of `J w' = T(J) - w x J w` in `c` with `w'` held, `dJ/dc_i = E_i`.) The dipole is a
//! constant with a small random walk `eta_m` (currents that change). Over a step the
//! nominal state is integrated by the rigid-body RK4 of [`pdcal_attitude::dynamics`]; the
//! transition `Phi` and process noise `Qd` of the 15 error states `[a, dbeta, dw, dm, dc]`
//! are accumulated over the same substeps, `Phi_h = exp(F_mid h)` (Taylor to 4th order,
//! `|F h|` is at most about [`MAX_SUBSTEP_ROTATION_RAD`]) with `F_mid` the mean of `F` at
//! the substep's ends, and `Qd <- Phi_h Qd Phi_h^T + (Phi_h M Phi_h^T + M) h / 2`
//! (trapezoid), `M = diag(0, sigma_u^2 I, J^-1 S J^-1, sigma_m^2 I, 0)`. Only `a` and `dw`
//! move under `F`, driven by the parameters `[dm, dc]`: the products run on those blocks
//! ([`Linearised`]).
//!
//! # Uncertain inertia
//!
//! The filter's inertia is the given `J0` with each diagonal moment corrected by a
//! fraction: `J = J0 + diag(J0_xx c_x, J0_yy c_y, J0_zz c_z)`, `c` estimated from a prior
//! of zero with sigma [`RateModel::inertia_sigma_fraction`] per axis. An error of the
//! inertia acts as a torque `w x (dJ w) - dJ w'` that turns with the body; carried as
//! white torque noise it would blur the rate between rows as fast as it grows, whereas
//! as a state it is learned from the motion. What the motion sees are the moments'
//! ratios: the torque-free motion and the gravity gradient are unchanged when `J` is
//! scaled, the dipole's torque only through `m / |J|`, so the common scale of `c` stays
//! near its prior, correlated with the dipole. Products of inertia are not corrected.

use std::borrow::Cow;

use nalgebra::{DMatrix, Matrix3, Matrix6, SMatrix, Vector3, Vector6};
use pdcal_attitude::dynamics::{
    AttitudeState, MU_EARTH_KM3_S2, RigidBody, gravity_gradient_torque, magnetic_dipole_torque,
    rk4_step,
};
use pdcal_attitude::{Quat, skew};

/// Number of error states the dynamics propagate: `[a, dbeta, dw, dm, dc]`.
pub const RATE_STATES: usize = 15;

/// Matrix of the error states `[a, dbeta, dw, dm, dc]`.
pub type RateMatrix = SMatrix<f64, RATE_STATES, RATE_STATES>;

/// Indices of the error states `[a, dbeta, dw, dm, dc]` in the filter's state.
pub type RateIndex = [usize; RATE_STATES];

/// Prior sigma of the moment correction `c` when the inertia is trusted
/// (`inertia_sigma_fraction` 0): a part per million, so that the covariance stays
/// positive definite while `c` stays put.
pub const TRUSTED_MOMENT_SIGMA: f64 = 1e-6;

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
    /// Prior sigma of each diagonal moment's fractional correction (module docs,
    /// "Uncertain inertia"); 0 trusts the inertia ([`TRUSTED_MOMENT_SIGMA`]).
    pub inertia_sigma_fraction: f64,
}

impl RateModel {
    /// The prior sigma of the moment correction `c` per axis.
    pub fn moment_sigma(&self) -> f64 {
        self.inertia_sigma_fraction.max(TRUSTED_MOMENT_SIGMA)
    }

    /// The rigid body with the moment correction `c` (module docs). A correction that
    /// would leave the inertia not positive definite (below -100 %, thousands of prior
    /// sigmas) is not applied.
    pub fn body_at(&self, c: &Vector3<f64>) -> Cow<'_, RigidBody> {
        if *c == Vector3::zeros() {
            return Cow::Borrowed(&self.body);
        }
        self.body
            .with_moment_fractions(c)
            .map_or(Cow::Borrowed(&self.body), Cow::Owned)
    }
}

/// The nominal states the dynamics carry besides the attitude.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Motion {
    /// Body rate, rad/s.
    pub w_body_rad_s: Vector3<f64>,
    /// Residual magnetic dipole, body frame, A m^2.
    pub dipole_body_a_m2: Vector3<f64>,
    /// Fractional correction `c` of the given inertia's diagonal moments (module docs,
    /// "Uncertain inertia").
    pub moment_fraction: Vector3<f64>,
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
    /// `Phi` of `[a, dbeta, dw, dm, dc]`.
    pub phi: RateMatrix,
    /// `Qd` of `[a, dbeta, dw, dm, dc]`.
    pub qd: RateMatrix,
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

/// `F` of the module docs in blocks: the attitude and rate errors `x = [a, dw]` move as
/// `x' = A x + B p` with the parameters `p = [dm, dc]`; the bias and the parameters are
/// random walks (their rows of `F` are zero, and the bias enters no other row).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Linearised {
    /// `A`, 6x6 over `x = [a, dw]`.
    a: Matrix6<f64>,
    /// `B`, 6x6 from `p = [dm, dc]` to `x`.
    b: Matrix6<f64>,
}

impl Linearised {
    /// `F` of the module docs at the nominal attitude `q`, motion `motion` (its inertia
    /// `body`, the given diagonal moments `j0_diag`), position `r_gcrf_km` and field
    /// `b_gcrf_nt`.
    fn at(
        (body, j0_diag): (&RigidBody, &Vector3<f64>),
        q: &Quat,
        motion: &Motion,
        (r_gcrf_km, b_gcrf_nt): (&Vector3<f64>, &Vector3<f64>),
    ) -> Self {
        let j = body.inertia_kg_m2();
        let j_inv = body.inertia_inv();
        let w = &motion.w_body_rad_s;
        let r = r_gcrf_km.norm();
        let u = q.to_body(r_gcrf_km) / r;
        let k = 3.0 * MU_EARTH_KM3_S2 / (r * r * r);
        let b_skew = skew(&(q.to_body(b_gcrf_nt) * 1e-9));
        let t_a = (skew(&u) * j - skew(&(j * u))) * skew(&u) * k;
        let m_a = skew(&motion.dipole_body_a_m2) * b_skew;
        let mut a = Matrix6::zeros();
        a.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-skew(w)));
        a.fixed_view_mut::<3, 3>(0, 3)
            .copy_from(&Matrix3::identity());
        a.fixed_view_mut::<3, 3>(3, 0)
            .copy_from(&(j_inv * (t_a + m_a)));
        a.fixed_view_mut::<3, 3>(3, 3)
            .copy_from(&(j_inv * (skew(&(j * w)) - skew(w) * j)));
        let mut b = Matrix6::zeros();
        b.fixed_view_mut::<3, 3>(3, 0).copy_from(&(-j_inv * b_skew));
        let torque_b = torque(body, &motion.dipole_body_a_m2, q, (r_gcrf_km, b_gcrf_nt));
        let w_dot = body.angular_acceleration(w, &torque_b);
        for i in 0..3 {
            // `E_i v = J0_ii v_i e_i`.
            let e_i = |v: &Vector3<f64>| {
                let mut out = Vector3::zeros();
                out[i] = j0_diag[i] * v[i];
                out
            };
            let column = j_inv * (-e_i(&w_dot) - w.cross(&e_i(w)) + u.cross(&e_i(&u)) * k);
            b.fixed_view_mut::<3, 1>(3, 3 + i).copy_from(&column);
        }
        Self { a, b }
    }
}

/// Where the rows of `x = [a, dw]` sit among the error states `[a, dbeta, dw, dm]`.
const X_STATES: [usize; 6] = [0, 1, 2, 6, 7, 8];

/// Where the parameters `p = [dm, dc]` sit among the error states `[a, dbeta, dw, dm, dc]`.
const PARAMETER_STATES: [usize; 6] = [9, 10, 11, 12, 13, 14];

/// The continuous error-dynamics matrix `F` of the module docs at the nominal attitude `q`,
/// motion `motion`, position `r_gcrf_km` and field `b_gcrf_nt`.
pub fn error_dynamics(
    model: &RateModel,
    q: &Quat,
    motion: &Motion,
    place: (&Vector3<f64>, &Vector3<f64>),
) -> RateMatrix {
    let body = model.body_at(&motion.moment_fraction);
    let j0_diag = model.body.inertia_kg_m2().diagonal();
    let blocks = Linearised::at((&body, &j0_diag), q, motion, place);
    let mut f = RateMatrix::zeros();
    for (r, &i) in X_STATES.iter().enumerate() {
        for (c, &j) in X_STATES.iter().enumerate() {
            f[(i, j)] = blocks.a[(r, c)];
        }
        for (c, &j) in PARAMETER_STATES.iter().enumerate() {
            f[(i, j)] = blocks.b[(r, c)];
        }
    }
    f
}

/// `Phi` and `Qd` of one step, accumulated over its substeps in the blocks of
/// [`Linearised`]: `Phi = [[Phi_x, Gamma], [0, I]]` over `[x, p]` (the bias's identity
/// apart), `Qd` over `[x, p]` plus the bias's `q_bias I`.
#[derive(Debug, Clone, Copy)]
struct Accumulated {
    phi_x: Matrix6<f64>,
    gamma: Matrix6<f64>,
    q_x: Matrix6<f64>,
    q_xp: Matrix6<f64>,
    q_p: Matrix6<f64>,
    q_bias: f64,
}

/// The diagonal blocks of the continuous process noise `M` of the module docs with the
/// inertia `body`: the rate's `J^-1 S J^-1`, the bias's variance per second, and the
/// parameters' (the dipole's walk; the inertia's correction is a constant).
struct NoiseDensity {
    rate: Matrix3<f64>,
    bias: f64,
    parameters: Matrix6<f64>,
}

impl NoiseDensity {
    fn at(model: &RateModel, body: &RigidBody) -> Self {
        let j_inv = body.inertia_inv();
        let d = model.dipole_walk_var_per_s;
        Self {
            rate: j_inv * j_inv.transpose() * model.torque_psd,
            bias: model.bias_walk_var_per_s,
            parameters: Matrix6::from_diagonal(&Vector6::new(d, d, d, 0.0, 0.0, 0.0)),
        }
    }
}

impl Accumulated {
    fn start() -> Self {
        Self {
            phi_x: Matrix6::identity(),
            gamma: Matrix6::zeros(),
            q_x: Matrix6::zeros(),
            q_xp: Matrix6::zeros(),
            q_p: Matrix6::zeros(),
            q_bias: 0.0,
        }
    }

    /// One substep `h` with `F_mid` = `mid`: `Phi_h = exp(F_mid h)` to 4th order, whose
    /// blocks are `E = sum_k (A h)^k / k!` and `G = sum_k (A h)^(k-1) B h / k!`;
    /// `Phi <- Phi_h Phi`, `Qd <- Phi_h (Qd + M h / 2) Phi_h^T + M h / 2`.
    fn substep(&mut self, mid: &Linearised, m: &NoiseDensity, h: f64) {
        let x = mid.a * h;
        let y = mid.b * h;
        let x2 = x * x;
        let x3 = x2 * x;
        let e = Matrix6::identity() + x + x2 * 0.5 + x3 * (1.0 / 6.0) + x3 * x * (1.0 / 24.0);
        let g = (Matrix6::identity() + x * 0.5 + x2 * (1.0 / 6.0) + x3 * (1.0 / 24.0)) * y;
        self.phi_x = e * self.phi_x;
        self.gamma = e * self.gamma + g;
        let half = 0.5 * h;
        let mut y_x = self.q_x;
        let mut rate_block = y_x.fixed_view_mut::<3, 3>(3, 3);
        rate_block += m.rate * half;
        let y_p = self.q_p + m.parameters * half;
        let z_x = e * y_x + g * self.q_xp.transpose();
        let z_p = e * self.q_xp + g * y_p;
        self.q_x = z_x * e.transpose() + z_p * g.transpose();
        let mut rate_block = self.q_x.fixed_view_mut::<3, 3>(3, 3);
        rate_block += m.rate * half;
        self.q_xp = z_p;
        self.q_p = y_p + m.parameters * half;
        self.q_bias = self.q_bias + m.bias * half + m.bias * half;
    }

    /// `Phi` and `Qd` over `[a, dbeta, dw, dm, dc]`, `Qd` made exactly symmetric.
    fn matrices(&self) -> (RateMatrix, RateMatrix) {
        let mut phi = RateMatrix::identity();
        let mut qd = RateMatrix::zeros();
        for (r, &i) in X_STATES.iter().enumerate() {
            for (c, &j) in X_STATES.iter().enumerate() {
                phi[(i, j)] = self.phi_x[(r, c)];
                qd[(i, j)] = self.q_x[(r, c)];
            }
            for (c, &j) in PARAMETER_STATES.iter().enumerate() {
                phi[(i, j)] = self.gamma[(r, c)];
                qd[(i, j)] = self.q_xp[(r, c)];
                qd[(j, i)] = self.q_xp[(r, c)];
            }
        }
        for (r, &i) in PARAMETER_STATES.iter().enumerate() {
            for (c, &j) in PARAMETER_STATES.iter().enumerate() {
                qd[(i, j)] = self.q_p[(r, c)];
            }
        }
        for k in 3..6 {
            qd[(k, k)] = self.q_bias;
        }
        (phi, 0.5 * (qd + qd.transpose()))
    }
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
    let body = model.body_at(&motion.moment_fraction);
    let body = body.as_ref();
    let j0_diag = model.body.inertia_kg_m2().diagonal();
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
    let m = NoiseDensity::at(model, body);
    let mut state = AttitudeState {
        q: *q,
        w_body_rad_s: motion.w_body_rad_s,
    };
    let linearised = |s: &AttitudeState, t: f64| {
        let (r, b) = place(t);
        let at = Motion {
            w_body_rad_s: s.w_body_rad_s,
            ..*motion
        };
        Linearised::at((body, &j0_diag), &s.q, &at, (&r, &b))
    };
    let mut acc = Accumulated::start();
    let mut f0 = linearised(&state, 0.0);
    for i in 0..n {
        let t = i as f64 * h;
        state = rk4_step(body, &state, t, h, &torque_at);
        let f1 = linearised(&state, t + h);
        let mid = Linearised {
            a: (f0.a + f1.a) * 0.5,
            b: (f0.b + f1.b) * 0.5,
        };
        acc.substep(&mid, &m, h);
        f0 = f1;
    }
    let (phi, qd) = acc.matrices();
    RateStep {
        q: state.q,
        w_body_rad_s: state.w_body_rad_s,
        phi,
        qd,
    }
}

/// The rows of `phi` that differ from the identity's (the bias and dipole rows are the
/// identity's: only the attitude and rate rows need the product).
fn moving_rows(phi: &RateMatrix) -> ([usize; RATE_STATES], usize) {
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
pub(crate) fn left_multiply(p: &mut DMatrix<f64>, idx: &RateIndex, phi: &RateMatrix) {
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
pub(crate) fn right_multiply_transpose(p: &mut DMatrix<f64>, idx: &RateIndex, phi: &RateMatrix) {
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
/// `other_noise` on the diagonal elsewhere; `P` symmetric, and kept exactly so.
///
/// After `P1 = Phi P`, only the columns `idx[r]` of the moved rows `r` change in
/// `P1 Phi^T`, and outside the moved rows they are the moved rows of `P1` transposed
/// (`P1[i, :] Phi[r, :]^T = Phi[r, :] P[:, i] = P1[r, i]` for a row `i` that `Phi` left
/// alone, `P` being symmetric): only the block of moved rows and columns needs the product.
pub(crate) fn propagate_covariance(
    p: &mut DMatrix<f64>,
    idx: &RateIndex,
    phi: &RateMatrix,
    qd: &RateMatrix,
    other_noise: &[f64],
) {
    left_multiply(p, idx, phi);
    let (rows, m) = moving_rows(phi);
    let rows = &rows[..m];
    let mut block = [[0.0; RATE_STATES]; RATE_STATES];
    for (a, &ra) in rows.iter().enumerate() {
        for (b, &rb) in rows.iter().enumerate() {
            block[a][b] = (0..RATE_STATES)
                .map(|j| p[(idx[ra], idx[j])] * phi[(rb, j)])
                .sum();
        }
    }
    for &r in rows {
        let k = idx[r];
        for c in 0..p.nrows() {
            p[(c, k)] = p[(k, c)];
        }
    }
    for (a, &ra) in rows.iter().enumerate() {
        for (b, &rb) in rows.iter().enumerate() {
            p[(idx[ra], idx[rb])] = 0.5 * (block[a][b] + block[b][a]);
        }
    }
    add_noise(p, idx, qd, other_noise);
}

/// `P += Q` with `Q` as in [`propagate_covariance`].
pub(crate) fn add_noise(p: &mut DMatrix<f64>, idx: &RateIndex, qd: &RateMatrix, other: &[f64]) {
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
            moment_fraction: Vector3::new(0.05, -0.1, 0.08),
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
        // 0.3 A m^2 dipole, an inertia corrected off the given one and 10 s steps make
        // every block of Phi non-trivial.
        let m = model();
        let q0 = Quat::new_normalized(0.3, -0.5, 0.2, 0.78).expect("non-zero");
        let w0 = Vector3::new(0.06, -0.08, 0.05);
        let d0 = Vector3::new(0.1, -0.2, 0.2);
        let mo = motion(w0, d0);
        let env = environment();
        let dt = 10.0;
        let nominal = propagate(&m, &q0, &mo, &env, dt);
        // The error `[a, dw, dm, dc]` at the start, each a 3-vector.
        let end = |e: [Vector3<f64>; 4]| {
            let start = Motion {
                w_body_rad_s: w0 + e[1],
                dipole_body_a_m2: d0 + e[2],
                moment_fraction: mo.moment_fraction + e[3],
            };
            let s = propagate(&m, &apply_error(&q0, &e[0]), &start, &env, dt);
            let mut x = [0.0; RATE_STATES];
            let da = error_vector(&s.q, &nominal.q);
            let dw1 = s.w_body_rad_s - nominal.w_body_rad_s;
            x[..3].copy_from_slice(da.as_slice());
            x[6..9].copy_from_slice(dw1.as_slice());
            x[9..12].copy_from_slice(e[2].as_slice());
            x[12..].copy_from_slice(e[3].as_slice());
            x
        };
        let h = 1e-6;
        let mut worst: f64 = 0.0;
        for col in (0..3).chain(6..RATE_STATES) {
            let block = if col < 3 { 0 } else { col / 3 - 1 };
            let mut plus_e = [Vector3::zeros(); 4];
            plus_e[block][col % 3] = h;
            let minus_e = plus_e.map(|v| -v);
            let (plus, minus) = (end(plus_e), end(minus_e));
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
        // So do the inertia's: a 1 % moment error turns the attitude by more than 1e-4
        // rad over the step.
        let inertia_to_attitude = nominal.phi.fixed_view::<3, 3>(0, 12).abs().max();
        assert!(inertia_to_attitude > 1e-2, "{inertia_to_attitude:e}");
        // The bias does not enter the dynamics: its columns are the identity.
        for col in 3..6 {
            for row in 0..RATE_STATES {
                let expected = if row == col { 1.0 } else { 0.0 };
                assert_eq!(nominal.phi[(row, col)], expected);
            }
        }
    }

    /// The transition and noise of the module docs with `F` and `M` as dense 15x15
    /// matrices over the same substeps: what [`propagate`]'s blocks must equal.
    fn dense_reference(
        model: &RateModel,
        q: &Quat,
        motion: &Motion,
        env: &StepEnvironment,
        dt: f64,
    ) -> (RateMatrix, RateMatrix) {
        let body = model.body_at(&motion.moment_fraction).into_owned();
        let body = &body;
        let n = (dt / (MAX_SUBSTEP_ROTATION_RAD / motion.w_body_rad_s.norm()).min(1.0)).ceil();
        let h = dt / n;
        let j_inv = body.inertia_kg_m2().try_inverse().expect("invertible");
        let mut m = RateMatrix::zeros();
        for k in 0..3 {
            m[(3 + k, 3 + k)] = model.bias_walk_var_per_s;
            m[(9 + k, 9 + k)] = model.dipole_walk_var_per_s;
        }
        let rate = j_inv * j_inv.transpose() * model.torque_psd;
        m.fixed_view_mut::<3, 3>(6, 6).copy_from(&rate);
        let torque_at = |t: f64, q: &Quat| {
            let (r, b) = env.at(t / dt);
            torque(body, &motion.dipole_body_a_m2, q, (&r, &b))
        };
        let f_at = |s: &AttitudeState, t: f64| {
            let (r, b) = env.at(t / dt);
            let at = Motion {
                w_body_rad_s: s.w_body_rad_s,
                ..*motion
            };
            error_dynamics(model, &s.q, &at, (&r, &b))
        };
        let mut state = AttitudeState {
            q: *q,
            w_body_rad_s: motion.w_body_rad_s,
        };
        let (mut phi, mut qd) = (RateMatrix::identity(), RateMatrix::zeros());
        for i in 0..n as usize {
            let t = i as f64 * h;
            let f0 = f_at(&state, t);
            state = rk4_step(body, &state, t, h, &torque_at);
            let x = (f0 + f_at(&state, t + h)) * (0.5 * h);
            let x2 = x * x;
            let phi_h = RateMatrix::identity() + x + x2 * 0.5 + x2 * x / 6.0 + x2 * x2 / 24.0;
            phi = phi_h * phi;
            qd = phi_h * (qd + m * (0.5 * h)) * phi_h.transpose() + m * (0.5 * h);
        }
        (phi, qd)
    }

    #[test]
    fn blocked_transition_and_noise_equal_the_dense_products() {
        // The blocks skip only products with zero blocks of `F` and `M`: the result is the
        // dense 15x15 computation's to round-off, on a tumble with every block non-zero.
        let m = model();
        let q0 = Quat::new_normalized(0.3, -0.5, 0.2, 0.78).expect("non-zero");
        let mo = motion(
            Vector3::new(0.06, -0.08, 0.05),
            Vector3::new(0.1, -0.2, 0.2),
        );
        let env = environment();
        for dt in [1.0, 10.0] {
            let step = propagate(&m, &q0, &mo, &env, dt);
            let (phi, qd) = dense_reference(&m, &q0, &mo, &env, dt);
            let phi_err = (step.phi - phi).abs().max() / phi.abs().max();
            let qd_err = (step.qd - qd).abs().max() / qd.abs().max();
            assert!(phi_err < 1e-13, "dt {dt}: Phi {phi_err:e}");
            assert!(qd_err < 1e-12, "dt {dt}: Qd {qd_err:e}");
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
        let mo = Motion {
            moment_fraction: Vector3::zeros(),
            ..motion(Vector3::zeros(), d)
        };
        let f = error_dynamics(&m, &q, &mo, (&r, &b));
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
            // The inertia's correction is a constant: no noise; the rest is positive.
            assert!(
                qd.fixed_view::<12, 12>(0, 0)
                    .into_owned()
                    .cholesky()
                    .is_some()
            );
            assert_eq!(qd.fixed_view::<3, 3>(12, 12).abs().max(), 0.0);
        }
        assert!(long[(6, 6)] > 5.0 * short[(6, 6)]);
        // The attitude error accumulates the rate noise: ~ S dt^3 / (3 J^2).
        assert!(long[(0, 0)] > 100.0 * short[(0, 0)]);
    }

    #[test]
    fn indexed_propagation_equals_the_dense_product() {
        let n = 20;
        let idx = [0, 1, 2, 3, 4, 5, 11, 12, 13, 14, 15, 16, 17, 18, 19];
        let a = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 3) % 11) as f64 / 10.0 - 0.4);
        let mut p = &a * a.transpose() + DMatrix::identity(n, n);
        // Rows 3..6 the identity's, as the bias rows are (the product skips them).
        let phi15 = RateMatrix::from_fn(|i, j| match i {
            3..6 => (i == j) as u8 as f64,
            _ => ((i + 2 * j) % 5) as f64 * 0.1 + (i == j) as u8 as f64,
        });
        let qd15 = RateMatrix::identity() * 0.01;
        let other: Vec<f64> = (0..n).map(|k| 0.001 * k as f64).collect();
        let mut phi = DMatrix::identity(n, n);
        let mut q = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(other.clone()));
        for (r, &i) in idx.iter().enumerate() {
            q[(i, i)] = 0.0;
            for (c, &j) in idx.iter().enumerate() {
                phi[(i, j)] = phi15[(r, c)];
                q[(i, j)] = qd15[(r, c)];
            }
        }
        let expected = &phi * &p * phi.transpose() + q;
        propagate_covariance(&mut p, &idx, &phi15, &qd15, &other);
        assert!((p - expected).abs().max() < 1e-12);
    }
}
