//! Initialisation as the paper (IV.B): `C` = maximum measured output (referred to 1 AU),
//! nominal normals, attitude by the q-method from the magnetometer and the photodiode Sun
//! vector at the first usable sample, zero gyro bias.

use nalgebra::{Matrix3, Vector3};
use pdcal_albedo::{AlbedoIrradiance, AlbedoModel, AlbedoView};
use pdcal_attitude::{Quat, VectorPair, q_method};
use pdcal_dataset::Telemetry;
use pdcal_photodiode::{Photodiode, SunEstimate, SunVectorOptions, estimate_sun_vector};

use crate::{FilterConfig, FilterError, StepReference};

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
    references: &[StepReference],
    threshold_v: f64,
) -> Result<InitialScales, FilterError> {
    crate::error::check_len("references", telemetry.len(), references.len())?;
    let factors: Vec<f64> = references
        .iter()
        .map(StepReference::sun_distance_factor)
        .collect();
    let maxima: Vec<f64> = telemetry
        .pd_v
        .iter()
        .map(|col| {
            col.iter()
                .zip(&factors)
                .filter_map(|(y, f)| y.map(|y| y / f))
                .fold(f64::NEG_INFINITY, f64::max)
        })
        .collect();
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

/// The first usable sample and the attitude there.
#[derive(Debug, Clone, PartialEq)]
pub struct Start {
    /// Telemetry row.
    pub index: usize,
    /// Attitude.
    pub q: Quat,
    /// Attitude-error covariance, rad^2.
    pub attitude_cov: Matrix3<f64>,
}

/// What [`find_start`] works with.
pub struct StartInputs<'a> {
    /// Telemetry.
    pub telemetry: &'a Telemetry,
    /// One reference per row.
    pub references: &'a [StepReference],
    /// Photodiodes with the initial scales and normals (`noise_v` = photodiode sigma).
    pub photodiodes: &'a [Photodiode],
    /// Which photodiodes take part.
    pub used: &'a [bool],
    /// Use the magnetometer (two-vector attitude) or the Sun alone.
    pub use_mag: bool,
    /// Magnetometer sigma, nT.
    pub mag_sigma_nt: f64,
    /// Albedo model to remove albedo from the initial Sun vector.
    pub albedo: Option<&'a AlbedoModel>,
}

