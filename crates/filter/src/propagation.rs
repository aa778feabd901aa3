//! Which propagation a run uses between samples: the gyro-driven MEKF (the gyro's rate,
//! held or interpolated between its samples) or the rigid-body dynamics of
//! [`crate::rate`], and why.
//!
//! With `dynamics: Auto` the data decide. The gyro-driven propagation assumes the gyro's
//! samples carry the rate between them: held from one sample to the next, or, averaging
//! (`average_gyro`), interpolated linearly between consecutive samples. Whether they do is
//! tested on the gyro itself: the residual of that rate model at a sample is, when the
//! model holds, gyro noise alone (the bias cancels; its random walk adds a small known
//! variance), so its squares normalised by their variance sum to a chi-square. Beyond the
//! [`RATE_TEST_TAIL`] quantile the rate changes between samples by more than the gyro's
//! noise explains and the dynamics run; otherwise the gyro carries the attitude. For a rate
//! interpolated linearly the residual is that of the middle sample of three:
//!
//! ```text
//! r = w1 - (a w0 + b w2),  a = (t2 - t1) / (t2 - t0),  b = (t1 - t0) / (t2 - t0)
//! var(r) = sigma_g^2 (1 + a^2 + b^2) + sigma_u^2 (t1 - t0)(t2 - t1) / (t2 - t0)
//! ```
//!
//! (the last term the gyro bias's random walk, a Brownian bridge at `t1`); for a rate held,
//! `r = w1 - w0`, `var(r) = 2 sigma_g^2 + sigma_u^2 (t1 - t0)`. The samples of one residual
//! are not shared with another's, so the residuals are independent and the sum is
//! chi-square with three degrees of freedom per residual. Samples further apart than the
//! gyro hold are not compared: the segments break there ([`crate::segments`]).
//!
//! A gyro that falls silent beyond its hold while rows go on (or starts after them) leaves
//! the gyro-driven filter nothing to carry the attitude with: those rows would be skipped
//! and each silence would end a segment. With the inertia given the dynamics run instead
//! ([`PropagationReason::GyroSilent`]), the gyro a measurement where it has samples, so the
//! attitude is carried through the silence by Euler's equations.
//!
//! The test asks what the propagation needs: a gyro at 1 Hz on a spacecraft tumbling at
//! 4 deg/s changes its rate between samples by more than its noise, but that change is
//! close to linear over a second, so the interpolated rate carries it; ten seconds apart
//! it is not.

use pdcal_dataset::{DatasetMeta, Telemetry};
use serde::Serialize;

use crate::config::{Dynamics, FilterConfig};
use crate::quantiles::{chi_square_quantile_wh, normal_quantile};

/// The probability that the test finds a rate change in a gyro whose samples carry the
/// rate (a false alarm): the 3-sigma two-sided tail, the project's false-alarm rate.
pub const RATE_TEST_TAIL: f64 = 0.0027;

/// The propagation between samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PropagationKind {
    /// The gyro-driven MEKF: the gyro's rate drives the attitude between samples.
    Gyro,
    /// The rigid-body dynamics ([`crate::rate`]): the rate is a state, the gyro (if any)
    /// a measurement of it.
    Dynamics,
}

/// Why the run uses its propagation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PropagationReason {
    /// The config says `dynamics: Off`.
    ConfigOff,
    /// The config says `dynamics: On`.
    ConfigOn,
    /// `dynamics: Auto` and dataset.ron has no `inertia_kg_m2`.
    NoInertia,
    /// `dynamics: Auto`, the inertia given and no gyro sample.
    NoGyro,
    /// `dynamics: Auto`, the inertia given and too few gyro samples close enough together
    /// to test whether they carry the rate.
    GyroUntested,
    /// `dynamics: Auto`, the inertia given, and rows farther than the gyro hold from the
    /// latest gyro sample (a gyro that stops or starts late): the dynamics carry on there.
    GyroSilent,
    /// `dynamics: Auto`: the gyro's rate changes between its samples by more than its
    /// noise explains ([`GyroRateTest`] beyond its threshold).
    RateChanges,
    /// `dynamics: Auto`: the gyro's samples carry the rate between them as far as its
    /// noise shows ([`GyroRateTest`] within its threshold).
    RateCarried,
}

