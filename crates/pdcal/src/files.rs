//! The output files of `docs/cli-contract.md`: summary.json, calibration.ron, estimates.csv,
//! residuals.csv, the figures and index.html, written whole or not at all. Their content
//! comes from [`crate::schema`] (summary.json) and [`crate::rows`] (the CSVs), both
//! re-exported here.

use anyhow::Result;
use pdcal_dataset::{DatasetMeta, Telemetry};

use crate::output::{OutputDir, write_file};

pub use crate::rows::{
    ESTIMATE_LEADING_COLUMNS, RESIDUAL_COLUMNS, estimate_header, estimate_row, estimates_csv,
    residual_row, residuals_csv, sensor_name,
};
pub use crate::schema::*;

/// Writes every output of a calibration into `dir` (created before the computation) and
/// publishes it in one step; with `evaluation` (the default run), also `evaluation.json` and
/// its rows in index.html.
pub fn write_calibration_outputs(
    dir: OutputDir,
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    outcome: &Outcome,
    evaluation: Option<&crate::evaluate::Evaluation>,
) -> Result<()> {
    let m = meta.photodiodes.len();
    write_file(
        &dir.file("estimates.csv"),
        &estimates_csv(&outcome.run.forward, m)?,
    )?;
    if let Some(smoothed) = &outcome.run.smoothed {
        write_file(
            &dir.file("estimates_smoothed.csv"),
            &estimates_csv(smoothed, m)?,
        )?;
    }
    write_file(
        &dir.file("residuals.csv"),
        &residuals_csv(&outcome.run.residuals)?,
    )?;
    let summary = summary(meta, outcome);
    write_summary_and_figures(dir, telemetry, outcome, &summary, evaluation)
}

/// Writes summary.json, calibration.ron, the figures and index.html into `dir` (which holds
/// the CSVs already) and publishes it; with `evaluation` (the default run), also
/// `evaluation.json` and its rows in index.html.
pub fn write_summary_and_figures(
    dir: OutputDir,
    telemetry: &Telemetry,
    outcome: &Outcome,
    summary: &Summary,
    evaluation: Option<&crate::evaluate::Evaluation>,
) -> Result<()> {
    write_file(
        &dir.file("summary.json"),
        serde_json::to_string_pretty(summary)?.as_bytes(),
    )?;
    write_file(
        &dir.file("calibration.ron"),
        summary.reported.to_ron_string()?.as_bytes(),
    )?;
    let figures = crate::figures::calibration_figures(dir.path(), telemetry, outcome)?;
    let rows = evaluation.map(crate::evaluate::index_rows);
    if let Some(e) = evaluation {
        write_file(
            &dir.file("evaluation.json"),
            serde_json::to_string_pretty(e)?.as_bytes(),
        )?;
    }
    crate::figures::write_index(dir.path(), summary, rows.as_deref(), &figures)?;
    // A photodiode column kept in a file that could not be read or written read as blank:
    // nothing computed from it is published.
    if let Some(e) = telemetry.storage_error() {
        anyhow::bail!("{e}");
    }
    dir.commit()
}
