//! Post-fit residuals over every sample: every photodiode sample from the filter's start
//! (eclipse, penumbra, high incidence and dark included, which the filter never used), the
//! magnetometer in the body frame, and the attitude increments the measurements forced on
//! the gyro, all from the smoothed attitude and the final calibration with the current
//! model; plus the regressors the candidate effects need.

use nalgebra::{Matrix3, Rotation3, Vector3};
use pdcal_albedo::{AlbedoIrradiance, AlbedoModel, AlbedoView};
use pdcal_dataset::Effect;
use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_ephem::Reference;
use pdcal_filter::{CalibrationRun, FilterConfig, StepEstimate};
use pdcal_photodiode::{
    ComponentId, MeasurementModel, Partials, Photodiode, Scene, ShadowMode, SunEstimate,
    SunVectorOptions, estimate_sun_vector,
};
use rayon::prelude::*;

use crate::DiagnoseError;
use crate::model::ModelSpec;

/// Photodiodes count as in full Sun for the Sun-vector check from this illuminated
/// fraction on (the filter's default gate).
pub const FULL_SUN: f64 = 0.999;
/// Below this illuminated fraction a row is in umbra.
pub const UMBRA: f64 = 1e-6;

/// One photodiode sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PdSample {
    /// Telemetry row.
    pub row: usize,
    /// Photodiode, zero-based.
    pub pd: usize,
    /// Time, s.
    pub t_s: f64,
    /// Measured output, V.
    pub measured_v: f64,
    /// Model output after the output stages, V.
    pub predicted_v: f64,
    /// Model output before the output stages, V.
    pub pre_stage_v: f64,
    /// Measured minus predicted, V (Eq. 25 over every sample).
    pub residual_v: f64,
    /// `n^T A s` with the estimated normal and attitude (incidence cosine, may be negative).
    pub cos_incidence: f64,
    /// Illuminated fraction of the Sun (reference eclipse model), 0..1.
    pub sun_fraction: f64,
    /// `C E_a/E_AM0` at the estimated normal and attitude, V (the albedo regressor).
    pub albedo_v: f64,
    /// `F C n^T A s` where lit in the hard-shadow sense (else 0), V; `F = (1 AU / r_sun)^2`
    /// as in the model's direct-Sun term (`C` is the output at 1 AU).
    pub direct_v: f64,
    /// `F C max(n^T A s, 0)` whatever the shadow, V.
    pub unshadowed_v: f64,
    /// `F C n^T (w x s)` where lit (else 0), V/s: the time-offset signature.
    pub time_offset_v_s: f64,
    /// `C dI/dC`: the model output's sensitivity to a relative scale change, V.
    pub scale_v: f64,
    /// The photodiode's temperature, degrees Celsius (held from its last sample; NaN
    /// without temperature columns).
    pub temperature_c: f64,
    /// 1-sigma of the prediction from the uncertainty the filter itself reports for the
    /// final scale factor and normal, V.
    pub prediction_sigma_v: f64,
    /// Geocentric latitude of the point below the spacecraft (Earth-fixed), rad: where the
    /// albedo a photodiode sees comes from, for the `albedo-map` candidate.
    pub nadir_lat_rad: f64,
}

/// One magnetometer sample, body frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MagSample {
    /// Telemetry row.
    pub row: usize,
    /// Time, s.
    pub t_s: f64,
    /// Measured minus `A b_ref`, nT.
    pub residual_nt: Vector3<f64>,
    /// `w x (A b_ref)`, nT/s: the magnetometer's time-offset signature.
    pub time_offset_nt_s: Vector3<f64>,
}

/// The rotation the smoothed attitude made over one step minus what the gyro said.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroSample {
    /// Telemetry row of the step's end.
    pub row: usize,
    /// Time, s.
    pub t_s: f64,
    /// Step length, s.
    pub dt_s: f64,
    /// Smoothed rotation minus `(w_gyro - bias) dt`, body frame, rad.
    pub residual_rad: Vector3<f64>,
    /// `(w_gyro - bias) dt`, rad.
    pub rotation_rad: Vector3<f64>,
    /// The same from the mean of the gyro samples around the step but not at its ends
    /// ([`NEARBY`] before, [`NEARBY`] after), rad.
    pub rotation_nearby_rad: Vector3<f64>,
}

