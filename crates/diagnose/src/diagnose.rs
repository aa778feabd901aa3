//! The rounds: calibrate with the current model, score the candidates on the residuals,
//! add the winner if significant, calibrate again, measure the gap; until `none`.

use pdcal_albedo::AlbedoModel;
use pdcal_dataset::{DatasetMeta, Telemetry, TruePd};
use pdcal_filter::{
    Algebra, Calibration, CalibrationRun, FilterConfig, Mode, RunInputs, StepReference,
    calibrate_with_model,
};
use pdcal_photodiode::Photodiode;
use serde::Serialize;

use crate::DiagnoseError;
use crate::candidates::{CandidateFit, Signature, score_candidates, score_one, scored, signature};
use crate::model::{AddedEffect, BaseModel, ModelSpec};
use crate::refit::time_offset_refit;
use crate::residuals::{FULL_SUN, ResidualInputs, Residuals, mean_std, residuals, rms};

/// Version of `diagnosis.json`.
pub const DIAGNOSIS_FORMAT_VERSION: u32 = 1;

/// What a diagnosis reads: the dataset (never its truth), references, the albedo model, and
/// optionally the truth's photodiodes, used only to report calibration errors.
#[derive(Clone, Copy)]
pub struct DiagnoseInputs<'a> {
    /// dataset.ron.
    pub meta: &'a DatasetMeta,
    /// telemetry.csv.
    pub telemetry: &'a Telemetry,
    /// One reference per telemetry row.
    pub references: &'a [StepReference],
    /// The albedo model (the filter's, and the albedo candidate's regressor).
    pub albedo: &'a AlbedoModel,
    /// truth.ron's photodiodes, for the report only: no decision reads them.
    pub truth: Option<&'a [TruePd]>,
}

/// Tuning of the diagnosis.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseConfig {
    /// The calibration filter's tuning.
    pub filter: FilterConfig,
    /// Most effects added (rounds). Default 4.
    pub max_rounds: usize,
    /// A candidate is named only when its score (nats, BIC already subtracted) exceeds
    /// this. Default [`DEFAULT_THRESHOLD`].
    pub threshold: f64,
    /// HAC window, telemetry rows. Default [`DEFAULT_MAX_LAG`].
    pub max_lag_rows: usize,
}

/// Score threshold above the BIC, nats (see docs/diagnose.md: set from control seeds).
pub const DEFAULT_THRESHOLD: f64 = 10.0;
/// Bartlett window of the HAC covariance, rows (1 min at 1 Hz: longer than the correlation
/// time of the smoother's attitude error on the built-in scenarios).
pub const DEFAULT_MAX_LAG: usize = 60;

impl Default for DiagnoseConfig {
    fn default() -> Self {
        DiagnoseConfig {
            filter: FilterConfig::default(),
            max_rounds: 4,
            threshold: DEFAULT_THRESHOLD,
            max_lag_rows: DEFAULT_MAX_LAG,
        }
    }
}

/// True calibration errors (reported only when the truth is given).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CalibrationErrors {
    /// Worst angle between true and estimated normal, deg, over photodiodes lit inside
    /// 60 deg incidence in full Sun for at least 5 minutes.
    pub worst_normal_error_deg: f64,
    /// Worst |true - estimated| scale over the same photodiodes, % of the true scale.
    pub worst_scale_error_percent: f64,
}

/// The gap between model and measurement.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Gap {
    /// RMS of every photodiode residual from the filter's start, V.
    #[serde(rename = "photodiode_rms_V")]
    pub photodiode_rms_v: f64,
    /// Fraction of those residuals inside 3 photodiode sigmas.
    pub fraction_within_3sigma: f64,
    /// Photodiode noise sigma (the floor of the RMS), V.
    #[serde(rename = "photodiode_noise_V")]
    pub photodiode_noise_v: f64,
    /// Mean magnitude of the photodiode least-squares Sun vector in full Sun.
    pub sun_vector_magnitude_mean: f64,
    /// Its standard deviation (1 for a perfect model and noise-free outputs).
    pub sun_vector_magnitude_std: f64,
    /// RMS of the magnetometer residual components, nT (NaN without magnetometer).
    #[serde(rename = "magnetometer_rms_nT")]
    pub magnetometer_rms_nt: f64,
    /// Magnetometer noise sigma, nT.
    #[serde(rename = "magnetometer_noise_nT")]
    pub magnetometer_noise_nt: f64,
    /// RMS of the smoothed attitude rate beyond the gyro, rad/s.
    pub gyro_residual_rms_rad_s: f64,
    /// True calibration errors, when the truth was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibration: Option<CalibrationErrors>,
}

