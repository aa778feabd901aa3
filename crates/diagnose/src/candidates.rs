//! The candidate effects: each fits its own parameters on the residuals of the current
//! model (linear least squares on its signature, or a small grid search for the nonlinear
//! ones), and is scored by its HAC Wald statistic (the log-likelihood gain, twice) minus
//! the BIC penalty of its parameters.

use nalgebra::Vector3;
use pdcal_dataset::{Effect, EffectId};
use pdcal_effects::REFERENCE_TEMPERATURE_C;
use pdcal_photodiode::{FovRolloff, ShadowMode};

use crate::fit::{CandidateFit, candidate_fit, pd_entries_of, scored};
use crate::forms;
use crate::model::ModelSpec;
use crate::residuals::{PdSample, Residuals, in_umbra};
use crate::stats::{Entry, WaldFit, hac_wald};

/// Residual against a candidate's regressor, for the figures.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Signature {
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Regressor values.
    pub x: Vec<f64>,
    /// Residuals.
    pub y: Vec<f64>,
}

impl Signature {
    /// Mean of `y` in `bins` equal bins of `x` over `[lo, hi]` (NaN for empty bins), and
    /// the bin centres.
    pub fn binned(&self, lo: f64, hi: f64, bins: usize) -> (Vec<f64>, Vec<f64>) {
        let bins = bins.max(1);
        let width = (hi - lo) / bins as f64;
        let mut sum = vec![0.0; bins];
        let mut count = vec![0usize; bins];
        if width > 0.0 {
            for (x, y) in self.x.iter().zip(&self.y) {
                if !(x.is_finite() && y.is_finite()) || *x < lo || *x > hi {
                    continue;
                }
                let b = (((x - lo) / width) as usize).min(bins - 1);
                sum[b] += y;
                count[b] += 1;
            }
        }
        let centres = (0..bins).map(|b| lo + (b as f64 + 0.5) * width).collect();
        let means = sum
            .iter()
            .zip(&count)
            .map(|(s, &n)| if n > 0 { s / n as f64 } else { f64::NAN })
            .collect();
        (centres, means)
    }

    /// Smallest and largest finite `x` (or `(0, 1)` when none).
    pub fn x_range(&self) -> (f64, f64) {
        let (lo, hi) = self
            .x
            .iter()
            .filter(|x| x.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &x| {
                (l.min(x), h.max(x))
            });
        if lo < hi { (lo, hi) } else { (0.0, 1.0) }
    }
}

/// The candidates of a model: every effect of the catalogue it does not hold whose
/// signature the data can carry, plus the changes of terms it holds (`albedo-gain` when it
/// has albedo). `temperature` needs temperature columns.
pub fn candidate_ids(spec: &ModelSpec, res: &Residuals) -> Vec<EffectId> {
    EffectId::ALL
        .into_iter()
        .filter(|&id| !spec.contains(id))
        .filter(|&id| match id {
            EffectId::AlbedoGain | EffectId::AlbedoMap => spec.contains(EffectId::Albedo),
            EffectId::Temperature => res.pd.iter().any(|p| p.temperature_c.is_finite()),
            _ => true,
        })
        .collect()
}

/// Scores every candidate of `spec` on `res`; `n_pd` photodiodes, HAC window `max_lag`
/// rows. Sorted best first.
pub fn score_candidates(
    res: &Residuals,
    spec: &ModelSpec,
    n_pd: usize,
    max_lag: usize,
) -> Vec<CandidateFit> {
    let mut fits: Vec<CandidateFit> = candidate_ids(spec, res)
        .into_iter()
        .filter_map(|id| score_one(id, res, n_pd, max_lag))
        .collect();
    fits.sort_by(|a, b| b.score.total_cmp(&a.score));
    fits
}

/// Fits and scores one candidate (whether or not the model already holds it: a second fit
/// of an added effect measures what its fitted constants still miss).
pub fn score_one(
    id: EffectId,
    res: &Residuals,
    n_pd: usize,
    max_lag: usize,
) -> Option<CandidateFit> {
    fit_candidate(id, res, n_pd, max_lag).map(|f| scored(f, res))
}

