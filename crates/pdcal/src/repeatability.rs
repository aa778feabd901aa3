//! Repeatability across the data sets of a joint calibration: each set's own estimate of
//! every calibration parameter (its own forward pass, [`crate::joint::own_estimates`]) is
//! compared with the other sets' per parameter, and a disagreement the sets' covariances do
//! not explain is a warning naming the parameter and the sets (a degradation, a changed
//! mounting, or an effect the model lacks).
//!
//! The statistics, per scalar parameter (a photodiode's `C`, azimuth or elevation) with
//! estimates `x` and variances `s^2` at the end times `t` of the sets' passes:
//! - a pair of sets: `z = (x_a - x_b) / sqrt(s_a^2 + s_b^2 + w |t_a - t_b|)`, `w` the
//!   parameter's random walk per second (the filter's, Eq. 19), so that what the joint
//!   model allows to change between the sets is not a disagreement;
//! - a set against the joint estimate: the joint contains the set, so their difference's
//!   variance is not `s_k^2 + s_joint^2`. Instead the set is compared with the *other*
//!   sets combined (inverse-variance weights, each other set's variance grown by the walk
//!   to this set's time): independent data, the leave-one-out form of the joint. It is
//!   done with three sets or more (with two it is the pair).
//!
//! Every set starts from the same configuration (prior sigmas, nominal normals), so the
//! estimates share the prior's information: the tests above count it twice in the
//! variance, which makes them conservative (fewer alarms), never the opposite.
//!
//! Each `z` is a standard normal under repeatability. With `N` tests in a run, the
//! family-wise false-alarm rate is held at [`FAMILY_FALSE_ALARM`] by Sidak's threshold
//! `|z| > Phi^-1(1 - a/2)`, `a = 1 - (1 - FAMILY_FALSE_ALARM)^(1/N)`: Sidak's inequality
//! holds for two-sided tests of jointly normal statistics whatever their correlation, so
//! the rate is at most the nominal one. Only parameters a set determined
//! (`calibrated` or `weakly-determined`, [`pdcal_filter::identifiability`]) enter; the
//! others are "not determined by set k".
//!
//! The gyro bias is no calibration constant: a MEMS gyro's turn-on bias changes with every
//! power cycle. Consecutive sets' biases are compared against the bias random walk over
//! the time between them; beyond [`BIAS_CHANGE_SIGMAS`] it is a warning of its own, which
//! says whether the bias prior allows the change (then it is expected) or not. When the
//! filter restarts the bias from its prior in each set (`gyro_bias_across_sets: Restart`,
//! the default), a change the prior allows is what the filter assumed and no warning; one
//! beyond 3 sigma of the prior still is (the prior is too narrow for this gyro).

use pdcal_filter::Calibration;
use pdcal_filter::identifiability::{Judged, PdIdentifiability, Status};
pub use pdcal_filter::quantiles::sidak_threshold;
use serde::Serialize;

/// The nominal family-wise false-alarm rate of a run's repeatability tests: the two-sided
/// tail of one 3-sigma test, so that a repeatable campaign is flagged in 0.27 % of runs,
/// however many parameters and sets it has.
pub const FAMILY_FALSE_ALARM: f64 = 0.0027;

/// A gyro-bias change between consecutive sets beyond this many sigmas (of the two
/// estimates and the bias random walk over the time between them) is a warning.
pub const BIAS_CHANGE_SIGMAS: f64 = 3.0;

/// What one data set's own pass estimated, for the comparison.
#[derive(Debug, Clone)]
pub struct SetEstimate {
    /// The set's final calibration (its pass's last row), with sigmas.
    pub calibration: Calibration,
    /// How well the set alone determined each photodiode's quantities.
    pub photodiodes: Vec<PdIdentifiability>,
    /// How well it determined each gyro-bias axis.
    pub gyro_bias: [Judged; 3],
}

/// One data set of the comparison: its name, the time of its pass's last row on the joint
/// time line (s), and its estimate, or why its own pass failed.
#[derive(Debug, Clone)]
pub struct SetInput {
    /// dataset.ron `name`.
    pub name: String,
    /// Time of its last row, s on the joint time line.
    pub end_s: f64,
    /// Its own estimate, or why there is none.
    pub estimate: Result<SetEstimate, String>,
}

/// The random walks of the calibration states (the filter's configuration), per second.
#[derive(Debug, Clone, Copy)]
pub struct Walks {
    /// Scale factor, fraction of `C` per sqrt(h) (`scale_walk_fraction_per_sqrt_h`).
    pub scale_fraction_per_sqrt_h: f64,
    /// Normal direction, deg per sqrt(h) (`normal_walk_deg_per_sqrt_h`).
    pub normal_deg_per_sqrt_h: f64,
    /// Gyro bias, rad/s per sqrt(s) (`gyro_bias_walk_rad_s_sqrt_s`).
    pub bias_rad_s_sqrt_s: f64,
    /// The filter restarts the gyro bias from its prior in each set
    /// (`gyro_bias_across_sets: Restart`): a change the prior allows is then expected, not
    /// a warning.
    pub bias_restarts: bool,
}

