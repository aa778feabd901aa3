//! The rounds: calibrate with the current model, score the candidates on the residuals
//! (effects to add and terms of the model to rescale), try the best significant one, keep
//! it only if its refit shrinks the gap it targets, drop earlier effects it made
//! unsupported, and repeat until nothing is left; then check whether what remains is noise.

use std::collections::HashMap;

use pdcal_dataset::{Effect, EffectId};
use pdcal_effects::Sensor;
use pdcal_filter::{Calibration, CalibrationRun, Consistency, Verdict};
use serde::Serialize;

use crate::DiagnoseError;
use crate::candidates::{Signature, score_candidates, score_one, signature};
use crate::consistency::{MAX_RMS_RATIO, Misfit, misfit};
use crate::fit::{CandidateFit, scored};
use crate::forms;
use crate::model::{BaseModel, ModelSpec, changes_filter};
use crate::refit::time_offset_refit;
use crate::residuals::{Residuals, mean_std, residuals, rms};
use crate::run::{DiagnoseConfig, DiagnoseInputs, calibrate_and_residuals, residual_inputs};
use crate::significance::{MIN_PARAMETER_SIGMAS, Significance, significance};

/// Version of `diagnosis.json`: 2 added `unexplained`, the rejected and dropped candidates,
/// the shrink of each round and the parameters in the files' spelling; 3 the significance
/// of each round (fast score and the filter's estimate, in sigmas) and the effects' other
/// forms (`KellyRolloff`, `SaturationPerPhotodiode`).
pub const DIAGNOSIS_FORMAT_VERSION: u32 = 3;

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
}

/// How much a refit shrank the residuals its candidate targets.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Shrink {
    /// The sensor whose residuals were compared.
    pub sensor: &'static str,
    /// Samples compared (the candidate's support, matched before and after).
    pub samples: usize,
    /// RMS over them before, in the sensor's unit (V, nT, rad/s).
    pub rms_before: f64,
    /// RMS over them after.
    pub rms_after: f64,
    /// Fraction of the excess mean square (above the noise variance) removed; for the
    /// magnetometer and gyro, of the whole mean square.
    pub fraction_removed: f64,
    /// Log-likelihood gain of the refit over those samples, nats.
    pub nats: f64,
    /// Whether it meets [`DiagnoseConfig::min_shrink`] and the threshold.
    pub significant: bool,
}

/// What a round did to the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Action {
    /// An effect the model lacked was added.
    Added,
    /// A term the model holds was rescaled (`albedo-gain`).
    Rescaled,
}

/// A significant candidate that was not named, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Rejected {
    /// Effect id.
    pub id: EffectId,
    /// Its score, nats.
    pub score: f64,
    /// Why: its refit failed (a physically invalid refit, e.g. a negative scale factor) or
    /// did not shrink the gap.
    pub reason: String,
}

/// An effect added earlier that a later round made unsupported, removed again.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Dropped {
    /// Effect id.
    pub id: EffectId,
    /// Its score on the residuals of the model without it, nats (at most the threshold).
    pub score: f64,
    /// The gap once dropped.
    pub gap_after: Gap,
}

/// An effect added earlier whose other form fits better once later effects are in the
/// model (a roll-off found before albedo, from the `cosine` base, is fitted to residuals
/// that also carry the missing albedo).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Reformed {
    /// Effect id.
    pub id: EffectId,
    /// The form it had (truth.ron's spelling).
    pub from: Effect,
    /// The form it has now.
    pub to: Effect,
    /// Photodiode residual sum of squares with the old form and with the new, V^2.
    #[serde(rename = "photodiode_rss_V2")]
    pub photodiode_rss_v2: [f64; 2],
    /// The gap once changed.
    pub gap_after: Gap,
}

/// One round that named an effect.
#[derive(Debug, Clone)]
pub struct Round {
    /// Effect id found.
    pub found: EffectId,
    /// Added or rescaled.
    pub action: Action,
    /// The effect as kept, with its fitted (or filter-estimated) values.
    pub effect: Effect,
    /// What gave it away.
    pub evidence: String,
    /// Its score, nats.
    pub score: f64,
    /// Every candidate of the round, best first.
    pub candidates: Vec<CandidateFit>,
    /// Significant candidates tried before it and not named.
    pub rejected: Vec<Rejected>,
    /// Effects of earlier rounds dropped after it.
    pub dropped: Vec<Dropped>,
    /// Effects of earlier rounds refitted (form or shape) after it.
    pub reformed: Vec<Reformed>,
    /// The shrink its refit achieved.
    pub shrink: Shrink,
    /// Its fast score and the filter's estimate of its parameters, as sigmas from the null.
    pub significance: Significance,
    /// Gap before the round.
    pub gap_before: Gap,
    /// Gap after it (and after any drop).
    pub gap_after: Gap,
    /// The residual signature before.
    pub signature_before: Signature,
    /// The same signature after.
    pub signature_after: Signature,
    /// The calibration before the round (for the developer demo's true errors).
    pub calibration_before: Calibration,
    /// The calibration after it.
    pub calibration_after: Calibration,
}

