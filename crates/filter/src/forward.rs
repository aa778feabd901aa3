//! The forward pass, the run's second stage: the filter over the prepared telemetry
//! ([`crate::prepare`]), one row per [`ForwardPass::step`], with the acquisition of each
//! segment's attitude; what the smoother ([`crate::smoother`]) needs of each step it records
//! there.

use std::sync::Arc;

use nalgebra::{Matrix3, Vector3};
use pdcal_albedo::{AlbedoIrradiance, AlbedoModel};
use pdcal_attitude::{GyroNoise, Quat, normal_from_az_el};
use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_photodiode::{MeasurementModel, Photodiode};

use crate::bias_fit::{BiasSource, FitInputs, FitPrior, InitialBias, fit_bias};
use crate::calibration::Calibration;
use crate::config::{E_AM0_W_M2, FilterConfig, Mode, SensorSigmas};
use crate::ensemble::StartDraw;
use crate::error::check_len;
use crate::filter::{
    AlbedoGainNoise, Algebra, Filter, FilterNoise, FilterState, InitialState, Measurements,
    Nominal, Sensor, StateView,
};
use crate::guard::RepairLog;
use crate::init::{InitialScales, Start, StartInputs, find_start, initial_scales};
use crate::layout::{ATTITUDE, BIAS, StateLayout};
use crate::output::{CalibrationRun, ModeUsed, ResidualRecord, StepEstimate};
use crate::prepare::{Prepared, RunInputs};
use crate::propagation::{self, PropagationChoice};
use crate::rate::{RateModel, StepEnvironment};
use crate::screen::{Channel, Rejections};
use crate::segments::{
    Acquisition, GapRules, InnovationWindow, SegmentBreak, SegmentReport, attitude_sigma_rad,
};
use crate::shared_rows::SharedRows;
use crate::smoother::SmootherStore;
use crate::{BiasAcrossSets, FilterError, References};
use pdcal_ephem::Reference;

/// A [`ForwardPass`] at one row, to replay from.
pub(crate) struct PassCheckpoint {
    filter: FilterState,
    pub(crate) at: Cursor,
    closed_segments: usize,
    current: SegmentReport,
    /// The data sets not yet entered: a replay from a checkpoint before a set's first
    /// acquisition must restart the gyro bias there as the pass did.
    sets_ahead: Vec<usize>,
    /// The temperatures held at the row (a temperature-dependent model reads them).
    temperatures_c: Vec<f64>,
    /// The linearisation points of the window after the segment's Sun-only acquisition.
    nominals: std::collections::BTreeMap<usize, Nominal>,
}

/// A [`ForwardPass`] before a probe ([`ForwardPass::choose_about_sun_line`]): a
/// checkpoint and the run's records, which a probe's steps must not keep.
struct ProbePoint {
    pass: PassCheckpoint,
    use_times: UseTimes,
    rejections: Rejections,
    repairs: RepairLog,
}

/// The time the data informed the calibration: per photodiode, the time its accepted
/// updates stand for (for each, the time since the photodiode's previous sample in the
/// segment: its own cadence, which is the rows' only when it is sampled on every row), and
/// the part of it with the attitude held; and the time the attitude was held since the gyro
/// bias last started from its prior. A state learnt while the attitude was tens of degrees
/// uncertain rests on linearisations at that attitude, and its sigma with them
/// ([`crate::identifiability`]).
#[derive(Debug, Clone)]
struct UseTimes {
    used_s: Vec<f64>,
    held_s: Vec<f64>,
    bias_held_s: f64,
    /// Per photodiode, the time of its last sample in the current segment, s.
    last_sampled_s: Vec<Option<f64>>,
}

impl UseTimes {
    fn new(photodiodes: usize) -> Self {
        UseTimes {
            used_s: vec![0.0; photodiodes],
            held_s: vec![0.0; photodiodes],
            bias_held_s: 0.0,
            last_sampled_s: vec![None; photodiodes],
        }
    }

    /// Photodiode `i`'s accepted update at `t_s`: the time since its previous sample in
    /// the segment (none on the row that starts one, `fresh`).
    fn add_photodiode(&mut self, i: usize, t_s: f64, held: bool, fresh: bool) {
        let since_s = match self.last_sampled_s[i] {
            Some(t0) if !fresh => t_s - t0,
            _ => 0.0,
        };
        self.used_s[i] += since_s;
        if held {
            self.held_s[i] += since_s;
        }
    }

    /// The photodiodes sampled at row `k` (`t_s`), after its updates; a row that starts a
    /// segment (`fresh`) forgets the samples before it.
    fn note_samples(&mut self, telemetry: &Telemetry, k: usize, t_s: f64, fresh: bool) {
        for (i, last) in self.last_sampled_s.iter_mut().enumerate() {
            if fresh {
                *last = None;
            }
            if telemetry.pd_v.get(i).and_then(|c| c.get(k)).is_some() {
                *last = Some(t_s);
            }
        }
    }
}

/// Where a [`ForwardPass`] stands between two steps, besides the filter and the segment
/// records: what a replay from a checkpoint restores.
#[derive(Clone)]
pub(crate) struct Cursor {
    /// The next row to process.
    pub(crate) next: usize,
    /// The attitude after the last propagation (before the updates).
    prior_q: Quat,
    propagated: bool,
    /// The next step is the first of a segment (no propagation leads to it).
    fresh: bool,
    last_gyro: Option<Vector3<f64>>,
    /// Time of `last_gyro`, s.
    last_gyro_t_s: f64,
    /// Time of the last processed row, s.
    last_t_s: f64,
    /// Position at the last processed row, GCRF, km (the dynamics' gravity gradient).
    last_r_gcrf_km: Vector3<f64>,
    /// Reference field at the last processed row, GCRF, nT (the dynamics' dipole torque).
    last_b_gcrf_nt: Vector3<f64>,
    /// With dynamics, whether the next acquisition carries the body rate from the last
    /// processed row through the dynamics (after a gap) instead of restarting it (at the
    /// first acquisition of a data set, and after a lost attitude, whose rate is suspect).
    carry_rate: bool,
    /// The next step must first acquire the attitude (a segment ended).
    acquiring: bool,
    window: InnovationWindow,
    /// The attitude sigma the segment's acquisition gave, deg ([`ForwardPass::lost_reason`]).
    acquired_sigma_deg: f64,
    /// Steps taken (the guard's full factorisation every [`FULL_GUARD_ROWS`]).
    steps: usize,
    /// The segment of the last step's row.
    step_segment: usize,
    /// Whether the attitude was held after the last step (`segments.held_attitude_sigma_deg`).
    held: bool,
}

/// Rows between two full factorisations of the covariance by the guard
/// ([`Filter::guard_covariance`]; its diagonal is tested every row).
pub const FULL_GUARD_ROWS: usize = 1024;

