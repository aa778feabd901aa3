//! The truth comparison of `pdcal evaluate`: the true errors of a calibration, which the
//! paper could not report (flight data has no truth), from a simulated data set's truth.
//! Values in, values out: the driver reads the files (`pdcal::evaluate`) and writes
//! `evaluation.json`; the diagnosis tests and the developer demo call it directly.

use anyhow::{Context, Result, bail};
use nalgebra::Vector3;
use pdcal_attitude::{Quat, mekf::error_vector, normal_from_az_el, wrap_deg};
use pdcal_dataset::{TruthConstants, TruthSeries};
use pdcal_filter::{Calibration, StepEstimate};
use serde::Serialize;

/// Version of the output files' layout (cli-contract.md): `evaluation.json` and the
/// driver's `summary.json` alike.
pub const OUTPUT_FORMAT_VERSION: u32 = 1;

/// Sunlit time after which attitude statistics are taken (the paper's ~10 min convergence).
pub const CONVERGENCE_SUNLIT_S: f64 = 600.0;

/// The attitude after an acquisition is judged from this long after it, s: the q-method's
/// 10-degree start needs a few tens of photodiode updates to converge.
pub const SETTLE_AFTER_ACQUISITION_S: f64 = 60.0;
/// Incidence angle inside which a photodiode counts as usefully lit (the filter's default
/// field of view), deg.
pub const LIT_FOV_DEG: f64 = 60.0;

/// Share of the estimate rows that truth.csv must cover for the time-series figures.
pub const MIN_TRUTH_COVERAGE: f64 = 0.99;
/// Minutes a photodiode must be lit to count in the worst-case figures.
pub const WELL_LIT_MINUTES: f64 = 5.0;

/// `evaluation.json`. A figure that cannot be computed is NaN here, `null` in the JSON, and
/// listed in `not_evaluable` with the reason; it is never reported as 0.
#[derive(Debug, Clone, Serialize)]
pub struct Evaluation {
    /// Layout version.
    pub format_version: u32,
    /// Per photodiode errors, pdNN order.
    pub photodiodes: Vec<PdError>,
    /// Worst normal error over photodiodes lit at least 5 minutes, deg.
    pub worst_normal_error_deg: f64,
    /// Worst |scale error| over photodiodes lit at least 5 minutes, %.
    pub worst_scale_error_percent: f64,
    /// Attitude error over sunlit samples after convergence.
    pub attitude: AttitudeStats,
    /// Attitude error over sunlit samples from [`SETTLE_AFTER_ACQUISITION_S`] after each
    /// acquisition of the attitude (the start of every segment).
    pub attitude_after_acquisition: AttitudeStats,
    /// NEES-style consistency.
    pub consistency: Consistency,
    /// Estimate rows whose time truth.csv has, and all estimate rows.
    pub truth_coverage: TruthCoverage,
    /// The figures that are `null`, and why.
    pub not_evaluable: Vec<NotEvaluable>,
    /// The smoother's attitude (`estimates_smoothed.csv`) on the same kind of samples, when
    /// the run smoothed ([`evaluate_with_smoothed`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub smoothed: Option<SmoothedAttitude>,
}

/// The attitude figures of [`Evaluation`] for the smoothed rows (`null` where their
/// evaluation's are: that evaluation's `not_evaluable` says why).
#[derive(Debug, Clone, Serialize)]
pub struct SmoothedAttitude {
    /// Attitude error over sunlit samples after convergence.
    pub attitude: AttitudeStats,
    /// As [`Consistency::attitude_within_3sigma`].
    pub attitude_within_3sigma: f64,
    /// As [`Consistency::attitude_about_sun_within_3sigma`].
    pub attitude_about_sun_within_3sigma: f64,
    /// As [`Consistency::attitude_across_sun_within_3sigma`].
    pub attitude_across_sun_within_3sigma: f64,
}

impl SmoothedAttitude {
    /// The attitude figures of `e`, the evaluation of a run's smoothed rows.
    fn of(e: &Evaluation) -> Self {
        let c = &e.consistency;
        SmoothedAttitude {
            attitude: e.attitude.clone(),
            attitude_within_3sigma: c.attitude_within_3sigma,
            attitude_about_sun_within_3sigma: c.attitude_about_sun_within_3sigma,
            attitude_across_sun_within_3sigma: c.attitude_across_sun_within_3sigma,
        }
    }
}

