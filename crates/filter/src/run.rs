//! The offline run over a dataset, its stages chained: prepare ([`Prepared`], once), the
//! forward pass ([`ForwardPass`]) and the RTS smoother ([`SmootherStore`]), in memory
//! ([`calibrate_with_model`]) or streamed through a [`RunSink`] ([`calibrate_streaming`]).

use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_photodiode::{Albedo, DirectSun, MeasurementModel, Photodiode};

use crate::FilterError;
use crate::config::{FilterConfig, Mode, SensorSigmas};
use crate::consistency::Dispersion;
use crate::ensemble::Ensemble;
use crate::filter::Algebra;
use crate::forward::{ForwardPass, PassCheckpoint};
use crate::output::{CalibrationRun, ResidualRecord, StepEstimate};
use crate::prepare::{Prepared, RunInputs};
use crate::smoother::SmootherStore;

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

/// Prepares `inputs` ([`Prepared`]) and calibrates with the paper's model
/// ([`paper_model`]).
pub fn calibrate(
    inputs: &RunInputs<'_>,
    config: &FilterConfig,
    mode: &Mode,
) -> Result<CalibrationRun, FilterError> {
    let prepared = Prepared::of(inputs, config)?;
    let model = || paper_model(nominal_photodiodes(inputs.meta), config);
    calibrate_in_memory(
        &prepared.inputs(inputs),
        &prepared,
        mode,
        (model(), Some(&model)),
        Algebra::Structured,
    )
}

/// A model for each member of the ensemble ([`crate::ensemble`]); `None`: no ensemble.
pub type MemberModels<'m> = Option<&'m dyn Fn() -> MeasurementModel>;

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
    prepared: &Prepared<'_>,
    mode: &Mode,
    model: MeasurementModel,
    algebra: Algebra,
) -> Result<CalibrationRun, FilterError> {
    calibrate_in_memory(inputs, prepared, mode, (model, None), algebra)
}

