//! `pdcal` with no arguments: simulate the RAX-2-like scenario, calibrate it, evaluate it
//! against truth and print a short report.

use std::path::Path;

use anyhow::Result;

use crate::evaluate::Evaluation;
use crate::files::Summary;

/// The seed of the embedded default run.
pub const DEFAULT_SEED: u64 = 1;

/// Runs the default into `root` (`dataset/` and `calibration/` below it).
pub fn run(root: &Path) -> Result<()> {
    let scenario = pdcal_sim::Scenario::rax2_like()?;
    let dataset = root.join("dataset");
    let out = root.join("calibration");
    crate::simulate::run_to_dir(&scenario, DEFAULT_SEED, &dataset)?;
    let outcome =
        crate::calibrate::run_dir(&dataset, &out, &crate::calibrate::RunConfig::default())?;
    let evaluation = crate::evaluate::run_dir(&dataset, &out)?;
    let meta = pdcal_dataset::read_meta(&dataset)?;
    let summary = crate::files::summary(&meta, &outcome);
    let rows = crate::evaluate::index_rows(&evaluation);
    crate::figures::write_index(&out, &summary, Some(&rows), &index_figures(&out))?;
    print!("{}", report(&summary, &evaluation, &out));
    Ok(())
}

/// The figures already in `out` (calibrate wrote them), in name order.
fn index_figures(out: &Path) -> Vec<(String, String)> {
    let mut stems: Vec<String> = std::fs::read_dir(out)
        .into_iter()
        .flatten()
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            e.file_name()
                .to_str()
                .and_then(|n| n.strip_suffix(".png"))
                .map(String::from)
        })
        .collect();
    stems.sort();
    stems
        .into_iter()
        .map(|s| (s.replace('_', " "), s))
        .collect()
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
    let _ = writeln!(s, "  outputs                {}/index.html", out.display());
    s
}
