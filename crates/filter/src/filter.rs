//! The calibration MEKF: state, covariance, propagation (paper Eqs. 8-10 with the MEKF
//! kinematics and Eq. 19), sequential scalar updates (Eqs. 4-7 with Eqs. 15, 20-24 and the
//! magnetometer) and the multiplicative reset.

use std::borrow::Cow;

use nalgebra::{DMatrix, DVector, Dyn, Matrix2, Matrix3, Matrix6, OMatrix, U6, Vector3};
use pdcal_albedo::LinearAlbedo;
use pdcal_attitude::mekf::{apply_small_error, process_noise, state_transition};
use pdcal_attitude::{GyroNoise, Quat, rotate_normal_in, skew};
use pdcal_ephem::Reference;
use pdcal_photodiode::{AlbedoIrradiance, MeasurementModel, Partials, Scene};

use crate::FilterError;
use crate::algebra::{self, Pending};
use crate::calibration::{Calibration, ParameterEstimate, PdCalibration};
use crate::dense;
use crate::error::check_len;
use crate::guard::{self, CovarianceRepair};
use crate::layout::{ATTITUDE, BIAS, CORE, StateLayout};
use crate::rate::{Motion, RateIndex, RateMatrix, RateModel, StepEnvironment};
use crate::sequential::{self, Outcome, Rows, Workspace};

/// How the covariance algebra is done. Both give the same numbers to rounding (a test
/// holds them to 1e-9); `Dense` is the textbook form kept as the reference and for the
/// benchmark comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Algebra {
    /// `Phi` touches only the 6 attitude/bias rows; H rows are sparse; the step's rank-1
    /// updates are deferred and applied as one rank-k product.
    #[default]
    Structured,
    /// Full `Phi P Phi^T + Q`, full H rows, dense gain and Joseph form.
    Dense,
}

/// Noise and gating numbers the filter runs with (resolved from [`crate::FilterConfig`]).
#[derive(Debug, Clone, PartialEq)]
pub struct FilterNoise {
    /// Gyro angle random walk (already inflated) and bias random walk.
    pub gyro: GyroNoise,
    /// Extra attitude noise per step as a fraction of `|w_k - w_k-1| dt`.
    pub rate_change_fraction: f64,
    /// Scale random-walk variance per second, per photodiode, V^2/s (Eq. 19).
    pub scale_walk_var_per_s: Vec<f64>,
    /// Normal random-walk variance per second per tangent axis, rad^2/s (Eq. 19).
    pub normal_walk_var_per_s: f64,
    /// Random-walk variance per second of each extra state, in [`StateLayout::extras`] order.
    pub extra_walk_var_per_s: Vec<f64>,
    /// Photodiode noise sigma, V.
    pub photodiode_sigma_v: f64,
    /// Albedo-model uncertainty of one row as a fraction of `E_AM0`: R adds `(C this)^2`,
    /// less the part the albedo gain state carries ([`FilterNoise::albedo_gain`]).
    pub albedo_sigma_ratio: f64,
    /// The albedo's error correlated in time, as a gain state; `None`: the albedo error
    /// is white only (`albedo_sigma_ratio`).
    pub albedo_gain: Option<AlbedoGainNoise>,
    /// Magnetometer sigma per axis, nT.
    pub mag_sigma_nt: f64,
    /// Gate in sigmas: each photodiode row `nu^2 <= g^2 s`; the magnetometer's 3-vector by
    /// its Mahalanobis distance at the chi-square (3 dof) threshold of the same tail
    /// probability ([`crate::gate`]).
    pub gate_sigmas: f64,
    /// Cosine of the largest incidence angle used.
    pub cos_fov: f64,
    /// Smallest illuminated fraction for photodiode updates.
    pub min_sun_fraction: f64,
    /// Add the second-order (curvature) variance of the measurement functions to R.
    pub second_order: bool,
}

/// The albedo gain `g` (the albedo seen is `(1 + g)` times the modelled one, Eq. 15's
/// second term) as a first-order Gauss-Markov process: `g(t + dt) = e^(-dt/tau) g(t) + w`
/// with stationary variance `sigma^2` (`var w = sigma^2 (1 - e^(-2 dt/tau))`). A
/// reflectivity map is a mean; the Earth under the satellite has today's clouds, and the
/// difference persists while the footprint crosses one region, so it is a state, not
/// white noise: as white noise, averaged over hundreds of rows, it would shrink the
/// calibration's sigmas below its errors.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AlbedoGainNoise {
    /// Stationary sigma of `g` (dimensionless).
    pub sigma: f64,
    /// Correlation time `tau`, s.
    pub time_s: f64,
}

impl AlbedoGainNoise {
    /// The transition `e^(-dt/tau)` over `dt_s` (negative steps count as none).
    pub fn decay(&self, dt_s: f64) -> f64 {
        (-dt_s.max(0.0) / self.time_s).exp()
    }
}

/// The state the filter starts from.
#[derive(Debug, Clone, PartialEq)]
pub struct InitialState {
    /// Attitude, GCRF -> body.
    pub q: Quat,
    /// Attitude-error covariance, rad^2, body frame.
    pub attitude_cov: Matrix3<f64>,
    /// Gyro bias, rad/s.
    pub bias_rad_s: Vector3<f64>,
    /// Gyro-bias sigma per axis, rad/s.
    pub bias_sigma_rad_s: f64,
    /// Scale factors, V (also written to the model's photodiodes).
    pub scale_v: Vec<f64>,
    /// Their sigmas, V.
    pub scale_sigma_v: Vec<f64>,
    /// Unit normals, body frame.
    pub n_body: Vec<Vector3<f64>>,
    /// Sigma per tangent axis of the normals, rad (ignored without normal states).
    pub normal_sigma_rad: f64,
    /// Initial sigma of each extra state, in [`StateLayout::extras`] order.
    pub extra_sigma: Vec<f64>,
    /// Which photodiodes take part (a never-lit one does not).
    pub used: Vec<bool>,
}

/// Which sensor a scalar update came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sensor {
    /// Photodiode, zero-based index.
    Photodiode(usize),
    /// Magnetometer axis 0, 1, 2 (body x, y, z).
    Magnetometer(usize),
}

/// One scalar update: the innovation against its predicted spread.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpdateRecord {
    /// Sensor.
    pub sensor: Sensor,
    /// Measured value (V or nT).
    pub measured: f64,
    /// Residual (Eq. 25): measured minus predicted at the current estimate, including the
    /// corrections of the scalar updates before it in the same step.
    pub residual: f64,
    /// `3 sqrt(H P H^T + R)`.
    pub bound_3sigma: f64,
    /// Whether the update was applied (false: rejected by the gate).
    pub accepted: bool,
    /// The residual after the whole step's correction, linearised (`y - h(x_0) - H dx`):
    /// for a model that explains the data, within the sensor noise.
    pub post_fit: f64,
}

/// Counts of one sensor class.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SensorCounts {
    /// Scalar updates applied.
    pub accepted: usize,
    /// Scalar updates rejected by the innovation gate.
    pub gated: usize,
    /// Samples not used: not sampled (empty cell).
    pub not_sampled: usize,
    /// Photodiode samples not used: eclipse or penumbra.
    pub shadowed: usize,
    /// Photodiode samples not used: Sun behind or outside the field of view (by the estimate).
    pub outside_fov: usize,
    /// Photodiode samples not used: the photodiode never lit in the data set.
    pub unused_sensor: usize,
    /// Photodiode samples outside the field of view (by the estimate) that read more than
    /// any light from there could give ([`Filter::contradicted`]); counted here, not in
    /// `outside_fov`.
    pub contradicted: usize,
}

/// Counts per sensor class.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct UpdateCounts {
    /// Photodiode scalar updates.
    pub photodiode: SensorCounts,
    /// Magnetometer scalar updates (one per axis; the three axes of a sample are gated
    /// together, so `gated` grows by 3 per rejected sample).
    pub magnetometer: SensorCounts,
}

/// The measurements of one sample.
#[derive(Debug, Clone, Copy)]
pub struct Measurements<'a> {
    /// Magnetometer, body, nT (`None`: not sampled or not used).
    pub mag_nt: Option<Vector3<f64>>,
    /// Photodiode outputs, V, one per photodiode (`None`: not sampled).
    pub pd_v: &'a [Option<f64>],
    /// Photodiode temperatures, degrees Celsius, one per photodiode (empty: none in the
    /// telemetry; NaN: none for that photodiode).
    pub temperature_c: &'a [f64],
}

/// The 6x6 transition and process noise of one propagation, plus the diagonal process
/// noise of the calibration states over the same step (kept for the smoother).
#[derive(Debug, Clone, PartialEq)]
pub struct Propagation {
    /// `Phi` of `[a, beta]`.
    pub phi: Matrix6<f64>,
    /// `Qd` of `[a, beta]`.
    pub qd: Matrix6<f64>,
    /// Step, s.
    pub dt_s: f64,
    /// The albedo gain's transition `e^(-dt/tau)` over the step (1 without the state).
    pub albedo_gain_decay: f64,
    /// With dynamics ([`crate::rate`]): `Phi` and `Qd` of `[a, beta, w, m, c]` (`phi` and `qd`
    /// above are then unused) and the body rate the step ended with.
    pub rate: Option<Box<RatePropagation>>,
}

/// One dynamics-aided propagation as the smoother needs it.
#[derive(Debug, Clone, PartialEq)]
pub struct RatePropagation {
    /// `Phi` of `[a, beta, w, m, c]`.
    pub phi: RateMatrix,
    /// `Qd` of `[a, beta, w, m, c]`.
    pub qd: RateMatrix,
    /// The states `[a, beta, w, m, c]` index.
    pub idx: RateIndex,
    /// Body rate at the end of the step (the prior), rad/s.
    pub w_prior_body_rad_s: Vector3<f64>,
}

/// The filter's body-rate state with dynamics ([`Filter::enable_dynamics`]).
#[derive(Debug, Clone)]
struct RateFilter {
    model: RateModel,
    /// `[a, beta, w, m, c]` state indices.
    idx: RateIndex,
    motion: Motion,
    /// Gyro noise variance per sample, (rad/s)^2.
    gyro_var: f64,
}

/// The filter.
pub struct Filter {
    layout: StateLayout,
    model: MeasurementModel,
    noise: FilterNoise,
    /// Squared Mahalanobis threshold of the magnetometer vector (from `noise.gate_sigmas`).
    mag_gate2: f64,
    algebra: Algebra,
    q: Quat,
    bias: Vector3<f64>,
    /// Per photodiode, the tangent basis of its normal estimate. The scale and normal
    /// estimates themselves live in `model`'s photodiodes, their one owner, which the
    /// reset writes ([`Filter::reset_photodiodes`]).
    basis: Vec<(Vector3<f64>, Vector3<f64>)>,
    used: Vec<bool>,
    rate_est: Vector3<f64>,
    /// The albedo gain estimate `g` (0 without the state).
    albedo_gain: f64,
    p: DMatrix<f64>,
    /// The diagonal of the initial covariance (what a state the guard resets returns to).
    initial_variance: Vec<f64>,
    scratch: Scratch,
    records: Vec<UpdateRecord>,
    /// This step's photodiode samples the estimate contradicts ([`Filter::contradicted`]).
    contradicted: Vec<UpdateRecord>,
    counts: UpdateCounts,
    last: Option<Propagation>,
    /// The Sun is the only vector ([`Filter::set_sun_only`]).
    sun_only: bool,
    /// The unit Sun direction in the body at the current step's prior attitude.
    prior_sun_body: Vector3<f64>,
    /// The body-rate state and its dynamics, when enabled.
    rate: Option<RateFilter>,
}