/// One round that found an effect.
#[derive(Debug, Clone)]
pub struct Round {
    /// Effect id found.
    pub found: &'static str,
    /// The effect as added, with its fitted values.
    pub effect: AddedEffect,
    /// What gave it away.
    pub evidence: String,
    /// Its score, nats.
    pub score: f64,
    /// Every candidate of the round, best first.
    pub candidates: Vec<CandidateFit>,
    /// Gap before adding it.
    pub gap_before: Gap,
    /// Gap after adding it and calibrating again.
    pub gap_after: Gap,
    /// The residual signature before.
    pub signature_before: Signature,
    /// The same signature after.
    pub signature_after: Signature,
}

/// The outcome of a diagnosis.
#[derive(Debug, Clone)]
pub struct Diagnosis {
    /// Where it started.
    pub base_model: BaseModel,
    /// Rounds that found something, in order.
    pub rounds: Vec<Round>,
    /// The candidates of the last check (none significant, or the round cap reached).
    pub final_candidates: Vec<CandidateFit>,
    /// The final model (filter-estimated values updated).
    pub final_spec: ModelSpec,
    /// The gap with the final model.
    pub final_gap: Gap,
    /// The final calibration run.
    pub final_run: CalibrationRun,
    /// Residuals of the first model (before any round).
    pub initial_residuals: Residuals,
    /// Residuals of the final model.
    pub final_residuals: Residuals,
    /// The significance threshold used, nats.
    pub threshold: f64,
}

impl Diagnosis {
    /// Effects found, strongest (highest score) first, joined by `+`; or `none`.
    pub fn verdict(&self) -> String {
        if self.rounds.is_empty() {
            return "none".to_owned();
        }
        let mut rounds: Vec<&Round> = self.rounds.iter().collect();
        rounds.sort_by(|a, b| b.score.total_cmp(&a.score));
        rounds.iter().map(|r| r.found).collect::<Vec<_>>().join("+")
    }

    /// `diagnosis.json`.
    pub fn summary(&self) -> DiagnosisSummary {
        let best = self.final_candidates.first();
        DiagnosisSummary {
            format_version: DIAGNOSIS_FORMAT_VERSION,
            base_model: self.base_model.as_str(),
            rounds: self
                .rounds
                .iter()
                .map(|r| RoundSummary {
                    found: r.found,
                    evidence: r.evidence.clone(),
                    score: r.score,
                    gap_before: r.gap_before,
                    gap_after: r.gap_after,
                    parameters: r.effect.clone(),
                    runner_up: r.candidates.get(1).map(|c| (c.id, c.score)),
                })
                .collect(),
            final_model: self.final_spec.effect_ids(),
            verdict: self.verdict(),
            final_check: FinalCheck {
                best: best.map(|c| c.id),
                score: best.map(|c| c.score),
                threshold: self.threshold,
            },
            final_gap: self.final_gap,
            final_parameters: self.final_spec.added.clone(),
        }
    }
}

/// `diagnosis.json` (cli-contract.md keys, plus detail).
#[derive(Debug, Clone, Serialize)]
pub struct DiagnosisSummary {
    /// Layout version.
    pub format_version: u32,
    /// `cosine` or `paper`.
    pub base_model: &'static str,
    /// Rounds that found an effect.
    pub rounds: Vec<RoundSummary>,
    /// Effect ids of the final model beyond the direct Sun.
    pub final_model: Vec<String>,
    /// Found effects, strongest first, joined by `+`, or `none`.
    pub verdict: String,
    /// The check that ended the diagnosis.
    pub final_check: FinalCheck,
    /// The gap with the final model.
    pub final_gap: Gap,
    /// The added effects with their final values.
    pub final_parameters: Vec<AddedEffect>,
}

