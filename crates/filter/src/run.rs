//! The offline run over a dataset: initialisation, forward filter, RTS smoother.

use std::borrow::Cow;

use nalgebra::Vector3;
use pdcal_albedo::{AlbedoIrradiance, AlbedoModel, AlbedoView};
use pdcal_attitude::{GyroNoise, Quat, normal_from_az_el};
use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_photodiode::{Albedo, DirectSun, MeasurementModel, Photodiode};

use crate::calibration::Calibration;
use crate::config::{E_AM0_W_M2, FilterConfig, Mode, SensorSigmas};
use crate::error::check_len;
use crate::filter::{
    Algebra, Filter, FilterNoise, FilterState, InitialState, Measurements, Sensor, StateView,
};
use crate::guard::RepairLog;
use crate::init::{StartInputs, find_start, initial_scales};
use crate::layout::{ATTITUDE, StateLayout};
use crate::output::{CalibrationRun, ModeUsed, ResidualRecord, StepEstimate};
use crate::screen::{Channel, Rejections, ScreenTolerances, find_outliers, remove_outliers};
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

/// The dataset's nominal photodiodes (unit scale, `dataset.ron` normals and fields of view),
/// for [`paper_model`].
pub fn nominal_photodiodes(meta: &DatasetMeta) -> Vec<Photodiode> {
    meta.photodiodes
        .iter()
        .map(|m| {
            Photodiode::from_az_el_deg(1.0, m.azimuth_deg, m.elevation_deg, 0.0)
                .with_fov_half_angle_rad(m.fov_half_angle_rad())
        })
        .collect()
}

/// Calibrates with a given measurement model: its components are kept (parameters marked
/// estimated become states), its photodiodes' scales and normals are replaced by the
/// initial estimates. The whole run in memory: one [`StepEstimate`] per row (and per
/// smoothed row), every residual.
pub fn calibrate_with_model(
    inputs: &RunInputs<'_>,
    config: &FilterConfig,
    mode: &Mode,
    model: MeasurementModel,
    algebra: Algebra,
) -> Result<CalibrationRun, FilterError> {
    let mut pass = ForwardPass::new(inputs, config, mode, model, algebra)?;
    let steps = pass.remaining();
    let mut store = config
        .smoother
        .then(|| SmootherStore::new(pass.filter().layout().len(), steps));
    let mut forward = Vec::with_capacity(steps);
    let mut residuals = Vec::with_capacity(steps * 4);
    while pass.step()?.is_some() {
        residuals.extend(pass.residual_records());
        forward.push(pass.estimate());
        if let Some(store) = store.as_mut() {
            pass.record_for_smoother(store);
        }
    }
    let smoothed = match store {
        Some(store) => Some(store.smooth(pass.filter().layout(), pass.prior)?),
        None => None,
    };
    Ok(pass.result(forward, smoothed, residuals))
}

/// Receives a streaming run's per-row results as they are produced
/// ([`calibrate_streaming`]). Infallible by design: a sink that writes files keeps its
/// first error and reports it after the run.
pub trait RunSink {
    /// The forward estimate after one row and that row's scalar updates; rows in
    /// increasing order.
    fn forward(&mut self, estimate: &StepEstimate, residuals: &[ResidualRecord]);
    /// Smoothed estimates of consecutive rows in increasing order. Segments arrive last
    /// first (the backward pass), each of at most `segment_rows + 1` rows.
    fn smoothed(&mut self, segment: &[StepEstimate]);
}

/// Rows per segment of the streaming smoother: the forward state is kept every this many
/// rows, and the backward pass recomputes one segment's posteriors at a time (about
/// `13 kB x segment_rows` for 17 photodiodes, `27 kB` per kept state).
pub const SEGMENT_ROWS: usize = 1024;

