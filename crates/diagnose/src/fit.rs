//! A candidate effect's fit and score, and the pieces every candidate's fit is built from
//! (the catalogue's in [`crate::candidates`], the other forms in `forms`).

use pdcal_dataset::{Effect, EffectId};
use serde::Serialize;

use crate::residuals::{PdSample, Residuals};
use crate::stats::{Entry, WaldFit};

/// One candidate's fit and score.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CandidateFit {
    /// Effect id.
    pub id: EffectId,
    /// The effect with its fitted parameters, as it would be added (for a change of a
    /// term the model holds, `albedo-gain`, the fitted increment as the effect).
    pub effect: Effect,
    /// HAC Wald statistic of the signature's amplitudes (2x the log-likelihood gain).
    pub wald: f64,
    /// Parameters the effect adds (the BIC's k).
    pub parameters: usize,
    /// Observations carrying its signature.
    pub samples: usize,
    /// `wald/2 - k ln(N)/2`, nats; N = all scalar observations.
    pub score: f64,
    /// One line: what was fitted to what.
    pub evidence: String,
    /// The photodiode samples `(row, photodiode)` that carry the signature; empty for the
    /// magnetometer and gyro candidates (all of that sensor's samples).
    #[serde(skip)]
    pub support: Vec<(usize, usize)>,
    /// The effect's other form (`fov-rolloff`: Kelly or start/cutoff; `saturation`: per
    /// photodiode or common), with its own fit and score; the diagnosis refits both when
    /// both are significant and keeps the one whose refit leaves the smaller residuals.
    #[serde(skip)]
    pub alternative: Option<Box<CandidateFit>>,
}

/// `f` with its score: `wald/2 - k ln(N)/2`, N every scalar observation of `res`.
pub(crate) fn scored(mut f: CandidateFit, res: &Residuals) -> CandidateFit {
    let n_obs = (res.pd.len() + 3 * res.mag.len() + 3 * res.gyro.len()).max(2) as f64;
    f.score = 0.5 * f.wald - 0.5 * f.parameters as f64 * n_obs.ln();
    f
}

pub(crate) fn candidate_fit(
    effect: Effect,
    fit: &WaldFit,
    parameters: usize,
    evidence: String,
    support: Vec<(usize, usize)>,
) -> CandidateFit {
    CandidateFit {
        id: effect.id(),
        effect,
        support,
        alternative: None,
        wald: fit.wald,
        parameters,
        samples: fit.samples,
        score: 0.0,
        evidence: format!(
            "{evidence}; Wald {:.1} over {} samples",
            fit.wald, fit.samples
        ),
    }
}

/// The regression entries of a photodiode signature and the samples carrying it.
pub(crate) fn pd_entries_of(
    res: &Residuals,
    signature: impl Fn(&PdSample) -> Option<(usize, f64)>,
) -> (Vec<Entry>, Vec<(usize, usize)>) {
    res.pd
        .iter()
        .filter_map(|p| {
            signature(p).map(|(param, s)| {
                let entry = Entry {
                    row: p.row,
                    param,
                    r: p.residual_v,
                    s,
                };
                (entry, (p.row, p.pd))
            })
        })
        .unzip()
}
