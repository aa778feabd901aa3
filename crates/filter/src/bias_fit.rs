//! The gyro bias from the data at an acquisition: a short batch fit of the bias `b` (and
//! the attitude at the window's first row) to the body-frame vectors of the first rows of a
//! segment, the photodiode Sun vector and, when used, the magnetometer's field.
//!
//! Model: a body vector at row `k` is `v_B(k) = A(t_k) v_I(k)` with
//! `A(t_k) = R(t_0 -> t_k; omega_meas - b) A(t_0)`, the body rotation integrated from the gyro
//! (Markley & Crassidis Sec. 6.2.4, `pdcal_attitude::mekf::propagate`), which is the
//! integral of `d(v_B)/dt = -(omega_meas - b) x v_B` for a fixed inertial vector; each row
//! takes its own reference `v_I(k)`, so the references' own slow rotation (the field's,
//! along the orbit) is accounted for. Gauss-Newton on the attitude error at `t_0` and the
//! bias, linearised with the MEKF's error-state transition (`mekf::state_transition`: the
//! attitude error at `t_k` is `Phi_top(t_k, t_0) [a_0; db]`, and `d v_B / d a = [v_B x]`),
//! with the acquisition's attitude covariance and the filter's current bias as priors.
//! Weighted least squares: each unit vector's residual has `sigma^2 I` (the QUEST
//! measurement model, Shuster 1989; two degrees of freedom per vector), the covariance is
//! scaled up by the fit's own residual variance factor when that exceeds one (errors the
//! sigmas did not cover: an uncalibrated Sun vector, albedo).
//!
//! The fit's information on the bias, the attitude at `t_0` marginalised, is handed to the
//! filter as independent scalar measurements along its eigenvectors
//! ([`BiasFit::rows`]), only the directions the data determine ([`DETERMINED_FRACTION`]);
//! with the Sun alone and the Sun line fixed in the body frame, the bias along it is not
//! among them. The filter processes the same rows afterwards, so their information would
//! count twice: the rows' variances are doubled, so that twice half is once.

use std::ops::Range;

use nalgebra::{Matrix3, Matrix6, SymmetricEigen, Vector3, Vector6};
use pdcal_attitude::mekf::{apply_error, error_vector, propagate, state_transition};
use pdcal_attitude::{Quat, skew};
use pdcal_dataset::Telemetry;
use pdcal_photodiode::{Photodiode, SunVectorOptions, estimate_sun_vector};
use serde::Serialize;

use crate::{FilterError, References};

/// A bias direction is used when the fit's sigma along it is at most this fraction of the
/// prior's sigma along it: the data then carry at least four times the prior's information
/// there, so the direction is determined by them and not by the linearisation's start.
pub const DETERMINED_FRACTION: f64 = 0.5;

/// Fewest vector samples a fit takes: two per vector and six unknowns leave the residual
/// variance factor at least two degrees of freedom.
pub const MIN_VECTORS: usize = 4;

/// A predicted decrease below this fraction of the cost that no step length achieves is
/// rounding: converged.
const NO_DECREASE: f64 = 1e-9;

/// Gauss-Newton iterations per window length.
const MAX_ITERATIONS: usize = 50;

/// A predicted decrease of the cost (half a chi-square) below this ends the iterations: it
/// moves the optimum by about a thousandth of its sigma.
const CONVERGED: f64 = 1e-6;

/// What the fit reads.
pub struct FitInputs<'a> {
    /// Telemetry.
    pub telemetry: &'a Telemetry,
    /// One reference per row.
    pub references: References<'a>,
    /// Photodiodes with the current scales and normals (`noise_v` = photodiode sigma).
    pub photodiodes: &'a [Photodiode],
    /// Which photodiodes take part.
    pub used: &'a [bool],
    /// Fit the magnetometer's field too.
    pub use_mag: bool,
    /// Direction sigma of the photodiode Sun vector, rad.
    pub sun_sigma_rad: f64,
    /// Magnetometer sigma per axis, nT.
    pub mag_sigma_nt: f64,
    /// Smallest illuminated fraction for a Sun vector.
    pub min_sun_fraction: f64,
    /// How long a gyro sample may be held beyond the last one, s.
    pub gyro_hold_s: f64,
    /// The window's length from its first row, s.
    pub window_s: f64,
}

