//! Initialisation as the paper (IV.B): `C` = maximum measured output (referred to 1 AU),
//! nominal normals, attitude by the q-method from the magnetometer and the photodiode Sun
//! vector at the first usable sample, zero gyro bias.

use std::ops::Range;

use nalgebra::{Matrix3, Vector3};
use pdcal_albedo::{AlbedoIrradiance, AlbedoModel, AlbedoView};
use pdcal_attitude::{Quat, VectorPair, q_method};
use pdcal_dataset::Telemetry;
use pdcal_ephem::Reference;
use pdcal_photodiode::{Photodiode, SunVectorOptions, estimate_sun_vector};

use crate::segments::GapRules;
use crate::shared_rows::SharedRows;
use crate::{FilterConfig, FilterError, References};

/// A lit photodiode whose maximum output stays below this fraction of the median maximum
/// of the lit photodiodes never faced the Sun near its normal (its maximum is a grazing or
/// albedo output): its maximum is no estimate of its scale factor.
pub const DIM_FRACTION: f64 = 0.8;

/// The paper's initial scale factors (IV.B: the maximum measured output) with the cases
/// where that rule fails made explicit.
#[derive(Debug, Clone, PartialEq)]
pub struct InitialScales {
    /// Initial `C` per photodiode, V.
    pub scale_v: Vec<f64>,
    /// Whether the photodiode's maximum exceeds the lit threshold (a photodiode that never
    /// does is treated as not lit: covered, failed or always shadowed).
    pub used: Vec<bool>,
    /// Whether the initial value is the median of the others' maxima rather than the
    /// photodiode's own (never lit, or dim: below [`DIM_FRACTION`] of the median). That
    /// assumes photodiodes of one type, so the filter gives these a wider initial sigma.
    pub from_median: Vec<bool>,
}

/// Maximum output of each photodiode over the data set, each sample divided by the Sun's
/// distance factor `(1 AU / r_sun)^2` of its row (`references`, one per row), so that the
/// initial `C` is, like the state, the output at 1 AU (the paper's initial `C`, which
/// ignored the 3 % annual swing); a never-lit or dim photodiode gets the median of the lit
/// photodiodes' maxima.
pub fn initial_scales(
    telemetry: &Telemetry,
    references: &References<'_>,
    threshold_v: f64,
) -> Result<InitialScales, FilterError> {
    crate::error::check_len("references", telemetry.len(), references.len())?;
    // Row by row, so that no per-row factor is kept (a long set's references are computed
    // when reached).
    let mut maxima = vec![f64::NEG_INFINITY; telemetry.pd_v.len()];
    for k in 0..references.len() {
        let factor = references.at(k)?.sun_distance_factor();
        for (max, col) in maxima.iter_mut().zip(&telemetry.pd_v) {
            if let Some(y) = col.get(k) {
                *max = max.max(y / factor);
            }
        }
    }
    let used: Vec<bool> = maxima.iter().map(|&m| m > threshold_v).collect();
    let mut lit: Vec<f64> = maxima
        .iter()
        .zip(&used)
        .filter(|(_, u)| **u)
        .map(|(m, _)| *m)
        .collect();
    if lit.is_empty() {
        return Err(FilterError::NoLitPhotodiode { threshold_v });
    }
    lit.sort_by(f64::total_cmp);
    let median = lit[lit.len() / 2];
    let from_median: Vec<bool> = maxima
        .iter()
        .zip(&used)
        .map(|(&m, &u)| !u || m < DIM_FRACTION * median)
        .collect();
    let scale_v = maxima
        .iter()
        .zip(&from_median)
        .map(|(&m, &f)| if f { median } else { m })
        .collect();
    Ok(InitialScales {
        scale_v,
        used,
        from_median,
    })
}

