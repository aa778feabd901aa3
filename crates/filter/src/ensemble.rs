//! The multi-start ensemble: the reported covariances widened by what the data do not
//! decide between.
//!
//! With the Sun as the only vector, an uncalibrated head's attitude and calibration are not
//! one Gaussian through the first sunlit minutes: a tilt of the attitude and a change of the
//! scale factors and normals fit the outputs nearly as well, and the EKF, linearised at
//! estimates tens of degrees from the truth, settles on one solution and shrinks its
//! covariance there (docs/validation.md, "pyramid-head"). Its sigmas then describe that
//! solution, not the data's uncertainty.
//!
//! The ensemble measures the part the covariance misses. Besides the run itself (the base),
//! it makes `n` forward passes over the same data, each from a calibration start drawn from
//! the prior (each photodiode's scale factor and normal moved by a draw of its own prior
//! sigma, [`StartDraw`]), the prior's sigmas unchanged. Where the data determine a state,
//! every pass ends at the same value and nothing changes; where they do not, the passes end
//! apart. At every row, the members' deviations from the base (the attitude as the filter's
//! rotation-vector error, split at the Sun line, [`attitude_deviation`]; the gyro bias,
//! each scale, azimuth and elevation, each estimated parameter) are averaged as outer
//! products and added to the base's covariance: the reported estimate stays the base's, its
//! sigma becomes that of the base's own Gaussian plus the spread of the solutions the data
//! allow (the second moment about the base of a mixture of the base and the members).
//! Each member's weight in that mixture is its posterior under equal priors: its predictive
//! likelihood over the base's, summed over the updates both made ([`row_evidence`], a gated
//! update counted at the gate so that one outlier cannot decide). A member the data have
//! ruled out adds nothing; members that fit as well as the base share the weight equally
//! with it.
//!
//! What is widened: every forward row (`estimates.csv`), the smoothed rows (with the spread
//! of the nearest stored forward row before them: conservative, as a smoothed estimate
//! spreads less than a forward one), the final calibration and the final covariance, so that
//! the statuses of [`crate::identifiability`] read the widened sigmas. What is not: the
//! filter's own gates, loss test and residual bounds, which are the base's.

use nalgebra::{DMatrix, Matrix3, Rotation3, Vector3};
use pdcal_attitude::mekf::error_vector;
use pdcal_attitude::{Quat, tangent_basis, wrap_deg};
use pdcal_photodiode::MeasurementModel;
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;

use crate::calibration::Calibration;
use crate::config::{EnsembleRuns, Mode};
use crate::filter::Algebra;
use crate::forward::ForwardPass;
use crate::layout::{ATTITUDE, BIAS, StateLayout};
use crate::output::{CalibrationRun, ResidualRecord, StepEstimate};
use crate::prepare::{Prepared, RunInputs};
use crate::smoother::tangent_log_in;
use crate::{FilterConfig, References};

/// Members of `EnsembleRuns::Auto` when the Sun is the only vector. Eight: the spread's
/// variance is estimated from eight deviations (its relative error about half), enough to
/// tell a state the data determine (members within its sigma) from one they do not
/// (members tens of sigmas apart), at nine times the forward pass's cost.
pub const AUTO_RUNS: usize = 8;

/// Most members a configuration may ask for.
pub const MAX_RUNS: usize = 64;

/// Stored forward spreads for the smoothed rows, at most: the spread of every row up to
/// this many rows, of every k-th beyond (about 30 MB for 17 photodiodes).
const MAX_STORED_SPREADS: usize = 1 << 16;

/// One member's start: standard normal draws that move each photodiode's initial scale by
/// its prior sigma times the draw, and its normal along its two tangent axes likewise.
#[derive(Debug, Clone, PartialEq)]
pub struct StartDraw {
    /// Per photodiode, the scale's draw.
    pub scale_z: Vec<f64>,
    /// Per photodiode, the normal's draws along its tangent basis.
    pub normal_z: Vec<[f64; 2]>,
}