/// The priors: the acquisition's attitude at the window's first row and the filter's bias.
#[derive(Debug, Clone, PartialEq)]
pub struct FitPrior {
    /// Attitude at the window's first row.
    pub q0: Quat,
    /// Its error covariance, rad^2.
    pub attitude_cov: Matrix3<f64>,
    /// Bias, rad/s.
    pub bias_rad_s: Vector3<f64>,
    /// Its covariance, (rad/s)^2.
    pub bias_cov: Matrix3<f64>,
}

/// One scalar measurement of the bias: `direction . b = value` with `variance`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasRow {
    /// Unit direction, body frame.
    pub direction: Vector3<f64>,
    /// Measured component, rad/s.
    pub value_rad_s: f64,
    /// Its variance, (rad/s)^2.
    pub variance: f64,
}

/// An accepted fit.
#[derive(Debug, Clone, PartialEq)]
pub struct BiasFit {
    /// The bias at the fit's optimum (prior included), rad/s.
    pub bias_rad_s: Vector3<f64>,
    /// The data's information as scalar measurements, the determined directions only.
    pub rows: Vec<BiasRow>,
    /// Vector samples used.
    pub vectors: usize,
    /// Time from the window's first to its last row, s.
    pub span_s: f64,
    /// The residual variance factor the covariance was scaled by (at least 1).
    pub variance_factor: f64,
}

/// Where a segment's bias came from at its acquisition (`summary.json` `initial_bias` and
/// `segments[i].initial_bias`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum BiasSource {
    /// The batch fit of [`fit_bias`].
    Fit,
    /// The prior (at the first acquisition `initial_bias_sigma_deg_s`), or the estimate
    /// carried from the previous segment.
    Prior,
}

/// The bias at a segment's acquisition, after the fit (`summary.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct InitialBias {
    /// Fit or prior.
    pub source: BiasSource,
    /// Bias per body axis, deg/s.
    pub bias_deg_s: [f64; 3],
    /// Its sigma per body axis, deg/s.
    pub sigma_deg_s: [f64; 3],
    /// Bias directions the fit determined (0 for the prior).
    pub directions: usize,
    /// Vector samples of the fit.
    pub vectors: usize,
    /// Time the fit spans, s.
    pub span_s: f64,
    /// Why the fit was not used, when it was not.
    pub reason: Option<String>,
}

/// A point of the fit: the attitude at the window's first row and the bias.
#[derive(Clone, Copy)]
struct Point {
    q0: Quat,
    bias: Vector3<f64>,
}

impl Point {
    /// The point moved by `step` (attitude error, bias change) times `scale`, the attitude
    /// multiplicatively as the linearisation assumes.
    fn moved(&self, step: &Vector6<f64>, scale: f64) -> Point {
        let a = Vector3::new(step[0], step[1], step[2]) * scale;
        let db = Vector3::new(step[3], step[4], step[5]) * scale;
        Point {
            q0: apply_error(&self.q0, &a),
            bias: self.bias + db,
        }
    }
}

/// A vector sample: window step, measured body unit vector, reference unit vector, sigma.
struct Sample {
    /// The photodiode Sun vector (else the magnetometer's field).
    sun: bool,
    step: usize,
    body: Vector3<f64>,
    inertial: Vector3<f64>,
    sigma_rad: f64,
}

/// The window: row times and the rate of each interval between consecutive rows.
struct Window {
    t_s: Vec<f64>,
    rate_rad_s: Vec<Vector3<f64>>,
}

/// Fits the bias over the rows of `rows` within `window_s` of its first row (the
/// acquisition row). `Ok(Err(reason))` when the fit is refused: too few vectors, the normal
/// matrix singular, no direction determined, no convergence.
pub fn fit_bias(
    inputs: &FitInputs<'_>,
    rows: Range<usize>,
    prior: &FitPrior,
) -> Result<Result<BiasFit, String>, FilterError> {
    let Some(window) = window(inputs, rows.clone()) else {
        return Ok(Err("no gyro rate over the window".to_owned()));
    };
    let samples = samples(inputs, rows.start, window.t_s.len())?;
    if samples.len() < MIN_VECTORS {
        return Ok(Err(format!(
            "too short: {} vector samples, {MIN_VECTORS} needed",
            samples.len()
        )));
    }
    let mut x = Point {
        q0: prior.q0,
        bias: prior.bias_rad_s,
    };
    let Some(priors) = prior_information(prior) else {
        return Ok(Err("a singular prior covariance".to_owned()));
    };
    // Window lengths doubling from the first few samples: each start is close enough to
    // the longer window's optimum for the linearisation.
    let mut n = 3.min(samples.len());
    loop {
        let used = &samples[..n];
        if !iterate(&window, used, prior, &priors, &mut x) {
            return Ok(Err("the fit did not converge".to_owned()));
        }
        if n == samples.len() {
            break;
        }
        n = (2 * n).min(samples.len());
    }
    let normal = normal_equations(&window, &samples, &x);
    Ok(conclude(&samples, &window, prior, &priors, &x, &normal))
}