/// The first usable sample of a row range and the attitude there.
#[derive(Debug, Clone, PartialEq)]
pub struct Start {
    /// Telemetry row (the photodiode row the attitude is at).
    pub index: usize,
    /// Attitude.
    pub q: Quat,
    /// Attitude-error covariance, rad^2.
    pub attitude_cov: Matrix3<f64>,
    /// The magnetometer row paired with it, when another row (brought to this row's time
    /// with the gyro).
    pub paired_field_row: Option<usize>,
    /// The gyro sample nearest the row and its time, s: the rate held until the next one.
    pub gyro_rad_s: Vector3<f64>,
    /// Time of that gyro sample, s.
    pub gyro_t_s: f64,
    /// Sun only: how the acquired attitude's error moves with each lit photodiode's
    /// calibration error; empty with the magnetometer.
    pub sensitivity: Vec<PdSensitivity>,
    /// Sun only: the attitude-error covariance given the calibration (the outputs' noise
    /// and the floor across the Sun line, `unobserved_axis_sigma_deg` about it), rad^2; the
    /// filter adds the calibration's part through `sensitivity`
    /// ([`crate::Filter::correlate_attitude`]). `attitude_cov` is then the fixed-sigma
    /// covariance of a Sun vector of `initial_sun_sigma_deg`.
    pub conditional_cov: Option<Matrix3<f64>>,
}

/// The attitude error of a Sun-only acquisition per unit error of one photodiode's
/// calibration (error = true - estimated, the filter's convention for every state).
#[derive(Debug, Clone, PartialEq)]
pub struct PdSensitivity {
    /// The photodiode.
    pub pd: usize,
    /// Attitude error (rad, body) per V of scale-factor error.
    pub d_scale: Vector3<f64>,
    /// Attitude error (rad, body) per unit change of the normal vector (applied to its
    /// tangent directions).
    pub d_normal: Matrix3<f64>,
}

/// What [`find_start`] works with.
pub struct StartInputs<'a> {
    /// Telemetry.
    pub telemetry: &'a Telemetry,
    /// One reference per row.
    pub references: References<'a>,
    /// The albedo views of the rows, shared with the other passes over the telemetry.
    pub shared: &'a SharedRows,
    /// Photodiodes with the current scales and normals (`noise_v` = photodiode sigma).
    pub photodiodes: &'a [Photodiode],
    /// Which photodiodes take part.
    pub used: &'a [bool],
    /// Use the magnetometer (two-vector attitude) or the Sun alone.
    pub use_mag: bool,
    /// Magnetometer sigma, nT.
    pub mag_sigma_nt: f64,
    /// Albedo model to remove albedo from the initial Sun vector.
    pub albedo: Option<&'a AlbedoModel>,
    /// Current gyro bias estimate, rad/s, and its largest 1-sigma, rad/s: a magnetometer
    /// sample from another row is rotated to the photodiode row with the corrected rate,
    /// and its direction sigma grows by the bias sigma times the time between them.
    pub bias_rad_s: Vector3<f64>,
    /// See `bias_rad_s`.
    pub bias_sigma_rad_s: f64,
    /// How far the gyro and magnetometer samples may be from the photodiode row.
    pub rules: GapRules,
    /// Without gyro samples, the body rate the dynamics carry, rad/s: it stands in for the
    /// bias-corrected gyro (a row then needs no gyro sample near it).
    pub rate_without_gyro: Option<Vector3<f64>>,
}