/// Every residual of one model, with its regressors.
#[derive(Debug, Clone, Default)]
pub struct Residuals {
    /// Photodiode samples, row-major.
    pub pd: Vec<PdSample>,
    /// Magnetometer samples.
    pub mag: Vec<MagSample>,
    /// Gyro step residuals.
    pub gyro: Vec<GyroSample>,
    /// Sun-vector magnitude per full-Sun row (photodiode least squares, the model's
    /// non-direct contributions removed).
    pub sun_magnitude: Vec<f64>,
    /// Photodiode noise 1-sigma, V.
    pub sigma_pd_v: f64,
    /// Magnetometer noise 1-sigma, nT.
    pub sigma_mag_nt: f64,
    /// Gyro white noise per sample, rad/s.
    pub sigma_gyro_rad_s: f64,
    /// Rows covered (from the filter's start).
    pub rows: usize,
    /// The reflectivity map of the albedo regressor.
    pub albedo_map: String,
}

/// What the residual pass reads.
pub struct ResidualInputs<'a> {
    /// dataset.ron.
    pub meta: &'a DatasetMeta,
    /// Telemetry with the model's sensor corrections applied.
    pub telemetry: &'a Telemetry,
    /// References per row.
    pub references: &'a [Reference],
    /// Albedo model.
    pub albedo: &'a AlbedoModel,
    /// Its reflectivity map's id.
    pub albedo_map: &'a str,
    /// Filter tuning (albedo partials).
    pub config: &'a FilterConfig,
}

/// The smoothed estimates (forward when the smoother is off), extended back towards row 0
/// by propagating the first estimate's attitude backwards with the gyro (the filter starts at
/// its first usable sample, often after an eclipse whose dark and penumbra samples the
/// diagnosis needs; their residuals depend little on attitude), never across a gap of the
/// run's segment rules (no gyro spans it).
fn attitude_track(run: &CalibrationRun, tel: &Telemetry) -> Vec<StepEstimate> {
    let track = run.smoothed.as_deref().unwrap_or(&run.forward);
    let Some(first) = track.first() else {
        return Vec::new();
    };
    let bias = Vector3::from(first.calibration.gyro_bias_rad_s);
    let mut back = Vec::with_capacity(first.index);
    let mut q = first.q;
    for k in (0..first.index).rev() {
        let (Some(a), Some(b)) = (gyro_at(tel, k), gyro_at(tel, k + 1)) else {
            break;
        };
        if tel.t_s[k + 1] - tel.t_s[k] > run.segment_rules.gap_threshold_s {
            break;
        }
        let rate = 0.5 * (a + b) - bias;
        q = pdcal_attitude::mekf::propagate(&q, &(-rate), tel.t_s[k + 1] - tel.t_s[k]);
        back.push(StepEstimate {
            index: k,
            t_s: tel.t_s[k],
            q,
            ..first.clone()
        });
    }
    back.reverse();
    back.extend(track.iter().cloned());
    back
}

/// The photodiodes of a calibration with the field of view dataset.ron declares (`fov_deg`),
/// else none: the cosine law to 90 deg, so that samples the filter's own gate left out are
/// still predicted.
fn calibrated_photodiodes(run: &CalibrationRun, meta: &DatasetMeta) -> Vec<Photodiode> {
    let noise_v = run.sensor_sigmas.photodiode_v;
    run.calibration
        .photodiodes
        .iter()
        .enumerate()
        .map(|(i, p)| Photodiode {
            scale_v: p.scale_v,
            n_body: p.n_body(),
            noise_v,
            fov_half_angle_rad: meta.photodiodes.get(i).and_then(|m| m.fov_half_angle_rad()),
        })
        .collect()
}

/// One row's photodiode samples, magnetometer sample and Sun-vector magnitude.
struct RowOut {
    pd: Vec<PdSample>,
    mag: Option<MagSample>,
    sun_magnitude: Option<f64>,
}

