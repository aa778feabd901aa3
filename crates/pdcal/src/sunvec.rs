//! The attitude-independent check of the paper's Figs. 8-11: the Sun vector measured by the
//! photodiodes, with the initial and with the calibrated parameters.
//!
//! A calibrated set of photodiodes measures a unit vector: the magnitude of the least-squares
//! Sun vector should be 1. Albedo is removed with the filter's attitude estimate (the albedo
//! depends on attitude: the paper's argument for an attitude-dependent calibration).

use anyhow::Result;
use nalgebra::Vector3;
use pdcal_albedo::{AlbedoIrradiance, AlbedoModel, AlbedoView};
use pdcal_attitude::Quat;
use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_filter::{Calibration, CalibrationRun, FilterConfig, References};
use pdcal_photodiode::{Photodiode, SunEstimate, SunVectorOptions, estimate_sun_vector};

use crate::stats::{MeanStdSums, Thinned};

/// The Sun-vector magnitudes and direction changes over the samples in full Sun where both
/// the initial and the calibrated sets give an observable vector: their statistics over
/// every such sample, and an evenly thinned series of them for the figures (every sample
/// up to `2 x` [`SUN_VECTOR_POINTS`]), so that memory does not grow with the rows.
#[derive(Debug, Clone, Default)]
pub struct SunVectorMetrics {
    /// Samples counted.
    pub samples: usize,
    /// |s| with the initial parameters, albedo removed.
    pub magnitude_initial: MeanStdSums,
    /// |s| with the calibrated parameters, albedo removed.
    pub magnitude_calibrated: MeanStdSums,
    /// Angle between the initial and calibrated directions, deg (Fig. 11).
    pub direction_change_deg: MeanStdSums,
    /// The samples the figures draw, in time order.
    pub points: Vec<SunVectorPoint>,
}

/// One sample of [`SunVectorMetrics`].
#[derive(Debug, Clone, Copy)]
pub struct SunVectorPoint {
    /// Sample time, s.
    pub t_s: f64,
    /// |s| with the initial parameters, albedo removed.
    pub magnitude_initial: f64,
    /// |s| with the calibrated parameters, albedo removed.
    pub magnitude_calibrated: f64,
    /// |s| with the calibrated parameters, raw outputs (Fig. 10, red).
    pub magnitude_uncompensated: f64,
    /// Angle between the initial and calibrated directions, deg (Fig. 11).
    pub direction_change_deg: f64,
    /// Measured Sun direction in the body frame with the initial parameters (Fig. 3).
    pub direction_initial_body: [f64; 3],
}

/// Half the most samples [`SunVectorMetrics::points`] keeps.
pub const SUN_VECTOR_POINTS: usize = 4000;

fn photodiodes(calibration: &Calibration, noise_v: f64, fov_rad: f64) -> Vec<Photodiode> {
    calibration
        .photodiodes
        .iter()
        .map(|p| Photodiode {
            scale_v: p.scale_v,
            n_body: p.n_body(),
            noise_v,
            fov_half_angle_rad: Some(fov_rad),
        })
        .collect()
}

/// A photodiode whose calibrated scale sigma is above this fraction of its scale was not
/// calibrated (too little sunlight inside its field of view): it is left out of both the
/// initial and the calibrated Sun vector, as a user would leave it out of attitude
/// determination, so the two sets stay comparable.
pub const UNCALIBRATED_SCALE_SIGMA_FRACTION: f64 = 0.05;

/// Computes the metrics from a finished run, along its smoothed attitudes (else the
/// forward ones).
pub fn metrics(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    references: References<'_>,
    run: &CalibrationRun,
    albedo: &AlbedoModel,
    config: &FilterConfig,
) -> Result<SunVectorMetrics> {
    let track = run.smoothed.as_ref().unwrap_or(&run.forward);
    let attitudes = track.iter().map(|e| Ok((e.index, e.q)));
    metrics_along(meta, telemetry, references, run, attitudes, albedo, config)
}