/// The forward filter over a dataset, one telemetry row per [`ForwardPass::step`]: the
/// initialisation (outlier screening, initial scales, the first attitude) in
/// [`ForwardPass::new`], then per row the propagation from the previous row, the updates
/// and the covariance guard. The rows fall into segments ([`crate::segments`]): at a gap, a
/// silent gyro or a lost attitude the segment ends, and the next step first re-acquires
/// the attitude in the rows that follow. The one implementation of the run's step, shared
/// by [`calibrate_with_model`] and the streaming run.
pub struct ForwardPass<'a> {
    telemetry: &'a Telemetry,
    references: References<'a>,
    albedo: Option<&'a AlbedoModel>,
    pub(crate) prior: Option<&'a Calibration>,
    config: FilterConfig,
    rules: GapRules,
    use_mag: bool,
    average_gyro: bool,
    /// The telemetry has gyro samples.
    has_gyro: bool,
    min_sun_fraction: f64,
    mode_used: ModeUsed,
    start: usize,
    initial: Calibration,
    used: Vec<bool>,
    sigmas: SensorSigmas,
    filter: Filter,
    at: Cursor,
    /// How long each photodiode updated the filter, and for how much of it the attitude
    /// was held.
    use_times: UseTimes,
    /// Closed segments, and the open one.
    segments: Vec<SegmentReport>,
    current: SegmentReport,
    row: Vec<Option<f64>>,
    /// Each photodiode's temperature column (`Telemetry::photodiode_temperatures`).
    temperature_columns: Vec<Option<usize>>,
    /// Each photodiode's temperature held from its last sample up to the current row
    /// (empty without temperature columns).
    temperatures_c: Vec<f64>,
    /// Each row's reference and albedo view, shared with the ensemble's members.
    rows: Arc<SharedRows>,
    rejections: Rejections,
    repairs: RepairLog,
    /// [`RunInputs::set_first_rows`] not yet reached.
    sets_ahead: Vec<usize>,
    /// The propagation between samples and why.
    propagation: PropagationChoice,
    /// While a window is run to find linearisation points: each propagation's row, gyro
    /// rate and step ([`ForwardPass::relinearise_window`]).
    gyro_log: Option<Vec<(usize, Vector3<f64>, f64)>>,
    /// The linearisation point of each row of the window after a Sun-only acquisition.
    nominals: std::collections::BTreeMap<usize, Nominal>,
}

impl<'a> ForwardPass<'a> {
    /// Initialises the filter on the prepared telemetry (`inputs.telemetry` must be
    /// `prepared`'s, [`Prepared::inputs`]) and acquires the first attitude (skipping, and
    /// reporting, segments where it cannot be acquired).
    pub fn new(
        inputs: &RunInputs<'a>,
        prepared: &'a Prepared<'a>,
        mode: &'a Mode,
        model: MeasurementModel,
        algebra: Algebra,
    ) -> Result<Self, FilterError> {
        Self::new_from(inputs, prepared, mode, model, algebra, None)
    }

    /// [`ForwardPass::new`] of an ensemble member ([`crate::ensemble`]): the calibration's
    /// start moved by `draw` (the prior's sigmas unchanged), the per-row work shared with
    /// the base through its [`ForwardPass::shared_rows`].
    pub fn new_from(
        inputs: &RunInputs<'a>,
        prepared: &'a Prepared<'a>,
        mode: &'a Mode,
        model: MeasurementModel,
        algebra: Algebra,
        member: Option<(&StartDraw, Arc<SharedRows>)>,
    ) -> Result<Self, FilterError> {
        let telemetry = prepared_telemetry(inputs, prepared)?;
        let config = prepared.config();
        let sigmas = prepared.sigmas();
        let (mode_used, use_mag) = mode_used(mode, telemetry.mag_nt.is_some());
        let (draw, rows) = match member {
            Some((draw, rows)) => (Some(draw), rows),
            None => (None, SharedRows::new()),
        };
        let m = inputs.meta.photodiodes.len();
        check_len("references", telemetry.len(), inputs.references.len())?;
        check_len("model photodiodes", m, model.photodiodes().len())?;
        let prior = scale_only_prior(mode, m)?;
        let initial = rows.initial_scales(|| {
            initial_scales(
                telemetry,
                &inputs.references,
                config.min_lit_output_sigmas * sigmas.photodiode_v,
            )
        })?;
        let used = initial.used.clone();
        let rules = prepared.rules();
        let layout = StateLayout::new(&model, prior.is_none());
        let (mut init, noise) =
            initial_state(inputs, &initial, prior, (config, sigmas, &rules), &layout);
        if let Some(draw) = draw {
            // A scale-only run holds the prior's normals fixed: a member moves its scales.
            let normal_sigma_rad = if prior.is_none() {
                init.normal_sigma_rad
            } else {
                0.0
            };
            draw.apply(
                &mut init.scale_v,
                &init.scale_sigma_v,
                &mut init.n_body,
                normal_sigma_rad,
            );
        }
        let mut filter = Filter::new(model, layout, init, noise, algebra)?;
        filter.set_sun_only(!use_mag);
        let propagation =
            enable_dynamics(&mut filter, inputs, telemetry, (config, sigmas, &rules))?;
        let initial = filter.calibration(prior);
        let mut pass = ForwardPass {
            references: inputs.references,
            albedo: inputs.albedo,
            prior,
            config: config.clone(),
            rules,
            use_mag,
            average_gyro: config.average_gyro,
            has_gyro: telemetry.gyro_rad_s.iter().any(|v| v.is_some()),
            min_sun_fraction: config.min_sun_fraction,
            mode_used,
            start: 0,
            initial,
            used,
            sigmas,
            at: Cursor::first(filter.q(), telemetry.t_s[0], config),
            filter,
            use_times: UseTimes::new(m),
            segments: Vec::new(),
            current: SegmentReport::open(0, telemetry.t_s[0]),
            row: vec![None; m],
            temperatures_c: telemetry.held_temperatures(inputs.meta).at(0).to_vec(),
            temperature_columns: telemetry.photodiode_temperatures(inputs.meta),
            rows,
            rejections: prepared.screened().clone(),
            repairs: RepairLog::default(),
            sets_ahead: inputs.set_first_rows.iter().rev().copied().collect(),
            propagation,
            gyro_log: None,
            nominals: std::collections::BTreeMap::new(),
            telemetry,
        };
        pass.acquire_first(inputs.meta)?;
        Ok(pass)
    }

    /// The first acquisition of the run ([`ForwardPass::acquire`]): the rows before it
    /// are skipped, the temperatures held to it, and a Sun-only start chooses its rotation
    /// about the Sun line ([`ForwardPass::choose_about_sun_line`]).
    fn acquire_first(&mut self, meta: &DatasetMeta) -> Result<(), FilterError> {
        if let Err(reason) = self.acquire()? {
            return Err(FilterError::NoInitialSample { reason });
        }
        self.start = self.at.next;
        self.temperatures_c = self
            .telemetry
            .held_temperatures(meta)
            .at(self.start)
            .to_vec();
        self.choose_about_sun_line()?;
        self.relinearise_window()
    }