/// How many estimate rows truth.csv covers.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct TruthCoverage {
    /// Estimate rows with a truth row at the same time.
    pub matched_rows: usize,
    /// Estimate rows.
    pub estimate_rows: usize,
}

/// A figure left `null` in `evaluation.json`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NotEvaluable {
    /// Its JSON path (`attitude.rms_deg`).
    pub figure: &'static str,
    /// Why it cannot be computed.
    pub reason: String,
}

/// One photodiode's true errors.
#[derive(Debug, Clone, Serialize)]
#[allow(non_snake_case)]
pub struct PdError {
    /// 1-based index.
    pub index: usize,
    /// True minus estimated scale, V.
    pub scale_error_V: f64,
    /// The same relative to the true scale, %.
    pub scale_error_percent: f64,
    /// Angle between true and estimated normals, deg.
    pub normal_error_deg: f64,
    /// Minutes in full Sun with incidence inside the field of view (true geometry).
    pub lit_minutes: f64,
}

/// Attitude error statistics, deg.
#[derive(Debug, Clone, Serialize)]
pub struct AttitudeStats {
    /// Samples counted (sunlit, after the first 10 sunlit minutes).
    pub samples: usize,
    /// Mean rotation angle error.
    pub mean_deg: f64,
    /// RMS rotation angle error.
    pub rms_deg: f64,
    /// 99th percentile of the rotation angle error.
    pub p99_deg: f64,
    /// RMS error per body axis (the empirical 1-sigma).
    pub axis_rms_deg: [f64; 3],
    /// Mean filter 1-sigma per body axis over the same samples.
    pub axis_filter_sigma_deg: [f64; 3],
}

/// Consistency of errors and covariance.
#[derive(Debug, Clone, Serialize)]
pub struct Consistency {
    /// Fraction of final calibration-state errors (scale, azimuth, elevation, gyro bias)
    /// inside 3 sigma.
    pub final_states_within_3sigma: f64,
    /// Final calibration states counted.
    pub final_states: usize,
    /// Fraction of attitude-axis errors inside 3 sigma over all samples after convergence.
    pub attitude_within_3sigma: f64,
    /// Fraction of calibration estimates within 3 sigma of their final values after 10 min of
    /// sunlit data (scale, elevation and, where defined, azimuth of every used photodiode).
    pub converged_within_3sigma_of_final: f64,
    /// Fraction of the attitude errors about the (true) Sun line inside their 3 sigma over
    /// the same samples as `attitude_within_3sigma` (NaN without the whole covariance).
    pub attitude_about_sun_within_3sigma: f64,
    /// The same across the Sun line (the two directions a Sun vector observes), per
    /// principal axis of the covariance across it.
    pub attitude_across_sun_within_3sigma: f64,
    /// Fraction of the gyro-bias errors inside their 3 sigma, per axis, over the same
    /// samples as `attitude_within_3sigma` (the running estimate against the simulated
    /// bias of that sample).
    pub gyro_bias_within_3sigma: f64,
    /// The final calibration states by their reported status (calibration.ron `status`):
    /// how many of each, and how many of those lie outside 3 sigma of the truth.
    pub by_status: StatusTally,
}

/// Final states per status, and those outside 3 sigma of the truth.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct StatusTally {
    /// `calibrated` states.
    pub calibrated: usize,
    /// Of which outside 3 sigma.
    pub calibrated_outside_3sigma: usize,
    /// `weakly-determined` states.
    pub weakly_determined: usize,
    /// Of which outside 3 sigma.
    pub weakly_determined_outside_3sigma: usize,
    /// `not-determined` states (reported at the prior).
    pub not_determined: usize,
    /// Of which outside 3 sigma.
    pub not_determined_outside_3sigma: usize,
}

impl StatusTally {
    fn add(&mut self, status: &str, inside: bool) {
        let outside = usize::from(!inside);
        match status {
            "not-determined" => {
                self.not_determined += 1;
                self.not_determined_outside_3sigma += outside;
            }
            "weakly-determined" => {
                self.weakly_determined += 1;
                self.weakly_determined_outside_3sigma += outside;
            }
            _ => {
                self.calibrated += 1;
                self.calibrated_outside_3sigma += outside;
            }
        }
    }
}