/// The priors' information blocks: attitude at `t_0`, bias.
fn prior_information(prior: &FitPrior) -> Option<(Matrix3<f64>, Matrix3<f64>)> {
    Some((
        prior.attitude_cov.try_inverse()?,
        prior.bias_cov.try_inverse()?,
    ))
}

/// Gauss-Newton to convergence on `samples`, each step halved until the cost (data and
/// priors) decreases; false when it does not converge.
fn iterate(
    window: &Window,
    samples: &[Sample],
    prior: &FitPrior,
    priors: &(Matrix3<f64>, Matrix3<f64>),
    x: &mut Point,
) -> bool {
    let mut normal = normal_equations(window, samples, x);
    let mut cost = add_priors(&mut normal, prior, priors, x);
    for _ in 0..MAX_ITERATIONS {
        let Some(step) = normal.matrix.cholesky().map(|c| c.solve(&normal.gradient)) else {
            return false;
        };
        // The cost decrease the step predicts, `g^T N^-1 g / 2`: converged when it is
        // rounding (a step along a direction the data barely see may stay finite).
        let predicted = 0.5 * normal.gradient.dot(&step);
        if predicted < CONVERGED {
            return true;
        }
        let mut scale = 1.0;
        loop {
            let trial = x.moved(&step, scale);
            let mut trial_normal = normal_equations(window, samples, &trial);
            let trial_cost = add_priors(&mut trial_normal, prior, priors, &trial);
            if trial_cost.is_finite() && trial_cost <= cost {
                *x = trial;
                normal = trial_normal;
                cost = trial_cost;
                break;
            }
            scale *= 0.5;
            if scale < 1e-6 {
                // No decrease along the step: at the optimum to rounding when the
                // predicted decrease is negligible against the cost, else stuck.
                return predicted < NO_DECREASE * cost.max(1.0);
            }
        }
    }
    false
}

/// Data-only normal equations at `x`: `sum H^T W H`, `sum H^T W r`, and `sum r^T W r`.
struct Normal {
    matrix: Matrix6<f64>,
    gradient: Vector6<f64>,
    chi2: f64,
}

fn normal_equations(window: &Window, samples: &[Sample], x: &Point) -> Normal {
    let bias = x.bias;
    let mut q = x.q0;
    let mut phi = Matrix6::identity();
    let mut normal = Normal {
        matrix: Matrix6::zeros(),
        gradient: Vector6::zeros(),
        chi2: 0.0,
    };
    let mut step = 0;
    for s in samples {
        while step < s.step {
            let rate = window.rate_rad_s[step] - bias;
            let dt = window.t_s[step + 1] - window.t_s[step];
            q = propagate(&q, &rate, dt);
            phi = state_transition(&rate, dt) * phi;
            step += 1;
        }
        let predicted = q.to_body(&s.inertial);
        let h = skew(&predicted) * phi.fixed_rows::<3>(0);
        let residual = s.body - predicted;
        let w = s.sigma_rad.powi(-2);
        normal.matrix += h.transpose() * h * w;
        normal.gradient += h.transpose() * residual * w;
        normal.chi2 += residual.norm_squared() * w;
    }
    normal
}

/// Adds the priors' information and their pull towards the prior means; the cost, half
/// the data's chi-square plus the priors' quadratic forms.
fn add_priors(
    normal: &mut Normal,
    prior: &FitPrior,
    (info_attitude, info_bias): &(Matrix3<f64>, Matrix3<f64>),
    x: &Point,
) -> f64 {
    // The attitude's offset from its prior as an error vector; its Jacobian taken as the
    // identity (exact at the prior, and the prior is wide where the offset is large).
    let attitude = error_vector(&x.q0, &prior.q0);
    let bias = x.bias - prior.bias_rad_s;
    let mut m = normal.matrix.fixed_view_mut::<3, 3>(0, 0);
    m += info_attitude;
    let mut m = normal.matrix.fixed_view_mut::<3, 3>(3, 3);
    m += info_bias;
    let pull_attitude = info_attitude * attitude;
    let pull_bias = info_bias * bias;
    for k in 0..3 {
        normal.gradient[k] -= pull_attitude[k];
        normal.gradient[3 + k] -= pull_bias[k];
    }
    0.5 * (normal.chi2 + attitude.dot(&pull_attitude) + bias.dot(&pull_bias))
}