/// The first row of `rows` in full Sun with photodiode samples, a gyro sample within the
/// gyro hold, an observable photodiode Sun vector and (with the magnetometer) a field sample
/// within the pairing tolerance at least `initial_min_sun_field_angle_deg` from the Sun;
/// the attitude there by the q-method (or, Sun only, the smallest rotation taking the
/// reference Sun to the measured one), refined twice with the albedo removed at that
/// attitude. A field sample of another row is brought to the photodiode row's time with
/// the bias-corrected gyro rate (`v(t + dt) = exp(-[w dt x]) v(t)` for a fixed inertial
/// vector) and paired with its own row's reference field. `Ok(Err(reason))` when no row of
/// the range qualifies.
///
/// Covariance: two vectors, `(sum w_i (I - b_i b_i^T))^-1` with `w = 1/sigma^2` (the
/// q-method's Fisher information; Markley & Crassidis Sec. 5.5); Sun only,
/// `sigma_sun^2 (I - s s^T) + sigma_unobserved^2 s s^T`. Plus the configured floor.
pub fn find_start(
    inputs: &StartInputs<'_>,
    rows: Range<usize>,
    config: &FilterConfig,
) -> Result<Result<Start, String>, FilterError> {
    let tel = inputs.telemetry;
    let no_albedo = AlbedoView::new();
    let sin_min_angle = config.initial_min_sun_field_angle_deg.to_radians().sin();
    // The reason of the row that came furthest through the checks: a row failing an
    // earlier check must not hide why a better row failed.
    const REASONS: [&str; 6] = [
        "no sample in full Sun (in eclipse throughout: no photodiode to calibrate from, so no attitude is acquired from the magnetometer and gyro alone)",
        "no photodiode sample in full Sun",
        "no gyro sample near a sunlit photodiode sample",
        "no magnetometer sample near a sunlit photodiode sample",
        "Sun and field too close to parallel",
        "photodiode Sun vector not observable",
    ];
    let mut furthest = 0;
    let mut reached = |stage: usize| furthest = furthest.max(stage);
    for k in rows.clone() {
        let reference = &inputs.references.at(k)?;
        if reference.sun_fraction < config.min_sun_fraction {
            continue;
        }
        // A scale the filter has driven to zero or below (a photodiode the data do not
        // support) cannot turn an output into a direction: such a photodiode sits out the
        // acquisition, as it sits out the filter's updates.
        let sampled: Vec<usize> = (0..inputs.photodiodes.len())
            .filter(|&i| {
                inputs.used[i]
                    && inputs.photodiodes[i].scale_v > 0.0
                    && tel.pd_v[i].get(k).is_some()
            })
            .collect();
        if sampled.is_empty() {
            reached(1);
            continue;
        }
        let gyro = match inputs.rate_without_gyro {
            Some(rate) => Some((tel.t_s[k], rate + inputs.bias_rad_s)),
            None => nearest_gyro(tel, &rows, k, inputs.rules.gyro_hold_s),
        };
        let Some((gyro_t_s, gyro_rad_s)) = gyro else {
            reached(2);
            continue;
        };
        let field = match (inputs.use_mag, paired_field(inputs, &rows, k, &gyro_rad_s)) {
            (false, _) => None,
            (true, Some(f)) => Some(f),
            (true, None) => {
                reached(3);
                continue;
            }
        };
        if let Some(f) = &field {
            let sin_angle = f
                .reference_nt
                .normalize()
                .cross(&reference.sun_gcrf_unit)
                .norm();
            if sin_angle < sin_min_angle || f.body_nt.norm() == 0.0 {
                reached(4);
                continue;
            }
        }
        let shared_view = match inputs.albedo {
            Some(model) => Some(inputs.shared.albedo(reference, model, k)?),
            None => None,
        };
        let view = shared_view.as_deref().unwrap_or(&no_albedo);
        let largest_albedo_ratio = view.max_ratio();
        let above = above_albedo(inputs, &sampled, k, largest_albedo_ratio);
        if above.is_empty() {
            reached(5);
            continue;
        }
        // The albedo is removed at the acquired attitude. With the field that attitude is
        // whole and every sampled photodiode takes part; with the Sun alone its rotation
        // about the Sun line is arbitrary, so is the albedo it predicts, and only the
        // photodiodes above any albedo do.
        let lit = if field.is_some() {
            sampled.clone()
        } else {
            above
        };
        let pds: Vec<Photodiode> = lit.iter().map(|&i| inputs.photodiodes[i]).collect();
        let outputs: Vec<f64> = lit
            .iter()
            .map(|&i| tel.pd_v[i].get(k).unwrap_or(0.0))
            .collect();
        let mut known = vec![0.0; pds.len()];
        let options = SunVectorOptions {
            sun_distance_factor: reference.sun_distance_factor(),
            ..SunVectorOptions::default()
        };
        let Some(mut sun_body) =
            estimate_sun_vector(&pds, &outputs, Some(&known), &options)?.direction_body()
        else {
            reached(5);
            continue;
        };
        let mut q = attitude(&sun_body, field.as_ref(), reference, config)?;
        // Sun alone, the albedo on every sampled photodiode is what tells the rotation
        // about the Sun line; the filter's linearisation needs a start in the right basin.
        let albedo_probe = (field.is_none() && inputs.albedo.is_some()).then(|| AlbedoProbe {
            pds: sampled.iter().map(|&i| inputs.photodiodes[i]).collect(),
            outputs: sampled
                .iter()
                .map(|&i| tel.pd_v[i].get(k).unwrap_or(0.0))
                .collect(),
            factor: reference.sun_distance_factor(),
        });
        if let Some(probe) = &albedo_probe {
            q = about_sun_line(&q, &sun_body, probe.best_angle(&q, &sun_body, view));
        }
        if inputs.albedo.is_some() {
            let mut refined = true;
            for _ in 0..2 {
                let a = q.attitude_matrix();
                for (known, pd) in known.iter_mut().zip(&pds) {
                    *known = pd.scale_v * view.ratio(&(a.transpose() * pd.n_body), 0.0);
                }
                // Without the albedo the outputs no longer give a direction: the one solved
                // with it leaned on albedo, and the row is no start.
                let Some(s) =
                    estimate_sun_vector(&pds, &outputs, Some(&known), &options)?.direction_body()
                else {
                    refined = false;
                    break;
                };
                sun_body = s;
                q = attitude(&sun_body, field.as_ref(), reference, config)?;
                if let Some(probe) = &albedo_probe {
                    q = about_sun_line(&q, &sun_body, probe.best_angle(&q, &sun_body, view));
                }
            }
            if !refined {
                reached(5);
                continue;
            }
        }
        let attitude_cov = covariance(&sun_body, field.as_ref(), config);
        let (conditional_cov, sensitivity) = match field {
            Some(_) => (None, Vec::new()),
            None => {
                let fit = SunFit::new(&pds, &outputs, &known, &options);
                let sensitivity = lit
                    .iter()
                    .enumerate()
                    .filter_map(|(j, &pd)| fit.sensitivity(j, pd))
                    .collect();
                (Some(fit.conditional_cov(config)), sensitivity)
            }
        };
        return Ok(Ok(Start {
            index: k,
            q,
            attitude_cov,
            paired_field_row: field.and_then(|f| (f.row != k).then_some(f.row)),
            gyro_rad_s,
            gyro_t_s,
            sensitivity,
            conditional_cov,
        }));
    }
    // Without the magnetometer no attitude comes from it in eclipse either: the reason
    // says what this run lacks, not what a run with a magnetometer would.
    let reason = match (furthest, inputs.use_mag) {
        (0, false) => {
            "no sample in full Sun (in eclipse throughout: no photodiode to calibrate from, and the Sun is the only vector of this run)"
        }
        _ => REASONS[furthest],
    };
    Ok(Err(reason.to_owned()))
}