/// The status calibration.ron gives quantity `name` (`pd03 scale_V`, `gyro_bias_x`):
/// `calibrated` unless a `status` line names it.
fn status_of<'a>(cal: &'a Calibration, name: &str) -> &'a str {
    cal.status
        .iter()
        .find_map(|line| {
            let rest = line.strip_prefix(name)?.strip_prefix(": ")?;
            rest.split_whitespace().next()
        })
        .unwrap_or("calibrated")
}

/// Whether the attitude error is inside 3 sigma about the Sun line and across it, given the
/// true and estimated attitudes, the true Sun direction in the body and the estimate's
/// attitude covariance `p` (deg^2); `None` without a whole covariance.
///
/// About the line: the rotation-vector error's component along the Sun. Across it: the
/// error of the Sun direction itself (`s_est x s_true`, the direction and angle by which
/// the estimate misplaces the Sun in the body), per principal axis of the covariance
/// across the line: unlike the rotation vector's components, it stays the observed error
/// whatever the (unobserved) rotation about the line.
pub fn sun_line_inside(
    q_true: &Quat,
    q_est: &Quat,
    sun_body_true: &Vector3<f64>,
    p: &nalgebra::Matrix3<f64>,
) -> Option<(bool, bool)> {
    if !p.iter().all(|x| x.is_finite()) {
        return None;
    }
    let s_true = sun_body_true.try_normalize(1e-12)?;
    let s_inertial = q_true.attitude_matrix().transpose() * s_true;
    let s_est = q_est.to_body(&s_inertial);
    let a = error_vector(q_true, q_est).map(f64::to_degrees);
    let about_var = (s_true.transpose() * p * s_true)[0];
    let about = a.dot(&s_true).abs() <= 3.0 * about_var.max(0.0).sqrt();
    let cross = s_est.cross(&s_true);
    let angle_deg = cross.norm().atan2(s_est.dot(&s_true)).to_degrees();
    let across_err = cross
        .try_normalize(1e-15)
        .map_or(Vector3::zeros(), |d| d * angle_deg);
    let e1 = s_true
        .cross(&Vector3::x())
        .try_normalize(1e-6)
        .or_else(|| s_true.cross(&Vector3::y()).try_normalize(1e-6))?;
    let e2 = s_true.cross(&e1);
    let basis = nalgebra::Matrix3x2::from_columns(&[e1, e2]);
    let eig = nalgebra::SymmetricEigen::new(basis.transpose() * p * basis);
    let across = (0..2).all(|k| {
        let axis = basis * eig.eigenvectors.column(k);
        across_err.dot(&axis).abs() <= 3.0 * eig.eigenvalues[k].max(0.0).sqrt()
    });
    Some((about, across))
}

fn quat_of(v: &nalgebra::Vector4<f64>) -> Option<Quat> {
    Quat::new_normalized(v.x, v.y, v.z, v.w)
}

/// What is wrong with four numbers that do not normalise to a quaternion: a NaN or an
/// infinity is not a zero quaternion.
pub fn quaternion_fault(q: &[f64; 4]) -> String {
    if !q.iter().all(|x| x.is_finite()) {
        format!("{q:?} (not finite)")
    } else if q.iter().all(|x| *x == 0.0) {
        format!("{q:?} (all zero)")
    } else {
        format!("{q:?} (its norm overflows)")
    }
}

/// [`evaluate`] of a run's forward estimates, with the attitude figures of its smoothed
/// rows (`smoothed`, when it smoothed) against the same truth and calibration.
pub fn evaluate_with_smoothed(
    estimates: &[StepEstimate],
    smoothed: Option<&[StepEstimate]>,
    final_cal: &Calibration,
    truth: &TruthSeries,
    constants: &TruthConstants,
) -> Result<Evaluation> {
    let mut evaluation = evaluate(estimates, final_cal, truth, constants)?;
    if let Some(rows) = smoothed {
        let of_rows = evaluate(rows, final_cal, truth, constants)?;
        evaluation.smoothed = Some(SmoothedAttitude::of(&of_rows));
    }
    Ok(evaluation)
}

