//! The one judgement of whether a run's residuals are consistent with the model: the
//! verdict `calibrate` writes to `summary.json` (and prints, and shows in index.html), the
//! one `diagnose` reports for its models, and the one the Python API reads back. One piece
//! of code, so they cannot contradict each other.
//!
//! Three figures per sensor class and per photodiode, each answering its own question:
//! - **The residuals' spread against the sensor noise alone**, over every accepted update.
//!   It does not read the covariance at all, so a filter whose attitude sigma has grown to
//!   tens of degrees cannot talk its way past it: residuals several times the noise mean
//!   the model and the data disagree, whatever the bounds say. The spread judged is the
//!   robust one, the median absolute residual over its Gaussian value (`0.6745 sigma`): the
//!   first minutes of a run, while the scale factors and normals converge from their prior,
//!   give residuals far beyond the noise that say nothing about the model, and a median is
//!   not moved by them as long as they are a minority. The RMS is reported beside it. The
//!   filter's own state errors (attitude, calibration) add to the residuals, which is why
//!   the bound is [`MAX_RMS_NOISE_RATIO`] times the noise and not one.
//! - **Normalised innovation squared** (`nu^2 / S`, S the predicted variance of the
//!   innovation) over the accepted updates of rows where the attitude is *held* (its sigma
//!   in the observed directions below the bound of [`crate::SegmentConfig`]), against the
//!   two-sided 99.9 % band of its chi-square mean. Above the band the innovations exceed
//!   what the filter predicts; below it the bounds are conservative (said, not an error).
//! - **The fraction inside 3 sigma** over every update (gated ones count as outside) of the
//!   held rows, against the 99.73 % a Gaussian gives: too many outside (more than 1 % and
//!   3 sigma beyond the binomial expectation) is inconsistent.

use serde::Serialize;

use crate::filter::Sensor;
use crate::output::ResidualRecord;
use crate::quantiles::{chi_square_quantile_wh, normal_quantile};

/// Residual RMS above this many times the sensor noise is inconsistent. A consistent
/// filter's pre-update residuals carry its own attitude and calibration errors too
/// (for a well-determined attitude about as much again as the noise); three times the
/// noise is nine times its variance, which no Gaussian error budget of the model explains.
pub const MAX_RMS_NOISE_RATIO: f64 = 3.0;

/// Fewer accepted updates than this and a channel's figures are reported but not judged.
pub const MIN_JUDGED_UPDATES: usize = 10;

/// Two-sided tail of the chi-square band of the mean NIS.
const NIS_TAIL: f64 = 1e-3;

/// The Gaussian probability of a residual beyond 3 sigma.
const OUTSIDE_3SIGMA_P: f64 = 0.0027;

/// `consistent` or `inconsistent`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Verdict {
    /// Every judged figure is inside its band.
    Consistent,
    /// At least one is not (the reasons say which).
    Inconsistent,
}

impl Verdict {
    /// `consistent` / `inconsistent`.
    pub fn as_str(self) -> &'static str {
        match self {
            Verdict::Consistent => "consistent",
            Verdict::Inconsistent => "inconsistent",
        }
    }
}

/// The figures of one channel (a sensor class, or one photodiode).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ChannelConsistency {
    /// `photodiode`, `magnetometer`, or `pd01`, ...
    pub channel: String,
    /// The sensor noise alone (1 sigma, V or nT).
    pub noise_sigma: f64,
    /// Accepted updates.
    pub updates: usize,
    /// RMS of the accepted updates' residuals (V or nT); absent without updates.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residual_rms: Option<f64>,
    /// That RMS over the noise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rms_over_noise: Option<f64>,
    /// The robust spread over the noise: the median `|residual| / noise` over 0.6745 (1 for
    /// Gaussian residuals at the noise); the figure the verdict judges.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub robust_over_noise: Option<f64>,
    /// Updates (accepted or gated) of rows where the attitude was held.
    pub held_updates: usize,
    /// Mean NIS of the held accepted updates.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nis_mean: Option<f64>,
    /// Its two-sided 99.9 % chi-square band.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nis_band: Option<[f64; 2]>,
    /// Fraction of the held updates inside their 3-sigma bound (gated ones outside).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fraction_within_3sigma: Option<f64>,
    /// Samples outside the field of view at the estimate that read more light than they
    /// could get anywhere within the gate's sigmas of it ([`crate::Filter::contradicted`]).
    #[serde(skip_serializing_if = "is_zero")]
    pub contradicted: usize,
    /// The largest of their excesses over that most light, V.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contradicted_excess_max: Option<f64>,
    /// Samples of a photodiode the run did not use (never lit) that read less than the
    /// direct Sun would give anywhere within the gate's sigmas of the estimate.
    #[serde(skip_serializing_if = "is_zero")]
    pub unlit: usize,
    /// The largest output among them, V.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unlit_measured_max: Option<f64>,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// The verdict with its figures and reasons (`summary.json` `consistency`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Consistency {
    /// The verdict.
    pub verdict: Verdict,
    /// Why it is inconsistent, or what could not be judged; one sentence each.
    pub reasons: Vec<String>,
    /// What is true of a consistent run and worth knowing: a sensor class whose mean NIS
    /// lies below its band has bounds wider than its residuals need (conservative, so not
    /// an error, but its sigmas overstate the uncertainty). One sentence each.
    pub notes: Vec<String>,
    /// The RMS bound, in noise sigmas ([`MAX_RMS_NOISE_RATIO`]).
    pub max_rms_over_noise: f64,
    /// Per sensor class (`photodiode`, `magnetometer`).
    pub sensors: Vec<ChannelConsistency>,
    /// Per photodiode, pdNN order.
    pub photodiodes: Vec<ChannelConsistency>,
    /// Per photodiode with samples in the Earth's umbra, what it read there
    /// ([`crate::dark`]); empty when not checked.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub dark: Vec<crate::dark::DarkLevel>,
}