    /// Acquires the attitude in the open segment from row `next` on: the first usable row
    /// ([`find_start`], with the current calibration) becomes the next row, the filter
    /// re-acquired there ([`Filter::reacquire`], the calibration's random walk grown over
    /// the time since the last processed row). A segment with no usable row is closed as
    /// skipped and the search goes on in the next. `Err(reason)` of the last segment tried
    /// when the data end first.
    fn acquire(&mut self) -> Result<Result<(), String>, FilterError> {
        // Why each segment tried was skipped, with how many times.
        let mut reasons: Vec<(String, usize)> = Vec::new();
        while self.at.next < self.telemetry.len() {
            let first = self.at.next;
            self.enter_set(first);
            let end = self.segment_end(first);
            let photodiodes = self.current_photodiodes();
            let p = self.filter.covariance();
            let bias_var = (0..3).map(|k| p[(BIAS + k, BIAS + k)]).fold(0.0, f64::max);
            let found = find_start(
                &StartInputs {
                    telemetry: self.telemetry,
                    references: self.references,
                    shared: &self.rows,
                    photodiodes: &photodiodes,
                    used: &self.used,
                    use_mag: self.use_mag,
                    mag_sigma_nt: self.sigmas.mag_nt,
                    albedo: self.albedo,
                    bias_rad_s: self.filter.bias_rad_s(),
                    bias_sigma_rad_s: bias_var.sqrt(),
                    rules: self.rules,
                    rate_without_gyro: (self.filter.has_dynamics() && !self.has_gyro)
                        .then(|| self.filter.rate_body_rad_s()),
                },
                first..end,
                &self.config,
            )?;
            match found {
                Ok(start) => {
                    self.acquired(&start, end, bias_var.sqrt())?;
                    return Ok(Ok(()));
                }
                Err(why) => {
                    self.skip_segment(end, why.clone());
                    match reasons.iter_mut().find(|(r, _)| *r == why) {
                        Some((_, n)) => *n += 1,
                        None => reasons.push((why, 1)),
                    }
                }
            }
        }
        let text = match reasons.as_slice() {
            [] => "no rows left".to_owned(),
            [(why, 1)] => why.clone(),
            _ => reasons
                .iter()
                .map(|(why, n)| format!("{n} segments: {why}"))
                .collect::<Vec<_>>()
                .join("; "),
        };
        Ok(Err(text))
    }

    /// The open segment's attitude acquired at `start` (its data segment ending before
    /// row `end`; `bias_sigma_rad_s` the largest gyro-bias sigma before it): the filter
    /// re-acquired there, the segment's record, the cursor moved to the row, the rate set
    /// from the gyro and the bias fitted ([`ForwardPass::initialise_bias`]).
    fn acquired(
        &mut self,
        start: &Start,
        end: usize,
        bias_sigma_rad_s: f64,
    ) -> Result<(), FilterError> {
        self.reacquire_at(start)?;
        self.filter.correlate_attitude(&start.sensitivity);
        self.current.acquired_row = Some(start.index);
        self.current.acquisition = if self.use_mag {
            Acquisition::SunAndField
        } else {
            Acquisition::SunOnly
        };
        self.current.paired_field_row = start.paired_field_row;
        self.at.next = start.index;
        self.at.prior_q = start.q;
        self.at.fresh = true;
        self.at.last_gyro = Some(start.gyro_rad_s);
        self.at.last_gyro_t_s = start.gyro_t_s;
        if self.has_gyro {
            self.filter.set_rate(
                start.gyro_rad_s - self.filter.bias_rad_s(),
                bias_sigma_rad_s.hypot(self.sigmas.gyro_rad_s),
            );
        }
        self.at.acquiring = false;
        self.at.window.clear();
        self.current.initial_bias = Some(self.initialise_bias(start, end)?);
        self.at.acquired_sigma_deg = self.attitude_sigma_deg(start.index);
        Ok(())
    }

    /// The open segment closed as skipped (no attitude could be acquired in it, `why`),
    /// ending before row `end`, where the search goes on.
    fn skip_segment(&mut self, end: usize, why: String) {
        let ended_by = if end < self.telemetry.len() {
            SegmentBreak::Gap
        } else {
            SegmentBreak::End
        };
        self.current.skipped = Some(why);
        self.close_segment(end - 1, ended_by);
        self.at.next = end;
    }

    /// Before acquiring from row `first`: when a later data set of a joint run begins at or
    /// before it, the gyro bias restarts from its prior
    /// ([`FilterConfig::gyro_bias_across_sets`]).
    fn enter_set(&mut self, first: usize) {
        let mut entered = false;
        while self.sets_ahead.last().is_some_and(|&row| row <= first) {
            self.sets_ahead.pop();
            entered = true;
        }
        if entered {
            self.at.carry_rate = false;
        }
        if entered && self.config.gyro_bias_across_sets == BiasAcrossSets::Restart {
            self.filter
                .restart_bias(self.config.initial_bias_sigma_deg_s.to_radians());
            self.use_times.bias_held_s = 0.0;
        }
    }

    /// Re-acquires the filter at `start` ([`Filter::reacquire`]). With dynamics, after a gap
    /// the attitude and rate are first carried through it by the dynamics (the rate's
    /// covariance grown by its transition and torque noise); otherwise, without a gyro, the
    /// rate restarts from its prior (zero, `initial_rate_sigma_deg_s`).
    fn reacquire_at(&mut self, start: &Start) -> Result<(), FilterError> {
        let t_s = self.telemetry.t_s[start.index];
        let dt_s = t_s - self.at.last_t_s;
        // Sun only, the acquisition's own covariance: the calibration's part follows
        // (`Filter::correlate_attitude`).
        let own_cov = start
            .conditional_cov
            .as_ref()
            .unwrap_or(&start.attitude_cov);
        if self.filter.has_dynamics() && self.at.carry_rate && dt_s > 0.0 {
            let reference = self.references.at(start.index)?;
            let env = StepEnvironment {
                r_gcrf_km: [self.at.last_r_gcrf_km, reference.r_gcrf_km],
                b_gcrf_nt: [self.at.last_b_gcrf_nt, reference.b_gcrf_nt],
            };
            self.filter.propagate_dynamics(&env, dt_s);
            self.filter.reacquire(start.q, own_cov, 0.0);
        } else {
            self.filter.reacquire(start.q, own_cov, dt_s);
            if !self.has_gyro {
                self.filter.set_rate(
                    Vector3::zeros(),
                    self.config.initial_rate_sigma_deg_s.to_radians(),
                );
            }
        }
        Ok(())
    }

    /// At an acquisition: the bias fitted over the segment's first rows (before `end`) and
    /// fused into the filter when `bias_from_data` is on and the fit is accepted
    /// ([`crate::bias_fit`]); what the segment's bias is after it, and where it came from.
    fn initialise_bias(&mut self, start: &Start, end: usize) -> Result<InitialBias, FilterError> {
        let fit = if self.config.bias_from_data {
            let photodiodes = self.current_photodiodes();
            let prior = FitPrior {
                q0: start.q,
                attitude_cov: start.attitude_cov,
                bias_rad_s: self.filter.bias_rad_s(),
                bias_cov: self
                    .filter
                    .covariance()
                    .fixed_view::<3, 3>(BIAS, BIAS)
                    .into_owned(),
            };
            let inputs = FitInputs {
                telemetry: self.telemetry,
                references: self.references,
                photodiodes: &photodiodes,
                used: &self.used,
                use_mag: self.use_mag,
                sun_sigma_rad: self.config.initial_sun_sigma_deg.to_radians(),
                mag_sigma_nt: self.sigmas.mag_nt,
                min_sun_fraction: self.min_sun_fraction,
                gyro_hold_s: self.rules.gyro_hold_s,
                window_s: self.config.bias_fit_window_s,
            };
            fit_bias(&inputs, start.index..end, &prior)?
        } else {
            Err("bias_from_data is off".to_owned())
        };
        let fused = match fit {
            Ok(fit) if self.filter.fuse_bias(&fit.rows)? => Ok(fit),
            Ok(_) => Err("the fit contradicts the bias held beyond the gate".to_owned()),
            Err(why) => Err(why),
        };
        let p = self.filter.covariance();
        let bias = self.filter.bias_rad_s();
        let sigma = |k: usize| p[(BIAS + k, BIAS + k)].sqrt().to_degrees();
        let mut initial = InitialBias {
            source: BiasSource::Prior,
            bias_deg_s: [0, 1, 2].map(|k| bias[k].to_degrees()),
            sigma_deg_s: [0, 1, 2].map(sigma),
            directions: 0,
            vectors: 0,
            span_s: 0.0,
            reason: None,
        };
        match fused {
            Ok(fit) => {
                initial.source = BiasSource::Fit;
                initial.directions = fit.rows.len();
                initial.vectors = fit.vectors;
                initial.span_s = fit.span_s;
            }
            Err(why) => initial.reason = Some(why),
        }
        Ok(initial)
    }

