//! Telemetry as a ground station gets it: a simulated 2-hour rax2-like set cut into passes,
//! its magnetometer and photodiodes in different rows, an attitude knocked off mid-run.
//! The run splits into segments, re-acquires the attitude in each, says when it is lost,
//! and recovers the simulated truth; the covariance stays symmetric positive definite at
//! every row.

use std::sync::OnceLock;

use nalgebra::{Cholesky, Vector3};
use pdcal_albedo::{AlbedoModel, MapChoice};
use pdcal_attitude::{Quat, mekf::error_vector, normal_from_az_el};
use pdcal_dataset::{DatasetMeta, Telemetry, TruthConstants, TruthSeries};
use pdcal_ephem::Reference;
use pdcal_filter::{
    Acquisition, Algebra, Calibration, FilterConfig, ForwardPass, Mode, Prepared, RunInputs,
    SegmentBreak, SegmentReport, StepEstimate, paper_model, step_references,
};
use pdcal_photodiode::Photodiode;

struct Fixture {
    meta: DatasetMeta,
    telemetry: Telemetry,
    references: Vec<Reference>,
    truth: TruthSeries,
    constants: TruthConstants,
    albedo: AlbedoModel,
}

fn fixture() -> &'static Fixture {
    static FIXTURE: OnceLock<Fixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let scenario = pdcal_sim::Scenario::rax2_like().unwrap();
        let sim = pdcal_sim::simulate(&scenario, 3).unwrap();
        let references = step_references(&sim.meta, &sim.telemetry).unwrap();
        Fixture {
            meta: sim.meta,
            telemetry: sim.telemetry,
            references,
            truth: sim.truth,
            constants: sim.constants,
            albedo: AlbedoModel::from_choice(&MapChoice::TomsMean1p25x1).unwrap(),
        }
    })
}

/// What a checked run returns.
struct Checked {
    calibration: Calibration,
    estimates: Vec<StepEstimate>,
    segments: Vec<SegmentReport>,
}

/// The forward filter over the rows `keep` of the fixture, asserting after every row that
/// the state is finite and the covariance symmetric with a Cholesky factor; `corrupt` may
/// change the pass after a row.
/// The rows of `telemetry` that `keep` keeps, with their references.
fn kept(telemetry: &Telemetry, keep: &dyn Fn(usize) -> bool) -> (Telemetry, Vec<Reference>) {
    let f = fixture();
    let references = (0..f.references.len())
        .filter(|&k| keep(k))
        .map(|k| f.references[k])
        .collect();
    (telemetry.select_rows(keep), references)
}

/// The fixture's run inputs over `telemetry` and its `references`.
fn inputs_of<'a>(telemetry: &'a Telemetry, references: &'a [Reference]) -> RunInputs<'a> {
    let f = fixture();
    RunInputs {
        meta: &f.meta,
        telemetry,
        references: references.into(),
        albedo: Some(&f.albedo),
        set_first_rows: &[],
    }
}

fn run_checked(
    telemetry: &Telemetry,
    keep: &dyn Fn(usize) -> bool,
    config: &FilterConfig,
    mut corrupt: impl FnMut(usize, &mut ForwardPass),
) -> Checked {
    let f = fixture();
    let (telemetry, references) = kept(telemetry, keep);
    let inputs = inputs_of(&telemetry, &references);
    let pds = f
        .meta
        .photodiodes
        .iter()
        .map(|m| Photodiode::from_az_el_deg(1.0, m.azimuth_deg, m.elevation_deg, 0.0))
        .collect();
    let model = paper_model(pds, config);
    let prepared = Prepared::of(&inputs, config).unwrap();
    let inputs = prepared.inputs(&inputs);
    let mut pass =
        ForwardPass::new(&inputs, &prepared, &Mode::Full, model, Algebra::Structured).unwrap();
    let mut estimates = Vec::new();
    while let Some(k) = pass.step().unwrap() {
        let e = pass.estimate();
        assert!(e.q.norm().is_finite() && e.attitude_sigma_deg.iter().all(|s| s.is_finite()));
        let p = pass.filter().covariance();
        assert!((p - p.transpose()).amax() <= 1e-12 * p.amax(), "row {k}");
        assert!(Cholesky::new(p.clone()).is_some(), "row {k}");
        estimates.push(e);
        corrupt(k, &mut pass);
    }
    let run_segments = pass.segments();
    Checked {
        calibration: pass.filter().calibration(None),
        estimates,
        segments: run_segments,
    }
}