/// The photodiodes of `sampled` that see the Sun itself at row `k`: their output exceeds
/// the largest Earth albedo any attitude could give them (`scale_v` times the albedo ratio
/// of every lit cell in view, no cosine) by the Sun vector's lit threshold. The attitude is
/// unknown at acquisition, so the albedo cannot be removed yet, and with the Sun behind
/// the photodiodes a head facing the sunlit Earth reads tens to hundreds of mV of albedo on
/// all of them: a Sun vector solved from that points at the Earth, not the Sun.
fn above_albedo(
    inputs: &StartInputs<'_>,
    sampled: &[usize],
    k: usize,
    largest_albedo_ratio: f64,
) -> Vec<usize> {
    let threshold = SunVectorOptions::default().threshold;
    sampled
        .iter()
        .copied()
        .filter(|&i| {
            let pd = &inputs.photodiodes[i];
            let bound = pd.scale_v * largest_albedo_ratio + threshold.volts(pd.noise_v);
            inputs.telemetry.pd_v[i].get(k).is_some_and(|v| v > bound)
        })
        .collect()
}

/// The outputs of every sampled photodiode at an acquisition row, to choose the rotation
/// about the Sun line (which the Sun alone leaves open) by the albedo each would see.
struct AlbedoProbe {
    pds: Vec<Photodiode>,
    outputs: Vec<f64>,
    factor: f64,
}