/// What the next step of a [`Filter`] reads of its past: a restart point
/// ([`Filter::state`], [`Filter::restore`]). The work space is not part of it: every step
/// overwrites what it reads of it.
#[derive(Debug, Clone, PartialEq)]
pub struct FilterState {
    q: Quat,
    bias: Vector3<f64>,
    scale: Vec<f64>,
    normal: Vec<Vector3<f64>>,
    basis: Vec<(Vector3<f64>, Vector3<f64>)>,
    rate_est: Vector3<f64>,
    albedo_gain: f64,
    p: DMatrix<f64>,
    parameters: Vec<f64>,
    counts: UpdateCounts,
    last: Option<Propagation>,
    motion: Option<Motion>,
}

/// Preallocated work space: nothing is allocated per step.
struct Scratch {
    dx: DVector<f64>,
    rows6: OMatrix<f64, U6, Dyn>,
    partials: Partials,
    cal_noise: DVector<f64>,
    /// The step's scalar rows, linearised at the prior, and per row its sensor and
    /// measured value.
    rows: Rows,
    sources: Vec<(Sensor, f64)>,
    /// What became of each row.
    outcome: Vec<Outcome>,
    work: Workspace,
    /// Columns `w_l = P_{l-1} H_l^T / sqrt(s_l)` of this step's accepted updates, applied
    /// at the end as one rank-k downdate of the lower triangle ([`algebra::apply_pending`]).
    pending: Pending,
    /// The photodiodes this step updates ([`Filter::select_photodiodes`]).
    selected: Vec<Selected>,
    /// The photodiodes whose normal the reset moved ([`Filter::reset_photodiodes`]).
    moved: Vec<usize>,
    /// This step's albedo per selected photodiode, evaluated at the prior
    /// ([`Filter::prior_albedo`]).
    albedo: AlbedoScratch,
}

/// A linearisation point of the states the photodiode rows depend on
/// ([`Filter::update_about`]).
#[derive(Debug, Clone)]
pub struct Nominal {
    /// Attitude.
    pub q: Quat,
    /// Gyro bias, rad/s.
    pub bias: Vector3<f64>,
    /// Scale factor per photodiode, V.
    pub scale_v: Vec<f64>,
    /// Unit normal per photodiode, body.
    pub n_body: Vec<Vector3<f64>>,
}

/// A photodiode this step updates.
#[derive(Debug, Clone, Copy)]
struct Selected {
    index: usize,
    measured_v: f64,
    /// `n . s` at the prior.
    cos_incidence: f64,
}

/// The step's albedo evaluations, one per selected photodiode: its normal in GCRF at the
/// prior attitude, its field-of-view cosine and the result.
#[derive(Default)]
struct AlbedoScratch {
    normals_gcrf: Vec<Vector3<f64>>,
    cos_fov: Vec<f64>,
    results: Vec<(f64, Vector3<f64>)>,
    /// The results as [`AlbedoIrradiance`]s for the model.
    linear: Vec<LinearAlbedo>,
}

impl Filter {
    /// A filter over `model` (its photodiodes get the initial scales and normals and keep
    /// their fields of view) with the state `layout` built from the same model.
    pub fn new(
        mut model: MeasurementModel,
        mut layout: StateLayout,
        init: InitialState,
        noise: FilterNoise,
        algebra: Algebra,
    ) -> Result<Self, FilterError> {
        let m = model.photodiodes().len();
        if noise.albedo_gain.is_some() {
            layout.add_albedo_gain();
        }
        let n = layout.len();
        for (what, len) in [
            ("initial scales", init.scale_v.len()),
            ("initial scale sigmas", init.scale_sigma_v.len()),
            ("initial normals", init.n_body.len()),
            ("used flags", init.used.len()),
            ("scale walk variances", noise.scale_walk_var_per_s.len()),
        ] {
            check_len(what, m, len)?;
        }
        check_len("layout photodiodes", m, layout.photodiodes())?;
        check_len(
            "extra sigmas",
            layout.extras().len(),
            init.extra_sigma.len(),
        )?;
        check_len(
            "extra walks",
            layout.extras().len(),
            noise.extra_walk_var_per_s.len(),
        )?;
        let mut p = DMatrix::zeros(n, n);
        p.fixed_view_mut::<3, 3>(ATTITUDE, ATTITUDE)
            .copy_from(&(0.5 * (init.attitude_cov + init.attitude_cov.transpose())));
        for k in 0..3 {
            p[(BIAS + k, BIAS + k)] = init.bias_sigma_rad_s.powi(2);
        }
        for i in 0..m {
            p[(layout.scale(i), layout.scale(i))] = init.scale_sigma_v[i].powi(2);
            if let Some(d) = layout.normal(i) {
                p[(d, d)] = init.normal_sigma_rad.powi(2);
                p[(d + 1, d + 1)] = init.normal_sigma_rad.powi(2);
            }
        }
        for (e, s) in layout.extras().iter().zip(&init.extra_sigma) {
            p[(e.state, e.state)] = s * s;
        }
        if let (Some(g), Some(gain)) = (layout.albedo_gain(), noise.albedo_gain) {
            p[(g, g)] = gain.sigma * gain.sigma;
        }
        let normal: Vec<Vector3<f64>> = init.n_body.iter().map(|n| n.normalize()).collect();
        layout.set_reference_normals(&normal);
        set_estimates(&mut model, &init.scale_v, &normal);
        let partials = Partials {
            d_parameters: vec![0.0; model.parameter_count()],
            ..Partials::default()
        };
        Ok(Filter {
            basis: (0..normal.len())
                .map(|i| layout.tangent_basis(i, &normal[i]))
                .collect(),
            scratch: Scratch {
                dx: DVector::zeros(n),
                rows6: OMatrix::<f64, U6, Dyn>::zeros(n),
                partials,
                cal_noise: DVector::zeros(n),
                rows: Rows::with_capacity(3 + m, 9 + m * layout.max_row_len()),
                sources: Vec::with_capacity(3 + m),
                outcome: Vec::with_capacity(3 + m),
                work: Workspace::default(),
                pending: Pending::new(n, 3 + m),
                selected: Vec::with_capacity(m),
                moved: Vec::with_capacity(m),
                albedo: AlbedoScratch {
                    normals_gcrf: Vec::with_capacity(m),
                    cos_fov: Vec::with_capacity(m),
                    results: Vec::with_capacity(m),
                    linear: Vec::with_capacity(m),
                },
            },
            layout,
            model,
            mag_gate2: crate::gate::chi_square_3_threshold(noise.gate_sigmas),
            noise,
            algebra,
            q: init.q,
            bias: init.bias_rad_s,
            used: init.used,
            rate_est: Vector3::zeros(),
            albedo_gain: 0.0,
            initial_variance: p.diagonal().iter().copied().collect(),
            p,
            records: Vec::with_capacity(3 + m),
            contradicted: Vec::new(),
            counts: UpdateCounts::default(),
            last: None,
            sun_only: false,
            prior_sun_body: Vector3::zeros(),
            rate: None,
        })
    }

    /// Adds the body rate `w`, the residual dipole `m` and the inertia's moment correction
    /// `c` as three states each (last in the layout) propagated by `model`'s dynamics
    /// ([`crate::rate`]): [`Filter::propagate_dynamics`] then replaces
    /// [`Filter::propagate`], and [`Filter::update_gyro`] takes the gyro as a measurement
    /// of `w + beta` with variance `gyro_sigma_rad_s^2`. The rate starts from `w0` with
    /// sigma `w_sigma_rad_s` per axis, the dipole from zero with sigma `dipole_sigma_a_m2`
    /// per axis, `c` from zero with the model's [`RateModel::moment_sigma`], uncorrelated.
    pub fn enable_dynamics(
        &mut self,
        model: RateModel,
        (w0_body_rad_s, w_sigma_rad_s): (Vector3<f64>, f64),
        dipole_sigma_a_m2: f64,
        gyro_sigma_rad_s: f64,
    ) {
        let index = self.layout.add_rate_states();
        let n = self.layout.len();
        if self.p.nrows() != n {
            self.p = self.p.clone().resize(n, n, 0.0);
            for k in index..index + 3 {
                self.p[(k, k)] = w_sigma_rad_s * w_sigma_rad_s;
                self.p[(k + 3, k + 3)] = dipole_sigma_a_m2 * dipole_sigma_a_m2;
                self.p[(k + 6, k + 6)] = model.moment_sigma().powi(2);
            }
            self.initial_variance = self.p.diagonal().iter().copied().collect();
            let m = self.used.len();
            self.scratch.dx = DVector::zeros(n);
            self.scratch.cal_noise = DVector::zeros(n);
            self.scratch.pending = Pending::new(n, 6 + m);
        }
        self.rate_est = w0_body_rad_s;
        let mut idx = [0; crate::rate::RATE_STATES];
        for (k, slot) in idx.iter_mut().enumerate() {
            *slot = if k < 6 { k } else { index + k - 6 };
        }
        self.rate = Some(RateFilter {
            model,
            idx,
            motion: Motion {
                w_body_rad_s: w0_body_rad_s,
                dipole_body_a_m2: Vector3::zeros(),
                moment_fraction: Vector3::zeros(),
            },
            gyro_var: gyro_sigma_rad_s * gyro_sigma_rad_s,
        });
    }

    /// Whether the body rate is a state ([`Filter::enable_dynamics`]).
    pub fn has_dynamics(&self) -> bool {
        self.rate.is_some()
    }

    /// The body-rate estimate, rad/s: the state with dynamics, else the bias-corrected gyro
    /// rate of the last propagation.
    pub fn rate_body_rad_s(&self) -> Vector3<f64> {
        self.rate
            .as_ref()
            .map_or(self.rate_est, |r| r.motion.w_body_rad_s)
    }

    /// The residual-dipole estimate, body frame, A m^2, with dynamics.
    pub fn dipole_body_a_m2(&self) -> Option<Vector3<f64>> {
        self.rate.as_ref().map(|r| r.motion.dipole_body_a_m2)
    }

    /// The nominal states of the dynamics, with dynamics.
    pub(crate) fn motion(&self) -> Option<Motion> {
        self.rate.as_ref().map(|r| r.motion)
    }

    /// Sets the body-rate state to `w0` with sigma `w_sigma_rad_s` per axis, uncorrelated
    /// (an acquisition); nothing without dynamics.
    pub fn set_rate(&mut self, w0_body_rad_s: Vector3<f64>, w_sigma_rad_s: f64) {
        let Some(r) = self.rate.as_mut() else {
            return;
        };
        r.motion.w_body_rad_s = w0_body_rad_s;
        for &k in &r.idx[6..9] {
            self.p.row_mut(k).fill(0.0);
            self.p.column_mut(k).fill(0.0);
            self.p[(k, k)] = w_sigma_rad_s * w_sigma_rad_s;
        }
    }