fn forward_only() -> FilterConfig {
    FilterConfig {
        smoother: false,
        ..FilterConfig::default()
    }
}

/// Worst normal (deg) and scale (%) errors over all photodiodes.
fn worst_errors(calibration: &Calibration) -> (f64, f64) {
    let truth = &fixture().constants.photodiodes;
    let mut worst = (0.0f64, 0.0f64);
    for (t, e) in truth.iter().zip(&calibration.photodiodes) {
        let n = normal_from_az_el(t.azimuth_deg.to_radians(), t.elevation_deg.to_radians());
        worst.0 = worst.0.max(n.angle(&e.n_body()).to_degrees());
        worst.1 = worst
            .1
            .max(100.0 * ((e.scale_v - t.scale_v) / t.scale_v).abs());
    }
    worst
}

/// Every calibrated normal and scale within 3 sigma of the truth.
fn assert_within_3_sigma(truth: &TruthConstants, calibration: &Calibration) {
    for (t, e) in truth.photodiodes.iter().zip(&calibration.photodiodes) {
        let n = normal_from_az_el(t.azimuth_deg.to_radians(), t.elevation_deg.to_radians());
        let sigma_deg = e
            .elevation_sigma_deg
            .max(e.azimuth_sigma_deg.unwrap_or(0.0));
        assert!(
            n.angle(&e.n_body()).to_degrees() < 3.0 * sigma_deg,
            "{e:?} {t:?}"
        );
        assert!(
            (e.scale_v - t.scale_v).abs() < 3.0 * e.scale_sigma_v,
            "{e:?} {t:?}"
        );
    }
}

/// RMS attitude error (deg) over sunlit estimates at least `settle_s` after the first row
/// of their segment.
fn settled_attitude_rms_deg(estimates: &[StepEstimate], settle_s: f64) -> (f64, usize) {
    let truth = &fixture().truth;
    let mut start = (usize::MAX, 0.0);
    let (mut sum, mut n) = (0.0, 0);
    for e in estimates {
        if e.segment != start.0 {
            start = (e.segment, e.t_s);
        }
        let row = truth.t_s.binary_search_by(|t| t.total_cmp(&e.t_s)).unwrap();
        if truth.eclipse[row] < 0.999 || e.t_s - start.1 < settle_s {
            continue;
        }
        let q = truth.q[row];
        let q_true = Quat::new_normalized(q.x, q.y, q.z, q.w).unwrap();
        sum += error_vector(&q_true, &e.q).norm().to_degrees().powi(2);
        n += 1;
    }
    ((sum / n.max(1) as f64).sqrt(), n)
}

/// Keeps 10 minutes of every 20, starting 4 minutes in (the pass boundaries fall in sunlight
/// and in eclipse).
fn on_off(k: usize) -> bool {
    let t = fixture().telemetry.t_s[k];
    (t + 240.0).rem_euclid(1200.0) < 600.0
}

/// Without the magnetometer a pass in eclipse throughout says that the Sun is this run's
/// only vector, not what a run with a magnetometer would lack.
#[test]
fn a_sun_only_pass_in_eclipse_says_what_this_run_lacks() {
    let (telemetry, references) = kept(&fixture().telemetry, &on_off);
    let inputs = inputs_of(&telemetry, &references);
    let config = FilterConfig {
        ensemble: pdcal_filter::EnsembleRuns::Off,
        ..forward_only()
    };
    let run = pdcal_filter::calibrate(&inputs, &config, &Mode::PhotodiodeOnly).unwrap();
    let dark: Vec<&str> = run
        .segments
        .iter()
        .filter_map(|s| s.skipped.as_deref())
        .filter(|r| r.contains("in eclipse throughout"))
        .collect();
    assert_eq!(dark.len(), 3, "{:#?}", run.segments);
    for reason in dark {
        assert!(
            reason.ends_with("the Sun is the only vector of this run)"),
            "{reason}"
        );
    }
}