impl AlbedoProbe {
    /// Candidate rotations about the Sun line, evenly spaced over a turn.
    const ANGLES: usize = 72;

    /// The rotation about the Sun line (from `q`, rad) whose predicted outputs (direct Sun,
    /// which no such rotation changes, plus the albedo at that attitude) fit the measured
    /// ones best in the least-squares sense of the photodiodes' noise.
    fn best_angle(&self, q: &Quat, sun_body: &Vector3<f64>, view: &AlbedoView) -> f64 {
        // The outputs less the direct Sun, which no rotation about the Sun line changes.
        let beyond_direct: Vec<f64> = self
            .pds
            .iter()
            .zip(&self.outputs)
            .map(|(pd, &y)| y - pd.scale_v * self.factor * pd.n_body.dot(sun_body).max(0.0))
            .collect();
        let cost = |angle: f64| {
            let a = about_sun_line(q, sun_body, angle).attitude_matrix();
            self.pds
                .iter()
                .zip(&beyond_direct)
                .map(|(pd, &rest)| {
                    let albedo = view.ratio(&(a.transpose() * pd.n_body), 0.0);
                    ((rest - pd.scale_v * albedo) / pd.noise_v).powi(2)
                })
                .sum::<f64>()
        };
        (0..Self::ANGLES)
            .map(|j| std::f64::consts::TAU * j as f64 / Self::ANGLES as f64)
            .map(|angle| (angle, cost(angle)))
            .fold((0.0, f64::INFINITY), |best, (angle, c)| {
                if c < best.1 { (angle, c) } else { best }
            })
            .0
    }
}

/// `q` turned by `angle_rad` about the body Sun direction: the same Sun in the body, the
/// rest of the attitude rotated about it.
fn about_sun_line(q: &Quat, sun_body: &Vector3<f64>, angle_rad: f64) -> Quat {
    let Some(axis) = nalgebra::Unit::try_new(*sun_body, 1e-12) else {
        return *q;
    };
    let turn = nalgebra::Rotation3::from_axis_angle(&axis, angle_rad);
    Quat::from_attitude_matrix(&(turn.matrix() * q.attitude_matrix()))
}

/// The least-squares Sun vector of the lit photodiodes, linearised: `s = G H^T y` with
/// `G = (H^T H)^-1`, `y_i = (I_i - b_i) / (F C_i)`, `H` the unit normals.
struct SunFit<'a> {
    pds: &'a [Photodiode],
    /// Lit (above the threshold after `known`): `y_i`, else `None`.
    y: Vec<Option<f64>>,
    g: Matrix3<f64>,
    s: Vector3<f64>,
    factor: f64,
}

impl<'a> SunFit<'a> {
    fn new(
        pds: &'a [Photodiode],
        outputs: &[f64],
        known: &[f64],
        options: &SunVectorOptions,
    ) -> Self {
        let factor = options.sun_distance_factor;
        let y: Vec<Option<f64>> = (0..pds.len())
            .map(|i| {
                let direct = outputs[i] - known[i];
                (direct > options.threshold.volts(pds[i].noise_v))
                    .then(|| direct / (factor * pds[i].scale_v))
            })
            .collect();
        let fit = SunFit::solve(pds, y, factor);
        // As the Sun vector does, a photodiode facing away from the solution is left out.
        let faces = |pd: &Photodiode| pd.n_body.dot(&fit.s) > 0.0;
        if fit
            .pds
            .iter()
            .zip(&fit.y)
            .all(|(pd, y)| y.is_none() || faces(pd))
        {
            return fit;
        }
        let y = pds
            .iter()
            .zip(&fit.y)
            .map(|(pd, y)| y.filter(|_| faces(pd)))
            .collect();
        SunFit::solve(pds, y, factor)
    }

