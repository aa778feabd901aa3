//! The hypotheses, their costs and the decision.

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

use crate::kinematics::{
    Angle, SCALE_FLOOR, Step, angle_residuals, bias_cost, cauchy_cost, robust_scale, step_residuals,
};
use crate::permutation::signed_permutations;

/// A vector sensor whose axes are checked.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Sensor {
    /// The rate gyro.
    Gyro,
    /// The magnetometer.
    Magnetometer,
    /// The photodiode table (its normals' frame).
    Photodiodes,
}

impl Sensor {
    /// The name used in files and messages.
    pub fn as_str(self) -> &'static str {
        match self {
            Sensor::Gyro => "gyro",
            Sensor::Magnetometer => "magnetometer",
            Sensor::Photodiodes => "photodiodes",
        }
    }
}

/// The data of the check, one entry per telemetry row; every vector in its sensor's stated
/// frame.
#[derive(Debug, Clone, Copy)]
pub struct Inputs<'a> {
    /// Sample times, s.
    pub t_s: &'a [f64],
    /// Gyro rate, rad/s (`None` where not sampled).
    pub gyro_rad_s: &'a [Option<Vector3<f64>>],
    /// Magnetometer, any unit (`None` where not sampled; an empty slice: no magnetometer).
    pub mag: &'a [Option<Vector3<f64>>],
    /// The Sun direction the photodiodes give with the stated table (`None` where they do
    /// not give one).
    pub sun_photodiodes: &'a [Option<Vector3<f64>>],
    /// Unit Sun direction and IGRF's field at the spacecraft, inertial, per row.
    pub references: &'a [(Vector3<f64>, Vector3<f64>)],
    /// The gyro bias's prior sigma per axis, rad/s: how large a bias may be. A reversed
    /// axis along which the body turns at a constant rate (the symmetry axis of an
    /// axisymmetric tumble) differs from the stated one only by a bias of twice that rate,
    /// which this prior weighs.
    pub gyro_bias_sigma_rad_s: f64,
}

/// When a hypothesis becomes a finding.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Thresholds {
    /// Cost (nats) by which the stated axes must lose to the best hypothesis.
    pub finding_nats: f64,
    /// Cost (nats) by which every other hypothesis must lose to the best.
    pub separation_nats: f64,
    /// Longest step between two rows a kinematic check uses, s.
    pub max_step_s: f64,
    /// Largest rotation over one step a kinematic check uses, rad.
    pub max_step_rad: f64,
    /// Fewest residuals a check needs to count.
    pub min_samples: usize,
    /// Most steps or rows a check uses, evenly thinned: a wrong frame costs hundreds of nats
    /// on a few hundred samples, and each hypothesis's bias fit is one pass over them.
    pub max_samples: usize,
}

impl Default for Thresholds {
    fn default() -> Self {
        Thresholds {
            finding_nats: 100.0,
            separation_nats: 30.0,
            max_step_s: 30.0,
            max_step_rad: 1.0,
            min_samples: 30,
            max_samples: 800,
        }
    }
}

/// What a finding rests on.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Evidence {
    /// Cost of the stated axes less that of the finding, nats (the log of the likelihood
    /// ratio under the checks' Cauchy model).
    pub log_odds_nats: f64,
    /// Cost of the next-best hypothesis less that of the finding, nats.
    pub runner_up_nats: f64,
    /// The checks that took part: name, residuals, robust scale with the stated axes and
    /// with the finding.
    pub checks: Vec<CheckUse>,
    /// Other matrices of the same sensor that fit within the separation (their bias
    /// differs; the finding is the one whose bias the prior finds likelier).
    pub twins: Vec<[[i8; 3]; 3]>,
}

/// One check's part in a decision.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CheckUse {
    /// `gyro-magnetometer`, `gyro-photodiodes` or `magnetometer-photodiodes`.
    pub name: &'static str,
    /// Residuals used.
    pub samples: usize,
    /// Robust scale of its residuals with the stated axes (rad, or cosine).
    pub stated_scale: f64,
    /// The same with the finding applied.
    pub found_scale: f64,
}

