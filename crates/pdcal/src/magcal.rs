//! `pdcal magcal DATASET --out OUT`: the attitude-independent magnetometer calibration of
//! `pdcal-magcal` (docs/magcal.md) on a dataset, written as magcal.ron, magcal.json, the
//! corrected dataset `OUT/dataset/`, figures and index.html, whole or not at all; and the
//! reading and application of a magcal.ron for `pdcal calibrate --mag-cal`.

use std::path::Path;

use anyhow::{Context, Result, bail};
use nalgebra::{DMatrix, Matrix3, Vector3};
use pdcal_dataset::{DatasetMeta, RonFaultKind, Telemetry};
use pdcal_magcal::{MagCalConfig, MagCalibration, MatrixForm, Sample};
use pdcal_report::{Figure, LineAxes, Mark, Series, lines};
use serde::{Deserialize, Serialize};

use crate::output::{OutputDir, write_file};

/// What magcal.ron says its numbers mean.
pub const CONVENTION: &str = "m = T B + b + sum_j c_j u_j + noise (sensor axes, nT; u_j the \
cur_<name>_A columns, A); corrected B = T^-1 (m - b - sum_j c_j u_j); T symmetric (the polar \
factor (T T^T)^(1/2)): the field magnitude does not determine the sensor's rotation";

/// How many rejected rows magcal.json lists; rejected_rows.csv has every one.
pub const REJECTED_ROWS_LISTED: usize = 50;

/// magcal.ron: the parameters in their convention, the covariance, the regressors.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MagCalFile {
    /// [`CONVENTION`].
    pub convention: String,
    /// The form of `T` the data determined.
    pub matrix_form: MatrixForm,
    /// `T` by rows.
    pub matrix: [[f64; 3]; 3],
    /// `b`, nT (file name `bias_nT`).
    #[serde(rename = "bias_nT")]
    pub bias_nt: [f64; 3],
    /// `c_j` of each kept regressor by column name, nT/A (file name
    /// `current_bias_nT_per_A`).
    #[serde(rename = "current_bias_nT_per_A")]
    pub current_bias_nt_per_a: Vec<(String, [f64; 3])>,
    /// Names of the covariance's rows and columns.
    pub parameters: Vec<String>,
    /// Covariance of `parameters` (from the Fisher information).
    pub covariance: Vec<Vec<f64>>,
    /// The per-axis magnetometer noise the residuals imply, nT (file name `noise_sigma_nT`).
    #[serde(rename = "noise_sigma_nT")]
    pub noise_sigma_nt: f64,
    /// Every regressor tested: kept or dropped, its score and the reason.
    pub regressors: Vec<RegressorRecord>,
}

/// One tested regressor, as magcal.ron and magcal.json give it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegressorRecord {
    /// The telemetry column.
    pub name: String,
    /// Kept in the model.
    pub kept: bool,
    /// Its score, nats (`W/2 - 3 ln(N)/2`), when it was fitted.
    pub score_nats: Option<f64>,
    /// Why it was kept or dropped.
    pub reason: String,
}

