//! Which calibrated quantities the data determined: every photodiode's scale factor,
//! azimuth and elevation and the gyro bias get a [`Status`] with its reason, judged from
//! what the data did to the prior (the posterior sigma against the prior sigma), how long
//! the photodiode was used (and for how much of it the attitude was held), how strongly
//! its states are correlated with another's, and whether the residuals were consistent
//! with the model at all. A quantity the data did
//! not determine is reported as its prior (nominal) value, never as a calibration
//! ([`reported_calibration`]).
//!
//! The rules compare the data's information with the prior's, so they hold for any prior
//! a user sets: with a posterior sigma above half the prior's, the data carried less
//! information than the prior (less than three quarters of the variance removed) and the
//! number is the prior's, not the data's; below a fifth (96 % of the variance removed from
//! the data), it is the data's. Between the two it is weakly determined: the number
//! moved, but a second data set should confirm it.

use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

use crate::calibration::{Calibration, PdCalibration};
use crate::consistency::Verdict;
use crate::layout::{BIAS, StateLayout};

/// Posterior over prior sigma at most this: `calibrated`.
pub const CALIBRATED_SIGMA_RATIO: f64 = 0.2;
/// Posterior over prior sigma above this: `not-determined`.
pub const NOT_DETERMINED_SIGMA_RATIO: f64 = 0.5;
/// A correlation coefficient beyond this with another calibration state: at most
/// `weakly-determined` (the two are told apart by the prior, not the data).
pub const MAX_CORRELATION: f64 = 0.98;
/// A photodiode used for less than this is at most `weakly-determined`, min: a few
/// minutes of one tumble cover a narrow band of incidence. The same bound applies to the
/// part of that time with the attitude *held* (its sigma in the observed directions within
/// `segments.held_attitude_sigma_deg`), and to the time the attitude was held since the
/// gyro bias last started from its prior: the EKF linearises each update at its estimate,
/// and a state learnt at an attitude tens of degrees uncertain gets a sigma from Jacobians
/// taken that far from the truth (docs/validation.md, "Weak real data"). A photodiode
/// with no time held at all has nothing but such updates behind its quantities: they are
/// `not-determined`, whatever their sigmas.
pub const MIN_USED_MIN: f64 = 5.0;

/// How well the data determined a quantity.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    /// The data determined it; its sigma is the data's.
    Calibrated,
    /// The data moved it, but not by much more than the prior allowed, or with a caveat.
    WeaklyDetermined,
    /// The data did not determine it: reported as the prior.
    NotDetermined,
}

impl Status {
    /// `calibrated`, `weakly-determined`, `not-determined`.
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Calibrated => "calibrated",
            Status::WeaklyDetermined => "weakly-determined",
            Status::NotDetermined => "not-determined",
        }
    }

    /// The weaker of two.
    fn at_most(self, other: Status) -> Status {
        self.max(other)
    }
}

/// A status and why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Judged {
    /// The status.
    pub status: Status,
    /// Why, one sentence (empty for a plain `calibrated`).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub reason: String,
}

/// The statuses of one photodiode.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PdIdentifiability {
    /// The weakest of the three.
    pub status: Status,
    /// The scale factor.
    pub scale: Judged,
    /// The azimuth.
    pub azimuth: Judged,
    /// The elevation.
    pub elevation: Judged,
}

/// What is known of a run to judge its quantities.
pub struct Evidence<'a> {
    /// The prior (initial) calibration, with its sigmas.
    pub initial: &'a Calibration,
    /// The final calibration.
    pub calibration: &'a Calibration,
    /// Which photodiodes took part.
    pub used: &'a [bool],
    /// The time each photodiode's accepted updates cover, s.
    pub time_used_s: &'a [f64],
    /// The part of it with the attitude held, s.
    pub time_held_s: &'a [f64],
    /// The time the attitude was held since the gyro bias last started from its prior, s.
    pub bias_time_held_s: f64,
    /// The final covariance and its layout (for correlations).
    pub covariance: &'a DMatrix<f64>,
    /// Its layout.
    pub layout: &'a StateLayout,
    /// Whether the normals were estimated (false: scale-only).
    pub normals_estimated: bool,
    /// The consistency verdict of the run.
    pub verdict: Verdict,
}