    /// Propagates over `dt_s` by the rigid-body dynamics ([`crate::rate`]) through `env`
    /// (position and reference field at both ends): attitude and rate integrated, `P <- Phi
    /// P Phi^T + Q` with `Phi` on `[a, beta, w, m]` and identity elsewhere, the calibration
    /// states a random walk (Eq. 19). Without dynamics, nothing.
    pub fn propagate_dynamics(&mut self, env: &StepEnvironment, dt_s: f64) {
        let Some(r) = self.rate.as_mut() else {
            return;
        };
        let step = crate::rate::propagate(&r.model, &self.q, &r.motion, env, dt_s);
        self.q = step.q;
        r.motion.w_body_rad_s = step.w_body_rad_s;
        self.rate_est = step.w_body_rad_s;
        let idx = r.idx;
        let albedo_gain_decay = self.decay_albedo_gain(dt_s);
        self.fill_calibration_noise(dt_s);
        crate::rate::propagate_covariance(
            &mut self.p,
            &idx,
            &step.phi,
            &step.qd,
            self.scratch.cal_noise.as_slice(),
        );
        self.last = Some(Propagation {
            phi: Matrix6::identity(),
            qd: Matrix6::zeros(),
            dt_s,
            albedo_gain_decay,
            rate: Some(Box::new(RatePropagation {
                phi: step.phi,
                qd: step.qd,
                idx,
                w_prior_body_rad_s: step.w_body_rad_s,
            })),
        });
    }

    /// The gyro sample `gyro_rad_s` as a measurement of `w + beta` (three scalar rows,
    /// gated like the photodiodes'), with the reset. Without dynamics, nothing.
    pub fn update_gyro(&mut self, gyro_rad_s: &Vector3<f64>) -> Result<(), FilterError> {
        let Some(r) = self.rate.as_ref() else {
            return Ok(());
        };
        let s = &mut self.scratch;
        s.rows.clear();
        let predicted = r.motion.w_body_rad_s + self.bias;
        for k in 0..3 {
            s.rows.begin(gyro_rad_s[k] - predicted[k], r.gyro_var);
            s.rows.entry(BIAS + k, 1.0);
            s.rows.entry(r.idx[6 + k], 1.0);
        }
        self.run_rows();
        if self.scratch.outcome.iter().any(|o| o.accepted) {
            self.reset()?;
        }
        Ok(())
    }

    /// Propagates over `dt_s` with the measured rate `gyro_rad_s` (held or averaged by the
    /// caller) and the measured rate change since the previous sample (for the extra
    /// attitude noise): `q <- dq((w - beta) dt) ⊗ q`, `P <- Phi P Phi^T + Q` with `Phi` the
    /// MEKF's 6x6 block and identity elsewhere, calibration states a random walk (Eq. 19).
    pub fn propagate(&mut self, gyro_rad_s: &Vector3<f64>, rate_change_rad_s: f64, dt_s: f64) {
        let rate = gyro_rad_s - self.bias;
        self.rate_est = rate;
        self.q = pdcal_attitude::mekf::propagate(&self.q, &rate, dt_s);
        let phi = state_transition(&rate, dt_s);
        let mut qd = process_noise(&rate, dt_s, &self.noise.gyro);
        let extra = (self.noise.rate_change_fraction * rate_change_rad_s * dt_s).powi(2);
        for k in 0..3 {
            qd[(k, k)] += extra;
        }
        let albedo_gain_decay = self.decay_albedo_gain(dt_s);
        self.fill_calibration_noise(dt_s);
        match self.algebra {
            Algebra::Structured => self.propagate_structured(&phi, &qd),
            Algebra::Dense => dense::propagate(&mut self.p, &phi, &qd, &self.scratch.cal_noise),
        }
        self.last = Some(Propagation {
            phi,
            qd,
            dt_s,
            albedo_gain_decay,
            rate: None,
        });
    }

    /// Starts a new segment `dt_s` after the last processed row (a gap, or an attitude
    /// declared lost): the calibration states and the gyro bias keep their estimates, their
    /// covariance grown by their random walks over `dt_s` (Eq. 19; the bias walk of the
    /// gyro model); the attitude becomes `q` with covariance `attitude_cov`, uncorrelated
    /// with every other state (it was acquired from the new segment's own samples). No
    /// propagation leads to the next update: the smoother starts afresh there.
    pub fn reacquire(&mut self, q: Quat, attitude_cov: &Matrix3<f64>, dt_s: f64) {
        let n = self.p.nrows();
        let dt_s = dt_s.max(0.0);
        self.decay_albedo_gain(dt_s);
        self.fill_calibration_noise(dt_s);
        for k in CORE..n {
            self.p[(k, k)] += self.scratch.cal_noise[k];
        }
        let bias_walk = self.noise.gyro.sigma_u_rad_s_sqrt_s.powi(2) * dt_s;
        for k in 0..3 {
            self.p[(BIAS + k, BIAS + k)] += bias_walk;
        }
        if let Some(r) = &self.rate {
            // The unknown torque's walk of the rate over the gap (the rate keeps its value:
            // the gyro or the vector measurements correct it).
            let body = r.model.body_at(&r.motion.moment_fraction);
            let j_inv = body.inertia_inv();
            let walk = j_inv * j_inv.transpose() * (r.model.torque_psd * dt_s);
            let k = r.idx[6];
            let mut block = self.p.fixed_view_mut::<3, 3>(k, k);
            block += walk;
        }
        for k in ATTITUDE..ATTITUDE + 3 {
            self.p.row_mut(k).fill(0.0);
            self.p.column_mut(k).fill(0.0);
        }
        self.p
            .fixed_view_mut::<3, 3>(ATTITUDE, ATTITUDE)
            .copy_from(&(0.5 * (attitude_cov + attitude_cov.transpose())));
        self.q = q;
        self.last = None;
    }

    /// After a Sun-only acquisition ([`Filter::reacquire`]): the attitude error becomes
    /// `a = J dc + w`, `dc` the photodiodes' calibration errors (`J` from `sensitivity`,
    /// its normal part applied to each normal's tangent basis) and `w` the acquisition's
    /// own error (the covariance `reacquire` set): `P_ax = J P_cx` for every other state
    /// `x`, `P_aa += J P_cc J^T`. The Sun direction the outputs give is only as good as
    /// the calibration that turned them into a direction; held as independent, the
    /// filter would take the outputs' agreement with a wrong calibration for knowledge
    /// of both.
    pub fn correlate_attitude(&mut self, sensitivity: &[crate::init::PdSensitivity]) {
        let mut cols: Vec<(usize, Vector3<f64>)> = Vec::new();
        for s in sensitivity {
            cols.push((self.layout.scale(s.pd), s.d_scale));
            if let Some(d) = self.layout.normal(s.pd) {
                let (e1, e2) = &self.basis[s.pd];
                cols.push((d, s.d_normal * e1));
                cols.push((d + 1, s.d_normal * e2));
            }
        }
        let n = self.p.nrows();
        let mut b = nalgebra::Matrix3xX::<f64>::zeros(n);
        for &(idx, col) in &cols {
            for x in 0..n {
                let v = self.p[(idx, x)];
                if v != 0.0 {
                    let mut column = b.column_mut(x);
                    column += col * v;
                }
            }
        }
        let mut added = Matrix3::zeros();
        for &(idx, col) in &cols {
            added += b.column(idx) * col.transpose();
        }
        for x in 0..n {
            if (ATTITUDE..ATTITUDE + 3).contains(&x) {
                continue;
            }
            for r in 0..3 {
                self.p[(ATTITUDE + r, x)] = b[(r, x)];
                self.p[(x, ATTITUDE + r)] = b[(r, x)];
            }
        }
        let mut p_aa = self.p.fixed_view_mut::<3, 3>(ATTITUDE, ATTITUDE);
        p_aa += 0.5 * (added + added.transpose());
    }

    /// The attitude-error covariance given the photodiodes' calibration states (scale and
    /// normal of each; rad^2):
    /// `P_aa - P_ac P_cc^-1 P_ca`, the attitude relative to the frame the photodiodes'
    /// normals define. `None` when `P_cc` is not positive definite.
    pub fn attitude_cov_given_calibration(&self) -> Option<Matrix3<f64>> {
        let cal: Vec<usize> = (0..self.layout.photodiodes())
            .flat_map(|i| {
                let normal = self.layout.normal(i);
                [Some(self.layout.scale(i)), normal, normal.map(|d| d + 1)]
            })
            .flatten()
            .filter(|&k| self.p[(k, k)] > 0.0)
            .collect();
        if cal.is_empty() {
            return Some(self.p.fixed_view::<3, 3>(ATTITUDE, ATTITUDE).into_owned());
        }
        let p_cc = DMatrix::from_fn(cal.len(), cal.len(), |r, c| self.p[(cal[r], cal[c])]);
        let p_ca = DMatrix::from_fn(cal.len(), 3, |r, c| self.p[(cal[r], ATTITUDE + c)]);
        let solved = p_cc.cholesky()?.solve(&p_ca);
        let reduction = p_ca.transpose() * solved;
        let p_aa = self.p.fixed_view::<3, 3>(ATTITUDE, ATTITUDE);
        Some(Matrix3::from_fn(|r, c| p_aa[(r, c)] - reduction[(r, c)]))
    }

    /// The gyro bias back to its prior: zero, `sigma_rad_s` per axis, uncorrelated with
    /// every other state (a gyro turned on anew).
    pub fn restart_bias(&mut self, sigma_rad_s: f64) {
        for k in BIAS..BIAS + 3 {
            self.p.row_mut(k).fill(0.0);
            self.p.column_mut(k).fill(0.0);
            self.p[(k, k)] = sigma_rad_s * sigma_rad_s;
        }
        self.bias = Vector3::zeros();
    }

    /// Fuses a batch fit's scalar measurements of the bias ([`crate::bias_fit::BiasRow`]:
    /// `u . b = y` with variance `r`) as Kalman updates of the whole state (Eqs. 4-7 with
    /// `H = [0, u^T, 0]`), so the calibration states move with their correlation to the
    /// bias. Refused whole, the state unchanged, when a row's innovation lies beyond the
    /// gate (`nu^2 > g^2 (u^T P u + r)`, at the state before the fit): the fit then
    /// contradicts what the filter holds. True when fused.
    pub fn fuse_bias(&mut self, rows: &[crate::bias_fit::BiasRow]) -> Result<bool, FilterError> {
        let gate2 = self.noise.gate_sigmas.powi(2);
        let p_bb = self.p.fixed_view::<3, 3>(BIAS, BIAS).into_owned();
        let contradicts = rows.iter().any(|row| {
            let nu = row.value_rad_s - row.direction.dot(&self.bias);
            let spread = (row.direction.transpose() * p_bb * row.direction)[0] + row.variance;
            nu * nu > gate2 * spread
        });
        if contradicts {
            return Ok(false);
        }
        self.scratch.dx.fill(0.0);
        let idx = [BIAS, BIAS + 1, BIAS + 2];
        for row in rows {
            let u = row.direction;
            let h_dx: f64 = (0..3).map(|k| u[k] * self.scratch.dx[BIAS + k]).sum();
            let nu = row.value_rad_s - u.dot(&self.bias) - h_dx;
            dense::joseph_update(
                &mut self.p,
                &mut self.scratch.dx,
                &idx,
                u.as_slice(),
                nu,
                row.variance,
            );
        }
        self.reset()?;
        Ok(true)
    }