/// magcal.json.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MagCalSummary {
    /// `b`, nT.
    #[serde(rename = "bias_nT")]
    pub bias_nt: [f64; 3],
    /// One sigma of `b`, nT.
    #[serde(rename = "bias_sigma_nT")]
    pub bias_sigma_nt: [f64; 3],
    /// `T` by rows.
    pub matrix: [[f64; 3]; 3],
    /// One sigma of each entry of `T` (0 where the form fixes it).
    pub matrix_sigma: [[f64; 3]; 3],
    /// The form of `T`.
    pub matrix_form: MatrixForm,
    /// `c_j` by column name, nT/A.
    #[serde(rename = "current_bias_nT_per_A")]
    pub current_bias_nt_per_a: std::collections::BTreeMap<String, [f64; 3]>,
    /// One sigma of each `c_j`, nT/A.
    #[serde(rename = "current_bias_sigma_nT_per_A")]
    pub current_bias_sigma_nt_per_a: std::collections::BTreeMap<String, [f64; 3]>,
    /// RMS of `|m| - |H|` (before, every row used) and `|B| - |H|` (after, the rows kept), nT.
    #[serde(rename = "residual_rms_nT")]
    pub residual_rms_nt: RmsPair,
    /// The noise the residuals imply, nT per axis.
    #[serde(rename = "noise_sigma_nT")]
    pub noise_sigma_nt: f64,
    /// Rows with a full magnetometer sample and every regressor.
    pub rows_usable: usize,
    /// Rows the fit used.
    pub rows_used: usize,
    /// Rows rejected by the outlier gate.
    pub rows_rejected: usize,
    /// The first [`REJECTED_ROWS_LISTED`] of their 0-based telemetry rows (all of them in
    /// `rejected_rows.csv`).
    pub rejected_rows: Vec<usize>,
    /// `rejected_rows` holds fewer than `rows_rejected`.
    pub rejected_rows_truncated: bool,
    /// The first [`REJECTED_ROWS_LISTED`] rows screened out before the fit (a current
    /// impossible for its column's history, a magnitude no calibration explains), with the
    /// cause; they are among `rejected_rows`.
    pub rows_screened: Vec<ScreenedRecord>,
    /// Every regressor tested.
    pub regressors: Vec<RegressorRecord>,
    /// Forms of `T` the data did not determine (fallen back from).
    pub matrix_forms_not_determined: Vec<MatrixForm>,
    /// Why the result should not be trusted, when the residuals say so (empty otherwise).
    pub warnings: Vec<String>,
    /// The sensor-axes check ([`crate::axes`]): one entry per finding, `[]` when none; not
    /// applied here (`applied: false`: the magnitude fit does not depend on the axes), but
    /// by `calibrate`, which finds them again.
    pub sensor_axes: Vec<crate::axes::SensorAxesEntry>,
    /// What the data could not decide of the sensors' axes.
    pub sensor_axes_not_checked: Vec<String>,
    /// [`CONVENTION`].
    pub convention: &'static str,
}

/// A row screened out before the fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScreenedRecord {
    /// 0-based telemetry row.
    pub row: usize,
    /// The column and its value against the column's history.
    pub cause: String,
}

/// Before and after.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RmsPair {
    /// Before the calibration.
    pub before: f64,
    /// After.
    pub after: f64,
}

/// A run's result with the samples it used (for figures and tests).
#[derive(Debug, Clone)]
pub struct MagCalOutcome {
    /// The calibration.
    pub calibration: MagCalibration,
    /// The samples, every candidate regressor per row.
    pub samples: Vec<Sample>,
    /// Every candidate regressor's name (the telemetry's current columns).
    pub names: Vec<String>,
    /// Why the result should not be trusted ([`warnings`]), and the sensor-axes finding.
    pub warnings: Vec<String>,
    /// The sensor-axes check before the fit.
    pub axes: pdcal_axes::AxesCheck,
}

/// The misfit that makes a calibration untrustworthy: the implied noise well beyond the
/// dataset's noise hint, or a corrected magnitude that misses the reference by more than
/// 5 % RMS (no magnetometer worth calibrating is that noisy: the model, the time tags or the
/// orbit do not describe the data).
pub fn warnings(cal: &MagCalibration, mean_field_nt: f64, hint_nt: Option<f64>) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(hint) = hint_nt.filter(|h| *h > 0.0)
        && cal.noise_sigma_nt > 1.5 * hint
    {
        out.push(format!(
            "the residuals imply {:.0} nT of noise per axis, {:.1} times dataset.ron's mag_nT {hint:.0}: the model does not describe these data; the parameters are not a calibration",
            cal.noise_sigma_nt,
            cal.noise_sigma_nt / hint
        ));
    }
    if cal.residual_rms_after_nt > 0.05 * mean_field_nt {
        out.push(format!(
            "the corrected magnitude misses the reference by {:.0} nT RMS ({:.1} % of the mean field): the model, the time tags or the orbit do not describe these data; the parameters are not a calibration",
            cal.residual_rms_after_nt,
            100.0 * cal.residual_rms_after_nt / mean_field_nt
        ));
    }
    out
}