/// Computes the residuals of `run` (made with `spec`, whose filter-estimated values must
/// already be the run's) over every row from the filter's start.
pub fn residuals(
    inputs: &ResidualInputs<'_>,
    spec: &ModelSpec,
    run: &CalibrationRun,
) -> Result<Residuals, DiagnoseError> {
    let tel = inputs.telemetry;
    if inputs.references.len() != tel.len() {
        return Err(DiagnoseError::LengthMismatch {
            what: "references",
            expected: tel.len(),
            found: inputs.references.len(),
        });
    }
    let photodiodes = calibrated_photodiodes(run, inputs.meta);
    let uncertainty = calibration_sigmas(run);
    let model = spec.measurement_model(photodiodes.clone(), inputs.config)?;
    let offset_s = spec
        .added
        .iter()
        .find_map(|e| match e {
            Effect::TimeOffset { seconds } => Some(*seconds),
            _ => None,
        })
        .unwrap_or(0.0);
    let track = attitude_track(run, tel);
    let rows: Vec<RowOut> = track
        .par_iter()
        .map_init(
            || {
                let held = tel.held_temperatures(inputs.meta);
                (AlbedoView::new(), Partials::default(), held)
            },
            |(view, partials, held), estimate| {
                let temperatures = held.at(estimate.index);
                let row = RowInputs {
                    model: &model,
                    photodiodes: &photodiodes,
                    used: &run.used_photodiodes,
                    uncertainty: &uncertainty,
                    offset_s,
                    temperatures,
                };
                row_samples(inputs, &row, estimate, view, partials)
            },
        )
        .collect::<Result<_, _>>()?;
    let mut out = Residuals {
        sigma_pd_v: run.sensor_sigmas.photodiode_v,
        sigma_mag_nt: run.sensor_sigmas.mag_nt,
        sigma_gyro_rad_s: run.sensor_sigmas.gyro_rad_s,
        rows: track.len(),
        albedo_map: inputs.albedo_map.to_owned(),
        ..Residuals::default()
    };
    for row in rows {
        out.pd.extend(row.pd);
        out.mag.extend(row.mag);
        out.sun_magnitude.extend(row.sun_magnitude);
    }
    // Only the filter's own rows: the back-propagated ones follow the gyro by construction.
    let filtered = run.smoothed.as_ref().map_or(run.forward.len(), Vec::len);
    out.gyro = gyro_samples(tel, &track[track.len() - filtered..]);
    Ok(out)
}

/// The rate at row `k`: the gyro sample there, else the nearest earlier one.
fn gyro_at(tel: &Telemetry, k: usize) -> Option<Vector3<f64>> {
    (0..=k).rev().find_map(|j| tel.gyro_rad_s.get(j))
}

/// The illuminated fraction at `t_s - offset_s`, linear between rows: photodiodes sampled
/// `offset_s` late see the shadow edge that much earlier. A first-order time-offset term
/// cannot move a shadow edge, where the output jumps by `C n^T s` within one sample.
fn sun_fraction_at(inputs: &ResidualInputs<'_>, k: usize, offset_s: f64) -> f64 {
    let tel = inputs.telemetry;
    let refs = inputs.references;
    if offset_s == 0.0 {
        return refs[k].sun_fraction;
    }
    let t = tel.t_s[k] - offset_s;
    let j = tel.t_s.partition_point(|&x| x <= t);
    if j == 0 || j >= tel.len() {
        return refs[k.min(refs.len() - 1)].sun_fraction;
    }
    let (t0, t1) = (tel.t_s[j - 1], tel.t_s[j]);
    let w = (t - t0) / (t1 - t0);
    refs[j - 1].sun_fraction * (1.0 - w) + refs[j].sun_fraction * w
}

/// What every row's residuals share, and the row's held temperatures.
struct RowInputs<'a> {
    model: &'a MeasurementModel,
    photodiodes: &'a [Photodiode],
    /// Which photodiodes the filter used: one it left out (never lit, dead, its data
    /// contradicting any mounting) has no residual of the model.
    used: &'a [bool],
    uncertainty: &'a [CalibrationSigma],
    offset_s: f64,
    temperatures: &'a [f64],
}

/// One photodiode's final calibration uncertainty: relative scale and normal direction.
#[derive(Debug, Clone, Copy)]
struct CalibrationSigma {
    scale_relative: f64,
    normal_rad: f64,
}

/// The calibration uncertainties of `run`'s photodiodes (an azimuth at the pole, which has
/// no sigma, counts as the elevation's).
fn calibration_sigmas(run: &CalibrationRun) -> Vec<CalibrationSigma> {
    run.calibration
        .photodiodes
        .iter()
        .map(|p| {
            let el = p.elevation_sigma_deg.to_radians();
            let az = p
                .azimuth_sigma_deg
                .map_or(el, |s| s.to_radians() * p.elevation_deg.to_radians().cos());
            CalibrationSigma {
                scale_relative: p.scale_sigma_v / p.scale_v.abs().max(f64::MIN_POSITIVE),
                normal_rad: (az * az + el * el).sqrt(),
            }
        })
        .collect()
}