    /// The albedo gain's Gauss-Markov transition over `dt_s`: its estimate and its row and
    /// column of `P` times `e^(-dt/tau)`, before the step's own transition (they act on
    /// different states, so the order does not matter) and before its noise
    /// ([`Filter::fill_calibration_noise`]). The factor; 1 without the state.
    fn decay_albedo_gain(&mut self, dt_s: f64) -> f64 {
        let (Some(g), Some(gain)) = (self.layout.albedo_gain(), self.noise.albedo_gain) else {
            return 1.0;
        };
        let decay = gain.decay(dt_s);
        self.albedo_gain *= decay;
        let n = self.p.nrows();
        for k in 0..n {
            self.p[(g, k)] *= decay;
        }
        for k in 0..n {
            self.p[(k, g)] *= decay;
        }
        decay
    }

    /// Diagonal calibration-state process noise over `dt_s` into `scratch.cal_noise`
    /// (entries 0..6 stay zero); for the albedo gain, the Gauss-Markov process noise
    /// `sigma^2 (1 - e^(-2 dt/tau))`.
    fn fill_calibration_noise(&mut self, dt_s: f64) {
        let q = &mut self.scratch.cal_noise;
        for i in 0..self.layout.photodiodes() {
            q[self.layout.scale(i)] = self.noise.scale_walk_var_per_s[i] * dt_s;
            if let Some(d) = self.layout.normal(i) {
                q[d] = self.noise.normal_walk_var_per_s * dt_s;
                q[d + 1] = self.noise.normal_walk_var_per_s * dt_s;
            }
        }
        for (e, v) in self
            .layout
            .extras()
            .iter()
            .zip(&self.noise.extra_walk_var_per_s)
        {
            q[e.state] = v * dt_s;
        }
        if let (Some(g), Some(gain)) = (self.layout.albedo_gain(), self.noise.albedo_gain) {
            q[g] = gain.sigma * gain.sigma * (1.0 - gain.decay(dt_s).powi(2));
        }
    }

