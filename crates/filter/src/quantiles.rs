//! Quantiles of the normal and chi-square distributions the statistical tests of the crate
//! use (the consistency verdict, the gyro's rate test). Two closed forms (Acklam's normal
//! quantile, Wilson-Hilferty's chi-square) instead of a statistics crate: they are all the
//! tests need, to better than 1e-6 of a sigma.

/// The chi-square(`k`) quantile at standard normal quantile `z` (Wilson-Hilferty).
pub fn chi_square_quantile_wh(k: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + z * a.sqrt()).powi(3)
}

/// Sidak's two-sided threshold on `|z|` that holds the family-wise false-alarm rate of
/// `tests` independent tests at `family_rate` (at most that rate for correlated ones).
pub fn sidak_threshold(family_rate: f64, tests: usize) -> f64 {
    let per_test = -((-family_rate).ln_1p() / tests.max(1) as f64).exp_m1();
    normal_quantile(1.0 - per_test / 2.0)
}

/// The standard normal quantile (Acklam's rational approximation, relative error < 1.2e-9).
pub fn normal_quantile(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.383_577_518_672_69e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e1,
        1.615858368580409e2,
        -1.556989798598866e2,
        6.680131188771972e1,
        -1.328068155288572e1,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-3,
        3.224671290700398e-1,
        2.445134137142996,
        3.754408661907416,
    ];
    let tail = |q: f64| {
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    if p < 0.02425 {
        tail((-2.0 * p.ln()).sqrt())
    } else if p > 1.0 - 0.02425 {
        -tail((-2.0 * (1.0 - p).ln()).sqrt())
    } else {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_quantile_matches_known_values() {
        assert!((normal_quantile(0.975) - 1.959964).abs() < 1e-6);
        assert!((normal_quantile(0.9995) - 3.290527).abs() < 1e-6);
        assert!((normal_quantile(0.5)).abs() < 1e-12);
        assert!((normal_quantile(0.01) + 2.326348).abs() < 1e-6);
    }

    #[test]
    fn chi_square_quantile_matches_a_table_value() {
        // chi-square(10) at 0.975: 20.483 (tables); Wilson-Hilferty is within 0.01 there.
        let q = chi_square_quantile_wh(10.0, normal_quantile(0.975));
        assert!((q - 20.483).abs() < 0.02, "{q}");
    }
}
