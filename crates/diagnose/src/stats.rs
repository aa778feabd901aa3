//! The significance of a fitted signature: amplitudes by least squares, and a Wald statistic
//! whose covariance is estimated from the data with a Newey-West (Bartlett-window HAC)
//! estimator over telemetry rows, so that residuals correlated in time (attitude errors of
//! the smoother, model mismatch) and across sensors at the same row do not pass for
//! independent evidence.

use nalgebra::{DMatrix, DVector};

/// One observation of a candidate's regression: residual `r` against signature `s` for
/// parameter `param`, at telemetry row `row`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Entry {
    /// Telemetry row (the time index for the correlation window).
    pub row: usize,
    /// Which amplitude this observation informs.
    pub param: usize,
    /// Residual.
    pub r: f64,
    /// Signature of a unit amplitude.
    pub s: f64,
}

/// Least-squares amplitudes and their HAC Wald statistic.
#[derive(Debug, Clone, PartialEq)]
pub struct WaldFit {
    /// Amplitude per parameter (0 where the parameter has no signature).
    pub amplitudes: Vec<f64>,
    /// `g^T V^-1 g`, `g_p = sum r s`, `V` the HAC covariance of `g`. Equals the
    /// chi-square drop `(RSS_0 - RSS_1)/sigma^2` for white noise of known sigma.
    pub wald: f64,
    /// Observations with a non-zero signature.
    pub samples: usize,
    /// Parameters with a signature.
    pub active: usize,
}

/// Fits one amplitude per parameter (the parameters' supports must be disjoint, as every
/// candidate here builds them) and computes the Wald statistic with a Bartlett window of
/// `max_lag` rows. `noise_var[p]` is the white-noise variance of parameter `p`'s sensor: the
/// covariance's diagonal is kept at least `noise_var sum s^2`, so that a near-perfect fit
/// (clipped samples reproduced exactly) does not make an infinite statistic.
pub fn hac_wald(entries: &[Entry], n_params: usize, max_lag: usize, noise_var: &[f64]) -> WaldFit {
    let mut num = vec![0.0; n_params];
    let mut den = vec![0.0; n_params];
    let mut samples = 0;
    for e in entries.iter().filter(|e| e.s != 0.0 && e.param < n_params) {
        num[e.param] += e.r * e.s;
        den[e.param] += e.s * e.s;
        samples += 1;
    }
    let amplitudes: Vec<f64> = num
        .iter()
        .zip(&den)
        .map(|(n, d)| if *d > 0.0 { n / d } else { 0.0 })
        .collect();
    let active: Vec<usize> = (0..n_params).filter(|&p| den[p] > 0.0).collect();
    let k = active.len();
    if k == 0 {
        return WaldFit {
            amplitudes,
            wald: 0.0,
            samples,
            active: 0,
        };
    }
    let mut slot = vec![usize::MAX; n_params];
    for (j, &p) in active.iter().enumerate() {
        slot[p] = j;
    }
    // Score contributions of the post-fit residuals, summed per row.
    let mut sorted: Vec<&Entry> = entries
        .iter()
        .filter(|e| e.s != 0.0 && e.param < n_params)
        .collect();
    sorted.sort_by_key(|e| e.row);
    let mut rows: Vec<(usize, DVector<f64>)> = Vec::new();
    for e in sorted {
        if rows.last().is_none_or(|(r, _)| *r != e.row) {
            rows.push((e.row, DVector::zeros(k)));
        }
        if let Some((_, z)) = rows.last_mut() {
            z[slot[e.param]] += (e.r - amplitudes[e.param] * e.s) * e.s;
        }
    }
    let mut v = DMatrix::<f64>::zeros(k, k);
    for (i, (row_i, z_i)) in rows.iter().enumerate() {
        v.ger(1.0, z_i, z_i, 1.0);
        for (row_j, z_j) in rows[i + 1..].iter() {
            let lag = row_j - row_i;
            if lag > max_lag {
                break;
            }
            let w = 1.0 - lag as f64 / (max_lag as f64 + 1.0);
            v.ger(w, z_i, z_j, 1.0);
            v.ger(w, z_j, z_i, 1.0);
        }
    }
    for (j, &p) in active.iter().enumerate() {
        let floor = noise_var.get(p).copied().unwrap_or(0.0) * den[p];
        v[(j, j)] = v[(j, j)].max(floor);
    }
    let g = DVector::from_iterator(k, active.iter().map(|&p| num[p]));
    WaldFit {
        amplitudes,
        wald: quadratic_inverse(&v, &g),
        samples,
        active: k,
    }
}