/// The outcome of a diagnosis.
#[derive(Debug, Clone)]
pub struct Diagnosis {
    /// Where it started.
    pub base_model: BaseModel,
    /// Effects of the starting model removed before the first round (their score on the
    /// model without them at most the threshold).
    pub initial_dropped: Vec<Dropped>,
    /// Rounds that named something, in order.
    pub rounds: Vec<Round>,
    /// The candidates of the last check.
    pub final_candidates: Vec<CandidateFit>,
    /// Significant candidates of the last check that were not named, and why.
    pub final_rejected: Vec<Rejected>,
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
    /// Whether the final residuals are consistent with the noise model, and where not.
    pub misfit: Misfit,
    /// The significance threshold used, nats.
    pub threshold: f64,
    /// The shared consistency verdict ([`pdcal_filter::consistency`], the one `calibrate`
    /// writes) of the first model's filter residuals.
    pub base_consistency: Consistency,
    /// The same of the final model's.
    pub consistency: Consistency,
}

/// The shared consistency verdict of a filter run's residuals.
pub fn run_consistency(
    inputs: &DiagnoseInputs<'_>,
    run: &CalibrationRun,
) -> Result<Consistency, DiagnoseError> {
    let mut c = pdcal_filter::consistency::judge(
        &run.residuals,
        run.used_photodiodes.len(),
        run.sensor_sigmas.photodiode_v,
        run.sensor_sigmas.mag_nt,
    );
    let references = inputs.references.into();
    pdcal_filter::dark::judge(&mut c, inputs.telemetry, &references, run)?;
    Ok(c)
}

impl Diagnosis {
    /// The effects of the final model that the rounds named, strongest (highest score)
    /// first, then `unexplained` when the final residuals are not noise; joined by `+`, or
    /// `none`.
    pub fn verdict(&self) -> String {
        let mut named: Vec<&Round> = self
            .rounds
            .iter()
            .filter(|r| self.final_spec.added.iter().any(|e| e.id() == r.found))
            .collect();
        named.sort_by(|a, b| b.score.total_cmp(&a.score));
        let mut parts: Vec<&str> = Vec::new();
        for r in named {
            // An effect dropped and found again counts once, at its best score.
            if !parts.contains(&r.found.as_str()) {
                parts.push(r.found.as_str());
            }
        }
        // The filter's own residuals judged as `calibrate` judges them: a final model
        // whose residuals that verdict calls inconsistent is not explained, whatever the
        // whiteness checks say.
        if !self.misfit.explained || self.consistency.verdict == Verdict::Inconsistent {
            parts.push(UNEXPLAINED);
        }
        if parts.is_empty() {
            "none".to_owned()
        } else {
            parts.join("+")
        }
    }

    /// The estimated parameters of the final calibration (name, unit, value, 1 sigma), e.g.
    /// `albedo_gain`.
    pub fn parameter_estimates(&self) -> &[pdcal_filter::ParameterEstimate] {
        &self.final_run.calibration.parameters
    }

    /// `diagnosis.json`.
    pub fn summary(&self) -> DiagnosisSummary {
        let best = self.final_candidates.first();
        DiagnosisSummary {
            format_version: DIAGNOSIS_FORMAT_VERSION,
            base_model: self.base_model.as_str(),
            initial_dropped: self.initial_dropped.clone(),
            rounds: self.rounds.iter().map(RoundSummary::of).collect(),
            final_model: self.final_spec.effect_ids(),
            verdict: self.verdict(),
            final_check: FinalCheck {
                best: best.map(|c| c.id),
                score: best.map(|c| c.score),
                threshold: self.threshold,
                rejected: self.final_rejected.clone(),
            },
            final_gap: self.final_gap,
            final_parameters: self.final_spec.added.clone(),
            parameter_estimates: self.parameter_estimates().to_vec(),
            unexplained: self.misfit.clone(),
            base_consistency: self.base_consistency.clone(),
            consistency: self.consistency.clone(),
        }
    }
}