    /// `P <- Phi P Phi^T + Q` using `Phi = diag(Phi6, I)`: only the first 6 rows and
    /// columns change (`18 n` instead of `2 n^3` multiply-adds: `Phi6`'s bias rows are
    /// `[0 I]`).
    fn propagate_structured(&mut self, phi: &Matrix6<f64>, qd: &Matrix6<f64>) {
        let n = self.p.nrows();
        let rows = &mut self.scratch.rows6;
        // rows = Phi6 * P[0..6, :], one column at a time (a 6x6 times 6-vector product per
        // column; nalgebra's general product would go through matrixmultiply's packing).
        // Phi's bias rows are [0 I] (`state_transition`): only the attitude rows mix.
        let top: [[f64; CORE]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| phi[(r, c)]));
        for (out, column) in rows
            .as_mut_slice()
            .chunks_exact_mut(CORE)
            .zip(self.p.as_slice().chunks_exact(n))
        {
            let x: &[f64; CORE] = column[..CORE].try_into().expect("n >= 6");
            for (o, row) in out.iter_mut().zip(&top) {
                *o = row
                    .iter()
                    .zip(x)
                    .fold(0.0, |acc, (a, b)| a.mul_add(*b, acc));
            }
            out[3..].copy_from_slice(&x[3..]);
        }
        let corner = rows.fixed_columns::<6>(0) * phi.transpose() + qd;
        let corner = 0.5 * (corner + corner.transpose());
        self.p.fixed_view_mut::<6, 6>(0, 0).copy_from(&corner);
        if n > CORE {
            self.p
                .view_mut((0, CORE), (CORE, n - CORE))
                .copy_from(&rows.columns(CORE, n - CORE));
            self.p
                .view_mut((CORE, 0), (n - CORE, CORE))
                .tr_copy_from(&rows.columns(CORE, n - CORE));
        }
        for k in CORE..n {
            self.p[(k, k)] += self.scratch.cal_noise[k];
        }
    }

    /// All measurement updates of one sample: magnetometer axes, then photodiodes, as
    /// sequential scalar updates all linearised at the prior (the paper's EKF; the
    /// structured algebra runs the serial recursion of `sequential`), then
    /// the multiplicative reset. Records of this sample: [`Filter::records`]. On an error
    /// the state and covariance are left as they were.
    pub fn update(
        &mut self,
        t_s: f64,
        meas: &Measurements<'_>,
        reference: &Reference,
        albedo: Option<&dyn AlbedoIrradiance>,
    ) -> Result<(), FilterError> {
        check_len("photodiode samples", self.used.len(), meas.pd_v.len())?;
        self.linearise(t_s, meas, reference, albedo)?;
        if self.apply_rows() {
            self.reset()?;
        }
        Ok(())
    }

    /// As [`Filter::update`], the rows linearised about `about` instead of the estimate:
    /// the estimate moved there by the reset with `d = about - x` (which, Sun only,
    /// carries the covariance into that attitude's error frame), the rows taken there
    /// with innovation `y - h(about) + H d` (the prior mean `x = about - d` seen from
    /// `about`), and the correction `dx - d` applied from there. `about` is a better
    /// estimate of the same state from more of the data (an iterated smoother's
    /// linearisation point); only where the rows are linearised changes, not the prior.
    pub fn update_about(
        &mut self,
        t_s: f64,
        meas: &Measurements<'_>,
        reference: &Reference,
        albedo: Option<&dyn AlbedoIrradiance>,
        about: &Nominal,
    ) -> Result<(), FilterError> {
        check_len("photodiode samples", self.used.len(), meas.pd_v.len())?;
        let saved = self.state();
        let offset = self.offset_to(about);
        self.scratch.dx.copy_from(&offset);
        self.reset()?;
        self.linearise(t_s, meas, reference, albedo)?;
        self.scratch.rows.shift_innovations(offset.as_slice());
        self.counts = saved.counts;
        if self.apply_rows() {
            let dx = &self.scratch.dx - &offset;
            self.scratch.dx.copy_from(&dx);
            self.reset()?;
        } else {
            let counts = self.counts;
            self.restore(&saved)?;
            self.counts = counts;
        }
        Ok(())
    }

    /// The error state that takes the estimate to `about`: attitude, bias, scales and
    /// normals (in their tangent bases); zero elsewhere.
    fn offset_to(&self, about: &Nominal) -> DVector<f64> {
        let mut d = DVector::zeros(self.p.nrows());
        let a = pdcal_attitude::mekf::error_vector(&about.q, &self.q);
        let b = about.bias - self.bias;
        for k in 0..3 {
            d[ATTITUDE + k] = a[k];
            d[BIAS + k] = b[k];
        }
        let photodiodes = self.model.photodiodes();
        for (i, pd) in photodiodes.iter().enumerate() {
            d[self.layout.scale(i)] = about.scale_v[i] - pd.scale_v;
            if let Some(k) = self.layout.normal(i) {
                let n = pd.n_body;
                let target = about.n_body[i];
                let along = target - n * n.dot(&target);
                let angle = along.norm().atan2(n.dot(&target));
                let t = along
                    .try_normalize(1e-15)
                    .map_or(Vector3::zeros(), |u| u * angle);
                let (e1, e2) = &self.basis[i];
                d[k] = t.dot(e1);
                d[k + 1] = t.dot(e2);
            }
        }
        d
    }

    /// The step's rows at the current estimate into `scratch.rows` (records cleared).
    fn linearise(
        &mut self,
        t_s: f64,
        meas: &Measurements<'_>,
        reference: &Reference,
        albedo: Option<&dyn AlbedoIrradiance>,
    ) -> Result<(), FilterError> {
        self.records.clear();
        self.contradicted.clear();
        self.scratch.rows.clear();
        self.scratch.sources.clear();
        let attitude = self.q.attitude_matrix();
        if let Some(mag) = meas.mag_nt {
            self.mag_rows(&attitude, &mag, &reference.b_gcrf_nt);
        }
        self.photodiode_rows(
            &attitude,
            t_s,
            meas.pd_v,
            meas.temperature_c,
            reference,
            albedo,
        )
    }

    /// The estimate as a linearisation point ([`Filter::update_about`]).
    pub fn nominal(&self) -> Nominal {
        Nominal {
            q: self.q,
            bias: self.bias,
            scale_v: self.scales_v(),
            n_body: self.normals(),
        }
    }

    /// Tells the filter the Sun is its only vector (no magnetometer): the curvature
    /// variance of a photodiode row then counts the attitude uncertainty across the Sun
    /// line only. The rotation about it is unobserved and its variance (tens of degrees)
    /// would otherwise swamp every photodiode row's noise and keep the Sun from holding the
    /// attitude.
    pub fn set_sun_only(&mut self, sun_only: bool) {
        self.sun_only = sun_only;
    }

    /// Checks the state and covariance after the step at telemetry row `index` (time
    /// `t_s`) and repairs the covariance if it stopped being positive definite
    /// ([`crate::guard`]). Every call tests the diagonal (`O(n)`); with `full` the whole
    /// matrix is factored (`O(n^3)`, for the caller to do every few hundred rows). A
    /// non-finite state, or a covariance the repair cannot save, is an error naming the row.
    pub fn guard_covariance(
        &mut self,
        index: usize,
        t_s: f64,
        full: bool,
    ) -> Result<Option<CovarianceRepair>, FilterError> {
        let finite = |v: &Vector3<f64>| v.iter().all(|x| x.is_finite());
        let photodiodes = self.model.photodiodes();
        let state_finite = [self.q.x, self.q.y, self.q.z, self.q.w]
            .iter()
            .chain(photodiodes.iter().map(|pd| &pd.scale_v))
            .all(|x| x.is_finite())
            && finite(&self.bias)
            && photodiodes.iter().all(|pd| finite(&pd.n_body));
        if !state_finite {
            return Err(FilterError::StateNotFinite { index, t_s });
        }
        if guard::diagonal_ok(&self.p) && (!full || guard::positive_definite(&self.p)) {
            return Ok(None);
        }
        match guard::repair(&mut self.p, &self.initial_variance) {
            Ok(kind) => Ok(kind.map(|kind| CovarianceRepair { index, t_s, kind })),
            Err(()) => Err(FilterError::NotPositiveDefinite { index }),
        }
    }

    /// Counts a magnetometer sample that was not taken (empty cell).
    pub fn count_mag_not_sampled(&mut self) {
        self.counts.magnetometer.not_sampled += 3;
    }

    /// The three magnetometer rows `[(A b) x]` at the prior attitude `attitude`, accepted or
    /// rejected together: the innovation `nu = b_meas - A b` against
    /// `S = H P_aa H^T + R` by its squared Mahalanobis distance `nu^T S^-1 nu <= mag_gate2`
    /// (a test that does not depend on the body axes; [`crate::gate`]). An `S` that is not
    /// positive definite rejects the sample.
    fn mag_rows(&mut self, attitude: &Matrix3<f64>, mag: &Vector3<f64>, b_gcrf: &Vector3<f64>) {
        let b_body = attitude * b_gcrf;
        let h = skew(&b_body);
        let r = self.noise.mag_sigma_nt.powi(2) + self.mag_second_order_var(&b_body);
        let nu = mag - b_body;
        let p_aa: Matrix3<f64> = self.p.fixed_view::<3, 3>(ATTITUDE, ATTITUDE).into_owned();
        let s = h * p_aa * h.transpose() + Matrix3::identity() * r;
        let accepted = s
            .cholesky()
            .is_some_and(|c| nu.dot(&c.solve(&nu)) <= self.mag_gate2);
        let rows = &mut self.scratch.rows;
        for axis in 0..3 {
            rows.begin_decided(nu[axis], r, accepted);
            for k in 0..3 {
                rows.entry(ATTITUDE + k, h[(axis, k)]);
            }
            self.scratch
                .sources
                .push((Sensor::Magnetometer(axis), mag[axis]));
        }
    }

    /// Variance of the second-order term of `A b` under the attitude uncertainty, per axis:
    /// `(1/2) [a x]^2 b` has size `|a|^2 |b| / 2`; with `tr P_aa = 3 v`, `var |a|^2 = 6 v^2`,
    /// spread over three axes: `|b|^2 (tr P_aa)^2 / 18`. Zero when disabled.
    fn mag_second_order_var(&self, b_body: &Vector3<f64>) -> f64 {
        if !self.noise.second_order {
            return 0.0;
        }
        let tr = self.p_diag(0) + self.p_diag(1) + self.p_diag(2);
        b_body.norm_squared() * tr * tr / 18.0
    }

    /// Variance of the second-order terms of `C n^T A s` (Gaussian second-order filter,
    /// simplified): the relative angle `delta` between normal and Sun has variance
    /// `sigma^2 = 2 tr(P_aa)/3 + P_d1 + P_d2` over two axes, the cosine's curvature gives
    /// `-(1/2) C cos(theta) |delta|^2` with variance `(1/4) (C cos theta)^2 sigma^4`, and the
    /// scale-angle product `dC sin(theta) delta` adds `(1/2) P_CC sigma^2`. It is large only
    /// while the initial uncertainty is (and keeps the first updates from over-trusting the
    /// linearisation); it vanishes as `P` shrinks. Zero when disabled.
    fn photodiode_second_order_var(&self, i: usize, cos_incidence: f64) -> f64 {
        if !self.noise.second_order {
            return 0.0;
        }
        let trace = self.p_diag(0) + self.p_diag(1) + self.p_diag(2);
        let mut angle_var = if self.sun_only {
            // The incidence sees only the attitude across the Sun line; the rotation about
            // it, unobserved without a second vector, may carry any variance at all.
            let u = self.prior_sun_body;
            let p_aa = self.p.fixed_view::<3, 3>(ATTITUDE, ATTITUDE);
            (trace - (u.transpose() * p_aa * u)[0]).max(0.0)
        } else {
            2.0 * trace / 3.0
        };
        if let Some(d) = self.layout.normal(i) {
            angle_var += self.p_diag(d) + self.p_diag(d + 1);
        }
        let sc = self.layout.scale(i);
        let c = self.model.photodiodes()[i].scale_v * cos_incidence;
        0.25 * c * c * angle_var * angle_var + 0.5 * self.p_diag(sc) * angle_var
    }

    /// Diagonal entry `i` of the prior covariance.
    fn p_diag(&self, i: usize) -> f64 {
        self.p[(i, i)]
    }

    /// The photodiode rows at the prior attitude `attitude`: one per photodiode that is
    /// sampled, lit, in use and inside the field of view ([`Filter::select_photodiodes`]),
    /// with the albedo of all of them evaluated in one batch first.
    fn photodiode_rows(
        &mut self,
        attitude: &Matrix3<f64>,
        t_s: f64,
        pd_v: &[Option<f64>],
        temperature_c: &[f64],
        reference: &Reference,
        albedo: Option<&dyn AlbedoIrradiance>,
    ) -> Result<(), FilterError> {
        let sun_body = attitude * reference.sun_gcrf_unit;
        self.prior_sun_body = sun_body.try_normalize(1e-12).unwrap_or_default();
        let sun_distance_factor = reference.sun_distance_factor();
        self.select_photodiodes(pd_v, reference, &sun_body);
        let albedo_used = albedo.filter(|_| !self.scratch.selected.is_empty());
        if let Some(albedo) = albedo_used {
            self.prior_albedo(attitude, albedo);
        }
        for k in 0..self.scratch.selected.len() {
            let Selected {
                index: i,
                measured_v: y,
                cos_incidence,
            } = self.scratch.selected[k];
            let scene = Scene {
                attitude: *attitude,
                sun_body,
                sun_fraction: reference.sun_fraction,
                sun_distance_factor,
                rate_body_rad_s: self.rate_est,
                t_s,
                albedo: albedo_used
                    .map(|_| &self.scratch.albedo.linear[k] as &dyn AlbedoIrradiance),
                temperature_c,
            };
            self.model
                .partials_into(i, &scene, &mut self.scratch.partials)?;
            let predicted = self.scratch.partials.value_v;
            let d_gain = match (albedo_used, self.noise.albedo_gain) {
                (Some(_), Some(_)) => self.albedo_gain_partial(i, &scene, predicted)?,
                _ => 0.0,
            };
            let r = self.noise.photodiode_sigma_v.powi(2)
                + self.white_albedo_var(i, d_gain)
                + self.photodiode_second_order_var(i, cos_incidence);
            self.scratch.rows.begin(y - predicted, r);
            self.fill_photodiode_row(i, d_gain);
            self.scratch.sources.push((Sensor::Photodiode(i), y));
        }
        Ok(())
    }

    /// `dh/dg`, the output's partial with respect to the albedo gain: the modelled albedo
    /// part of photodiode `i`'s prediction (Eq. 15's second term through the model's gains),
    /// `(h - h_0) / (1 + g)` with `h` the prediction `predicted_v` (albedo times `1 + g`)
    /// and `h_0` the prediction without albedo. Every term is linear in the albedo
    /// irradiance, so this is exact below an output stage's knee.
    fn albedo_gain_partial(
        &self,
        i: usize,
        scene: &Scene,
        predicted_v: f64,
    ) -> Result<f64, FilterError> {
        let factor = 1.0 + self.albedo_gain;
        if factor.abs() < 1e-9 {
            return Ok(0.0);
        }
        let without = Scene {
            albedo: None,
            ..*scene
        };
        Ok((predicted_v - self.model.evaluate(i, &without)?) / factor)
    }

    /// The white part of photodiode `i`'s albedo variance, V^2: the declared one-row
    /// albedo variance `(C albedo_sigma_ratio)^2` less what the gain state carries,
    /// `(sigma_g dh/dg)^2`, so that one error is not counted twice (the declared sigma is
    /// the whole albedo error of one row; where the albedo is strong the gain's share is
    /// all of it).
    fn white_albedo_var(&self, i: usize, d_gain: f64) -> f64 {
        let declared =
            (self.model.photodiodes()[i].scale_v * self.noise.albedo_sigma_ratio).powi(2);
        let correlated = self
            .noise
            .albedo_gain
            .map_or(0.0, |g| (g.sigma * d_gain).powi(2));
        (declared - correlated).max(0.0)
    }

    /// The photodiodes this step updates, into `scratch.selected`: sampled, lit (full Sun),
    /// in use and inside the field of view at the prior (`sun_body`): the configured gate and
    /// the photodiode's own (the model's `fov_half_angle_rad`, from dataset.ron), whichever
    /// is narrower; the others counted by why they were left out.
    fn select_photodiodes(
        &mut self,
        pd_v: &[Option<f64>],
        reference: &Reference,
        sun_body: &Vector3<f64>,
    ) {
        let lit = reference.sun_fraction >= self.noise.min_sun_fraction;
        let (sigma_v, gate) = (self.noise.photodiode_sigma_v, self.noise.gate_sigmas);
        let counts = &mut self.counts.photodiode;
        let selected = &mut self.scratch.selected;
        selected.clear();
        for (i, sample) in pd_v.iter().enumerate() {
            let Some(y) = *sample else {
                counts.not_sampled += 1;
                continue;
            };
            if !lit {
                counts.shadowed += 1;
                continue;
            }
            let pd = &self.model.photodiodes()[i];
            if !self.used[i] || pd.scale_v <= 0.0 {
                counts.unused_sensor += 1;
                let sample = OutsideSample {
                    scale_v: pd.scale_v,
                    n_body: pd.n_body,
                    y,
                };
                let spread = || Spread::of(&self.p, &self.layout, i);
                let sun = (*sun_body, reference.sun_distance_factor());
                if let Some(shortfall) = missing_light(&sample, sun, spread, (sigma_v, gate)) {
                    self.contradicted
                        .push(contradicted_record(i, y, shortfall, sigma_v));
                }
                continue;
            }
            let cos_incidence = pd.n_body.dot(sun_body);
            // The narrower of the filter's gate and the photodiode's own field of view, if it
            // has one (without one the gate alone decides, even beyond 90 deg).
            let cos_fov = pd
                .fov_half_angle_rad
                .map_or(self.noise.cos_fov, |fov| self.noise.cos_fov.max(fov.cos()));
            if cos_incidence < cos_fov {
                let sample = OutsideSample {
                    scale_v: pd.scale_v,
                    n_body: pd.n_body,
                    y,
                };
                let spread = || Spread::of(&self.p, &self.layout, i);
                match excess_light(&sample, *sun_body, reference, spread, (sigma_v, gate)) {
                    Some(excess) => {
                        counts.contradicted += 1;
                        self.contradicted
                            .push(contradicted_record(i, y, excess, sigma_v));
                    }
                    None => counts.outside_fov += 1,
                }
                continue;
            }
            selected.push(Selected {
                index: i,
                measured_v: y,
                cos_incidence,
            });
        }
    }

    /// The rows in `scratch.rows` through the algebra: the correction into `scratch.dx`,
    /// the covariance updated, each row's fate in `scratch.outcome`.
    fn run_rows(&mut self) {
        let s = &mut self.scratch;
        let gate2 = self.noise.gate_sigmas.powi(2);
        s.dx.fill(0.0);
        match self.algebra {
            Algebra::Structured => {
                sequential::update(
                    self.p.as_slice(),
                    &s.rows,
                    gate2,
                    &mut s.pending,
                    &mut s.work,
                    s.dx.as_mut_slice(),
                    &mut s.outcome,
                );
                algebra::apply_pending(self.p.as_mut_slice(), &mut s.pending);
            }
            Algebra::Dense => {
                dense::sequential_update(&mut self.p, &s.rows, gate2, &mut s.dx, &mut s.outcome)
            }
        }
    }

    /// Runs the step's rows through the algebra, records each and counts it. Whether any
    /// was accepted.
    fn apply_rows(&mut self) -> bool {
        self.run_rows();
        let s = &mut self.scratch;
        let mut any = false;
        for (l, (o, &(sensor, measured))) in s.outcome.iter().zip(&s.sources).enumerate() {
            self.records.push(UpdateRecord {
                sensor,
                measured,
                residual: o.residual,
                bound_3sigma: 3.0 * o.spread.sqrt(),
                accepted: o.accepted,
                post_fit: s.rows.after(l, s.dx.as_slice()),
            });
            let counts = match sensor {
                Sensor::Photodiode(_) => &mut self.counts.photodiode,
                Sensor::Magnetometer(_) => &mut self.counts.magnetometer,
            };
            if o.accepted {
                counts.accepted += 1;
            } else {
                counts.gated += 1;
            }
            any |= o.accepted;
        }
        any
    }

    /// Evaluates the albedo of the selected photodiodes at the prior attitude `attitude` in
    /// one batch call (one call lets the provider, or the CPU, work on the photodiodes
    /// together), each kept as the [`LinearAlbedo`] at its prior normal, which returns the
    /// evaluation itself there.
    fn prior_albedo(&mut self, attitude: &Matrix3<f64>, albedo: &dyn AlbedoIrradiance) {
        // The albedo seen: the modelled one times the gain's `1 + g` (1 without the state).
        let gain = 1.0 + self.albedo_gain;
        let a = &mut self.scratch.albedo;
        a.normals_gcrf.clear();
        a.cos_fov.clear();
        let photodiodes = self.model.photodiodes();
        for selected in &self.scratch.selected {
            let pd = &photodiodes[selected.index];
            a.normals_gcrf.push(attitude.tr_mul(&pd.n_body));
            a.cos_fov.push(pd.cos_fov());
        }
        a.results.clear();
        a.results
            .resize(a.normals_gcrf.len(), (0.0, Vector3::zeros()));
        albedo.ratios_and_vectors(&a.normals_gcrf, &a.cos_fov, &mut a.results);
        a.linear.clear();
        a.linear.extend(
            a.normals_gcrf
                .iter()
                .zip(&a.results)
                .map(|(n0, &(ratio0, vector))| LinearAlbedo {
                    n0_gcrf: *n0,
                    ratio0: gain * ratio0,
                    vector_gcrf: gain * vector,
                }),
        );
    }

    /// The sparse H row of photodiode `i` from the model's partials, appended to the row
    /// begun last: Eq. (20) for `a`, Eq. (22) for `C`, the normal gradient projected on the
    /// tangent basis for `(d1, d2)` (the singularity-free replacement of Eqs. 23-24), and the
    /// estimated parameters.
    fn fill_photodiode_row(&mut self, i: usize, d_gain: f64) {
        let s = &mut self.scratch;
        let pa = &s.partials;
        for k in 0..3 {
            s.rows.entry(ATTITUDE + k, pa.d_attitude[k]);
        }
        s.rows.entry(self.layout.scale(i), pa.d_scale);
        if let Some(d) = self.layout.normal(i) {
            let (e1, e2) = &self.basis[i];
            s.rows.entry(d, pa.d_normal.dot(e1));
            s.rows.entry(d + 1, pa.d_normal.dot(e2));
        }
        for &k in self.layout.extras_of(i) {
            let e = &self.layout.extras()[k];
            s.rows.entry(e.state, pa.d_parameters[e.parameter]);
        }
        if let Some(g) = self.layout.albedo_gain() {
            s.rows.entry(g, d_gain);
        }
    }

    /// The multiplicative reset: `q <- dq(a) ⊗ q`, additive for bias, scales and parameters,
    /// normals rotated along the tangent correction and their bases recomputed; the error
    /// state returns to zero. With a second vector the covariance change of the reset (the
    /// rotation of the attitude error frame by the correction) is neglected, as usual for
    /// the MEKF; with the Sun alone it is applied ([`Filter::rotate_attitude_error_frame`]).
    fn reset(&mut self) -> Result<(), FilterError> {
        let dx = &self.scratch.dx;
        // A step's correction is small: the series form (`apply_small_error`, the exact
        // `apply_error` above 0.1 rad).
        let a = Vector3::new(dx[ATTITUDE], dx[ATTITUDE + 1], dx[ATTITUDE + 2]);
        let before = self.q.attitude_matrix();
        self.q = apply_small_error(&self.q, &a);
        let turn = self.q.attitude_matrix() * before.transpose();
        self.bias += Vector3::new(dx[BIAS], dx[BIAS + 1], dx[BIAS + 2]);
        if let Some(r) = self.rate.as_mut() {
            let (k, d, c) = (r.idx[6], r.idx[9], r.idx[12]);
            r.motion.w_body_rad_s += Vector3::new(dx[k], dx[k + 1], dx[k + 2]);
            r.motion.dipole_body_a_m2 += Vector3::new(dx[d], dx[d + 1], dx[d + 2]);
            r.motion.moment_fraction += Vector3::new(dx[c], dx[c + 1], dx[c + 2]);
        }
        self.reset_photodiodes();
        let dx = &self.scratch.dx;
        if let Some(g) = self.layout.albedo_gain() {
            self.albedo_gain += dx[g];
        }
        for e in self.layout.extras() {
            let p = self.model.parameter_mut(e.parameter)?;
            p.value += dx[e.state];
        }
        if self.sun_only {
            self.rotate_attitude_error_frame(&turn);
        }
        Ok(())
    }

    /// The reset's rotation of the attitude error frame, `P_a. <- G P_a.` and
    /// `P_.a <- P_.a G^T` with `G` the correction's rotation of body vectors. Kept when the
    /// Sun is the only vector: the error about the Sun line is then large (up to a half
    /// turn), and a reset that leaves `P` as it is (the usual first-order MEKF reset) keeps
    /// that large variance about the *previous* Sun direction; the next rows see part of it
    /// across the corrected one and "observe" the unobservable rotation, which shrinks its
    /// sigma far below its error (spurious information). Rotated, the unobserved axis stays
    /// on the estimate's Sun line. With a second vector the errors are small and `G - I` is
    /// of their order, so the usual reset is kept there.
    fn rotate_attitude_error_frame(&mut self, g: &Matrix3<f64>) {
        // The rows rotated, then the columns mirrored from them, so that `P` stays exactly
        // symmetric (the structured algebra reads one triangle).
        let rows = g * self.p.fixed_rows::<3>(ATTITUDE);
        self.p.fixed_rows_mut::<3>(ATTITUDE).copy_from(&rows);
        let block = self.p.fixed_view::<3, 3>(ATTITUDE, ATTITUDE) * g.transpose();
        let block = (block + block.transpose()) * 0.5;
        self.p
            .fixed_view_mut::<3, 3>(ATTITUDE, ATTITUDE)
            .copy_from(&block);
        let rows = self.p.fixed_rows::<3>(ATTITUDE).transpose();
        self.p.fixed_columns_mut::<3>(ATTITUDE).copy_from(&rows);
    }

    /// The reset of the scales and normals, written into the model's photodiodes (their
    /// one owner), in two passes over the photodiodes: scales and normals, then the
    /// tangent bases of the normals that moved. Each pass's iterations are independent, so
    /// the processor overlaps them, which one loop doing both prevents
    /// (docs/performance.md).
    fn reset_photodiodes(&mut self) {
        let Scratch { dx, moved, .. } = &mut self.scratch;
        moved.clear();
        let photodiodes = self.model.photodiodes_mut();
        for (i, pd) in photodiodes.iter_mut().enumerate() {
            pd.scale_v += dx[self.layout.scale(i)];
            if let Some(d) = self.layout.normal(i)
                && (dx[d] != 0.0 || dx[d + 1] != 0.0)
            {
                // The cached basis is the layout's basis at the normal: rotate in it.
                let (e1, e2) = &self.basis[i];
                pd.n_body = rotate_normal_in(&pd.n_body, (e1, e2), dx[d], dx[d + 1]);
                moved.push(i);
            }
        }
        for &i in moved.iter() {
            self.basis[i] = self.layout.tangent_basis(i, &photodiodes[i].n_body);
        }
    }

    /// Attitude estimate.
    pub fn q(&self) -> Quat {
        self.q
    }

    /// Turns the attitude estimate by `turn_body`, a rotation of the body frame, keeping
    /// the covariance: for the half turn about the Sun line ([`crate::sun_line`]), under
    /// which the Sun's direction in the body, and with it every error the photodiodes
    /// tie to it, stays the same.
    pub fn turn_attitude(&mut self, turn_body: &nalgebra::Matrix3<f64>) {
        self.q = Quat::from_attitude_matrix(&(turn_body * self.q.attitude_matrix()));
    }

    /// Gyro bias estimate, rad/s.
    pub fn bias_rad_s(&self) -> Vector3<f64> {
        self.bias
    }

    /// Scale factor estimates, V (read from the model's photodiodes, their owner).
    pub fn scales_v(&self) -> Vec<f64> {
        self.model
            .photodiodes()
            .iter()
            .map(|pd| pd.scale_v)
            .collect()
    }

    /// Normal estimates, body frame (read from the model's photodiodes, their owner).
    pub fn normals(&self) -> Vec<Vector3<f64>> {
        self.model
            .photodiodes()
            .iter()
            .map(|pd| pd.n_body)
            .collect()
    }

    /// The albedo gain estimate `g` ([`AlbedoGainNoise`]), when it is a state.
    pub fn albedo_gain(&self) -> Option<f64> {
        self.layout.albedo_gain().map(|_| self.albedo_gain)
    }

    /// Values of the extra states, in layout order.
    pub fn extra_values(&self) -> Vec<f64> {
        let params: Vec<f64> = self.model.parameters().map(|(_, p)| p.value).collect();
        self.layout
            .extras()
            .iter()
            .map(|e| params[e.parameter])
            .collect()
    }

    /// Error-state covariance.
    pub fn covariance(&self) -> &DMatrix<f64> {
        &self.p
    }

    /// The state to restart from later ([`Filter::restore`]).
    pub fn state(&self) -> FilterState {
        FilterState {
            q: self.q,
            bias: self.bias,
            scale: self.scales_v(),
            normal: self.normals(),
            basis: self.basis.clone(),
            rate_est: self.rate_est,
            albedo_gain: self.albedo_gain,
            p: self.p.clone(),
            parameters: self.model.parameters().map(|(_, p)| p.value).collect(),
            counts: self.counts,
            last: self.last.clone(),
            motion: self.motion(),
        }
    }

    /// Returns to a state taken from this filter by [`Filter::state`]: the steps after it
    /// repeat bit for bit.
    pub fn restore(&mut self, state: &FilterState) -> Result<(), FilterError> {
        check_len("restored covariance", self.p.nrows(), state.p.nrows())?;
        check_len("restored scales", self.used.len(), state.scale.len())?;
        self.q = state.q;
        self.bias = state.bias;
        set_estimates(&mut self.model, &state.scale, &state.normal);
        self.basis.copy_from_slice(&state.basis);
        self.rate_est = state.rate_est;
        self.albedo_gain = state.albedo_gain;
        self.p.copy_from(&state.p);
        for (k, value) in state.parameters.iter().enumerate() {
            self.model.parameter_mut(k)?.value = *value;
        }
        self.counts = state.counts;
        self.last.clone_from(&state.last);
        if let (Some(r), Some(motion)) = (self.rate.as_mut(), state.motion) {
            r.motion = motion;
        }
        Ok(())
    }

    /// Replaces the error-state covariance (a restart from an outside estimate). It is
    /// taken as given: the guard ([`Filter::guard_covariance`]) judges it after the next
    /// step.
    pub fn set_covariance(&mut self, p: DMatrix<f64>) -> Result<(), FilterError> {
        check_len("covariance rows", self.p.nrows(), p.nrows())?;
        check_len("covariance columns", self.p.ncols(), p.ncols())?;
        self.p = p;
        Ok(())
    }

    /// The state layout.
    pub fn layout(&self) -> &StateLayout {
        &self.layout
    }

    /// Each photodiode's output the model predicts with no light at all (in the Earth's
    /// umbra, no albedo): its additive terms at their current values, V; 0 where the model
    /// cannot say.
    pub fn umbra_outputs(&self) -> Vec<f64> {
        let Ok(scene) = Scene::new(Matrix3::identity(), &Vector3::x()) else {
            return vec![0.0; self.model.photodiodes().len()];
        };
        let dark = scene.with_sun_fraction(0.0);
        (0..self.model.photodiodes().len())
            .map(|i| self.model.evaluate(i, &dark).unwrap_or(0.0))
            .collect()
    }

    /// The photodiode samples of the last step that the estimate contradicts: outside the
    /// field of view at the prior attitude, so never an update, yet reading more than
    /// the direct Sun at that incidence and a white Earth filling the view could give
    /// together, by more than the gate's sigmas of noise. Each a record with
    /// `accepted: false`, its residual the excess over that bound and its bound the
    /// noise's 3 sigma: the consistency verdict counts it outside 3 sigma, where a sample
    /// left out would have said nothing (a swapped pair of columns on a four-photodiode
    /// head, the attitude held by the magnetometer 78 deg from the truth, had every
    /// photodiode sample left out and the run called consistent).
    pub fn contradicted(&self) -> &[UpdateRecord] {
        &self.contradicted
    }

    /// The measurement model with the current estimates.
    pub fn model(&self) -> &MeasurementModel {
        &self.model
    }

    /// The scalar updates of the last [`Filter::update`].
    pub fn records(&self) -> &[UpdateRecord] {
        &self.records
    }

    /// Counts since the start.
    pub fn counts(&self) -> &UpdateCounts {
        &self.counts
    }

    /// Diagonal process noise of the calibration states over the last step (entries 0..6
    /// are zero).
    pub fn calibration_noise(&self) -> &DVector<f64> {
        &self.scratch.cal_noise
    }

    /// The last propagation's matrices.
    pub fn last_propagation(&self) -> Option<&Propagation> {
        self.last.as_ref()
    }

    /// The current calibration: scales, normals (az/el with sigmas), bias, parameters.
    /// `fixed` supplies the normal sigmas when normals are not states (scale-only).
    pub fn calibration(&self, fixed: Option<&Calibration>) -> Calibration {
        let state = StateView {
            bias: self.bias,
            scale: self.scales_v().into(),
            normal: self.normals().into(),
            extras: self.extra_values(),
            p: &self.p,
        };
        state.calibration(&self.layout, fixed)
    }
}