/// The rate model between gyro samples the test checks: the one the gyro-driven
/// propagation would use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum GyroRateModel {
    /// Held from one sample to the next (`average_gyro: false`).
    Held,
    /// Interpolated linearly between consecutive samples (`average_gyro: true`).
    Linear,
}

/// The test of the gyro's samples against its noise (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GyroRateTest {
    /// The rate model tested.
    pub rate_model: GyroRateModel,
    /// Residuals tested (each from its own samples).
    pub residuals: usize,
    /// Degrees of freedom of the chi-square (three per residual).
    pub dof: usize,
    /// The chi-square per degree of freedom: about 1 when the gyro's noise explains the
    /// residuals, its excess over 1 the rate change's variance in units of the noise's.
    pub chi_square_per_dof: f64,
    /// Its [`RATE_TEST_TAIL`] quantile per degree of freedom.
    pub threshold_per_dof: f64,
    /// The gyro noise sigma tested against, rad/s per axis and sample.
    pub gyro_sigma_rad_s: f64,
}

impl GyroRateTest {
    /// Whether the rate changes by more than the noise explains.
    pub fn rate_changes(&self) -> bool {
        self.chi_square_per_dof > self.threshold_per_dof
    }
}

/// The propagation a run uses and why: `summary.json` `propagation`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PropagationChoice {
    /// The propagation.
    pub propagation: PropagationKind,
    /// Why.
    pub reason: PropagationReason,
    /// The test of the gyro's samples, when `dynamics: Auto` ran it.
    pub gyro_rate_test: Option<GyroRateTest>,
}

impl PropagationChoice {
    /// Whether the dynamics run.
    pub fn dynamics(&self) -> bool {
        self.propagation == PropagationKind::Dynamics
    }

    /// One line for the printed summary.
    pub fn describe(&self) -> String {
        let what = match self.propagation {
            PropagationKind::Gyro => "gyro-driven",
            PropagationKind::Dynamics => "rigid-body dynamics",
        };
        let why = match self.reason {
            PropagationReason::ConfigOff => "the config says dynamics: Off".to_owned(),
            PropagationReason::ConfigOn => "the config says dynamics: On".to_owned(),
            PropagationReason::NoInertia => "dataset.ron gives no inertia_kg_m2".to_owned(),
            PropagationReason::NoGyro => "no gyro samples".to_owned(),
            PropagationReason::GyroUntested => {
                "too few gyro samples to test whether they carry the rate".to_owned()
            }
            PropagationReason::GyroSilent => {
                "the gyro is silent beyond its hold on some rows: the dynamics carry the attitude there".to_owned()
            }
            PropagationReason::RateChanges | PropagationReason::RateCarried => {
                let verb = if self.reason == PropagationReason::RateChanges {
                    "changes by more than"
                } else {
                    "changes within"
                };
                match &self.gyro_rate_test {
                    Some(t) => format!(
                        "the rate between gyro samples {verb} its noise (chi-square per dof \
                         {:.3} against {:.3}, {} dof)",
                        t.chi_square_per_dof, t.threshold_per_dof, t.dof
                    ),
                    None => format!("the rate between gyro samples {verb} its noise"),
                }
            }
        };
        format!("{what} ({why})")
    }
}

