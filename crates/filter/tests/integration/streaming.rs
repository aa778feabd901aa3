//! The streaming run (per-row results through a sink, smoother by blocks recomputed from
//! kept forward states, every block start kept or only some and the others regenerated)
//! gives the in-memory run's numbers bit for bit, with and without gaps in the telemetry,
//! with the magnetometer and with the Sun alone (where the smoother leaves the rows whose
//! attitude is beyond its linear range as the forward pass has them).

use crate::common;

use common::Case;
use pdcal_filter::{
    Algebra, FilterConfig, Mode, Prepared, ResidualRecord, RunInputs, RunSink, StepEstimate,
    calibrate_streaming, calibrate_streaming_kept, calibrate_with_model, paper_model,
};
use pdcal_photodiode::Photodiode;

#[derive(Default)]
struct Collect {
    forward: Vec<StepEstimate>,
    residuals: Vec<ResidualRecord>,
    segments: Vec<Vec<StepEstimate>>,
}

impl RunSink for Collect {
    fn forward(&mut self, estimate: &StepEstimate, residuals: &[ResidualRecord]) {
        self.forward.push(estimate.clone());
        self.residuals.extend_from_slice(residuals);
    }
    fn smoothed(&mut self, segment: &[StepEstimate]) {
        self.segments.push(segment.to_vec());
    }
}

#[test]
fn streaming_equals_in_memory_bit_for_bit() {
    let mut case = Case::rax2(11, 1300);
    // Starts in eclipse: the run's first row is not the data's.
    case.eclipse = 0..40;
    let (meta, tel, refs, _) = case.build();
    let memory = compare(&meta, &tel, &refs, &Mode::Full, FilterConfig::default());
    assert!(memory.start_index >= 40);
    // The residuals' spread scaled what was reported, the same in both.
    assert!(memory.dispersion.unwrap().sigma_factor > 1.0);
}

/// With the Sun alone and no albedo the rotation about the Sun line is never observed
/// (sigmas of a hundred degrees and more): every such row keeps its forward estimate, row
/// for row, in memory and streaming alike. (The sigmas the filter's own: scaled by the
/// residuals' spread, a forward row takes the factor of the updates up to it and its
/// smoothed row the whole run's.)
#[test]
fn streaming_equals_in_memory_with_the_sun_alone() {
    let (meta, tel, refs, _) = Case::rax2(11, 1300).build();
    let config = FilterConfig {
        widen_by_residual_spread: false,
        ..FilterConfig::default()
    };
    let memory = compare(&meta, &tel, &refs, &Mode::PhotodiodeOnly, config);
    let smoothed = memory.smoothed.as_ref().unwrap();
    let whole_sigma_deg = |e: &StepEstimate| {
        e.attitude_cov_deg2()
            .symmetric_eigenvalues()
            .max()
            .max(0.0)
            .sqrt()
    };
    // Far beyond any loss bound (20 deg, or the acquisition's sigma across the Sun line).
    let wide = |k: usize| whole_sigma_deg(&memory.forward[k]) > 90.0;
    let mut kept = 0;
    for k in 0..smoothed.len() {
        if wide(k) && (k + 1 == smoothed.len() || wide(k + 1)) {
            assert_eq!(smoothed[k], memory.forward[k], "row {k}");
            kept += 1;
        }
    }
    assert!(kept > 1000, "{kept} of {} rows", smoothed.len());
}

#[test]
fn streaming_equals_in_memory_across_gaps() {
    let case = Case::rax2(12, 1300);
    let (meta, tel, refs, _) = case.build();
    // Two downlink gaps (200 s and 100 s, beyond the 10 s threshold): three segments,
    // the smoother's blocks ending at each.
    let keep = |k: usize| !(300..500).contains(&k) && !(800..900).contains(&k);
    let cut = tel.select_rows(keep);
    let refs: Vec<_> = refs
        .iter()
        .enumerate()
        .filter(|(k, _)| keep(*k))
        .map(|(_, r)| *r)
        .collect();
    let memory = compare(&meta, &cut, &refs, &Mode::Full, FilterConfig::default());
    assert_eq!(memory.segments.len(), 3, "{:#?}", memory.segments);
    let smoothed = memory.smoothed.as_ref().unwrap();
    for (f, s) in memory.forward.iter().zip(smoothed) {
        assert_eq!((f.index, f.segment), (s.index, s.segment));
    }
}