/// Writes the scale and normal estimates into `model`'s photodiodes, their one owner.
fn set_estimates(model: &mut MeasurementModel, scale_v: &[f64], n_body: &[Vector3<f64>]) {
    let estimates = scale_v.iter().zip(n_body);
    for (pd, (scale_v, n_body)) in model.photodiodes_mut().iter_mut().zip(estimates) {
        pd.scale_v = *scale_v;
        pd.n_body = *n_body;
    }
}

/// A state and its covariance, from the filter or the smoother.
pub(crate) struct StateView<'a> {
    pub bias: Vector3<f64>,
    pub scale: Cow<'a, [f64]>,
    pub normal: Cow<'a, [Vector3<f64>]>,
    pub extras: Vec<f64>,
    pub p: &'a DMatrix<f64>,
}

impl StateView<'_> {
    pub(crate) fn calibration(
        &self,
        layout: &StateLayout,
        fixed: Option<&Calibration>,
    ) -> Calibration {
        let p = self.p;
        let photodiodes = (0..layout.photodiodes())
            .map(|i| {
                let sc = layout.scale(i);
                let scale_sigma = p[(sc, sc)].max(0.0).sqrt();
                match layout.normal(i) {
                    Some(d) => {
                        let cov = Matrix2::new(
                            p[(d, d)],
                            p[(d, d + 1)],
                            p[(d + 1, d)],
                            p[(d + 1, d + 1)],
                        );
                        PdCalibration::from_normal_in(
                            self.scale[i],
                            scale_sigma,
                            &self.normal[i],
                            &layout.tangent_basis(i, &self.normal[i]),
                            &cov,
                        )
                    }
                    None => {
                        let mut pd = PdCalibration::from_normal(
                            self.scale[i],
                            scale_sigma,
                            &self.normal[i],
                            &Matrix2::zeros(),
                        );
                        if let Some(prior) = fixed.and_then(|f| f.photodiodes.get(i)) {
                            pd.azimuth_sigma_deg = prior.azimuth_sigma_deg;
                            pd.elevation_sigma_deg = prior.elevation_sigma_deg;
                        }
                        pd
                    }
                }
            })
            .collect();
        let sig = |k: usize| p[(k, k)].max(0.0).sqrt();
        Calibration {
            format_version: crate::calibration::CALIBRATION_FORMAT_VERSION,
            photodiodes,
            gyro_bias_rad_s: [self.bias.x, self.bias.y, self.bias.z],
            gyro_bias_sigma_rad_s: [sig(BIAS), sig(BIAS + 1), sig(BIAS + 2)],
            parameters: layout
                .extras()
                .iter()
                .zip(&self.extras)
                .map(|(e, v)| ParameterEstimate {
                    name: e.name.clone(),
                    unit: e.unit.clone(),
                    value: *v,
                    sigma: sig(e.state),
                })
                .collect(),
            status: Vec::new(),
        }
    }
}