/// Bins per decade of the histogram of `|residual| / noise`.
const BINS_PER_DECADE: f64 = 20.0;
/// Its lowest edge, a decade exponent: 1e-4 of the noise.
const LOWEST_DECADE: f64 = -4.0;
/// Its bins: 1e-4 to 1e8 of the noise, 12 % wide each.
const BINS: usize = 240;

/// Counts of `|residual| / noise` on a log scale: the median of any number of updates in
/// fixed memory (a streaming run never holds its residuals), interpolated in its 12 % bin.
#[derive(Debug, Clone)]
struct LogHistogram {
    counts: Vec<u64>,
    total: u64,
}

impl Default for LogHistogram {
    fn default() -> Self {
        LogHistogram {
            counts: vec![0; BINS],
            total: 0,
        }
    }
}

impl LogHistogram {
    fn push(&mut self, x: f64) {
        if !x.is_finite() {
            return;
        }
        let at = (x.max(1e-300).log10() - LOWEST_DECADE) * BINS_PER_DECADE;
        let bin = (at.max(0.0) as usize).min(BINS - 1);
        self.counts[bin] += 1;
        self.total += 1;
    }

    /// The median, interpolated in its bin on the log scale (the counts taken as spread
    /// evenly across the bin).
    fn median(&self) -> Option<f64> {
        if self.total == 0 {
            return None;
        }
        let half = self.total as f64 / 2.0;
        let mut seen = 0.0;
        for (bin, &c) in self.counts.iter().enumerate() {
            let c = c as f64;
            if c > 0.0 && seen + c >= half {
                let within = (half - seen) / c;
                let exponent = LOWEST_DECADE + (bin as f64 + within) / BINS_PER_DECADE;
                return Some(10f64.powf(exponent));
            }
            seen += c;
        }
        None
    }
}

/// The median of `|x|` for a standard Gaussian `x`.
const GAUSSIAN_MEDIAN_ABS: f64 = 0.674_489_750_196_081_7;

#[derive(Debug, Clone, Default)]
struct Sums {
    updates: usize,
    spread: LogHistogram,
    sum_sq: f64,
    held: usize,
    held_accepted: usize,
    held_nis: f64,
    held_inside: usize,
    contradicted: usize,
    contradicted_excess_max: f64,
    unlit: usize,
    unlit_measured_max: f64,
}

impl Sums {
    /// Counts an accepted update and its `|residual|` over the noise in the spread.
    fn push_spread(&mut self, residual: f64, noise_sigma: f64) {
        self.updates += 1;
        if noise_sigma > 0.0 {
            self.spread.push(residual.abs() / noise_sigma);
        }
    }

    fn push(&mut self, r: &ResidualRecord, noise_sigma: f64) {
        if r.contradicted && r.residual < 0.0 {
            // An unused photodiode dark where it must be lit: its own warning, not the
            // verdict's (nothing of it was calibrated).
            self.unlit += 1;
            self.unlit_measured_max = self.unlit_measured_max.max(r.measured);
            return;
        }
        if r.contradicted {
            // Its own rule ([`contradiction_problem`]): never an update, so not one of the
            // held updates whose bounds the fraction inside 3 sigma judges.
            self.contradicted += 1;
            self.contradicted_excess_max = self.contradicted_excess_max.max(r.residual);
            return;
        }
        if r.accepted {
            self.push_spread(r.residual, noise_sigma);
            self.sum_sq += r.residual * r.residual;
        }
        if !r.attitude_held {
            return;
        }
        self.held += 1;
        let sigma = r.bound_3sigma / 3.0;
        if r.accepted && sigma > 0.0 {
            self.held_accepted += 1;
            self.held_nis += (r.residual / sigma).powi(2);
        }
        if r.accepted && r.residual.abs() <= r.bound_3sigma {
            self.held_inside += 1;
        }
    }