/// Evaluates estimates (forward or smoothed) and the final calibration against truth.
pub fn evaluate(
    estimates: &[StepEstimate],
    final_cal: &Calibration,
    truth: &TruthSeries,
    constants: &TruthConstants,
) -> Result<Evaluation> {
    if constants.photodiodes.len() != final_cal.photodiodes.len() {
        bail!(
            "truth.ron has {} photodiodes, the calibration {}",
            constants.photodiodes.len(),
            final_cal.photodiodes.len()
        );
    }
    let truth_row = |t: f64| truth.t_s.binary_search_by(|x| x.total_cmp(&t)).ok();
    let (photodiodes, worst_normal_error_deg, worst_scale_error_percent) =
        photodiode_errors(final_cal, truth, constants);
    let attitude = attitude_stats(
        estimates,
        truth,
        converged_sunlit(estimates, truth, &truth_row),
    )?;
    let after_acquisition = attitude_stats(
        estimates,
        truth,
        settled_sunlit(estimates, truth, &truth_row),
    )?;
    let consistency = consistency(
        estimates,
        final_cal,
        truth,
        constants,
        &truth_row,
        &attitude.1,
    );
    let truth_coverage = TruthCoverage {
        matched_rows: estimates
            .iter()
            .filter(|e| truth_row(e.t_s).is_some())
            .count(),
        estimate_rows: estimates.len(),
    };
    let mut evaluation = Evaluation {
        format_version: OUTPUT_FORMAT_VERSION,
        worst_normal_error_deg,
        worst_scale_error_percent,
        photodiodes,
        attitude: attitude.0,
        attitude_after_acquisition: after_acquisition.0,
        consistency,
        truth_coverage,
        not_evaluable: Vec::new(),
        smoothed: None,
    };
    mark_not_evaluable(&mut evaluation);
    Ok(evaluation)
}

/// Each photodiode's true errors, and the worst normal (deg) and scale (%) errors over the
/// photodiodes lit at least 5 minutes (NaN when none was). The calibration must have truth.ron's photodiode
/// count (checked by [`evaluate`]).
pub fn photodiode_errors(
    final_cal: &Calibration,
    truth: &TruthSeries,
    constants: &TruthConstants,
) -> (Vec<PdError>, f64, f64) {
    let lit_minutes = lit_minutes(truth, constants);
    let photodiodes: Vec<PdError> = constants
        .photodiodes
        .iter()
        .zip(&final_cal.photodiodes)
        .enumerate()
        .map(|(i, (t, e))| {
            let n_true =
                normal_from_az_el(t.azimuth_deg.to_radians(), t.elevation_deg.to_radians());
            PdError {
                index: i + 1,
                scale_error_V: t.scale_v - e.scale_v,
                scale_error_percent: 100.0 * (t.scale_v - e.scale_v) / t.scale_v,
                normal_error_deg: n_true.angle(&e.n_body()).to_degrees(),
                lit_minutes: lit_minutes[i],
            }
        })
        .collect();
    let well_lit = || {
        photodiodes
            .iter()
            .filter(|p| p.lit_minutes >= WELL_LIT_MINUTES)
    };
    // NaN, not 0, when no photodiode was lit long enough: there is no worst case.
    let normal = well_lit()
        .map(|p| p.normal_error_deg)
        .fold(f64::NAN, f64::max);
    let scale = well_lit()
        .map(|p| p.scale_error_percent.abs())
        .fold(f64::NAN, f64::max);
    (photodiodes, normal, scale)
}