/// The propagation for `telemetry` under `config` (module docs). `gyro_sigma_rad_s` is the
/// gyro noise per sample the filter uses, `gyro_hold_s` the longest the segments hold a gyro
/// sample ([`crate::segments::GapRules`]).
pub fn choose(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    config: &FilterConfig,
    gyro_sigma_rad_s: f64,
    gyro_hold_s: f64,
) -> PropagationChoice {
    let choice = |propagation, reason, gyro_rate_test| PropagationChoice {
        propagation,
        reason,
        gyro_rate_test,
    };
    match config.dynamics {
        Dynamics::Off => return choice(PropagationKind::Gyro, PropagationReason::ConfigOff, None),
        Dynamics::On => {
            return choice(PropagationKind::Dynamics, PropagationReason::ConfigOn, None);
        }
        Dynamics::Auto => {}
    }
    if meta.inertia_kg_m2.is_none() {
        return choice(PropagationKind::Gyro, PropagationReason::NoInertia, None);
    }
    if gyro_samples(telemetry).next().is_none() {
        return choice(PropagationKind::Dynamics, PropagationReason::NoGyro, None);
    }
    if has_silent_rows(telemetry, gyro_hold_s) {
        return choice(
            PropagationKind::Dynamics,
            PropagationReason::GyroSilent,
            None,
        );
    }
    let model = if config.average_gyro {
        GyroRateModel::Linear
    } else {
        GyroRateModel::Held
    };
    let noise = GyroNoise {
        sigma_rad_s: gyro_sigma_rad_s,
        walk_var_per_s: config.gyro_bias_walk_rad_s_sqrt_s.powi(2),
    };
    match rate_test(gyro_samples(telemetry), model, noise, gyro_hold_s) {
        None => choice(
            PropagationKind::Dynamics,
            PropagationReason::GyroUntested,
            None,
        ),
        Some(test) if test.rate_changes() => choice(
            PropagationKind::Dynamics,
            PropagationReason::RateChanges,
            Some(test),
        ),
        Some(test) => choice(
            PropagationKind::Gyro,
            PropagationReason::RateCarried,
            Some(test),
        ),
    }
}

/// Whether a row lies farther than `hold_s` after the latest gyro sample, or before the
/// first: where the gyro-driven filter has no rate to carry the attitude with.
fn has_silent_rows(telemetry: &Telemetry, hold_s: f64) -> bool {
    let Some((first_t, _)) = gyro_samples(telemetry).next() else {
        return false;
    };
    let mut latest = first_t;
    for (&t, g) in telemetry.t_s.iter().zip(&telemetry.gyro_rad_s) {
        if g.is_some() {
            latest = t;
        } else if t - latest > hold_s || first_t - t > hold_s {
            return true;
        }
    }
    false
}

/// A gyro sample: its time, s, and rate, rad/s.
type Sample = (f64, [f64; 3]);

/// The gyro's white noise per sample and its bias's random walk.
#[derive(Debug, Clone, Copy)]
struct GyroNoise {
    sigma_rad_s: f64,
    walk_var_per_s: f64,
}

/// The gyro's samples in row order, read as they are reached (a long set's gyro column is
/// not copied).
fn gyro_samples(telemetry: &Telemetry) -> impl Iterator<Item = Sample> + '_ {
    telemetry
        .t_s
        .iter()
        .zip(&telemetry.gyro_rad_s)
        .filter_map(|(&t, g)| g.map(|w| (t, [w.x, w.y, w.z])))
}