/// Runs in memory and streaming with blocks of 1 row, an uneven split and one block for
/// the whole run; asserts the same numbers bit for bit; returns the in-memory run.
fn compare(
    meta: &pdcal_dataset::DatasetMeta,
    tel: &pdcal_dataset::Telemetry,
    refs: &[pdcal_ephem::Reference],
    mode: &Mode,
    config: FilterConfig,
) -> pdcal_filter::CalibrationRun {
    let inputs = RunInputs {
        meta,
        telemetry: tel,
        references: refs.into(),
        albedo: None,
        set_first_rows: &[],
    };
    let model = || {
        let pds = meta
            .photodiodes
            .iter()
            .map(|m| Photodiode::from_az_el_deg(1.0, m.azimuth_deg, m.elevation_deg, 0.0))
            .collect();
        paper_model(pds, &config)
    };
    let prepared = Prepared::of(&inputs, &config).unwrap();
    let inputs = prepared.inputs(&inputs);
    let memory =
        calibrate_with_model(&inputs, &prepared, mode, model(), Algebra::Structured).unwrap();
    let smoothed = memory.smoothed.as_ref().unwrap();
    assert_eq!(smoothed.len(), memory.forward.len());
    // Every block start kept (what sets of up to a million rows get), and sparser: every
    // 3rd or 7th, the others regenerated going backward (what longer sets get).
    for (block_rows, every) in [(1, 1), (97, 1), (5000, 1), (97, 3), (1, 7), (250, 2)] {
        let mut sink = Collect::default();
        let streamed = calibrate_streaming_kept(
            &inputs,
            &prepared,
            mode,
            (model(), None),
            Algebra::Structured,
            block_rows,
            every,
            &mut sink,
        )
        .unwrap();
        assert_eq!(
            sink.forward, memory.forward,
            "blocks of {block_rows}, every {every}"
        );
        assert_eq!(
            sink.residuals, memory.residuals,
            "blocks of {block_rows}, every {every}"
        );
        assert_eq!(streamed.calibration, memory.calibration);
        assert_eq!(streamed.final_covariance, memory.final_covariance);
        assert_eq!(streamed.counts, memory.counts);
        assert_eq!(streamed.rejections, memory.rejections);
        assert_eq!(streamed.segments, memory.segments);
        assert_eq!(streamed.dispersion, memory.dispersion);
        // Blocks arrive last first, each in row order.
        let joined: Vec<StepEstimate> = sink.segments.iter().rev().flatten().cloned().collect();
        assert_eq!(&joined, smoothed, "blocks of {block_rows}, every {every}");
        assert!(sink.segments.iter().all(|s| s.len() <= block_rows + 1));
    }
    memory
}

/// A sink that asks to stop at its `stop_at`-th poll, counting the polls and the forward
/// and smoothed rows it received.
struct StopAfter {
    stop_at: usize,
    polls: usize,
    forward_rows: usize,
    smoothed_rows: usize,
}

impl RunSink for StopAfter {
    fn forward(&mut self, _: &StepEstimate, _: &[ResidualRecord]) {
        self.forward_rows += 1;
    }
    fn smoothed(&mut self, segment: &[StepEstimate]) {
        self.smoothed_rows += segment.len();
    }
    fn cancelled(&mut self) -> bool {
        self.polls += 1;
        self.polls >= self.stop_at
    }
}

/// A sink that asks to stop ends the run with `Cancelled` within one poll interval, in the
/// forward pass and in the smoother's replays; one that never asks sees the whole run.
#[test]
fn a_sink_can_cancel_the_forward_pass_and_the_smoother() {
    let case = Case::rax2(13, 1300);
    let (meta, tel, refs, _) = case.build();
    let config = FilterConfig::default();
    let run = |stop_at: usize| {
        let mut sink = StopAfter {
            stop_at,
            polls: 0,
            forward_rows: 0,
            smoothed_rows: 0,
        };
        let inputs = RunInputs {
            meta: &meta,
            telemetry: &tel,
            references: (&refs).into(),
            albedo: None,
            set_first_rows: &[],
        };
        let model = paper_model(pdcal_filter::nominal_photodiodes(&meta), &config);
        let prepared = Prepared::of(&inputs, &config).unwrap();
        let result = calibrate_streaming(
            &prepared.inputs(&inputs),
            &prepared,
            &Mode::Full,
            (model, None),
            Algebra::Structured,
            pdcal_filter::SMOOTHER_BLOCK_ROWS,
            &mut sink,
        );
        (result, sink)
    };
    let (whole, sink) = run(usize::MAX);
    assert!(whole.is_ok());
    let rows = sink.forward_rows;
    assert!(rows > 3 * pdcal_filter::CANCEL_POLL_ROWS, "{rows} rows");
    assert!(sink.smoothed_rows >= rows);
    let forward_polls = rows / pdcal_filter::CANCEL_POLL_ROWS;
    // At the first poll: in the forward pass, after one interval of rows.
    let (first, sink) = run(1);
    assert!(matches!(
        first,
        Err(pdcal_filter::FilterError::Cancelled { .. })
    ));
    assert_eq!(sink.forward_rows, pdcal_filter::CANCEL_POLL_ROWS - 1);
    assert_eq!(sink.smoothed_rows, 0);
    // After the forward pass: in the smoother's replay, with the forward rows all out.
    let (late, sink) = run(forward_polls + 1);
    assert!(matches!(
        late,
        Err(pdcal_filter::FilterError::Cancelled { .. })
    ));
    assert_eq!(sink.forward_rows, rows);
    assert!(sink.smoothed_rows < rows, "{} smoothed", sink.smoothed_rows);
}
