//! The offline run over a dataset: initialisation, forward filter, RTS smoother.

use nalgebra::Vector3;
use pdcal_albedo::{AlbedoIrradiance, AlbedoModel, AlbedoView};
use pdcal_attitude::{GyroNoise, Quat, normal_from_az_el};
use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_photodiode::{Albedo, DirectSun, MeasurementModel, Photodiode};

use crate::calibration::Calibration;
use crate::config::{E_AM0_W_M2, FilterConfig, Mode};
use crate::error::check_len;
use crate::filter::{Algebra, Filter, FilterNoise, InitialState, Measurements, StateView};
use crate::init::{StartInputs, find_start, initial_scales};
use crate::layout::{ATTITUDE, StateLayout};
use crate::output::{CalibrationRun, ModeUsed, ResidualRecord, StepEstimate};
use crate::smoother::SmootherStore;
use crate::{FilterError, StepReference};

/// What a run reads: the dataset's metadata and telemetry (never its truth), one reference
/// per telemetry row, and optionally the albedo model.
#[derive(Clone, Copy)]
pub struct RunInputs<'a> {
    /// dataset.ron.
    pub meta: &'a DatasetMeta,
    /// telemetry.csv.
    pub telemetry: &'a Telemetry,
    /// Sun, field, eclipse fraction and frames at every telemetry row.
    pub references: &'a [StepReference],
    /// Albedo model (the paper's Eq. 13); `None` runs without albedo.
    pub albedo: Option<&'a AlbedoModel>,
}

/// The paper's measurement model (Eq. 15: direct Sun plus albedo) for `photodiodes`, with
/// the configured albedo partials.
pub fn paper_model(photodiodes: Vec<Photodiode>, config: &FilterConfig) -> MeasurementModel {
    let mut model = MeasurementModel::new(photodiodes);
    // Ids are distinct, so adding cannot fail; the results are ignored deliberately.
    let _ = model.add_term(DirectSun::default());
    let _ = model.add_term(Albedo {
        partials: config.albedo_partials,
    });
    model
}

/// Calibrates with the paper's model ([`paper_model`]).
pub fn calibrate(
    inputs: &RunInputs<'_>,
    config: &FilterConfig,
    mode: &Mode,
) -> Result<CalibrationRun, FilterError> {
    let photodiodes = nominal_photodiodes(inputs.meta);
    calibrate_with_model(
        inputs,
        config,
        mode,
        paper_model(photodiodes, config),
        Algebra::Structured,
    )
}

fn nominal_photodiodes(meta: &DatasetMeta) -> Vec<Photodiode> {
    meta.photodiodes
        .iter()
        .map(|m| Photodiode::from_az_el_deg(1.0, m.azimuth_deg, m.elevation_deg, 0.0))
        .collect()
}