#[test]
fn passes_with_gaps_are_segments_each_reacquired() {
    let f = fixture();
    let run = run_checked(&f.telemetry, &on_off, &forward_only(), |_, _| {});
    let acquired: Vec<&SegmentReport> = run
        .segments
        .iter()
        .filter(|s| s.acquired_row.is_some())
        .collect();
    // Seven passes; three fall wholly in eclipse, where nothing can be acquired.
    assert_eq!(run.segments.len(), 7, "{:#?}", run.segments);
    assert_eq!(acquired.len(), 4, "{:#?}", run.segments);
    for s in &run.segments {
        assert!(s.lost.is_none(), "{s:#?}");
        match s.acquired_row {
            Some(_) => assert_eq!(s.acquisition, Acquisition::SunAndField),
            None => assert_eq!(
                s.skipped.as_deref(),
                Some(
                    "no sample in full Sun (in eclipse throughout: no photodiode to calibrate from, so no attitude is acquired from the magnetometer and gyro alone)"
                )
            ),
        }
        // Every segment but the last ends at a gap.
        assert!(matches!(s.ended_by, SegmentBreak::Gap | SegmentBreak::End));
    }
    let (normal_deg, scale_pct) = worst_errors(&run.calibration);
    assert!(
        normal_deg < 0.5 && scale_pct < 1.0,
        "{normal_deg} deg, {scale_pct} %"
    );
    let (rms_deg, n) = settled_attitude_rms_deg(&run.estimates, 60.0);
    assert!(n > 1000 && rms_deg < 1.0, "{rms_deg} deg over {n}");

    // The same rows without segments (the threshold beyond every gap): the attitude is
    // propagated blind across each gap and the calibration suffers.
    let mut blind = forward_only();
    blind.segments.gap_threshold_s = Some(pdcal_filter::config::MAX_WINDOW_S);
    blind.segments.gyro_hold_s = Some(pdcal_filter::config::MAX_WINDOW_S);
    blind.segments.lost_attitude_sigma_deg = 1e3;
    blind.segments.lost_gated_fraction = 1.0;
    let worse = run_checked(&f.telemetry, &on_off, &blind, |_, _| {});
    let (rms_blind, _) = settled_attitude_rms_deg(&worse.estimates, 60.0);
    assert!(
        rms_blind > 5.0 * rms_deg,
        "{rms_blind} against {rms_deg} deg"
    );
}

#[test]
fn irregular_rows_are_not_gaps() {
    let f = fixture();
    // Drop 2 rows of every 5 (gaps of up to 3 s): one segment.
    let keep = |k: usize| k % 5 != 1 && k % 5 != 3;
    let run = run_checked(&f.telemetry, &keep, &forward_only(), |_, _| {});
    assert_eq!(run.segments.len(), 1, "{:#?}", run.segments);
    let (normal_deg, scale_pct) = worst_errors(&run.calibration);
    assert!(
        normal_deg < 0.5 && scale_pct < 1.0,
        "{normal_deg} deg, {scale_pct} %"
    );
}

#[test]
fn magnetometer_in_other_rows_is_paired_with_the_gyro() {
    let f = fixture();
    // The magnetometer on odd rows only, the photodiodes on even rows only: never in one row.
    let mut split = f.telemetry.clone();
    for k in 0..split.len() {
        if k % 2 == 0 {
            split.mag_nt.as_mut().unwrap().set(k, None);
        } else {
            split.pd_v.iter_mut().for_each(|c| c.set(k, None));
        }
    }
    let run = run_checked(&split, &on_off, &forward_only(), |_, _| {});
    let paired: Vec<_> = run
        .segments
        .iter()
        .filter_map(|s| s.acquired_row.zip(s.paired_field_row))
        .collect();
    assert_eq!(paired.len(), 4, "{:#?}", run.segments);
    assert!(paired.iter().all(|(pd, mag)| pd % 2 == 0 && mag % 2 == 1));
    let (normal_deg, scale_pct) = worst_errors(&run.calibration);
    assert!(
        normal_deg < 0.5 && scale_pct < 1.0,
        "{normal_deg} deg, {scale_pct} %"
    );
    let (rms_deg, _) = settled_attitude_rms_deg(&run.estimates, 60.0);
    assert!(rms_deg < 1.0, "{rms_deg} deg");
}

