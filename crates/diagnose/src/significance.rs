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
                format!(
                    "{score}; filter: {}{more} (null {}), {:.1} sigma from the null \
                     (chi-square {:.1} on {})",
                    values.join(", "),
                    f.null,
                    f.sigmas,
                    f.chi_square,
                    f.parameters.len()
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
        FilterSignificance {
            sigmas: chi_square_sigmas(chi_square, parameters.len()),
            parameters,
            null,
            chi_square,
        }
    });
    Significance {
        score_sigmas,
        filter,
    }
}

/// `d^T P^-1 d` over the filter states of `parameters` (by name), `P` their block of the
/// final covariance; `None` when a state is missing or the block is singular.
fn joint_chi_square(
    run: &CalibrationRun,
    parameters: &[ParameterEstimate],
    null: f64,
) -> Option<f64> {
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
    let x = block.cholesky()?.solve(&d);
    let chi = d.dot(&x);
    chi.is_finite().then_some(chi)
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
}