/// Calibrates the magnetometer of `meta`/`telemetry`.
pub fn run(meta: &DatasetMeta, telemetry: &Telemetry) -> Result<MagCalOutcome> {
    if telemetry.mag_nt.is_none() {
        bail!("the dataset has no magnetometer columns (mag_x_nT, mag_y_nT, mag_z_nT)");
    }
    // The magnetometer's axes against the gyro (and the photodiodes), as `calibrate` checks
    // them. Reported, not applied: the magnitude fit does not depend on the axes, and
    // `calibrate --mag-cal` applies this calibration to the samples as recorded, then finds
    // and applies the same axes itself.
    let references = pdcal_filter::step_references(meta, telemetry)?;
    let axes = crate::axes::check(
        meta,
        telemetry,
        &(&references).into(),
        &pdcal_filter::FilterConfig::default(),
        &[],
    )?;
    let Some(mag) = telemetry.mag_nt.as_ref() else {
        bail!("the dataset has no magnetometer columns (mag_x_nT, mag_y_nT, mag_z_nT)");
    };
    let model = pdcal_filter::reference_model(meta, telemetry)?;
    let names: Vec<String> = telemetry.current_a.iter().map(|c| c.name.clone()).collect();
    // A row needs every current: one column without a sample would leave no row, and the
    // fit would report too few rows without saying why.
    if let Some(empty) = (telemetry.current_a.iter()).find(|c| c.values.iter().all(|v| v.is_none()))
    {
        bail!(
            "telemetry.csv: current column {} has no sample: every row of the fit needs each \
             current column's value (held from its latest sample), so this one leaves none; \
             remove the column or give its samples",
            pdcal_text::quote(&format!("cur_{}_A", empty.name))
        );
    }
    let held = held_currents(telemetry);
    let mut samples = Vec::new();
    for (row, (m, u)) in mag.iter().zip(held).enumerate() {
        let (Some(m), Some(u)) = (m, u) else {
            continue;
        };
        let t_s = telemetry.t_s[row];
        samples.push(pdcal_magcal::sample_along_orbit(&model, row, t_s, m, u)?);
    }
    // The unit first: a field in uT spans less than an nT noise on every axis, and would be
    // called stuck.
    pdcal_magcal::screen::check_field_size(&samples)?;
    stuck_axis(mag, meta.noise.as_ref().and_then(|n| n.mag_nt))?;
    let calibration = pdcal_magcal::calibrate(&samples, &names, &MagCalConfig::default())?;
    let mean_field_nt =
        samples.iter().map(|s| s.field_nt).sum::<f64>() / samples.len().max(1) as f64;
    let hint = meta.noise.as_ref().and_then(|n| n.mag_nt);
    let axes_warnings = axes.finding.iter().map(crate::axes::message_not_applied);
    Ok(MagCalOutcome {
        warnings: axes_warnings
            .chain(warnings(&calibration, mean_field_nt, hint))
            .collect(),
        calibration,
        samples,
        names,
        axes,
    })
}

/// An error naming a magnetometer axis whose samples span no more than its noise (exactly
/// one value without a noise hint): a stuck or dead axis, from which no scale can be fitted
/// (the fit would only say a scale factor was not determined).
fn stuck_axis(mag: &pdcal_dataset::Vectors, noise_nt: Option<f64>) -> Result<()> {
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        let values = mag.iter().flatten().map(|m| m[k]);
        let (low, high) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        if low.is_finite() && high - low <= noise_nt.unwrap_or(0.0) {
            bail!(
                "telemetry.csv: mag_{axis}_nT spans {:.3} nT ({} .. {} nT) over every sample, \
                 within its noise: a stuck or dead axis (or a spacecraft that never turned), \
                 from which no scale or bias can be fitted",
                high - low,
                pdcal_text::number(low),
                pdcal_text::number(high)
            );
        }
    }
    Ok(())
}

