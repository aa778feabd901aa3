//! The other forms the field gives two effects of the catalogue, fitted beside the
//! built-in ones and chosen by the same evidence (the score, `W/2 - k ln(N)/2`):
//! - `fov-rolloff` in the Kelly form of other tools' coarse-sun-sensor models,
//!   `K(c) = 1 - exp(-c^k / kappa)` (Basilisk: `k = 2`), beside the raised-cosine
//!   start/cutoff taper;
//! - `saturation` with one clip level per photodiode (each channel's own range), beside
//!   one level for all.

use pdcal_dataset::Effect;
use pdcal_photodiode::KellyRolloff;

use crate::fit::{CandidateFit, candidate_fit, pd_entries_of, scored};
use crate::residuals::Residuals;
use crate::stats::{Entry, hac_wald};

/// Width of the incidence-angle bins of the Kelly search, deg.
const KELLY_BIN_DEG: f64 = 0.25;
/// `log10 kappa` searched: 0.001 to 10 (a loss of e^-1000 to 90 % at normal incidence).
const KELLY_LOG_KAPPA: (f64, f64, usize) = (-3.0, 1.0, 81);
/// Exponents searched: 0.5 to 6 in steps of 0.25.
const KELLY_EXPONENT: (f64, f64, usize) = (0.5, 6.0, 23);