/// The catalogue's candidates: one fit per effect.
fn fit_candidate(id: EffectId, res: &Residuals, n_pd: usize, lag: usize) -> Option<CandidateFit> {
    match id {
        EffectId::Albedo => Some(albedo(res, lag)),
        EffectId::FovRolloff => Some(better(
            scored(fov_rolloff(res, lag), res),
            forms::kelly_rolloff(res, n_pd, lag),
        )),
        EffectId::DarkOffset => Some(dark_offset(res, n_pd, lag)),
        EffectId::Saturation => {
            let shared = scored(saturation(res, lag), res);
            let level = match shared.effect {
                Effect::Saturation { volts } => volts,
                _ => f64::INFINITY,
            };
            Some(better(
                shared,
                forms::saturation_per_photodiode(res, n_pd, level, lag),
            ))
        }
        EffectId::Penumbra => Some(penumbra(res, lag)),
        EffectId::TimeOffset => Some(time_offset(res, lag)),
        EffectId::ScaleDrift => Some(scale_drift(res, n_pd, lag)),
        EffectId::MagBias => (!res.mag.is_empty()).then(|| mag_bias(res, lag)),
        EffectId::GyroScale => (!res.gyro.is_empty()).then(|| gyro_scale(res, lag)),
        EffectId::AlbedoGain => Some(albedo_gain(res, lag)),
        EffectId::Temperature => Some(temperature(res, n_pd, lag)),
        EffectId::AlbedoMap => Some(forms::albedo_map(res, lag)),
    }
}

/// The better-supported of two forms of one effect: the higher score (`W/2 - k ln(N)/2`,
/// the same evidence that names an effect), the first on a tie.
/// The other is kept as [`CandidateFit::alternative`] of the one returned.
fn better(first: CandidateFit, other: Option<CandidateFit>) -> CandidateFit {
    match other {
        Some(mut o) if o.score > first.score => {
            o.alternative = Some(Box::new(first));
            o
        }
        Some(o) => CandidateFit {
            alternative: Some(Box::new(o)),
            ..first
        },
        None => first,
    }
}

/// A physical effect acts in one direction (albedo and penumbra add light, roll-off and
/// clipping remove it): a fitted amplitude of the wrong sign is no evidence for it.
fn signed(mut fit: WaldFit) -> WaldFit {
    if fit.amplitudes.first().is_some_and(|a| *a <= 0.0) {
        fit.wald = 0.0;
    }
    fit
}

fn pd_var(res: &Residuals) -> f64 {
    res.sigma_pd_v * res.sigma_pd_v
}

/// `albedo`: one gain on `C E_a/E_AM0` at the estimated normal (1 when albedo is missing).
fn albedo(res: &Residuals, lag: usize) -> CandidateFit {
    let (entries, support) = pd_entries_of(res, |p| Some((0, p.albedo_v)));
    let fit = signed(hac_wald(&entries, 1, lag, &[pd_var(res)]));
    let evidence = format!(
        "photodiode residual vs C E_a/E_AM0 (albedo regressor): gain {:.3}",
        fit.amplitudes[0]
    );
    let effect = Effect::Albedo {
        map: res.albedo_map.clone(),
    };
    candidate_fit(effect, &fit, 1, evidence, support)
}

/// Width of the incidence-angle bins of the roll-off search, deg.
const FOV_BIN_DEG: f64 = 0.25;
/// Grid step of the roll-off start and cutoff, deg.
const FOV_STEP_DEG: f64 = 0.5;
/// Smallest roll-off start searched, deg (below, the cosine law is the calibration's).
const FOV_MIN_START_DEG: f64 = 20.0;