/// One round in `diagnosis.json`.
#[derive(Debug, Clone, Serialize)]
pub struct RoundSummary {
    /// Effect id.
    pub found: &'static str,
    /// What gave it away.
    pub evidence: String,
    /// Score, nats.
    pub score: f64,
    /// Gap before.
    pub gap_before: Gap,
    /// Gap after.
    pub gap_after: Gap,
    /// The effect's fitted values as added.
    pub parameters: AddedEffect,
    /// The second-best candidate and its score.
    pub runner_up: Option<(&'static str, f64)>,
}

/// The last check: the best remaining candidate and the threshold it failed.
#[derive(Debug, Clone, Serialize)]
pub struct FinalCheck {
    /// Best remaining candidate.
    pub best: Option<&'static str>,
    /// Its score, nats.
    pub score: Option<f64>,
    /// Threshold, nats.
    pub threshold: f64,
}

/// Runs the diagnosis from `base`.
pub fn diagnose(
    inputs: &DiagnoseInputs<'_>,
    base: BaseModel,
    config: &DiagnoseConfig,
) -> Result<Diagnosis, DiagnoseError> {
    if config.max_lag_rows == 0 {
        return Err(DiagnoseError::Config {
            field: "max_lag_rows",
            value: 0.0,
            rule: "must be at least 1",
        });
    }
    let n_pd = inputs.meta.photodiodes.len();
    let mut spec = ModelSpec::new(base);
    let (mut run, mut res) = calibrate_and_residuals(inputs, &mut spec, config)?;
    let initial_residuals = res.clone();
    let mut rounds = Vec::new();
    loop {
        let candidates = rescored_by_refit(
            inputs,
            &spec,
            config,
            &run,
            &res,
            score_candidates(&res, &spec, n_pd, config.max_lag_rows),
        )?;
        let best = candidates
            .first()
            .filter(|c| c.score > config.threshold)
            .cloned();
        let (Some(best), true) = (best, rounds.len() < config.max_rounds) else {
            let final_gap = gap(&res, &run.calibration, inputs.truth);
            return Ok(Diagnosis {
                base_model: base,
                rounds,
                final_candidates: candidates,
                final_spec: spec,
                final_gap,
                final_run: run,
                initial_residuals,
                final_residuals: res,
                threshold: config.threshold,
            });
        };
        let gap_before = gap(&res, &run.calibration, inputs.truth);
        let signature_before = signature(best.id, &res);
        spec.added.push(best.effect.clone());
        if best.effect.changes_filter() {
            (run, res) = calibrate_and_residuals(inputs, &mut spec, config)?;
            (run, res) = refine(inputs, &mut spec, config, best.id, run, res)?;
        } else {
            let telemetry = spec.corrected_telemetry(inputs.telemetry);
            res = residuals(&residual_inputs(inputs, &telemetry, config), &spec, &run)?;
        }
        rounds.push(Round {
            found: best.id,
            effect: spec.added.last().cloned().unwrap_or(best.effect),
            evidence: best.evidence,
            score: best.score,
            candidates,
            gap_before,
            gap_after: gap(&res, &run.calibration, inputs.truth),
            signature_before,
            signature_after: signature(best.id, &res),
        });
    }
}

/// Most re-fits of an added effect's constants.
const MAX_REFINEMENTS: usize = 3;

/// Re-fits the constants of the effect just added while its own signature stays
/// significant in the new residuals, calibrating again after each.
fn refine(
    inputs: &DiagnoseInputs<'_>,
    spec: &mut ModelSpec,
    config: &DiagnoseConfig,
    id: &str,
    mut run: CalibrationRun,
    mut res: Residuals,
) -> Result<(CalibrationRun, Residuals), DiagnoseError> {
    let n_pd = inputs.meta.photodiodes.len();
    for _ in 0..MAX_REFINEMENTS {
        let Some(again) = score_one(id, &res, n_pd, config.max_lag_rows) else {
            break;
        };
        if again.score <= config.threshold {
            break;
        }
        let Some(last) = spec.added.last_mut() else {
            break;
        };
        if !last.refine(&again.effect) {
            break;
        }
        (run, res) = calibrate_and_residuals(inputs, spec, config)?;
    }
    Ok((run, res))
}

fn residual_inputs<'a>(
    inputs: &'a DiagnoseInputs<'a>,
    telemetry: &'a Telemetry,
    config: &'a DiagnoseConfig,
) -> ResidualInputs<'a> {
    ResidualInputs {
        meta: inputs.meta,
        telemetry,
        references: inputs.references,
        albedo: inputs.albedo,
        config: &config.filter,
    }
}

/// `time-offset` (when not in `spec`) scored again from a refit instead of its residual
/// regression ([`crate::refit`]); sorted best first.
fn rescored_by_refit(
    inputs: &DiagnoseInputs<'_>,
    spec: &ModelSpec,
    config: &DiagnoseConfig,
    run: &CalibrationRun,
    res: &Residuals,
    mut candidates: Vec<CandidateFit>,
) -> Result<Vec<CandidateFit>, DiagnoseError> {
    for c in candidates.iter_mut() {
        if c.id == "time-offset" {
            let refit = scored(time_offset_refit(inputs, spec, config, run)?, res);
            let linear = format!("; residual regression: Wald {:.1}", c.wald);
            *c = refit;
            c.evidence += &linear;
        }
    }
    candidates.sort_by(|a, b| b.score.total_cmp(&a.score));
    Ok(candidates)
}

/// Calibrates with the model `spec` describes, forward filter only (no smoother), and
/// adopts the filter's estimates of its estimated effects: what a refit score needs.
pub(crate) fn forward_run(
    inputs: &DiagnoseInputs<'_>,
    spec: &mut ModelSpec,
    config: &DiagnoseConfig,
) -> Result<CalibrationRun, DiagnoseError> {
    let filter = FilterConfig {
        smoother: false,
        ..config.filter.clone()
    };
    let telemetry = spec.corrected_telemetry(inputs.telemetry);
    let run = filter_run(inputs, spec, &filter, &telemetry)?;
    spec.adopt_estimates(&run.calibration);
    Ok(run)
}