impl StartDraw {
    /// `runs` draws for `photodiodes` photodiodes from `seed` (ChaCha8: the same seed gives
    /// the same draws in every rand version).
    pub fn draws(seed: u64, photodiodes: usize, runs: usize) -> Vec<StartDraw> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut z = || -> f64 { StandardNormal.sample(&mut rng) };
        (0..runs)
            .map(|_| StartDraw {
                scale_z: (0..photodiodes).map(|_| z()).collect(),
                normal_z: (0..photodiodes).map(|_| [z(), z()]).collect(),
            })
            .collect()
    }

    /// Moves the initial scales (by `scale_sigma_v` times the draw, kept above a tenth of
    /// the scale: a scale factor is positive) and the normals (by `normal_sigma_rad` times
    /// the draws along their tangent basis, along the sphere).
    pub fn apply(
        &self,
        scale_v: &mut [f64],
        scale_sigma_v: &[f64],
        n_body: &mut [Vector3<f64>],
        normal_sigma_rad: f64,
    ) {
        for ((c, sigma), z) in scale_v.iter_mut().zip(scale_sigma_v).zip(&self.scale_z) {
            *c = (*c + sigma * z).max(0.1 * *c);
        }
        for (n, z) in n_body.iter_mut().zip(&self.normal_z) {
            let (e1, e2) = tangent_basis(n);
            let t = (e1 * z[0] + e2 * z[1]) * normal_sigma_rad;
            let angle = t.norm();
            if angle > 0.0 {
                *n = (*n * angle.cos() + t * (angle.sin() / angle)).normalize();
            }
        }
    }
}

/// What `summary.json` says of the ensemble.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EnsembleReport {
    /// Members asked for.
    pub runs: usize,
    /// Members that acquired an attitude and ran (a start from which no attitude is
    /// acquired, or whose pass fails, is left out).
    pub started: usize,
    /// Members that ran to the end of the data.
    pub completed: usize,
    /// The seed of their starts.
    pub seed: u64,
}

/// How many members `config` asks for on a run that uses the magnetometer or not.
pub fn runs_for(config: &FilterConfig, uses_magnetometer: bool) -> usize {
    match config.ensemble {
        EnsembleRuns::Auto if !uses_magnetometer => AUTO_RUNS,
        EnsembleRuns::Auto | EnsembleRuns::Off => 0,
        EnsembleRuns::Runs(n) => n.min(MAX_RUNS),
    }
}

/// One member: its pass, its latest estimate with that row's updates, and its evidence
/// against the base.
struct Member<'a> {
    pass: ForwardPass<'a>,
    last: Option<StepEstimate>,
    records: Vec<ResidualRecord>,
    done: bool,
    /// `-2 ln` of the member's predictive likelihood over the base's, summed over the
    /// updates both made ([`row_evidence`]).
    score: f64,
}

impl Member<'_> {
    /// Whether the member's latest estimate is of row `index`.
    fn holds(&self, index: usize) -> bool {
        self.last.as_ref().is_some_and(|e| e.index == index)
    }

    /// Steps the member to row `index`; whether it has an estimate there (not where its
    /// attitude is not held, or its pass ended or failed).
    fn at(&mut self, index: usize) -> bool {
        while !self.done && self.last.as_ref().is_none_or(|e| e.index < index) {
            match self.pass.step() {
                Ok(Some(_)) => {
                    self.last = Some(self.pass.estimate());
                    self.records.clear();
                    self.records.extend(self.pass.residual_records());
                }
                // A member that fails is left out from there; the base is unaffected.
                Ok(None) | Err(_) => self.done = true,
            }
        }
        self.holds(index)
    }

    /// Steps the member to the end of the data; whether it got there.
    fn finish(&mut self) -> bool {
        while !self.done {
            match self.pass.step() {
                Ok(Some(_)) => self.last = Some(self.pass.estimate()),
                Ok(None) => return true,
                Err(_) => self.done = true,
            }
        }
        self.pass.remaining() == 0
    }
}