impl<'a> Evidence<'a> {
    /// What `run` gives to judge its quantities, with the consistency `verdict` of its
    /// residuals.
    pub fn of_run(run: &'a crate::output::CalibrationRun, verdict: Verdict) -> Self {
        Evidence {
            initial: &run.initial,
            calibration: &run.calibration,
            used: &run.used_photodiodes,
            time_used_s: &run.photodiode_time_used_s,
            time_held_s: &run.photodiode_time_held_s,
            bias_time_held_s: run.bias_time_held_s,
            covariance: &run.final_covariance,
            layout: &run.layout,
            normals_estimated: !matches!(run.mode, crate::output::ModeUsed::ScaleOnly { .. }),
            verdict,
        }
    }
}

/// The statuses of every photodiode, pdNN order.
pub fn judge_photodiodes(e: &Evidence<'_>) -> Vec<PdIdentifiability> {
    (0..e.calibration.photodiodes.len())
        .map(|i| judge_photodiode(e, i))
        .collect()
}

/// The status of each gyro-bias axis (x, y, z).
pub fn judge_gyro_bias(e: &Evidence<'_>) -> [Judged; 3] {
    std::array::from_fn(|k| {
        let prior = e.initial.gyro_bias_sigma_rad_s[k];
        let post = e.calibration.gyro_bias_sigma_rad_s[k];
        let mut j = by_sigma_ratio(post, prior, "rad/s");
        let rho = max_correlation(e.covariance, BIAS + k, &[BIAS + k], e.layout);
        cap_by_correlation(&mut j, rho);
        let held_min = e.bias_time_held_s / 60.0;
        if held_min < MIN_USED_MIN {
            demote(
                &mut j,
                Status::WeaklyDetermined,
                format!(
                    "the attitude was held {held_min:.1} min only since the bias started from its prior (under {MIN_USED_MIN} min)"
                ),
            );
        }
        cap_by_consistency(&mut j, e.verdict);
        j
    })
}

fn judge_photodiode(e: &Evidence<'_>, i: usize) -> PdIdentifiability {
    let cal = &e.calibration.photodiodes[i];
    let init = &e.initial.photodiodes[i];
    if !e.used.get(i).copied().unwrap_or(false) {
        let never = Judged {
            status: Status::NotDetermined,
            reason: "never lit: nothing to calibrate from".to_owned(),
        };
        return PdIdentifiability {
            status: Status::NotDetermined,
            scale: never.clone(),
            azimuth: never.clone(),
            elevation: never,
        };
    }
    let mut scale = by_sigma_ratio(cal.scale_sigma_v, init.scale_sigma_v, "V");
    let (mut azimuth, mut elevation) = if e.normals_estimated {
        normal_statuses(cal, init)
    } else {
        let fixed = Judged {
            status: Status::NotDetermined,
            reason: "not estimated (scale-only run): the prior".to_owned(),
        };
        (fixed.clone(), fixed)
    };
    let own: Vec<usize> = std::iter::once(e.layout.scale(i))
        .chain(e.layout.normal(i).into_iter().flat_map(|d| [d, d + 1]))
        .collect();
    let minutes = e.time_used_s.get(i).copied().unwrap_or(0.0) / 60.0;
    let held_minutes = e.time_held_s.get(i).copied().unwrap_or(0.0) / 60.0;
    let scale_states = [e.layout.scale(i)];
    let normal_states: Vec<usize> = e
        .layout
        .normal(i)
        .map(|d| vec![d, d + 1])
        .unwrap_or_default();
    for (j, states) in [
        (&mut scale, &scale_states[..]),
        (&mut azimuth, &normal_states[..]),
        (&mut elevation, &normal_states[..]),
    ] {
        if j.status == Status::NotDetermined {
            continue;
        }
        let rho = states
            .iter()
            .filter_map(|&k| max_correlation(e.covariance, k, &own, e.layout))
            .max_by(|a, b| a.0.abs().total_cmp(&b.0.abs()));
        cap_by_correlation(j, rho);
        if held_minutes <= 0.0 {
            demote(
                j,
                Status::NotDetermined,
                format!(
                    "lit and used {minutes:.1} min, none of them with the attitude held: \
                     every update that moved it was linearised at an attitude less certain \
                     than the held bound, so its sigma is not the data's"
                ),
            );
        } else if minutes < MIN_USED_MIN {
            demote(
                j,
                Status::WeaklyDetermined,
                format!("lit and used {minutes:.1} min only (under {MIN_USED_MIN} min)"),
            );
        } else if held_minutes < MIN_USED_MIN {
            demote(
                j,
                Status::WeaklyDetermined,
                format!(
                    "lit and used {minutes:.1} min, {held_minutes:.1} of them with the \
                     attitude held (under {MIN_USED_MIN} min)"
                ),
            );
        }
        cap_by_consistency(j, e.verdict);
    }
    let status = scale.status.max(azimuth.status).max(elevation.status);
    PdIdentifiability {
        status,
        scale,
        azimuth,
        elevation,
    }
}