/// `fov-rolloff`: grid search of the taper's start and cutoff on binned sums of
/// `r C c` and `(C c)^2` (the gain of a pattern `s = C c (taper - 1)` is
/// `sum 2 g r y - g^2 y^2` per bin), then the Wald statistic of its amplitude.
fn fov_rolloff(res: &Residuals, lag: usize) -> CandidateFit {
    let bins = (90.0 / FOV_BIN_DEG) as usize;
    let mut ry = vec![0.0; bins];
    let mut yy = vec![0.0; bins];
    for p in res.pd.iter().filter(|p| p.direct_v > 0.0) {
        let theta = p.cos_incidence.clamp(-1.0, 1.0).acos().to_degrees();
        let b = ((theta / FOV_BIN_DEG) as usize).min(bins - 1);
        ry[b] += p.residual_v * p.direct_v;
        yy[b] += p.direct_v * p.direct_v;
    }
    let centre_cos: Vec<f64> = (0..bins)
        .map(|b| ((b as f64 + 0.5) * FOV_BIN_DEG).to_radians().cos())
        .collect();
    let mut best = (0.0, 89.0, 90.0);
    let steps = ((90.0 - FOV_MIN_START_DEG) / FOV_STEP_DEG) as usize;
    for i in 0..steps {
        let start = FOV_MIN_START_DEG + i as f64 * FOV_STEP_DEG;
        let mut cutoff = start + FOV_STEP_DEG;
        while cutoff <= 90.0 + 1e-9 {
            if let Ok(law) = FovRolloff::from_deg(start, cutoff.min(90.0)) {
                let first = (start / FOV_BIN_DEG) as usize;
                let gain: f64 = (first..bins)
                    .map(|b| {
                        let g = law.factor(centre_cos[b]) - 1.0;
                        2.0 * g * ry[b] - g * g * yy[b]
                    })
                    .sum();
                if gain > best.0 {
                    best = (gain, start, cutoff.min(90.0));
                }
            }
            cutoff += FOV_STEP_DEG;
        }
    }
    let (_, start, cutoff) = best;
    let law = FovRolloff::from_deg(start, cutoff).ok();
    let (entries, support) = pd_entries_of(res, |p| {
        let law = law.as_ref()?;
        (p.direct_v > 0.0).then(|| (0, p.direct_v * (law.factor(p.cos_incidence) - 1.0)))
    });
    let fit = signed(hac_wald(&entries, 1, lag, &[pd_var(res)]));
    let evidence = format!(
        "photodiode residual vs incidence: raised-cosine roll-off from {start:.1} to {cutoff:.1} deg, \
         amplitude {:.2}",
        fit.amplitudes[0]
    );
    let effect = Effect::FovRolloff {
        start_rad: start.to_radians(),
        cutoff_rad: cutoff.to_radians(),
    };
    candidate_fit(effect, &fit, 2, evidence, support)
}

/// `albedo-gain`: the same regressor as `albedo`, on a model that holds the term: the
/// residual's slope on `C E_a/E_AM0` is the gain's error, either sign (a model with albedo
/// the data lack gives a slope near -1). The effect carries `1 + slope`, the gain that
/// explains the residuals when composed with the model's ([`Effect::compose`]).
fn albedo_gain(res: &Residuals, lag: usize) -> CandidateFit {
    let (entries, support) = pd_entries_of(res, |p| (p.albedo_v != 0.0).then_some((0, p.albedo_v)));
    let fit = hac_wald(&entries, 1, lag, &[pd_var(res)]);
    let gain = 1.0 + fit.amplitudes[0];
    let evidence = format!(
        "photodiode residual vs C E_a/E_AM0 with albedo modelled: albedo term off by {:+.3}, \
         gain {gain:.3}",
        fit.amplitudes[0]
    );
    candidate_fit(Effect::AlbedoGain { gain }, &fit, 1, evidence, support)
}

/// `temperature`: per photodiode, the residual against `C dI/dC (T - mean T)` (the mean is
/// the calibrated scale's), in 1/K; the effect carries the coefficients about the reference
/// temperature.
fn temperature(res: &Residuals, n_pd: usize, lag: usize) -> CandidateFit {
    let (fit, support) = scale_gain_fit(res, n_pd, lag, |p| {
        p.temperature_c.is_finite().then_some(p.temperature_c)
    });
    let (lo, hi) = min_max(&fit.amplitudes);
    let evidence = format!(
        "photodiode residual vs C dI/dC (T - mean T), per photodiode: {:.3} .. {:.3} %/K",
        100.0 * lo,
        100.0 * hi
    );
    let k = fit.active;
    let effect = Effect::Temperature {
        coefficient_per_k: fit.amplitudes.clone(),
        reference_c: REFERENCE_TEMPERATURE_C,
    };
    candidate_fit(effect, &fit, k, evidence, support)
}

/// Smallest and largest of `values` (infinities when empty), for the evidence lines.
fn min_max(values: &[f64]) -> (f64, f64) {
    values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        })
}