    fn robust_over_noise(&self) -> Option<f64> {
        self.spread.median().map(|m| m / GAUSSIAN_MEDIAN_ABS)
    }

    fn channel(&self, name: String, noise_sigma: f64) -> ChannelConsistency {
        let rms = (self.updates > 0).then(|| (self.sum_sq / self.updates as f64).sqrt());
        let nis = (self.held_accepted > 0).then(|| self.held_nis / self.held_accepted as f64);
        ChannelConsistency {
            channel: name,
            noise_sigma,
            updates: self.updates,
            residual_rms: rms,
            rms_over_noise: rms.filter(|_| noise_sigma > 0.0).map(|r| r / noise_sigma),
            robust_over_noise: self.robust_over_noise(),
            held_updates: self.held,
            nis_mean: nis,
            nis_band: nis.map(|_| nis_band(self.held_accepted)),
            fraction_within_3sigma: (self.held > 0)
                .then(|| self.held_inside as f64 / self.held as f64),
            contradicted: self.contradicted,
            contradicted_excess_max: (self.contradicted > 0)
                .then_some(self.contradicted_excess_max),
            unlit: self.unlit,
            unlit_measured_max: (self.unlit > 0).then_some(self.unlit_measured_max),
        }
    }
}

/// Accumulates residual records, one at a time (a streaming run never holds them all),
/// into a [`Consistency`].
#[derive(Debug, Clone)]
pub struct ConsistencyAccumulator {
    photodiode_sigma_v: f64,
    mag_sigma_nt: f64,
    photodiode: Sums,
    magnetometer: Sums,
    per_photodiode: Vec<Sums>,
}

impl ConsistencyAccumulator {
    /// For `photodiodes` photodiodes with the sensor noise sigmas the run used.
    pub fn new(photodiodes: usize, photodiode_sigma_v: f64, mag_sigma_nt: f64) -> Self {
        ConsistencyAccumulator {
            photodiode_sigma_v,
            mag_sigma_nt,
            photodiode: Sums::default(),
            magnetometer: Sums::default(),
            per_photodiode: vec![Sums::default(); photodiodes],
        }
    }

    /// Adds one scalar update.
    pub fn push(&mut self, r: &ResidualRecord) {
        match r.sensor {
            Sensor::Photodiode(i) => {
                self.photodiode.push(r, self.photodiode_sigma_v);
                if let Some(s) = self.per_photodiode.get_mut(i) {
                    s.push(r, self.photodiode_sigma_v);
                }
            }
            Sensor::Magnetometer(_) => self.magnetometer.push(r, self.mag_sigma_nt),
        }
    }

    /// The verdict over everything pushed.
    pub fn finish(&self) -> Consistency {
        let mut sensors = vec![
            self.photodiode
                .channel("photodiode".to_owned(), self.photodiode_sigma_v),
        ];
        if self.magnetometer.updates + self.magnetometer.held > 0 {
            sensors.push(
                self.magnetometer
                    .channel("magnetometer".to_owned(), self.mag_sigma_nt),
            );
        }
        let photodiodes: Vec<ChannelConsistency> = self
            .per_photodiode
            .iter()
            .enumerate()
            .map(|(i, s)| s.channel(format!("pd{:02}", i + 1), self.photodiode_sigma_v))
            .collect();
        let mut reasons = Vec::new();
        for c in sensors.iter().chain(&photodiodes) {
            reasons.extend(channel_problems(c));
        }
        reasons.extend(photodiodes.iter().filter_map(contradiction_problem));
        let judged = sensors.iter().any(|c| c.updates >= MIN_JUDGED_UPDATES);
        if !judged {
            reasons.push(format!(
                "fewer than {MIN_JUDGED_UPDATES} accepted updates of any sensor: nothing to \
                 judge the model by"
            ));
        }
        let verdict = if reasons.is_empty() {
            Verdict::Consistent
        } else {
            Verdict::Inconsistent
        };
        let notes = sensors
            .iter()
            .flat_map(|c| [conservative_note(c), unheld_note(c), tail_note(c)])
            .flatten()
            .collect();
        Consistency {
            verdict,
            reasons,
            notes,
            max_rms_over_noise: MAX_RMS_NOISE_RATIO,
            sensors,
            photodiodes,
            dark: Vec::new(),
        }
    }
}