/// One sensor's axes found other than stated.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Finding {
    /// The sensor.
    pub sensor: Sensor,
    /// `v_body = M v_sensor`, a signed permutation.
    pub body_from_sensor: [[i8; 3]; 3],
    /// Why.
    pub evidence: Evidence,
}

impl Finding {
    /// The matrix as floats.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::from_fn(|r, c| f64::from(self.body_from_sensor[r][c]))
    }
}

/// A sensor whose axes the data could not decide.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NotChecked {
    /// The sensor.
    pub sensor: Sensor,
    /// Why, in words.
    pub reason: String,
}

/// The result of [`check`].
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct AxesCheck {
    /// The finding, if any (one sensor at most).
    pub finding: Option<Finding>,
    /// The sensors whose axes were not checked, with the reason.
    pub not_checked: Vec<NotChecked>,
    /// The checks that had enough data, with their residual counts.
    pub checks: Vec<CheckCount>,
    /// When the stated axes fit best: by how much the next hypothesis loses, nats.
    pub stated_margin_nats: Option<f64>,
}

/// One check that ran.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CheckCount {
    /// `gyro-magnetometer`, `gyro-photodiodes` or `magnetometer-photodiodes`.
    pub name: &'static str,
    /// Residuals used.
    pub samples: usize,
}

/// One hypothesis: one sensor's matrix, the others as stated.
#[derive(Debug, Clone, Copy)]
struct Hypothesis {
    sensor: Option<Sensor>,
    matrix: Matrix3<f64>,
}

impl Hypothesis {
    fn of(&self, sensor: Sensor) -> Matrix3<f64> {
        if self.sensor == Some(sensor) {
            self.matrix
        } else {
            Matrix3::identity()
        }
    }
}

/// The checks' data.
struct Data {
    bias_sigma_rad_s: f64,
    gyro_mag: Vec<Step>,
    gyro_sun: Vec<Step>,
    angles: Vec<Angle>,
}

/// Checks the axes of every vector sensor against the others (module docs).
pub fn check(inputs: &Inputs<'_>, thresholds: &Thresholds) -> AxesCheck {
    let thin = |v| thinned(v, thresholds.max_samples);
    let data = Data {
        bias_sigma_rad_s: inputs.gyro_bias_sigma_rad_s,
        gyro_mag: thin(steps(inputs, inputs.mag, thresholds)),
        gyro_sun: thin(steps(inputs, inputs.sun_photodiodes, thresholds)),
        angles: thinned(angles(inputs), thresholds.max_samples),
    };
    let enough = |n: usize| n >= thresholds.min_samples;
    let (gm, gs, ms) = (
        enough(data.gyro_mag.len()),
        enough(data.gyro_sun.len()),
        enough(data.angles.len()),
    );
    let mut sensors = Vec::new();
    let mut not_checked = Vec::new();
    let mut consider = |sensor: Sensor, checkable: bool, why: &str| {
        if checkable {
            sensors.push(sensor);
        } else {
            not_checked.push(NotChecked {
                sensor,
                reason: why.to_owned(),
            });
        }
    };
    let has_mag = !inputs.mag.is_empty();
    consider(
        Sensor::Gyro,
        gm || gs,
        "too few steps with the gyro and a magnetometer or photodiode direction at both ends",
    );
    if has_mag {
        consider(
            Sensor::Magnetometer,
            gm || ms,
            "too few rows with the field and the gyro or the Sun direction",
        );
        // With the gyro and the magnetometer agreeing, the photodiode table is checked
        // against both; without the magnetometer the table defines the body frame.
        consider(
            Sensor::Photodiodes,
            gs || ms,
            "too few rows with a Sun direction from the photodiodes",
        );
    }
    let mut hypotheses = vec![Hypothesis {
        sensor: None,
        matrix: Matrix3::identity(),
    }];
    for &sensor in &sensors {
        hypotheses.extend(
            signed_permutations()
                .into_iter()
                .skip(1)
                .map(|matrix| Hypothesis {
                    sensor: Some(sensor),
                    matrix,
                }),
        );
    }
    let (mut result, _) = decide(&data, &hypotheses, thresholds, (gm, gs, ms));
    result.not_checked.splice(0..0, not_checked);
    result
}