/// `dark-offset`: per-photodiode mean residual in umbra (no direct Sun, no albedo).
fn dark_offset(res: &Residuals, n_pd: usize, lag: usize) -> CandidateFit {
    let (entries, support) = pd_entries_of(res, |p| in_umbra(p).then_some((p.pd, 1.0)));
    let fit = hac_wald(&entries, n_pd, lag, &vec![pd_var(res); n_pd]);
    let (lo, hi) = min_max(&fit.amplitudes);
    let evidence = format!(
        "photodiode residual in umbra, per photodiode: offsets {:.4} .. {:.4} V",
        lo, hi
    );
    let effect = Effect::DarkOffset {
        volts: fit.amplitudes.clone(),
    };
    let k = fit.active;
    candidate_fit(effect, &fit, k, evidence, support)
}

/// `saturation`: the clip level is the largest measured output (a real sensor clips after
/// noise, so clipped samples sit exactly on it); signature `min(y, L) - y` of the model's
/// pre-stage output `y`.
fn saturation(res: &Residuals, lag: usize) -> CandidateFit {
    let largest = res
        .pd
        .iter()
        .map(|p| p.measured_v)
        .fold(f64::NEG_INFINITY, f64::max);
    // The largest output is always at the largest output: clipping shows as samples piled
    // up exactly there ([`forms::clip_level`]).
    let clipped = forms::clip_level(res.pd.iter().map(|p| p.measured_v), res.sigma_pd_v);
    let (level, at_level) = clipped.unwrap_or((largest, 0));
    let (entries, support) = pd_entries_of(res, |p| {
        (p.pre_stage_v > level).then_some((0, level - p.pre_stage_v))
    });
    let mut fit = signed(hac_wald(&entries, 1, lag, &[pd_var(res)]));
    if clipped.is_none() {
        fit.wald = 0.0;
    }
    let evidence = format!(
        "photodiode residual vs predicted output: clipped at {level:.4} V ({at_level} samples \
         exactly there), amplitude {:.2}",
        fit.amplitudes[0]
    );
    let effect = Effect::Saturation { volts: level };
    candidate_fit(effect, &fit, 1, evidence, support)
}

/// `penumbra`: gain on `(nu - hard(nu)) C n^T s` while the Sun is partly hidden.
fn penumbra(res: &Residuals, lag: usize) -> CandidateFit {
    let (entries, support) = pd_entries_of(res, |p| {
        let nu = p.sun_fraction;
        (nu > 0.0 && nu < 1.0 && p.unshadowed_v > 0.0)
            .then(|| (0, (nu - ShadowMode::Hard.factor(nu)) * p.unshadowed_v))
    });
    let fit = signed(hac_wald(&entries, 1, lag, &[pd_var(res)]));
    let evidence = format!(
        "photodiode residual vs (nu - hard(nu)) C n^T s in penumbra: gain {:.2}",
        fit.amplitudes[0]
    );
    candidate_fit(Effect::Penumbra, &fit, 1, evidence, support)
}

/// `time-offset`: photodiodes sampled `delta` late see `s + delta (w x s)`. The filter's
/// attitude can follow the photodiodes part of the way (`A(t - g delta)`), moving that part
/// of the signature into the magnetometer (`-g delta w x b`); both amplitudes are fitted
/// (`a_pd = (1 - g) delta`, `a_mag = -g delta`, so `delta = a_pd - a_mag`), two parameters.
fn time_offset(res: &Residuals, lag: usize) -> CandidateFit {
    let (mut entries, support) = pd_entries_of(res, |p| {
        (p.time_offset_v_s != 0.0).then_some((0, p.time_offset_v_s))
    });
    for m in &res.mag {
        for a in 0..3 {
            entries.push(Entry {
                row: m.row,
                param: 1,
                r: m.residual_nt[a],
                s: m.time_offset_nt_s[a],
            });
        }
    }
    let fit = hac_wald(&entries, 2, lag, &[pd_var(res), res.sigma_mag_nt.powi(2)]);
    let (a_pd, a_mag) = (fit.amplitudes[0], fit.amplitudes[1]);
    let seconds = a_pd - a_mag;
    let evidence = format!(
        "photodiode residual vs C n^T (w x s): {a_pd:.3} s; magnetometer residual vs w x b: \
         {:.3} s; offset {seconds:.3} s",
        -a_mag
    );
    let k = fit.active;
    candidate_fit(Effect::TimeOffset { seconds }, &fit, k, evidence, support)
}