    /// The least squares over the photodiodes with `Some(y)`.
    fn solve(pds: &'a [Photodiode], y: Vec<Option<f64>>, factor: f64) -> Self {
        let lit = || pds.iter().zip(&y).filter_map(|(pd, y)| y.map(|y| (pd, y)));
        let normal_matrix: Matrix3<f64> =
            lit().map(|(pd, _)| pd.n_body * pd.n_body.transpose()).sum();
        let g = normal_matrix.try_inverse().unwrap_or_else(Matrix3::zeros);
        let s = lit().map(|(pd, y)| g * pd.n_body * y).sum();
        SunFit {
            pds,
            y,
            g,
            s,
            factor,
        }
    }

    /// From a change of `s` to the attitude error it means: with `d = s/|s|` and
    /// `A_true = (I - [a x]) A_est`, `d_true = d + d x a`, so across the Sun line
    /// `a = -[d x] (I - d d^T) ds / |s|`.
    fn to_attitude(&self) -> Matrix3<f64> {
        let norm = self.s.norm().max(1e-12);
        let d = self.s / norm;
        -pdcal_attitude::skew(&d) * (Matrix3::identity() - d * d.transpose()) / norm
    }

    /// Photodiode `j` of the fit (filter photodiode `pd`): the attitude error per error of
    /// its scale (`ds/dC = -G n y / C`) and of its normal (`ds/dn = G (r I - n s^T)`, `r`
    /// its least-squares residual); `None` when it is not lit.
    fn sensitivity(&self, j: usize, pd: usize) -> Option<PdSensitivity> {
        let y = self.y[j]?;
        let p = &self.pds[j];
        let to_a = self.to_attitude();
        let residual = y - p.n_body.dot(&self.s);
        let ds_dn = self.g * (Matrix3::identity() * residual - p.n_body * self.s.transpose());
        Some(PdSensitivity {
            pd,
            d_scale: to_a * (-self.g * p.n_body * y / p.scale_v),
            d_normal: to_a * ds_dn,
        })
    }

    /// The acquired attitude's covariance given the calibration (rad^2, body): the
    /// outputs' noise across the Sun line (`dI_i / (F C_i)` along `G n_i`), the configured
    /// floor, and `unobserved_axis_sigma_deg` about the line.
    fn conditional_cov(&self, config: &FilterConfig) -> Matrix3<f64> {
        let to_a = self.to_attitude();
        let noise: Matrix3<f64> = self
            .pds
            .iter()
            .zip(&self.y)
            .filter(|(_, y)| y.is_some())
            .map(|(pd, _)| {
                let col = to_a * self.g * pd.n_body * (pd.noise_v / (self.factor * pd.scale_v));
                col * col.transpose()
            })
            .sum();
        let d = self.s.try_normalize(1e-12).unwrap_or_else(Vector3::z);
        let floor = config.initial_attitude_sigma_floor_deg.to_radians().powi(2);
        let var_axis = config.unobserved_axis_sigma_deg.to_radians().powi(2);
        noise + Matrix3::identity() * floor + d * d.transpose() * var_axis
    }
}

/// A magnetometer sample paired with a photodiode row.
struct PairedField {
    /// Its row.
    row: usize,
    /// The measured field brought to the photodiode row's time, body frame, nT.
    body_nt: Vector3<f64>,
    /// The reference field at its own row, GCRF, nT.
    reference_nt: Vector3<f64>,
    /// Its direction sigma, rad: noise over magnitude, plus the bias sigma times the time
    /// it was rotated over.
    sigma_rad: f64,
}