/// The verdict's entry for residuals the final model does not explain.
pub const UNEXPLAINED: &str = "unexplained";

/// `diagnosis.json` (cli-contract.md keys, plus detail).
#[derive(Debug, Clone, Serialize)]
pub struct DiagnosisSummary {
    /// Layout version.
    pub format_version: u32,
    /// `cosine` or `paper`.
    pub base_model: &'static str,
    /// Effects of the starting model removed before the first round.
    pub initial_dropped: Vec<Dropped>,
    /// Rounds that named an effect.
    pub rounds: Vec<RoundSummary>,
    /// Effect ids of the final model beyond the direct Sun.
    pub final_model: Vec<EffectId>,
    /// Named effects, strongest first, then `unexplained` if so, joined by `+`, or `none`.
    pub verdict: String,
    /// The check that ended the diagnosis.
    pub final_check: FinalCheck,
    /// The gap with the final model.
    pub final_gap: Gap,
    /// The added effects with their final values (truth.ron's spelling).
    pub final_parameters: Vec<Effect>,
    /// The filter's estimates of the estimated effect parameters, with 1 sigma
    /// (`albedo_gain`, `time_offset_s`, ...).
    pub parameter_estimates: Vec<pdcal_filter::ParameterEstimate>,
    /// The consistency check of the final residuals.
    pub unexplained: Misfit,
    /// The shared verdict (as `calibrate`'s summary.json) on the first model's filter
    /// residuals.
    pub base_consistency: Consistency,
    /// The same on the final model's.
    pub consistency: Consistency,
}

/// One round in `diagnosis.json`.
#[derive(Debug, Clone, Serialize)]
pub struct RoundSummary {
    /// Effect id.
    pub found: EffectId,
    /// `added` or `rescaled`.
    pub action: Action,
    /// What gave it away.
    pub evidence: String,
    /// Score, nats.
    pub score: f64,
    /// Gap before.
    pub gap_before: Gap,
    /// Gap after.
    pub gap_after: Gap,
    /// How much the refit shrank the residuals it targets.
    pub shrink: Shrink,
    /// The fast score's sigmas and the filter's estimate of the effect's parameters.
    pub significance: Significance,
    /// The effect's values as kept (truth.ron's spelling).
    pub parameters: Effect,
    /// The second-best candidate and its score.
    pub runner_up: Option<(EffectId, f64)>,
    /// Significant candidates tried first and not named.
    pub rejected: Vec<Rejected>,
    /// Earlier effects dropped after this round.
    pub dropped: Vec<Dropped>,
    /// Earlier effects changed to their other form after this round.
    pub reformed: Vec<Reformed>,
}

impl RoundSummary {
    fn of(r: &Round) -> Self {
        RoundSummary {
            found: r.found,
            action: r.action,
            evidence: r.evidence.clone(),
            score: r.score,
            gap_before: r.gap_before,
            gap_after: r.gap_after,
            shrink: r.shrink.clone(),
            significance: r.significance.clone(),
            parameters: r.effect.clone(),
            runner_up: r.candidates.get(1).map(|c| (c.id, c.score)),
            rejected: r.rejected.clone(),
            dropped: r.dropped.clone(),
            reformed: r.reformed.clone(),
        }
    }
}

/// The last check: the best remaining candidate and the threshold it failed.
#[derive(Debug, Clone, Serialize)]
pub struct FinalCheck {
    /// Best remaining candidate.
    pub best: Option<EffectId>,
    /// Its score, nats.
    pub score: Option<f64>,
    /// Threshold, nats.
    pub threshold: f64,
    /// Significant candidates whose refit was rejected.
    pub rejected: Vec<Rejected>,
}

/// The model, its calibration and residuals at one point of the search.
struct State {
    spec: ModelSpec,
    run: CalibrationRun,
    res: Residuals,
}

/// Runs the diagnosis from `base`.
pub fn diagnose(
    inputs: &DiagnoseInputs<'_>,
    base: BaseModel,
    config: &DiagnoseConfig,
) -> Result<Diagnosis, DiagnoseError> {
    diagnose_from(inputs, ModelSpec::new(base), config)
}