/// A relative scale change linear in `x` per photodiode (`scale-drift`: time in hours;
/// `temperature`: degrees): the residual regressed on `C dI/dC (x - mean x)`, the mean
/// weighted by `(C dI/dC)^2` per photodiode, so that a constant scale error (the
/// calibration's) carries no signature. Samples where `x` is `None` are left out.
fn scale_gain_fit(
    res: &Residuals,
    n_pd: usize,
    lag: usize,
    x: impl Fn(&PdSample) -> Option<f64>,
) -> (WaldFit, Vec<(usize, usize)>) {
    let (entries, support) = scale_gain_entries(res, n_pd, x);
    let fit = hac_wald(&entries, n_pd, lag, &vec![pd_var(res); n_pd]);
    (fit, support)
}

/// The regression entries of [`scale_gain_fit`] (parameter = photodiode) and their samples.
fn scale_gain_entries(
    res: &Residuals,
    n_pd: usize,
    x: impl Fn(&PdSample) -> Option<f64>,
) -> (Vec<Entry>, Vec<(usize, usize)>) {
    let usable = |p: &PdSample| (p.scale_v > 0.0 && p.pd < n_pd).then(|| x(p)).flatten();
    let mut sum = vec![0.0; n_pd];
    let mut weight = vec![0.0; n_pd];
    for p in &res.pd {
        if let Some(v) = usable(p) {
            let w = p.scale_v * p.scale_v;
            sum[p.pd] += w * v;
            weight[p.pd] += w;
        }
    }
    let mean: Vec<f64> = sum
        .iter()
        .zip(&weight)
        .map(|(s, w)| if *w > 0.0 { s / w } else { 0.0 })
        .collect();
    pd_entries_of(res, |p| {
        usable(p).map(|v| (p.pd, p.scale_v * (v - mean[p.pd])))
    })
}

/// `scale-drift`: per photodiode, the residual against `C dI/dC t/3600` made orthogonal to
/// `C dI/dC` (a constant scale error is the calibration's, not an effect); or one drift
/// common to every photodiode (the same regressors, one amplitude: a degradation of the
/// whole sensor head, or its electronics), whichever scores higher. The common form is
/// returned with `parameters == 1` and the same rate on every photodiode, and no
/// alternative: both forms start the same per-photodiode filter states, so a refit cannot
/// tell them apart and the score's BIC decides.
fn scale_drift(res: &Residuals, n_pd: usize, lag: usize) -> CandidateFit {
    let (fit, support) = scale_gain_fit(res, n_pd, lag, |p| Some(p.t_s / 3600.0));
    let (lo, hi) = min_max(&fit.amplitudes);
    let evidence = format!(
        "photodiode residual vs C dI/dC t, per photodiode: {:.2} .. {:.2} %/h",
        100.0 * lo,
        100.0 * hi
    );
    let k = fit.active;
    let effect = Effect::ScaleDrift {
        fraction_per_hour: fit.amplitudes.clone(),
    };
    let per_pd = scored(candidate_fit(effect, &fit, k, evidence, support), res);
    let common = scored(common_scale_drift(res, n_pd, lag), res);
    if common.score > per_pd.score {
        common
    } else {
        per_pd
    }
}

/// `scale-drift` in its common form: one rate for every photodiode, fitted on the
/// per-photodiode signatures of [`scale_gain_fit`] pooled into one amplitude.
fn common_scale_drift(res: &Residuals, n_pd: usize, lag: usize) -> CandidateFit {
    let (entries, support) = scale_gain_entries(res, n_pd, |p| Some(p.t_s / 3600.0));
    let pooled: Vec<Entry> = entries.iter().map(|e| Entry { param: 0, ..*e }).collect();
    let fit = hac_wald(&pooled, 1, lag, &[pd_var(res)]);
    let rate = fit.amplitudes[0];
    let evidence = format!(
        "photodiode residual vs C dI/dC t, one rate for all photodiodes: {:.3} %/h",
        100.0 * rate
    );
    let effect = Effect::ScaleDrift {
        fraction_per_hour: vec![rate; n_pd],
    };
    candidate_fit(effect, &fit, 1, evidence, support)
}