/// 1-sigma of a photodiode's predicted output from its calibration's uncertainty:
/// `dI/dC sigma_C` and `C sin(theta) sigma_n` (a normal error moves the incidence by its
/// component across the Sun line). The smoothed attitude's own sigma is left out: it is
/// estimated from these same samples, so the residuals are already free of most of it.
fn prediction_sigma(
    sigma: CalibrationSigma,
    scale_v: f64,
    scale_part_v: f64,
    cos_incidence: f64,
) -> f64 {
    let scale = scale_part_v * sigma.scale_relative;
    let sin = if cos_incidence > 0.0 {
        (1.0 - cos_incidence * cos_incidence).max(0.0).sqrt()
    } else {
        0.0
    };
    let angle = scale_v * sin * sigma.normal_rad;
    (scale * scale + angle * angle).sqrt()
}

fn row_samples(
    inputs: &ResidualInputs<'_>,
    row: &RowInputs<'_>,
    estimate: &StepEstimate,
    view: &mut AlbedoView,
    partials: &mut Partials,
) -> Result<RowOut, DiagnoseError> {
    let RowInputs {
        model,
        photodiodes,
        used,
        uncertainty,
        offset_s,
        temperatures,
    } = *row;

    let k = estimate.index;
    let tel = inputs.telemetry;
    let reference = &inputs.references[k];
    let attitude: Matrix3<f64> = estimate.q.attitude_matrix();
    let bias = Vector3::from(estimate.calibration.gyro_bias_rad_s);
    let rate = gyro_at(tel, k).map_or(Vector3::zeros(), |g| g - bias);
    let t_s = tel.t_s[k];
    let mag = match tel.mag_nt.as_ref().and_then(|m| m.get(k)) {
        Some(m) => {
            let b_body = attitude * reference.b_gcrf_nt;
            Some(MagSample {
                row: k,
                t_s,
                residual_nt: m - b_body,
                time_offset_nt_s: rate.cross(&b_body),
            })
        }
        None => None,
    };
    let mut out = RowOut {
        pd: Vec::with_capacity(photodiodes.len()),
        mag,
        sun_magnitude: None,
    };
    if tel.pd_v.iter().all(|c| c.get(k).is_none()) {
        return Ok(out);
    }
    inputs
        .albedo
        .compute_into(
            view,
            &reference.r_gcrf_km,
            &reference.sun_gcrf_km,
            &reference.gcrf_to_itrf,
        )
        .map_err(|e| DiagnoseError::Albedo {
            index: k,
            message: e.to_string(),
        })?;
    let sun_body = attitude * reference.sun_gcrf_unit;
    let sun_fraction = sun_fraction_at(inputs, k, offset_s);
    let sun_distance_factor = reference.sun_distance_factor();
    let scene = Scene {
        attitude,
        sun_body,
        sun_fraction,
        sun_distance_factor,
        rate_body_rad_s: rate,
        t_s,
        albedo: Some(&*view as &dyn AlbedoIrradiance),
        temperature_c: temperatures,
    };
    // The candidates' direct-Sun signatures carry the distance factor as the model does.
    let hard = ShadowMode::Hard.factor(sun_fraction) * sun_distance_factor;
    let a_t = attitude.transpose();
    let w_cross_s = rate.cross(&sun_body);
    let r_itrf = reference.gcrf_to_itrf * reference.r_gcrf_km;
    let nadir_lat_rad = (r_itrf.z / r_itrf.norm().max(f64::MIN_POSITIVE))
        .clamp(-1.0, 1.0)
        .asin();
    let mut known = vec![0.0; photodiodes.len()];
    let mut outputs = vec![0.0; photodiodes.len()];
    let mut complete = true;
    for (i, pd) in photodiodes.iter().enumerate() {
        let Some(y) = tel.pd_v[i].get(k) else {
            complete = false;
            continue;
        };
        model.partials_into(i, &scene, partials)?;
        let pre = model.pre_stage_output(i, &scene)?;
        let predicted = partials.value_v;
        let cos = pd.n_body.dot(&sun_body);
        let lit = if pd.accepts(cos) { hard } else { 0.0 };
        let direct = lit * pd.scale_v * cos;
        known[i] = pre - model_direct(model, i, &scene)?;
        outputs[i] = y;
        if !used.get(i).copied().unwrap_or(true) {
            continue;
        }
        out.pd.push(PdSample {
            row: k,
            pd: i,
            t_s,
            measured_v: y,
            predicted_v: predicted,
            pre_stage_v: pre,
            residual_v: y - predicted,
            cos_incidence: cos,
            sun_fraction,
            albedo_v: pd.scale_v * view.ratio(&(a_t * pd.n_body), pd.cos_fov()),
            direct_v: direct,
            unshadowed_v: if pd.accepts(cos) {
                sun_distance_factor * pd.scale_v * cos
            } else {
                0.0
            },
            time_offset_v_s: lit * pd.scale_v * pd.n_body.dot(&w_cross_s),
            scale_v: partials.d_scale * pd.scale_v,
            temperature_c: temperatures.get(i).copied().unwrap_or(f64::NAN),
            prediction_sigma_v: uncertainty.get(i).map_or(0.0, |&u| {
                let scale_part = partials.d_scale * pd.scale_v;
                prediction_sigma(u, pd.scale_v, scale_part, cos)
            }),
            nadir_lat_rad,
        });
    }
    if complete && sun_fraction >= FULL_SUN {
        let options = SunVectorOptions {
            sun_distance_factor,
            ..SunVectorOptions::default()
        };
        if let SunEstimate::Observable(s) =
            estimate_sun_vector(photodiodes, &outputs, Some(&known), &options)?
        {
            out.sun_magnitude = Some(s.vector_body.norm());
        }
    }
    Ok(out)
}