/// Sets to NaN, and lists with the reason, every figure the data cannot support: all
/// time-series figures when truth.csv covers too few estimate rows, the worst-case figures
/// when no photodiode was lit long enough, and statistics over no samples.
fn mark_not_evaluable(e: &mut Evaluation) {
    let mut out = Vec::new();
    let c = e.truth_coverage;
    let covered =
        c.estimate_rows > 0 && c.matched_rows as f64 >= MIN_TRUTH_COVERAGE * c.estimate_rows as f64;
    if !covered {
        let reason = format!(
            "truth.csv covers {} of {} estimate rows (needs {:.0} %)",
            c.matched_rows,
            c.estimate_rows,
            100.0 * MIN_TRUTH_COVERAGE
        );
        let a = &mut e.attitude;
        let k = &mut e.consistency;
        for (figure, value) in [
            ("worst_normal_error_deg", &mut e.worst_normal_error_deg),
            (
                "worst_scale_error_percent",
                &mut e.worst_scale_error_percent,
            ),
            ("attitude.mean_deg", &mut a.mean_deg),
            ("attitude.rms_deg", &mut a.rms_deg),
            ("attitude.p99_deg", &mut a.p99_deg),
            (
                "consistency.attitude_within_3sigma",
                &mut k.attitude_within_3sigma,
            ),
            (
                "consistency.converged_within_3sigma_of_final",
                &mut k.converged_within_3sigma_of_final,
            ),
        ] {
            *value = f64::NAN;
            out.push(NotEvaluable {
                figure,
                reason: reason.clone(),
            });
        }
        a.axis_rms_deg = [f64::NAN; 3];
        a.axis_filter_sigma_deg = [f64::NAN; 3];
    }
    if covered && e.worst_normal_error_deg.is_nan() {
        let most = e
            .photodiodes
            .iter()
            .max_by(|a, b| a.lit_minutes.total_cmp(&b.lit_minutes));
        let reason = match most {
            Some(p) => format!(
                "no photodiode was lit (full Sun, within {LIT_FOV_DEG:.0} deg) for \
                 {WELL_LIT_MINUTES:.0} minutes; the most was pd{:02} with {:.1} min",
                p.index, p.lit_minutes
            ),
            None => "no photodiodes".to_owned(),
        };
        for figure in ["worst_normal_error_deg", "worst_scale_error_percent"] {
            out.push(NotEvaluable {
                figure,
                reason: reason.clone(),
            });
        }
    }
    if covered && e.attitude.samples == 0 {
        for figure in ["attitude.mean_deg", "attitude.rms_deg", "attitude.p99_deg"] {
            out.push(NotEvaluable {
                figure,
                reason: format!(
                    "no sunlit samples after the first {CONVERGENCE_SUNLIT_S:.0} sunlit seconds"
                ),
            });
        }
    }
    if covered && e.attitude_after_acquisition.samples == 0 {
        for figure in [
            "attitude_after_acquisition.mean_deg",
            "attitude_after_acquisition.rms_deg",
            "attitude_after_acquisition.p99_deg",
        ] {
            out.push(NotEvaluable {
                figure,
                reason: format!(
                    "no sunlit samples {SETTLE_AFTER_ACQUISITION_S:.0} s after an acquisition"
                ),
            });
        }
    }
    e.not_evaluable = out;
}

/// Minutes each photodiode spent in full Sun with the Sun inside its field of view (truth).
fn lit_minutes(truth: &TruthSeries, constants: &TruthConstants) -> Vec<f64> {
    let cos_fov = LIT_FOV_DEG.to_radians().cos();
    let dt_min = truth
        .t_s
        .windows(2)
        .next()
        .map_or(1.0 / 60.0, |w| (w[1] - w[0]) / 60.0);
    constants
        .photodiodes
        .iter()
        .map(|p| {
            let n = normal_from_az_el(p.azimuth_deg.to_radians(), p.elevation_deg.to_radians());
            let rows = truth
                .sun_body
                .iter()
                .zip(&truth.eclipse)
                .filter(|(s, e)| **e >= 0.999 && n.dot(s) >= cos_fov);
            rows.count() as f64 * dt_min
        })
        .collect()
}

/// Indices (into `estimates`) of the samples in full Sun after the first 10 sunlit minutes.
fn converged_sunlit(
    estimates: &[StepEstimate],
    truth: &TruthSeries,
    truth_row: &dyn Fn(f64) -> Option<usize>,
) -> Vec<(usize, usize)> {
    let mut sunlit_s = 0.0;
    let mut previous: Option<(usize, f64)> = None;
    let mut out = Vec::new();
    for (k, e) in estimates.iter().enumerate() {
        let Some(row) = truth_row(e.t_s) else {
            continue;
        };
        // The time across a gap between segments was not observed.
        let dt = match previous {
            Some((segment, t)) if segment == e.segment => e.t_s - t,
            _ => 0.0,
        };
        previous = Some((e.segment, e.t_s));
        if truth.eclipse[row] >= 0.999 {
            sunlit_s += dt;
            if sunlit_s >= CONVERGENCE_SUNLIT_S {
                out.push((k, row));
            }
        }
    }
    out
}

