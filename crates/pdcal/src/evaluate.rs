//! `pdcal evaluate`: reads a calibration's output files back and compares them with a
//! simulated data set's truth ([`pdcal_evaluate`], re-exported here), writing
//! `evaluation.json`.

use std::path::Path;

use anyhow::{Context, Result, bail};
use pdcal_attitude::Quat;
use pdcal_dataset::{TruthConstants, TruthSeries};
use pdcal_filter::{Calibration, PdCalibration, StepEstimate};

pub use pdcal_evaluate::*;

/// Reads `estimates.csv` back into step estimates (the columns of cli-contract.md).
pub fn read_estimates(path: &Path) -> Result<Vec<StepEstimate>> {
    let mut reader = csv::Reader::from_path(path)
        .with_context(|| format!("cannot read {}", pdcal_text::path(path)))?;
    let header = reader
        .headers()
        .with_context(|| format!("{}: cannot read the header row", pdcal_text::path(path)))?
        .clone();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .with_context(|| format!("{}: missing column {name}", pdcal_text::path(path)))
    };
    let m = (1..)
        .take_while(|i| header.iter().any(|h| h == format!("pd{i:02}_scale_V")))
        .count();
    let base: Vec<usize> = crate::rows::ESTIMATE_LEADING_COLUMNS
        .iter()
        .map(|n| col(n))
        .collect::<Result<_>>()?;
    let bias: Vec<usize> = ["x", "y", "z"]
        .iter()
        .map(|a| col(&format!("gyro_bias_{a}_rad_s")))
        .collect::<Result<_>>()?;
    let bias_sigma: Vec<usize> = ["x", "y", "z"]
        .iter()
        .map(|a| col(&format!("gyro_bias_sigma_{a}_rad_s")))
        .collect::<Result<_>>()?;
    let pd_cols: Vec<[usize; 6]> = (1..=m)
        .map(|i| {
            let c = |q: &str| col(&format!("pd{i:02}_{q}"));
            Ok([
                c("scale_V")?,
                c("scale_sigma_V")?,
                c("azimuth_deg")?,
                c("azimuth_sigma_deg")?,
                c("elevation_deg")?,
                c("elevation_sigma_deg")?,
            ])
        })
        .collect::<Result<_>>()?;
    // Files written before segments existed have no `segment` column: one segment.
    let segment_col = header.iter().position(|h| h == "segment");
    // Files written before the attitude covariance was whole have no off-diagonal columns.
    let cov_cols: Vec<Option<usize>> = crate::rows::ATTITUDE_COV_COLUMNS
        .iter()
        .map(|n| header.iter().position(|h| h == *n))
        .collect();
    let mut out = Vec::new();
    for (line, record) in reader.records().enumerate() {
        let record = record.with_context(|| format!("{}:{}", pdcal_text::path(path), line + 2))?;
        let num = |c: usize| -> Result<f64> {
            let text = record.get(c).unwrap_or("");
            text.parse::<f64>().map_err(|_| {
                anyhow::anyhow!(
                    "{}:{}:{} ({}): {} is not a number",
                    pdcal_text::path(path),
                    line + 2,
                    c + 1,
                    header.get(c).unwrap_or("?"),
                    pdcal_text::quote(text)
                )
            })
        };
        let opt = |c: usize| {
            record
                .get(c)
                .filter(|s| !s.is_empty())
                .and_then(|s| s.parse::<f64>().ok())
        };
        let q = [num(base[1])?, num(base[2])?, num(base[3])?, num(base[4])?];
        let q = Quat::new_normalized(q[0], q[1], q[2], q[3]).with_context(|| {
            format!(
                "{}:{} (q_x, q_y, q_z, q_w): {} is not a quaternion",
                pdcal_text::path(path),
                line + 2,
                quaternion_fault(&q)
            )
        })?;
        let photodiodes = pd_cols
            .iter()
            .map(|c| {
                Ok(PdCalibration {
                    scale_v: num(c[0])?,
                    scale_sigma_v: num(c[1])?,
                    azimuth_deg: num(c[2])?,
                    azimuth_sigma_deg: opt(c[3]),
                    elevation_deg: num(c[4])?,
                    elevation_sigma_deg: num(c[5])?,
                })
            })
            .collect::<Result<_>>()?;
        let segment = match segment_col {
            Some(c) => {
                let text = record.get(c).unwrap_or("");
                text.parse::<usize>().map_err(|_| {
                    anyhow::anyhow!(
                        "{}:{}:{} (segment): {} is not a segment number",
                        pdcal_text::path(path),
                        line + 2,
                        c + 1,
                        pdcal_text::quote(text)
                    )
                })?
            }
            None => 0,
        };
        out.push(StepEstimate {
            index: line,
            t_s: num(base[0])?,
            segment,
            q,
            attitude_sigma_deg: [num(base[5])?, num(base[6])?, num(base[7])?],
            attitude_cov_offdiag_deg2: [0, 1, 2].map(|k| {
                cov_cols[k]
                    .and_then(|c| record.get(c))
                    .and_then(|t| t.parse::<f64>().ok())
                    .unwrap_or(f64::NAN)
            }),
            calibration: Calibration {
                format_version: pdcal_filter::calibration::CALIBRATION_FORMAT_VERSION,
                photodiodes,
                gyro_bias_rad_s: [num(bias[0])?, num(bias[1])?, num(bias[2])?],
                gyro_bias_sigma_rad_s: [
                    num(bias_sigma[0])?,
                    num(bias_sigma[1])?,
                    num(bias_sigma[2])?,
                ],
                parameters: Vec::new(),
                status: Vec::new(),
            },
        });
    }
    Ok(out)
}