/// `-2 ln` of the predictive likelihood of `member`'s updates of one row over `base`'s, over
/// the sensors both updated or gated there (each update `nu^2 / S + ln S`, a gated one
/// counted at the gate, `nu^2 / S = gate^2`: an outlier the gate refused is no more
/// evidence than the gate itself).
pub fn row_evidence(base: &[ResidualRecord], member: &[ResidualRecord], gate_sigmas: f64) -> f64 {
    let term = |r: &ResidualRecord| {
        let s = (r.bound_3sigma / 3.0).powi(2);
        if s.is_nan() || s <= 0.0 {
            return None;
        }
        let nis = if r.accepted {
            r.residual * r.residual / s
        } else {
            gate_sigmas * gate_sigmas
        };
        Some(nis + s.ln())
    };
    base.iter()
        .filter_map(|b| {
            let m = member.iter().find(|m| m.sensor == b.sensor)?;
            Some(term(m)? - term(b)?)
        })
        .sum()
}

/// Normalised weights of the base (first) and of the members with `scores` (`-2 ln` of
/// their likelihood over the base's): the posterior weights of an equal-prior mixture.
fn mixture_weights(scores: &[f64]) -> Vec<f64> {
    let log_w: Vec<f64> = std::iter::once(0.0)
        .chain(scores.iter().map(|s| -0.5 * s))
        .collect();
    let max = log_w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let w: Vec<f64> = log_w.iter().map(|l| (l - max).exp()).collect();
    let total: f64 = w.iter().sum();
    w.iter().map(|x| x / total).collect()
}

/// The members' spread about the base at one row: the mean outer product of their
/// deviations, per state group.
#[derive(Debug, Clone, PartialEq)]
pub struct Spread {
    /// Attitude (rotation-vector error of the member from the base, body frame), rad^2.
    pub attitude_rad2: Matrix3<f64>,
    /// Gyro bias per axis, (rad/s)^2.
    pub bias_rad2_s2: [f64; 3],
    /// Per photodiode: scale (V^2), azimuth (deg^2), elevation (deg^2).
    pub photodiodes: Vec<[f64; 3]>,
    /// Per estimated parameter, unit^2.
    pub parameters: Vec<f64>,
}

impl Spread {
    /// The spread of `members` about `base`, the attitude's split about the Sun line
    /// `sun_gcrf` when given ([`attitude_deviation`]); `None` without members.
    pub fn of(
        base: &StepEstimate,
        members: &[(&StepEstimate, f64)],
        sun_gcrf: Option<&Vector3<f64>>,
    ) -> Option<Spread> {
        if members.is_empty() {
            return None;
        }
        let mut attitude_rad2 = Matrix3::zeros();
        for (m, w) in members {
            let d = attitude_deviation(&m.q, &base.q, sun_gcrf);
            attitude_rad2 += d * d.transpose() * *w;
        }
        let calibrations: Vec<(&Calibration, f64)> =
            members.iter().map(|(m, w)| (&m.calibration, *w)).collect();
        let mut spread = Spread::of_calibration(&base.calibration, &calibrations);
        spread.attitude_rad2 = attitude_rad2;
        Some(spread)
    }

    /// The calibration part of the spread of `members` (each with its mixture weight)
    /// about `base` (attitude zero).
    fn of_calibration(base: &Calibration, members: &[(&Calibration, f64)]) -> Spread {
        let mean_sq = |f: &dyn Fn(&Calibration) -> f64| {
            members
                .iter()
                .map(|(m, w)| w * (f(m) - f(base)).powi(2))
                .sum::<f64>()
        };
        let photodiodes = (0..base.photodiodes.len())
            .map(|i| {
                let azimuth_sq = members
                    .iter()
                    .map(|(m, w)| {
                        w * wrap_deg(m.photodiodes[i].azimuth_deg - base.photodiodes[i].azimuth_deg)
                            .powi(2)
                    })
                    .sum::<f64>();
                [
                    mean_sq(&|c| c.photodiodes[i].scale_v),
                    azimuth_sq,
                    mean_sq(&|c| c.photodiodes[i].elevation_deg),
                ]
            })
            .collect();
        let parameters = base
            .parameters
            .iter()
            .map(|p| {
                let dev = members.iter().filter_map(|(m, w)| {
                    m.parameters
                        .iter()
                        .find(|q| q.name == p.name)
                        .map(|q| w * (q.value - p.value).powi(2))
                });
                dev.sum::<f64>()
            })
            .collect();
        Spread {
            attitude_rad2: Matrix3::zeros(),
            bias_rad2_s2: std::array::from_fn(|k| mean_sq(&|c| c.gyro_bias_rad_s[k])),
            photodiodes,
            parameters,
        }
    }