fn grid((lo, hi, n): (f64, f64, usize)) -> impl Iterator<Item = f64> {
    (0..n).map(move |i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
}

/// `fov-rolloff`, Kelly form: the signature `C c (K(c) - 1)` made orthogonal, per
/// photodiode, to `C c` (the calibration's scale factors, fitted inside the filter's gate,
/// absorb the mean loss: a Kelly roll-off of `kappa = 0.3` takes 19 % at 45 deg). Grid
/// search of `kappa` and `k` on per-photodiode binned sums of `r C c` and `(C c)^2`, then
/// the HAC Wald statistic of the amplitude. `None` without lit samples.
pub(crate) fn kelly_rolloff(res: &Residuals, n_pd: usize, lag: usize) -> Option<CandidateFit> {
    let bins = (90.0 / KELLY_BIN_DEG) as usize;
    let mut ry = vec![vec![0.0; bins]; n_pd];
    let mut yy = vec![vec![0.0; bins]; n_pd];
    let lit = |p: &crate::residuals::PdSample| p.direct_v > 0.0 && p.pd < n_pd;
    for p in res.pd.iter().filter(|p| lit(p)) {
        let theta = p.cos_incidence.clamp(-1.0, 1.0).acos().to_degrees();
        let b = ((theta / KELLY_BIN_DEG) as usize).min(bins - 1);
        ry[p.pd][b] += p.residual_v * p.direct_v;
        yy[p.pd][b] += p.direct_v * p.direct_v;
    }
    let centre_cos: Vec<f64> = (0..bins)
        .map(|b| ((b as f64 + 0.5) * KELLY_BIN_DEG).to_radians().cos())
        .collect();
    let mut best: Option<(f64, f64, f64)> = None;
    for log_kappa in grid(KELLY_LOG_KAPPA) {
        let kappa = 10f64.powf(log_kappa);
        for exponent in grid(KELLY_EXPONENT) {
            let g: Vec<f64> = centre_cos
                .iter()
                .map(|c| -(-c.powf(exponent) / kappa).exp())
                .collect();
            let (mut num, mut den) = (0.0, 0.0);
            for pd in 0..n_pd {
                let w: f64 = yy[pd].iter().sum();
                if w <= 0.0 {
                    continue;
                }
                let mean = g.iter().zip(&yy[pd]).map(|(g, y)| g * y).sum::<f64>() / w;
                for b in 0..bins {
                    let d = g[b] - mean;
                    num += d * ry[pd][b];
                    den += d * d * yy[pd][b];
                }
            }
            if den > 0.0 && num > 0.0 {
                let gain = num * num / den;
                if best.is_none_or(|(b, _, _)| gain > b) {
                    best = Some((gain, kappa, exponent));
                }
            }
        }
    }
    let (_, kappa, exponent) = best?;
    let law = KellyRolloff::new(kappa, exponent).ok()?;
    // The per-photodiode mean of the loss over its lit samples, weighted as the fit.
    let mut sum = vec![0.0; n_pd];
    let mut weight = vec![0.0; n_pd];
    for p in res.pd.iter().filter(|p| lit(p)) {
        let y2 = p.direct_v * p.direct_v;
        sum[p.pd] += y2 * (law.factor(p.cos_incidence) - 1.0);
        weight[p.pd] += y2;
    }
    let (entries, support) = pd_entries_of(res, |p| {
        lit(p).then(|| {
            let mean = sum[p.pd] / weight[p.pd];
            (0, p.direct_v * (law.factor(p.cos_incidence) - 1.0 - mean))
        })
    });
    let mut fit = hac_wald(&entries, 1, lag, &[res.sigma_pd_v * res.sigma_pd_v]);
    if fit.amplitudes[0] <= 0.0 {
        fit.wald = 0.0;
    }
    let evidence = format!(
        "photodiode residual vs incidence: Kelly roll-off 1 - exp(-c^{exponent:.2} / \
         {kappa:.4}) (loss {:.1} % at 45 deg, {:.1} % at 60, {:.1} % at 75), amplitude {:.2} \
         beside each photodiode's scale",
        100.0 * (1.0 - law.factor(45f64.to_radians().cos())),
        100.0 * (1.0 - law.factor(60f64.to_radians().cos())),
        100.0 * (1.0 - law.factor(75f64.to_radians().cos())),
        fit.amplitudes[0]
    );
    let effect = Effect::KellyRolloff { kappa, exponent };
    Some(scored(
        candidate_fit(effect, &fit, 2, evidence, support),
        res,
    ))
}

/// The Kelly roll-off fitted again on the residuals of a model that holds `current` (a
/// `KellyRolloff`), with that term taken out of them sample by sample
/// (`r + C c (K(c) - 1)`): the shape the data ask for once the calibration has been made
/// with a roll-off in the model and with the effects found after it. The exponent is not a
/// filter state and the filter sees only incidences inside its gate, so a shape fitted in
/// an earlier round, on residuals that still carried a later round's effect (a missing
/// albedo adds light mostly at high incidence), stays wrong unless fitted again here.
/// `None` for another form or without lit samples.
pub(crate) fn kelly_reshaped(
    res: &Residuals,
    current: &Effect,
    n_pd: usize,
    lag: usize,
) -> Option<CandidateFit> {
    let Effect::KellyRolloff { kappa, exponent } = current else {
        return None;
    };
    let law = KellyRolloff::new(*kappa, *exponent).ok()?;
    let mut without = res.clone();
    for p in without.pd.iter_mut().filter(|p| p.direct_v > 0.0) {
        p.residual_v += p.direct_v * (law.factor(p.cos_incidence) - 1.0);
    }
    kelly_rolloff(&without, n_pd, lag)
}

/// Fewest samples exactly at a photodiode's largest output that make it its clip level.
pub(crate) const MIN_CLIPPED_SAMPLES: usize = 3;

/// The largest of `outputs` and whether the data pile up there as a clipped sensor's do:
/// at least [`MIN_CLIPPED_SAMPLES`] samples exactly at it, and more than lie just below it,
/// within the noise `noise_sigma_v` or one step, whichever is wider. Outputs read by an ADC
/// sit on its codes, and a peak that merely reaches its top code may have several samples
/// there too, but no more than the band below it holds (a smooth peak thins out towards its
/// maximum, and noise spreads its top over the codes below); clipping piles every sample
/// beyond the level onto it. The step is the smallest gap between distinct outputs (one
/// code; for unquantised data a gap no other sample falls in).
pub(crate) fn clip_level(
    outputs: impl Iterator<Item = f64>,
    noise_sigma_v: f64,
) -> Option<(f64, usize)> {
    let mut values: Vec<f64> = outputs.filter(|v| v.is_finite()).collect();
    values.sort_by(|a, b| b.total_cmp(a));
    let level = *values.first()?;
    let at_level = values.iter().take_while(|v| **v >= level).count();
    let step = values
        .windows(2)
        .map(|w| w[0] - w[1])
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    let band = noise_sigma_v.max(step) + 0.5 * step;
    let below = values
        .iter()
        .filter(|v| **v < level && **v >= level - band)
        .count();
    (at_level >= MIN_CLIPPED_SAMPLES && at_level > below).then_some((level, at_level))
}

/// `saturation`, one level per photodiode: photodiode `i`'s clip level is its largest
/// measured output where the data pile up as a clipped sensor's do ([`clip_level`]); signature `min(y, L_i) - y` of the model's pre-stage output, one
/// amplitude per clipped photodiode. A photodiode the data never clip keeps `common`
/// (nothing in the data says where it would clip). `None` when no photodiode clips.
pub(crate) fn saturation_per_photodiode(
    res: &Residuals,
    n_pd: usize,
    common: f64,
    lag: usize,
) -> Option<CandidateFit> {
    let clipped_at: Vec<Option<f64>> = (0..n_pd)
        .map(|i| {
            clip_level(
                res.pd.iter().filter(|p| p.pd == i).map(|p| p.measured_v),
                res.sigma_pd_v,
            )
            .map(|(level, _)| level)
            .filter(|l| *l > 0.0)
        })
        .collect();
    let reached: Vec<bool> = clipped_at.iter().map(Option::is_some).collect();
    let level: Vec<f64> = clipped_at
        .iter()
        .map(|l| l.unwrap_or(f64::NEG_INFINITY))
        .collect();
    if !reached.iter().any(|r| *r) {
        return None;
    }
    let entries: Vec<Entry>;
    let support;
    (entries, support) = pd_entries_of(res, |p| {
        (p.pd < n_pd && reached[p.pd] && p.pre_stage_v > level[p.pd])
            .then(|| (p.pd, level[p.pd] - p.pre_stage_v))
    });
    let mut fit = hac_wald(&entries, n_pd, lag, &vec![res.sigma_pd_v.powi(2); n_pd]);
    // Clipping removes output: a photodiode whose amplitude has the wrong sign is no
    // evidence, and the fit keeps only the others.
    if fit.amplitudes.iter().any(|a| *a < 0.0) {
        let keep: Vec<bool> = fit.amplitudes.iter().map(|a| *a > 0.0).collect();
        let kept: Vec<Entry> = entries.into_iter().filter(|e| keep[e.param]).collect();
        fit = hac_wald(&kept, n_pd, lag, &vec![res.sigma_pd_v.powi(2); n_pd]);
    }
    let volts: Vec<f64> = (0..n_pd)
        .map(|i| if reached[i] { level[i] } else { common })
        .collect();
    let clipped: Vec<String> = (0..n_pd)
        .filter(|&i| reached[i])
        .map(|i| format!("pd{:02} {:.3}", i + 1, level[i]))
        .collect();
    let evidence = format!(
        "photodiode residual vs predicted output, each photodiode clipped at its own largest \
         output ({} of {n_pd} reached, V: {})",
        clipped.len(),
        clipped.join(", ")
    );
    let k = fit.active;
    let effect = Effect::SaturationPerPhotodiode { volts };
    Some(scored(
        candidate_fit(effect, &fit, k, evidence, support),
        res,
    ))
}

/// Latitude bands of the `albedo-map` correction (30 deg each).
pub const ALBEDO_MAP_BANDS: usize = 6;

/// `albedo-map`: one gain per 30-deg latitude band of the point below the spacecraft, on
/// the albedo regressor `C E_a/E_AM0` (either sign: the map may be too bright or too dark
/// there). The visible Earth is a cap of about 25 deg around that point at 600 km, most of
/// its albedo from near its centre, so the band of the nadir stands for the band of the
/// reflecting cells; the correction is then applied to the map cell by cell (piecewise
/// linear between the band centres, [`pdcal_effects::albedo_map_factor`]) and the refit,
/// not this regression, decides whether it shrinks the gap. A constant field is
/// `albedo-gain` with fewer parameters: the score's BIC decides between them.
pub(crate) fn albedo_map(res: &Residuals, lag: usize) -> CandidateFit {
    let (entries, support) = pd_entries_of(res, |p| {
        (p.albedo_v != 0.0).then(|| {
            (
                pdcal_effects::albedo_map_band(ALBEDO_MAP_BANDS, p.nadir_lat_rad),
                p.albedo_v,
            )
        })
    });
    // The pattern beyond one common gain (the constant part is `albedo-gain`'s): the bands
    // are fitted, and their Wald statistic taken, on the residuals left by the common gain
    // (the score test of the pattern given the gain); the effect carries the common gain
    // plus each band's increment.
    let common: Vec<Entry> = entries.iter().map(|e| Entry { param: 0, ..*e }).collect();
    let gain = hac_wald(&common, 1, lag, &[res.sigma_pd_v.powi(2)]);
    let beyond: Vec<Entry> = entries
        .iter()
        .map(|e| Entry {
            r: e.r - gain.amplitudes[0] * e.s,
            ..*e
        })
        .collect();
    let mut fit = hac_wald(
        &beyond,
        ALBEDO_MAP_BANDS,
        lag,
        &[res.sigma_pd_v.powi(2); ALBEDO_MAP_BANDS],
    );
    for a in fit.amplitudes.iter_mut() {
        *a += gain.amplitudes[0];
    }
    let latitude_gains: Vec<f64> = fit.amplitudes.iter().map(|a| (1.0 + a).max(0.0)).collect();
    let bands: Vec<String> = latitude_gains
        .iter()
        .enumerate()
        .map(|(j, g)| {
            let lo = -90.0 + 180.0 * j as f64 / ALBEDO_MAP_BANDS as f64;
            format!(
                "{lo:+.0}..{:+.0} deg {g:.3}",
                lo + 180.0 / ALBEDO_MAP_BANDS as f64
            )
        })
        .collect();
    let evidence = format!(
        "photodiode residual vs C E_a/E_AM0 per latitude band below the spacecraft: map \
         factors {} (common gain {:.3}; Wald beyond it)",
        bands.join(", "),
        1.0 + gain.amplitudes[0]
    );
    let k = fit.active.saturating_sub(1).max(1);
    candidate_fit(
        Effect::AlbedoMap { latitude_gains },
        &fit,
        k,
        evidence,
        support,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::residuals::PdSample;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// A photodiode's outputs over a smooth peak of `peak_v` (a cosine over five turns of a
    /// tumble) with 0.5 mV noise, under the 1.2 mV step of a 12-bit ADC of 5 V, clipped at
    /// `clip_v`, read by that ADC when `quantised`.
    fn peak_outputs(peak_v: f64, clip_v: f64, quantised: bool) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let noise = Normal::new(0.0, 0.0005).unwrap();
        let lsb = 5.0 / 4096.0;
        (0..6000)
            .map(|k| {
                let y = peak_v * (k as f64 * 0.3).to_radians().cos().max(0.0);
                let y = (y + noise.sample(&mut rng)).min(clip_v);
                if quantised {
                    (y / lsb).round() * lsb
                } else {
                    y
                }
            })
            .collect()
    }

    #[test]
    fn a_peak_on_an_adc_code_is_not_clipping_and_a_clipped_one_is() {
        // Unclipped: no level, quantised or not (the top code of a quantised peak holds
        // several samples, but no more than the code below).
        for quantised in [false, true] {
            let outputs = peak_outputs(0.667, f64::INFINITY, quantised);
            let top = outputs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let at_top = outputs.iter().filter(|v| **v >= top).count();
            // Quantised, the top code alone would pass for clipping.
            assert_eq!(
                at_top >= MIN_CLIPPED_SAMPLES,
                quantised,
                "{at_top} at the top"
            );
            assert_eq!(
                clip_level(outputs.into_iter(), 0.0005),
                None,
                "quantised {quantised}"
            );
        }
        // Clipped at 0.6 V: found, with the samples piled there, quantised or not.
        for quantised in [false, true] {
            let outputs = peak_outputs(0.667, 0.6, quantised);
            let (level, at) = clip_level(outputs.into_iter(), 0.0005).expect("clipped");
            assert!((level - 0.6).abs() < 5.0 / 4096.0, "{level}");
            assert!(at > 20, "{at} samples at the level");
        }
        // Noise of several codes: three samples on the top code and fewer on the code
        // below happen by chance, and the band of the noise below holds more.
        let lsb = 5.0 / 4096.0;
        let code = |k: f64| (546.0 - k) * lsb;
        let counts = [3, 2, 3, 2, 3];
        let peak: Vec<f64> = (0..5)
            .flat_map(|k| std::iter::repeat_n(code(k as f64), counts[k]))
            .collect();
        assert_eq!(clip_level(peak.iter().copied(), 0.0055), None);
        // The same band under thirty samples piled on the top code: clipped.
        let piled = peak
            .iter()
            .copied()
            .chain(std::iter::repeat_n(code(0.0), 27));
        assert_eq!(clip_level(piled, 0.0055), Some((code(0.0), 30)));
    }

    /// Lit samples of `n_pd` photodiodes (C = 4 V) over incidences 0-89.9 deg, residuals
    /// of a model holding `model` on data made with `truth` (both Kelly laws).
    fn residuals(n_pd: usize, truth: &KellyRolloff, model: &KellyRolloff) -> Residuals {
        let mut res = Residuals {
            sigma_pd_v: 0.015,
            ..Residuals::default()
        };
        for row in 0..3000 {
            let theta = (row as f64 * 0.03).to_radians();
            let c = theta.cos();
            for pd in 0..n_pd {
                let direct_v = 4.0 * c;
                let residual_v = direct_v * (truth.factor(c) - model.factor(c));
                res.pd.push(PdSample {
                    row,
                    pd,
                    t_s: row as f64,
                    measured_v: direct_v * truth.factor(c),
                    predicted_v: direct_v * model.factor(c),
                    pre_stage_v: direct_v * model.factor(c),
                    residual_v,
                    cos_incidence: c,
                    sun_fraction: 1.0,
                    albedo_v: 0.0,
                    direct_v,
                    unshadowed_v: direct_v,
                    time_offset_v_s: 0.0,
                    scale_v: direct_v,
                    temperature_c: f64::NAN,
                    prediction_sigma_v: 0.0,
                    nadir_lat_rad: 0.0,
                });
            }
        }
        res
    }

    #[test]
    fn a_kelly_shape_fitted_before_is_fitted_again_with_the_term_taken_out() {
        let truth = KellyRolloff::new(0.3, 2.0).expect("law");
        let (kappa, exponent) = (0.28, 2.5);
        let model = KellyRolloff::new(kappa, exponent).expect("law");
        let res = residuals(3, &truth, &model);
        let current = Effect::KellyRolloff { kappa, exponent };
        let fit = kelly_reshaped(&res, &current, 3, 60).expect("lit samples");
        let Effect::KellyRolloff { kappa, exponent } = fit.effect else {
            panic!("not a Kelly law: {:?}", fit.effect);
        };
        assert_eq!(exponent, 2.0);
        // One grid step of log10 kappa is 0.05.
        assert!(
            (kappa.log10() - 0.3f64.log10()).abs() <= 0.05,
            "kappa {kappa}"
        );
        // The same fit on the residuals as they are (the term left in) does not find it.
        let as_is = kelly_rolloff(&res, 3, 60).map(|f| f.effect);
        assert_ne!(as_is, Some(Effect::KellyRolloff { kappa, exponent }));
        // Another form: nothing to reshape.
        let taper = Effect::FovRolloff {
            start_rad: 1.0,
            cutoff_rad: 1.5,
        };
        assert!(kelly_reshaped(&res, &taper, 3, 60).is_none());
    }
}