/// The data's marginal information on the bias (the attitude at `t_0` eliminated with its
/// prior), scaled by the variance factor, as scalar measurements along the determined
/// eigenvectors, each centred so that the filter's update reaches the fit's optimum.
fn conclude(
    samples: &[Sample],
    window: &Window,
    prior: &FitPrior,
    (info_attitude, info_bias): &(Matrix3<f64>, Matrix3<f64>),
    x: &Point,
    normal: &Normal,
) -> Result<BiasFit, String> {
    let m = &normal.matrix;
    let aa = m.fixed_view::<3, 3>(0, 0) + info_attitude;
    let ab = m.fixed_view::<3, 3>(0, 3).into_owned();
    let bb = m.fixed_view::<3, 3>(3, 3).into_owned();
    let aa_inv = aa
        .try_inverse()
        .ok_or_else(|| "the attitude's normal matrix is singular".to_owned())?;
    let data = bb - ab.transpose() * aa_inv * ab;
    let dof = 2 * samples.len() - 6;
    let variance_factor = (normal.chi2 / dof as f64).max(1.0);
    let floor = systematic_floor(samples, window, x);
    let bias = x.bias;
    let pull = info_bias * (bias - prior.bias_rad_s);
    let eigen = SymmetricEigen::new(0.5 * (data + data.transpose()));
    let mut rows = Vec::new();
    for (k, &lambda) in eigen.eigenvalues.iter().enumerate() {
        let u: Vector3<f64> = eigen.eigenvectors.column(k).into_owned();
        let prior_sigma = (u.transpose() * prior.bias_cov * u)[0].sqrt();
        let variance = variance_factor / lambda + floor;
        if lambda > 0.0 && variance.sqrt() <= DETERMINED_FRACTION * prior_sigma {
            rows.push(BiasRow {
                direction: u,
                // The data-only estimate along u: the optimum less the prior's pull.
                value_rad_s: u.dot(&bias) + u.dot(&pull) / lambda,
                variance: 2.0 * variance,
            });
        }
    }
    if rows.is_empty() {
        return Err(format!(
            "not determined: no bias direction's fit sigma within {DETERMINED_FRACTION} of \
             its prior sigma over {} vector samples",
            samples.len()
        ));
    }
    let last = samples.last().map_or(0, |s| s.step);
    Ok(BiasFit {
        bias_rad_s: bias,
        rows,
        vectors: samples.len(),
        span_s: window.t_s[last] - window.t_s[0],
        variance_factor,
    })
}

/// The bias variance that errors of the vectors which change with their direction in the
/// body frame leave, whatever the number of samples: an uncalibrated Sun vector is off by
/// up to its sigma, and that error changes by about its sigma per radian the Sun moves
/// through the body frame, so it reads as a rate error of `sigma |w x v|`. Per kind of
/// vector, the mean of `(sigma |(w - b) x v|)^2` over its samples; the smaller of the kinds
/// (the bias rests on the better one).
fn systematic_floor(samples: &[Sample], window: &Window, x: &Point) -> f64 {
    let mean = |sun: bool| {
        let terms: Vec<f64> = samples
            .iter()
            .filter(|s| s.sun == sun)
            .map(|s| {
                let rate = window.rate_rad_s[s.step.min(window.rate_rad_s.len() - 1)] - x.bias;
                (s.sigma_rad * rate.cross(&s.body).norm()).powi(2)
            })
            .collect();
        (!terms.is_empty()).then(|| terms.iter().sum::<f64>() / terms.len() as f64)
    };
    match (mean(true), mean(false)) {
        (Some(a), Some(b)) => a.min(b),
        (a, b) => a.or(b).unwrap_or(0.0),
    }
}