    /// Adds the spread to `e`'s attitude covariance and calibration sigmas.
    pub fn widen(&self, e: &mut StepEstimate) {
        e.set_attitude_cov_deg2(&(e.attitude_cov_deg2() + self.attitude_rad2 * DEG2_PER_RAD2));
        self.widen_calibration(&mut e.calibration);
    }

    /// Adds the calibration part of the spread to `cal`'s sigmas.
    fn widen_calibration(&self, cal: &mut Calibration) {
        for (s, b) in cal.gyro_bias_sigma_rad_s.iter_mut().zip(&self.bias_rad2_s2) {
            *s = s.hypot(b.sqrt());
        }
        for (pd, [scale, azimuth, elevation]) in cal.photodiodes.iter_mut().zip(&self.photodiodes) {
            pd.scale_sigma_v = pd.scale_sigma_v.hypot(scale.sqrt());
            pd.azimuth_sigma_deg = pd.azimuth_sigma_deg.map(|s| s.hypot(azimuth.sqrt()));
            pd.elevation_sigma_deg = pd.elevation_sigma_deg.hypot(elevation.sqrt());
        }
        for (p, v) in cal.parameters.iter_mut().zip(&self.parameters) {
            p.sigma = p.sigma.hypot(v.sqrt());
        }
    }
}

/// The attitude of `member` relative to `base` as the filter's error vector (`A(member) =
/// A(dq(a)) A(base)`), split at the Sun line `sun_gcrf`: the swing that carries the base's
/// body Sun direction to the member's (across the line, its length the angle between the
/// two Sun directions) plus the twist about the base's Sun line. One rotation vector of a
/// large rotation mixes the two (a half turn about an axis 10 deg off the Sun line has 31
/// deg across it while the Sun direction moves 20 deg); split, the spread across the Sun
/// line is that of the Sun directions themselves. Without a Sun direction, the rotation
/// vector ([`error_vector`]).
pub fn attitude_deviation(
    member: &Quat,
    base: &Quat,
    sun_gcrf: Option<&Vector3<f64>>,
) -> Vector3<f64> {
    let Some(sun) = sun_gcrf else {
        return error_vector(member, base);
    };
    let (s_base, s_member) = (base.to_body(sun), member.to_body(sun));
    let cross = s_member.cross(&s_base);
    let sin = cross.norm();
    let swing = if sin > 0.0 {
        cross * (sin.atan2(s_member.dot(&s_base)) / sin)
    } else {
        Vector3::zeros()
    };
    // The body-vector rotation of `member` from `base`, less the swing's: about `s_base`.
    let total = member.attitude_matrix() * base.attitude_matrix().transpose();
    let twist = Rotation3::new(-swing).matrix().transpose() * total;
    let (u, _) = tangent_basis(&s_base);
    let turned = twist * u;
    let angle = s_base.dot(&u.cross(&turned)).atan2(u.dot(&turned));
    swing - s_base * angle
}

const DEG2_PER_RAD2: f64 = (180.0 / std::f64::consts::PI) * (180.0 / std::f64::consts::PI);

/// The members of a run and the spreads kept for its smoothed rows.
pub struct Ensemble<'a> {
    members: Vec<Member<'a>>,
    /// The run's references (the Sun line of each row).
    references: References<'a>,
    runs: usize,
    seed: u64,
    /// Every `stride`-th row's spread, by row index, for the smoothed rows.
    stored: Vec<(usize, Spread)>,
    stride: usize,
    /// The base's last forward estimate (its attitude for the final covariance).
    last_base: Option<(usize, Quat)>,
    /// The innovation gate, sigmas ([`row_evidence`]).
    gate_sigmas: f64,
}