/// Calibrates with the model `spec` describes (its sensor corrections applied to the
/// telemetry), adopts the filter's estimates of its estimated effects, and computes the
/// residuals over every sample.
pub fn calibrate_and_residuals(
    inputs: &DiagnoseInputs<'_>,
    spec: &mut ModelSpec,
    config: &DiagnoseConfig,
) -> Result<(CalibrationRun, Residuals), DiagnoseError> {
    let telemetry = spec.corrected_telemetry(inputs.telemetry);
    let run = filter_run(inputs, spec, &config.filter, &telemetry)?;
    spec.adopt_estimates(&run.calibration);
    let res = residuals(&residual_inputs(inputs, &telemetry, config), spec, &run)?;
    Ok((run, res))
}

/// One calibration with the model `spec` describes on `telemetry` (already corrected).
fn filter_run(
    inputs: &DiagnoseInputs<'_>,
    spec: &ModelSpec,
    filter: &FilterConfig,
    telemetry: &Telemetry,
) -> Result<CalibrationRun, DiagnoseError> {
    let nominal: Vec<Photodiode> = inputs
        .meta
        .photodiodes
        .iter()
        .map(|m| Photodiode::from_az_el_deg(1.0, m.azimuth_deg, m.elevation_deg, 0.0))
        .collect();
    let model = spec.measurement_model(nominal, filter)?;
    // Without albedo in the model, the filter's start (photodiode Sun vector) must not
    // remove it either.
    let albedo = spec.contains("albedo").then_some(inputs.albedo);
    let run_inputs = RunInputs {
        meta: inputs.meta,
        telemetry,
        references: inputs.references,
        albedo,
    };
    Ok(calibrate_with_model(
        &run_inputs,
        filter,
        &Mode::Full,
        model,
        Algebra::Structured,
    )?)
}

/// The gap of one set of residuals.
pub fn gap(res: &Residuals, calibration: &Calibration, truth: Option<&[TruePd]>) -> Gap {
    let bound = 3.0 * res.sigma_pd_v;
    let inside = res
        .pd
        .iter()
        .filter(|p| p.residual_v.abs() <= bound)
        .count();
    let (mag_mean, mag_std) = mean_std(&res.sun_magnitude);
    Gap {
        photodiode_rms_v: rms(res.pd.iter().map(|p| p.residual_v)),
        fraction_within_3sigma: inside as f64 / res.pd.len().max(1) as f64,
        photodiode_noise_v: res.sigma_pd_v,
        sun_vector_magnitude_mean: mag_mean,
        sun_vector_magnitude_std: mag_std,
        magnetometer_rms_nt: rms(res.mag.iter().flat_map(|m| m.residual_nt.iter().copied())),
        magnetometer_noise_nt: res.sigma_mag_nt,
        gyro_residual_rms_rad_s: rms(res.gyro.iter().flat_map(|g| {
            (g.residual_rad / g.dt_s)
                .iter()
                .copied()
                .collect::<Vec<_>>()
        })),
        calibration: truth.map(|t| calibration_errors(res, calibration, t)),
    }
}

/// Lit samples (inside 60 deg incidence, full Sun) a photodiode needs before its errors
/// count: 5 minutes at 1 Hz, the calibration-filter issue's rule.
const MIN_LIT_SAMPLES: usize = 300;

/// Worst true normal and scale errors over the photodiodes lit long enough.
pub fn calibration_errors(
    res: &Residuals,
    calibration: &Calibration,
    truth: &[TruePd],
) -> CalibrationErrors {
    let cos60 = 60f64.to_radians().cos();
    let mut lit = vec![0usize; calibration.photodiodes.len()];
    for p in res
        .pd
        .iter()
        .filter(|p| p.sun_fraction >= FULL_SUN && p.cos_incidence >= cos60)
    {
        if let Some(n) = lit.get_mut(p.pd) {
            *n += 1;
        }
    }
    let mut worst = CalibrationErrors {
        worst_normal_error_deg: 0.0,
        worst_scale_error_percent: 0.0,
    };
    for ((est, t), n) in calibration.photodiodes.iter().zip(truth).zip(&lit) {
        if *n < MIN_LIT_SAMPLES {
            continue;
        }
        let n_true = pdcal_attitude::normal_from_az_el(
            t.azimuth_deg.to_radians(),
            t.elevation_deg.to_radians(),
        );
        let angle = n_true.angle(&est.n_body()).to_degrees();
        let scale = 100.0 * ((t.scale_v - est.scale_v) / t.scale_v).abs();
        worst.worst_normal_error_deg = worst.worst_normal_error_deg.max(angle);
        worst.worst_scale_error_percent = worst.worst_scale_error_percent.max(scale);
    }
    worst
}