/// The chi-square test of the residuals of `model` (module docs) over disjoint runs of
/// consecutive samples no further apart than `max_spacing_s`; `None` without one residual.
/// The samples are read once, in order, holding one run.
fn rate_test(
    samples: impl Iterator<Item = Sample>,
    model: GyroRateModel,
    noise: GyroNoise,
    max_spacing_s: f64,
) -> Option<GyroRateTest> {
    let span = match model {
        GyroRateModel::Held => 2,
        GyroRateModel::Linear => 3,
    };
    let mut sum = 0.0;
    let mut residuals = 0;
    // The run starting at the next untested sample: a run with a gap moves on by one
    // sample, a tested run by all of its own.
    let mut run: Vec<Sample> = Vec::with_capacity(span);
    for sample in samples {
        run.push(sample);
        if run.len() < span {
            continue;
        }
        if run.windows(2).any(|w| w[1].0 - w[0].0 > max_spacing_s) {
            run.remove(0);
            continue;
        }
        let (r, var) = residual(&run, noise);
        sum += r.iter().map(|x| x * x).sum::<f64>() / var;
        residuals += 1;
        run.clear();
    }
    if residuals == 0 {
        return None;
    }
    let dof = 3 * residuals;
    let z = normal_quantile(1.0 - RATE_TEST_TAIL);
    Some(GyroRateTest {
        rate_model: model,
        residuals,
        dof,
        chi_square_per_dof: sum / dof as f64,
        threshold_per_dof: chi_square_quantile_wh(dof as f64, z) / dof as f64,
        gyro_sigma_rad_s: noise.sigma_rad_s,
    })
}