/// Calibrates with a given measurement model: its components are kept (parameters marked
/// estimated become states), its photodiodes' scales and normals are replaced by the
/// initial estimates.
pub fn calibrate_with_model(
    inputs: &RunInputs<'_>,
    config: &FilterConfig,
    mode: &Mode,
    model: MeasurementModel,
    algebra: Algebra,
) -> Result<CalibrationRun, FilterError> {
    config.validate()?;
    let tel = inputs.telemetry;
    let m = inputs.meta.photodiodes.len();
    check_len("references", tel.len(), inputs.references.len())?;
    check_len("telemetry photodiode columns", m, tel.pd_v.len())?;
    check_len("model photodiodes", m, model.photodiodes().len())?;
    let sigmas = config.resolve(inputs.meta.noise.as_ref());
    let has_mag = tel.mag_nt.is_some();
    let (mode_used, use_mag) = match mode {
        Mode::Full if has_mag => (ModeUsed::Full, true),
        Mode::Full | Mode::PhotodiodeOnly => (ModeUsed::PhotodiodeOnly, false),
        Mode::ScaleOnly { .. } => (
            ModeUsed::ScaleOnly {
                with_magnetometer: has_mag,
            },
            has_mag,
        ),
    };
    let prior = match mode {
        Mode::ScaleOnly { prior } => {
            check_len("prior photodiodes", m, prior.photodiodes.len())?;
            Some(prior)
        }
        _ => None,
    };
    let initial = initial_scales(tel, config.min_lit_output_sigmas * sigmas.photodiode_v)?;
    let used = initial.used.clone();
    let max_scales = initial.scale_v.clone();
    let (scale_v, scale_sigma_v, n_body): (Vec<f64>, Vec<f64>, Vec<Vector3<f64>>) = match prior {
        Some(prior) => (
            prior.photodiodes.iter().map(|p| p.scale_v).collect(),
            prior
                .photodiodes
                .iter()
                .map(|p| {
                    p.scale_sigma_v
                        .hypot(config.initial_scale_sigma_fraction * p.scale_v)
                })
                .collect(),
            prior.photodiodes.iter().map(|p| p.n_body()).collect(),
        ),
        None => (
            max_scales.clone(),
            max_scales
                .iter()
                .zip(&initial.from_median)
                .map(|(c, &median)| {
                    // A median-based value is an assumption (same sensor type): 2x wider.
                    let widen = if median { 2.0 } else { 1.0 };
                    widen * config.initial_scale_sigma_fraction * c
                })
                .collect(),
            inputs
                .meta
                .photodiodes
                .iter()
                .map(|p| {
                    normal_from_az_el(p.azimuth_deg.to_radians(), p.elevation_deg.to_radians())
                })
                .collect(),
        ),
    };
    let init_pds: Vec<Photodiode> = scale_v
        .iter()
        .zip(&n_body)
        .map(|(&c, n)| Photodiode {
            scale_v: c,
            n_body: *n,
            noise_v: sigmas.photodiode_v,
            fov_half_angle_rad: None,
        })
        .collect();
    let start = find_start(
        &StartInputs {
            telemetry: tel,
            references: inputs.references,
            photodiodes: &init_pds,
            used: &used,
            use_mag,
            mag_sigma_nt: sigmas.mag_nt,
            albedo: inputs.albedo,
        },
        config,
    )?;
    let layout = StateLayout::new(&model, prior.is_none());
    let dt_nominal = nominal_step_s(tel);
    let (extra_sigma, extra_walk): (Vec<f64>, Vec<f64>) = layout
        .extras()
        .iter()
        .map(|e| {
            let (s, w) = config.parameter_sigma(&e.name, &e.unit);
            (s, w * w)
        })
        .unzip();
    let noise = FilterNoise {
        gyro: GyroNoise {
            sigma_v_rad_sqrt_s: sigmas.gyro_rad_s * dt_nominal.sqrt() * config.gyro_noise_inflation,
            sigma_u_rad_s_sqrt_s: config.gyro_bias_walk_rad_s_sqrt_s,
        },
        rate_change_fraction: config.rate_change_fraction,
        scale_walk_var_per_s: scale_v
            .iter()
            .map(|c| (config.scale_walk_fraction_per_sqrt_h * c).powi(2) / 3600.0)
            .collect(),
        normal_walk_var_per_s: config.normal_walk_deg_per_sqrt_h.to_radians().powi(2) / 3600.0,
        extra_walk_var_per_s: extra_walk,
        photodiode_sigma_v: sigmas.photodiode_v,
        albedo_sigma_ratio: config.albedo_sigma_w_m2 / E_AM0_W_M2,
        mag_sigma_nt: sigmas.mag_nt,
        gate_sigmas: config.gate_sigmas,
        cos_fov: config.fov_half_angle_deg.to_radians().cos(),
        min_sun_fraction: config.min_sun_fraction,
        second_order: config.second_order_noise,
    };
    let init = InitialState {
        q: start.q,
        attitude_cov: start.attitude_cov,
        bias_rad_s: Vector3::zeros(),
        bias_sigma_rad_s: config.initial_bias_sigma_deg_s.to_radians(),
        scale_v,
        scale_sigma_v,
        n_body,
        normal_sigma_rad: config.initial_normal_sigma_deg.to_radians(),
        extra_sigma,
        used: used.clone(),
    };
    let mut filter = Filter::new(model, layout, init, noise, algebra)?;
    let initial = filter.calibration(prior);
    let steps = tel.len() - start.index;
    let mut store = config
        .smoother
        .then(|| SmootherStore::new(filter.layout().len(), steps));
    let mut forward = Vec::with_capacity(steps);
    let mut residuals = Vec::with_capacity(steps * 4);
    let mut row = vec![None; m];
    let mut view = AlbedoView::new();
    let mut last_gyro: Option<Vector3<f64>> = None;
    let mut temperatures = tel.held_temperatures(inputs.meta);
    for k in start.index..tel.len() {
        let t_s = tel.t_s[k];
        let reference = &inputs.references[k];
        check_reference(k, t_s, reference)?;
        let gyro = tel.gyro_rad_s[k];
        if k > start.index {
            let dt = t_s - tel.t_s[k - 1];
            let previous = tel.gyro_rad_s[k - 1].or(last_gyro);
            let (rate, change) = step_rate(previous, gyro, config.average_gyro);
            filter.propagate(&rate, change, dt);
            if let (Some(store), Some(prop)) = (store.as_mut(), filter.last_propagation()) {
                let prop = prop.clone();
                store.push_transition(&prop, filter.q(), filter.calibration_noise());
            }
        }
        if gyro.is_some() {
            last_gyro = gyro;
        }
        for (i, slot) in row.iter_mut().enumerate() {
            *slot = tel.pd_v[i][k];
        }
        let mag_nt = if use_mag {
            tel.mag_nt.as_ref().and_then(|col| col[k])
        } else {
            None
        };
        if use_mag && mag_nt.is_none() {
            filter.count_mag_not_sampled();
        }
        let provider: Option<&dyn AlbedoIrradiance> = match inputs.albedo {
            Some(model)
                if reference.sun_fraction >= config.min_sun_fraction
                    && row.iter().any(Option::is_some) =>
            {
                reference.albedo_into(model, &mut view, k)?;
                Some(&view)
            }
            _ => None,
        };
        filter.update(
            t_s,
            &Measurements {
                mag_nt,
                pd_v: &row,
                temperature_c: temperatures.at(k),
            },
            reference,
            provider,
        )?;
        residuals.extend(filter.records().iter().map(|r| ResidualRecord {
            index: k,
            t_s,
            sensor: r.sensor,
            measured: r.measured,
            residual: r.residual,
            bound_3sigma: r.bound_3sigma,
            accepted: r.accepted,
        }));
        forward.push(filter_estimate(&filter, k, t_s, prior));
        if let Some(store) = store.as_mut() {
            store.push_posterior(k, t_s, &filter);
        }
    }
    let smoothed = match store {
        Some(store) => Some(store.smooth(filter.layout(), prior)?),
        None => None,
    };
    Ok(CalibrationRun {
        mode: mode_used,
        start_index: start.index,
        initial,
        used_photodiodes: used,
        sensor_sigmas: sigmas,
        forward,
        smoothed,
        residuals,
        calibration: filter.calibration(prior),
        counts: *filter.counts(),
        layout: filter.layout().clone(),
        final_covariance: filter.covariance().clone(),
    })
}

