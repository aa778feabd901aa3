//! The honest end of a diagnosis: are the final photodiode residuals what the noise model
//! says (RMS against the sensor noise, fraction inside 3 sigma, whiteness per photodiode)?
//! If not, the verdict gains `unexplained`, with the size of the misfit and where it
//! concentrates: which photodiodes, which incidence band, Sun or shadow, which part of the
//! orbit.
//!
//! The noise model is the sensor noise, the uncertainty the filter reports for what it
//! estimated (each photodiode's final scale factor and normal: a photodiode seldom lit
//! inside the filter's 60-deg gate keeps a wide normal, and its residuals at high incidence
//! may be wide too), plus the albedo model's own uncertainty: a
//! reflectivity map is a mean over years and cloud cover, and two maps of the same Earth
//! (TOMS, CERES) differ by a fraction of the albedo they predict, not by a gain. Each
//! sample's sigma is `sqrt(sigma_pd^2 + sigma_pred^2 + (kappa a)^2)`, `a` the modelled
//! albedo output and
//! `kappa` = [`ALBEDO_RELATIVE_SIGMA`]; a photodiode that sees no Earth keeps the sensor
//! noise alone.
//!
//! The bounds are set on control seeds of the built-in scenarios (docs/diagnose.md): the
//! residuals over every sample include the smoothed attitude's own error, so they are a
//! little above the noise and a little correlated even when the model is complete.

use pdcal_ephem::Reference;
use serde::Serialize;

use crate::residuals::{FULL_SUN, PdSample, Residuals, UMBRA};

/// Largest photodiode RMS over the noise sigma of a consistent model, all samples.
pub const MAX_RMS_RATIO: f64 = 1.15;
/// Smallest fraction of residuals inside 3 noise sigmas of a consistent model.
pub const MIN_FRACTION_WITHIN_3SIGMA: f64 = 0.98;
/// Largest RMS over noise of any one photodiode of a consistent model.
pub const MAX_PD_RMS_RATIO: f64 = 1.25;
/// Largest lag-one autocorrelation of one photodiode's residuals of a consistent model
/// (counted only together with an RMS above [`WHITENESS_RMS_RATIO`]: a correlated residual
/// at the noise level is the attitude error's, not a missing effect).
pub const MAX_LAG1: f64 = 0.5;
/// RMS ratio above which a photodiode's correlation counts.
pub const WHITENESS_RMS_RATIO: f64 = 1.2;
/// Largest share of the total excess that one photodiode may hold while it is above
/// [`WHITENESS_RMS_RATIO`]: a model error shared by all photodiodes (attitude, albedo map)
/// spreads over the ones that see it.
pub const MAX_ONE_PD_SHARE: f64 = 0.35;
/// Relative 1-sigma uncertainty of the modelled albedo output (the reflectivity map's).
pub const ALBEDO_RELATIVE_SIGMA: f64 = 0.1;
/// Fewest samples a photodiode needs for its own checks.
const MIN_PD_SAMPLES: usize = 100;

/// One photodiode's residual statistics.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PdMisfit {
    /// 1-based photodiode index.
    pub photodiode: usize,
    /// Samples.
    pub samples: usize,
    /// RMS residual, V.
    #[serde(rename = "rms_V")]
    pub rms_v: f64,
    /// RMS of the residuals over their noise model's sigma.
    pub rms_ratio: f64,
    /// Fraction inside 3 sigmas of the noise model.
    pub fraction_within_3sigma: f64,
    /// Lag-one autocorrelation over consecutive rows.
    pub lag1_autocorrelation: f64,
    /// Share of the total excess sum of squares (above the noise) in this photodiode.
    pub excess_share: f64,
}

/// Residual statistics of one band of samples (incidence, illumination, orbit part).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Band {
    /// What the band is (`incidence 60-75 deg`, `umbra`, `orbit angle from the Sun 0-30
    /// deg`).
    pub band: String,
    /// Samples.
    pub samples: usize,
    /// RMS residual, V.
    #[serde(rename = "rms_V")]
    pub rms_v: f64,
    /// Share of the total excess sum of squares in this band.
    pub excess_share: f64,
    /// Share of the samples in this band.
    pub sample_share: f64,
}

/// The consistency check of the final residuals.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Misfit {
    /// True when every check holds: the residuals are noise as far as they can tell.
    pub explained: bool,
    /// The checks that failed, one line each.
    pub failed: Vec<String>,
    /// Photodiode RMS over every sample, V.
    #[serde(rename = "photodiode_rms_V")]
    pub photodiode_rms_v: f64,
    /// Photodiode sensor noise sigma, V.
    #[serde(rename = "photodiode_noise_V")]
    pub photodiode_noise_v: f64,
    /// RMS of the residuals over their noise model's sigma (sensor noise plus the albedo
    /// model's uncertainty).
    pub rms_ratio: f64,
    /// Fraction inside 3 sigmas of the noise model.
    pub fraction_within_3sigma: f64,
    /// Where the misfit concentrates, one line (empty when explained).
    pub concentrated_in: String,
    /// Every photodiode, largest excess first.
    pub photodiodes: Vec<PdMisfit>,
    /// By incidence angle.
    pub by_incidence: Vec<Band>,
    /// Full Sun, penumbra, umbra.
    pub by_illumination: Vec<Band>,
    /// By the angle between the spacecraft's position and the Sun (0 over the subsolar
    /// point, 180 over the antisolar point).
    pub by_orbit: Vec<Band>,
}