impl<'a> Ensemble<'a> {
    /// The members `base`'s configuration asks for ([`runs_for`]), each a [`ForwardPass`]
    /// from its own [`StartDraw`] with the model `model` makes; `None` when it asks for none.
    pub fn start(
        base: &ForwardPass<'a>,
        (inputs, prepared, mode): (&RunInputs<'a>, &'a Prepared<'a>, &'a Mode),
        model: &dyn Fn() -> MeasurementModel,
        algebra: Algebra,
    ) -> Option<Ensemble<'a>> {
        let config = prepared.config();
        let runs = runs_for(config, base.uses_magnetometer());
        if runs == 0 {
            return None;
        }
        let photodiodes = inputs.meta.photodiodes.len();
        let members = StartDraw::draws(config.ensemble_seed, photodiodes, runs)
            .iter()
            .filter_map(|draw| {
                let member = Some((draw, base.shared_rows()));
                ForwardPass::new_from(inputs, prepared, mode, model(), algebra, member).ok()
            })
            .map(|pass| Member {
                pass,
                last: None,
                records: Vec::new(),
                done: false,
                score: 0.0,
            })
            .collect();
        let rows = prepared.telemetry().len();
        Some(Ensemble {
            members,
            references: inputs.references,
            runs,
            seed: config.ensemble_seed,
            stored: Vec::new(),
            stride: rows.div_ceil(MAX_STORED_SPREADS).max(1),
            last_base: None,
            gate_sigmas: config.gate_sigmas,
        })
    }

    /// Widens the base's forward estimate `e` by the members' spread at its row (the
    /// members stepped there), and keeps that spread for the smoothed rows.
    pub fn widen(&mut self, e: &mut StepEstimate, records: &[ResidualRecord]) {
        self.last_base = Some((e.index, e.q));
        let index = e.index;
        for m in &mut self.members {
            if m.at(index) {
                m.score += row_evidence(records, &m.records, self.gate_sigmas);
            }
        }
        let held: Vec<&Member> = self.members.iter().filter(|m| m.holds(index)).collect();
        let scores: Vec<f64> = held.iter().map(|m| m.score).collect();
        let weights = mixture_weights(&scores);
        let present: Vec<(&StepEstimate, f64)> = held
            .iter()
            .zip(&weights[1..])
            .filter_map(|(m, &w)| Some((m.last.as_ref()?, w)))
            .collect();
        let sun = self.references.at(index).ok().map(|r| r.sun_gcrf_unit);
        let Some(spread) = Spread::of(e, &present, sun.as_ref()) else {
            return;
        };
        spread.widen(e);
        if index.is_multiple_of(self.stride) || self.stored.is_empty() {
            self.stored.push((index, spread));
        }
    }

    /// Widens a smoothed estimate by the stored forward spread of the nearest row at or
    /// before it.
    pub fn widen_smoothed(&self, e: &mut StepEstimate) {
        let at = self.stored.partition_point(|(k, _)| *k <= e.index);
        if let Some((_, spread)) = at.checked_sub(1).and_then(|j| self.stored.get(j)) {
            spread.widen(e);
        }
    }

    /// Runs the members to the end of the data and widens `run`'s final calibration and
    /// final covariance by their final spread; records the ensemble in `run.ensemble`.
    pub fn widen_final(mut self, run: &mut CalibrationRun) {
        let completed = self
            .members
            .iter_mut()
            .map(Member::finish)
            .filter(|&c| c)
            .count();
        let scores: Vec<f64> = self.members.iter().map(|m| m.score).collect();
        let weights = mixture_weights(&scores);
        let ended: Vec<(&StepEstimate, f64)> = self
            .members
            .iter()
            .zip(&weights[1..])
            .filter_map(|(m, &w)| Some((m.last.as_ref()?, w)))
            .collect();
        let calibrations: Vec<(&Calibration, f64)> =
            ended.iter().map(|(e, w)| (&e.calibration, *w)).collect();
        run.ensemble = Some(EnsembleReport {
            runs: self.runs,
            started: self.members.len(),
            completed,
            seed: self.seed,
        });
        if calibrations.is_empty() {
            return;
        }
        let base_final = run.calibration.clone();
        Spread::of_calibration(&base_final, &calibrations).widen_calibration(&mut run.calibration);
        // The final attitude: the members that hold one at the base's last row.
        let attitudes: Vec<Vector3<f64>> = match self.last_base {
            Some((index, q)) => {
                let sun = self.references.at(index).ok().map(|r| r.sun_gcrf_unit);
                ended
                    .iter()
                    .filter(|(e, _)| e.index == index)
                    .map(|(e, w)| attitude_deviation(&e.q, &q, sun.as_ref()) * w.sqrt())
                    .collect()
            }
            None => Vec::new(),
        };
        widen_covariance(
            &mut run.final_covariance,
            &run.layout,
            &base_final,
            &calibrations,
            &attitudes,
        );
    }
}