    /// The first row after the gap that ends the data segment holding row `first` (the
    /// number of rows when none does).
    fn segment_end(&self, first: usize) -> usize {
        let t = &self.telemetry.t_s;
        (first + 1..t.len())
            .find(|&k| t[k] - t[k - 1] > self.rules.gap_threshold_s)
            .unwrap_or(t.len())
    }

    /// The filter's photodiodes with the sensor noise, for the Sun vector of an
    /// acquisition.
    fn current_photodiodes(&self) -> Vec<Photodiode> {
        self.filter
            .model()
            .photodiodes()
            .iter()
            .map(|pd| Photodiode {
                noise_v: self.sigmas.photodiode_v,
                fov_half_angle_rad: None,
                ..*pd
            })
            .collect()
    }

    /// Closes the open segment after `last_row` and opens the next one after it.
    fn close_segment(&mut self, last_row: usize, ended_by: SegmentBreak) {
        let t = &self.telemetry.t_s;
        self.current.close(last_row, t[last_row], ended_by);
        let next_row = last_row + 1;
        let next_t = t.get(next_row).copied().unwrap_or(t[last_row]);
        let closed = std::mem::replace(&mut self.current, SegmentReport::open(next_row, next_t));
        self.segments.push(closed);
    }

    /// Rows left to process.
    pub fn remaining(&self) -> usize {
        self.telemetry.len() - self.at.next
    }

    /// The row the filter starts at (rows before it are skipped).
    pub fn start_index(&self) -> usize {
        self.start
    }

    /// The sensor sigmas the run uses (config, hints, defaults).
    pub fn sensor_sigmas(&self) -> SensorSigmas {
        self.sigmas
    }

    /// Whether the run uses the magnetometer (else the Sun is its only vector).
    pub fn uses_magnetometer(&self) -> bool {
        self.use_mag
    }

    /// The pass's per-row results, for the ensemble members it starts
    /// ([`ForwardPass::new_from`]).
    pub fn shared_rows(&self) -> Arc<SharedRows> {
        Arc::clone(&self.rows)
    }

    /// The filter, after the last step.
    pub fn filter(&self) -> &Filter {
        &self.filter
    }

    /// The filter, to change between steps (a restart, a test's fault injection).
    pub fn filter_mut(&mut self) -> &mut Filter {
        &mut self.filter
    }

    /// Whether the next step starts a segment: the attitude is acquired first, and no
    /// propagation leads to it (the smoother's segments end before it).
    pub fn at_segment_start(&self) -> bool {
        self.at.acquiring || self.at.fresh
    }

    /// The segments so far: the closed ones and, after the last step, the open one.
    pub fn segments(&self) -> Vec<SegmentReport> {
        let mut all = self.segments.clone();
        if self.current.rows_used > 0 || self.current.skipped.is_some() {
            let mut open = self.current.clone();
            let last = self.at.next.saturating_sub(1).min(self.telemetry.len() - 1);
            open.close(
                last.max(open.first_row),
                self.telemetry.t_s[last],
                SegmentBreak::End,
            );
            all.push(open);
        }
        all
    }

    /// Processes the next row: at a segment start the attitude is acquired first (rows
    /// before the acquisition are not used); then the propagation from the previous row
    /// (the gyro samples at both ends averaged or held; a sample the screening rejected is
    /// bridged by holding the last one), the updates, the gated samples recorded, the
    /// covariance guard, and the test whether the attitude is lost or the next row starts
    /// a segment. The row processed, `None` after the last.
    pub fn step(&mut self) -> Result<Option<usize>, FilterError> {
        if self.at.acquiring && !self.acquire_in_step()? {
            return Ok(None);
        }
        let tel: &Telemetry = self.telemetry;
        let k = self.at.next;
        if k >= tel.len() {
            return Ok(None);
        }
        let t_s = tel.t_s[k];
        let reference = &self.rows.reference(&self.references, k)?;
        check_reference(k, t_s, reference)?;
        self.propagate_to(k, reference)?;
        for (slot, column) in self.row.iter_mut().zip(&tel.pd_v) {
            *slot = column.get(k);
        }
        self.hold_temperatures(k);
        self.update_at(k, reference)?;
        self.finish_step(k, reference)?;
        Ok(Some(k))
    }

    /// At a step that must first acquire the attitude: the acquisition
    /// ([`ForwardPass::acquire`]), the temperatures held over the rows it skipped, and a
    /// Sun-only start's choice about the Sun line. Whether a row is left to step to.
    fn acquire_in_step(&mut self) -> Result<bool, FilterError> {
        let from = self.at.next;
        if self.acquire()?.is_err() {
            return Ok(false);
        }
        for k in from..self.at.next {
            self.hold_temperatures(k);
        }
        self.choose_about_sun_line()?;
        self.relinearise_window()?;
        Ok(true)
    }

    /// Right after a Sun-only acquisition: the next `relinearise_window_s` of the
    /// segment, run first as the EKF runs it, give its end state (attitude, bias,
    /// calibration), carried back to each of the window's rows by the gyro with that
    /// state's bias; the rows are then processed again from the acquisition, each
    /// linearised about its row's point ([`Filter::update_about`]): one Gauss-Newton
    /// iteration of the window's smoother. Tens of degrees from the truth, as an
    /// uncalibrated head's first acquisitions are, the EKF's linearisation at each row's
    /// own estimate makes the bias and the calibration look known before they are. Not
    /// with the dynamics (the window's points come from the gyro).
    fn relinearise_window(&mut self) -> Result<(), FilterError> {
        self.nominals.clear();
        let window_s = self.config.relinearise_window_s;
        if self.current.acquisition != Acquisition::SunOnly
            || self.filter.has_dynamics()
            || window_s <= 0.0
        {
            return Ok(());
        }
        let first = self.at.next;
        let until_t_s = self.telemetry.t_s[first] + window_s;
        let start = self.probe_point();
        self.gyro_log = Some(Vec::new());
        let mut last = None;
        while self.steps_before(until_t_s) {
            match self.step()? {
                Some(k) => last = Some(k),
                None => break,
            }
        }
        let log = self.gyro_log.take().unwrap_or_default();
        let end = self.filter.nominal();
        self.back_to(&start)?;
        let Some(last) = last else {
            return Ok(());
        };
        // Each logged propagation ends at its row `k`: undone with the end state's bias,
        // it gives the point of row `k - 1`.
        let mut q = end.q;
        self.nominals.insert(last, end.clone());
        for &(k, gyro_rad_s, dt_s) in log.iter().rev() {
            if k > last || k <= first {
                continue;
            }
            q = pdcal_attitude::mekf::propagate(&q, &(gyro_rad_s - end.bias), -dt_s);
            self.nominals.insert(k - 1, Nominal { q, ..end.clone() });
        }
        Ok(())
    }