/// The residual of the rate model at the run's last sample (two samples: held) or middle
/// one (three: linear), and its variance per axis when the model holds.
fn residual(run: &[Sample], noise: GyroNoise) -> ([f64; 3], f64) {
    let white = noise.sigma_rad_s.powi(2);
    match *run {
        [(t0, w0), (t1, w1)] => (
            std::array::from_fn(|k| w1[k] - w0[k]),
            2.0 * white + noise.walk_var_per_s * (t1 - t0),
        ),
        [(t0, w0), (t1, w1), (t2, w2)] => {
            let a = (t2 - t1) / (t2 - t0);
            let b = (t1 - t0) / (t2 - t0);
            (
                std::array::from_fn(|k| w1[k] - a * w0[k] - b * w2[k]),
                white * (1.0 + a * a + b * b)
                    + noise.walk_var_per_s * (t1 - t0) * (t2 - t1) / (t2 - t0),
            )
        }
        _ => unreachable!("runs are of two or three samples"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    /// Samples every `dt_s` of `rate(t)` plus white noise of `sigma` and a constant bias.
    fn sampled(dt_s: f64, n: usize, sigma: f64, rate: impl Fn(f64) -> [f64; 3]) -> Vec<Sample> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let normal = Normal::new(0.0, sigma).unwrap();
        let bias = [0.05, -0.03, 0.02];
        (0..n)
            .map(|i| {
                let t = i as f64 * dt_s;
                let w = rate(t);
                (
                    t,
                    std::array::from_fn(|k| w[k] + bias[k] + normal.sample(&mut rng)),
                )
            })
            .collect()
    }

    fn noise(sigma: f64) -> GyroNoise {
        GyroNoise {
            sigma_rad_s: sigma,
            walk_var_per_s: 0.0,
        }
    }

    /// A rate turning at `omega` rad/s with amplitude `amp` rad/s on x and y.
    fn coning(amp: f64, omega: f64) -> impl Fn(f64) -> [f64; 3] {
        move |t| [amp * (omega * t).cos(), amp * (omega * t).sin(), 0.01]
    }

    #[test]
    fn noise_alone_is_a_chi_square_of_mean_one() {
        for model in [GyroRateModel::Held, GyroRateModel::Linear] {
            let s = sampled(1.0, 30_000, 1e-3, |_| [0.1, 0.0, -0.05]);
            let test = rate_test(s.iter().copied(), model, noise(1e-3), 5.0).unwrap();
            // 3e4 samples: the mean's sigma is sqrt(2 / dof) < 0.02.
            assert!((test.chi_square_per_dof - 1.0).abs() < 0.05, "{test:?}");
            assert!(!test.rate_changes(), "{test:?}");
            assert!(test.threshold_per_dof > 1.0 && test.threshold_per_dof < 1.1);
        }
    }

    #[test]
    fn a_rate_change_close_to_linear_is_carried_by_the_interpolation_not_the_hold() {
        // 0.05 rad/s turning at 0.05 rad/s: a change of 2.5e-3 rad/s per second, 2.5 times
        // the noise; its curvature over a second is 1.25e-4 rad/s, a tenth of the noise.
        let s = sampled(1.0, 7200, 1e-3, coning(0.05, 0.05));
        let linear = rate_test(s.iter().copied(), GyroRateModel::Linear, noise(1e-3), 5.0).unwrap();
        let held = rate_test(s.iter().copied(), GyroRateModel::Held, noise(1e-3), 5.0).unwrap();
        assert!(!linear.rate_changes(), "{linear:?}");
        assert!(held.rate_changes(), "{held:?}");
    }

    #[test]
    fn a_rate_that_curves_between_samples_is_found() {
        // The same motion sampled every 10 s: the middle sample's residual is the
        // curvature, 0.05 x 0.05^2 x 10^2 / 2 = 6.25e-3 rad/s across z, against a noise
        // variance of 1.5e-6 per axis: chi-square per dof (3.9e-5 / 1.5e-6 + 3) / 3 = 9.7.
        let s = sampled(10.0, 720, 1e-3, coning(0.05, 0.05));
        let linear =
            rate_test(s.iter().copied(), GyroRateModel::Linear, noise(1e-3), 50.0).unwrap();
        assert!(linear.rate_changes(), "{linear:?}");
        assert!((linear.chi_square_per_dof - 9.7).abs() < 1.0, "{linear:?}");
    }

    #[test]
    fn samples_beyond_the_hold_are_not_compared() {
        let mut s = sampled(1.0, 4, 1e-3, |_| [0.0; 3]);
        s[2].0 = 100.0;
        s[3].0 = 101.0;
        // The rate after the gap is another.
        s[2].1[0] += 1.0;
        s[3].1[0] += 1.0;
        // Held: (0, 1) and (2, 3), not the jump between them; linear: no three samples
        // within 5 s of each other.
        let held = rate_test(s.iter().copied(), GyroRateModel::Held, noise(1e-3), 5.0).unwrap();
        assert_eq!(held.residuals, 2);
        assert!(!held.rate_changes(), "{held:?}");
        assert!(rate_test(s.iter().copied(), GyroRateModel::Linear, noise(1e-3), 5.0).is_none());
    }

    #[test]
    fn uneven_spacing_and_the_bias_walk_keep_the_noise_a_chi_square_of_mean_one() {
        // Every third sample 0.7 s late, and a bias walking as fast as the white noise
        // over a sample: the residual's variance carries both.
        let sigma = 1e-3;
        let walk_var_per_s = sigma * sigma;
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let white = Normal::new(0.0, sigma).unwrap();
        let mut bias = [0.0; 3];
        let mut last_t = 0.0;
        let s: Vec<Sample> = (0..30_000)
            .map(|i| {
                let t = i as f64 + if i % 3 == 1 { 0.7 } else { 0.0 };
                let step = Normal::new(0.0, (walk_var_per_s * (t - last_t)).sqrt()).unwrap();
                for b in &mut bias {
                    *b += step.sample(&mut rng);
                }
                last_t = t;
                (t, std::array::from_fn(|k| bias[k] + white.sample(&mut rng)))
            })
            .collect();
        let noise = GyroNoise {
            sigma_rad_s: sigma,
            walk_var_per_s,
        };
        for model in [GyroRateModel::Held, GyroRateModel::Linear] {
            let test = rate_test(s.iter().copied(), model, noise, 5.0).unwrap();
            assert!((test.chi_square_per_dof - 1.0).abs() < 0.05, "{test:?}");
            let no_walk =
                rate_test(s.iter().copied(), model, super::tests::noise(sigma), 5.0).unwrap();
            assert!(no_walk.chi_square_per_dof > 1.1, "{no_walk:?}");
        }
    }
}