/// Adds to the final covariance `p` the mean outer product of each member's deviation from
/// `base` in the filter's error state (`layout`), each with its mixture weight: bias,
/// scales, each normal in the layout's tangent basis of the base's normal, and the
/// parameters; the attitude from `attitudes` (deviations of the members that hold one,
/// each scaled by the square root of its weight).
fn widen_covariance(
    p: &mut DMatrix<f64>,
    layout: &StateLayout,
    base: &Calibration,
    members: &[(&Calibration, f64)],
    attitudes: &[Vector3<f64>],
) {
    for (m, w) in members {
        let d = deviation(layout, base, m);
        p.ger(*w, &d, &d, 1.0);
    }
    for d in attitudes {
        let block = d * d.transpose();
        let mut view = p.fixed_view_mut::<3, 3>(ATTITUDE, ATTITUDE);
        view += block;
    }
}

/// A member's calibration deviation from `base` as an error-state vector of `layout`
/// (attitude zero).
fn deviation(
    layout: &StateLayout,
    base: &Calibration,
    member: &Calibration,
) -> nalgebra::DVector<f64> {
    let mut d = nalgebra::DVector::zeros(layout.len());
    for k in 0..3 {
        d[BIAS + k] = member.gyro_bias_rad_s[k] - base.gyro_bias_rad_s[k];
    }
    for (i, (b, m)) in base.photodiodes.iter().zip(&member.photodiodes).enumerate() {
        d[layout.scale(i)] = m.scale_v - b.scale_v;
        if let Some(j) = layout.normal(i) {
            let nb = b.n_body();
            let (u, v) = tangent_log_in(&nb, &m.n_body(), &layout.tangent_basis(i, &nb));
            d[j] = u;
            d[j + 1] = v;
        }
    }
    for e in layout.extras() {
        let value = |c: &Calibration| {
            c.parameters
                .iter()
                .find(|p| p.name == e.name)
                .map(|p| p.value)
        };
        if let (Some(b), Some(m)) = (value(base), value(member)) {
            d[e.state] = m - b;
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::Sensor;
    use pdcal_attitude::mekf::apply_error;

    fn quat(axis: [f64; 3], angle_rad: f64) -> Quat {
        let v = Vector3::from(axis).normalize() * angle_rad;
        apply_error(&Quat::IDENTITY, &v)
    }

    const SUN: [f64; 3] = [0.3, -0.5, 0.81];

    #[test]
    fn a_twist_and_a_swing_alone_are_the_rotation_vector() {
        let base = quat([0.2, 0.9, -0.1], 0.7);
        let sun = Vector3::from(SUN).normalize();
        let s_body = base.to_body(&sun);
        let (e1, _) = tangent_basis(&s_body);
        for a in [s_body * 2.5, s_body * -0.3, e1 * 0.4, e1 * -1.2] {
            let member = apply_error(&base, &a);
            let d = attitude_deviation(&member, &base, Some(&sun));
            assert!((d - a).norm() < 1e-9, "{d} against {a}");
            assert!((d - error_vector(&member, &base)).norm() < 1e-9);
        }
    }

    #[test]
    fn the_swing_is_the_angle_between_the_sun_directions_and_the_split_recomposes() {
        let base = quat([0.2, 0.9, -0.1], 0.7);
        let sun = Vector3::from(SUN).normalize();
        for (axis, angle) in [
            ([1.0, 0.3, 0.2], 2.9),
            ([0.0, -1.0, 0.4], 1.1),
            ([0.5, 0.5, 0.5], 0.05),
        ] {
            let member = apply_error(&base, &(Vector3::from(axis).normalize() * angle));
            let d = attitude_deviation(&member, &base, Some(&sun));
            let (s_base, s_member) = (base.to_body(&sun), member.to_body(&sun));
            let across = d - s_base * d.dot(&s_base);
            let between = s_base.dot(&s_member).clamp(-1.0, 1.0).acos();
            assert!((across.norm() - between).abs() < 1e-9);
            // The twist about the base's Sun line, then the swing: the member again.
            let twist = s_base * d.dot(&s_base);
            let rebuilt = apply_error(&apply_error(&base, &twist), &across);
            assert!(
                rebuilt.angle_to(&member) < 1e-9,
                "{}",
                rebuilt.angle_to(&member)
            );
        }
    }

    #[test]
    fn mixture_weights_are_the_posterior_of_equal_priors() {
        let w = mixture_weights(&[0.0, 0.0, 0.0]);
        assert!(w.iter().all(|x| (x - 0.25).abs() < 1e-15));
        // A member 10 times less likely than the base: -2 ln(1/10).
        let w = mixture_weights(&[2.0 * 10f64.ln()]);
        assert!((w[0] - 10.0 / 11.0).abs() < 1e-15 && (w[1] - 1.0 / 11.0).abs() < 1e-15);
        // One overwhelmingly more likely member takes the weight, without overflow.
        let w = mixture_weights(&[0.0, -1e6]);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        assert!(w[2] == 1.0 && w[0] == 0.0, "{w:?}");
    }

    fn record(pd: usize, residual: f64, sigma: f64, accepted: bool) -> ResidualRecord {
        ResidualRecord {
            index: 0,
            t_s: 0.0,
            sensor: Sensor::Photodiode(pd),
            measured: 0.5,
            residual,
            bound_3sigma: 3.0 * sigma,
            accepted,
            post_fit: residual,
            attitude_held: true,
            contradicted: false,
        }
    }

    #[test]
    fn row_evidence_is_the_log_likelihood_ratio_over_the_sensors_both_updated() {
        let base = [record(0, 0.01, 0.01, true), record(1, 0.0, 0.01, true)];
        assert_eq!(row_evidence(&base, &base, 5.0), 0.0);
        // Photodiode 0 at 3 sigma in the member, 1 sigma in the base; photodiode 1 only in
        // the base, so not compared.
        let member = [record(0, 0.03, 0.01, true)];
        assert!((row_evidence(&base, &member, 5.0) - 8.0).abs() < 1e-12);
        // A gated update counts at the gate, whatever its size.
        let gated = [record(0, 10.0, 0.01, false)];
        assert!((row_evidence(&base, &gated, 5.0) - 24.0).abs() < 1e-9);
    }

    #[test]
    fn draws_repeat_with_their_seed_and_move_the_start_by_their_sigma() {
        let a = StartDraw::draws(7, 4, 3);
        assert_eq!(a, StartDraw::draws(7, 4, 3));
        assert_ne!(a, StartDraw::draws(8, 4, 3));
        let mut scale = vec![1.0; 4];
        let normal = Vector3::new(0.0, 0.3, 1.0).normalize();
        let mut normals = vec![normal; 4];
        a[0].apply(&mut scale, &[0.15; 4], &mut normals, 0.1);
        for i in 0..4 {
            let [z1, z2] = a[0].normal_z[i];
            assert!((normals[i].norm() - 1.0).abs() < 1e-15);
            let moved = normals[i].dot(&normal).clamp(-1.0, 1.0).acos();
            assert!((moved - 0.1 * z1.hypot(z2)).abs() < 1e-12);
            assert!((scale[i] - (1.0 + 0.15 * a[0].scale_z[i]).max(0.1)).abs() < 1e-15);
        }
    }
}