    /// The propagation from the previous row to row `k` (none at a segment's first row):
    /// by the dynamics, or by the gyro samples at both ends averaged or held (a sample the
    /// screening rejected bridged by holding the last one); then row `k`'s gyro sample, a
    /// measurement with the dynamics.
    fn propagate_to(&mut self, k: usize, reference: &Reference) -> Result<(), FilterError> {
        let tel: &Telemetry = self.telemetry;
        let t_s = tel.t_s[k];
        let gyro = tel.gyro_rad_s.get(k);
        self.at.propagated = !self.at.fresh;
        self.at.fresh = false;
        if self.at.propagated && self.filter.has_dynamics() {
            let env = StepEnvironment {
                r_gcrf_km: [self.at.last_r_gcrf_km, reference.r_gcrf_km],
                b_gcrf_nt: [self.at.last_b_gcrf_nt, reference.b_gcrf_nt],
            };
            self.filter.propagate_dynamics(&env, t_s - tel.t_s[k - 1]);
            self.at.prior_q = self.filter.q();
        } else if self.at.propagated {
            let t0 = tel.t_s[k - 1];
            let before = match tel.gyro_rad_s.get(k - 1) {
                Some(g) => Some((t0, g)),
                None => self.at.last_gyro.map(|g| (self.at.last_gyro_t_s, g)),
            };
            let after = match gyro {
                Some(g) => Some((t_s, g)),
                None => self.gyro_after(k),
            };
            let (rate, change) = step_rate(before, after, (t0, t_s), self.average_gyro);
            if let Some(log) = self.gyro_log.as_mut() {
                log.push((k, rate, t_s - t0));
            }
            self.filter.propagate(&rate, change, t_s - t0);
            self.at.prior_q = self.filter.q();
        }
        if let Some(g) = gyro {
            self.at.last_gyro = gyro;
            self.at.last_gyro_t_s = t_s;
            self.filter.update_gyro(&g)?;
            self.at.prior_q = self.filter.q();
        }
        Ok(())
    }

    /// The updates of row `k` (its photodiodes in `row`, the magnetometer when used),
    /// with the albedo of the row's reference when the spacecraft is lit.
    fn update_at(&mut self, k: usize, reference: &Reference) -> Result<(), FilterError> {
        let tel: &Telemetry = self.telemetry;
        let t_s = tel.t_s[k];
        let mag_nt = if self.use_mag {
            tel.mag_nt.as_ref().and_then(|col| col.get(k))
        } else {
            None
        };
        if self.use_mag && mag_nt.is_none() {
            self.filter.count_mag_not_sampled();
        }
        let view = match self.albedo {
            Some(model)
                if reference.sun_fraction >= self.min_sun_fraction
                    && self.row.iter().any(Option::is_some) =>
            {
                Some(self.rows.albedo(reference, model, k)?)
            }
            _ => None,
        };
        let provider = view.as_deref().map(|v| v as &dyn AlbedoIrradiance);
        let meas = Measurements {
            mag_nt,
            pd_v: &self.row,
            temperature_c: &self.temperatures_c,
        };
        match self.nominals.get(&k) {
            Some(about) => self
                .filter
                .update_about(t_s, &meas, reference, provider, about),
            None => self.filter.update(t_s, &meas, reference, provider),
        }
    }

    /// After row `k`'s updates: the covariance guard, whether the attitude is held, the
    /// gated samples and the times of use recorded, the cursor moved past the row, and
    /// the test whether the attitude is lost or the next row starts a segment.
    fn finish_step(&mut self, k: usize, reference: &Reference) -> Result<(), FilterError> {
        let tel: &Telemetry = self.telemetry;
        let t_s = tel.t_s[k];
        let step_s = if self.at.propagated {
            t_s - tel.t_s[k - 1]
        } else {
            0.0
        };
        let full = self.at.steps.is_multiple_of(FULL_GUARD_ROWS);
        if let Some(repair) = self.filter.guard_covariance(k, t_s, full)? {
            self.repairs.push(repair);
        }
        self.at.held = self.attitude_sigma_deg(k) <= self.config.segments.held_attitude_sigma_deg;
        self.record_rejections(k, t_s);
        self.use_times
            .note_samples(tel, k, t_s, !self.at.propagated);
        if self.at.held {
            self.use_times.bias_held_s += step_s;
        }
        self.at.steps += 1;
        self.at.step_segment = self.segments.len();
        self.current.rows_used += 1;
        self.at.next = k + 1;
        self.at.last_t_s = t_s;
        self.at.last_r_gcrf_km = reference.r_gcrf_km;
        self.at.last_b_gcrf_nt = reference.b_gcrf_nt;
        self.end_segment_if_due(k);
        Ok(())
    }

    /// Right after a Sun-only acquisition with albedo: follows the probe window twice, from the
    /// acquired attitude and from its half turn about the Sun line, and goes on from the
    /// start the data favour ([`crate::sun_line`]). Everything the probe steps changed is
    /// put back, so the rows are then processed once, as in any run.
    fn choose_about_sun_line(&mut self) -> Result<(), FilterError> {
        if self.current.acquisition != Acquisition::SunOnly
            || self.albedo.is_none()
            || self.config.about_sun_probe_s <= 0.0
        {
            return Ok(());
        }
        let k = self.at.next;
        let sun_gcrf = self.references.at(k)?.sun_gcrf_unit;
        let Some(axis) = nalgebra::Unit::try_new(self.filter.q().to_body(&sun_gcrf), 1e-12) else {
            return Ok(());
        };
        let half_turn = *nalgebra::Rotation3::from_axis_angle(&axis, std::f64::consts::PI).matrix();
        let until_t_s = self.telemetry.t_s[k] + self.config.about_sun_probe_s;
        let start = self.probe_point();
        let kept = self.probe(until_t_s)?;
        let kept_end = self.probe_end();
        self.back_to(&start)?;
        self.filter.turn_attitude(&half_turn);
        let turned = self.probe(until_t_s)?;
        let turned_end = self.probe_end();
        self.back_to(&start)?;
        let variance_factor = crate::sun_line::variance_factor(&kept, self.sigmas)
            .min(crate::sun_line::variance_factor(&turned, self.sigmas));
        let choice =
            crate::sun_line::compare(&kept, &turned, [&kept_end, &turned_end], variance_factor);
        if choice.turned {
            self.filter.turn_attitude(&half_turn);
            self.at.prior_q = self.filter.q();
        }
        self.current.about_sun_line = Some(choice);
        Ok(())
    }

    /// Whether the next row is in this segment (no new acquisition due) and at or before
    /// `until_t_s`.
    fn steps_before(&self, until_t_s: f64) -> bool {
        !self.at.acquiring
            && self
                .telemetry
                .t_s
                .get(self.at.next)
                .is_some_and(|&t| t <= until_t_s)
    }

    /// Steps on until `until_t_s` or the segment's end: every scalar update's term of the
    /// predictive likelihood.
    fn probe(&mut self, until_t_s: f64) -> Result<Vec<crate::sun_line::ProbeTerm>, FilterError> {
        let mut terms = Vec::new();
        while self.steps_before(until_t_s) {
            let Some(k) = self.step()? else { break };
            terms.extend(
                self.filter
                    .records()
                    .iter()
                    .filter_map(|r| crate::sun_line::ProbeTerm::new(k, r)),
            );
        }
        Ok(terms)
    }

    /// The attitude and its covariance where a probe ended.
    fn probe_end(&self) -> crate::sun_line::ProbeEnd {
        crate::sun_line::ProbeEnd {
            q: self.filter.q(),
            p_aa: self
                .filter
                .covariance()
                .fixed_view::<3, 3>(ATTITUDE, ATTITUDE)
                .into_owned(),
        }
    }