impl Walks {
    /// The walks of a filter configuration.
    pub fn of(config: &pdcal_filter::FilterConfig) -> Self {
        Walks {
            scale_fraction_per_sqrt_h: config.scale_walk_fraction_per_sqrt_h,
            normal_deg_per_sqrt_h: config.normal_walk_deg_per_sqrt_h,
            bias_rad_s_sqrt_s: config.gyro_bias_walk_rad_s_sqrt_s,
            bias_restarts: config.gyro_bias_across_sets == pdcal_filter::BiasAcrossSets::Restart,
        }
    }
}

/// The run's verdict on repeatability.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RepeatVerdict {
    /// Every compared parameter agrees across the sets.
    Repeatable,
    /// At least one parameter differs beyond the threshold (the warnings say which).
    NotRepeatable,
    /// Nothing could be compared (fewer than two sets determined any parameter).
    NotChecked,
}

impl RepeatVerdict {
    /// `repeatable`, `not-repeatable`, `not-checked`.
    pub fn as_str(self) -> &'static str {
        match self {
            RepeatVerdict::Repeatable => "repeatable",
            RepeatVerdict::NotRepeatable => "not-repeatable",
            RepeatVerdict::NotChecked => "not-checked",
        }
    }
}

/// `summary.json` `repeatability`: the run's verdict, its threshold and warnings.
#[derive(Debug, Clone, Serialize)]
pub struct Repeatability {
    /// `repeatable`, `not-repeatable` or `not-checked`.
    pub verdict: RepeatVerdict,
    /// Tests made (pairs and set-against-the-others, over every parameter).
    pub comparisons: usize,
    /// The nominal family-wise false-alarm rate ([`FAMILY_FALSE_ALARM`]).
    pub family_false_alarm_rate: f64,
    /// Sidak's threshold on `|z|` for `comparisons` tests.
    pub threshold_sigmas: f64,
    /// The parameters that differ (`pd03 scale_V`, ...).
    pub differing: Vec<String>,
    /// One line per parameter that differs.
    pub warnings: Vec<String>,
    /// The gyro-bias threshold ([`BIAS_CHANGE_SIGMAS`]).
    pub bias_change_threshold_sigmas: f64,
    /// One line per gyro-bias axis and pair of consecutive sets whose change exceeds it.
    pub bias_warnings: Vec<String>,
    /// Per set, its parameters (`summary.json` `datasets[k].repeatability`).
    #[serde(skip)]
    pub sets: Vec<SetRepeatability>,
}

/// `summary.json` `datasets[k].repeatability`.
#[derive(Debug, Clone, Serialize)]
pub struct SetRepeatability {
    /// Why the set's own pass failed, when it did (then nothing of it is compared).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub own_pass_failed: Option<String>,
    /// Every parameter: the set's own estimate and its comparisons.
    pub parameters: Vec<ParameterRepeat>,
}

/// One parameter of one set.
#[derive(Debug, Clone, Serialize)]
pub struct ParameterRepeat {
    /// `pd01 scale_V`, `pd01 azimuth_deg`, `pd01 elevation_deg`, `gyro_bias_x_rad_s`.
    pub parameter: String,
    /// How well this set alone determined it.
    pub status: Status,
    /// The set's own estimate (absent when the set did not determine it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub estimate: Option<f64>,
    /// Its 1-sigma.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma: Option<f64>,
    /// Normalised difference from the other sets combined (three sets or more).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vs_other_sets: Option<f64>,
    /// Normalised difference from each other set that determined it (for the gyro bias:
    /// the previous set only, the walk over the gap included).
    pub vs_sets: Vec<PairDifference>,
    /// `agrees`, `differs`, `changed`, `not compared: ...` or `not determined by set k`.
    pub verdict: String,
}

/// A normalised difference `(this - other) / sigma` from another set.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct PairDifference {
    /// The other set, 1-based in time order.
    pub set: usize,
    /// The normalised difference.
    pub normalised_difference: f64,
}

impl Repeatability {
    /// Adds the warnings to the run's `warnings` and makes the consistency verdict of a run
    /// whose sets are not repeatable `inconsistent`, with a reason naming the parameters
    /// that differ: a model that fits each set but not the same constants across them is
    /// not consistent with the data.
    pub fn apply(&self, c: &mut pdcal_filter::Consistency, warnings: &mut Vec<String>) {
        warnings.extend(self.warnings.iter().chain(&self.bias_warnings).cloned());
        if self.verdict != RepeatVerdict::NotRepeatable {
            return;
        }
        c.verdict = pdcal_filter::Verdict::Inconsistent;
        c.reasons.push(format!(
            "the data sets' own estimates disagree beyond {:.2} sigma (repeatability): {}",
            self.threshold_sigmas,
            self.differing.join(", ")
        ));
    }
}

/// `(a - b) / sqrt(var_a + var_b + walk_var)`.
pub fn normalised_difference(a: f64, var_a: f64, b: f64, var_b: f64, walk_var: f64) -> f64 {
    (a - b) / (var_a + var_b + walk_var).sqrt()
}