/// One hypothesis's residuals of the three checks (empty when unused) and the cost of the
/// bias it needs (its prior, counted once: on the gyro-magnetometer check when used).
fn residuals(data: &Data, h: &Hypothesis, used: (bool, bool, bool)) -> ([Vec<f64>; 3], f64) {
    let (g, m, p) = (
        h.of(Sensor::Gyro),
        h.of(Sensor::Magnetometer),
        h.of(Sensor::Photodiodes),
    );
    let prior = Some(data.bias_sigma_rad_s);
    let (gm, gm_bias) = if used.0 {
        step_residuals(&data.gyro_mag, &g, &m, prior)
    } else {
        (Vec::new(), Vector3::zeros())
    };
    let (gs, gs_bias) = if used.1 {
        step_residuals(&data.gyro_sun, &g, &p, prior)
    } else {
        (Vec::new(), Vector3::zeros())
    };
    let bias = if used.0 { gm_bias } else { gs_bias };
    let ms = if used.2 {
        angle_residuals(&data.angles, &p, &m)
    } else {
        Vec::new()
    };
    ([gm, gs, ms], bias_cost(&bias, prior))
}

const CHECK_NAMES: [&str; 3] = [
    "gyro-magnetometer",
    "gyro-photodiodes",
    "magnetometer-photodiodes",
];

fn decide(
    data: &Data,
    hypotheses: &[Hypothesis],
    thresholds: &Thresholds,
    used: (bool, bool, bool),
) -> (AxesCheck, Vec<f64>) {
    let (all, bias_costs): (Vec<[Vec<f64>; 3]>, Vec<f64>) =
        hypotheses.iter().map(|h| residuals(data, h, used)).unzip();
    let scales: Vec<[f64; 3]> = all
        .iter()
        .map(|sets| sets.clone().map(|mut r| robust_scale(&mut r)))
        .collect();
    // Each check's scale: its best hypothesis's (a wrong frame widens it).
    let scale: [f64; 3] = std::array::from_fn(|j| {
        scales
            .iter()
            .map(|s| s[j])
            .fold(f64::INFINITY, f64::min)
            .max(SCALE_FLOOR)
    });
    let costs: Vec<f64> = all
        .iter()
        .zip(&bias_costs)
        .map(|(sets, bias)| bias + (0..3).map(|j| cauchy_cost(&sets[j], scale[j])).sum::<f64>())
        .collect();
    let mut order: Vec<usize> = (0..hypotheses.len()).collect();
    order.sort_by(|&a, &b| costs[a].total_cmp(&costs[b]));
    let best = order[0];
    let runner_up = order
        .get(1)
        .map_or(f64::INFINITY, |&k| costs[k] - costs[best]);
    let mut result = AxesCheck {
        checks: (0..3)
            .filter(|&j| !all[0][j].is_empty())
            .map(|j| CheckCount {
                name: CHECK_NAMES[j],
                samples: all[0][j].len(),
            })
            .collect(),
        ..AxesCheck::default()
    };
    let best_h = hypotheses[best];
    match best_h.sensor {
        None => {
            result.stated_margin_nats = runner_up.is_finite().then_some(runner_up);
            if runner_up < thresholds.finding_nats {
                let rival = hypotheses[order[1]];
                let sensor = rival.sensor.unwrap_or(Sensor::Gyro);
                result.not_checked.push(NotChecked {
                    sensor,
                    reason: format!(
                        "the data cannot tell its stated axes from {} ({:.1} nats apart; a \
                         finding needs {:.0})",
                        matrix_text(&rival.matrix),
                        runner_up,
                        thresholds.finding_nats
                    ),
                });
            }
        }
        Some(sensor) => {
            let log_odds = costs[0] - costs[best];
            let evidence = Evidence {
                log_odds_nats: log_odds,
                runner_up_nats: runner_up,
                checks: (0..3)
                    .filter(|&j| !all[best][j].is_empty())
                    .map(|j| CheckUse {
                        name: CHECK_NAMES[j],
                        samples: all[best][j].len(),
                        stated_scale: scales[0][j],
                        found_scale: scales[best][j],
                    })
                    .collect(),
                twins: Vec::new(),
            };
            // Rivals within the separation of the same sensor are twins the data cannot
            // tell apart but that change nothing the filter sees beyond the bias (a
            // reversed axis turning at a constant rate); the prior on the bias ranks them.
            // A rival of another sensor (or the stated axes) leaves it undecided.
            let rivals: Vec<&Hypothesis> = order[1..]
                .iter()
                .take_while(|&&k| costs[k] - costs[best] < thresholds.separation_nats)
                .map(|&k| &hypotheses[k])
                .collect();
            let twins_only = rivals.iter().all(|h| h.sensor == Some(sensor));
            if log_odds >= thresholds.finding_nats && twins_only {
                let mut evidence = evidence;
                evidence.twins = rivals.iter().map(|h| signs(&h.matrix)).collect();
                result.finding = Some(Finding {
                    sensor,
                    body_from_sensor: signs(&best_h.matrix),
                    evidence,
                });
            } else {
                result.not_checked.push(NotChecked {
                    sensor,
                    reason: format!(
                        "its axes fit better as {} ({:.1} nats over the stated, {:.1} over the \
                         next hypothesis), short of a finding's {:.0} and {:.0}",
                        matrix_text(&best_h.matrix),
                        log_odds,
                        runner_up,
                        thresholds.finding_nats,
                        thresholds.separation_nats
                    ),
                });
            }
        }
    }
    (result, costs)
}