    /// Everything a step changes, to come back to after a probe.
    fn probe_point(&self) -> ProbePoint {
        ProbePoint {
            pass: self.checkpoint(),
            use_times: self.use_times.clone(),
            rejections: self.rejections.clone(),
            repairs: self.repairs.clone(),
        }
    }

    fn back_to(&mut self, point: &ProbePoint) -> Result<(), FilterError> {
        self.restore(&point.pass)?;
        self.use_times.clone_from(&point.use_times);
        self.rejections.clone_from(&point.rejections);
        self.repairs.clone_from(&point.repairs);
        Ok(())
    }

    /// The gated samples of the last update, counted per sensor (one magnetometer
    /// rejection per row) and in the innovation window.
    fn record_rejections(&mut self, k: usize, t_s: f64) {
        let mut mag_gated = false;
        for r in self.filter.records() {
            self.at.window.push(r.accepted);
            if r.accepted {
                if let Sensor::Photodiode(i) = r.sensor {
                    let fresh = !self.at.propagated;
                    self.use_times.add_photodiode(i, t_s, self.at.held, fresh);
                }
                continue;
            }
            match r.sensor {
                Sensor::Magnetometer(_) if mag_gated => {}
                sensor => {
                    mag_gated |= matches!(sensor, Sensor::Magnetometer(_));
                    self.rejections.push_gated(Channel::from(sensor), k);
                }
            }
        }
    }

    /// Ends the segment after row `k` when the attitude is lost or the next row is beyond
    /// a gap or a silent gyro.
    fn end_segment_if_due(&mut self, k: usize) {
        let ended_by = if let Some(why) = self.lost_reason() {
            self.current.lost = Some(why);
            Some(SegmentBreak::Lost)
        } else {
            let t = &self.telemetry.t_s;
            t.get(k + 1).and_then(|&t_next| {
                // The dynamics carry the attitude through a silent gyro.
                let t_gyro = if self.filter.has_dynamics() {
                    t_next
                } else {
                    self.at.last_gyro_t_s
                };
                self.rules.breaks(t[k], t_next, t_gyro)
            })
        };
        if let Some(ended_by) = ended_by {
            self.at.carry_rate = ended_by != SegmentBreak::Lost;
            self.close_segment(k, ended_by);
            self.at.acquiring = true;
        }
    }

    /// The filter's largest attitude sigma at row `k`, deg (across the Sun line without
    /// the magnetometer).
    fn attitude_sigma_deg(&self, k: usize) -> f64 {
        let p = self.filter.covariance();
        let p_aa = p.fixed_view::<3, 3>(ATTITUDE, ATTITUDE).into_owned();
        self.observed_sigma_deg(&p_aa, k)
    }

    /// The largest sigma of the attitude covariance `p_aa` at row `k`, deg: across the Sun
    /// line without the magnetometer, of every axis with it.
    fn observed_sigma_deg(&self, p_aa: &nalgebra::Matrix3<f64>, k: usize) -> f64 {
        let sun_body = if self.use_mag {
            None
        } else {
            let sun = self.references.at(k).ok().map(|r| r.sun_gcrf_unit);
            sun.map(|s| self.filter.q().to_body(&s))
        };
        attitude_sigma_rad(p_aa, sun_body.as_ref()).to_degrees()
    }

    /// As [`Self::attitude_sigma_deg`], of the attitude given the photodiodes' calibration
    /// ([`Filter::attitude_cov_given_calibration`]) without the magnetometer: with the Sun
    /// alone the photodiodes' own mounting uncertainty is part of the attitude's, and an
    /// attitude known relative to the photodiodes is held whatever that frame's uncertainty.
    /// With the magnetometer, the attitude's own sigma.
    fn relative_sigma_deg(&self, k: usize) -> f64 {
        let given = (!self.use_mag)
            .then(|| self.filter.attitude_cov_given_calibration())
            .flatten();
        match given {
            Some(p_aa) => self.observed_sigma_deg(&p_aa, k),
            None => self.attitude_sigma_deg(k),
        }
    }

    /// The attitude sigma beyond which the segment's attitude is not held, deg: the
    /// configured bound, or the acquisition's sigma where larger.
    fn loss_bound_deg(&self) -> f64 {
        self.config
            .segments
            .lost_attitude_sigma_deg
            .max(self.at.acquired_sigma_deg)
    }

    /// Why the attitude is lost after the last step, if it is: its sigma beyond the bound
    /// and beyond what the acquisition gave (a q-method with Sun and field 20 degrees apart
    /// starts near 30 degrees about one axis, and is not lost for that), or most of a full
    /// window of innovations gated.
    fn lost_reason(&self) -> Option<String> {
        let sigma_deg = self.attitude_sigma_deg(self.at.next - 1);
        let bound_deg = self.loss_bound_deg();
        if sigma_deg > bound_deg && self.relative_sigma_deg(self.at.next - 1) > bound_deg {
            let which = if self.use_mag {
                ""
            } else {
                " across the Sun line"
            };
            return Some(format!(
                "attitude sigma{which} {sigma_deg:.1} deg above {bound_deg:.1} deg"
            ));
        }
        self.at.window.lost().map(|fraction| {
            format!(
                "{:.0} % of the latest {} updates gated",
                100.0 * fraction,
                self.config.segments.lost_window_updates
            )
        })
    }

    /// The first gyro sample after row `k` within the gyro hold of the last one.
    fn gyro_after(&self, k: usize) -> Option<GyroSample> {
        let tel: &Telemetry = self.telemetry;
        let limit = self.at.last_gyro_t_s + self.rules.gyro_hold_s;
        (k + 1..tel.len())
            .take_while(|&j| tel.t_s[j] <= limit)
            .find_map(|j| tel.gyro_rad_s.get(j).map(|g| (tel.t_s[j], g)))
    }

    /// Holds each photodiode's temperature sample of row `k`, if it has one.
    fn hold_temperatures(&mut self, k: usize) {
        let tel: &Telemetry = self.telemetry;
        for (held, column) in self
            .temperatures_c
            .iter_mut()
            .zip(&self.temperature_columns)
        {
            if let Some(v) = column.and_then(|c| tel.temperature_c[c].values[k]) {
                *held = v;
            }
        }
    }

    /// The row [`ForwardPass::step`] processed last and its time.
    fn last_row(&self) -> (usize, f64) {
        let k = self.at.next.saturating_sub(1);
        (k, self.telemetry.t_s.get(k).copied().unwrap_or(f64::NAN))
    }