/// A photodiode sample the filter does not update with: outside the field of view at the
/// estimate, or of a photodiode it does not use.
struct OutsideSample {
    scale_v: f64,
    n_body: Vector3<f64>,
    y: f64,
}

/// The estimate's uncertainty a sample's light could hide in: the attitude error
/// covariance, the normal's tangent variance (its trace) and the scale factor's sigma.
struct Spread {
    p_aa: Matrix3<f64>,
    normal_var: f64,
    scale_sigma_v: f64,
}

impl Spread {
    fn of(p: &DMatrix<f64>, layout: &StateLayout, i: usize) -> Self {
        let normal_var = layout
            .normal(i)
            .map_or(0.0, |k| (p[(k, k)] + p[(k + 1, k + 1)]).max(0.0));
        let sc = layout.scale(i);
        Spread {
            p_aa: p.fixed_view::<3, 3>(ATTITUDE, ATTITUDE).into_owned(),
            normal_var,
            scale_sigma_v: p[(sc, sc)].max(0.0).sqrt(),
        }
    }

    /// The sigma of the angle between the Sun `s` and the normal `n` (unit, body): the
    /// attitude's about `s x n` (any axis across the Sun line when they are opposite: the
    /// widest) and the normal's.
    fn turn_sigma(&self, s: &Vector3<f64>, n: &Vector3<f64>) -> f64 {
        let attitude_var = match s.cross(n).try_normalize(1e-12) {
            Some(axis) => (axis.transpose() * self.p_aa * axis)[(0, 0)],
            None => self.p_aa.symmetric_eigenvalues().max(),
        };
        (attitude_var + self.normal_var).max(0.0).sqrt()
    }
}

/// Photodiode `i`'s sample `y` that the estimate contradicts by `residual` (an excess over
/// the most light it could get, or a shortfall below the least), with the noise's 3-sigma
/// bound: never applied ([`Filter::contradicted`]).
fn contradicted_record(i: usize, y: f64, residual: f64, sigma_v: f64) -> UpdateRecord {
    UpdateRecord {
        sensor: Sensor::Photodiode(i),
        measured: y,
        residual,
        bound_3sigma: 3.0 * sigma_v,
        accepted: false,
        post_fit: residual,
    }
}

/// The shortfall of a sample of an unused photodiode (never lit in the data) that reads less
/// than a working one of its assumed scale (the others' median output when it never lit)
/// would get anywhere within `gate` sigmas of the estimate (the attitude turned away from
/// the normal, the normal away from the Sun), by more than `gate` sigmas of the noise
/// `sigma_v`: the direct Sun alone at the farthest incidence so reached, at the Sun's
/// distance (`sun_distance_factor`). The shortfall is negative. `None` when
/// it does not, or when a photodiode so turned could face away. With the prior's 10 deg
/// per normal axis this takes the Sun within about 20 deg of its nominal normal with the
/// attitude held. The scale is not lowered by its sigma: a scale near zero is what a dead
/// channel is, and the record says the photodiode did not read what one of its kind would.
fn missing_light(
    sample: &OutsideSample,
    (sun_body, sun_distance_factor): (Vector3<f64>, f64),
    spread: impl FnOnce() -> Spread,
    (sigma_v, gate): (f64, f64),
) -> Option<f64> {
    let s = sun_body.try_normalize(1e-12)?;
    let cos_incidence = sample.n_body.dot(&s).clamp(-1.0, 1.0);
    // Not short of the light at the estimate itself: not short of less.
    let at_estimate_v = sample.scale_v * sun_distance_factor * cos_incidence.max(0.0);
    if sample.y - at_estimate_v >= -gate * sigma_v {
        return None;
    }
    let farthest = cos_incidence.acos() + gate * spread().turn_sigma(&s, &sample.n_body);
    if farthest >= std::f64::consts::FRAC_PI_2 || sample.scale_v <= 0.0 {
        return None;
    }
    let shortfall = sample.y - sample.scale_v * sun_distance_factor * farthest.cos();
    (shortfall < -gate * sigma_v).then_some(shortfall)
}

/// The excess of a sample outside the field of view that reads more light than it could
/// get anywhere within `gate` sigmas of the estimate (the attitude turned towards the
/// normal, the normal towards the Sun, the scale factor up), by more than `gate` sigmas of
/// the noise `sigma_v`: the direct Sun at the closest incidence so reached, and the albedo
/// of a white Earth filling the view, whose irradiance on any plate is at most the Sun's
/// times the view factor of the whole disc, `(R_E / r)^2` (Lambertian, reflectivity 1).
/// `None` when it does not.
fn excess_light(
    sample: &OutsideSample,
    sun_body: Vector3<f64>,
    reference: &Reference,
    spread: impl FnOnce() -> Spread,
    (sigma_v, gate): (f64, f64),
) -> Option<f64> {
    // Only a sample beyond the gate in the noise can be beyond any light.
    if sample.y <= gate * sigma_v {
        return None;
    }
    let r_km = reference.r_gcrf_km.norm();
    let s = sun_body.try_normalize(1e-12)?;
    // Inside the Earth, or a position not a number: no bound to judge by.
    let view_factor = Some(pdcal_ephem::eclipse::EARTH_RADIUS_KM / r_km)
        .filter(|ratio| (0.0..1.0).contains(ratio))?
        .powi(2);
    let cos_incidence = sample.n_body.dot(&s).clamp(-1.0, 1.0);
    let sun_v = reference.sun_distance_factor();
    // Within what the estimate itself allows, as nearly every sample outside the field of
    // view is (albedo), there is nothing to widen.
    if sample.y - sample.scale_v * sun_v * (cos_incidence.max(0.0) + view_factor) <= gate * sigma_v
    {
        return None;
    }
    let spread = spread();
    let closest = (cos_incidence.acos() - gate * spread.turn_sigma(&s, &sample.n_body)).max(0.0);
    let scale_v = sample.scale_v + gate * spread.scale_sigma_v;
    let most_v = scale_v * sun_v * (closest.cos().max(0.0) + view_factor);
    let excess = sample.y - most_v;
    (excess > gate * sigma_v).then_some(excess)
}