/// `mag-bias`: body-frame mean of the magnetometer residuals.
fn mag_bias(res: &Residuals, lag: usize) -> CandidateFit {
    let entries: Vec<Entry> = res
        .mag
        .iter()
        .flat_map(|m| {
            (0..3).map(move |a| Entry {
                row: m.row,
                param: a,
                r: m.residual_nt[a],
                s: 1.0,
            })
        })
        .collect();
    let fit = hac_wald(&entries, 3, lag, &[res.sigma_mag_nt.powi(2); 3]);
    let b = [fit.amplitudes[0], fit.amplitudes[1], fit.amplitudes[2]];
    let evidence = format!(
        "magnetometer residual mean, body frame: [{:.0}, {:.0}, {:.0}] nT",
        b[0], b[1], b[2]
    );
    candidate_fit(
        Effect::MagBias { bias_nt: b },
        &fit,
        3,
        evidence,
        Vec::new(),
    )
}

/// Rows per block over which a gyro-bias error counts as constant (10 min at 1 Hz; the
/// bias walk of the built-in gyros moves it by about 1e-4 deg/s in that time).
const GYRO_BLOCK_ROWS: usize = 600;
/// Signal-to-noise an axis's rate variation needs to carry a gyro-scale signature.
const GYRO_MIN_SNR: f64 = 10.0;

/// `gyro-scale`: a gyro reading `(1 + e) w` turns the attitude by `e w dt` more than the
/// measurements allow, so the smoothed attitude's step rotation minus the gyro's is
/// `-e w dt` per axis. A bias error adds a slowly varying term: the signature is the gyro
/// rotation minus its mean over blocks of [`GYRO_BLOCK_ROWS`] rows, which also leaves an
/// axis whose rate stays constant (a spin axis, where scale and bias cannot be told apart)
/// without a signature. The regressor is the gyro rotation from the samples *around* the
/// step ([`crate::residuals::GyroSample::rotation_nearby_rad`]): the step's own samples carry
/// gyro noise that is also in the residual and would pass for a scale error.
fn gyro_scale(res: &Residuals, lag: usize) -> CandidateFit {
    let block = |row: usize| row / GYRO_BLOCK_ROWS;
    let blocks = res.gyro.last().map_or(0, |g| block(g.row) + 1);
    let mut sum = vec![Vector3::<f64>::zeros(); blocks];
    let mut count = vec![0usize; blocks];
    for g in &res.gyro {
        sum[block(g.row)] += g.rotation_nearby_rad;
        count[block(g.row)] += 1;
    }
    let mean: Vec<Vector3<f64>> = sum
        .iter()
        .zip(&count)
        .map(|(s, &n)| s / n.max(1) as f64)
        .collect();
    // An axis carries a signature only where the rate varies well above the regressor's own
    // noise (std of the block-demeaned rate >= GYRO_MIN_SNR times the noise of a mean of
    // 2 NEARBY samples); a spin axis at constant rate does not, and fitting it would fit
    // noise shared between the regressor and the smoothed attitude.
    let mut var = Vector3::<f64>::zeros();
    for g in &res.gyro {
        let d = (g.rotation_nearby_rad - mean[block(g.row)]) / g.dt_s;
        var += d.component_mul(&d);
    }
    var /= res.gyro.len().max(1) as f64;
    let noise_var = res.sigma_gyro_rad_s.powi(2) / (2 * crate::residuals::NEARBY) as f64;
    let usable: Vec<bool> = (0..3)
        .map(|a| var[a] >= GYRO_MIN_SNR.powi(2) * noise_var)
        .collect();
    let entries: Vec<Entry> = res
        .gyro
        .iter()
        .flat_map(|g| {
            let m = mean[block(g.row)];
            let usable = &usable;
            (0..3).filter(move |&a| usable[a]).map(move |a| Entry {
                row: g.row,
                param: a,
                r: g.residual_rad[a],
                s: -(g.rotation_nearby_rad[a] - m[a]),
            })
        })
        .collect();
    let fit = hac_wald(&entries, 3, lag, &[]);
    let e = [fit.amplitudes[0], fit.amplitudes[1], fit.amplitudes[2]];
    let k = fit.active;
    let evidence = format!(
        "attitude step rotation beyond the gyro vs the gyro rotation: scale errors \
         [{:.4}, {:.4}, {:.4}]",
        e[0], e[1], e[2]
    );
    let effect = Effect::GyroScale { scale_error: e };
    candidate_fit(effect, &fit, k, evidence, Vec::new())
}

