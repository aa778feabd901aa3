//! What the photodiodes read where no light reaches them: in the Earth's umbra.
//!
//! The filter updates a photodiode only in full Sun and inside its field of view, as the
//! paper does; there a constant added to its output (a dark current, an ADC or amplifier
//! offset, a reference channel subtracted at the wrong level) is taken up by its scale
//! factor and normal, its residuals stay at the noise, and the scale factor comes out
//! wrong by many of its sigmas with nothing said. In the umbra the model predicts no
//! output at all, whatever the attitude (no sunlit Earth is in view from inside the
//! shadow cylinder either), so the outputs there test the model's additive part alone.
//!
//! The statistic is the median of a photodiode's umbra samples: a front end that clips
//! at zero, an ADC's quantisation, a spike or a few rows whose time tags put them in the
//! umbra a step early leave it where it is. Its standard error is `sqrt(pi / 2)` times the
//! spread over `sqrt(n)`, the spread the larger of the sensor noise and the samples' own
//! (1.4826 times their median absolute deviation): a noise the configuration understates
//! must not make a hair of offset significant. Significance holds the family-wise
//! false-alarm rate of the photodiodes tested at that of one 3-sigma test
//! ([`crate::quantiles::sidak_threshold`]).
//!
//! A significant level is a reason of the consistency verdict when it matters to the
//! calibration: when it is larger than the photodiode's scale-factor sigma. A least-squares
//! scale factor takes up an offset `b` as `b sum(c) / sum(c^2)` (`c` the cosines of the
//! lit updates, at most 1), at least `b`, so such an offset moves it beyond its sigma.
//! Below that, or on a photodiode the run did not use, it is a note.

use serde::Serialize;

use crate::FilterError;
use crate::calibration::Calibration;
use crate::consistency::{Consistency, MIN_JUDGED_UPDATES, Verdict};
use crate::output::CalibrationRun;
use crate::quantiles::sidak_threshold;
use crate::references::References;
use pdcal_dataset::Telemetry;

/// The family-wise false-alarm rate of the photodiodes' tests: one 3-sigma test's.
const FAMILY_FALSE_ALARM: f64 = 0.0027;

/// The standard error of the median of `n` Gaussian samples is this times `sigma / sqrt(n)`.
const MEDIAN_EFFICIENCY: f64 = 1.253_314_137_315_500_3;

/// A Gaussian's sigma over its median absolute deviation.
const MAD_TO_SIGMA: f64 = 1.482_602_218_505_602;

/// One photodiode's output in the umbra (`summary.json` `consistency.dark`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DarkLevel {
    /// `pd01`, ...
    pub channel: String,
    /// Its index, 0-based.
    #[serde(skip)]
    pub index: usize,
    /// Samples in the umbra.
    pub samples: usize,
    /// Their median, V.
    pub median_v: f64,
    /// What the model predicts there (its additive terms: a dark offset; else 0), V.
    pub predicted_v: f64,
    /// The median's standard error, V.
    pub standard_error_v: f64,
    /// `(median - predicted) / standard error`.
    pub z: f64,
    /// `|z|` beyond the family-wise threshold.
    pub significant: bool,
}

/// The umbra levels of every photodiode with at least [`MIN_JUDGED_UPDATES`] umbra samples
/// (a row is in the umbra when its reference's illuminated fraction of the solar disc is
/// 0), judged against `predicted_v`, the model's output there (0 where it has none), with
/// the photodiode noise `noise_sigma_v`.
pub fn dark_levels(
    telemetry: &Telemetry,
    references: &References<'_>,
    predicted_v: &[f64],
    noise_sigma_v: f64,
) -> Result<Vec<DarkLevel>, FilterError> {
    let mut umbra = Vec::new();
    for k in 0..telemetry.len() {
        if references.at(k)?.sun_fraction <= 0.0 {
            umbra.push(k);
        }
    }
    let mut levels: Vec<DarkLevel> = (telemetry.pd_v.iter().enumerate())
        .filter_map(|(i, column)| {
            let mut values: Vec<f64> = (umbra.iter())
                .filter_map(|&k| column.get(k))
                .filter(|v| v.is_finite())
                .collect();
            (values.len() >= MIN_JUDGED_UPDATES).then(|| {
                let channel = format!("pd{:02}", i + 1);
                let predicted = predicted_v.get(i).copied().unwrap_or(0.0);
                let mut l = level(channel, &mut values, predicted, noise_sigma_v);
                l.index = i;
                l
            })
        })
        .collect();
    let threshold = sidak_threshold(FAMILY_FALSE_ALARM, levels.len());
    for l in &mut levels {
        l.significant = l.z.abs() > threshold;
    }
    Ok(levels)
}

/// The level of one photodiode's umbra `values` (reordered), not yet judged.
fn level(channel: String, values: &mut [f64], predicted_v: f64, noise_sigma_v: f64) -> DarkLevel {
    let n = values.len();
    let median_v = median(values);
    let mut deviations: Vec<f64> = values.iter().map(|v| (v - median_v).abs()).collect();
    let spread = (MAD_TO_SIGMA * median(&mut deviations)).max(noise_sigma_v);
    let standard_error_v = MEDIAN_EFFICIENCY * spread / (n as f64).sqrt();
    let z = if standard_error_v > 0.0 {
        (median_v - predicted_v) / standard_error_v
    } else {
        0.0
    };
    DarkLevel {
        channel,
        index: 0,
        samples: n,
        median_v,
        predicted_v,
        standard_error_v,
        z,
        significant: false,
    }
}

/// The median of a non-empty `values` (reordered).
fn median(values: &mut [f64]) -> f64 {
    let mid = values.len() / 2;
    let upper = *values.select_nth_unstable_by(mid, f64::total_cmp).1;
    if values.len() % 2 == 1 {
        return upper;
    }
    let lower = values[..mid]
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    0.5 * (lower + upper)
}