/// Runs the diagnosis from a model that may already hold effects (a team's own model):
/// each of them is first tested for removal with the same score as any candidate.
pub fn diagnose_from(
    inputs: &DiagnoseInputs<'_>,
    mut spec: ModelSpec,
    config: &DiagnoseConfig,
) -> Result<Diagnosis, DiagnoseError> {
    check_config(config)?;
    let base = spec.base;
    let (run, res) = calibrate_and_residuals(inputs, &mut spec, config)?;
    let base_consistency = run_consistency(inputs, &run)?;
    let initial_residuals = res.clone();
    let mut state = State { spec, run, res };
    let (initial_dropped, _) = drop_unsupported(inputs, config, &mut state, None)?;
    let mut rounds = Vec::new();
    loop {
        let candidates = candidates_of(inputs, config, &state)?;
        let (accepted, rejected) = if rounds.len() < config.max_rounds {
            try_candidates(inputs, config, &state, &candidates)?
        } else {
            (None, Vec::new())
        };
        let Some((best, shrink, significance, next)) = accepted else {
            let mut d = finish(
                inputs,
                base,
                config,
                state,
                rounds,
                candidates,
                rejected,
                initial_residuals,
            )?;
            d.initial_dropped = initial_dropped;
            d.base_consistency = base_consistency;
            return Ok(d);
        };
        let before = state;
        state = next;
        let (dropped, reformed) = drop_unsupported(inputs, config, &mut state, Some(best.id))?;
        rounds.push(Round {
            found: best.id,
            action: if before.spec.contains(EffectId::Albedo) && best.id == EffectId::AlbedoGain {
                Action::Rescaled
            } else {
                Action::Added
            },
            effect: state
                .spec
                .added(best.id)
                .cloned()
                .unwrap_or(best.effect.clone()),
            evidence: best.evidence.clone(),
            score: best.score,
            candidates,
            rejected,
            dropped,
            reformed,
            shrink,
            significance,
            gap_before: gap(&before.res),
            gap_after: gap(&state.res),
            signature_before: signature(best.id, &before.res),
            signature_after: signature(best.id, &state.res),
            calibration_before: before.run.calibration,
            calibration_after: state.run.calibration.clone(),
        });
    }
}

fn check_config(config: &DiagnoseConfig) -> Result<(), DiagnoseError> {
    if config.max_lag_rows == 0 {
        return Err(DiagnoseError::Config {
            field: "max_lag_rows",
            value: 0.0,
            rule: "must be at least 1",
        });
    }
    if !(0.0..1.0).contains(&config.min_shrink) {
        return Err(DiagnoseError::Config {
            field: "min_shrink",
            value: config.min_shrink,
            rule: "must be in 0 ..< 1",
        });
    }
    Ok(())
}

/// The model's factor on the albedo regressor: 0 without albedo, else its gain.
fn albedo_gain(spec: &ModelSpec) -> f64 {
    match spec.added(EffectId::AlbedoGain) {
        _ if !spec.contains(EffectId::Albedo) => 0.0,
        Some(Effect::AlbedoGain { gain }) => *gain,
        _ => 1.0,
    }
}

#[allow(clippy::too_many_arguments)]
fn finish(
    inputs: &DiagnoseInputs<'_>,
    base: BaseModel,
    config: &DiagnoseConfig,
    state: State,
    rounds: Vec<Round>,
    final_candidates: Vec<CandidateFit>,
    final_rejected: Vec<Rejected>,
    initial_residuals: Residuals,
) -> Result<Diagnosis, DiagnoseError> {
    let misfit = misfit(&state.res, inputs.references, albedo_gain(&state.spec));
    let consistency = run_consistency(inputs, &state.run)?;
    Ok(Diagnosis {
        base_consistency: consistency.clone(),
        consistency,
        base_model: base,
        initial_dropped: Vec::new(),
        rounds,
        final_candidates,
        final_rejected,
        final_gap: gap(&state.res),
        final_spec: state.spec,
        final_run: state.run,
        initial_residuals,
        final_residuals: state.res,
        misfit,
        threshold: config.threshold,
    })
}

/// Every candidate of the current model, scored, best first (`time-offset` by refit).
fn candidates_of(
    inputs: &DiagnoseInputs<'_>,
    config: &DiagnoseConfig,
    state: &State,
) -> Result<Vec<CandidateFit>, DiagnoseError> {
    let n_pd = inputs.meta.photodiodes.len();
    let scored = score_candidates(&state.res, &state.spec, n_pd, config.max_lag_rows);
    rescored_by_refit(inputs, &state.spec, config, &state.run, &state.res, scored)
}