#[test]
fn a_lost_attitude_is_said_and_reacquired() {
    let f = fixture();
    // Knock the attitude 90 degrees off with a confident covariance at row 3000 (sunlit,
    // past convergence): what a gyro glitch or a bad time tag does.
    let mut knocked = None;
    let run = run_checked(&f.telemetry, &|_| true, &forward_only(), |k, pass| {
        let sunlit = fixture().truth.eclipse[k] >= 0.999;
        if knocked.is_none() && k >= 3000 && sunlit {
            let q = pass.filter().q();
            let off =
                pdcal_attitude::mekf::apply_error(&q, &Vector3::new(0.0, 0.0, 90f64.to_radians()));
            let cov = nalgebra::Matrix3::identity() * 0.5f64.to_radians().powi(2);
            pass.filter_mut().reacquire(off, &cov, 0.0);
            knocked = Some(k);
        }
    });
    let knocked = knocked.unwrap();
    let lost: Vec<&SegmentReport> = run.segments.iter().filter(|s| s.lost.is_some()).collect();
    assert_eq!(lost.len(), 1, "{:#?}", run.segments);
    let lost_row = lost[0].last_row;
    assert!(
        lost_row > knocked && lost_row < knocked + 30,
        "knocked at {knocked}, lost at {lost_row}: {:#?}",
        lost[0]
    );
    assert!(lost[0].lost.as_ref().unwrap().contains("gated"));
    let next = run
        .segments
        .iter()
        .find(|s| s.first_row == lost_row + 1)
        .unwrap();
    assert!(next.acquired_row.is_some(), "{next:#?}");
    // Re-acquired, the attitude is right again and the calibration unharmed.
    let after: Vec<StepEstimate> = run
        .estimates
        .iter()
        .filter(|e| e.index > lost_row)
        .cloned()
        .collect();
    let (rms_deg, n) = settled_attitude_rms_deg(&after, 60.0);
    assert!(n > 500 && rms_deg < 1.0, "{rms_deg} deg over {n}");
    let (normal_deg, scale_pct) = worst_errors(&run.calibration);
    assert!(
        normal_deg < 0.5 && scale_pct < 1.0,
        "{normal_deg} deg, {scale_pct} %"
    );
}

#[test]
fn a_silent_gyro_ends_its_segment() {
    let f = fixture();
    // The gyro silent for a minute (rows 3000..3060) while the other sensors go on: beyond
    // the 10 s hold the attitude cannot be propagated.
    let mut silent = f.telemetry.clone();
    for k in 3000..3060 {
        silent.gyro_rad_s.set(k, None);
    }
    // The gyro-driven filter's rule (with the inertia and `dynamics: Auto` the dynamics
    // would carry the attitude through the silence instead).
    let gyro_driven = FilterConfig {
        dynamics: pdcal_filter::Dynamics::Off,
        ..forward_only()
    };
    let run = run_checked(&silent, &|_| true, &gyro_driven, |_, _| {});
    let ended: Vec<&SegmentReport> = run
        .segments
        .iter()
        .filter(|s| s.ended_by == SegmentBreak::GyroSilent)
        .collect();
    assert_eq!(ended.len(), 1, "{:#?}", run.segments);
    // Held for the 10 s hold (the last sample at row 2999), then a new segment.
    assert_eq!(ended[0].last_row, 3009, "{:#?}", ended[0]);
    let next = run.segments.iter().find(|s| s.first_row == 3010).unwrap();
    // Re-acquired once a gyro sample is within the hold again.
    assert!(next.acquired_row.unwrap() >= 3050, "{next:#?}");
    let (normal_deg, scale_pct) = worst_errors(&run.calibration);
    assert!(
        normal_deg < 0.5 && scale_pct < 1.0,
        "{normal_deg} deg, {scale_pct} %"
    );
}