/// Adds `levels` to `c`: a significant level on a used photodiode larger than its
/// scale-factor sigma in `calibration` makes the verdict `inconsistent`; another
/// significant level is a note.
pub fn apply(
    levels: Vec<DarkLevel>,
    calibration: &Calibration,
    used: &[bool],
    c: &mut Consistency,
) {
    for l in levels.iter().filter(|l| l.significant) {
        let offset = l.median_v - l.predicted_v;
        let said = format!(
            "{}: a median {:.4} V over {} samples in the Earth's umbra, where no light reaches \
             it and the model predicts {:.4} V ({:.1} of its standard errors): an offset the \
             model lacks (a dark current, an ADC or reference offset; or time tags that put lit rows \
             in the umbra)",
            l.channel, l.median_v, l.samples, l.predicted_v, l.z
        );
        let used = used.get(l.index).copied().unwrap_or(false);
        match calibration
            .photodiodes
            .get(l.index)
            .map(|p| p.scale_sigma_v)
        {
            Some(sigma) if used && offset.abs() > sigma => {
                c.verdict = Verdict::Inconsistent;
                c.reasons.push(format!(
                    "{said}, which its scale factor takes up by more than its sigma \
                     ({sigma:.4} V); `pdcal diagnose` tests a dark offset"
                ));
            }
            Some(sigma) if used => c.notes.push(format!(
                "{said}, smaller than its scale factor's sigma ({sigma:.4} V)"
            )),
            _ => c
                .notes
                .push(format!("{said}; the run did not use the photodiode")),
        }
    }
    c.dark = levels;
}

/// [`dark_levels`] of `run` on its `telemetry` and `references`, added to `c` by [`apply`]:
/// the one way calibrate and diagnose judge the umbra.
pub fn judge(
    c: &mut Consistency,
    telemetry: &Telemetry,
    references: &References<'_>,
    run: &CalibrationRun,
) -> Result<(), FilterError> {
    let levels = dark_levels(
        telemetry,
        references,
        &run.umbra_output_v,
        run.sensor_sigmas.photodiode_v,
    )?;
    apply(levels, &run.calibration, &run.used_photodiodes, c);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::PdCalibration;
    use crate::consistency::ConsistencyAccumulator;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    const NOISE_V: f64 = 0.01;

    fn noise(n: usize, offset_v: f64, seed: u64) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let d = Normal::new(offset_v, NOISE_V).unwrap();
        (0..n).map(|_| d.sample(&mut rng)).collect()
    }

    fn calibration(scale_sigma_v: f64) -> Calibration {
        let pd = PdCalibration {
            scale_v: 1.0,
            scale_sigma_v,
            azimuth_deg: 0.0,
            azimuth_sigma_deg: Some(1.0),
            elevation_deg: 0.0,
            elevation_sigma_deg: 1.0,
        };
        Calibration {
            format_version: crate::calibration::CALIBRATION_FORMAT_VERSION,
            photodiodes: vec![pd],
            gyro_bias_rad_s: [0.0; 3],
            gyro_bias_sigma_rad_s: [0.0; 3],
            parameters: Vec::new(),
            status: Vec::new(),
        }
    }

    fn judged(values: &mut [f64]) -> DarkLevel {
        let mut l = level("pd01".to_owned(), values, 0.0, NOISE_V);
        l.significant = l.z.abs() > sidak_threshold(FAMILY_FALSE_ALARM, 1);
        l
    }

    #[test]
    fn the_median_of_odd_and_even_counts() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
    }

    #[test]
    fn noise_clipped_at_zero_is_no_offset_and_its_z_is_standard_normal_unclipped() {
        // A front end that clips at zero: half the samples read 0, the mean moves by 0.4
        // sigma (40 standard errors over 10 000 samples), the median does not.
        let mut clipped: Vec<f64> = noise(10_000, 0.0, 1).iter().map(|v| v.max(0.0)).collect();
        let l = judged(&mut clipped);
        assert!(!l.significant && l.median_v == 0.0, "{l:?}");
        // Unclipped, z over many seeds is standard normal: its variance near 1.
        let zs: Vec<f64> = (0..400)
            .map(|s| judged(&mut noise(1_000, 0.0, s)).z)
            .collect();
        let var = zs.iter().map(|z| z * z).sum::<f64>() / zs.len() as f64;
        assert!((0.8..1.25).contains(&var), "variance of z {var}");
    }

    #[test]
    fn an_offset_beyond_the_scale_sigma_is_a_reason_below_it_a_note() {
        let fresh = || ConsistencyAccumulator::new(1, NOISE_V, 1.0).finish();
        let level = judged(&mut noise(2_000, 0.02, 7));
        assert!(
            level.significant && (level.median_v - 0.02).abs() < 0.002,
            "{level:?}"
        );

        let mut c = fresh();
        apply(vec![level.clone()], &calibration(0.005), &[true], &mut c);
        assert_eq!(c.verdict, Verdict::Inconsistent, "{c:?}");
        assert!(c.reasons.iter().any(|r| r.starts_with("pd01: a median")));

        let mut c = fresh();
        apply(vec![level.clone()], &calibration(0.05), &[true], &mut c);
        assert!(c.reasons.iter().all(|r| !r.starts_with("pd01")), "{c:?}");
        assert!(c.notes.iter().any(|n| n.contains("smaller than its scale")));

        let mut c = fresh();
        apply(vec![level], &calibration(0.005), &[false], &mut c);
        assert!(c.notes.iter().any(|n| n.contains("did not use")), "{c:?}");
        assert_eq!(c.dark.len(), 1);
    }
}