/// `pdcal evaluate DATASET_DIR OUT_DIR`: reads the calibration outputs and the truth, writes
/// `OUT_DIR/evaluation.json`.
pub fn run_dir(dataset: &Path, out: &Path) -> Result<Evaluation> {
    let meta = pdcal_dataset::read_meta(dataset)?;
    check_same_data(dataset, &meta, out)?;
    let Some((truth, constants)) = pdcal_dataset::read_truth(dataset, &meta)? else {
        bail!(
            "{}: evaluate needs truth.csv and truth.ron (a simulated dataset)",
            pdcal_text::path(dataset)
        );
    };
    let evaluation = evaluate_output(&truth, &constants, out)?;
    crate::output::add_file(
        out,
        "evaluation.json",
        serde_json::to_string_pretty(&evaluation)?.as_bytes(),
    )?;
    Ok(evaluation)
}

/// Refuses a data set the calibration in `out` was not made from: its summary.json lists
/// every set it read (name, epoch, rows), and another set's truth, even of the same layout,
/// describes other times (its attitude errors would be meaningless). An output without
/// summary.json (written by hand or by an older pdcal) is not judged.
fn check_same_data(dataset: &Path, meta: &pdcal_dataset::DatasetMeta, out: &Path) -> Result<()> {
    let path = out.join("summary.json");
    let Ok(bytes) = std::fs::read(&path) else {
        return Ok(());
    };
    let summary: serde_json::Value = serde_json::from_slice(&bytes).with_context(|| {
        format!(
            "{}: not the summary.json of pdcal calibrate",
            path.display()
        )
    })?;
    // One set: the summary's own name and epoch; several: each set's.
    let sets: Vec<serde_json::Value> = match summary["datasets"].as_array() {
        Some(sets) => sets.clone(),
        None if summary["epoch_utc"].is_string() => vec![serde_json::json!({
            "name": summary["dataset"],
            "epoch_utc": summary["epoch_utc"],
        })],
        None => return Ok(()),
    };
    let epoch = meta.epoch_utc.epoch();
    let same = |set: &serde_json::Value| {
        set["name"].as_str() == Some(meta.name.as_str())
            && set["epoch_utc"]
                .as_str()
                .and_then(|e| pdcal_dataset::EpochUtc::parse(e).ok())
                .is_some_and(|e| e.epoch() == epoch)
    };
    if sets.is_empty() || sets.iter().any(same) {
        return Ok(());
    }
    let made_from: Vec<String> = (sets.iter())
        .map(|set| {
            format!(
                "{} (epoch {})",
                pdcal_text::quote(set["name"].as_str().unwrap_or("?")),
                pdcal_text::clip(set["epoch_utc"].as_str().unwrap_or("?"))
            )
        })
        .collect();
    bail!(
        "{}: the calibration in {} was made from {}, not from this data set {} (epoch {}): another data set's truth describes other times, so its errors would be meaningless; evaluate against the data set the calibration read",
        dataset.display(),
        out.display(),
        made_from.join(", "),
        pdcal_text::quote(&meta.name),
        meta.epoch_utc.as_str()
    )
}

/// [`evaluate`] of the calibration outputs in `out` (`calibration.ron`, `estimates.csv`,
/// and `estimates_smoothed.csv` when there is one) against a dataset's truth, writing
/// nothing.
pub fn evaluate_output(
    truth: &TruthSeries,
    constants: &TruthConstants,
    out: &Path,
) -> Result<Evaluation> {
    let cal_path = out.join("calibration.ron");
    let text = std::fs::read_to_string(&cal_path)
        .with_context(|| format!("cannot read {}", pdcal_text::path(&cal_path)))?;
    let final_cal = Calibration::from_ron_str(&text)
        .with_context(|| pdcal_text::path(&cal_path).to_string())?;
    let estimates = read_estimates(&out.join("estimates.csv"))?;
    let smoothed_path = out.join("estimates_smoothed.csv");
    let smoothed = match smoothed_path.exists() {
        true => Some(read_estimates(&smoothed_path)?),
        false => None,
    };
    evaluate_with_smoothed(
        &estimates,
        smoothed.as_deref(),
        &final_cal,
        truth,
        constants,
    )
}