/// A candidate that passed, the shrink it achieved, its significance and the state with it.
type Accepted = (CandidateFit, Shrink, Significance, State);

/// Tries the significant candidates best first (at most [`DiagnoseConfig::max_tries`]):
/// the first whose refit succeeds and shrinks the gap it targets is accepted; the others
/// are reported with the reason.
fn try_candidates(
    inputs: &DiagnoseInputs<'_>,
    config: &DiagnoseConfig,
    state: &State,
    candidates: &[CandidateFit],
) -> Result<(Option<Accepted>, Vec<Rejected>), DiagnoseError> {
    let mut rejected = Vec::new();
    let mut significant: Vec<&CandidateFit> = candidates
        .iter()
        .filter(|c| c.score > config.threshold)
        .collect();
    // Nested terms, the simpler first: a significant `albedo-gain` is tried before
    // `albedo-map` (a pattern beyond the common gain), which is otherwise scored on the
    // residuals the gain leaves and is tried again on them in the next round.
    if let (Some(gain), Some(map)) = (
        significant
            .iter()
            .position(|c| c.id == EffectId::AlbedoGain),
        significant.iter().position(|c| c.id == EffectId::AlbedoMap),
    ) && map < gain
    {
        // After the removal the gain sits at `gain - 1`: the map goes right after it.
        let m = significant.remove(map);
        significant.insert(gain, m);
    }
    for &c in significant.iter().take(config.max_tries) {
        let (c, refit) = better_form(inputs, config, state, c);
        let c = &c;
        let reason = match refit {
            Ok(next) => {
                let kept = next.spec.added(c.id).unwrap_or(&c.effect);
                if let Err(e) = kept.check_physical() {
                    rejected.push(Rejected {
                        id: c.id,
                        score: c.score,
                        reason: unphysical(&e),
                    });
                    continue;
                }
                let shrink = shrink(c, &state.res, &next.res, config);
                let sig = significance(c, kept, &next.run, albedo_gain(&state.spec));
                if shrink.significant && sig.agrees() {
                    return Ok((Some((c.clone(), shrink, sig, next)), rejected));
                }
                if shrink.significant {
                    format!(
                        "its refitted parameter is within {MIN_PARAMETER_SIGMAS} sigma of its \
                         null in the filter's own estimate: {}",
                        sig.text()
                    )
                } else {
                    format!(
                        "its refit does not shrink the gap it targets: {} RMS {:.4} -> {:.4} over {} \
                     samples, {:.0} % of the excess removed (at least {:.0} % needed), {:.1} nats",
                        shrink.sensor,
                        shrink.rms_before,
                        shrink.rms_after,
                        shrink.samples,
                        100.0 * shrink.fraction_removed,
                        100.0 * config.min_shrink,
                        shrink.nats
                    )
                }
            }
            Err(e) => format!("its refit failed: {e}"),
        };
        rejected.push(Rejected {
            id: c.id,
            score: c.score,
            reason,
        });
    }
    Ok((None, rejected))
}

/// Why a refit outside its effect's physical range is not named: it says the residuals
/// need something no hardware does, so the base model or the data are wrong.
pub(crate) fn unphysical(e: &pdcal_effects::Invalid) -> String {
    format!(
        "its refit is outside the effect's physical range ({e}): not an explanation, a sign \
         that the base model or the data are wrong"
    )
}

/// Candidate `c`, or its other form when that one is significant too and its refit leaves
/// the smaller photodiode residuals (sum of squares over every sample): the fast fits of
/// two similar shapes (a Kelly roll-off and a raised-cosine taper from 57 to 90 deg differ
/// by a few percent of the output) cannot tell them apart as well as a calibration with
/// each can. With the refit of the one kept.
fn better_form(
    inputs: &DiagnoseInputs<'_>,
    config: &DiagnoseConfig,
    state: &State,
    c: &CandidateFit,
) -> (CandidateFit, Result<State, DiagnoseError>) {
    let first = with_candidate(inputs, config, state, c);
    let Some(other) = c
        .alternative
        .as_deref()
        .filter(|o| o.score > config.threshold)
    else {
        return (c.clone(), first);
    };
    let second = with_candidate(inputs, config, state, other);
    let rss =
        |r: &Result<State, DiagnoseError>| r.as_ref().map_or(f64::INFINITY, |s| pd_rss(&s.res));
    let (rss_first, rss_second) = (rss(&first), rss(&second));
    let note = |kept: &CandidateFit, lost: &CandidateFit, kept_rss: f64, lost_rss: f64| {
        format!(
            "; this form kept over {} by the refits' photodiode residual sums of squares \
             ({kept_rss:.4} V^2 against {lost_rss:.4})",
            effect_form(&lost.effect)
        ) + if kept.score < lost.score {
            " although its fast score is lower"
        } else {
            ""
        }
    };
    if rss_second < rss_first {
        let mut kept = other.clone();
        kept.evidence += &note(other, c, rss_second, rss_first);
        kept.alternative = Some(Box::new(CandidateFit {
            alternative: None,
            ..c.clone()
        }));
        (kept, second)
    } else {
        let mut kept = c.clone();
        kept.evidence += &note(c, other, rss_first, rss_second);
        (kept, first)
    }
}