/// Indices (into `estimates`) of the samples in full Sun at least
/// [`SETTLE_AFTER_ACQUISITION_S`] after the first row of their segment, with their truth rows.
fn settled_sunlit(
    estimates: &[StepEstimate],
    truth: &TruthSeries,
    truth_row: &dyn Fn(f64) -> Option<usize>,
) -> Vec<(usize, usize)> {
    let mut segment_start: Option<(usize, f64)> = None;
    let mut out = Vec::new();
    for (k, e) in estimates.iter().enumerate() {
        let start = match segment_start {
            Some((segment, t)) if segment == e.segment => t,
            _ => {
                segment_start = Some((e.segment, e.t_s));
                e.t_s
            }
        };
        if let Some(row) = truth_row(e.t_s)
            && truth.eclipse[row] >= 0.999
            && e.t_s - start >= SETTLE_AFTER_ACQUISITION_S
        {
            out.push((k, row));
        }
    }
    out
}

fn attitude_stats(
    estimates: &[StepEstimate],
    truth: &TruthSeries,
    samples: Vec<(usize, usize)>,
) -> Result<(AttitudeStats, Vec<(usize, usize)>)> {
    let mut angles = Vec::with_capacity(samples.len());
    let (mut sq, mut sig) = (Vector3::zeros(), Vector3::zeros());
    for &(k, row) in &samples {
        let q = &truth.q[row];
        let q_true = quat_of(q).with_context(|| {
            format!(
                "truth.csv at t_s = {} (q_x, q_y, q_z, q_w): {} is not a quaternion",
                truth.t_s[row],
                quaternion_fault(&[q.x, q.y, q.z, q.w])
            )
        })?;
        let a = error_vector(&q_true, &estimates[k].q).map(f64::to_degrees);
        angles.push(a.norm());
        sq += a.component_mul(&a);
        sig += Vector3::from(estimates[k].attitude_sigma_deg);
    }
    // No samples gives NaN statistics, which evaluate lists as not evaluable.
    let n = samples.len() as f64;
    angles.sort_by(f64::total_cmp);
    let p99 = angles
        .get(((angles.len() as f64 * 0.99) as usize).min(angles.len().saturating_sub(1)))
        .copied();
    let stats = AttitudeStats {
        samples: samples.len(),
        mean_deg: angles.iter().sum::<f64>() / n,
        rms_deg: (angles.iter().map(|a| a * a).sum::<f64>() / n).sqrt(),
        p99_deg: p99.unwrap_or(f64::NAN),
        axis_rms_deg: (sq / n).map(f64::sqrt).into(),
        axis_filter_sigma_deg: (sig / n).into(),
    };
    Ok((stats, samples))
}

fn consistency(
    estimates: &[StepEstimate],
    final_cal: &Calibration,
    truth: &TruthSeries,
    constants: &TruthConstants,
    truth_row: &dyn Fn(f64) -> Option<usize>,
    converged: &[(usize, usize)],
) -> Consistency {
    let mut inside = Vec::new();
    let mut by_status = StatusTally::default();
    let mut tally = |inside: &mut Vec<bool>, name: String, ok: bool| {
        inside.push(ok);
        by_status.add(status_of(final_cal, &name), ok);
    };
    for (i, (t, e)) in constants
        .photodiodes
        .iter()
        .zip(&final_cal.photodiodes)
        .enumerate()
    {
        let pd = format!("pd{:02}", i + 1);
        let ok = (t.scale_v - e.scale_v).abs() <= 3.0 * e.scale_sigma_v;
        tally(&mut inside, format!("{pd} scale_V"), ok);
        let ok = (t.elevation_deg - e.elevation_deg).abs() <= 3.0 * e.elevation_sigma_deg;
        tally(&mut inside, format!("{pd} elevation_deg"), ok);
        if let Some(s) = e.azimuth_sigma_deg {
            let ok = wrap_deg(t.azimuth_deg - e.azimuth_deg).abs() <= 3.0 * s;
            tally(&mut inside, format!("{pd} azimuth_deg"), ok);
        }
    }
    if let Some(row) = estimates.last().and_then(|e| truth_row(e.t_s)) {
        for (axis, name) in ["x", "y", "z"].iter().enumerate() {
            let err = truth.gyro_bias_rad_s[row][axis] - final_cal.gyro_bias_rad_s[axis];
            let ok = err.abs() <= 3.0 * final_cal.gyro_bias_sigma_rad_s[axis];
            tally(&mut inside, format!("gyro_bias_{name}"), ok);
        }
    }
    let attitude_inside: Vec<bool> = converged
        .iter()
        .filter_map(|&(k, row)| {
            let q_true = quat_of(&truth.q[row])?;
            let a = error_vector(&q_true, &estimates[k].q).map(f64::to_degrees);
            Some((0..3).map(move |i| a[i].abs() <= 3.0 * estimates[k].attitude_sigma_deg[i]))
        })
        .flatten()
        .collect();
    let bias_inside = gyro_bias_inside(estimates, truth, converged);
    let sun_line: Vec<(bool, bool)> = converged
        .iter()
        .filter_map(|&(k, row)| {
            let q_true = quat_of(&truth.q[row])?;
            let e = &estimates[k];
            sun_line_inside(&q_true, &e.q, &truth.sun_body[row], &e.attitude_cov_deg2())
        })
        .collect();
    let about: Vec<bool> = sun_line.iter().map(|s| s.0).collect();
    let across: Vec<bool> = sun_line.iter().map(|s| s.1).collect();
    Consistency {
        by_status,
        attitude_about_sun_within_3sigma: fraction(&about),
        attitude_across_sun_within_3sigma: fraction(&across),
        gyro_bias_within_3sigma: fraction(&bias_inside),
        final_states_within_3sigma: fraction(&inside),
        final_states: inside.len(),
        attitude_within_3sigma: fraction(&attitude_inside),
        converged_within_3sigma_of_final: converged_to_final(estimates, final_cal, converged),
    }
}