/// The residuals' spread against the sensor noise as a variance factor for the reported
/// covariances: the unit-weight variance of an adjustment whose residuals exceed its noise
/// model, by which least squares scales its formal covariance.
///
/// With the Sun as the only vector, an EKF linearised at estimates tens of degrees from the
/// truth can settle on a tilt of the attitude and the calibration that fits the outputs
/// several times worse than the noise while its covariance says it is known to a few
/// degrees (docs/validation.md, "pyramid-head"): the covariance describes the model, and the
/// model does not describe the data. The factor is the robust spread of the accepted
/// updates' residuals *after* their step's correction (`ResidualRecord::post_fit`) over the
/// sensor noise alone (the statistic of the verdict's
/// [`ChannelConsistency::robust_over_noise`]), of the sensor class that spreads most, never
/// below one: every reported sigma is multiplied by it. Post-fit, not pre-update: the
/// innovations also carry the filter's own state uncertainty, which its covariance already
/// holds, while a post-fit residual of a model that explains its data lies within the
/// noise. What it does not touch: the estimates, the filter's own gates and bounds, and
/// the verdict, which judge the run as it is.
#[derive(Debug, Clone)]
pub struct Dispersion {
    photodiode_sigma_v: f64,
    mag_sigma_nt: f64,
    photodiode: Sums,
    magnetometer: Sums,
}

/// The variance factor a run's reported covariances were scaled by (`summary.json`
/// `dispersion`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DispersionReport {
    /// The factor on every reported sigma (its square on the variances), at least 1.
    pub sigma_factor: f64,
    /// The sensor class that set it (`photodiode`, `magnetometer`); absent when no class
    /// had [`MIN_JUDGED_UPDATES`] accepted updates or none spread beyond its noise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sensor: Option<&'static str>,
}

impl Dispersion {
    /// For the sensor noise sigmas the run used.
    pub fn new(photodiode_sigma_v: f64, mag_sigma_nt: f64) -> Self {
        Dispersion {
            photodiode_sigma_v,
            mag_sigma_nt,
            photodiode: Sums::default(),
            magnetometer: Sums::default(),
        }
    }

    /// Adds one scalar update (its residual after the step's correction).
    pub fn push(&mut self, r: &ResidualRecord) {
        self.push_update(r.sensor, r.post_fit, r.accepted);
    }

    /// Adds one scalar update by its sensor, post-fit residual and acceptance.
    pub fn push_update(&mut self, sensor: Sensor, post_fit: f64, accepted: bool) {
        let (sums, noise_sigma) = match sensor {
            Sensor::Photodiode(_) => (&mut self.photodiode, self.photodiode_sigma_v),
            Sensor::Magnetometer(_) => (&mut self.magnetometer, self.mag_sigma_nt),
        };
        if accepted {
            sums.push_spread(post_fit, noise_sigma);
        }
    }

    /// The factor over everything pushed so far.
    pub fn report(&self) -> DispersionReport {
        let mut out = DispersionReport {
            sigma_factor: 1.0,
            sensor: None,
        };
        for (name, sums) in [
            ("photodiode", &self.photodiode),
            ("magnetometer", &self.magnetometer),
        ] {
            if sums.updates < MIN_JUDGED_UPDATES {
                continue;
            }
            if let Some(ratio) = sums.robust_over_noise()
                && ratio > out.sigma_factor
            {
                out = DispersionReport {
                    sigma_factor: ratio,
                    sensor: Some(name),
                };
            }
        }
        out
    }
}

/// The verdict of a run's residual records.
pub fn judge<'a>(
    records: impl IntoIterator<Item = &'a ResidualRecord>,
    photodiodes: usize,
    photodiode_sigma_v: f64,
    mag_sigma_nt: f64,
) -> Consistency {
    let mut acc = ConsistencyAccumulator::new(photodiodes, photodiode_sigma_v, mag_sigma_nt);
    for r in records {
        acc.push(r);
    }
    acc.finish()
}

/// The robust spread over the noise of a judged channel, when beyond the bound.
fn spread_beyond(c: &ChannelConsistency) -> Option<f64> {
    c.robust_over_noise
        .filter(|&ratio| c.updates >= MIN_JUDGED_UPDATES && ratio > MAX_RMS_NOISE_RATIO)
}

/// The mean NIS of a judged channel and its band's top, when above it.
fn nis_beyond(c: &ChannelConsistency) -> Option<(f64, f64)> {
    let (nis, [_, high]) = (c.nis_mean?, c.nis_band?);
    (c.held_updates >= MIN_JUDGED_UPDATES && nis > high).then_some((nis, high))
}

/// The fraction of a judged channel's held updates inside 3 sigma, when too low.
fn inside_too_few(c: &ChannelConsistency) -> Option<f64> {
    let fraction = c.fraction_within_3sigma?;
    (c.held_updates >= MIN_JUDGED_UPDATES && too_many_outside(c.held_updates, fraction))
        .then_some(fraction)
}

/// What is wrong with one channel's figures, one sentence each.
fn channel_problems(c: &ChannelConsistency) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(ratio) = spread_beyond(c) {
        out.push(format!(
            "{}: residuals {ratio:.1} times the noise {:.3e} (robust spread; RMS {:.3e}; \
             bound {MAX_RMS_NOISE_RATIO})",
            c.channel,
            c.noise_sigma,
            c.residual_rms.unwrap_or(f64::NAN),
        ));
    }
    if let Some((nis, high)) = nis_beyond(c) {
        out.push(format!(
            "{}: mean normalised innovation squared {nis:.2} above its 99.9 % band (<= \
             {high:.2}): innovations larger than the filter predicts",
            c.channel
        ));
    }
    if let Some(fraction) = inside_too_few(c) {
        out.push(format!(
            "{}: {:.2} % of the residuals of held rows inside 3 sigma (a Gaussian gives \
             99.73 %)",
            c.channel,
            100.0 * fraction
        ));
    }
    out
}

