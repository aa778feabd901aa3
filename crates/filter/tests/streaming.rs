//! The streaming run (per-row results through a sink, smoother by segments recomputed from
//! kept forward states) gives the in-memory run's numbers bit for bit.

mod common;

use common::Case;
use pdcal_filter::{
    Algebra, FilterConfig, Mode, ResidualRecord, RunInputs, RunSink, StepEstimate,
    calibrate_streaming, calibrate_with_model, paper_model,
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
    let inputs = RunInputs {
        meta: &meta,
        telemetry: &tel,
        references: (&refs).into(),
        albedo: None,
    };
    let config = FilterConfig::default();
    let model = || {
        let pds = meta
            .photodiodes
            .iter()
            .map(|m| Photodiode::from_az_el_deg(1.0, m.azimuth_deg, m.elevation_deg, 0.0))
            .collect();
        paper_model(pds, &config)
    };
    let memory =
        calibrate_with_model(&inputs, &config, &Mode::Full, model(), Algebra::Structured).unwrap();
    assert!(memory.start_index >= 40);
    let smoothed = memory.smoothed.as_ref().unwrap();
    // Segments of 1 row, an uneven split and one segment for the whole run.
    for segment_rows in [1, 97, 5000] {
        let mut sink = Collect::default();
        let streamed = calibrate_streaming(
            &inputs,
            &config,
            &Mode::Full,
            model(),
            Algebra::Structured,
            segment_rows,
            &mut sink,
        )
        .unwrap();
        assert_eq!(sink.forward, memory.forward, "segment {segment_rows}");
        assert_eq!(sink.residuals, memory.residuals, "segment {segment_rows}");
        assert_eq!(streamed.calibration, memory.calibration);
        assert_eq!(streamed.final_covariance, memory.final_covariance);
        assert_eq!(streamed.counts, memory.counts);
        assert_eq!(streamed.rejections, memory.rejections);
        // Segments arrive last first, each in row order.
        let joined: Vec<StepEstimate> = sink.segments.iter().rev().flatten().cloned().collect();
        assert_eq!(&joined, smoothed, "segment {segment_rows}");
        assert!(sink.segments.iter().all(|s| s.len() <= segment_rows + 1));
    }
}