/// [`metrics`] along given attitudes `(row, attitude)`, rows increasing (a streaming run
/// reads them back from its spill file, [`crate::stream::AttitudeSpill`]).
pub fn metrics_along(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    references: References<'_>,
    run: &CalibrationRun,
    attitudes: impl IntoIterator<Item = Result<(usize, Quat)>>,
    albedo: &AlbedoModel,
    config: &FilterConfig,
) -> Result<SunVectorMetrics> {
    let noise_v = run.sensor_sigmas.photodiode_v;
    // Albedo reaches a photodiode over its whole hemisphere.
    let hemisphere = std::f64::consts::FRAC_PI_2;
    let calibrated_ok: Vec<bool> = run
        .calibration
        .photodiodes
        .iter()
        .zip(&run.used_photodiodes)
        .map(|(p, used)| *used && p.scale_sigma_v <= UNCALIBRATED_SCALE_SIGMA_FRACTION * p.scale_v)
        .collect();
    let initial = photodiodes(&run.initial, noise_v, hemisphere);
    let mut calibrated = photodiodes(&run.calibration, noise_v, hemisphere);
    // A photodiode left out reads 0 V and is never lit; one whose scale the filter drove
    // through zero keeps its initial scale here so that the estimator accepts the set.
    for ((pd, first), ok) in calibrated.iter_mut().zip(&initial).zip(&calibrated_ok) {
        if !ok {
            pd.scale_v = first.scale_v;
        }
    }
    let m = meta.photodiodes.len();
    let mut out = SunVectorMetrics::default();
    let mut points = Thinned::new(SUN_VECTOR_POINTS);
    let mut view = AlbedoView::new();
    let (mut outputs, mut known_initial, mut known_cal) =
        (vec![0.0; m], vec![0.0; m], vec![0.0; m]);
    for attitude in attitudes {
        let (k, q) = attitude?;
        let reference = references.at(k)?;
        if reference.sun_fraction < config.min_sun_fraction
            || !read_outputs(telemetry, k, &calibrated_ok, &mut outputs)
        {
            continue;
        }
        albedo.compute_into(
            &mut view,
            &reference.r_gcrf_km,
            &reference.sun_gcrf_km,
            &reference.gcrf_to_itrf,
        )?;
        // The scales are the outputs at 1 AU: |s| = 1 needs the sample's distance factor.
        let options = SunVectorOptions {
            sun_distance_factor: reference.sun_distance_factor(),
            ..SunVectorOptions::default()
        };
        let a_t = q.attitude_matrix().transpose();
        albedo_volts(&view, &initial, &a_t, &mut known_initial);
        albedo_volts(&view, &calibrated, &a_t, &mut known_cal);
        let s_init = observable(estimate_sun_vector(
            &initial,
            &outputs,
            Some(&known_initial),
            &options,
        )?);
        let s_cal = observable(estimate_sun_vector(
            &calibrated,
            &outputs,
            Some(&known_cal),
            &options,
        )?);
        let s_raw = observable(estimate_sun_vector(&calibrated, &outputs, None, &options)?);
        if let (Some(si), Some(sc), Some(sr)) = (s_init, s_cal, s_raw) {
            let d = si.normalize();
            let point = SunVectorPoint {
                t_s: telemetry.t_s[k],
                magnitude_initial: si.norm(),
                magnitude_calibrated: sc.norm(),
                magnitude_uncompensated: sr.norm(),
                direction_change_deg: si.angle(&sc).to_degrees(),
                direction_initial_body: [d.x, d.y, d.z],
            };
            out.magnitude_initial.push(point.magnitude_initial);
            out.magnitude_calibrated.push(point.magnitude_calibrated);
            out.direction_change_deg.push(point.direction_change_deg);
            points.push(point);
        }
    }
    out.samples = points.seen();
    out.points = points.into_kept();
    Ok(out)
}

/// Copies row `k`'s photodiode outputs (0 for photodiodes left out, which the least
/// squares then treats as dark); false when a photodiode in use was not sampled.
fn read_outputs(telemetry: &Telemetry, k: usize, in_use: &[bool], outputs: &mut [f64]) -> bool {
    for ((out, column), used) in outputs.iter_mut().zip(&telemetry.pd_v).zip(in_use) {
        match (column.get(k), used) {
            (_, false) => *out = 0.0,
            (Some(v), true) => *out = v,
            (None, true) => return false,
        }
    }
    true
}

/// `C E_a / E_AM0` per photodiode (Eq. 15's albedo term) at the estimated attitude.
fn albedo_volts(
    view: &AlbedoView,
    pds: &[Photodiode],
    a_transpose: &nalgebra::Matrix3<f64>,
    out: &mut [f64],
) {
    for (o, pd) in out.iter_mut().zip(pds) {
        *o = pd.scale_v * view.ratio(&(a_transpose * pd.n_body), pd.cos_fov());
    }
}

fn observable(estimate: SunEstimate) -> Option<Vector3<f64>> {
    match estimate {
        SunEstimate::Observable(s) => Some(s.vector_body),
        SunEstimate::NotObservable { .. } => None,
    }
}
