//! The half turn about the Sun line. With the Sun alone (no magnetometer) a photodiode
//! acquisition fixes the attitude up to a rotation about the Sun line; only the Earth's
//! albedo on the photodiodes tells that rotation, and the albedo of an attitude and of its
//! half turn about the Sun line are often alike (the lit Earth seen mirrored about the
//! Sun). An extended Kalman filter started in the wrong one of the two basins stays there,
//! confident. So each Sun-only acquisition is followed twice over a probe window, once as
//! acquired and once turned by half a turn, and the start whose predictions the data
//! favour is kept: the predictive likelihood of the same scalar measurements under each
//! (the innovations and their variances are the filter's own, Eq. 25).

use nalgebra::Matrix3;
use pdcal_attitude::Quat;
use serde::Serialize;

use crate::{Sensor, UpdateRecord};

/// Posterior odds, between the two starts with equal prior weight, below which the choice
/// is reported as not decided: the odds of a 3-sigma event (0.27 %).
const DECIDED_ODDS: f64 = (1.0 - 0.0027) / 0.0027;

/// One scalar measurement of a probe: its row, its sensor, and its term of `-2 ln L`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ProbeTerm {
    row: usize,
    sensor: Sensor,
    neg2_ln_l: f64,
    post_fit: f64,
    accepted: bool,
}

impl ProbeTerm {
    /// The term of one scalar update at `row`: `nu^2 / S + ln S`, `S = (bound / 3)^2` the
    /// innovation's variance (the constant `ln 2 pi` left out: it cancels).
    pub(crate) fn new(row: usize, record: &UpdateRecord) -> Option<Self> {
        let variance = (record.bound_3sigma / 3.0).powi(2);
        (variance > 0.0 && variance.is_finite() && record.residual.is_finite()).then(|| ProbeTerm {
            row,
            sensor: record.sensor,
            neg2_ln_l: record.residual.powi(2) / variance + variance.ln(),
            post_fit: record.post_fit,
            accepted: record.accepted,
        })
    }
}

/// Which start the probe kept, and how clearly (`summary.json` `segments[].about_sun_line`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AboutSunLine {
    /// Whether the kept attitude is the acquired one turned by half a turn about the Sun line.
    pub turned: bool,
    /// `-2 ln` of the likelihood ratio of the other start to the kept one over the
    /// measurements both made (>= 0).
    pub neg2_ln_likelihood_ratio: f64,
    /// Scalar measurements both starts made in the probe window.
    pub common_measurements: usize,
    /// Whether the two starts ended the probe at the same attitude (within 3 sigma of
    /// their combined covariance): the filter's own updates then settled the rotation
    /// about the Sun line from either start, and the choice did not matter.
    pub same_end: bool,
    /// Whether the choice holds: the same end, or odds beyond those of a 3-sigma event.
    /// When not, the data did not tell the attitude about the Sun line from its half
    /// turn, and the segment's attitude may be either.
    pub decided: bool,
}

/// The attitude at the end of a probe and its covariance (rad^2, body).
pub(crate) struct ProbeEnd {
    pub(crate) q: Quat,
    pub(crate) p_aa: Matrix3<f64>,
}

impl ProbeEnd {
    /// Whether `other` lies within 3 sigma of this one (the chi-square of 3 degrees of
    /// freedom with the tail of a 3-sigma event, [`crate::gate::chi_square_3_threshold`]).
    fn same_as(&self, other: &ProbeEnd) -> bool {
        let turn = other.q.to_nalgebra() * self.q.to_nalgebra().inverse();
        let a = turn.scaled_axis();
        let p = self.p_aa + other.p_aa;
        p.try_inverse()
            .is_some_and(|info| a.dot(&(info * a)) <= crate::gate::chi_square_3_threshold(3.0))
    }
}

/// The unit-weight variance of a probe's own updates (the square of
/// [`crate::consistency::Dispersion`]'s factor over them), for the sensor noise `sigmas`.
pub(crate) fn variance_factor(terms: &[ProbeTerm], sigmas: crate::SensorSigmas) -> f64 {
    let mut d = crate::consistency::Dispersion::new(sigmas.photodiode_v, sigmas.mag_nt);
    for t in terms {
        d.push_update(t.sensor, t.post_fit, t.accepted);
    }
    d.report().sigma_factor.powi(2)
}