/// Per axis of each sample of `converged`: whether the running gyro-bias estimate lies
/// within 3 sigma of the simulated bias at that sample.
fn gyro_bias_inside(
    estimates: &[StepEstimate],
    truth: &TruthSeries,
    converged: &[(usize, usize)],
) -> Vec<bool> {
    converged
        .iter()
        .flat_map(|&(k, row)| {
            let cal = &estimates[k].calibration;
            let truth_bias = truth.gyro_bias_rad_s[row];
            (0..3).map(move |axis| {
                let err = cal.gyro_bias_rad_s[axis] - truth_bias[axis];
                err.abs() <= 3.0 * cal.gyro_bias_sigma_rad_s[axis]
            })
        })
        .collect()
}

fn converged_to_final(
    estimates: &[StepEstimate],
    final_cal: &Calibration,
    converged: &[(usize, usize)],
) -> f64 {
    let mut inside = Vec::new();
    for &(k, _) in converged {
        for (p, f) in estimates[k]
            .calibration
            .photodiodes
            .iter()
            .zip(&final_cal.photodiodes)
        {
            inside.push((p.scale_v - f.scale_v).abs() <= 3.0 * p.scale_sigma_v);
            inside.push((p.elevation_deg - f.elevation_deg).abs() <= 3.0 * p.elevation_sigma_deg);
            if let Some(s) = p.azimuth_sigma_deg {
                inside.push(wrap_deg(p.azimuth_deg - f.azimuth_deg).abs() <= 3.0 * s);
            }
        }
    }
    fraction(&inside)
}

/// The share of true flags; NaN for none (not 0: nothing was checked).
fn fraction(flags: &[bool]) -> f64 {
    flags.iter().filter(|b| **b).count() as f64 / flags.len() as f64
}

/// Rows for index.html.
pub fn index_rows(e: &Evaluation) -> Vec<(String, String)> {
    let mut rows = vec![
        (
            "worst normal error, lit >= 5 min (deg)".into(),
            format!("{:.3}", e.worst_normal_error_deg),
        ),
        (
            "worst scale error, lit >= 5 min (%)".into(),
            format!("{:.3}", e.worst_scale_error_percent),
        ),
        (
            "attitude error RMS after 10 sunlit min (deg)".into(),
            format!("{:.3}", e.attitude.rms_deg),
        ),
        (
            "final calibration states inside 3-sigma".into(),
            format!("{:.1} %", 100.0 * e.consistency.final_states_within_3sigma),
        ),
        (
            "attitude errors inside 3-sigma".into(),
            format!("{:.1} %", 100.0 * e.consistency.attitude_within_3sigma),
        ),
    ];
    if let Some(s) = &e.smoothed {
        rows.push((
            "smoothed attitude errors inside 3-sigma".into(),
            format!("{:.1} %", 100.0 * s.attitude_within_3sigma),
        ));
    }
    rows
}