fn signs(m: &Matrix3<f64>) -> [[i8; 3]; 3] {
    std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)].round() as i8))
}

/// `[[1, 0, 0], [0, -1, 0], [0, 0, 1]]`.
pub(crate) fn matrix_text(m: &Matrix3<f64>) -> String {
    let rows: Vec<String> = (0..3)
        .map(|r| {
            let cells: Vec<String> = (0..3)
                .map(|c| format!("{}", m[(r, c)].round() as i8))
                .collect();
            format!("[{}]", cells.join(", "))
        })
        .collect();
    format!("[{}]", rows.join(", "))
}

/// The steps between consecutive rows where `vectors` is sampled, with the gyro's mean
/// over the rows of the step.
fn steps(inputs: &Inputs<'_>, vectors: &[Option<Vector3<f64>>], t: &Thresholds) -> Vec<Step> {
    let present: Vec<(usize, Vector3<f64>)> = vectors
        .iter()
        .enumerate()
        .filter_map(|(k, v)| v.and_then(|v| v.try_normalize(1e-12)).map(|v| (k, v)))
        .collect();
    present
        .windows(2)
        .filter_map(|pair| {
            let ((k0, from), (k1, to)) = (pair[0], pair[1]);
            let dt_s = inputs.t_s.get(k1)? - inputs.t_s.get(k0)?;
            let rate = mean_rate(inputs.gyro_rad_s.get(k0..=k1)?)?;
            let ok = dt_s > 0.0 && dt_s <= t.max_step_s && rate.norm() * dt_s <= t.max_step_rad;
            ok.then_some(Step {
                from,
                to,
                rate_rad_s: rate,
                dt_s,
            })
        })
        .collect()
}

/// At most `max` of `items`, evenly spaced.
fn thinned<T: Copy>(items: Vec<T>, max: usize) -> Vec<T> {
    if items.len() <= max || max == 0 {
        return items;
    }
    (0..max).map(|i| items[i * items.len() / max]).collect()
}

fn mean_rate(rates: &[Option<Vector3<f64>>]) -> Option<Vector3<f64>> {
    let present: Vec<Vector3<f64>> = rates.iter().flatten().copied().collect();
    (!present.is_empty()).then(|| present.iter().sum::<Vector3<f64>>() / present.len() as f64)
}

fn angles(inputs: &Inputs<'_>) -> Vec<Angle> {
    inputs
        .mag
        .iter()
        .zip(inputs.sun_photodiodes)
        .zip(inputs.references)
        .filter_map(|((m, s), (sun_ref, field_ref))| {
            let field = m.as_ref()?.try_normalize(1e-12)?;
            let sun = s.as_ref()?.try_normalize(1e-12)?;
            let cos_ref = sun_ref
                .try_normalize(1e-12)?
                .dot(&field_ref.try_normalize(1e-12)?);
            Some(Angle {
                sun,
                field,
                cos_ref,
            })
        })
        .collect()
}