#[test]
fn sparse_flight_frames_calibrate_honestly() {
    // Real CubeSat frames: a pass every 130 min with 1 to 15 frames 42 s apart, the
    // magnetometer sampled 2 s after the photodiodes in its own row; 12 hours.
    let mut scenario = pdcal_sim::Scenario::rax2_like().unwrap();
    scenario.duration_s = 12.0 * 3600.0;
    let sim = pdcal_sim::simulate(&scenario, 2).unwrap();
    let t = sim.telemetry.t_s.clone();
    let (pass_s, frame_s) = (7800.0, 42.0);
    let frames = |pass: usize| 1 + (pass * 7) % 15;
    let in_frame = |t: f64| {
        let pass = (t / pass_s).floor();
        let into = t - pass * pass_s;
        let frame = (into / frame_s).floor();
        let offset = into - frame * frame_s;
        ((frame as usize) < frames(pass as usize)).then_some(offset)
    };
    let keep = |k: usize| matches!(in_frame(t[k]), Some(o) if o == 0.0 || o == 2.0);
    let mut tel = sim.telemetry.select_rows(keep);
    for k in 0..tel.len() {
        if in_frame(tel.t_s[k]) == Some(0.0) {
            tel.mag_nt.as_mut().unwrap().set(k, None);
        } else {
            tel.pd_v.iter_mut().for_each(|c| c.set(k, None));
        }
    }
    let refs = step_references(&sim.meta, &tel).unwrap();
    let albedo = AlbedoModel::from_choice(&MapChoice::TomsMean1p25x1).unwrap();
    let inputs = RunInputs {
        meta: &sim.meta,
        telemetry: &tel,
        references: (&refs).into(),
        albedo: Some(&albedo),
        set_first_rows: &[],
    };
    let run = pdcal_filter::calibrate(&inputs, &FilterConfig::default(), &Mode::Full).unwrap();
    // The frames' rhythm is not a gap; the passes are.
    assert!(run.segment_rules.gap_threshold_s >= 400.0);
    // Six passes in 12 h, two of them in eclipse throughout: the other four acquired
    // (again after a lost attitude, if one is lost).
    let acquired = run
        .segments
        .iter()
        .filter(|s| s.acquired_row.is_some())
        .count();
    assert!(acquired >= 4, "{:#?}", run.segments);
    assert!(
        run.segments
            .iter()
            .all(|s| s.acquired_row.is_some() || s.skipped.is_some())
    );
    // Every acquisition paired the photodiode row with the magnetometer row after it.
    for s in run.segments.iter().filter(|s| s.acquired_row.is_some()) {
        assert_eq!(s.paired_field_row, s.acquired_row.map(|r| r + 1), "{s:#?}");
    }
    // Honest: every calibrated parameter within 3 sigma of the truth.
    assert_within_3_sigma(&sim.constants, &run.calibration);
    let pd: Vec<_> = run
        .residuals
        .iter()
        .filter(|r| matches!(r.sensor, pdcal_filter::Sensor::Photodiode(_)))
        .collect();
    let inside = pd
        .iter()
        .filter(|r| r.residual.abs() <= r.bound_3sigma)
        .count();
    assert!(
        inside as f64 >= 0.95 * pd.len() as f64,
        "{inside} of {}",
        pd.len()
    );
}

#[test]
fn irregular_random_cuts_and_blank_cells_stay_honest() {
    // Passes of random length (1 s to 10 min) after random gaps (0 to 25 min), and blank
    // cells scattered over every sensor: nothing may depend on the cut being regular.
    let f = fixture();
    let mut x: u64 = 0x5eed_0001;
    let mut uniform = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    let t = &f.telemetry.t_s;
    let mut kept = vec![false; t.len()];
    let mut at = 0.0;
    while at < 7200.0 {
        let on = 1.0 + uniform() * 600.0;
        for (k, keep) in kept.iter_mut().enumerate() {
            *keep |= t[k] >= at && t[k] < at + on;
        }
        at += on + uniform() * 1500.0;
    }
    let mut blanked = f.telemetry.clone();
    for k in 0..blanked.len() {
        if uniform() < 0.1 {
            blanked.gyro_rad_s.set(k, None);
        }
        if uniform() < 0.3 {
            blanked.mag_nt.as_mut().unwrap().set(k, None);
        }
        if uniform() < 0.05 {
            blanked.pd_v.iter_mut().for_each(|c| c.set(k, None));
        }
    }
    let run = run_checked(&blanked, &|k| kept[k], &forward_only(), |_, _| {});
    assert!(
        run.segments
            .iter()
            .filter(|s| s.acquired_row.is_some())
            .count()
            >= 2
    );
    assert_within_3_sigma(&f.constants, &run.calibration);
}