/// A ratio to the noise as a reader takes it in: `32`, `3.4`.
fn times(ratio: f64) -> String {
    match ratio >= 10.0 {
        true => format!("{ratio:.0}"),
        false => format!("{ratio:.1}"),
    }
}

/// The verdict's main reason in a few words, from the figures: the largest spread beyond
/// the bound (a sensor class before its photodiodes), else innovations above their band,
/// else too few residuals inside 3 sigma, else contradicted samples; else the first reason
/// up to its first bracket or semicolon.
fn main_reason(c: &Consistency) -> Option<String> {
    let classes_first = [&c.sensors, &c.photodiodes];
    let worst_spread = classes_first.iter().find_map(|channels| {
        channels
            .iter()
            .filter_map(|ch| spread_beyond(ch).map(|r| (ch, r)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
    });
    if let Some((ch, ratio)) = worst_spread {
        return Some(format!(
            "{} residuals {} times the noise",
            ch.channel,
            times(ratio)
        ));
    }
    let all = || c.sensors.iter().chain(&c.photodiodes);
    if let Some((ch, (nis, _))) = all().find_map(|ch| nis_beyond(ch).map(|x| (ch, x))) {
        return Some(format!(
            "{} innovations {} times the variance the filter predicts",
            ch.channel,
            times(nis)
        ));
    }
    if let Some((ch, f)) = all().find_map(|ch| inside_too_few(ch).map(|x| (ch, x))) {
        return Some(format!(
            "{} residuals: {:.1} % inside 3 sigma, not 99.7 %",
            ch.channel,
            100.0 * f
        ));
    }
    if let Some(ch) = c
        .photodiodes
        .iter()
        .find(|p| p.contradicted >= MIN_JUDGED_UPDATES)
    {
        return Some(format!(
            "{} read more light than it could get in {} samples",
            ch.channel, ch.contradicted
        ));
    }
    let first = c.reasons.first()?;
    let cut = first.find([';', '(']).unwrap_or(first.len());
    Some(first[..cut].trim_end().to_owned())
}

impl Consistency {
    /// The verdict in one short line with its main reason (`inconsistent: photodiode
    /// residuals 32 times the noise`), and how many more reasons there are; a consistent
    /// run says how far its sensor classes' residuals are from their noise.
    pub fn headline(&self) -> String {
        let verdict = self.verdict.as_str();
        if self.verdict == Verdict::Consistent {
            let spreads: Vec<String> = (self.sensors.iter())
                .filter_map(|ch| {
                    let ratio = ch.robust_over_noise.filter(|_| ch.updates > 0)?;
                    Some(format!(
                        "{} residuals {} times the noise",
                        ch.channel,
                        times(ratio)
                    ))
                })
                .collect();
            return match spreads.is_empty() {
                true => verdict.to_owned(),
                false => format!("{verdict}: {}", spreads.join(", ")),
            };
        }
        let main = main_reason(self).unwrap_or_else(|| "no reason recorded".to_owned());
        match self.reasons.len() {
            0 | 1 => format!("{verdict}: {main}"),
            2 => format!("{verdict}: {main} (and one more reason)"),
            n => format!("{verdict}: {main} (and {} more reasons)", n - 1),
        }
    }
}

/// A sentence when a photodiode has at least [`MIN_JUDGED_UPDATES`] samples that read more
/// light than they could get anywhere within the gate's sigmas of the estimate. One such
/// sample is beyond the gate in the noise and in the estimate's uncertainty at once; ten
/// are no chance.
fn contradiction_problem(c: &ChannelConsistency) -> Option<String> {
    (c.contradicted >= MIN_JUDGED_UPDATES).then(|| {
        format!(
            "{}: {} samples outside its field of view at the estimate read more light than \
             they could get within the gate's sigmas of the attitude, normal and scale (by up \
             to {:.3} V over the direct Sun there and a white Earth filling the view): a \
             swapped or misnamed column, a wrong mounting, an output stage the model lacks, time tags \
             off, or an attitude the data contradict",
            c.channel,
            c.contradicted,
            c.contradicted_excess_max.unwrap_or(0.0),
        )
    })
}

impl Consistency {
    /// One warning per photodiode with at least [`MIN_JUDGED_UPDATES`] samples dark where
    /// the estimate says the Sun shone on it (`unlit`): a dead, blocked or unconnected
    /// channel, which the run could only call never lit.
    pub fn unlit_warnings(&self) -> Vec<String> {
        (self.photodiodes.iter())
            .filter(|c| c.unlit >= MIN_JUDGED_UPDATES)
            .map(|c| {
                format!(
                    "{}: never lit, yet in {} samples the attitude and its nominal normal, \
                     within the gate's sigmas, put the Sun on it, where it read at most {:.3} \
                     V: a dead, blocked or unconnected channel, or a normal far from the \
                     nominal one",
                    c.channel,
                    c.unlit,
                    c.unlit_measured_max.unwrap_or(0.0)
                )
            })
            .collect()
    }
}

/// A sentence when a sensor class's mean NIS over its held updates lies below its band.
fn conservative_note(c: &ChannelConsistency) -> Option<String> {
    let (nis, [low, _]) = (c.nis_mean?, c.nis_band?);
    let rms = c.rms_over_noise.unwrap_or(0.0);
    (c.held_updates >= MIN_JUDGED_UPDATES && nis < low).then(|| {
        format!(
            "{}: mean normalised innovation squared {nis:.3} below its 99.9 % band (>= \
             {low:.2}): the filter's bounds are wider than the residuals need, and its sigmas \
             overstate the uncertainty (a measurement variance larger than the misfit: the \
             declared noise, albedo_sigma_w_m2; or a state uncertainty wider than its error); \
             the residuals themselves are {rms:.2} times the sensor noise",
            c.channel
        )
    })
}

/// A channel judged by its spread alone: no update of it was made with the attitude held,
/// so an attitude free to follow the outputs may have absorbed a misfit the spread cannot
/// show.
fn unheld_note(c: &ChannelConsistency) -> Option<String> {
    (c.updates >= MIN_JUDGED_UPDATES && c.held_updates == 0).then(|| {
        format!(
            "{}: no update was made with the attitude held, so its normalised innovations \
             and the fraction inside 3 sigma were not tested: the verdict rests on the \
             residuals' spread alone, which cannot see a misfit that an attitude free to \
             follow the outputs took up",
            c.channel
        )
    })
}

/// A channel whose RMS is beyond the bound while its robust spread is not: the misfit is
/// in a minority of its updates.
fn tail_note(c: &ChannelConsistency) -> Option<String> {
    let (rms, robust) = (c.rms_over_noise?, c.robust_over_noise?);
    (c.updates >= MIN_JUDGED_UPDATES && rms > MAX_RMS_NOISE_RATIO && robust <= MAX_RMS_NOISE_RATIO)
        .then(|| {
            format!(
                "{}: residual RMS {rms:.2} times the sensor noise, its robust spread \
                 {robust:.2}: the misfit sits in a minority of the updates (the first minutes \
                 of convergence, or an effect the model lacks where it acts); residuals.csv \
                 shows where",
                c.channel
            )
        })
}

/// More than 1 % outside and 3 sigma beyond the binomial expectation of 0.27 %.
fn too_many_outside(n: usize, fraction_inside: f64) -> bool {
    let n = n as f64;
    let outside = n * (1.0 - fraction_inside);
    let expected = n * OUTSIDE_3SIGMA_P;
    let sd = (n * OUTSIDE_3SIGMA_P * (1.0 - OUTSIDE_3SIGMA_P)).sqrt();
    outside > 0.01 * n && outside > expected + 3.0 * sd
}

/// The two-sided [`NIS_TAIL`] band of the mean of `n` chi-square(1) variables (Wilson-Hilferty).
pub fn nis_band(n: usize) -> [f64; 2] {
    let z = normal_quantile(1.0 - NIS_TAIL / 2.0);
    let q = |z: f64| chi_square_quantile_wh(n as f64, z) / n as f64;
    [q(-z).max(0.0), q(z)]
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    fn record(sensor: Sensor, residual: f64, sigma: f64, held: bool) -> ResidualRecord {
        ResidualRecord {
            index: 0,
            t_s: 0.0,
            sensor,
            measured: 0.0,
            residual,
            bound_3sigma: 3.0 * sigma,
            accepted: residual.abs() <= 5.0 * sigma,
            post_fit: residual,
            attitude_held: held,
            contradicted: false,
        }
    }

    fn gaussian_records(n: usize, scale: f64, sigma: f64, seed: u64) -> Vec<ResidualRecord> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        (0..n)
            .map(|k| {
                let x: f64 = StandardNormal.sample(&mut rng);
                record(Sensor::Photodiode(k % 3), scale * x, sigma, true)
            })
            .collect()
    }

    fn dispersion_of(records: &[ResidualRecord], photodiode_sigma_v: f64) -> DispersionReport {
        let mut d = Dispersion::new(photodiode_sigma_v, 300.0);
        records.iter().for_each(|r| d.push(r));
        d.report()
    }

    #[test]
    fn the_dispersion_factor_is_the_post_fit_spread_over_the_noise_and_never_below_one() {
        // Post-fit residuals three times the noise 0.01 V (their bounds wide enough that
        // the gate takes them all): the factor is 3.
        let wide = gaussian_records(4000, 0.03, 1.0, 5);
        let d = dispersion_of(&wide, 0.01);
        assert!((d.sigma_factor - 3.0).abs() < 0.15, "{d:?}");
        assert_eq!(d.sensor, Some("photodiode"));
        // At half the noise (a filter that fits better than the noise): 1, no class named.
        let narrow = gaussian_records(4000, 0.005, 1.0, 5);
        let d = dispersion_of(&narrow, 0.01);
        assert_eq!((d.sigma_factor, d.sensor), (1.0, None));
        // The pre-update residual does not count: large innovations fitted to the noise.
        let fitted: Vec<ResidualRecord> = wide
            .iter()
            .zip(&narrow)
            .map(|(w, n)| ResidualRecord {
                post_fit: n.residual,
                accepted: true,
                ..*w
            })
            .collect();
        assert_eq!(dispersion_of(&fitted, 0.01).sigma_factor, 1.0);
        // Too few updates to judge: 1.
        assert_eq!(
            dispersion_of(&wide[..MIN_JUDGED_UPDATES - 1], 0.01).sigma_factor,
            1.0
        );
    }

    #[test]
    fn gaussian_residuals_at_their_noise_are_consistent() {
        let records = gaussian_records(6000, 0.01, 0.01, 7);
        let c = judge(&records, 3, 0.01, 300.0);
        assert_eq!(c.verdict, Verdict::Consistent, "{:?}", c.reasons);
        let pd = &c.sensors[0];
        assert!((pd.rms_over_noise.unwrap() - 1.0).abs() < 0.05);
        assert!((pd.robust_over_noise.unwrap() - 1.0).abs() < 0.12);
        let [lo, hi] = pd.nis_band.unwrap();
        assert!(lo < pd.nis_mean.unwrap() && pd.nis_mean.unwrap() < hi);
    }

    #[test]
    fn residuals_many_times_the_noise_are_inconsistent_whatever_the_bounds() {
        // Bounds inflated to cover everything (an attitude sigma of tens of degrees) and
        // residuals 70 times the noise: the RMS test still says no.
        let records: Vec<ResidualRecord> = gaussian_records(500, 0.35, 2.0, 3);
        let c = judge(&records, 3, 0.005, 300.0);
        assert_eq!(c.verdict, Verdict::Inconsistent);
        assert!(c.reasons[0].contains("times the noise"), "{:?}", c.reasons);
        // The verdict in a line: the sensor class's spread, not a photodiode's, and how
        // many more reasons there are.
        let line = c.headline();
        assert!(
            line.starts_with("inconsistent: photodiode residuals ") && line.len() < 100,
            "{line}"
        );
        assert!(line.contains(" times the noise (and "), "{line}");
        assert!(
            c.photodiodes
                .iter()
                .all(|p| p.robust_over_noise.unwrap() > 50.0)
        );
        assert!(
            c.photodiodes
                .iter()
                .all(|p| p.rms_over_noise.unwrap() > 50.0)
        );
    }

    #[test]
    fn innovations_above_their_predicted_spread_are_inconsistent() {
        // Residuals twice their predicted sigma but near the noise (a covariance that is
        // too small): the NIS and the 3-sigma fraction catch it.
        let records = gaussian_records(3000, 0.02, 0.01, 11);
        let c = judge(&records, 3, 0.01, 300.0);
        assert_eq!(c.verdict, Verdict::Inconsistent);
        assert!(
            c.reasons
                .iter()
                .any(|r| r.contains("normalised innovation"))
        );
        assert!(c.reasons.iter().any(|r| r.contains("inside 3 sigma")));
    }

    #[test]
    fn bounds_far_wider_than_the_residuals_are_consistent_with_a_note() {
        // Residuals at the noise, predicted ten times wider: conservative, said.
        let records = gaussian_records(3000, 0.01, 0.1, 13);
        let c = judge(&records, 3, 0.01, 300.0);
        assert_eq!(c.verdict, Verdict::Consistent, "{:?}", c.reasons);
        assert_eq!(c.notes.len(), 1, "{:?}", c.notes);
        assert!(c.notes[0].starts_with("photodiode: mean normalised innovation squared 0.01"));
        let fitting = judge(&gaussian_records(3000, 0.01, 0.01, 13), 3, 0.01, 300.0);
        assert!(fitting.notes.is_empty(), "{:?}", fitting.notes);
    }

    #[test]
    fn rows_without_a_held_attitude_do_not_count_for_the_bounds() {
        let mut records = gaussian_records(2000, 0.01, 0.01, 5);
        // Wide residuals on rows whose attitude is not held, inside their wide bounds:
        // the RMS over every accepted update sees them, the held figures do not.
        records.extend((0..10).map(|_| record(Sensor::Photodiode(0), 0.02, 1.0, false)));
        let c = judge(&records, 3, 0.01, 300.0);
        assert_eq!(c.sensors[0].held_updates, 2000);
        assert_eq!(c.sensors[0].updates, 2010);
        assert_eq!(c.verdict, Verdict::Consistent, "{:?}", c.reasons);
    }

    #[test]
    fn a_convergence_transient_does_not_make_a_run_inconsistent() {
        // A fifth of the updates at 20 times the noise (the first minutes, scale factors
        // still at their prior), the rest at the noise: the robust spread stays near 1.
        let mut records = gaussian_records(4000, 0.01, 1.0, 9);
        for r in records.iter_mut().take(800) {
            r.residual *= 20.0;
        }
        let c = judge(&records, 3, 0.01, 300.0);
        assert!(c.sensors[0].rms_over_noise.unwrap() > 5.0);
        assert_eq!(c.verdict, Verdict::Consistent, "{:?}", c.reasons);
        // Said: the RMS beyond the bound sits in a minority of the updates.
        assert!(
            c.notes
                .iter()
                .any(|n| n.starts_with("photodiode: residual RMS") && n.contains("minority")),
            "{:?}",
            c.notes
        );
    }

    #[test]
    fn a_verdict_on_the_spread_alone_says_so() {
        // Residuals at the noise, but no row with the attitude held: consistent by the
        // spread, the held figures untested, and the notes say both.
        let records: Vec<ResidualRecord> = gaussian_records(600, 0.01, 0.01, 17)
            .into_iter()
            .map(|r| ResidualRecord {
                attitude_held: false,
                contradicted: false,
                ..r
            })
            .collect();
        let c = judge(&records, 3, 0.01, 300.0);
        assert_eq!(c.verdict, Verdict::Consistent, "{:?}", c.reasons);
        assert!(c.sensors[0].nis_mean.is_none() && c.sensors[0].fraction_within_3sigma.is_none());
        assert_eq!(c.notes.len(), 1, "{:?}", c.notes);
        assert!(c.notes[0].starts_with("photodiode: no update was made with the attitude held"));
        // With held rows the note is not given.
        let held = judge(&gaussian_records(600, 0.01, 0.01, 17), 3, 0.01, 300.0);
        assert!(held.notes.is_empty(), "{:?}", held.notes);
    }

    #[test]
    fn too_little_data_is_not_called_consistent() {
        let records = gaussian_records(5, 0.01, 0.01, 1);
        let c = judge(&records, 3, 0.01, 300.0);
        assert_eq!(c.verdict, Verdict::Inconsistent);
        assert!(c.reasons[0].contains("nothing to judge"));
    }

    #[test]
    fn ten_contradicted_samples_of_a_photodiode_make_the_run_inconsistent() {
        let judged = |n: usize| {
            let mut acc = ConsistencyAccumulator::new(2, 0.01, 100.0);
            for k in 0..200 {
                acc.push(&record(Sensor::Photodiode(k % 2), 0.005, 0.01, true));
            }
            for _ in 0..n {
                acc.push(&ResidualRecord {
                    accepted: false,
                    residual: 0.3,
                    contradicted: true,
                    // Held: yet no held update, or nine would sink the fraction inside 3
                    // sigma of pd02's 100 below the Gaussian's.
                    attitude_held: true,
                    ..record(Sensor::Photodiode(1), 0.3, 0.01, true)
                });
            }
            acc.finish()
        };
        let few = judged(MIN_JUDGED_UPDATES - 1);
        assert_eq!(few.verdict, Verdict::Consistent, "{few:?}");
        assert_eq!(few.photodiodes[1].contradicted, MIN_JUDGED_UPDATES - 1);
        assert_eq!(few.photodiodes[1].held_updates, 100);
        let many = judged(MIN_JUDGED_UPDATES);
        assert_eq!(many.verdict, Verdict::Inconsistent, "{many:?}");
        assert!(
            many.reasons
                .iter()
                .any(|r| r.starts_with("pd02: 10 samples outside"))
        );
    }

    #[test]
    fn an_unused_photodiode_dark_in_the_sun_is_a_warning_not_a_reason() {
        let mut acc = ConsistencyAccumulator::new(2, 0.01, 100.0);
        for k in 0..200 {
            acc.push(&record(Sensor::Photodiode(0), 0.005, 0.01, true));
            if k < MIN_JUDGED_UPDATES {
                acc.push(&ResidualRecord {
                    accepted: false,
                    measured: 0.01,
                    contradicted: true,
                    ..record(Sensor::Photodiode(1), -0.5, 0.01, true)
                });
            }
        }
        let c = acc.finish();
        assert_eq!(c.verdict, Verdict::Consistent, "{c:?}");
        assert_eq!(c.photodiodes[1].unlit, MIN_JUDGED_UPDATES);
        let warnings = c.unlit_warnings();
        assert!(warnings.len() == 1 && warnings[0].starts_with("pd02: never lit"));
    }
}