/// `g^T V^-1 g` by Cholesky, with a small ridge when `V` is singular (a parameter whose
/// post-fit score contributions vanish, e.g. a perfect fit).
fn quadratic_inverse(v: &DMatrix<f64>, g: &DVector<f64>) -> f64 {
    let scale = v.diagonal().iter().cloned().fold(0.0, f64::max);
    if scale.is_nan() || scale <= 0.0 {
        return 0.0;
    }
    for ridge in [0.0, 1e-12, 1e-9, 1e-6] {
        let mut m = v.clone();
        for i in 0..m.nrows() {
            m[(i, i)] += ridge * scale;
        }
        if let Some(chol) = m.cholesky() {
            return g.dot(&chol.solve(g));
        }
    }
    0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random sequence (no rand dependency in the library).
    fn noise(n: usize, seed: u64) -> Vec<f64> {
        let mut x = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (0..n)
            .map(|_| {
                // Sum of 12 uniforms - 6: close to a unit Gaussian.
                (0..12)
                    .map(|_| {
                        x = x
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        (x >> 11) as f64 / (1u64 << 53) as f64
                    })
                    .sum::<f64>()
                    - 6.0
            })
            .collect()
    }

    #[test]
    fn white_noise_wald_is_the_chi_square_drop() {
        let n = 4000;
        let e = noise(n, 3);
        let s: Vec<f64> = (0..n).map(|i| (i as f64 * 0.01).sin()).collect();
        let entries: Vec<Entry> = (0..n)
            .map(|i| Entry {
                row: i,
                param: 0,
                r: 0.1 * s[i] + e[i],
                s: s[i],
            })
            .collect();
        let fit = hac_wald(&entries, 1, 0, &[]);
        let ss: f64 = s.iter().map(|x| x * x).sum();
        let rs: f64 = entries.iter().map(|e| e.r * e.s).sum();
        // With lag 0 the HAC variance is sum (e s)^2 ~ sigma^2 sum s^2: within 10 % for
        // 4000 samples (the variance estimate's relative sigma is sqrt(2/n) ~ 2 %).
        let chi2 = rs * rs / ss;
        assert!(
            (fit.wald / chi2 - 1.0).abs() < 0.1,
            "{} vs {chi2}",
            fit.wald
        );
        assert!((fit.amplitudes[0] - 0.1).abs() < 0.05);
    }

    #[test]
    fn correlated_noise_is_not_evidence() {
        // AR(1) noise with correlation time 20 rows and a slowly varying signature: the
        // naive chi-square is inflated by about (1 + rho)/(1 - rho) ~ 39; the HAC Wald stays
        // of order 1 (chi-square with 1 dof: below 10 with probability 0.998).
        let n = 6000;
        let e = noise(n, 7);
        let rho: f64 = 0.95;
        let mut x = 0.0;
        let r: Vec<f64> = e
            .iter()
            .map(|v| {
                x = rho * x + (1.0 - rho * rho).sqrt() * v;
                x
            })
            .collect();
        let entries: Vec<Entry> = (0..n)
            .map(|i| Entry {
                row: i,
                param: 0,
                r: r[i],
                s: 1.0 + (i as f64 * 0.003).sin(),
            })
            .collect();
        let fit = hac_wald(&entries, 1, 200, &[]);
        assert!(fit.wald < 10.0, "{}", fit.wald);
    }
}