/// The form of an effect in words, for evidence lines.
fn effect_form(effect: &Effect) -> &'static str {
    match effect {
        Effect::KellyRolloff { .. } => "the Kelly form",
        Effect::FovRolloff { .. } => "the start/cutoff taper",
        Effect::Saturation { .. } => "one common level",
        Effect::SaturationPerPhotodiode { .. } => "a level per photodiode",
        _ => "the other form",
    }
}

/// The state with candidate `c` in the model: calibrated again (unless it does not change
/// what the filter sees) with its constants refined.
fn with_candidate(
    inputs: &DiagnoseInputs<'_>,
    config: &DiagnoseConfig,
    state: &State,
    c: &CandidateFit,
) -> Result<State, DiagnoseError> {
    let mut spec = state.spec.clone();
    spec.added.push(c.effect.clone());
    let (run, res) = if changes_filter(&c.effect) {
        let (run, res) = calibrate_and_residuals(inputs, &mut spec, config)?;
        refine(inputs, &mut spec, config, c.id, run, res)?
    } else {
        let telemetry = spec.corrected_telemetry(inputs.telemetry);
        let screened = crate::run::screened(inputs, &telemetry, config)?;
        let corrected = spec.albedo_model(inputs.albedo);
        let inputs = &DiagnoseInputs {
            albedo: corrected.as_ref().unwrap_or(inputs.albedo),
            ..*inputs
        };
        let res = residuals(
            &residual_inputs(inputs, screened.telemetry(), config),
            &spec,
            &state.run,
        )?;
        (state.run.clone(), res)
    };
    Ok(State { spec, run, res })
}

/// Drops every effect of the model but `newest` whose score on the residuals of the model
/// without it no longer exceeds the threshold (the same evidence measure as for adding);
/// an effect kept that has two forms is fitted again there (either form) and changed when
/// the model with the new fit leaves the smaller photodiode residuals.
fn drop_unsupported(
    inputs: &DiagnoseInputs<'_>,
    config: &DiagnoseConfig,
    state: &mut State,
    newest: Option<EffectId>,
) -> Result<(Vec<Dropped>, Vec<Reformed>), DiagnoseError> {
    let n_pd = inputs.meta.photodiodes.len();
    let earlier: Vec<EffectId> = state
        .spec
        .added
        .iter()
        .map(Effect::id)
        .filter(|&id| Some(id) != newest)
        .collect();
    let mut dropped = Vec::new();
    let mut reformed = Vec::new();
    for id in earlier {
        let mut spec = state.spec.without(id);
        // A model that cannot be calibrated without the effect keeps it.
        let Ok((run, res)) = calibrate_and_residuals(inputs, &mut spec, config) else {
            continue;
        };
        let Some(fit) = score_one(id, &res, n_pd, config.max_lag_rows) else {
            continue;
        };
        let score = if id == EffectId::TimeOffset {
            scored(time_offset_refit(inputs, &spec, config, &run)?, &res).score
        } else {
            fit.score
        };
        if score <= config.threshold {
            dropped.push(Dropped {
                id,
                score,
                gap_after: gap(&res),
            });
            *state = State { spec, run, res };
            continue;
        }
        let without = State { spec, run, res };
        if let Some((next, change)) = other_form(inputs, config, state, &without, &fit) {
            reformed.push(change);
            *state = next;
        }
    }
    reformed.extend(reshape_kelly(inputs, config, state));
    Ok((dropped, reformed))
}

