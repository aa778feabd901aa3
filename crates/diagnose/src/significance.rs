//! Whether a named effect's parameter, as the filter estimates it, is away from its null:
//! the fast score (a HAC Wald statistic on the residuals) says the residuals carry the
//! effect's signature; the filter's estimate, with its sigma from the full covariance
//! (attitude, gyro bias and calibration states included), says how well the data pin the
//! parameter down once the calibration can absorb part of it. An effect is named only if
//! both agree (docs/diagnose.md, "A verdict consistent with its sigmas").

use nalgebra::{DMatrix, DVector};
use pdcal_dataset::{Effect, EffectId};
use pdcal_filter::{CalibrationRun, ParameterEstimate};
use serde::Serialize;

use crate::fit::CandidateFit;
use crate::model::parameter_names;

/// Least distance from the null, in sigmas, of a named effect's filter-estimated parameter.
pub const MIN_PARAMETER_SIGMAS: f64 = 3.0;

/// The two measures of one effect's significance, as equivalent normal deviates.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Significance {
    /// The fast score's Wald statistic (`W`, `k` parameters) as a normal deviate: `sqrt(W)`
    /// for one parameter, the Wilson-Hilferty transform of the chi-square for more.
    pub score_sigmas: f64,
    /// The filter's estimate of the effect's parameters, where the filter carries them as
    /// states (`albedo-gain`, `time-offset`, `scale-drift`, `temperature`, the Kelly
    /// roll-off's `kappa`); `None` for effects fitted as fixed constants on the residuals.
    pub filter: Option<FilterSignificance>,
}

impl Significance {
    /// Whether the filter's estimate (where there is one) is more than
    /// [`MIN_PARAMETER_SIGMAS`] from the null.
    pub fn agrees(&self) -> bool {
        self.filter
            .as_ref()
            .is_none_or(|f| f.sigmas > MIN_PARAMETER_SIGMAS)
    }

    /// One line for reports.
    pub fn text(&self) -> String {
        let score = format!("fast score {:.1} sigma", self.score_sigmas);
        match &self.filter {
            None => format!(
                "{score}; fixed constants (no filter state): the score's sigma is the only one"
            ),
            Some(f) => {
                let values: Vec<String> = f
                    .parameters
                    .iter()
                    .take(4)
                    .map(|p| format!("{} = {:.4} +- {:.4}", p.name, p.value, p.sigma))
                    .collect();
                let more = if f.parameters.len() > 4 {
                    format!(" and {} more", f.parameters.len() - 4)
                } else {
                    String::new()
                };
                let common = f.common.as_ref().map_or(String::new(), |c| {
                    format!(
                        "; common form: {} = {:.5} +- {:.5} (one parameter)",
                        c.name, c.value, c.sigma
                    )
                });
                format!(
                    "{score}; filter: {}{more}{common} (null {}), {:.1} sigma from the null \
                     (chi-square {:.1} on {})",
                    values.join(", "),
                    f.null,
                    f.sigmas,
                    f.chi_square,
                    if f.common.is_some() {
                        1
                    } else {
                        f.parameters.len()
                    }
                )
            }
        }
    }
}

/// The filter's estimate of an effect's parameters against their null.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FilterSignificance {
    /// The estimates, 1 sigma each.
    pub parameters: Vec<ParameterEstimate>,
    /// The value meaning "no effect" (0; the model's gain before the round for
    /// `albedo-gain`).
    pub null: f64,
    /// `d^T P^-1 d`, `d` the estimates minus the null and `P` their block of the filter's
    /// final covariance (so the correlations between them are included; the marginal
    /// `sum (d/sigma)^2` when the block cannot be inverted).
    pub chi_square: f64,
    /// As a normal deviate (`|value - null|/sigma` for one parameter).
    pub sigmas: f64,
    /// For an effect in a common form (one rate for every photodiode, `scale-drift`) whose
    /// filter states are per photodiode: their generalised-least-squares mean over the joint
    /// covariance, `a = 1^T P^-1 d / 1^T P^-1 1` with sigma `(1^T P^-1 1)^-1/2`, the one
    /// parameter the form has; `chi_square` and `sigmas` are then its `(a/sigma)^2` and
    /// `|a|/sigma`.
    pub common: Option<ParameterEstimate>,
}

