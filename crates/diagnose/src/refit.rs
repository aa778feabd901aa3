//! Refit scores: a candidate the filter can carry as a state is scored by calibrating again
//! with it and comparing the forward filter's innovations, the likelihood ratio test.
//!
//! Why not the residual regression for these: the calibration absorbs most of a time
//! offset before the residuals are formed. With a steady body rate, a late tag is nearly a
//! fixed rotation of every normal (`n^T (s + delta w x s) = (R^T n)^T s`) plus an attitude
//! shift that the magnetometer only partly resists, so the regression on `C n^T (w x s)`
//! sees a third of the offset or less (0.05 s for a 0.3 s offset, seeds 1-3 of the tests).
//! The forward filter's innovations are the prediction-error decomposition of the data's
//! likelihood under the model: with the offset as a state, the filter separates it from the
//! normals as the body rate changes direction, and the log-likelihood gain is the test
//! statistic: a likelihood ratio from a refit with the term added.
//! It costs one forward calibration per round.

use std::collections::HashMap;

use pdcal_filter::{CalibrationRun, ResidualRecord, Sensor};

use crate::DiagnoseError;
use crate::fit::CandidateFit;
use crate::model::ModelSpec;
use crate::run::{DiagnoseConfig, DiagnoseInputs, forward_run};
use pdcal_dataset::Effect;

/// Log-likelihood gain of the forward innovations of `with` over `base`, nats, over the
/// scalar updates both runs accepted (an update one gate rejected is in neither sum, so an
/// outlier the new term explains earns nothing: conservative); and that count.
///
/// Each accepted update contributes `-(nu^2/s + ln s)/2` with `s = H P H^T + R`
/// (`bound_3sigma = 3 sqrt(s)`); the constant `ln 2 pi` cancels.
pub fn innovation_log_likelihood_gain(
    base: &[ResidualRecord],
    with: &[ResidualRecord],
) -> (f64, usize) {
    let base_terms: HashMap<(usize, u8, usize), f64> = base
        .iter()
        .filter(|r| r.accepted)
        .map(|r| (key(r), log_likelihood(r)))
        .collect();
    let (mut gain, mut common) = (0.0, 0);
    for r in with.iter().filter(|r| r.accepted) {
        if let Some(b) = base_terms.get(&key(r)) {
            gain += log_likelihood(r) - b;
            common += 1;
        }
    }
    (gain, common)
}

fn key(r: &ResidualRecord) -> (usize, u8, usize) {
    match r.sensor {
        Sensor::Photodiode(i) => (r.index, 0, i),
        Sensor::Magnetometer(a) => (r.index, 1, a),
    }
}

fn log_likelihood(r: &ResidualRecord) -> f64 {
    let s = (r.bound_3sigma / 3.0).powi(2);
    -0.5 * (r.residual * r.residual / s + s.ln())
}

/// The `time-offset` candidate from a refit: the offset as a filter state starting at 0
/// (prior sigma from the filter configuration, 0.5 s by default), `wald` = twice the
/// innovation log-likelihood gain over `base`, one parameter. The score is left for the
/// caller (the same BIC as every candidate).
pub(crate) fn time_offset_refit(
    inputs: &DiagnoseInputs<'_>,
    spec: &ModelSpec,
    config: &DiagnoseConfig,
    base: &CalibrationRun,
) -> Result<CandidateFit, DiagnoseError> {
    let mut with = spec.clone();
    with.added.push(Effect::TimeOffset { seconds: 0.0 });
    let run = forward_run(inputs, &mut with, config)?;
    let seconds = match with.added.last() {
        Some(Effect::TimeOffset { seconds }) => *seconds,
        _ => 0.0,
    };
    let (gain, common) = innovation_log_likelihood_gain(&base.residuals, &run.residuals);
    // A negative gain (the prior's transient costs more than the state explains) is no
    // evidence at all.
    let wald = 2.0 * gain.max(0.0);
    Ok(CandidateFit {
        id: pdcal_dataset::EffectId::TimeOffset,
        effect: Effect::TimeOffset { seconds },
        support: Vec::new(),
        alternative: None,
        wald,
        parameters: 1,
        samples: common,
        score: 0.0,
        evidence: format!(
            "refit with the photodiode time offset as a filter state: {seconds:.3} s; \
             forward-innovation log-likelihood {gain:+.1} nats over {common} updates"
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(index: usize, sensor: Sensor, residual: f64, sigma: f64) -> ResidualRecord {
        ResidualRecord {
            index,
            t_s: index as f64,
            sensor,
            measured: 0.0,
            residual,
            bound_3sigma: 3.0 * sigma,
            accepted: true,
            post_fit: residual,
            attitude_held: true,
            contradicted: false,
        }
    }

    #[test]
    fn gain_is_the_gaussian_log_likelihood_difference_on_common_updates() {
        let base = vec![
            record(0, Sensor::Photodiode(2), 0.03, 0.015),
            record(0, Sensor::Magnetometer(1), 300.0, 320.0),
            record(1, Sensor::Photodiode(2), -0.02, 0.015),
        ];
        let mut with = base.clone();
        with[0].residual = 0.015;
        with[1].bound_3sigma = 3.0 * 330.0;
        // Only in one run, or rejected: no contribution.
        with[2].accepted = false;
        with.push(record(2, Sensor::Photodiode(0), 5.0, 0.015));
        let (gain, common) = innovation_log_likelihood_gain(&base, &with);
        assert_eq!(common, 2);
        // By hand: photodiode (0.03/0.015)^2 = 4 -> 1: +1.5; magnetometer
        // -(300^2/330^2 + ln 330^2)/2 + (300^2/320^2 + ln 320^2)/2.
        let mag = -0.5 * ((300.0f64 / 330.0).powi(2) + (330.0f64 * 330.0).ln())
            + 0.5 * ((300.0f64 / 320.0).powi(2) + (320.0f64 * 320.0).ln());
        assert!((gain - (1.5 + mag)).abs() < 1e-12, "{gain}");
        // Same runs: no gain.
        assert_eq!(innovation_log_likelihood_gain(&base, &base), (0.0, 3));
    }
}