/// Azimuth and elevation by the tangent-plane sigma each stands for against the prior's:
/// the azimuth sigma times `cos(el)` (near the pole a large azimuth sigma is a small
/// displacement of the normal).
fn normal_statuses(cal: &PdCalibration, init: &PdCalibration) -> (Judged, Judged) {
    let prior_deg = init.elevation_sigma_deg;
    let elevation = by_sigma_ratio(cal.elevation_sigma_deg, prior_deg, "deg");
    let cos_el = cal.elevation_deg.to_radians().cos();
    let azimuth = match cal.azimuth_sigma_deg {
        Some(s) => by_sigma_ratio(s * cos_el, prior_deg, "deg (across)"),
        None => Judged {
            status: Status::NotDetermined,
            reason: "undefined: the normal's uncertainty reaches the pole".to_owned(),
        },
    };
    (azimuth, elevation)
}

fn by_sigma_ratio(post: f64, prior: f64, unit: &str) -> Judged {
    if !(prior > 0.0 && post.is_finite()) {
        return Judged {
            status: Status::NotDetermined,
            reason: "no prior sigma to compare with".to_owned(),
        };
    }
    let ratio = post / prior;
    let what =
        format!("posterior sigma {post:.3e} {unit} is {ratio:.2} of the prior's {prior:.3e}");
    if ratio > NOT_DETERMINED_SIGMA_RATIO {
        Judged {
            status: Status::NotDetermined,
            reason: format!("{what}: the data did not determine it"),
        }
    } else if ratio > CALIBRATED_SIGMA_RATIO {
        Judged {
            status: Status::WeaklyDetermined,
            reason: what,
        }
    } else {
        Judged {
            status: Status::Calibrated,
            reason: String::new(),
        }
    }
}

/// Caps `j` at `to` (never promotes it) and adds `why` to its reasons: every caveat found
/// is said, also when an earlier one had already set the status.
fn demote(j: &mut Judged, to: Status, why: String) {
    j.status = j.status.at_most(to);
    j.reason = if j.reason.is_empty() {
        why
    } else {
        format!("{}; {why}", j.reason)
    };
}

fn cap_by_correlation(j: &mut Judged, rho: Option<(f64, String)>) {
    if let Some((rho, with)) = rho
        && rho.abs() > MAX_CORRELATION
    {
        demote(
            j,
            Status::WeaklyDetermined,
            format!("correlated {rho:.3} with {with}"),
        );
    }
}

fn cap_by_consistency(j: &mut Judged, verdict: Verdict) {
    if verdict == Verdict::Inconsistent && j.status == Status::Calibrated {
        demote(
            j,
            Status::WeaklyDetermined,
            "the residuals are inconsistent with the model, so its sigma is not to be trusted"
                .to_owned(),
        );
    }
}

/// The largest correlation of state `k` with a calibration or bias state outside `own`,
/// with that state's name.
fn max_correlation(
    p: &DMatrix<f64>,
    k: usize,
    own: &[usize],
    layout: &StateLayout,
) -> Option<(f64, String)> {
    let n = p.nrows().min(layout.len());
    if k >= n || p[(k, k)] <= 0.0 {
        return None;
    }
    (BIAS..n)
        .filter(|j| *j != k && !own.contains(j) && p[(*j, *j)] > 0.0)
        .map(|j| (p[(k, j)] / (p[(k, k)] * p[(j, j)]).sqrt(), j))
        .max_by(|a, b| a.0.abs().total_cmp(&b.0.abs()))
        .map(|(rho, j)| (rho, state_name(layout, j)))
}