/// Inverse-variance combination of `(value, variance)` pairs: the combined value and its
/// variance; `None` without a pair of positive variance.
pub fn combine(items: &[(f64, f64)]) -> Option<(f64, f64)> {
    let (sw, swx) = items
        .iter()
        .filter(|(_, v)| *v > 0.0 && v.is_finite())
        .fold((0.0, 0.0), |(sw, swx), (x, v)| (sw + 1.0 / v, swx + x / v));
    (sw > 0.0).then(|| (swx / sw, 1.0 / sw))
}

/// A parameter's kind: how it is read from a calibration and how it walks.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Scale,
    Azimuth,
    Elevation,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Scale => "scale_V",
            Kind::Azimuth => "azimuth_deg",
            Kind::Elevation => "elevation_deg",
        }
    }

    fn unit(self) -> &'static str {
        match self {
            Kind::Scale => "V",
            Kind::Azimuth | Kind::Elevation => "deg",
        }
    }

    /// The estimate and variance of photodiode `i` in `e`, if `e` determined it.
    fn of(self, e: &SetEstimate, i: usize) -> (Status, Option<(f64, f64)>) {
        let (Some(p), Some(d)) = (e.calibration.photodiodes.get(i), e.photodiodes.get(i)) else {
            return (Status::NotDetermined, None);
        };
        let (status, value, sigma) = match self {
            Kind::Scale => (d.scale.status, p.scale_v, Some(p.scale_sigma_v)),
            Kind::Azimuth => (d.azimuth.status, p.azimuth_deg, p.azimuth_sigma_deg),
            Kind::Elevation => (
                d.elevation.status,
                p.elevation_deg,
                Some(p.elevation_sigma_deg),
            ),
        };
        let determined = status != Status::NotDetermined;
        let pair = sigma
            .filter(|s| determined && s.is_finite() && *s > 0.0 && value.is_finite())
            .map(|s| (value, s * s));
        (status, pair)
    }

    /// The random walk's variance per second at `value` (elevation `el_deg`).
    fn walk_var_per_s(self, walks: &Walks, value: f64, el_deg: f64) -> f64 {
        let normal = walks.normal_deg_per_sqrt_h.powi(2) / 3600.0;
        match self {
            Kind::Scale => (walks.scale_fraction_per_sqrt_h * value).powi(2) / 3600.0,
            Kind::Elevation => normal,
            // An azimuth step is the normal's step over cos(el).
            Kind::Azimuth => normal / el_deg.to_radians().cos().powi(2).max(1e-12),
        }
    }

    /// `a - b`, azimuths wrapped into [-180, 180).
    fn difference(self, a: f64, b: f64) -> f64 {
        match self {
            Kind::Azimuth => pdcal_attitude::wrap_deg(a - b),
            _ => a - b,
        }
    }
}

/// One test: the sets it involves (the other set of a pair, or none against the rest),
/// and its `z`.
#[derive(Debug, Clone, Copy)]
struct Test {
    set: usize,
    other: Option<usize>,
    z: f64,
}

/// One parameter across the sets.
struct Parameter {
    label: String,
    kind: Kind,
    /// Per set: status, and (value, variance) when determined.
    per_set: Vec<(Status, Option<(f64, f64)>)>,
    tests: Vec<Test>,
    /// Per set, its normalised difference from the others combined.
    rest: Vec<Option<f64>>,
    /// The combined others' (value, variance) per set, for the warning's text.
    rest_value: Vec<Option<(f64, f64)>>,
}

/// Compares the sets' own estimates ([`SetInput`], in time order) per parameter, and
/// consecutive sets' gyro biases; `initial_bias_sigma_rad_s` is the bias prior's sigma.
pub fn compare(sets: &[SetInput], walks: &Walks, initial_bias_sigma_rad_s: f64) -> Repeatability {
    let m = sets
        .iter()
        .filter_map(|s| s.estimate.as_ref().ok())
        .map(|e| e.calibration.photodiodes.len())
        .max()
        .unwrap_or(0);
    let end_s: Vec<f64> = sets.iter().map(|s| s.end_s).collect();
    let parameters: Vec<Parameter> = (0..m)
        .flat_map(|i| [Kind::Scale, Kind::Azimuth, Kind::Elevation].map(|k| (i, k)))
        .map(|(i, kind)| {
            let per_set = sets
                .iter()
                .map(|s| match &s.estimate {
                    Ok(e) => kind.of(e, i),
                    Err(_) => (Status::NotDetermined, None),
                })
                .collect();
            let el_deg = sets
                .iter()
                .filter_map(|s| s.estimate.as_ref().ok())
                .filter_map(|e| e.calibration.photodiodes.get(i))
                .map(|p| p.elevation_deg)
                .next()
                .unwrap_or(0.0);
            test_parameter(
                format!("pd{:02} {}", i + 1, kind.name()),
                kind,
                per_set,
                &end_s,
                walks,
                el_deg,
            )
        })
        .collect();
    let comparisons: usize = parameters.iter().map(|p| p.tests.len()).sum();
    let threshold = sidak_threshold(FAMILY_FALSE_ALARM, comparisons);
    let (differing, warnings): (Vec<String>, Vec<String>) = parameters
        .iter()
        .filter_map(|p| warning(p, sets, threshold, comparisons).map(|w| (p.label.clone(), w)))
        .unzip();
    let verdict = match (comparisons, warnings.is_empty()) {
        (0, _) => RepeatVerdict::NotChecked,
        (_, true) => RepeatVerdict::Repeatable,
        (_, false) => RepeatVerdict::NotRepeatable,
    };
    let (bias_rows, bias_warnings) = bias_changes(sets, walks, initial_bias_sigma_rad_s);
    let sets_out = (0..sets.len())
        .map(|k| SetRepeatability {
            own_pass_failed: sets[k].estimate.as_ref().err().cloned(),
            parameters: parameters
                .iter()
                .map(|p| parameter_row(p, k, threshold))
                .chain(bias_rows[k].iter().cloned())
                .collect(),
        })
        .collect();
    Repeatability {
        verdict,
        comparisons,
        family_false_alarm_rate: FAMILY_FALSE_ALARM,
        threshold_sigmas: threshold,
        differing,
        warnings,
        bias_change_threshold_sigmas: BIAS_CHANGE_SIGMAS,
        bias_warnings,
        sets: sets_out,
    }
}