/// The magnetometer sample of `rows` nearest in time to row `k`, within the pairing
/// tolerance, rotated to row `k`'s time.
fn paired_field(
    inputs: &StartInputs<'_>,
    rows: &Range<usize>,
    k: usize,
    gyro_rad_s: &Vector3<f64>,
) -> Option<PairedField> {
    let tel = inputs.telemetry;
    let mag = tel.mag_nt.as_ref()?;
    let t_k = tel.t_s[k];
    let tolerance = inputs.rules.pairing_tolerance_s;
    let j = nearest_row(tel, rows, k, tolerance, |j| mag.get(j).is_some())?;
    let b = mag.get(j)?;
    let dt = t_k - tel.t_s[j];
    let rate = gyro_rad_s - inputs.bias_rad_s;
    // The body rotation from t_j to t_k, A(t_k) = R A(t_j).
    let rotation = pdcal_attitude::mekf::propagate(&Quat::IDENTITY, &rate, dt).attitude_matrix();
    let noise = inputs.mag_sigma_nt / b.norm();
    Some(PairedField {
        row: j,
        body_nt: rotation * b,
        reference_nt: inputs.references.at(j).ok()?.b_gcrf_nt,
        sigma_rad: noise.hypot(inputs.bias_sigma_rad_s * dt.abs()),
    })
}

/// The gyro sample of `rows` nearest in time to row `k` within `hold_s`: its time and rate.
fn nearest_gyro(
    tel: &Telemetry,
    rows: &Range<usize>,
    k: usize,
    hold_s: f64,
) -> Option<(f64, Vector3<f64>)> {
    let j = nearest_row(tel, rows, k, hold_s, |j| tel.gyro_rad_s.get(j).is_some())?;
    Some((tel.t_s[j], tel.gyro_rad_s.get(j)?))
}

/// The row of `rows` nearest in time to row `k` (itself first) within `tolerance_s` that
/// satisfies `has`.
fn nearest_row(
    tel: &Telemetry,
    rows: &Range<usize>,
    k: usize,
    tolerance_s: f64,
    has: impl Fn(usize) -> bool,
) -> Option<usize> {
    if has(k) {
        return Some(k);
    }
    let t_k = tel.t_s[k];
    let within = |j: usize| (tel.t_s[j] - t_k).abs() <= tolerance_s;
    let before = (rows.start..k)
        .rev()
        .take_while(|&j| within(j))
        .find(|&j| has(j));
    let after = (k + 1..rows.end)
        .take_while(|&j| within(j))
        .find(|&j| has(j));
    match (before, after) {
        (Some(b), Some(a)) => Some(if t_k - tel.t_s[b] <= tel.t_s[a] - t_k {
            b
        } else {
            a
        }),
        (b, a) => b.or(a),
    }
}

fn attitude(
    sun_body: &Vector3<f64>,
    field: Option<&PairedField>,
    reference: &Reference,
    config: &FilterConfig,
) -> Result<Quat, FilterError> {
    let Some(f) = field else {
        return Ok(minimal_rotation(&reference.sun_gcrf_unit, sun_body));
    };
    let w_sun = config.initial_sun_sigma_deg.to_radians().powi(-2);
    let w_mag = f.sigma_rad.powi(-2);
    let pairs = [
        VectorPair::new(*sun_body, reference.sun_gcrf_unit, w_sun),
        VectorPair::new(f.body_nt, f.reference_nt, w_mag),
    ];
    q_method(&pairs).map_err(|e| FilterError::NoInitialSample {
        reason: format!("q-method failed: {e}"),
    })
}

/// The attitude `A` with `A s_ref = s_body` closest to the identity (rotation about
/// `s_ref x s_body`): the Sun-only choice; the rotation about the Sun line is unobserved.
pub fn minimal_rotation(s_ref: &Vector3<f64>, s_body: &Vector3<f64>) -> Quat {
    let r = s_ref.normalize();
    let b = s_body.normalize();
    let k = r.cross(&b);
    let c = r.dot(&b);
    let a = if 1.0 + c > 1e-12 {
        let kx = pdcal_attitude::skew(&k);
        Matrix3::identity() + kx + kx * kx / (1.0 + c)
    } else {
        // Opposite vectors: half turn about any axis perpendicular to r.
        let axis = r
            .cross(&Vector3::x())
            .try_normalize(1e-6)
            .unwrap_or_else(|| r.cross(&Vector3::y()).normalize());
        2.0 * axis * axis.transpose() - Matrix3::identity()
    };
    Quat::from_attitude_matrix(&a)
}