/// The rate over a step from the gyro samples at its ends: their mean (or the first held),
/// and the size of the change between them.
fn step_rate(
    previous: Option<Vector3<f64>>,
    current: Option<Vector3<f64>>,
    average: bool,
) -> (Vector3<f64>, f64) {
    match (previous, current) {
        (Some(a), Some(b)) => {
            let rate = if average { 0.5 * (a + b) } else { a };
            (rate, (b - a).norm())
        }
        (Some(a), None) => (a, 0.0),
        (None, Some(b)) => (b, 0.0),
        (None, None) => (Vector3::zeros(), 0.0),
    }
}

/// Median spacing of consecutive rows (the gyro sample period for the noise conversion).
fn nominal_step_s(tel: &Telemetry) -> f64 {
    let mut dts: Vec<f64> = tel.t_s.windows(2).map(|w| w[1] - w[0]).collect();
    if dts.is_empty() {
        return 1.0;
    }
    dts.sort_by(f64::total_cmp);
    dts[dts.len() / 2]
}

fn check_reference(index: usize, t_s: f64, r: &StepReference) -> Result<(), FilterError> {
    let finite = |v: &Vector3<f64>| v.iter().all(|x| x.is_finite());
    let checks = [
        (
            "Sun direction",
            finite(&r.sun_gcrf_unit) && r.sun_gcrf_unit.norm() > 0.5,
        ),
        ("magnetic field", finite(&r.b_gcrf_nt)),
        ("Sun fraction", r.sun_fraction.is_finite()),
        ("position", finite(&r.r_gcrf_km)),
        ("Sun position", finite(&r.sun_gcrf_km)),
    ];
    match checks.iter().find(|(_, ok)| !ok) {
        Some((what, _)) => Err(FilterError::NonFinite { index, t_s, what }),
        None => Ok(()),
    }
}

fn filter_estimate(
    filter: &Filter,
    index: usize,
    t_s: f64,
    fixed: Option<&Calibration>,
) -> StepEstimate {
    let view = StateView {
        bias: filter.bias_rad_s(),
        scale: filter.scales_v(),
        normal: filter.normals(),
        extras: filter.extra_values(),
        p: filter.covariance(),
    };
    step_estimate(index, t_s, filter.q(), &view, filter.layout(), fixed)
}

pub(crate) fn step_estimate(
    index: usize,
    t_s: f64,
    q: Quat,
    view: &StateView<'_>,
    layout: &StateLayout,
    fixed: Option<&Calibration>,
) -> StepEstimate {
    let sig = |k: usize| {
        view.p[(ATTITUDE + k, ATTITUDE + k)]
            .max(0.0)
            .sqrt()
            .to_degrees()
    };
    StepEstimate {
        index,
        t_s,
        q,
        attitude_sigma_deg: [sig(0), sig(1), sig(2)],
        calibration: view.calibration(layout, fixed),
    }
}