/// The tests of one parameter: every pair of sets that determined it, and with three sets
/// or more each set against the others combined (when at least two others determined it).
fn test_parameter(
    label: String,
    kind: Kind,
    per_set: Vec<(Status, Option<(f64, f64)>)>,
    end_s: &[f64],
    walks: &Walks,
    el_deg: f64,
) -> Parameter {
    let k = per_set.len();
    let mut tests = Vec::new();
    let walk = |value: f64, dt: f64| kind.walk_var_per_s(walks, value, el_deg) * dt.abs();
    for a in 0..k {
        for b in a + 1..k {
            if let (Some((xa, va)), Some((xb, vb))) = (per_set[a].1, per_set[b].1) {
                let w = walk(xa, end_s[a] - end_s[b]);
                let z = normalised_difference(kind.difference(xa, xb), va, 0.0, vb, w);
                tests.push(Test {
                    set: a,
                    other: Some(b),
                    z,
                });
            }
        }
    }
    let mut rest = vec![None; k];
    let mut rest_value = vec![None; k];
    if k >= 3 {
        for a in 0..k {
            let Some((xa, va)) = per_set[a].1 else {
                continue;
            };
            // The others as differences from this set's value (azimuths wrapped), their
            // variances grown by the walk to this set's time.
            let others: Vec<(f64, f64)> = (0..k)
                .filter(|&b| b != a)
                .filter_map(|b| {
                    per_set[b].1.map(|(xb, vb)| {
                        (kind.difference(xb, xa), vb + walk(xb, end_s[a] - end_s[b]))
                    })
                })
                .collect();
            if others.len() < 2 {
                continue;
            }
            let Some((delta, v)) = combine(&others) else {
                continue;
            };
            let z = normalised_difference(0.0, va, delta, v, 0.0);
            rest[a] = Some(z);
            rest_value[a] = Some((xa + delta, v));
            tests.push(Test {
                set: a,
                other: None,
                z,
            });
        }
    }
    Parameter {
        label,
        kind,
        per_set,
        tests,
        rest,
        rest_value,
    }
}

/// The warning of a parameter with a test beyond `threshold`: the set that differs from the
/// others (the largest such `z`), or else the pair of sets that differ most.
fn warning(p: &Parameter, sets: &[SetInput], threshold: f64, comparisons: usize) -> Option<String> {
    let worst = p
        .tests
        .iter()
        .filter(|t| t.z.abs() > threshold)
        .max_by(|a, b| {
            (a.other.is_none(), a.z.abs())
                .partial_cmp(&(b.other.is_none(), b.z.abs()))
                .unwrap_or(std::cmp::Ordering::Equal)
        })?;
    let unit = p.kind.unit();
    let digits = if unit == "V" { 4 } else { 2 };
    let show = |(x, v): (f64, f64)| format!("{x:.digits$} +- {:.digits$} {unit}", v.sqrt());
    let name = |k: usize| format!("set {} ({})", k + 1, sets[k].name);
    let shown = |k: usize| {
        let (status, value) = p.per_set[k];
        let value = value.map(show).unwrap_or_default();
        match status {
            Status::Calibrated => value,
            _ => format!("{value} ({})", status.as_str()),
        }
    };
    let (what, involved) = match worst.other {
        Some(b) => (
            format!(
                "{} {} against {} {}",
                name(worst.set),
                shown(worst.set),
                name(b),
                shown(b)
            ),
            vec![worst.set, b],
        ),
        None => (
            format!(
                "{} {} against the other sets' {}",
                name(worst.set),
                shown(worst.set),
                p.rest_value[worst.set].map(show).unwrap_or_default()
            ),
            (0..p.per_set.len())
                .filter(|&k| p.per_set[k].1.is_some())
                .collect(),
        ),
    };
    let weak = involved
        .iter()
        .any(|&k| p.per_set[k].0 != Status::Calibrated);
    let causes = if weak {
        "a degradation, a changed mounting, an effect the model lacks, or a set that \
         determined it only weakly holding a wrong solution tighter than its sigma says"
    } else {
        "a degradation, a changed mounting or an effect the model lacks"
    };
    Some(format!(
        "repeatability: {} differs between the data sets: {what}, {:.1} sigma (threshold \
         {threshold:.2} sigma for {comparisons} comparisons at {:.2} % family-wise): {causes}",
        p.label,
        worst.z.abs(),
        100.0 * FAMILY_FALSE_ALARM
    ))
}