/// The first row in full Sun with a gyro sample, an observable photodiode Sun vector and
/// (with the magnetometer) a field sample at least `initial_min_sun_field_angle_deg` from the
/// Sun; the attitude there by the q-method (or, Sun only, the smallest rotation taking the
/// reference Sun to the measured one), refined twice with the albedo removed at that attitude.
///
/// Covariance: two vectors, `(sum w_i (I - b_i b_i^T))^-1` with `w = 1/sigma^2` (the
/// q-method's Fisher information; Markley & Crassidis Sec. 5.5); Sun only,
/// `sigma_sun^2 (I - s s^T) + sigma_unobserved^2 s s^T`. Plus the configured floor.
pub fn find_start(inputs: &StartInputs<'_>, config: &FilterConfig) -> Result<Start, FilterError> {
    let tel = inputs.telemetry;
    let m = inputs.photodiodes.len();
    let mut outputs = vec![0.0; m];
    let mut known = vec![0.0; m];
    let mut view = AlbedoView::new();
    let sin_min_angle = config.initial_min_sun_field_angle_deg.to_radians().sin();
    let mut reason = "no sample in full Sun";
    for k in 0..tel.len() {
        let reference = &inputs.references[k];
        if reference.sun_fraction < config.min_sun_fraction || tel.gyro_rad_s[k].is_none() {
            continue;
        }
        let mag = match (inputs.use_mag, tel.mag_nt.as_ref().and_then(|m| m[k])) {
            (false, _) => None,
            (true, Some(b)) => Some(b),
            (true, None) => {
                reason = "no magnetometer sample in full Sun";
                continue;
            }
        };
        if let Some(b) = mag {
            let sin_angle = reference
                .b_gcrf_nt
                .normalize()
                .cross(&reference.sun_gcrf_unit)
                .norm();
            if sin_angle < sin_min_angle || b.norm() == 0.0 {
                reason = "Sun and field too close to parallel";
                continue;
            }
        }
        for (i, out) in outputs.iter_mut().enumerate() {
            *out = if inputs.used[i] {
                tel.pd_v[i][k].unwrap_or(0.0)
            } else {
                0.0
            };
        }
        known.iter_mut().for_each(|x| *x = 0.0);
        let options = SunVectorOptions {
            sun_distance_factor: reference.sun_distance_factor(),
            ..SunVectorOptions::default()
        };
        let Some(mut sun_body) = sun_direction(inputs.photodiodes, &outputs, &known, &options)?
        else {
            reason = "photodiode Sun vector not observable";
            continue;
        };
        let mut q = attitude(
            &sun_body,
            mag.as_ref(),
            reference,
            config,
            inputs.mag_sigma_nt,
        )?;
        if let Some(model) = inputs.albedo {
            reference.albedo_into(model, &mut view, k)?;
            for _ in 0..2 {
                let a = q.attitude_matrix();
                for (i, pd) in inputs.photodiodes.iter().enumerate() {
                    known[i] = pd.scale_v * view.ratio(&(a.transpose() * pd.n_body), 0.0);
                }
                if let Some(s) = sun_direction(inputs.photodiodes, &outputs, &known, &options)? {
                    sun_body = s;
                    q = attitude(
                        &sun_body,
                        mag.as_ref(),
                        reference,
                        config,
                        inputs.mag_sigma_nt,
                    )?;
                }
            }
        }
        let attitude_cov = covariance(&sun_body, mag.as_ref(), config, inputs.mag_sigma_nt);
        return Ok(Start {
            index: k,
            q,
            attitude_cov,
        });
    }
    Err(FilterError::NoInitialSample {
        reason: reason.to_owned(),
    })
}

fn sun_direction(
    photodiodes: &[Photodiode],
    outputs: &[f64],
    known: &[f64],
    options: &SunVectorOptions,
) -> Result<Option<Vector3<f64>>, FilterError> {
    Ok(
        match estimate_sun_vector(photodiodes, outputs, Some(known), options)? {
            SunEstimate::Observable(s) => Some(s.direction_body),
            SunEstimate::NotObservable { .. } => None,
        },
    )
}

fn attitude(
    sun_body: &Vector3<f64>,
    mag_body: Option<&Vector3<f64>>,
    reference: &StepReference,
    config: &FilterConfig,
    mag_sigma_nt: f64,
) -> Result<Quat, FilterError> {
    let Some(b) = mag_body else {
        return Ok(minimal_rotation(&reference.sun_gcrf_unit, sun_body));
    };
    let w_sun = config.initial_sun_sigma_deg.to_radians().powi(-2);
    let w_mag = (mag_sigma_nt / b.norm()).powi(-2);
    let pairs = [
        VectorPair::new(*sun_body, reference.sun_gcrf_unit, w_sun),
        VectorPair::new(*b, reference.b_gcrf_nt, w_mag),
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
    mag_body: Option<&Vector3<f64>>,
    config: &FilterConfig,
    mag_sigma_nt: f64,
) -> Matrix3<f64> {
    let s = sun_body.normalize();
    let var_sun = config.initial_sun_sigma_deg.to_radians().powi(2);
    let floor = config.initial_attitude_sigma_floor_deg.to_radians().powi(2) * Matrix3::identity();
    let across = |v: &Vector3<f64>| Matrix3::identity() - v * v.transpose();
    match mag_body {
        Some(b) => {
            let bu = b.normalize();
            let var_mag = (mag_sigma_nt / b.norm()).powi(2);
            let info = across(&s) / var_sun + across(&bu) / var_mag;
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