/// [`calibrate_with_model`] with memory that does not grow with the data beyond the
/// telemetry and references it reads: per-row results go to `sink` as they are produced;
/// the smoother keeps the forward state every `segment_rows` rows and, going backward,
/// recomputes one segment's posteriors from its kept state (the same step code, so the
/// same numbers bit for bit) before smoothing it. The returned run has empty `forward`,
/// `residuals` and (with the smoother) `smoothed` vectors: those went to `sink`.
pub fn calibrate_streaming(
    inputs: &RunInputs<'_>,
    config: &FilterConfig,
    mode: &Mode,
    model: MeasurementModel,
    algebra: Algebra,
    segment_rows: usize,
    sink: &mut dyn RunSink,
) -> Result<CalibrationRun, FilterError> {
    let segment_rows = segment_rows.max(1);
    let mut pass = ForwardPass::new(inputs, config, mode, model, algebra)?;
    let mut kept = Vec::new();
    let mut residuals = Vec::new();
    loop {
        if config.smoother && (pass.next - pass.start).is_multiple_of(segment_rows) {
            kept.push(pass.checkpoint());
        }
        if pass.step()?.is_none() {
            break;
        }
        residuals.clear();
        residuals.extend(pass.residual_records());
        sink.forward(&pass.estimate(), &residuals);
    }
    // The forward results, before the replays below move the filter.
    let mut run = pass.result(Vec::new(), None, Vec::new());
    if config.smoother {
        let layout = run.layout.clone();
        let mut store = SmootherStore::new(layout.len(), segment_rows + 1);
        let mut boundary = None;
        let mut segment = Vec::with_capacity(segment_rows + 1);
        for (i, checkpoint) in kept.iter().enumerate().rev() {
            pass.restore(checkpoint)?;
            // Through the next segment's first row: its transition ends this segment.
            let last_row = kept.get(i + 1).map(|c| c.next);
            store.clear();
            while let Some(k) = pass.step()? {
                pass.record_for_smoother(&mut store);
                if Some(k) == last_row {
                    break;
                }
            }
            segment.clear();
            boundary =
                store.smooth_into(&layout, pass.prior, boundary, &mut |e| segment.push(e))?;
            segment.reverse();
            sink.smoothed(&segment);
        }
        run.smoothed = Some(Vec::new());
    }
    Ok(run)
}

/// A [`ForwardPass`] at one row, to replay from.
struct PassCheckpoint {
    filter: FilterState,
    next: usize,
    prior_q: Quat,
    propagated: bool,
    last_gyro: Option<Vector3<f64>>,
}

/// Rows between two full factorisations of the covariance by the guard
/// ([`Filter::guard_covariance`]; its diagonal is tested every row).
pub const FULL_GUARD_ROWS: usize = 1024;

/// The forward filter over a dataset, one telemetry row per [`ForwardPass::step`]: the
/// initialisation (outlier screening, initial scales, start row and attitude) in
/// [`ForwardPass::new`], then per row the propagation from the previous row, the updates
/// and the covariance guard. The one implementation of the run's step, shared by
/// [`calibrate_with_model`] and the streaming run.
pub struct ForwardPass<'a> {
    telemetry: Cow<'a, Telemetry>,
    references: &'a [StepReference],
    albedo: Option<&'a AlbedoModel>,
    prior: Option<&'a Calibration>,
    use_mag: bool,
    average_gyro: bool,
    min_sun_fraction: f64,
    mode_used: ModeUsed,
    start: usize,
    initial: Calibration,
    used: Vec<bool>,
    sigmas: SensorSigmas,
    filter: Filter,
    /// The next row to process.
    next: usize,
    /// The attitude after the last propagation (before the updates).
    prior_q: Quat,
    propagated: bool,
    last_gyro: Option<Vector3<f64>>,
    row: Vec<Option<f64>>,
    /// Each photodiode's temperature column (`Telemetry::photodiode_temperatures`).
    temperature_columns: Vec<Option<usize>>,
    /// Each photodiode's temperature held from its last sample up to the current row
    /// (empty without temperature columns).
    temperatures_c: Vec<f64>,
    view: AlbedoView,
    rejections: Rejections,
    repairs: RepairLog,
}