/// Set `k`'s row of parameter `p`.
fn parameter_row(p: &Parameter, k: usize, threshold: f64) -> ParameterRepeat {
    let (status, value) = p.per_set[k];
    let mine: Vec<&Test> = p
        .tests
        .iter()
        .filter(|t| t.set == k || t.other == Some(k))
        .collect();
    let vs_sets = mine
        .iter()
        .filter_map(|t| {
            let other = t.other?;
            // The pair's `z` is (earlier - later); from set k's side the sign follows k.
            Some(if t.set == k {
                PairDifference {
                    set: other + 1,
                    normalised_difference: t.z,
                }
            } else {
                PairDifference {
                    set: t.set + 1,
                    normalised_difference: -t.z,
                }
            })
        })
        .collect();
    let verdict = match value {
        None => format!("not determined by set {}", k + 1),
        Some(_) if mine.is_empty() => "not compared: no other set determined it".to_owned(),
        Some(_) if mine.iter().any(|t| t.z.abs() > threshold) => "differs".to_owned(),
        Some(_) => "agrees".to_owned(),
    };
    ParameterRepeat {
        parameter: p.label.clone(),
        status,
        estimate: value.map(|v| v.0),
        sigma: value.map(|v| v.1.sqrt()),
        vs_other_sets: p.rest[k],
        vs_sets,
        verdict,
    }
}

/// Per set, its gyro-bias rows, and the warnings of changes between consecutive sets
/// beyond [`BIAS_CHANGE_SIGMAS`] of the two estimates and the bias walk over the time
/// between them.
fn bias_changes(
    sets: &[SetInput],
    walks: &Walks,
    initial_bias_sigma_rad_s: f64,
) -> (Vec<Vec<ParameterRepeat>>, Vec<String>) {
    let mut rows: Vec<Vec<ParameterRepeat>> = vec![Vec::new(); sets.len()];
    let mut warnings = Vec::new();
    for axis in 0..3 {
        let label = format!("gyro_bias_{}_rad_s", ["x", "y", "z"][axis]);
        let of = |s: &SetInput| -> (Status, Option<(f64, f64)>) {
            match &s.estimate {
                Ok(e) if e.gyro_bias[axis].status != Status::NotDetermined => (
                    e.gyro_bias[axis].status,
                    Some((
                        e.calibration.gyro_bias_rad_s[axis],
                        e.calibration.gyro_bias_sigma_rad_s[axis].powi(2),
                    )),
                ),
                Ok(e) => (e.gyro_bias[axis].status, None),
                Err(_) => (Status::NotDetermined, None),
            }
        };
        for (k, set) in sets.iter().enumerate() {
            let (status, value) = of(set);
            let previous = k.checked_sub(1).map(|j| (j, of(&sets[j]).1));
            let change = match (value, previous) {
                (Some((b, v)), Some((j, Some((bj, vj))))) => {
                    let dt = set.end_s - sets[j].end_s;
                    let walk = walks.bias_rad_s_sqrt_s.powi(2) * dt.abs();
                    Some((
                        j,
                        b - bj,
                        normalised_difference(b, v, bj, vj, walk),
                        (v + vj + walk).sqrt(),
                    ))
                }
                _ => None,
            };
            let verdict = match (value, change) {
                (None, _) => format!("not determined by set {}", k + 1),
                (Some(_), None) if k == 0 => "not compared: the first set".to_owned(),
                (Some(_), None) => "not compared: the previous set did not determine it".to_owned(),
                (Some(_), Some((_, _, z, _))) if z.abs() > BIAS_CHANGE_SIGMAS => {
                    "changed".to_owned()
                }
                (Some(_), Some(_)) => "agrees".to_owned(),
            };
            if let Some((j, delta, z, sigma)) = change
                && z.abs() > BIAS_CHANGE_SIGMAS
                && !(walks.bias_restarts && delta.abs() <= 3.0 * initial_bias_sigma_rad_s)
            {
                warnings.push(bias_warning(
                    &label,
                    (j, k),
                    sets,
                    (delta, z, sigma),
                    initial_bias_sigma_rad_s,
                ));
            }
            rows[k].push(ParameterRepeat {
                parameter: label.clone(),
                status,
                estimate: value.map(|v| v.0),
                sigma: value.map(|v| v.1.sqrt()),
                vs_other_sets: None,
                vs_sets: change
                    .map(|(j, _, z, _)| PairDifference {
                        set: j + 1,
                        normalised_difference: z,
                    })
                    .into_iter()
                    .collect(),
                verdict,
            });
        }
    }
    (rows, warnings)
}