/// [`calibrate_with_model`] with the ensemble's members made by `members`, when given and
/// the configuration asks for them ([`crate::ensemble`]).
fn calibrate_in_memory(
    inputs: &RunInputs<'_>,
    prepared: &Prepared<'_>,
    mode: &Mode,
    (model, members): (MeasurementModel, MemberModels<'_>),
    algebra: Algebra,
) -> Result<CalibrationRun, FilterError> {
    let config = prepared.config();
    let mut pass = ForwardPass::new(inputs, prepared, mode, model, algebra)?;
    let mut ensemble =
        members.and_then(|m| Ensemble::start(&pass, (inputs, prepared, mode), m, algebra));
    let mut scaling = ResidualScaling::new(config, pass.sensor_sigmas());
    let steps = pass.remaining();
    let mut store = config
        .smoother
        .then(|| SmootherStore::new(pass.filter().layout().len(), steps));
    let mut forward = Vec::with_capacity(steps);
    let mut residuals = Vec::with_capacity(steps * 4);
    let mut smoothed = config.smoother.then(|| Vec::with_capacity(steps));
    loop {
        // The smoother runs per segment: nothing links the attitude across a break.
        if pass.at_segment_start()
            && let (Some(store), Some(out)) = (store.as_mut(), smoothed.as_mut())
        {
            out.extend(store.smooth(pass.filter().layout(), pass.prior)?);
            store.clear();
        }
        if pass.step()?.is_none() {
            break;
        }
        let first = residuals.len();
        residuals.extend(pass.residual_records());
        let mut estimate = pass.estimate();
        scaling.widen(&mut estimate, &residuals[first..]);
        if let Some(e) = ensemble.as_mut() {
            e.widen(&mut estimate, &residuals[first..]);
        }
        forward.push(estimate);
        if let Some(store) = store.as_mut() {
            pass.record_for_smoother(store);
        }
    }
    if let (Some(store), Some(out)) = (store.as_ref(), smoothed.as_mut()) {
        out.extend(store.smooth(pass.filter().layout(), pass.prior)?);
    }
    if let Some(out) = smoothed.as_mut() {
        let k = scaling.factor();
        out.iter_mut().for_each(|s| s.scale_sigmas(k));
    }
    if let (Some(e), Some(out)) = (ensemble.as_ref(), smoothed.as_mut()) {
        out.iter_mut().for_each(|s| e.widen_smoothed(s));
    }
    let mut run = pass.result(forward, smoothed, residuals);
    scaling.widen_final(&mut run);
    if let Some(e) = ensemble {
        e.widen_final(&mut run);
    }
    Ok(run)
}

/// Receives a streaming run's per-row results as they are produced
/// ([`calibrate_streaming`]). Infallible by design: a sink that writes files keeps its
/// first error and reports it after the run.
pub trait RunSink {
    /// The forward estimate after one row and that row's scalar updates; rows in
    /// increasing order.
    fn forward(&mut self, estimate: &StepEstimate, residuals: &[ResidualRecord]);
    /// Smoothed estimates of consecutive rows of one segment in increasing order. Blocks
    /// arrive last first (the backward pass), each of at most `block_rows + 1` rows.
    fn smoothed(&mut self, segment: &[StepEstimate]);
    /// Whether the run should stop, asked every [`CANCEL_POLL_ROWS`] rows of the forward
    /// pass and of the smoother's replays; the run then ends with
    /// [`FilterError::Cancelled`]. A caller that must stay responsive (an interactive
    /// session's interrupt) answers here; the default never stops.
    fn cancelled(&mut self) -> bool {
        false
    }
}

/// Steps between two [`RunSink::cancelled`] polls: short enough to stop within a fraction
/// of a second, long enough that a poll that takes a lock costs nothing measurable.
pub const CANCEL_POLL_ROWS: usize = 256;

/// Counts the steps of a streaming run and asks its sink, every [`CANCEL_POLL_ROWS`] of
/// them, whether to stop.
#[derive(Default)]
struct CancelPoll {
    steps: usize,
}

impl CancelPoll {
    /// [`FilterError::Cancelled`] at row `k` when this is a poll step and `sink` asks to stop.
    fn step(&mut self, sink: &mut dyn RunSink, k: usize) -> Result<(), FilterError> {
        self.steps += 1;
        if self.steps.is_multiple_of(CANCEL_POLL_ROWS) && sink.cancelled() {
            return Err(FilterError::Cancelled { index: k });
        }
        Ok(())
    }
}

/// Rows per block of the streaming smoother: the forward state is kept every this many
/// rows (and at every segment start), and the backward pass recomputes one block's
/// posteriors at a time (about `13 kB x block_rows` for 17 photodiodes, `27 kB` per kept
/// state).
pub const SMOOTHER_BLOCK_ROWS: usize = 1024;

/// Kept states of the streaming smoother beyond which they are kept sparser
/// ([`kept_every`]): 1024 states are 27 MB for 17 photodiodes, a million rows in blocks of
/// [`SMOOTHER_BLOCK_ROWS`].
pub const MAX_DENSE_KEPT: usize = 1024;

/// How many of the smoother's block starts apart a state is kept over `rows` rows in
/// blocks of `block_rows`: every one up to [`MAX_DENSE_KEPT`] blocks, else about the square
/// root of the number of blocks, so that the kept states and the states of one group
/// regenerated in the backward pass are both about that root (100 states, 2.7 MB for 17
/// photodiodes, at 10 million rows) for one more forward replay of the data.
pub fn kept_every(rows: usize, block_rows: usize) -> usize {
    let blocks = rows.div_ceil(block_rows.max(1)) + 1;
    if blocks <= MAX_DENSE_KEPT {
        1
    } else {
        blocks.isqrt() + 1
    }
}

/// [`calibrate_with_model`] with memory that does not grow with the data beyond the
/// telemetry and references it reads: per-row results go to `sink` as they are produced;
/// the smoother keeps the forward state every `block_rows` rows and at every segment
/// start and, going backward, recomputes one block's posteriors from its kept state (the
/// same step code, so the same numbers bit for bit) before smoothing it; a block that ends
/// a segment starts the backward pass afresh. Beyond [`MAX_DENSE_KEPT`] blocks only every
/// [`kept_every`]-th block start is kept and the others of a group are regenerated from it
/// going backward ([`calibrate_streaming_kept`]). The returned run has empty `forward`,
/// `residuals` and (with the smoother) `smoothed` vectors: those went to `sink`.
pub fn calibrate_streaming(
    inputs: &RunInputs<'_>,
    prepared: &Prepared<'_>,
    mode: &Mode,
    models: (MeasurementModel, MemberModels<'_>),
    algebra: Algebra,
    block_rows: usize,
    sink: &mut dyn RunSink,
) -> Result<CalibrationRun, FilterError> {
    let every = kept_every(prepared.telemetry().len(), block_rows);
    calibrate_streaming_kept(
        inputs, prepared, mode, models, algebra, block_rows, every, sink,
    )
}

/// A forward state kept for the smoother's replay, and whether a segment starts there.
type Kept = (PassCheckpoint, bool);

/// [`calibrate_streaming`] keeping the forward state at every `every`-th block start
/// (at least 1) instead of [`kept_every`]'s choice: the same numbers whatever `every`.
#[allow(clippy::too_many_arguments)]
pub fn calibrate_streaming_kept(
    inputs: &RunInputs<'_>,
    prepared: &Prepared<'_>,
    mode: &Mode,
    (model, members): (MeasurementModel, MemberModels<'_>),
    algebra: Algebra,
    block_rows: usize,
    every: usize,
    sink: &mut dyn RunSink,
) -> Result<CalibrationRun, FilterError> {
    let block_rows = block_rows.max(1);
    let every = every.max(1);
    let config = prepared.config();
    let mut pass = ForwardPass::new(inputs, prepared, mode, model, algebra)?;
    let mut ensemble =
        members.and_then(|m| Ensemble::start(&pass, (inputs, prepared, mode), m, algebra));
    let mut scaling = ResidualScaling::new(config, pass.sensor_sigmas());
    let mut kept: Vec<Kept> = Vec::new();
    let mut residuals = Vec::new();
    let mut starts = BlockStarts::new(block_rows);
    let mut block_starts = 0_usize;
    let mut poll = CancelPoll::default();
    loop {
        if config.smoother
            && let Some(segment_start) = starts.at(&pass)
        {
            if block_starts.is_multiple_of(every) {
                kept.push((pass.checkpoint(), segment_start));
            }
            block_starts += 1;
        }
        let Some(k) = pass.step()? else { break };
        poll.step(sink, k)?;
        starts.in_block += 1;
        residuals.clear();
        residuals.extend(pass.residual_records());
        let mut estimate = pass.estimate();
        scaling.widen(&mut estimate, &residuals);
        if let Some(e) = ensemble.as_mut() {
            e.widen(&mut estimate, &residuals);
        }
        sink.forward(&estimate, &residuals);
    }
    // The forward results, before the replays below move the filter.
    let mut run = pass.result(Vec::new(), None, Vec::new());
    scaling.widen_final(&mut run);
    let mut widening = WideningSink {
        inner: sink,
        sigma_factor: scaling.factor(),
        ensemble: ensemble.as_ref(),
    };
    let sink: &mut dyn RunSink = &mut widening;
    if config.smoother {
        let mut smoother = Backward {
            layout: run.layout.clone(),
            store: SmootherStore::new(run.layout.len(), block_rows + 1),
            boundary: None,
            block: Vec::with_capacity(block_rows + 1),
            poll,
        };
        for j in (0..kept.len()).rev() {
            let after = kept.get(j + 1);
            if every == 1 {
                smoother.smooth_group(&mut pass, &kept[j..=j], after, sink)?;
            } else {
                let group = regenerate_group(&mut pass, &kept[j], every, block_rows, sink)?;
                smoother.smooth_group(&mut pass, &group, after, sink)?;
            }
        }
        run.smoothed = Some(Vec::new());
    }
    if let Some(e) = ensemble {
        e.widen_final(&mut run);
    }
    Ok(run)
}

/// A sink that widens the smoothed rows by the residuals' spread (the whole run's factor,
/// [`ResidualScaling`]) and the ensemble's before passing them on.
struct WideningSink<'s, 'e> {
    inner: &'s mut dyn RunSink,
    sigma_factor: f64,
    ensemble: Option<&'s Ensemble<'e>>,
}

impl RunSink for WideningSink<'_, '_> {
    fn forward(&mut self, estimate: &StepEstimate, residuals: &[ResidualRecord]) {
        self.inner.forward(estimate, residuals);
    }

    fn smoothed(&mut self, segment: &[StepEstimate]) {
        let mut widened = segment.to_vec();
        for s in &mut widened {
            s.scale_sigmas(self.sigma_factor);
            if let Some(e) = self.ensemble {
                e.widen_smoothed(s);
            }
        }
        self.inner.smoothed(&widened);
    }

    fn cancelled(&mut self) -> bool {
        self.inner.cancelled()
    }
}

/// The states at the `every` block starts from `first` on (fewer at the end of the data),
/// regenerated by replaying the forward pass from `first` as the forward pass kept them.
fn regenerate_group(
    pass: &mut ForwardPass<'_>,
    first: &Kept,
    every: usize,
    block_rows: usize,
    sink: &mut dyn RunSink,
) -> Result<Vec<Kept>, FilterError> {
    pass.restore(&first.0)?;
    let mut group: Vec<Kept> = Vec::with_capacity(every);
    // `first` is a block start: counted as one whatever the count before it.
    let mut starts = BlockStarts::new(block_rows);
    starts.in_block = block_rows;
    let mut poll = CancelPoll::default();
    loop {
        if let Some(segment_start) = starts.at(pass) {
            if group.len() == every {
                break;
            }
            group.push((pass.checkpoint(), segment_start));
        }
        let Some(k) = pass.step()? else { break };
        poll.step(sink, k)?;
        starts.in_block += 1;
    }
    Ok(group)
}

/// Where the smoother's blocks start: at every segment start and after `rows` rows.
struct BlockStarts {
    rows: usize,
    /// Rows stepped since the last block start.
    in_block: usize,
}

impl BlockStarts {
    fn new(rows: usize) -> Self {
        BlockStarts { rows, in_block: 0 }
    }

    /// At a block start, whether it starts a segment (the row count restarts); `None`
    /// elsewhere.
    fn at(&mut self, pass: &ForwardPass<'_>) -> Option<bool> {
        let segment_start = pass.at_segment_start();
        (segment_start || self.in_block == self.rows).then(|| {
            self.in_block = 0;
            segment_start
        })
    }
}

/// The smoother's backward pass over the kept states, last first.
struct Backward {
    layout: crate::layout::StateLayout,
    store: SmootherStore,
    boundary: Option<crate::smoother::Boundary>,
    block: Vec<StepEstimate>,
    poll: CancelPoll,
}

impl Backward {
    /// Smooths the blocks that start at the states of `group` (consecutive, in row order),
    /// last first; `after` is the kept state that follows the group's last block, if any.
    fn smooth_group(
        &mut self,
        pass: &mut ForwardPass<'_>,
        group: &[Kept],
        after: Option<&Kept>,
        sink: &mut dyn RunSink,
    ) -> Result<(), FilterError> {
        for (i, (checkpoint, _)) in group.iter().enumerate().rev() {
            pass.restore(checkpoint)?;
            // Through the next block's first row, whose transition ends this block, unless
            // the next block starts a segment: then this block ends its segment.
            let next = group.get(i + 1).or(after);
            let through = next.and_then(|(c, starts)| (!starts).then_some(c.at.next));
            if next.is_none_or(|(_, starts)| *starts) {
                self.boundary = None;
            }
            self.store.clear();
            loop {
                if pass.at_segment_start() && !self.store.is_empty() {
                    break;
                }
                let Some(k) = pass.step()? else { break };
                self.poll.step(sink, k)?;
                pass.record_for_smoother(&mut self.store);
                if Some(k) == through {
                    break;
                }
            }
            self.block.clear();
            let block = &mut self.block;
            self.boundary = self.store.smooth_into(
                &self.layout,
                pass.prior,
                self.boundary.take(),
                &mut |e| block.push(e),
            )?;
            self.block.reverse();
            sink.smoothed(&self.block);
        }
        Ok(())
    }
}

/// Median spacing of consecutive rows, s, 1 with fewer than two rows (the diagnosis's
/// gap test; the gyro's own spacing is [`crate::segments::gyro_step_s`]).
pub fn nominal_step_s(tel: &Telemetry) -> f64 {
    crate::segments::median_spacing(tel.t_s.iter().copied()).unwrap_or(1.0)
}

/// The reported covariances scaled by the residuals' spread over the sensor noise
/// ([`Dispersion`]), when the configuration asks for it: each forward row by the spread of
/// the updates up to it (what a forward pass knows), the smoothed rows and the final
/// calibration and covariance by the whole run's. Applied before the ensemble adds its
/// spread: the factor measures the base's misfit.
struct ResidualScaling(Option<Dispersion>);

impl ResidualScaling {
    fn new(config: &FilterConfig, sigmas: SensorSigmas) -> Self {
        ResidualScaling(
            config
                .widen_by_residual_spread
                .then(|| Dispersion::new(sigmas.photodiode_v, sigmas.mag_nt)),
        )
    }

    fn widen(&mut self, e: &mut StepEstimate, records: &[ResidualRecord]) {
        if let Some(d) = self.0.as_mut() {
            records.iter().for_each(|r| d.push(r));
            e.scale_sigmas(d.report().sigma_factor);
        }
    }

    /// The factor of everything pushed so far (1 when off).
    fn factor(&self) -> f64 {
        self.0.as_ref().map_or(1.0, |d| d.report().sigma_factor)
    }

    fn widen_final(&self, run: &mut CalibrationRun) {
        if let Some(d) = self.0.as_ref() {
            let report = d.report();
            let k = report.sigma_factor;
            run.calibration.scale_sigmas(k);
            run.final_covariance *= k * k;
            run.dispersion = Some(report);
        }
    }
}