/// A Kelly roll-off in the model given the shape the current residuals ask for
/// ([`forms::kelly_reshaped`]) while that refit gains more than the threshold
/// (`(rss_before - rss_after) / (2 sigma^2)` over every photodiode sample), at most
/// [`MAX_REFINEMENTS`] times. The changes made, as [`Reformed`].
fn reshape_kelly(
    inputs: &DiagnoseInputs<'_>,
    config: &DiagnoseConfig,
    state: &mut State,
) -> Vec<Reformed> {
    let n_pd = inputs.meta.photodiodes.len();
    let mut changes = Vec::new();
    for _ in 0..MAX_REFINEMENTS {
        let Some(current) = state.spec.added(EffectId::FovRolloff).cloned() else {
            break;
        };
        let Some(fit) = forms::kelly_reshaped(&state.res, &current, n_pd, config.max_lag_rows)
        else {
            break;
        };
        let (
            Effect::KellyRolloff {
                exponent: k_new, ..
            },
            Effect::KellyRolloff {
                exponent: k_old, ..
            },
        ) = (&fit.effect, &current)
        else {
            break;
        };
        // The filter estimates kappa; only a new exponent is a new shape.
        if (k_new - k_old).abs() < 1e-9 {
            break;
        }
        let mut spec = state.spec.clone();
        for e in spec
            .added
            .iter_mut()
            .filter(|e| e.id() == EffectId::FovRolloff)
        {
            *e = fit.effect.clone();
        }
        let Ok((run, res)) = calibrate_and_residuals(inputs, &mut spec, config) else {
            break;
        };
        let (old, new) = (pd_rss(&state.res), pd_rss(&res));
        let nats = 0.5 * (old - new) / (res.sigma_pd_v * res.sigma_pd_v).max(f64::MIN_POSITIVE);
        if nats <= config.threshold {
            break;
        }
        let to = spec
            .added(EffectId::FovRolloff)
            .cloned()
            .unwrap_or(fit.effect);
        *state = State { spec, run, res };
        changes.push(Reformed {
            id: EffectId::FovRolloff,
            from: current,
            to,
            photodiode_rss_v2: [old, new],
            gap_after: gap(&state.res),
        });
    }
    changes
}

/// Photodiode residual sum of squares over every sample, V^2.
fn pd_rss(res: &Residuals) -> f64 {
    res.pd.iter().map(|p| p.residual_v * p.residual_v).sum()
}

/// The model `without` plus the effect as fitted again now (`fit`, or its other form when
/// `fit` equals the one `state` holds), when it scores above the threshold and leaves the
/// smaller photodiode residuals than `state`.
fn other_form(
    inputs: &DiagnoseInputs<'_>,
    config: &DiagnoseConfig,
    state: &State,
    without: &State,
    fit: &CandidateFit,
) -> Option<(State, Reformed)> {
    let current = state.spec.added(fit.id)?.clone();
    // Only effects with two forms: their shape parameters (the Kelly exponent, which the
    // filter does not estimate, or a taper's ends) were fitted on the residuals of their
    // round, which may have carried effects found later.
    // Both forms are refitted: the one the fast score prefers on these residuals is not
    // always the one whose calibration fits best (as when the form was first chosen).
    fit.alternative.as_ref()?;
    let (form, next) = std::iter::once(fit)
        .chain(fit.alternative.as_deref())
        .filter(|f| f.effect != current && f.score > config.threshold)
        .filter_map(|f| Some((f, with_candidate(inputs, config, without, f).ok()?)))
        .min_by(|a, b| pd_rss(&a.1.res).total_cmp(&pd_rss(&b.1.res)))?;
    let (old, new) = (pd_rss(&state.res), pd_rss(&next.res));
    (new < old).then(|| {
        let to = next
            .spec
            .added(fit.id)
            .cloned()
            .unwrap_or(form.effect.clone());
        let change = Reformed {
            id: fit.id,
            from: current,
            to,
            photodiode_rss_v2: [old, new],
            gap_after: gap(&next.res),
        };
        (next, change)
    })
}

/// The shrink of the residuals candidate `c` targets from `before` to `after`: its
/// photodiode support (or every sample of its sensor) matched by row.
pub fn shrink(
    c: &CandidateFit,
    before: &Residuals,
    after: &Residuals,
    config: &DiagnoseConfig,
) -> Shrink {
    match c.id.sensor() {
        Sensor::Photodiode => pd_shrink(c, before, after, config),
        Sensor::Magnetometer => {
            let squares = |r: &Residuals| -> HashMap<usize, f64> {
                r.mag
                    .iter()
                    .map(|m| (m.row, m.residual_nt.norm_squared() / 3.0))
                    .collect()
            };
            vector_shrink("magnetometer", squares(before), squares(after), config)
        }
        Sensor::Gyro => {
            let squares = |r: &Residuals| -> HashMap<usize, f64> {
                r.gyro
                    .iter()
                    .map(|g| (g.row, (g.residual_rad / g.dt_s).norm_squared() / 3.0))
                    .collect()
            };
            vector_shrink("gyro", squares(before), squares(after), config)
        }
    }
}