/// The window's row times and interval rates: each row's rate interpolated linearly
/// between the gyro samples around it (held within the gyro hold before the first or after
/// the last), the interval's rate the mean of its ends. The window ends at the first row
/// without a rate. `None` with fewer than two rows.
fn window(inputs: &FitInputs<'_>, rows: Range<usize>) -> Option<Window> {
    let tel = inputs.telemetry;
    let t0 = tel.t_s[rows.start];
    let rows = rows.start
        ..rows.end.min(
            (rows.start..rows.end)
                .find(|&k| tel.t_s[k] - t0 > inputs.window_s)
                .unwrap_or(rows.end),
        );
    let gyro: Vec<(f64, Vector3<f64>)> = rows
        .clone()
        .filter_map(|k| tel.gyro_rad_s.get(k).map(|w| (tel.t_s[k], w)))
        .collect();
    let mut t_s = Vec::new();
    let mut rates = Vec::new();
    for k in rows {
        let Some(rate) = rate_at(&gyro, tel.t_s[k], inputs.gyro_hold_s) else {
            break;
        };
        t_s.push(tel.t_s[k]);
        rates.push(rate);
    }
    if t_s.len() < 2 {
        return None;
    }
    let rate_rad_s = rates.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
    Some(Window { t_s, rate_rad_s })
}

/// The rate at `t` from the samples `gyro` (in time order).
fn rate_at(gyro: &[(f64, Vector3<f64>)], t: f64, hold_s: f64) -> Option<Vector3<f64>> {
    let after = gyro.partition_point(|(tg, _)| *tg < t);
    match (after.checked_sub(1).map(|i| gyro[i]), gyro.get(after)) {
        (_, Some(&(ta, wa))) if ta == t => Some(wa),
        (Some((tb, wb)), Some(&(ta, wa))) => Some(wb + (wa - wb) * ((t - tb) / (ta - tb))),
        (Some((tb, wb)), None) if t - tb <= hold_s => Some(wb),
        (None, Some(&(ta, wa))) if ta - t <= hold_s => Some(wa),
        _ => None,
    }
}

/// The vector samples of the window's first `steps` rows from `first`: the photodiode Sun
/// vector in full Sun (least squares through the current calibration, the albedo inside its
/// sigma), the magnetometer's field when used.
fn samples(inputs: &FitInputs<'_>, first: usize, steps: usize) -> Result<Vec<Sample>, FilterError> {
    let tel = inputs.telemetry;
    let mut out = Vec::new();
    for step in 0..steps {
        let k = first + step;
        let reference = inputs.references.at(k)?;
        if reference.sun_fraction >= inputs.min_sun_fraction
            && let Some(sun) = sun_vector(inputs, k, reference.sun_distance_factor())?
        {
            out.push(Sample {
                sun: true,
                step,
                body: sun,
                inertial: reference.sun_gcrf_unit,
                sigma_rad: inputs.sun_sigma_rad,
            });
        }
        let field = tel.mag_nt.as_ref().and_then(|m| m.get(k));
        if inputs.use_mag
            && let Some(b) = field
            && b.norm() > 0.0
            && reference.b_gcrf_nt.norm() > 0.0
        {
            out.push(Sample {
                sun: false,
                step,
                body: b.normalize(),
                inertial: reference.b_gcrf_nt.normalize(),
                sigma_rad: inputs.mag_sigma_nt / b.norm(),
            });
        }
    }
    Ok(out)
}

/// The photodiode Sun direction at row `k`, when observable.
fn sun_vector(
    inputs: &FitInputs<'_>,
    k: usize,
    sun_distance_factor: f64,
) -> Result<Option<Vector3<f64>>, FilterError> {
    let tel = inputs.telemetry;
    // As in the acquisition, a photodiode whose scale the filter has driven to zero or
    // below cannot turn its output into a direction.
    let sampled: Vec<usize> = (0..inputs.photodiodes.len())
        .filter(|&i| {
            inputs.used[i] && inputs.photodiodes[i].scale_v > 0.0 && tel.pd_v[i].get(k).is_some()
        })
        .collect();
    let pds: Vec<Photodiode> = sampled.iter().map(|&i| inputs.photodiodes[i]).collect();
    let outputs: Vec<f64> = sampled
        .iter()
        .map(|&i| tel.pd_v[i].get(k).unwrap_or(0.0))
        .collect();
    let options = SunVectorOptions {
        sun_distance_factor,
        ..SunVectorOptions::default()
    };
    Ok(estimate_sun_vector(&pds, &outputs, None, &options)?.direction_body())
}