/// Each sample's noise variance: the sensor's plus the modelled albedo's uncertainty.
#[derive(Debug, Clone, Copy)]
struct Noise {
    sensor_var: f64,
    /// `kappa` times the model's albedo gain (0 without albedo in the model).
    albedo_sigma_per_v: f64,
}

impl Noise {
    fn var(&self, p: &PdSample) -> f64 {
        let a = self.albedo_sigma_per_v * p.albedo_v;
        self.sensor_var + a * a + p.prediction_sigma_v * p.prediction_sigma_v
    }
}

/// Checks the residuals `res` against their noise model; `references` per telemetry row;
/// `albedo_gain` the model's factor on the albedo regressor (0 when it has no albedo).
pub fn misfit(res: &Residuals, references: &[Reference], albedo_gain: f64) -> Misfit {
    let sigma = res.sigma_pd_v;
    let noise = Noise {
        sensor_var: sigma * sigma,
        albedo_sigma_per_v: ALBEDO_RELATIVE_SIGMA * albedo_gain.abs(),
    };
    let total_excess: f64 =
        excess(&res.pd.iter().collect::<Vec<_>>(), noise).max(f64::MIN_POSITIVE);
    let all = stats(res.pd.iter(), noise);
    let photodiodes = per_photodiode(res, noise, total_excess);
    let by_incidence = bands(res, noise, total_excess, incidence_band);
    let by_illumination = bands(res, noise, total_excess, illumination_band);
    let by_orbit = bands(res, noise, total_excess, |p| orbit_band(p, references));
    let mut failed = Vec::new();
    if all.ratio > MAX_RMS_RATIO {
        failed.push(format!(
            "photodiode RMS {:.4} V is {:.2} times the noise model's ({:.4} V sensor noise plus \
             {:.0} % of the modelled albedo; at most {MAX_RMS_RATIO})",
            all.rms,
            all.ratio,
            sigma,
            100.0 * ALBEDO_RELATIVE_SIGMA
        ));
    }
    if all.inside < MIN_FRACTION_WITHIN_3SIGMA {
        failed.push(format!(
            "{:.1} % of photodiode residuals inside 3 sigma (at least {:.0} %)",
            100.0 * all.inside,
            100.0 * MIN_FRACTION_WITHIN_3SIGMA
        ));
    }
    for p in photodiodes.iter().filter(|p| p.samples >= MIN_PD_SAMPLES) {
        if p.rms_ratio > MAX_PD_RMS_RATIO {
            failed.push(format!(
                "photodiode {} RMS {:.4} V is {:.2} times its noise model's (at most \
                 {MAX_PD_RMS_RATIO})",
                p.photodiode, p.rms_v, p.rms_ratio
            ));
        } else if p.lag1_autocorrelation > MAX_LAG1 && p.rms_ratio > WHITENESS_RMS_RATIO {
            failed.push(format!(
                "photodiode {} residuals are not white: lag-one autocorrelation {:.2} at {:.2} \
                 times the noise",
                p.photodiode, p.lag1_autocorrelation, p.rms_ratio
            ));
        }
    }
    if let Some(p) = photodiodes.first()
        && p.samples >= MIN_PD_SAMPLES
        && p.excess_share >= MAX_ONE_PD_SHARE
        && p.rms_ratio > WHITENESS_RMS_RATIO
    {
        failed.push(format!(
            "photodiode {} holds {:.0} % of the misfit (at {:.2} times its noise model's): a \
             fault of one sensor, not of the shared model",
            p.photodiode,
            100.0 * p.excess_share,
            p.rms_ratio
        ));
    }
    let explained = failed.is_empty();
    let concentrated_in = if explained {
        String::new()
    } else {
        concentration(&photodiodes, &[&by_incidence, &by_illumination, &by_orbit])
    };
    Misfit {
        explained,
        failed,
        photodiode_rms_v: all.rms,
        photodiode_noise_v: sigma,
        rms_ratio: all.ratio,
        fraction_within_3sigma: all.inside,
        concentrated_in,
        photodiodes,
        by_incidence,
        by_illumination,
        by_orbit,
    }
}

/// RMS, RMS of the standardised residuals and fraction inside 3 sigma of some samples.
struct Stats {
    n: usize,
    rms: f64,
    ratio: f64,
    inside: f64,
}

fn stats<'a>(samples: impl Iterator<Item = &'a PdSample>, noise: Noise) -> Stats {
    let (mut n, mut ss, mut zz, mut inside) = (0usize, 0.0, 0.0, 0usize);
    for p in samples {
        let var = noise.var(p);
        let r2 = p.residual_v * p.residual_v;
        n += 1;
        ss += r2;
        zz += r2 / var;
        inside += usize::from(r2 <= 9.0 * var);
    }
    let nf = n.max(1) as f64;
    Stats {
        n,
        rms: (ss / nf).sqrt(),
        ratio: (zz / nf).sqrt(),
        inside: inside as f64 / nf,
    }
}