#[cfg(test)]
mod tests {
    use nalgebra::{Matrix3, Vector3};
    use pdcal_albedo::LinearAlbedo;
    use pdcal_attitude::{GyroNoise, Quat};
    use pdcal_photodiode::{MeasurementModel, Photodiode, ScaleDrift, Scene};

    use super::*;

    /// A filter over four photodiodes, the paper's model with a scale drift (a gain the
    /// albedo part must go through), and the albedo gain a state.
    fn filter() -> Filter {
        let pds: Vec<Photodiode> = [(0.0, 10.0), (90.0, -20.0), (200.0, 40.0), (300.0, 0.0)]
            .iter()
            .map(|&(az, el)| Photodiode::from_az_el_deg(3.7, az, el, 0.015))
            .collect();
        let m = pds.len();
        let mut model = MeasurementModel::paper(pds);
        model.add_gain(ScaleDrift::shared(0.02)).unwrap();
        let layout = StateLayout::new(&model, true);
        let init = InitialState {
            q: Quat::IDENTITY,
            attitude_cov: Matrix3::identity() * 1e-4,
            bias_rad_s: Vector3::zeros(),
            bias_sigma_rad_s: 1e-3,
            scale_v: vec![3.7; m],
            scale_sigma_v: vec![0.3; m],
            n_body: model.photodiodes().iter().map(|p| p.n_body).collect(),
            normal_sigma_rad: 0.1,
            extra_sigma: Vec::new(),
            used: vec![true; m],
        };
        let noise = FilterNoise {
            gyro: GyroNoise {
                sigma_v_rad_sqrt_s: 1e-3,
                sigma_u_rad_s_sqrt_s: 2e-6,
            },
            rate_change_fraction: 0.3,
            scale_walk_var_per_s: vec![1e-9; m],
            normal_walk_var_per_s: 1e-12,
            extra_walk_var_per_s: Vec::new(),
            photodiode_sigma_v: 0.015,
            albedo_sigma_ratio: 50.0 / 1367.0,
            albedo_gain: Some(AlbedoGainNoise {
                sigma: 0.2,
                time_s: 360.0,
            }),
            mag_sigma_nt: 320.0,
            gate_sigmas: 5.0,
            cos_fov: 60f64.to_radians().cos(),
            min_sun_fraction: 0.999,
            second_order: true,
        };
        Filter::new(model, layout, init, noise, Algebra::Structured).unwrap()
    }

    /// The albedo `factor` times a fixed linearised one.
    fn albedo(factor: f64) -> LinearAlbedo {
        LinearAlbedo {
            n0_gcrf: Vector3::new(0.3, -0.2, 0.93).normalize(),
            ratio0: 0.21 * factor,
            vector_gcrf: Vector3::new(0.05, 0.12, 0.3) * factor,
        }
    }

    #[test]
    fn albedo_gain_partial_matches_finite_differences() {
        let mut f = filter();
        let attitude = *nalgebra::Rotation3::from_euler_angles(0.3, -0.4, 1.1).matrix();
        let sun_body = attitude * Vector3::new(0.2, 0.5, 0.84).normalize();
        for g in [-0.4, 0.0, 0.35] {
            f.albedo_gain = g;
            let seen = albedo(1.0 + g);
            fn scene<'a>(
                attitude: Matrix3<f64>,
                sun_body: Vector3<f64>,
                a: &'a LinearAlbedo,
            ) -> Scene<'a> {
                Scene {
                    attitude,
                    sun_body,
                    sun_fraction: 1.0,
                    sun_distance_factor: 1.0,
                    rate_body_rad_s: Vector3::zeros(),
                    t_s: 5400.0,
                    albedo: Some(a as &dyn AlbedoIrradiance),
                    temperature_c: &[],
                }
            }
            for i in 0..4 {
                let predicted = f
                    .model
                    .evaluate(i, &scene(attitude, sun_body, &seen))
                    .unwrap();
                let d = f
                    .albedo_gain_partial(i, &scene(attitude, sun_body, &seen), predicted)
                    .unwrap();
                let h = 1e-6;
                let up = f
                    .model
                    .evaluate(i, &scene(attitude, sun_body, &albedo(1.0 + g + h)))
                    .unwrap();
                let down = f
                    .model
                    .evaluate(i, &scene(attitude, sun_body, &albedo(1.0 + g - h)))
                    .unwrap();
                let fd = (up - down) / (2.0 * h);
                assert!(d.abs() > 1e-3, "photodiode {i}: no albedo seen ({d})");
                assert!(
                    (d - fd).abs() <= 1e-7 * fd.abs().max(1.0),
                    "photodiode {i}, g {g}: partial {d} against finite differences {fd}"
                );
            }
        }
    }

    #[test]
    fn albedo_gain_is_a_stationary_gauss_markov_process() {
        // Unobserved, the gain's variance stays its prior over any steps (the decay and
        // the noise balance), its estimate decays by e^(-dt/tau) and its correlation with
        // another state with it.
        let mut f = filter();
        let g = f.layout().albedo_gain().unwrap();
        let c = f.layout().scale(0);
        f.albedo_gain = 0.1;
        f.p[(g, c)] = 0.01;
        f.p[(c, g)] = 0.01;
        let mut decay = 1.0;
        for dt in [1.0, 10.0, 100.0, 1000.0] {
            f.propagate(&Vector3::new(0.01, -0.02, 0.005), 0.0, dt);
            decay *= (-dt / 360.0f64).exp();
            assert!(
                (f.p[(g, g)] - 0.04).abs() < 1e-15,
                "variance {}",
                f.p[(g, g)]
            );
            assert!((f.albedo_gain - 0.1 * decay).abs() < 1e-15);
            assert!((f.p[(g, c)] - 0.01 * decay).abs() < 1e-15);
            assert_eq!(f.p[(g, c)], f.p[(c, g)]);
            assert_eq!(
                f.last_propagation().unwrap().albedo_gain_decay,
                (-dt / 360.0f64).exp()
            );
        }
        f.reacquire(Quat::IDENTITY, &(Matrix3::identity() * 1e-4), 1e5);
        assert!((f.p[(g, g)] - 0.04).abs() < 1e-15);
        assert!(f.albedo_gain.abs() < 1e-100);
    }

    /// [`excess_light`] as the record the filter keeps.
    fn contradiction(
        sample: &OutsideSample,
        sun_body: Vector3<f64>,
        reference: &Reference,
        spread: impl FnOnce() -> Spread,
        noise: (f64, f64),
    ) -> Option<UpdateRecord> {
        let excess = excess_light(sample, sun_body, reference, spread, noise)?;
        Some(contradicted_record(0, sample.y, excess, noise.0))
    }

    /// [`missing_light`] as the record the filter keeps.
    fn unlit(
        sample: &OutsideSample,
        sun: (Vector3<f64>, f64),
        spread: Spread,
        noise: (f64, f64),
    ) -> Option<UpdateRecord> {
        let shortfall = missing_light(sample, sun, || spread, noise)?;
        Some(contradicted_record(0, sample.y, shortfall, noise.0))
    }

    /// A reference 7000 km from the Earth's centre with the Sun along +x at 1 AU.
    fn reference_at_7000_km() -> Reference {
        let sun_gcrf_km = Vector3::new(1.495_978_707e8, 0.0, 0.0);
        Reference {
            r_gcrf_km: Vector3::new(0.0, 7000.0, 0.0),
            sun_gcrf_km,
            sun_gcrf_unit: Vector3::x(),
            b_gcrf_nt: Vector3::zeros(),
            sun_fraction: 1.0,
            gcrf_to_itrf: Matrix3::identity(),
        }
    }

    fn spread(attitude_sigma_rad: f64) -> Spread {
        Spread {
            p_aa: Matrix3::identity() * attitude_sigma_rad.powi(2),
            normal_var: 0.0,
            scale_sigma_v: 0.01,
        }
    }

    #[test]
    fn a_sample_behind_its_photodiode_reading_the_sun_is_contradicted_only_if_the_estimate_is_sure()
    {
        let reference = reference_at_7000_km();
        // Normal along -x, the Sun along +x: behind it. A white Earth filling the view
        // gives at most (6378.137 / 7000)^2 = 0.83 of C.
        let sample = |y| OutsideSample {
            scale_v: 1.0,
            n_body: -Vector3::x(),
            y,
        };
        let tilted = OutsideSample {
            n_body: Vector3::new(-1.0, 0.2, 0.0).normalize(),
            ..sample(1.0)
        };
        let sun_body = Vector3::x();
        let gate = (0.005, 5.0);
        let sure = || spread(1f64.to_radians());
        // It reads the full Sun: no light from behind gives that.
        let r = contradiction(&sample(1.0), sun_body, &reference, sure, gate).unwrap();
        assert!(!r.accepted && r.residual > 0.0, "{r:?}");
        assert!(contradiction(&tilted, sun_body, &reference, sure, gate).is_some());
        // What the brightest Earth could give is no contradiction.
        assert!(contradiction(&sample(0.8), sun_body, &reference, sure, gate).is_none());
        // Nor is the full Sun when the attitude is uncertain by 40 deg: within 5 sigmas it
        // may face the Sun.
        let unsure = || spread(40f64.to_radians());
        assert!(contradiction(&sample(1.0), sun_body, &reference, unsure, gate).is_none());
    }

    #[test]
    fn an_unused_photodiode_dark_in_the_sun_is_unlit_only_if_the_estimate_is_sure() {
        // Its nominal normal 5 deg from the Sun, a scale of 1 V assumed.
        let n_body = Vector3::new(5f64.to_radians().cos(), 5f64.to_radians().sin(), 0.0);
        let sample = |y| OutsideSample {
            scale_v: 1.0,
            n_body,
            y,
        };
        let sun = (Vector3::x(), 1.0);
        let gate = (0.005, 5.0);
        let sure = || Spread {
            normal_var: 2.0 * 10f64.to_radians().powi(2),
            ..spread(1f64.to_radians())
        };
        let r = unlit(&sample(0.0), sun, sure(), gate).unwrap();
        assert!(!r.accepted && r.residual < 0.0, "{r:?}");
        // Lit as a working one would be: nothing to say.
        assert!(unlit(&sample(0.9), sun, sure(), gate).is_none());
        // The attitude uncertain by 40 deg: it may have faced away.
        assert!(unlit(&sample(0.0), sun, spread(40f64.to_radians()), gate).is_none());
    }
}