impl<'a> ForwardPass<'a> {
    /// Screens the telemetry ([`crate::screen`]; a screened copy is made only when a
    /// sample is rejected), initialises the filter and positions it at the start row.
    pub fn new(
        inputs: &RunInputs<'a>,
        config: &FilterConfig,
        mode: &'a Mode,
        model: MeasurementModel,
        algebra: Algebra,
    ) -> Result<Self, FilterError> {
        config.validate()?;
        let m = inputs.meta.photodiodes.len();
        check_len(
            "references",
            inputs.telemetry.len(),
            inputs.references.len(),
        )?;
        check_len(
            "telemetry photodiode columns",
            m,
            inputs.telemetry.pd_v.len(),
        )?;
        check_len("model photodiodes", m, model.photodiodes().len())?;
        let sigmas = config.resolve(inputs.meta.noise.as_ref());
        let mut rejections = Rejections::new(m);
        let outliers = find_outliers(inputs.telemetry, &ScreenTolerances::new(config, &sigmas));
        let telemetry = if outliers.is_empty() {
            Cow::Borrowed(inputs.telemetry)
        } else {
            let mut screened = inputs.telemetry.clone();
            remove_outliers(&mut screened, &outliers);
            for &(channel, k) in &outliers {
                rejections.push_screened(channel, k);
            }
            Cow::Owned(screened)
        };
        let tel: &Telemetry = &telemetry;
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
        let initial = initial_scales(
            tel,
            inputs.references,
            config.min_lit_output_sigmas * sigmas.photodiode_v,
        )?;
        let used = initial.used.clone();
        let max_scales = initial.scale_v.clone();
        let (scale_v, scale_sigma_v, n_body): (Vec<f64>, Vec<f64>, Vec<Vector3<f64>>) = match prior
        {
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
                sigma_v_rad_sqrt_s: sigmas.gyro_rad_s
                    * dt_nominal.sqrt()
                    * config.gyro_noise_inflation,
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
        let filter = Filter::new(model, layout, init, noise, algebra)?;
        let initial = filter.calibration(prior);
        Ok(ForwardPass {
            references: inputs.references,
            albedo: inputs.albedo,
            prior,
            use_mag,
            average_gyro: config.average_gyro,
            min_sun_fraction: config.min_sun_fraction,
            mode_used,
            start: start.index,
            initial,
            used,
            sigmas,
            next: start.index,
            prior_q: filter.q(),
            propagated: false,
            filter,
            last_gyro: None,
            row: vec![None; m],
            temperatures_c: telemetry
                .held_temperatures(inputs.meta)
                .at(start.index)
                .to_vec(),
            temperature_columns: telemetry.photodiode_temperatures(inputs.meta),
            view: AlbedoView::new(),
            rejections,
            repairs: RepairLog::default(),
            telemetry,
        })
    }

    /// Rows left to process.
    pub fn remaining(&self) -> usize {
        self.telemetry.len() - self.next
    }

    /// The row the filter starts at (rows before it are skipped).
    pub fn start_index(&self) -> usize {
        self.start
    }

    /// The filter, after the last step.
    pub fn filter(&self) -> &Filter {
        &self.filter
    }

    /// The filter, to change between steps (a restart, a test's fault injection).
    pub fn filter_mut(&mut self) -> &mut Filter {
        &mut self.filter
    }

    /// Processes the next row: propagation from the previous row (the gyro samples at both
    /// ends averaged or held; a sample the screening rejected is bridged by holding the
    /// last one), the updates, the gated samples recorded and the covariance guard. The row
    /// processed, `None` after the last.
    pub fn step(&mut self) -> Result<Option<usize>, FilterError> {
        let tel: &Telemetry = &self.telemetry;
        let k = self.next;
        if k >= tel.len() {
            return Ok(None);
        }
        let t_s = tel.t_s[k];
        let reference = &self.references[k];
        check_reference(k, t_s, reference)?;
        let gyro = tel.gyro_rad_s[k];
        self.propagated = k > self.start;
        if self.propagated {
            let dt = t_s - tel.t_s[k - 1];
            let previous = tel.gyro_rad_s[k - 1].or(self.last_gyro);
            let (rate, change) = step_rate(previous, gyro, self.average_gyro);
            self.filter.propagate(&rate, change, dt);
            self.prior_q = self.filter.q();
        }
        if gyro.is_some() {
            self.last_gyro = gyro;
        }
        for (slot, column) in self.row.iter_mut().zip(&tel.pd_v) {
            *slot = column[k];
        }
        for (held, column) in self
            .temperatures_c
            .iter_mut()
            .zip(&self.temperature_columns)
        {
            if let Some(v) = column.and_then(|c| tel.temperature_c[c].values[k]) {
                *held = v;
            }
        }
        let mag_nt = if self.use_mag {
            tel.mag_nt.as_ref().and_then(|col| col[k])
        } else {
            None
        };
        if self.use_mag && mag_nt.is_none() {
            self.filter.count_mag_not_sampled();
        }
        let provider: Option<&dyn AlbedoIrradiance> = match self.albedo {
            Some(model)
                if reference.sun_fraction >= self.min_sun_fraction
                    && self.row.iter().any(Option::is_some) =>
            {
                reference.albedo_into(model, &mut self.view, k)?;
                Some(&self.view)
            }
            _ => None,
        };
        self.filter.update(
            t_s,
            &Measurements {
                mag_nt,
                pd_v: &self.row,
                temperature_c: &self.temperatures_c,
            },
            reference,
            provider,
        )?;
        let mut mag_gated = false;
        for r in self.filter.records().iter().filter(|r| !r.accepted) {
            match r.sensor {
                Sensor::Magnetometer(_) if mag_gated => {}
                sensor => {
                    mag_gated |= matches!(sensor, Sensor::Magnetometer(_));
                    self.rejections.push_gated(Channel::from(sensor), k);
                }
            }
        }
        let full = (k - self.start).is_multiple_of(FULL_GUARD_ROWS);
        if let Some(repair) = self.filter.guard_covariance(k, t_s, full)? {
            self.repairs.push(repair);
        }
        self.next = k + 1;
        Ok(Some(k))
    }

    /// The row [`ForwardPass::step`] processed last and its time.
    fn last_row(&self) -> (usize, f64) {
        let k = self.next.saturating_sub(1);
        (k, self.telemetry.t_s.get(k).copied().unwrap_or(f64::NAN))
    }

    /// The scalar updates of the last step as residual records.
    pub fn residual_records(&self) -> impl Iterator<Item = ResidualRecord> + '_ {
        let (index, t_s) = self.last_row();
        self.filter.records().iter().map(move |r| ResidualRecord {
            index,
            t_s,
            sensor: r.sensor,
            measured: r.measured,
            residual: r.residual,
            bound_3sigma: r.bound_3sigma,
            accepted: r.accepted,
        })
    }