/// Each row's current channels, held from their latest sample; `None` before every channel
/// has been sampled once.
fn held_currents(telemetry: &Telemetry) -> Vec<Option<Vec<f64>>> {
    let mut held: Vec<Option<f64>> = vec![None; telemetry.current_a.len()];
    (0..telemetry.len())
        .map(|row| {
            for (h, column) in held.iter_mut().zip(&telemetry.current_a) {
                if let Some(v) = column.values[row] {
                    *h = Some(v);
                }
            }
            held.iter().copied().collect()
        })
        .collect()
}

/// `pdcal magcal DATASET --out OUT` (`--force` as the other commands).
pub fn run_dir_forced(dataset: &Path, out: &Path, force: bool) -> Result<MagCalOutcome> {
    let dir = OutputDir::create_reading(out, "magcal", force, &[dataset])?;
    let meta = pdcal_dataset::read_meta(dataset)?;
    let telemetry = pdcal_dataset::read_telemetry(dataset, &meta)?;
    let outcome = run(&meta, &telemetry)?;
    write_outputs(dir, Some(dataset), &meta, telemetry, &outcome)?;
    Ok(outcome)
}

/// magcal.ron, magcal.json, the corrected dataset, the figures and index.html, published
/// in one step; `dataset`, the directory read, if any, gives the truth files copied.
pub fn write_outputs(
    dir: OutputDir,
    dataset: Option<&Path>,
    meta: &DatasetMeta,
    mut telemetry: Telemetry,
    outcome: &MagCalOutcome,
) -> Result<()> {
    let cal = &outcome.calibration;
    let file = file_of(cal);
    let ron_text = ron::ser::to_string_pretty(&file, ron::ser::PrettyConfig::default())?;
    write_file(&dir.file("magcal.ron"), format!("{ron_text}\n").as_bytes())?;
    let summary = summary_of(outcome);
    write_file(
        &dir.file("magcal.json"),
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    write_file(
        &dir.file("rejected_rows.csv"),
        rejected_rows_csv(outcome).as_bytes(),
    )?;
    apply(&mut telemetry, cal)?;
    write_corrected_dataset(&dir.file("dataset"), dataset, meta, telemetry)?;
    let figures = figures(dir.path(), outcome)?;
    let rows = index_rows(&summary);
    pdcal_report::index_html(
        dir.path(),
        &format!("pdcal magcal: {}", meta.name),
        &rows,
        &figures,
    )?;
    dir.commit()
}

/// Every rejected row: `row` (0-based telemetry row), `t_s` and `cause` (`gate` for the
/// outlier gate, else the screening's reason, quoted).
fn rejected_rows_csv(outcome: &MagCalOutcome) -> String {
    let cal = &outcome.calibration;
    let mut text = String::from("row,t_s,cause\n");
    for &row in &cal.rejected_rows {
        let t_s = (outcome.samples.iter())
            .find(|s| s.row == row)
            .map_or(f64::NAN, |s| s.t_s);
        let cause = (cal.screened.iter().find(|r| r.row == row)).map_or("gate".to_owned(), |r| {
            format!("\"{}\"", r.cause.replace('"', "\"\""))
        });
        text.push_str(&format!("{row},{t_s},{cause}\n"));
    }
    text
}

/// dataset.ron and the corrected telemetry.csv, with the input's truth files copied as
/// they are (never parsed: another tool's truth must not stop the run).
fn write_corrected_dataset(
    target: &Path,
    source: Option<&Path>,
    meta: &DatasetMeta,
    telemetry: Telemetry,
) -> Result<()> {
    std::fs::create_dir(target)
        .with_context(|| format!("cannot create {}", pdcal_text::path(target)))?;
    let corrected = pdcal_dataset::Dataset {
        meta: meta.clone(),
        telemetry,
        truth: None,
    };
    for (name, text) in pdcal_dataset::render_dataset(&corrected)? {
        write_file(&target.join(name), text.as_bytes())?;
    }
    for name in [pdcal_dataset::TRUTH_CSV, pdcal_dataset::TRUTH_RON] {
        let Some(from) = source.map(|s| s.join(name)) else {
            break;
        };
        if from.is_file() {
            std::fs::copy(&from, target.join(name))
                .with_context(|| format!("cannot copy {}", pdcal_text::path(&from)))?;
        }
    }
    Ok(())
}

/// Replaces the magnetometer columns of `telemetry` by the corrected field (a row whose
/// kept regressors have no sample yet loses its magnetometer sample: it cannot be
/// corrected); returns the RMS over the rows of the correction's own one-sigma uncertainty
/// per axis, nT.
pub fn apply(telemetry: &mut Telemetry, cal: &MagCalibration) -> Result<f64> {
    let columns: Vec<usize> = (cal.regressors.iter())
        .map(|name| {
            telemetry
                .current_a
                .iter()
                .position(|c| c.name == *name)
                .with_context(|| {
                    format!("the calibration needs the column {name}, which the dataset lacks")
                })
        })
        .collect::<Result<_>>()?;
    let held = held_currents(telemetry);
    let Some(mag) = telemetry.mag_nt.as_mut() else {
        bail!("the dataset has no magnetometer columns to correct");
    };
    let (mut var_sum, mut n) = (0.0, 0usize);
    for (k, u) in held.into_iter().enumerate().take(mag.len()) {
        let Some(raw) = mag.get(k) else { continue };
        let Some(u) = u.map(|u| columns.iter().map(|&j| u[j]).collect::<Vec<f64>>()) else {
            mag.set(k, None);
            continue;
        };
        mag.set(k, Some(cal.correct(&raw, &u)));
        var_sum += cal.correction_covariance(&raw, &u).trace() / 3.0;
        n += 1;
    }
    Ok(if n == 0 {
        0.0
    } else {
        (var_sum / n as f64).sqrt()
    })
}

/// Reads a magcal.ron written by `pdcal magcal`.
pub fn load(path: &Path) -> Result<MagCalibration> {
    let text =
        pdcal_dataset::bounded::read_text_bounded(path, pdcal_dataset::bounded::MAX_RON_BYTES)
            .with_context(|| format!("cannot read {}", pdcal_text::path(path)))?;
    let file: MagCalFile = pdcal_dataset::parse_ron(&text).map_err(|fault| {
        let what = match fault.kind {
            RonFaultKind::Ron { message } => message,
            RonFaultKind::UnknownField { name, expected } => {
                format!("unknown field {name:?} (expected one of {expected})")
            }
            RonFaultKind::MissingField { name } => format!("missing field {name}"),
        };
        anyhow::anyhow!(
            "{}:{}:{}: {what} (expected the magcal.ron of pdcal magcal)",
            pdcal_text::path(path),
            fault.line,
            fault.column
        )
    })?;
    from_file(&file).with_context(|| pdcal_text::path(path).to_string())
}

fn from_file(file: &MagCalFile) -> Result<MagCalibration> {
    let n = file.parameters.len();
    if file.covariance.len() != n || file.covariance.iter().any(|r| r.len() != n) {
        bail!("covariance is not {n} x {n} (one row and column per parameter)");
    }
    check_numbers(file)?;
    let covariance = DMatrix::from_fn(n, n, |i, j| file.covariance[i][j]);
    let matrix = Matrix3::from_fn(|a, b| file.matrix[a][b]);
    let regressors = (file.current_bias_nt_per_a.iter())
        .map(|(name, c)| (name.clone(), Vector3::from(*c)))
        .collect();
    MagCalibration::from_forward(
        file.matrix_form,
        matrix,
        Vector3::from(file.bias_nt),
        regressors,
        covariance,
    )
    .context("the matrix is singular or the covariance does not match the parameters")
}

/// Refuses a magcal.ron whose numbers no calibration has: a value that is not finite, a
/// variance that is not positive, a covariance that is not symmetric, a noise that is not
/// positive, or a matrix and biases no magnetometer has ([`pdcal_magcal::not_physical`]).
/// The matrix has the shape its `matrix_form` says: symmetric; diagonal (no off-diagonal
/// entry); scalar (one value on the diagonal). A matrix of another shape under a form would
/// be read as that form's parameters and silently lose the rest.
fn check_form(form: MatrixForm, m: &[[f64; 3]; 3]) -> Result<()> {
    let scale = m.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
    let differs = |a: f64, b: f64| (a - b).abs() > 1e-9 * scale;
    let off = [(0, 1), (0, 2), (1, 2)];
    if let Some(&(r, c)) = off.iter().find(|&&(r, c)| differs(m[r][c], m[c][r])) {
        bail!(
            "the matrix is not symmetric (row {} column {}: {} against {}): matrix_form {form:?} \
             holds a symmetric matrix",
            r + 1,
            c + 1,
            pdcal_text::number(m[r][c]),
            pdcal_text::number(m[c][r])
        );
    }
    let off_diagonal = off.iter().find(|&&(r, c)| differs(m[r][c], 0.0));
    match (form, off_diagonal) {
        (MatrixForm::Diagonal | MatrixForm::Scalar, Some(&(r, c))) => bail!(
            "matrix_form is {form:?} but the matrix has an off-diagonal entry (row {} column {}: \
             {}): write the form the matrix has (Symmetric) or the matrix of the form",
            r + 1,
            c + 1,
            pdcal_text::number(m[r][c])
        ),
        (MatrixForm::Scalar, None) if differs(m[0][0], m[1][1]) || differs(m[0][0], m[2][2]) => {
            bail!(
                "matrix_form is Scalar but the diagonal holds {}, {}, {}: a scalar form has one \
                 scale factor",
                pdcal_text::number(m[0][0]),
                pdcal_text::number(m[1][1]),
                pdcal_text::number(m[2][2])
            )
        }
        _ => Ok(()),
    }
}

fn check_numbers(file: &MagCalFile) -> Result<()> {
    let values = (file.matrix.iter().flatten())
        .chain(&file.bias_nt)
        .chain(file.current_bias_nt_per_a.iter().flat_map(|(_, c)| c));
    if let Some(v) = values.clone().find(|v| !v.is_finite()) {
        bail!(
            "the matrix or a bias holds {}, not a number",
            pdcal_text::number(*v)
        );
    }
    for (i, row) in file.covariance.iter().enumerate() {
        let name = &file.parameters[i];
        let variance = row[i];
        if !(variance.is_finite() && variance > 0.0) {
            bail!(
                "the variance of {} is {}: a variance is a positive number",
                pdcal_text::quote(name),
                pdcal_text::number(variance)
            );
        }
        for (j, v) in row.iter().enumerate() {
            let mirror = file.covariance[j][i];
            if !v.is_finite() || (v - mirror).abs() > 1e-9 * (v.abs() + mirror.abs()) {
                bail!(
                    "covariance row {} column {}: {} against {} across the diagonal (a covariance is symmetric and finite)",
                    i + 1,
                    j + 1,
                    pdcal_text::number(*v),
                    pdcal_text::number(mirror)
                );
            }
        }
    }
    check_form(file.matrix_form, &file.matrix)?;
    if !(file.noise_sigma_nt.is_finite() && file.noise_sigma_nt > 0.0) {
        bail!(
            "noise_sigma_nT is {}: a noise sigma is a positive number of nT",
            pdcal_text::number(file.noise_sigma_nt)
        );
    }
    let coeffs: Vec<(String, Vector3<f64>)> = (file.current_bias_nt_per_a.iter())
        .map(|(name, c)| (pdcal_text::quote(name), Vector3::from(*c)))
        .collect();
    let matrix = Matrix3::from_fn(|a, b| file.matrix[a][b]);
    if let Some(why) = pdcal_magcal::not_physical(&matrix, &Vector3::from(file.bias_nt), &coeffs) {
        bail!("not a magnetometer calibration: {why}");
    }
    Ok(())
}

fn rows3(m: &Matrix3<f64>) -> [[f64; 3]; 3] {
    [0, 1, 2].map(|a| [0, 1, 2].map(|b| m[(a, b)]))
}

fn file_of(cal: &MagCalibration) -> MagCalFile {
    let n = cal.covariance.nrows();
    MagCalFile {
        convention: CONVENTION.to_owned(),
        matrix_form: cal.params.form,
        matrix: rows3(&cal.matrix),
        bias_nt: cal.params.bias_nt.into(),
        current_bias_nt_per_a: (cal.regressors.iter())
            .zip(&cal.params.coeff_nt)
            .map(|(name, c)| (name.clone(), (*c).into()))
            .collect(),
        parameters: cal.parameter_names(),
        covariance: (0..n)
            .map(|i| (0..n).map(|j| cal.covariance[(i, j)]).collect())
            .collect(),
        noise_sigma_nt: cal.noise_sigma_nt,
        regressors: records(cal),
    }
}

fn records(cal: &MagCalibration) -> Vec<RegressorRecord> {
    (cal.decisions.iter())
        .map(|d| RegressorRecord {
            name: d.name.clone(),
            kept: d.kept,
            score_nats: d.score_nats,
            reason: d.reason.clone(),
        })
        .collect()
}

/// magcal.json of `outcome`.
pub fn summary_of(outcome: &MagCalOutcome) -> MagCalSummary {
    let cal = &outcome.calibration;
    let by_name = |values: &[Vector3<f64>]| {
        (cal.regressors.iter())
            .zip(values)
            .map(|(name, v)| (name.clone(), (*v).into()))
            .collect()
    };
    MagCalSummary {
        bias_nt: cal.params.bias_nt.into(),
        bias_sigma_nt: cal.bias_sigma_nt().into(),
        matrix: rows3(&cal.matrix),
        matrix_sigma: rows3(&cal.matrix_sigma()),
        matrix_form: cal.params.form,
        current_bias_nt_per_a: by_name(&cal.params.coeff_nt),
        current_bias_sigma_nt_per_a: by_name(&cal.coeff_sigma_nt()),
        residual_rms_nt: RmsPair {
            before: cal.residual_rms_before_nt,
            after: cal.residual_rms_after_nt,
        },
        noise_sigma_nt: cal.noise_sigma_nt,
        rows_usable: outcome.samples.len(),
        rows_used: cal.rows_used,
        rows_rejected: cal.rejected_rows.len(),
        rejected_rows: (cal.rejected_rows.iter().take(REJECTED_ROWS_LISTED).copied()).collect(),
        rejected_rows_truncated: cal.rejected_rows.len() > REJECTED_ROWS_LISTED,
        rows_screened: (cal.screened.iter().take(REJECTED_ROWS_LISTED))
            .map(|r| ScreenedRecord {
                row: r.row,
                cause: r.cause.clone(),
            })
            .collect(),
        regressors: records(cal),
        matrix_forms_not_determined: cal.forms_not_determined.clone(),
        warnings: outcome.warnings.clone(),
        sensor_axes: crate::axes::entries_applied(&outcome.axes, false),
        sensor_axes_not_checked: crate::axes::notes(&outcome.axes),
        convention: CONVENTION,
    }
}

fn index_rows(s: &MagCalSummary) -> Vec<(String, String)> {
    let v3 = |v: &[f64; 3], sig: &[f64; 3]| {
        format!(
            "({:.0} +- {:.0}, {:.0} +- {:.0}, {:.0} +- {:.0})",
            v[0], sig[0], v[1], sig[1], v[2], sig[2]
        )
    };
    let mut rows: Vec<(String, String)> = (s.warnings.iter())
        .map(|w| ("warning".to_owned(), w.clone()))
        .collect();
    rows.extend([
        (
            "field-magnitude residual RMS, nT".to_owned(),
            format!(
                "{:.1} before, {:.1} after",
                s.residual_rms_nt.before, s.residual_rms_nt.after
            ),
        ),
        (
            "hard-iron bias b, nT".to_owned(),
            v3(&s.bias_nt, &s.bias_sigma_nt),
        ),
        (
            format!("T ({:?}), rows", s.matrix_form),
            s.matrix
                .iter()
                .zip(&s.matrix_sigma)
                .map(|(r, sig)| {
                    format!(
                        "({:.4} +- {:.4}, {:.4} +- {:.4}, {:.4} +- {:.4})",
                        r[0], sig[0], r[1], sig[1], r[2], sig[2]
                    )
                })
                .collect::<Vec<_>>()
                .join(" "),
        ),
        (
            "rows used / rejected".to_owned(),
            format!("{} / {}", s.rows_used, s.rows_rejected),
        ),
    ]);
    for (name, c) in &s.current_bias_nt_per_a {
        let sig = &s.current_bias_sigma_nt_per_a[name];
        rows.push((format!("{name}, nT/A"), v3(c, sig)));
    }
    for r in s.regressors.iter().filter(|r| !r.kept) {
        rows.push((format!("{} (dropped)", r.name), r.reason.clone()));
    }
    rows
}

/// Magnitudes before and after against the reference, the residual against time and
/// against each tested regressor; (caption, stem) per figure.
fn figures(dir: &Path, outcome: &MagCalOutcome) -> Result<Vec<(String, String)>> {
    let cal = &outcome.calibration;
    let samples = &outcome.samples;
    let t_min: Vec<f64> = samples.iter().map(|s| s.t_s / 60.0).collect();
    let reference: Vec<f64> = samples.iter().map(|s| s.field_nt).collect();
    let measured: Vec<f64> = samples.iter().map(|s| s.mag_nt.norm()).collect();
    let kept_u = |s: &Sample| -> Vec<f64> {
        (cal.regressors.iter())
            .map(|name| {
                let j = outcome.names.iter().position(|n| n == name).unwrap_or(0);
                s.u[j]
            })
            .collect()
    };
    let corrected: Vec<f64> = samples
        .iter()
        .map(|s| cal.correct(&s.mag_nt, &kept_u(s)).norm())
        .collect();
    let residual: Vec<f64> = corrected
        .iter()
        .zip(&reference)
        .map(|(c, r)| c - r)
        .collect();
    let mut out = Vec::new();
    lines(
        dir,
        &Figure::new(
            "magnitude",
            "Field magnitude: measured, corrected and IGRF-14 reference",
        ),
        &LineAxes::new("time, min", "|B|, nT"),
        &t_min,
        &[
            Series::new("measured |m|", &measured, Mark::Dot).with_colour([220, 40, 40]),
            Series::new("corrected |B|", &corrected, Mark::Dot).with_colour([30, 80, 220]),
            Series::new("reference |H|", &reference, Mark::Line).with_colour([0, 0, 0]),
        ],
    )?;
    out.push((
        "Measured and corrected field magnitude against the IGRF-14 reference along the orbit"
            .to_owned(),
        "magnitude".to_owned(),
    ));
    lines(
        dir,
        &Figure::new("residual_time", "Magnitude residual after calibration"),
        &LineAxes::new("time, min", "|B| - |H|, nT"),
        &t_min,
        &[Series::new("residual", &residual, Mark::Dot)],
    )?;
    out.push((
        "Residual |B| - |H| against time (rejected rows included)".to_owned(),
        "residual_time".to_owned(),
    ));
    for (j, name) in outcome.names.iter().enumerate() {
        let mut pairs: Vec<(f64, f64)> = samples
            .iter()
            .map(|s| s.u[j])
            .zip(residual.iter().copied())
            .collect();
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (x, y): (Vec<f64>, Vec<f64>) = pairs.into_iter().unzip();
        let stem = format!("residual_{}", name.to_lowercase());
        lines(
            dir,
            &Figure::new(&stem, &format!("Residual against {name}")),
            &LineAxes::new(&format!("{name}, A"), "|B| - |H|, nT"),
            &x,
            &[Series::new("residual", &y, Mark::Dot)],
        )?;
        out.push((
            format!(
                "Residual against the regressor {name} (flat when its bias is removed or it drives nothing)"
            ),
            stem,
        ));
    }
    Ok(out)
}
