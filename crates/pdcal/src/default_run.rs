//! `pdcal` with no arguments: simulate the RAX-2-like scenario, calibrate it, evaluate it
//! against truth and print a short report.

use std::path::Path;

use anyhow::{Context, Result};

use crate::evaluate::Evaluation;
use crate::files::Summary;
use crate::output::OutputDir;

/// The seed of the embedded default run.
pub const DEFAULT_SEED: u64 = 1;

/// Runs the default into `root` (`dataset/` and `calibration/` below it): both output
/// directories are checked and locked first, the evaluation is written with the calibration
/// in one publication.
pub fn run(root: &Path) -> Result<()> {
    let scenario = pdcal_sim::Scenario::rax2_like()?;
    let dataset = root.join("dataset");
    let out = root.join("calibration");
    let dir = OutputDir::create(&out, "default")?;
    let sim = crate::simulate::run_to_dir(&scenario, DEFAULT_SEED, &dataset)?;
    let albedo = crate::calibrate::albedo_model()?;
    let outcome = crate::calibrate::run(
        &sim.meta,
        &sim.telemetry,
        &crate::calibrate::RunConfig::default(),
        &albedo,
    )?;
    let ds = sim.to_dataset();
    let (truth, constants) = ds.truth.as_ref().context("the simulator wrote no truth")?;
    let evaluation = crate::evaluate::evaluate(
        &outcome.run.forward,
        &outcome.run.calibration,
        truth,
        constants,
    )?;
    let summary = crate::files::summary(&sim.meta, &outcome);
    crate::files::write_calibration_outputs(
        dir,
        &sim.meta,
        &sim.telemetry,
        &outcome,
        Some(&evaluation),
    )?;
    print!("{}", report(&summary, &evaluation, &out));
    Ok(())
}

/// The short text report of the default run.
pub fn report(summary: &Summary, evaluation: &Evaluation, out: &Path) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let sv = &summary.sun_vector_magnitude;
    let _ = writeln!(
        s,
        "pdcal: {} ({} photodiodes)",
        summary.dataset,
        summary.photodiodes.len()
    );
    let _ = writeln!(
        s,
        "  sun-vector magnitude   initial {:.3} +- {:.3}   calibrated {:.3} +- {:.3}   (paper: 0.925 +- 0.029 -> 0.993 +- 0.022)",
        sv.initial.mean, sv.initial.std, sv.calibrated.mean, sv.calibrated.std
    );
    let _ = writeln!(
        s,
        "  sun-direction change   mean {:.1} deg (paper: 9.1 deg)",
        summary.sun_direction_change_deg.mean
    );
    let _ = writeln!(
        s,
        "  residuals              RMS {:.4} V, {:.1} % inside 3-sigma",
        summary.residuals.photodiode_rms_V,
        100.0 * summary.residuals.fraction_within_3sigma
    );
    let _ = writeln!(
        s,
        "  true errors            worst normal {:.2} deg, worst scale {:.2} %, attitude RMS {:.2} deg",
        evaluation.worst_normal_error_deg,
        evaluation.worst_scale_error_percent,
        evaluation.attitude.rms_deg
    );
    let _ = writeln!(
        s,
        "  consistency            {:.1} % of final states and {:.1} % of attitude errors inside 3-sigma",
        100.0 * evaluation.consistency.final_states_within_3sigma,
        100.0 * evaluation.consistency.attitude_within_3sigma
    );
    let _ = writeln!(s, "  filter run time        {:.2} s", summary.runtime_s);
    let _ = writeln!(
        s,
        "  outputs                {}/index.html",
        pdcal_text::path(out)
    );
    s
}