fn pd_shrink(
    c: &CandidateFit,
    before: &Residuals,
    after: &Residuals,
    config: &DiagnoseConfig,
) -> Shrink {
    let after_by_key: HashMap<(usize, usize), f64> = after
        .pd
        .iter()
        .map(|p| ((p.row, p.pd), p.residual_v))
        .collect();
    let support: std::collections::HashSet<(usize, usize)> = c.support.iter().copied().collect();
    let (mut sb, mut sa, mut n) = (0.0, 0.0, 0usize);
    for p in &before.pd {
        let key = (p.row, p.pd);
        if !support.is_empty() && !support.contains(&key) {
            continue;
        }
        if let Some(r_after) = after_by_key.get(&key) {
            sb += p.residual_v * p.residual_v;
            sa += r_after * r_after;
            n += 1;
        }
    }
    let noise_var = before.sigma_pd_v * before.sigma_pd_v;
    let nf = n.max(1) as f64;
    let (ms_before, ms_after) = (sb / nf, sa / nf);
    let excess = (ms_before - noise_var).max(f64::MIN_POSITIVE);
    let fraction_removed = (ms_before - ms_after) / excess;
    let nats = 0.5 * (sb - sa) / noise_var.max(f64::MIN_POSITIVE);
    Shrink {
        sensor: "photodiode",
        samples: n,
        rms_before: ms_before.sqrt(),
        rms_after: ms_after.sqrt(),
        fraction_removed,
        nats,
        // Where the misfit over the support is already within the noise model's bound, the
        // gain alone decides: a small true effect cannot remove a quarter of an excess that
        // is mostly the attitude error's.
        significant: n > 0
            && nats > config.threshold
            && (fraction_removed >= config.min_shrink
                || ms_before.sqrt() <= MAX_RMS_RATIO * before.sigma_pd_v),
    }
}

/// Magnetometer and gyro: the noise of these residuals is not a given sigma (the attitude's
/// own error is in them), so the gain is the unknown-variance likelihood ratio
/// `n/2 ln(ms_before/ms_after)` and the fraction is of the whole mean square.
fn vector_shrink(
    sensor: &'static str,
    before: HashMap<usize, f64>,
    after: HashMap<usize, f64>,
    config: &DiagnoseConfig,
) -> Shrink {
    let (mut sb, mut sa, mut n) = (0.0, 0.0, 0usize);
    for (row, b) in &before {
        if let Some(a) = after.get(row) {
            sb += b;
            sa += a;
            n += 1;
        }
    }
    let nf = n.max(1) as f64;
    let (ms_before, ms_after) = (sb / nf, sa / nf);
    let nats = if ms_before > 0.0 && ms_after > 0.0 {
        // Three components per sample.
        1.5 * nf * (ms_before / ms_after).ln()
    } else {
        0.0
    };
    let fraction_removed = if ms_before > 0.0 {
        1.0 - ms_after / ms_before
    } else {
        0.0
    };
    Shrink {
        sensor,
        samples: n,
        rms_before: ms_before.sqrt(),
        rms_after: ms_after.sqrt(),
        fraction_removed,
        nats,
        significant: n > 0 && ms_after < ms_before && nats > config.threshold,
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
    id: EffectId,
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
        if !last.compose(&again.effect) {
            break;
        }
        (run, res) = calibrate_and_residuals(inputs, spec, config)?;
    }
    Ok((run, res))
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
        if c.id == EffectId::TimeOffset {
            let mut refit = scored(time_offset_refit(inputs, spec, config, run)?, res);
            refit.evidence += &format!("; residual regression: Wald {:.1}", c.wald);
            refit.support = std::mem::take(&mut c.support);
            *c = refit;
        }
    }
    candidates.sort_by(|a, b| b.score.total_cmp(&a.score));
    Ok(candidates)
}

/// The gap of one set of residuals.
pub fn gap(res: &Residuals) -> Gap {
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
    }
}