/// The residual signature that tells effect `id` apart: its regressor against the
/// residual of the sensor it affects.
pub fn signature(id: EffectId, res: &Residuals) -> Signature {
    let pd = |x_label: &str, f: &dyn Fn(&PdSample) -> Option<(f64, f64)>| {
        let (x, y) = res.pd.iter().filter_map(f).unzip();
        Signature {
            x_label: x_label.to_owned(),
            y_label: "photodiode residual (V)".to_owned(),
            x,
            y,
        }
    };
    match id {
        EffectId::Albedo | EffectId::AlbedoGain => {
            pd("C E_a/E_AM0 at the estimated normal (V)", &|p| {
                Some((p.albedo_v, p.residual_v))
            })
        }
        EffectId::FovRolloff => pd("incidence angle (deg)", &|p| {
            (p.direct_v > 0.0).then(|| {
                (
                    p.cos_incidence.clamp(-1.0, 1.0).acos().to_degrees(),
                    p.residual_v,
                )
            })
        }),
        EffectId::DarkOffset => pd("photodiode (umbra samples)", &|p| {
            in_umbra(p).then(|| ((p.pd + 1) as f64, p.residual_v))
        }),
        EffectId::Saturation => pd("predicted output before clipping (V)", &|p| {
            (p.pre_stage_v > 0.0).then_some((p.pre_stage_v, p.residual_v))
        }),
        EffectId::Penumbra => pd("illuminated fraction of the Sun", &|p| {
            (p.sun_fraction > 0.0 && p.sun_fraction < 1.0 && p.unshadowed_v > 0.0)
                .then_some((p.sun_fraction, p.residual_v))
        }),
        EffectId::TimeOffset => pd("C n^T (w x s) (V/s)", &|p| {
            (p.time_offset_v_s != 0.0).then_some((p.time_offset_v_s, p.residual_v))
        }),
        EffectId::ScaleDrift => {
            let mut sig = pd("time (min)", &|p| {
                (p.direct_v > 1.0).then(|| (p.t_s / 60.0, p.residual_v / p.scale_v))
            });
            sig.y_label = "relative photodiode residual r / (C dI/dC)".to_owned();
            sig
        }
        EffectId::MagBias => {
            let (x, y) = res
                .mag
                .iter()
                .flat_map(|m| (0..3).map(move |a| ((a + 1) as f64, m.residual_nt[a])))
                .unzip();
            Signature {
                x_label: "magnetometer axis (1 = x, 2 = y, 3 = z)".to_owned(),
                y_label: "magnetometer residual (nT)".to_owned(),
                x,
                y,
            }
        }
        EffectId::GyroScale => {
            let (x, y) = res
                .gyro
                .iter()
                .flat_map(|g| {
                    (0..3).map(move |a| (g.rotation_rad[a] / g.dt_s, g.residual_rad[a] / g.dt_s))
                })
                .unzip();
            Signature {
                x_label: "gyro rate, any axis (rad/s)".to_owned(),
                y_label: "smoothed minus gyro rate (rad/s)".to_owned(),
                x,
                y,
            }
        }
        EffectId::AlbedoMap => {
            let mut sig = pd("latitude below the spacecraft (deg)", &|p| {
                // Samples with albedo well above the noise: the ratio is noise elsewhere.
                (p.albedo_v > 3.0 * res.sigma_pd_v)
                    .then(|| (p.nadir_lat_rad.to_degrees(), p.residual_v / p.albedo_v))
            });
            sig.y_label = "photodiode residual / C E_a/E_AM0 (map factor - 1)".to_owned();
            sig
        }
        EffectId::Temperature => {
            let mut sig = pd("photodiode temperature (C)", &|p| {
                (p.direct_v > 1.0 && p.temperature_c.is_finite())
                    .then(|| (p.temperature_c, p.residual_v / p.scale_v))
            });
            sig.y_label = "relative photodiode residual r / (C dI/dC)".to_owned();
            sig
        }
    }
}