fn covariance(
    sun_body: &Vector3<f64>,
    field: Option<&PairedField>,
    config: &FilterConfig,
) -> Matrix3<f64> {
    let s = sun_body.normalize();
    let var_sun = config.initial_sun_sigma_deg.to_radians().powi(2);
    let floor = config.initial_attitude_sigma_floor_deg.to_radians().powi(2) * Matrix3::identity();
    let across = |v: &Vector3<f64>| Matrix3::identity() - v * v.transpose();
    match field {
        Some(f) => {
            let bu = f.body_nt.normalize();
            let info = across(&s) / var_sun + across(&bu) / f.sigma_rad.powi(2);
            info.try_inverse()
                .unwrap_or_else(|| Matrix3::identity() * var_sun)
                + floor
        }
        None => {
            let var_axis = config.unobserved_axis_sigma_deg.to_radians().powi(2);
            across(&s) * var_sun + s * s.transpose() * var_axis + floor
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Four photodiodes under a pyramid (normals 18 deg off +z) lit by a Sun 30 deg off +z.
    fn head() -> (Vec<Photodiode>, Vector3<f64>) {
        let pds = [0.0f64, 90.0, 180.0, 270.0]
            .iter()
            .zip([0.9, 1.1, 0.8, 1.0])
            .map(|(&az, c)| Photodiode::from_az_el_deg(c, az, 72.0, 0.005))
            .collect();
        let s = Vector3::new(0.4, 0.25, 1.0).normalize();
        (pds, s)
    }

    /// The attitude error (true - estimated, `A_true = (I - [a x]) A_est`) between the
    /// directions solved with the estimated and with the true photodiodes, from the same
    /// outputs: `a = (d_true - d_est) x d_est` across the line.
    fn attitude_error(est: &[Photodiode], truth: &[Photodiode], outputs: &[f64]) -> Vector3<f64> {
        let options = SunVectorOptions::default();
        let known = vec![0.0; outputs.len()];
        let d_est = SunFit::new(est, outputs, &known, &options).s.normalize();
        let d_true = SunFit::new(truth, outputs, &known, &options).s.normalize();
        (d_true - d_est).cross(&d_est)
    }

    #[test]
    fn the_acquisition_sensitivity_matches_finite_differences() {
        let (truth, s) = head();
        let outputs: Vec<f64> = truth
            .iter()
            .map(|pd| pd.scale_v * pd.n_body.dot(&s))
            .collect();
        // The estimate: scales and one normal a little off, so the fit has a residual.
        let mut est = truth.clone();
        est[0].scale_v *= 1.1;
        est[2].n_body = (est[2].n_body + Vector3::new(0.03, -0.02, 0.0)).normalize();
        let known = vec![0.0; outputs.len()];
        let fit = SunFit::new(&est, &outputs, &known, &SunVectorOptions::default());
        for j in 0..est.len() {
            let sens = fit.sensitivity(j, j).unwrap();
            let h = 1e-6;
            let mut moved = est.clone();
            moved[j].scale_v += h;
            let fd = attitude_error(&est, &moved, &outputs) / h;
            assert!(
                (fd - sens.d_scale).norm() <= 1e-4 * sens.d_scale.norm().max(1e-3),
                "pd {j} scale: {fd} against {}",
                sens.d_scale
            );
            let (e1, e2) = pdcal_attitude::tangent_basis(&est[j].n_body);
            for e in [e1, e2] {
                let mut moved = est.clone();
                moved[j].n_body = pdcal_attitude::rotate_normal_in(
                    &est[j].n_body,
                    (&e1, &e2),
                    h * e.dot(&e1),
                    h * e.dot(&e2),
                );
                let fd = attitude_error(&est, &moved, &outputs) / h;
                let analytic = sens.d_normal * e;
                assert!(
                    (fd - analytic).norm() <= 1e-4 * analytic.norm().max(1e-3),
                    "pd {j} normal: {fd} against {analytic}"
                );
            }
        }
    }
}