/// A readable name of state `j`: `pd03 scale`, `pd03 normal`, `gyro bias`, `state 40`.
fn state_name(layout: &StateLayout, j: usize) -> String {
    if (BIAS..BIAS + 3).contains(&j) {
        return format!("gyro bias {}", ["x", "y", "z"][j - BIAS]);
    }
    for i in 0..layout.photodiodes() {
        if layout.scale(i) == j {
            return format!("pd{:02} scale", i + 1);
        }
        if let Some(d) = layout.normal(i)
            && (j == d || j == d + 1)
        {
            return format!("pd{:02} normal", i + 1);
        }
    }
    format!("state {j}")
}

/// The calibration to report: each quantity the data did not determine replaced by its
/// prior value and sigma, so that no number the data did not determine reads as a result.
pub fn reported_calibration(
    initial: &Calibration,
    calibration: &Calibration,
    photodiodes: &[PdIdentifiability],
    bias: &[Judged; 3],
) -> Calibration {
    let mut out = calibration.clone();
    for ((pd, init), id) in out
        .photodiodes
        .iter_mut()
        .zip(&initial.photodiodes)
        .zip(photodiodes)
    {
        if id.scale.status == Status::NotDetermined {
            pd.scale_v = init.scale_v;
            pd.scale_sigma_v = init.scale_sigma_v;
        }
        if id.azimuth.status == Status::NotDetermined {
            pd.azimuth_deg = init.azimuth_deg;
            pd.azimuth_sigma_deg = init.azimuth_sigma_deg;
        }
        if id.elevation.status == Status::NotDetermined {
            pd.elevation_deg = init.elevation_deg;
            pd.elevation_sigma_deg = init.elevation_sigma_deg;
        }
    }
    for (k, j) in bias.iter().enumerate() {
        if j.status == Status::NotDetermined {
            out.gyro_bias_rad_s[k] = initial.gyro_bias_rad_s[k];
            out.gyro_bias_sigma_rad_s[k] = initial.gyro_bias_sigma_rad_s[k];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sigma_ratio_sets_the_status() {
        assert_eq!(by_sigma_ratio(0.01, 0.5, "V").status, Status::Calibrated);
        assert_eq!(
            by_sigma_ratio(0.2, 0.5, "V").status,
            Status::WeaklyDetermined
        );
        let nd = by_sigma_ratio(0.4, 0.5, "V");
        assert_eq!(nd.status, Status::NotDetermined);
        assert!(nd.reason.contains("0.80 of the prior"), "{}", nd.reason);
    }

    #[test]
    fn demotion_never_promotes_and_keeps_every_reason() {
        let mut j = by_sigma_ratio(0.2, 0.5, "V");
        demote(
            &mut j,
            Status::WeaklyDetermined,
            "lit 2 min only".to_owned(),
        );
        assert_eq!(j.status, Status::WeaklyDetermined);
        assert!(j.reason.contains("0.40") && j.reason.contains("lit 2 min"));
        let mut nd = by_sigma_ratio(0.5, 0.5, "V");
        demote(&mut nd, Status::WeaklyDetermined, "x".to_owned());
        assert_eq!(nd.status, Status::NotDetermined);
    }

    #[test]
    fn near_the_pole_the_azimuth_is_judged_by_the_displacement_it_stands_for() {
        let init = PdCalibration {
            scale_v: 3.7,
            scale_sigma_v: 0.5,
            azimuth_deg: 0.0,
            azimuth_sigma_deg: Some(10.0),
            elevation_deg: 90.0,
            elevation_sigma_deg: 10.0,
        };
        let cal = PdCalibration {
            azimuth_deg: -7.0,
            azimuth_sigma_deg: Some(12.4),
            elevation_deg: 89.23,
            elevation_sigma_deg: 0.15,
            ..init
        };
        let (az, el) = normal_statuses(&cal, &init);
        assert_eq!(az.status, Status::Calibrated, "{}", az.reason);
        assert_eq!(el.status, Status::Calibrated);
    }
}