/// Compares the probes of the acquired start (`kept`) and of its half turn (`turned`)
/// over the measurements (row and sensor) both made. The likelihood ratio is divided by
/// `variance_factor`, the unit-weight variance of the start that fits better
/// ([`variance_factor`]): a quasi-likelihood, so that a model whose residuals spread
/// beyond their noise does not decide with the confidence of one that explains them.
pub(crate) fn compare(
    kept: &[ProbeTerm],
    turned: &[ProbeTerm],
    ends: [&ProbeEnd; 2],
    variance_factor: f64,
) -> AboutSunLine {
    let mut sum = [0.0, 0.0];
    let mut common = 0;
    let mut j = 0;
    for a in kept {
        while j < turned.len() && turned[j].row < a.row {
            j += 1;
        }
        let same = turned[j..]
            .iter()
            .take_while(|b| b.row == a.row)
            .find(|b| b.sensor == a.sensor);
        if let Some(b) = same {
            sum[0] += a.neg2_ln_l;
            sum[1] += b.neg2_ln_l;
            common += 1;
        }
    }
    let delta = (sum[0] - sum[1]) / variance_factor.max(1.0);
    let same_end = ends[0].same_as(ends[1]);
    AboutSunLine {
        turned: delta > 0.0,
        neg2_ln_likelihood_ratio: delta.abs(),
        common_measurements: common,
        same_end,
        decided: same_end || delta.abs() > 2.0 * DECIDED_ODDS.ln(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn end(angle_deg: f64, sigma_deg: f64) -> ProbeEnd {
        let half = angle_deg.to_radians() / 2.0;
        ProbeEnd {
            q: Quat::new_normalized(0.0, 0.0, half.sin(), half.cos()).unwrap(),
            p_aa: Matrix3::identity() * sigma_deg.to_radians().powi(2),
        }
    }

    /// Two ends far apart: the choice rests on the likelihood alone.
    fn apart() -> [ProbeEnd; 2] {
        [end(0.0, 1.0), end(180.0, 1.0)]
    }

    fn term(row: usize, pd: usize, neg2_ln_l: f64) -> ProbeTerm {
        ProbeTerm {
            row,
            sensor: Sensor::Photodiode(pd),
            neg2_ln_l,
            post_fit: 0.0,
            accepted: true,
        }
    }

    #[test]
    fn a_start_whose_residuals_spread_beyond_the_noise_decides_less_surely() {
        // Odds of 20 decide at a unit-weight variance of 1; the same over a model whose
        // post-fit residuals spread twice the noise (variance 4) are 5, not decided.
        let kept: Vec<_> = (0..10).map(|k| term(k, 0, 3.0)).collect();
        let turned: Vec<_> = (0..10).map(|k| term(k, 0, 1.0)).collect();
        let [a, b] = apart();
        assert!(compare(&kept, &turned, [&a, &b], 1.0).decided);
        let spread: Vec<_> = turned
            .iter()
            .enumerate()
            .map(|(k, t)| ProbeTerm {
                post_fit: if k % 2 == 0 { 0.02 } else { -0.02 },
                ..*t
            })
            .collect();
        // |post-fit| 0.02 V against a noise whose Gaussian median |x| is 0.01 V: a spread
        // of 2 (to the 12 % histogram bin the median is read from).
        let sigmas = crate::SensorSigmas {
            photodiode_v: 0.01 / 0.674_489_750_196_081_7,
            mag_nt: 300.0,
            gyro_rad_s: 1e-3,
        };
        let factor = variance_factor(&spread, sigmas);
        assert!((3.5..4.5).contains(&factor), "{factor}");
        let c = compare(&kept, &spread, [&a, &b], factor);
        assert!(c.turned && !c.decided, "{c:?}");
        assert!((c.neg2_ln_likelihood_ratio - 20.0 / factor).abs() < 1e-9);
        // Below the noise the factor is 1: a model never decides more surely for it.
        assert_eq!(variance_factor(&turned, sigmas), 1.0);
    }

    #[test]
    fn only_the_measurements_both_starts_made_are_compared() {
        // The turned start made one more, very unlikely, measurement: it must not count.
        let kept = [term(3, 0, 1.0), term(3, 1, 1.0), term(4, 0, 1.0)];
        let turned = [term(3, 0, 2.0), term(3, 2, 100.0), term(4, 0, 2.0)];
        let [a, b] = apart();
        let c = compare(&kept, &turned, [&a, &b], 1.0);
        assert_eq!(c.common_measurements, 2);
        assert!(!c.turned);
        assert!((c.neg2_ln_likelihood_ratio - 2.0).abs() < 1e-12);
        assert!(!c.decided);
    }

    #[test]
    fn the_start_the_data_favour_is_kept_and_decided_beyond_three_sigma_odds() {
        let kept: Vec<_> = (0..10).map(|k| term(k, 0, 3.0)).collect();
        let turned: Vec<_> = (0..10).map(|k| term(k, 0, 1.0)).collect();
        let [a, b] = apart();
        let c = compare(&kept, &turned, [&a, &b], 1.0);
        assert!(c.turned);
        assert!((c.neg2_ln_likelihood_ratio - 20.0).abs() < 1e-12);
        // 2 ln(369.4) = 11.8: 20 is beyond it, 11 would not be.
        assert!(c.decided);
        let turned: Vec<_> = (0..10).map(|k| term(k, 0, 1.9)).collect();
        assert!(!compare(&kept, &turned, [&a, &b], 1.0).decided);
        // Ends 2 deg apart with 1 deg sigmas each (2.0 of a combined 1.41 sigma): the
        // same attitude, so the choice holds however close the likelihoods.
        let (c, d) = (end(0.0, 1.0), end(2.0, 1.0));
        let near = compare(&kept, &turned, [&c, &d], 1.0);
        assert!(near.same_end && near.decided);
        // 6 deg apart is 4.2 combined sigma: not the same.
        let e = end(6.0, 1.0);
        assert!(!compare(&kept, &turned, [&c, &e], 1.0).same_end);
    }

    #[test]
    fn a_term_is_the_gaussian_negative_twice_log_likelihood() {
        let record = UpdateRecord {
            sensor: Sensor::Photodiode(0),
            measured: 1.0,
            residual: 0.2,
            bound_3sigma: 0.3,
            accepted: true,
            post_fit: 0.2,
        };
        let t = ProbeTerm::new(7, &record).unwrap();
        let s: f64 = 0.01;
        assert!((t.neg2_ln_l - (0.04 / s + s.ln())).abs() < 1e-12);
        let bad = UpdateRecord {
            bound_3sigma: 0.0,
            ..record
        };
        assert!(ProbeTerm::new(7, &bad).is_none());
    }
}