/// The model's direct-Sun contribution (id `sun`) for photodiode `i`.
fn model_direct(model: &MeasurementModel, i: usize, scene: &Scene) -> Result<f64, DiagnoseError> {
    Ok(model
        .contributions(i, scene)?
        .iter()
        .filter(|(id, _)| *id == ComponentId::Sun)
        .map(|(_, v)| v)
        .sum())
}

/// Gyro samples on each side of a step averaged into its nearby rotation.
pub const NEARBY: usize = 3;

/// Longest step, in median row spacings, whose rotation the gyro residuals compare.
const MAX_GYRO_STEP_SPACINGS: f64 = 5.0;

/// Rotation over each step of the smoothed attitude minus the gyro's, body frame.
///
/// `A_{k+1} = exp(-[theta x]) A_k` for a body rotation `theta = w dt` (`dA/dt = -[w x] A`),
/// so `theta = -log(A_{k+1} A_k^T)`. The gyro's rotation uses the mean of the samples at
/// both ends minus the smoothed bias, as the filter propagates.
fn gyro_samples(tel: &Telemetry, track: &[StepEstimate]) -> Vec<GyroSample> {
    let n = tel.len();
    let longest_s = MAX_GYRO_STEP_SPACINGS * pdcal_filter::nominal_step_s(tel);
    track
        .windows(2)
        .filter_map(|w| {
            let (a, b) = (&w[0], &w[1]);
            // Across a gap in the telemetry the step's rotation is not the gyro's to answer
            // for: no sample covers it.
            if b.t_s - a.t_s > longest_s {
                return None;
            }
            let nearby: Vec<Vector3<f64>> = (a.index.saturating_sub(NEARBY)..a.index)
                .chain((b.index + 1..b.index + 1 + NEARBY).filter(|&k| k < n))
                .filter_map(|k| tel.gyro_rad_s.get(k))
                .collect();
            if nearby.is_empty() {
                return None;
            }
            let mean_nearby = nearby.iter().sum::<Vector3<f64>>() / nearby.len() as f64;
            let (ga, gb) = (tel.gyro_rad_s.get(a.index)?, tel.gyro_rad_s.get(b.index)?);
            let dt_s = b.t_s - a.t_s;
            if dt_s <= 0.0 {
                return None;
            }
            let m = b.q.attitude_matrix() * a.q.attitude_matrix().transpose();
            let theta = -Rotation3::from_matrix_unchecked(m).scaled_axis();
            let bias = Vector3::from(a.calibration.gyro_bias_rad_s);
            let rotation_rad = (0.5 * (ga + gb) - bias) * dt_s;
            let rotation_nearby_rad = (mean_nearby - bias) * dt_s;
            Some(GyroSample {
                rotation_nearby_rad,
                row: b.index,
                t_s: b.t_s,
                dt_s,
                residual_rad: theta - rotation_rad,
                rotation_rad,
            })
        })
        .collect()
}

/// Root mean square of finite values (NaN when none).
pub fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values
        .filter(|v| v.is_finite())
        .fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        (sum / n as f64).sqrt()
    }
}

/// Mean and sample standard deviation (NaN for fewer than 2 values).
pub fn mean_std(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    if values.len() < 2 {
        return (f64::NAN, f64::NAN);
    }
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, var.sqrt())
}

/// Whether the row is in umbra.
pub fn in_umbra(sample: &PdSample) -> bool {
    sample.sun_fraction <= UMBRA
}