    /// The scalar updates of the last step as residual records.
    pub fn residual_records(&self) -> impl Iterator<Item = ResidualRecord> + '_ {
        let (index, t_s) = self.last_row();
        let records = self.filter.records().iter().map(|r| (r, false));
        let contradicted = self.filter.contradicted().iter().map(|r| (r, true));
        records
            .chain(contradicted)
            .map(move |(r, contradicted)| ResidualRecord {
                index,
                t_s,
                sensor: r.sensor,
                measured: r.measured,
                residual: r.residual,
                bound_3sigma: r.bound_3sigma,
                accepted: r.accepted,
                post_fit: r.post_fit,
                attitude_held: self.at.held,
                contradicted,
            })
    }

    /// The estimate after the last step.
    pub fn estimate(&self) -> StepEstimate {
        let (index, t_s) = self.last_row();
        filter_estimate(&self.filter, (index, t_s, self.at.step_segment), self.prior)
    }

    /// Records the last step (its propagation and posterior) for the smoother.
    pub(crate) fn record_for_smoother(&self, store: &mut SmootherStore) {
        let (index, t_s) = self.last_row();
        if self.at.propagated
            && let Some(prop) = self.filter.last_propagation()
        {
            store.push_transition(prop, self.at.prior_q, self.filter.calibration_noise());
        }
        let p = self.filter.covariance();
        let p_aa = p.fixed_view::<3, 3>(ATTITUDE, ATTITUDE).into_owned();
        let linear = attitude_sigma_rad(&p_aa, None).to_degrees() <= self.loss_bound_deg();
        store.push_posterior(index, t_s, self.at.step_segment, &self.filter, linear);
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
    pub(crate) fn checkpoint(&self) -> PassCheckpoint {
        PassCheckpoint {
            filter: self.filter.state(),
            at: self.at.clone(),
            closed_segments: self.segments.len(),
            current: self.current.clone(),
            sets_ahead: self.sets_ahead.clone(),
            temperatures_c: self.temperatures_c.clone(),
            nominals: self.nominals.clone(),
        }
    }

    /// Back to a checkpoint of this pass (the rejection and repair records keep what they
    /// have: a replay is not a new run).
    pub(crate) fn restore(&mut self, checkpoint: &PassCheckpoint) -> Result<(), FilterError> {
        self.filter.restore(&checkpoint.filter)?;
        self.at.clone_from(&checkpoint.at);
        self.segments.truncate(checkpoint.closed_segments);
        self.current.clone_from(&checkpoint.current);
        self.sets_ahead.clone_from(&checkpoint.sets_ahead);
        self.temperatures_c.clone_from(&checkpoint.temperatures_c);
        self.nominals.clone_from(&checkpoint.nominals);
        Ok(())
    }

    /// The run's result with the given per-row outputs.
    pub(crate) fn result(
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
            segments: self.segments(),
            segment_rules: self.rules,
            photodiode_time_used_s: self.use_times.used_s.clone(),
            photodiode_time_held_s: self.use_times.held_s.clone(),
            bias_time_held_s: self.use_times.bias_held_s,
            propagation: self.propagation,
            ensemble: None,
            dispersion: None,
            umbra_output_v: self.filter.umbra_outputs(),
        }
    }
}

/// The run's telemetry, which must be `prepared`'s ([`Prepared::inputs`]): the screened
/// rows, never another copy.
fn prepared_telemetry<'a>(
    inputs: &RunInputs<'a>,
    prepared: &'a Prepared<'a>,
) -> Result<&'a Telemetry, FilterError> {
    let telemetry = prepared.telemetry();
    if !std::ptr::eq(inputs.telemetry, telemetry) {
        return Err(FilterError::Missing(
            "the run's telemetry is not its prepared (screened) telemetry: build the run \
             inputs with Prepared::inputs"
                .to_owned(),
        ));
    }
    Ok(telemetry)
}

/// The mode the run reports and whether it uses the magnetometer, given whether the
/// telemetry has one.
fn mode_used(mode: &Mode, has_mag: bool) -> (ModeUsed, bool) {
    match mode {
        Mode::Full if has_mag => (ModeUsed::Full, true),
        Mode::Full | Mode::PhotodiodeOnly => (ModeUsed::PhotodiodeOnly, false),
        Mode::ScaleOnly { .. } => (
            ModeUsed::ScaleOnly {
                with_magnetometer: has_mag,
            },
            has_mag,
        ),
    }
}

/// The prior calibration of a scale-only run, checked to have the `m` photodiodes.
fn scale_only_prior(mode: &Mode, m: usize) -> Result<Option<&Calibration>, FilterError> {
    match mode {
        Mode::ScaleOnly { prior } => {
            check_len("prior photodiodes", m, prior.photodiodes.len())?;
            Ok(Some(prior))
        }
        _ => Ok(None),
    }
}

/// The filter's initial state and its noise: each photodiode's scale, its sigma and
/// normal from the prior of a scale-only run, else from the data's maxima (`initial`)
/// and the mounting in dataset.ron; the attitude is set by the first acquisition.
fn initial_state(
    inputs: &RunInputs<'_>,
    initial: &InitialScales,
    prior: Option<&Calibration>,
    (config, sigmas, rules): (&FilterConfig, SensorSigmas, &GapRules),
    layout: &StateLayout,
) -> (InitialState, FilterNoise) {
    let (scale_v, scale_sigma_v, n_body) = match prior {
        Some(prior) => prior_photodiodes(prior, config),
        None => data_photodiodes(inputs.meta, initial, config),
    };
    let (extra_sigma, extra_walk): (Vec<f64>, Vec<f64>) = layout
        .extras()
        .iter()
        .map(|e| {
            let (s, w) = config.parameter_sigma(&e.name, &e.unit);
            (s, w * w)
        })
        .unzip();
    let mut noise = filter_noise(config, sigmas, rules, &scale_v, extra_walk);
    if inputs.albedo.is_none() {
        // No albedo modelled: nothing for a gain to scale.
        noise.albedo_gain = None;
    }
    let init = InitialState {
        // Set by the first acquisition.
        q: Quat::IDENTITY,
        attitude_cov: Matrix3::identity(),
        bias_rad_s: Vector3::zeros(),
        bias_sigma_rad_s: config.initial_bias_sigma_deg_s.to_radians(),
        scale_v,
        scale_sigma_v,
        n_body,
        normal_sigma_rad: config.initial_normal_sigma_deg.to_radians(),
        extra_sigma,
        used: initial.used.clone(),
    };
    (init, noise)
}

/// Per photodiode, the initial scale (V), its sigma (V) and the normal (body frame).
type PhotodiodeStart = (Vec<f64>, Vec<f64>, Vec<Vector3<f64>>);

/// Scales, scale sigmas and normals of a scale-only run: the prior's, each sigma widened
/// by `initial_scale_sigma_fraction` of its scale.
fn prior_photodiodes(prior: &Calibration, config: &FilterConfig) -> PhotodiodeStart {
    (
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
    )
}

/// Scales, scale sigmas and normals from the data: each photodiode's maximum output
/// (`initial`), with `initial_scale_sigma_fraction` of it as sigma, and the normal of
/// its mounting in dataset.ron (Eq. 16).
fn data_photodiodes(
    meta: &DatasetMeta,
    initial: &InitialScales,
    config: &FilterConfig,
) -> PhotodiodeStart {
    (
        initial.scale_v.clone(),
        initial
            .scale_v
            .iter()
            .zip(&initial.from_median)
            .map(|(c, &median)| {
                // A median-based value is an assumption (same sensor type): 2x wider.
                let widen = if median { 2.0 } else { 1.0 };
                widen * config.initial_scale_sigma_fraction * c
            })
            .collect(),
        meta.photodiodes
            .iter()
            .map(|p| normal_from_az_el(p.azimuth_deg.to_radians(), p.elevation_deg.to_radians()))
            .collect(),
    )
}

