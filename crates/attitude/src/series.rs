//! `sin(x)/x` and `cos(x)` of a small angle by their Taylor series, for the per-update
//! corrections of a filter (rotations of a fraction of a degree), where a libm call costs
//! more than the whole series.

/// Largest angle (radians) for which [`sinc_and_cos`] answers: the first neglected terms,
/// `x^10/11!` and `x^10/10!`, are below 3e-17 there, under the rounding of the results.
pub(crate) const SMALL_ANGLE_RAD: f64 = 0.1;

/// `(sin(x)/x, cos(x))` from `x^2`, nested (Horner) in `x^2` to `x^8`; `None` at or above
/// [`SMALL_ANGLE_RAD`] (and for NaN), where the caller uses libm.
pub(crate) fn sinc_and_cos(x2: f64) -> Option<(f64, f64)> {
    // NaN fails the comparison too.
    let small = x2 < SMALL_ANGLE_RAD * SMALL_ANGLE_RAD;
    if !small {
        return None;
    }
    let sinc = 1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0)));
    let cos = 1.0 - x2 / 2.0 * (1.0 - x2 / 12.0 * (1.0 - x2 / 30.0 * (1.0 - x2 / 56.0)));
    Some((sinc, cos))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_match_libm_to_rounding() {
        // 2 ulps of values near 1: the series and libm round differently.
        for i in 0..=1000 {
            let x = SMALL_ANGLE_RAD * (i as f64 / 1000.0) * 0.999_999;
            let (sinc, cos) = sinc_and_cos(x * x).expect("inside the range");
            let want_sinc = if x > 0.0 { x.sin() / x } else { 1.0 };
            assert!(
                (sinc - want_sinc).abs() <= 4.5e-16,
                "x {x}: {sinc} vs {want_sinc}"
            );
            assert!(
                (cos - x.cos()).abs() <= 4.5e-16,
                "x {x}: {cos} vs {}",
                x.cos()
            );
        }
        assert!(sinc_and_cos(SMALL_ANGLE_RAD * SMALL_ANGLE_RAD).is_none());
        assert!(sinc_and_cos(f64::NAN).is_none());
    }
}