/// Sum of the squares above each sample's noise variance.
fn excess(samples: &[&PdSample], noise: Noise) -> f64 {
    samples
        .iter()
        .map(|p| (p.residual_v * p.residual_v - noise.var(p)).max(0.0))
        .sum()
}

fn per_photodiode(res: &Residuals, noise: Noise, total_excess: f64) -> Vec<PdMisfit> {
    let n_pd = res.pd.iter().map(|p| p.pd + 1).max().unwrap_or(0);
    let mut out: Vec<PdMisfit> = (0..n_pd)
        .map(|i| {
            let own: Vec<&PdSample> = res.pd.iter().filter(|p| p.pd == i).collect();
            let s = stats(own.iter().copied(), noise);
            PdMisfit {
                photodiode: i + 1,
                samples: s.n,
                rms_v: s.rms,
                rms_ratio: s.ratio,
                fraction_within_3sigma: s.inside,
                lag1_autocorrelation: lag1(&own),
                excess_share: excess(&own, noise) / total_excess,
            }
        })
        .collect();
    out.sort_by(|a, b| b.excess_share.total_cmp(&a.excess_share));
    out
}
/// Lag-one autocorrelation over pairs of consecutive rows.
fn lag1(samples: &[&PdSample]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for w in samples.windows(2) {
        if w[1].row == w[0].row + 1 {
            num += w[0].residual_v * w[1].residual_v;
        }
    }
    for p in samples {
        den += p.residual_v * p.residual_v;
    }
    if den > 0.0 { num / den } else { 0.0 }
}

fn bands(
    res: &Residuals,
    noise: Noise,
    total_excess: f64,
    band: impl Fn(&PdSample) -> String,
) -> Vec<Band> {
    let mut labels: Vec<String> = Vec::new();
    let mut members: Vec<Vec<&PdSample>> = Vec::new();
    for p in &res.pd {
        let label = band(p);
        match labels.iter().position(|l| *l == label) {
            Some(k) => members[k].push(p),
            None => {
                labels.push(label);
                members.push(vec![p]);
            }
        }
    }
    let total = res.pd.len().max(1) as f64;
    let mut out: Vec<Band> = labels
        .into_iter()
        .zip(members)
        .map(|(label, m)| Band {
            samples: m.len(),
            rms_v: stats(m.iter().copied(), noise).rms,
            excess_share: excess(&m, noise) / total_excess,
            sample_share: m.len() as f64 / total,
            band: label,
        })
        .collect();
    out.sort_by(|a, b| a.band.cmp(&b.band));
    out
}

fn incidence_band(p: &PdSample) -> String {
    let deg = p.cos_incidence.clamp(-1.0, 1.0).acos().to_degrees();
    let edges = [30.0, 60.0, 75.0, 90.0];
    let mut lo = 0.0;
    for hi in edges {
        if deg < hi {
            return format!("incidence {lo:02.0}-{hi:.0} deg");
        }
        lo = hi;
    }
    "incidence 90-180 deg (Sun behind)".to_owned()
}

fn illumination_band(p: &PdSample) -> String {
    if p.sun_fraction >= FULL_SUN {
        "full Sun".to_owned()
    } else if p.sun_fraction <= UMBRA {
        "umbra".to_owned()
    } else {
        "penumbra".to_owned()
    }
}

fn orbit_band(p: &PdSample, references: &[Reference]) -> String {
    let Some(r) = references.get(p.row) else {
        return "orbit unknown".to_owned();
    };
    let cos = r
        .r_gcrf_km
        .normalize()
        .dot(&r.sun_gcrf_unit)
        .clamp(-1.0, 1.0);
    let deg = cos.acos().to_degrees();
    let lo = ((deg / 30.0).floor() * 30.0).min(150.0);
    format!("orbit angle from the Sun {lo:03.0}-{:03.0} deg", lo + 30.0)
}

/// One line: the photodiodes and bands holding the misfit out of proportion.
fn concentration(photodiodes: &[PdMisfit], groups: &[&Vec<Band>]) -> String {
    let mut parts = Vec::new();
    let top: Vec<String> = photodiodes
        .iter()
        .take_while(|p| p.excess_share >= 0.2)
        .take(3)
        .map(|p| {
            format!(
                "photodiode {} ({:.0} %)",
                p.photodiode,
                100.0 * p.excess_share
            )
        })
        .collect();
    if top.is_empty() {
        parts.push("spread over the photodiodes".to_owned());
    } else {
        parts.push(top.join(", "));
    }
    for bands in groups {
        if let Some(b) = bands
            .iter()
            .filter(|b| b.excess_share > 1.5 * b.sample_share && b.excess_share >= 0.3)
            .max_by(|a, b| a.excess_share.total_cmp(&b.excess_share))
        {
            parts.push(format!(
                "{} ({:.0} % of the misfit in {:.0} % of the samples)",
                b.band,
                100.0 * b.excess_share,
                100.0 * b.sample_share
            ));
        }
    }
    parts.join("; ")
}