/// The warning of a gyro-bias change between sets `j` and `k`.
fn bias_warning(
    label: &str,
    (j, k): (usize, usize),
    sets: &[SetInput],
    (delta, z, sigma): (f64, f64, f64),
    prior_sigma: f64,
) -> String {
    let days = (sets[k].end_s - sets[j].end_s).abs() / 86_400.0;
    let allowed = if delta.abs() <= 3.0 * prior_sigma {
        format!(
            "expected of a gyro whose turn-on bias differs per power cycle, and the bias prior \
             ({:.3} deg/s) allows it",
            prior_sigma.to_degrees()
        )
    } else {
        format!(
            "beyond 3 sigma of the bias prior ({:.3} deg/s) too: set a wider \
             initial_bias_sigma_deg_s in --config for this gyro",
            prior_sigma.to_degrees()
        )
    };
    format!(
        "gyro bias: {label} changed by {:.3} deg/s from set {} ({}) to set {} ({}), {:.1} sigma \
         of the estimates and the bias random walk over {days:.1} days ({:.3} deg/s); {allowed}",
        delta.to_degrees(),
        j + 1,
        sets[j].name,
        k + 1,
        sets[k].name,
        z.abs(),
        sigma.to_degrees()
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use pdcal_filter::PdCalibration;

    fn judged(status: Status) -> Judged {
        Judged {
            status,
            reason: String::new(),
        }
    }

    /// A set of one photodiode with scale `c +- sigma`, the normal at (0, 60) +- 0.5 deg,
    /// the scale's status `status`, gyro bias `bias` +- 0.01 deg/s on every axis.
    fn set(name: &str, end_s: f64, (c, sigma): (f64, f64), status: Status, bias: f64) -> SetInput {
        let calibration = Calibration {
            format_version: 1,
            photodiodes: vec![PdCalibration {
                scale_v: c,
                scale_sigma_v: sigma,
                azimuth_deg: 0.0,
                azimuth_sigma_deg: Some(1.0),
                elevation_deg: 60.0,
                elevation_sigma_deg: 0.5,
            }],
            gyro_bias_rad_s: [bias; 3],
            gyro_bias_sigma_rad_s: [0.01f64.to_radians(); 3],
            parameters: Vec::new(),
            status: Vec::new(),
        };
        SetInput {
            name: name.to_owned(),
            end_s,
            estimate: Ok(SetEstimate {
                calibration,
                photodiodes: vec![PdIdentifiability {
                    status,
                    scale: judged(status),
                    azimuth: judged(Status::Calibrated),
                    elevation: judged(Status::Calibrated),
                }],
                gyro_bias: [
                    judged(Status::Calibrated),
                    judged(Status::Calibrated),
                    judged(Status::Calibrated),
                ],
            }),
        }
    }

    const NO_WALK: Walks = Walks {
        scale_fraction_per_sqrt_h: 0.0,
        normal_deg_per_sqrt_h: 0.0,
        bias_rad_s_sqrt_s: 0.0,
        bias_restarts: false,
    };

    const PRIOR: f64 = 0.5 * std::f64::consts::PI / 180.0;

    #[test]
    fn sidak_threshold_holds_the_family_rate() {
        // One test: the plain two-sided 3-sigma threshold.
        assert!((sidak_threshold(FAMILY_FALSE_ALARM, 1) - 3.0).abs() < 2e-3);
        // N tests at threshold z: 1 - (1 - P(|Z| > z))^N is the family rate.
        for n in [2, 12, 72, 1000] {
            let z = sidak_threshold(FAMILY_FALSE_ALARM, n);
            let tail = pdcal_filter::gate::erfc(z / std::f64::consts::SQRT_2);
            let family = 1.0 - (1.0 - tail).powi(n as i32);
            assert!(
                (family / FAMILY_FALSE_ALARM - 1.0).abs() < 1e-3,
                "{n}: {family}"
            );
        }
        assert!(sidak_threshold(0.0027, 72) > 4.0 && sidak_threshold(0.0027, 72) < 4.2);
    }

    #[test]
    fn inverse_variance_combination() {
        let (x, v) = combine(&[(1.0, 1.0), (3.0, 1.0)]).unwrap();
        assert!((x - 2.0).abs() < 1e-12 && (v - 0.5).abs() < 1e-12);
        let (x, v) = combine(&[(1.0, 1.0), (4.0, 4.0)]).unwrap();
        assert!((x - 1.6).abs() < 1e-12 && (v - 0.8).abs() < 1e-12);
        assert!(combine(&[(1.0, 0.0)]).is_none());
        assert!((normalised_difference(1.0, 0.5, 0.0, 0.25, 0.25) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn equal_estimates_agree() {
        let sets = [
            set("a", 0.0, (0.7, 0.01), Status::Calibrated, 0.0),
            set("b", 1.0, (0.7, 0.01), Status::Calibrated, 0.0),
            set("c", 2.0, (0.7, 0.01), Status::Calibrated, 0.0),
        ];
        let r = compare(&sets, &NO_WALK, PRIOR);
        assert_eq!(r.verdict, RepeatVerdict::Repeatable, "{:?}", r.warnings);
        // 3 parameters x (3 pairs + 3 against the rest).
        assert_eq!(r.comparisons, 18);
        assert!(r.warnings.is_empty() && r.bias_warnings.is_empty());
        let row = &r.sets[2].parameters[0];
        assert_eq!(row.parameter, "pd01 scale_V");
        assert_eq!(row.verdict, "agrees");
        assert_eq!(row.vs_sets.len(), 2);
        assert_eq!(row.vs_other_sets, Some(0.0));
    }

    #[test]
    fn a_known_disagreement_names_the_parameter_and_the_set() {
        // Set 3's C is 0.1 V off with sigmas of 0.01 V: 0.1 / sqrt(1e-4 + 0.5e-4) = 8.2 sigma
        // against the other two combined.
        let sets = [
            set("a", 0.0, (0.7, 0.01), Status::Calibrated, 0.0),
            set("b", 1.0, (0.7, 0.01), Status::WeaklyDetermined, 0.0),
            set("c", 2.0, (0.8, 0.01), Status::Calibrated, 0.0),
        ];
        let r = compare(&sets, &NO_WALK, PRIOR);
        assert_eq!(r.verdict, RepeatVerdict::NotRepeatable);
        assert_eq!(r.warnings.len(), 1, "{:?}", r.warnings);
        let w = &r.warnings[0];
        assert!(
            w.starts_with("repeatability: pd01 scale_V differs between the data sets: set 3 (c) 0.8000 +- 0.0100 V against the other sets' 0.7000 +- 0.0071 V, 8.2 sigma"),
            "{w}"
        );
        // Set 2 determined it only weakly: the warning says a weak set's wrong solution
        // may be the cause.
        assert!(
            w.ends_with("holding a wrong solution tighter than its sigma says"),
            "{w}"
        );
        let row = &r.sets[2].parameters[0];
        assert_eq!(row.verdict, "differs");
        assert!((row.vs_other_sets.unwrap() - 0.1 / 1.5e-4f64.sqrt()).abs() < 1e-9);
        // Every set calibrated it: the causes are the hardware's or the model's.
        let mut calibrated = sets;
        calibrated[1] = set("b", 1.0, (0.7, 0.01), Status::Calibrated, 0.0);
        let w = &compare(&calibrated, &NO_WALK, PRIOR).warnings[0];
        assert!(
            w.ends_with("a changed mounting or an effect the model lacks"),
            "{w}"
        );
        // A weak set's estimate says its status.
        calibrated[2] = set("c", 2.0, (0.8, 0.01), Status::WeaklyDetermined, 0.0);
        let w = &compare(&calibrated, &NO_WALK, PRIOR).warnings[0];
        assert!(
            w.contains("set 3 (c) 0.8000 +- 0.0100 V (weakly-determined) against"),
            "{w}"
        );
        // The pair (1, 3) differs too; the normals agree.
        assert_eq!(r.sets[0].parameters[0].verdict, "differs");
        assert_eq!(r.sets[0].parameters[1].verdict, "agrees");
    }

    #[test]
    fn the_walk_over_the_gap_is_allowed_and_undetermined_sets_are_not_compared() {
        // 0.05 V apart with sigmas 0.01 V: 3.5 sigma, inside the threshold for 2 tests...
        let two = |walks: &Walks, status| {
            compare(
                &[
                    set("a", 0.0, (0.7, 0.01), Status::Calibrated, 0.0),
                    set("b", 3600.0 * 1e4, (0.75, 0.01), status, 0.0),
                ],
                walks,
                PRIOR,
            )
        };
        let r = two(&NO_WALK, Status::Calibrated);
        assert_eq!(r.comparisons, 3);
        assert!(r.threshold_sigmas > 3.0 && r.threshold_sigmas < 3.4);
        assert_eq!(
            r.verdict,
            RepeatVerdict::NotRepeatable,
            "3.5 sigma > threshold"
        );
        // ... but a walk of 1e-3 C per sqrt(h) over 1e4 h (0.07 V) explains it.
        let walks = Walks {
            scale_fraction_per_sqrt_h: 1e-3,
            ..NO_WALK
        };
        assert_eq!(
            two(&walks, Status::Calibrated).verdict,
            RepeatVerdict::Repeatable
        );
        // A set that did not determine C: no number, no test.
        let r = two(&NO_WALK, Status::NotDetermined);
        assert_eq!(r.comparisons, 2);
        let row = &r.sets[1].parameters[0];
        assert_eq!(row.verdict, "not determined by set 2");
        assert!(row.estimate.is_none() && row.sigma.is_none());
        assert_eq!(r.verdict, RepeatVerdict::Repeatable);
    }

    #[test]
    fn a_run_that_does_not_repeat_is_not_consistent() {
        let consistent = || pdcal_filter::Consistency {
            verdict: pdcal_filter::Verdict::Consistent,
            reasons: Vec::new(),
            notes: Vec::new(),
            max_rms_over_noise: 3.0,
            sensors: Vec::new(),
            photodiodes: Vec::new(),
            dark: Vec::new(),
        };
        let run = |c3: f64| {
            let sets = [
                set("a", 0.0, (0.7, 0.01), Status::Calibrated, 0.0),
                set("b", 1.0, (0.7, 0.01), Status::Calibrated, 0.0),
                set("c", 2.0, (c3, 0.01), Status::Calibrated, 0.0),
            ];
            let (mut c, mut warnings) = (consistent(), vec!["earlier".to_owned()]);
            compare(&sets, &NO_WALK, PRIOR).apply(&mut c, &mut warnings);
            (c, warnings)
        };
        let (c, warnings) = run(0.7);
        assert_eq!(c.verdict, pdcal_filter::Verdict::Consistent);
        assert_eq!(warnings, ["earlier"]);
        let (c, warnings) = run(0.8);
        assert_eq!(c.verdict, pdcal_filter::Verdict::Inconsistent);
        assert_eq!(warnings.len(), 2);
        assert!(warnings[1].starts_with("repeatability: pd01 scale_V differs"));
        assert_eq!(c.reasons.len(), 1);
        assert!(
            c.reasons[0].ends_with("(repeatability): pd01 scale_V"),
            "{}",
            c.reasons[0]
        );
    }

    #[test]
    fn azimuths_are_compared_across_the_wrap() {
        assert!((Kind::Azimuth.difference(179.0, -179.0) + 2.0).abs() < 1e-12);
        assert!((Kind::Elevation.difference(179.0, -179.0) - 358.0).abs() < 1e-12);
    }

    #[test]
    fn a_bias_change_beyond_the_walk_is_a_warning_that_says_whether_the_prior_allows_it() {
        let sets = |b: f64| {
            [
                set("a", 0.0, (0.7, 0.01), Status::Calibrated, 0.0),
                set("b", 86_400.0, (0.7, 0.01), Status::Calibrated, b),
            ]
        };
        let r = compare(&sets(0.2f64.to_radians()), &NO_WALK, PRIOR);
        assert_eq!(
            r.verdict,
            RepeatVerdict::Repeatable,
            "the bias is no calibration constant"
        );
        assert_eq!(r.bias_warnings.len(), 3, "{:?}", r.bias_warnings);
        assert!(
            r.bias_warnings[0].contains(
                "gyro_bias_x_rad_s changed by 0.200 deg/s from set 1 (a) to set 2 (b), 14.1 sigma"
            ),
            "{}",
            r.bias_warnings[0]
        );
        assert!(r.bias_warnings[0].contains("the bias prior (0.500 deg/s) allows it"));
        let r = compare(&sets(2.0f64.to_radians()), &NO_WALK, PRIOR);
        assert!(
            r.bias_warnings[0].contains("beyond 3 sigma of the bias prior"),
            "{}",
            r.bias_warnings[0]
        );
        // A walk of 1e-4 rad/s/sqrt(s) over a day (0.029 rad/s) covers 0.2 deg/s.
        let walks = Walks {
            bias_rad_s_sqrt_s: 1e-4,
            ..NO_WALK
        };
        assert!(
            compare(&sets(0.2f64.to_radians()), &walks, PRIOR)
                .bias_warnings
                .is_empty()
        );
        let row = &compare(&sets(0.2f64.to_radians()), &NO_WALK, PRIOR).sets[1].parameters[3];
        assert_eq!(row.parameter, "gyro_bias_x_rad_s");
        assert_eq!(row.verdict, "changed");
    }

    #[test]
    fn a_filter_that_restarts_the_bias_per_set_is_warned_only_beyond_the_prior() {
        let sets = |b: f64| {
            [
                set("a", 0.0, (0.7, 0.01), Status::Calibrated, 0.0),
                set("b", 86_400.0, (0.7, 0.01), Status::Calibrated, b),
            ]
        };
        let restarts = Walks {
            bias_restarts: true,
            ..NO_WALK
        };
        let r = compare(&sets(0.2f64.to_radians()), &restarts, PRIOR);
        assert!(r.bias_warnings.is_empty(), "{:?}", r.bias_warnings);
        assert_eq!(r.sets[1].parameters[3].verdict, "changed");
        let r = compare(&sets(2.0f64.to_radians()), &restarts, PRIOR);
        assert_eq!(r.bias_warnings.len(), 3, "{:?}", r.bias_warnings);
        assert!(r.bias_warnings[0].contains("beyond 3 sigma of the bias prior"));
    }

    #[test]
    fn a_failed_own_pass_is_said_and_left_out() {
        let mut sets = vec![
            set("a", 0.0, (0.7, 0.01), Status::Calibrated, 0.0),
            set("b", 1.0, (0.7, 0.01), Status::Calibrated, 0.0),
        ];
        sets[1].estimate = Err("no usable row".to_owned());
        let r = compare(&sets, &NO_WALK, PRIOR);
        assert_eq!(r.verdict, RepeatVerdict::NotChecked);
        assert_eq!(r.sets[1].own_pass_failed.as_deref(), Some("no usable row"));
        assert_eq!(
            r.sets[0].parameters[0].verdict,
            "not compared: no other set determined it"
        );
    }
}