/// A chi-square `x` on `k` degrees of freedom as the two-sided normal deviate of the same
/// tail probability: `sqrt(x)` for `k = 1` (the distance in sigmas), for more the
/// Wilson-Hilferty normal approximation of the chi-square's tail, then the deviate `z` with
/// `P(|N| > z)` equal to it. So "more than 3 sigma" means a tail below 0.27 % whatever `k`.
pub fn chi_square_sigmas(x: f64, k: usize) -> f64 {
    let x = x.max(0.0);
    if k <= 1 {
        return x.sqrt();
    }
    let k = k as f64;
    let v = 2.0 / (9.0 * k);
    let one_sided = ((x / k).cbrt() - (1.0 - v)) / v.sqrt();
    let tail = normal_upper_tail(one_sided);
    // Bisection of P(|N| > z) = tail on 0..40 (the tail is monotone).
    let (mut lo, mut hi) = (0.0, 40.0);
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if 2.0 * normal_upper_tail(mid) > tail {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// `P(N > z)` for a standard normal, from the filter's complementary error function
/// (relative error below 1.2e-7).
fn normal_upper_tail(z: f64) -> f64 {
    0.5 * pdcal_filter::gate::erfc(z / std::f64::consts::SQRT_2)
}

/// The significance of candidate `c`, named with `effect` as kept, from the calibration
/// run after its refit; `null_gain` is the model's albedo gain before the round.
pub fn significance(
    c: &CandidateFit,
    effect: &Effect,
    run: &CalibrationRun,
    null_gain: f64,
) -> Significance {
    let calibration = &run.calibration;
    let score_sigmas = chi_square_sigmas(c.wald, c.parameters.max(1));
    let names = parameter_names(effect);
    let parameters: Vec<ParameterEstimate> = calibration
        .parameters
        .iter()
        .filter(|p| names.contains(&p.name))
        .cloned()
        .collect();
    let filter = (!parameters.is_empty()).then(|| {
        let null = if effect.id() == EffectId::AlbedoGain {
            null_gain
        } else {
            0.0
        };
        let marginal: f64 = parameters
            .iter()
            .filter(|p| p.sigma > 0.0)
            .map(|p| ((p.value - null) / p.sigma).powi(2))
            .sum();
        let chi_square = joint_chi_square(run, &parameters, null).unwrap_or(marginal);
        let joint = FilterSignificance {
            sigmas: chi_square_sigmas(chi_square, parameters.len()),
            parameters: parameters.clone(),
            null,
            chi_square,
            common: None,
        };
        // Per-photodiode states also hold the nested common form (one value for all): a
        // form with one parameter is tested along that direction only; the per-photodiode
        // form falls back to it when the states are not determined one by one but their
        // common value is (a drift shared by all photodiodes is pinned down by all of
        // them together).
        let common = (parameters.len() > 1)
            .then(|| common_estimate(run, &parameters, null))
            .flatten()
            .map(|common| {
                let z = (common.value - null) / common.sigma;
                FilterSignificance {
                    sigmas: z.abs(),
                    chi_square: z * z,
                    parameters,
                    null,
                    common: Some(common),
                }
            });
        match common {
            Some(common) if c.parameters == 1 => common,
            Some(common)
                if joint.sigmas <= MIN_PARAMETER_SIGMAS && common.sigmas > joint.sigmas =>
            {
                common
            }
            _ => joint,
        }
    });
    Significance {
        score_sigmas,
        filter,
    }
}

/// The block of the final covariance over the filter states of `parameters` (by name), and
/// `d`, the estimates minus `null`; `None` when a state is missing.
fn covariance_block(
    run: &CalibrationRun,
    parameters: &[ParameterEstimate],
    null: f64,
) -> Option<(DMatrix<f64>, DVector<f64>)> {
    let extras = run.layout.extras();
    let states: Vec<usize> = parameters
        .iter()
        .map(|p| extras.iter().find(|e| e.name == p.name).map(|e| e.state))
        .collect::<Option<_>>()?;
    let n = states.len();
    let cov = &run.final_covariance;
    if states.iter().any(|&s| s >= cov.nrows() || s >= cov.ncols()) {
        return None;
    }
    let block = DMatrix::from_fn(n, n, |i, j| cov[(states[i], states[j])]);
    let d = DVector::from_iterator(n, parameters.iter().map(|p| p.value - null));
    Some((block, d))
}

/// `d^T P^-1 d` over the filter states of `parameters`, `P` their block of the final
/// covariance; `None` when a state is missing or the block is singular.
fn joint_chi_square(
    run: &CalibrationRun,
    parameters: &[ParameterEstimate],
    null: f64,
) -> Option<f64> {
    let (block, d) = covariance_block(run, parameters, null)?;
    let x = block.cholesky()?.solve(&d);
    let chi = d.dot(&x);
    chi.is_finite().then_some(chi)
}

/// The generalised-least-squares common value of `parameters` (one value shared by all
/// their states) over the joint covariance `P`: `1^T P^-1 x / 1^T P^-1 1`, sigma
/// `(1^T P^-1 1)^-1/2`, named after the first with `common_` before it; `None` when a state
/// is missing or the block is singular.
fn common_estimate(
    run: &CalibrationRun,
    parameters: &[ParameterEstimate],
    null: f64,
) -> Option<ParameterEstimate> {
    let (block, d) = covariance_block(run, parameters, null)?;
    let (mean, sigma) = gls_common(&block, &d)?;
    Some(ParameterEstimate {
        name: format!("common_{}", common_name(&parameters[0].name)),
        unit: parameters[0].unit.clone(),
        value: null + mean,
        sigma,
    })
}

/// The generalised-least-squares estimate of one value `a` with `d = a 1 + e`,
/// `cov(e) = p`: `(1^T p^-1 d / 1^T p^-1 1, (1^T p^-1 1)^-1/2)`; `None` when `p` is not
/// positive definite.
fn gls_common(p: &DMatrix<f64>, d: &DVector<f64>) -> Option<(f64, f64)> {
    let ones = DVector::from_element(d.len(), 1.0);
    let w = p.clone().cholesky()?.solve(&ones);
    let information = ones.dot(&w);
    let mean = w.dot(d) / information;
    let sigma = information.recip().sqrt();
    (mean.is_finite() && sigma.is_finite() && sigma > 0.0).then_some((mean, sigma))
}

/// `pd01_scale_drift_per_h` -> `scale_drift_per_h`: a per-photodiode name without its
/// photodiode.
fn common_name(name: &str) -> &str {
    match name.split_once('_') {
        Some((pd, rest)) if pd.starts_with("pd") => rest,
        _ => name,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi_square_deviates_match_the_normal_tail() {
        // One parameter: the distance in sigmas itself.
        assert!((chi_square_sigmas(9.0, 1) - 3.0).abs() < 1e-12);
        // The 0.27 % upper points (3 sigma two-sided) of chi-square with 3 and 17 degrees
        // of freedom: 14.16 (tables) and 37.70 (series of the regularised gamma function).
        for (x, k) in [(14.16, 3), (37.70, 17)] {
            let z = chi_square_sigmas(x, k);
            assert!((z - 3.0).abs() < 0.05, "{x} on {k}: {z}");
        }
        assert!((2.0 * normal_upper_tail(3.0) - 0.0027).abs() < 1e-6);
        assert!(chi_square_sigmas(17.0, 17) < 1.0);
    }

    #[test]
    fn the_common_value_is_the_weighted_mean_over_the_joint_covariance() {
        // Independent, equal sigmas: the plain mean, sigma / sqrt(n).
        let d = DVector::from_vec(vec![0.004, 0.005, 0.003, 0.006]);
        let p = DMatrix::from_diagonal_element(4, 4, 0.005f64.powi(2));
        let (mean, sigma) = gls_common(&p, &d).expect("positive definite");
        assert!((mean - 0.0045).abs() < 1e-15);
        assert!((sigma - 0.0025).abs() < 1e-15);
        // Independent, unequal sigmas: inverse-variance weights.
        let p = DMatrix::from_diagonal(&DVector::from_vec(vec![1.0, 4.0, 1.0, 4.0]));
        let (mean, sigma) = gls_common(&p, &d).expect("positive definite");
        let w = [1.0, 0.25, 1.0, 0.25];
        let expected = d.iter().zip(w).map(|(x, w)| x * w).sum::<f64>() / 2.5;
        assert!((mean - expected).abs() < 1e-15);
        assert!((sigma - 2.5f64.recip().sqrt()).abs() < 1e-15);
        // A shared error (correlation rho between every pair): the mean's variance
        // s^2 (1 + (n - 1) rho) / n does not shrink below rho s^2.
        let (s2, rho, n) = (1.0, 0.5, 4.0);
        let p = DMatrix::from_fn(4, 4, |i, j| if i == j { s2 } else { rho * s2 });
        let (_, sigma) = gls_common(&p, &d).expect("positive definite");
        assert!((sigma * sigma - s2 * (1.0 + (n - 1.0) * rho) / n).abs() < 1e-12);
        // Not positive definite: no estimate.
        assert!(gls_common(&DMatrix::zeros(4, 4), &d).is_none());
    }
}