/// The filter's noise from the configuration, the resolved sensor sigmas and the gyro's
/// own sample period (`rules`); the scales' random walk relative to `scale_v`.
fn filter_noise(
    config: &FilterConfig,
    sigmas: SensorSigmas,
    rules: &GapRules,
    scale_v: &[f64],
    extra_walk_var_per_s: Vec<f64>,
) -> FilterNoise {
    FilterNoise {
        gyro: GyroNoise {
            // The white-noise density from the gyro's own sample period: another
            // sensor sampling faster must not shrink it.
            sigma_v_rad_sqrt_s: sigmas.gyro_rad_s
                * rules.gyro_step_s.sqrt()
                * config.gyro_noise_inflation,
            sigma_u_rad_s_sqrt_s: config.gyro_bias_walk_rad_s_sqrt_s,
        },
        rate_change_fraction: config.rate_change_fraction,
        scale_walk_var_per_s: scale_v
            .iter()
            .map(|c| (config.scale_walk_fraction_per_sqrt_h * c).powi(2) / 3600.0)
            .collect(),
        normal_walk_var_per_s: config.normal_walk_deg_per_sqrt_h.to_radians().powi(2) / 3600.0,
        extra_walk_var_per_s,
        photodiode_sigma_v: sigmas.photodiode_v,
        albedo_sigma_ratio: config.albedo_sigma_w_m2 / E_AM0_W_M2,
        albedo_gain: (config.albedo_gain_sigma > 0.0).then_some(AlbedoGainNoise {
            sigma: config.albedo_gain_sigma,
            time_s: config.albedo_gain_time_s,
        }),
        mag_sigma_nt: sigmas.mag_nt,
        gate_sigmas: config.gate_sigmas,
        cos_fov: config.fov_half_angle_deg.to_radians().cos(),
        min_sun_fraction: config.min_sun_fraction,
        second_order: config.second_order_noise,
    }
}

/// Decides the propagation ([`propagation::choose`]) and adds the rigid-body dynamics'
/// states to `filter` when it runs them ([`dynamics_model`]); the rate is set at each
/// acquisition, until then unknown.
fn enable_dynamics(
    filter: &mut Filter,
    inputs: &RunInputs<'_>,
    telemetry: &Telemetry,
    (config, sigmas, rules): (&FilterConfig, SensorSigmas, &GapRules),
) -> Result<PropagationChoice, FilterError> {
    let choice = propagation::choose(
        inputs.meta,
        telemetry,
        config,
        sigmas.gyro_rad_s,
        rules.gyro_hold_s,
    );
    if let Some(rate_model) = dynamics_model(inputs.meta, telemetry, config, &choice)? {
        filter.enable_dynamics(
            rate_model,
            (
                Vector3::zeros(),
                config.initial_rate_sigma_deg_s.to_radians(),
            ),
            config.dipole_sigma_a_m2,
            sigmas.gyro_rad_s,
        );
    }
    Ok(choice)
}

impl Cursor {
    /// Before the run's first row (time `t0_s`): the attitude `q` until the first
    /// acquisition, which the first step makes.
    fn first(q: Quat, t0_s: f64, config: &FilterConfig) -> Self {
        Cursor {
            next: 0,
            prior_q: q,
            propagated: false,
            fresh: true,
            last_gyro: None,
            last_gyro_t_s: f64::NEG_INFINITY,
            last_t_s: t0_s,
            last_r_gcrf_km: Vector3::zeros(),
            last_b_gcrf_nt: Vector3::zeros(),
            carry_rate: false,
            acquiring: true,
            window: InnovationWindow::new(&config.segments),
            acquired_sigma_deg: 0.0,
            steps: 0,
            step_segment: 0,
            held: false,
        }
    }
}

/// The rigid-body model of the dynamics-aided propagation ([`crate::rate`]) when `choice`
/// runs it, else `None`; no gyro and no dynamics, or the dynamics without the inertia, is
/// an error saying what is missing.
fn dynamics_model(
    meta: &DatasetMeta,
    tel: &Telemetry,
    config: &FilterConfig,
    choice: &PropagationChoice,
) -> Result<Option<RateModel>, FilterError> {
    let has_gyro = tel.gyro_rad_s.iter().any(|v| v.is_some());
    let carried = choice.dynamics() && meta.inertia_kg_m2.is_some();
    if !has_gyro && !carried {
        let why = if meta.inertia_kg_m2.is_none() {
            "and dataset.ron has no inertia_kg_m2 (the filter needs a gyro or, with the \
             inertia, the rigid-body dynamics to carry the attitude between samples)"
        } else {
            "and the filter config turns the dynamics off (dynamics: Off)"
        };
        return Err(FilterError::Missing(format!(
            "telemetry.csv has no gyro sample {why}"
        )));
    }
    if !choice.dynamics() {
        return Ok(None);
    }
    let Some(inertia) = &meta.inertia_kg_m2 else {
        return Err(FilterError::Missing(
            "filter config: dynamics = On needs the spacecraft's inertia: add inertia_kg_m2 \
             to dataset.ron (docs/dataset-format.md)"
                .to_owned(),
        ));
    };
    let body = inertia
        .rigid_body()
        .map_err(|reason| FilterError::Missing(format!("dataset.ron: inertia_kg_m2: {reason}")))?;
    Ok(Some(RateModel {
        body,
        torque_psd: config.torque_noise_n_m_sqrt_s.powi(2),
        bias_walk_var_per_s: config.gyro_bias_walk_rad_s_sqrt_s.powi(2),
        dipole_walk_var_per_s: config.dipole_walk_a_m2_sqrt_s.powi(2),
        inertia_sigma_fraction: config.inertia_sigma_fraction,
    }))
}

/// A gyro sample: its time, s, and rate, rad/s.
type GyroSample = (f64, Vector3<f64>);

/// The rate over the step from `t0` to `t1` (s) from the gyro samples around it: `before`,
/// the latest at or before `t0`, and `after`, the first after `t0` (at `t1`, or, the run
/// being offline, a later one within the gyro hold when the gyro samples slower than the
/// rows). Averaging, the rate between them interpolated linearly at the step's midpoint
/// (their mean when they are the step's ends: second-order accurate for a rate that
/// changes during the step); otherwise `before` held. With it, the change of the rate over
/// the step (the extra attitude noise's measure).
fn step_rate(
    before: Option<GyroSample>,
    after: Option<GyroSample>,
    (t0, t1): (f64, f64),
    average: bool,
) -> (Vector3<f64>, f64) {
    match (before, after) {
        (Some((ta, a)), Some((tb, b))) => {
            let span = tb - ta;
            if ta == t0 && tb == t1 {
                let rate = if average { 0.5 * (a + b) } else { a };
                return (rate, (b - a).norm());
            }
            if span <= 0.0 {
                return (a, 0.0);
            }
            let change = (b - a).norm() * ((t1 - t0) / span).min(1.0);
            if !average {
                return (a, change);
            }
            let f = ((0.5 * (t0 + t1) - ta) / span).clamp(0.0, 1.0);
            (a + (b - a) * f, change)
        }
        (Some((_, a)), None) => (a, 0.0),
        (None, Some((_, b))) => (b, 0.0),
        (None, None) => (Vector3::zeros(), 0.0),
    }
}

fn check_reference(index: usize, t_s: f64, r: &Reference) -> Result<(), FilterError> {
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
    (index, t_s, segment): (usize, f64, usize),
    fixed: Option<&Calibration>,
) -> StepEstimate {
    let view = StateView {
        bias: filter.bias_rad_s(),
        scale: filter.scales_v().into(),
        normal: filter.normals().into(),
        extras: filter.extra_values(),
        p: filter.covariance(),
    };
    crate::output::step_estimate(
        index,
        t_s,
        segment,
        filter.q(),
        &view,
        filter.layout(),
        fixed,
    )
}