    /// The estimate after the last step.
    pub fn estimate(&self) -> StepEstimate {
        let (index, t_s) = self.last_row();
        filter_estimate(&self.filter, index, t_s, self.prior)
    }

    /// Records the last step (its propagation and posterior) for the smoother.
    pub(crate) fn record_for_smoother(&self, store: &mut SmootherStore) {
        let (index, t_s) = self.last_row();
        if self.propagated
            && let Some(prop) = self.filter.last_propagation()
        {
            store.push_transition(prop, self.prior_q, self.filter.calibration_noise());
        }
        store.push_posterior(index, t_s, &self.filter);
    }

    /// The samples rejected so far (screened, and gated up to the last step).
    pub fn rejections(&self) -> &Rejections {
        &self.rejections
    }

    /// The covariance repairs so far.
    pub fn repairs(&self) -> &RepairLog {
        &self.repairs
    }

    /// The pass's position and filter state, to replay from.
    fn checkpoint(&self) -> PassCheckpoint {
        PassCheckpoint {
            filter: self.filter.state(),
            next: self.next,
            prior_q: self.prior_q,
            propagated: self.propagated,
            last_gyro: self.last_gyro,
        }
    }

    /// Back to a checkpoint of this pass (the rejection and repair records keep what they
    /// have: a replay is not a new run).
    fn restore(&mut self, checkpoint: &PassCheckpoint) -> Result<(), FilterError> {
        self.filter.restore(&checkpoint.filter)?;
        self.next = checkpoint.next;
        self.prior_q = checkpoint.prior_q;
        self.propagated = checkpoint.propagated;
        self.last_gyro = checkpoint.last_gyro;
        Ok(())
    }

    /// The run's result with the given per-row outputs.
    fn result(
        &self,
        forward: Vec<StepEstimate>,
        smoothed: Option<Vec<StepEstimate>>,
        residuals: Vec<ResidualRecord>,
    ) -> CalibrationRun {
        CalibrationRun {
            mode: self.mode_used,
            start_index: self.start,
            initial: self.initial.clone(),
            used_photodiodes: self.used.clone(),
            sensor_sigmas: self.sigmas,
            forward,
            smoothed,
            residuals,
            calibration: self.filter.calibration(self.prior),
            counts: *self.filter.counts(),
            layout: self.filter.layout().clone(),
            final_covariance: self.filter.covariance().clone(),
            rejections: self.rejections.clone(),
            covariance_repairs: self.repairs.clone(),
        }
    }
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

/// Median spacing of consecutive rows, s, 1 with fewer than two rows (the gyro sample
/// period for the noise conversion; the diagnosis's gap test).
pub fn nominal_step_s(tel: &Telemetry) -> f64 {
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
