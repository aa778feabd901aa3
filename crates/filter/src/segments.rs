//! Telemetry as it arrives from orbit: passes with gaps between them, sensors sampled at
//! their own rates. The run is split into **segments** wherever no row arrives for longer
//! than the gap threshold or the gyro falls silent for longer than it can be held; the
//! calibration states carry over a gap (their covariance grown by their random walk), the
//! attitude is re-acquired from the Sun and the field at the first usable rows of the next
//! segment, and an attitude that is lost (its sigma beyond a bound, or its innovations
//! persistently gated) ends its segment and is re-acquired.
//!
//! The rules are derived from the data (multiples of the median spacings) so that the same
//! defaults hold on 1 Hz simulations, 10 Hz gyros and flight frames 40 s apart; the config
//! ([`SegmentConfig`]) can set each one.

use std::collections::VecDeque;

use nalgebra::{Matrix3, Vector3};
use pdcal_dataset::Telemetry;
use serde::{Deserialize, Serialize};

use crate::FilterError;
use crate::config::{MAX_WINDOW_S, WINDOW_RULE};

/// A gap is this many median spacings without a row (and the gyro may be held this many of
/// its own spacings): irregular rows and a dropped sample or two are not gaps.
pub const GAP_SPACINGS: f64 = 10.0;

/// Floor of the derived gap threshold and gyro hold, s: at 10 Hz, ten spacings are 1 s,
/// less than a ground segment's usual jitter in time tags.
pub const GAP_FLOOR_S: f64 = 5.0;

/// Most updates in the lost-attitude test's window: two thousand rows of a few lit
/// photodiodes and the magnetometer, longer than any attitude stays lost unnoticed.
pub const MAX_LOST_WINDOW_UPDATES: usize = 10_000;

/// How the run splits the telemetry into segments and when it calls the attitude lost
/// (`segments` in the filter config RON; every field defaulted).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SegmentConfig {
    /// A new segment starts after this long without a row, s; `None`: [`GAP_SPACINGS`]
    /// median row spacings, at least [`GAP_FLOOR_S`].
    pub gap_threshold_s: Option<f64>,
    /// The last gyro sample is held (a blank gyro cell) for at most this long, s; beyond
    /// it the attitude cannot be propagated and a new segment starts. `None`:
    /// [`GAP_SPACINGS`] median spacings of the gyro's own samples, at least
    /// [`GAP_FLOOR_S`].
    pub gyro_hold_s: Option<f64>,
    /// Acquiring the attitude, a magnetometer sample up to this far in time from the
    /// photodiode row is used, brought to that row's time with the gyro, s. Default 10
    /// (flight frames often sample the magnetometer and the photodiodes seconds apart).
    pub pairing_tolerance_s: f64,
    /// The attitude is lost when its 1-sigma error exceeds this, deg (without the
    /// magnetometer, only the axes across the Sun line count: the rotation about it is
    /// unobserved by design). Default 20: twice the initial Sun-vector sigma.
    pub lost_attitude_sigma_deg: f64,
    /// The attitude is *held* at a row when its 1-sigma error in the observed directions
    /// (as for the lost test) is at most this, deg. The consistency verdict judges the
    /// residuals' bounds on held rows only (`crate::consistency`): a bound inflated by a
    /// loose attitude says nothing about the model. Default 5.
    pub held_attitude_sigma_deg: f64,
    /// The innovation test looks at this many of the latest scalar updates. Default 50
    /// (about ten rows with a few photodiodes lit and the magnetometer).
    pub lost_window_updates: usize,
    /// The attitude is lost when at least this fraction of a full window of updates was
    /// rejected by the innovation gate. Default 0.5: a consistent filter gates about one
    /// update in a million, and one dead or shadowed photodiode among several lit ones
    /// stays far below half.
    pub lost_gated_fraction: f64,
}

impl Default for SegmentConfig {
    fn default() -> Self {
        SegmentConfig {
            gap_threshold_s: None,
            gyro_hold_s: None,
            pairing_tolerance_s: 10.0,
            lost_attitude_sigma_deg: 20.0,
            held_attitude_sigma_deg: 5.0,
            lost_window_updates: 50,
            lost_gated_fraction: 0.5,
        }
    }
}

impl SegmentConfig {
    /// Checks every field's range.
    pub fn validate(&self) -> Result<(), FilterError> {
        let bad = |field, value, rule| FilterError::Config { field, value, rule };
        for (field, value) in [
            ("segments.gap_threshold_s", self.gap_threshold_s),
            ("segments.gyro_hold_s", self.gyro_hold_s),
        ] {
            if let Some(v) = value
                && !(v > 0.0 && v.is_finite())
            {
                return Err(bad(field, v, "must be positive and finite"));
            }
        }
        for (field, value) in [
            ("segments.pairing_tolerance_s", self.pairing_tolerance_s),
            (
                "segments.lost_attitude_sigma_deg",
                self.lost_attitude_sigma_deg,
            ),
            (
                "segments.held_attitude_sigma_deg",
                self.held_attitude_sigma_deg,
            ),
        ] {
            if !(value >= 0.0 && value.is_finite()) {
                return Err(bad(field, value, "must be non-negative and finite"));
            }
        }
        for (field, value) in [
            ("segments.gap_threshold_s", self.gap_threshold_s),
            ("segments.gyro_hold_s", self.gyro_hold_s),
            (
                "segments.pairing_tolerance_s",
                Some(self.pairing_tolerance_s),
            ),
        ] {
            if let Some(v) = value
                && v > MAX_WINDOW_S
            {
                return Err(bad(field, v, WINDOW_RULE));
            }
        }
        let updates = self.lost_window_updates;
        if !(1..=MAX_LOST_WINDOW_UPDATES).contains(&updates) {
            return Err(FilterError::ConfigValue {
                field: "segments.lost_window_updates".into(),
                value: updates.to_string(),
                rule: format!("must be at least 1 and at most {MAX_LOST_WINDOW_UPDATES}"),
            });
        }
        if !(self.lost_gated_fraction > 0.0 && self.lost_gated_fraction <= 1.0) {
            return Err(bad(
                "segments.lost_gated_fraction",
                self.lost_gated_fraction,
                "must be in (0, 1]",
            ));
        }
        Ok(())
    }
}

/// The segment rules of one data set, with the derived values resolved.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GapRules {
    /// A new segment starts after this long without a row, s.
    pub gap_threshold_s: f64,
    /// The longest the last gyro sample is held, s.
    pub gyro_hold_s: f64,
    /// Median spacing of the gyro's own samples, s (its white-noise density's period).
    pub gyro_step_s: f64,
    /// Magnetometer-to-photodiode pairing tolerance, s.
    pub pairing_tolerance_s: f64,
}

impl GapRules {
    /// The rules for `telemetry`: the config's values, else derived from the spacings.
    /// The thresholds scale the upper quartile of the spacings, not the median: flight
    /// frames that sample the magnetometer 2 s after the photodiodes, 42 s apart, have a
    /// median spacing of 2 s, but 40 s between frames is their rhythm, not a gap.
    pub fn new(config: &SegmentConfig, telemetry: &Telemetry) -> Self {
        let row_rhythm_s = spacing_quantile(telemetry.t_s.iter().copied(), 0.75).unwrap_or(1.0);
        let gyro_rhythm_s = spacing_quantile(gyro_times(telemetry), 0.75).unwrap_or(row_rhythm_s);
        let gyro_step_s = gyro_step_s(telemetry);
        let derived = |step: f64| (GAP_SPACINGS * step).max(GAP_FLOOR_S);
        GapRules {
            gap_threshold_s: config
                .gap_threshold_s
                .unwrap_or_else(|| derived(row_rhythm_s)),
            gyro_hold_s: config.gyro_hold_s.unwrap_or_else(|| derived(gyro_rhythm_s)),
            gyro_step_s,
            pairing_tolerance_s: config.pairing_tolerance_s,
        }
    }

    /// Whether the step from a row at `t_prev_s` to one at `t_s`, with the last gyro
    /// sample at `t_gyro_s`, crosses a break: no row for longer than the gap threshold, or
    /// a gyro held longer than it may be.
    pub fn breaks(&self, t_prev_s: f64, t_s: f64, t_gyro_s: f64) -> Option<SegmentBreak> {
        if t_s - t_prev_s > self.gap_threshold_s {
            Some(SegmentBreak::Gap)
        } else if t_s - t_gyro_s > self.gyro_hold_s {
            Some(SegmentBreak::GyroSilent)
        } else {
            None
        }
    }
}

/// Median spacing of consecutive times, `None` with fewer than two.
pub fn median_spacing(times: impl Iterator<Item = f64>) -> Option<f64> {
    spacing_quantile(times, 0.5)
}

/// The `q` quantile (0..1, lower value at a tie) of the spacings of consecutive times,
/// `None` with fewer than two.
pub fn spacing_quantile(times: impl Iterator<Item = f64>, q: f64) -> Option<f64> {
    let mut times = times.peekable();
    let mut dts: Vec<f64> = Vec::new();
    while let (Some(t0), Some(&t1)) = (times.next(), times.peek()) {
        dts.push(t1 - t0);
    }
    if dts.is_empty() {
        return None;
    }
    dts.sort_by(f64::total_cmp);
    let at = ((dts.len() as f64 * q) as usize).min(dts.len() - 1);
    Some(dts[at])
}

/// Times of the rows with a gyro sample.
fn gyro_times(telemetry: &Telemetry) -> impl Iterator<Item = f64> + '_ {
    telemetry
        .t_s
        .iter()
        .zip(&telemetry.gyro_rad_s)
        .filter(|(_, g)| g.is_some())
        .map(|(t, _)| *t)
}

/// Median spacing of the gyro's own samples (rows with a gyro sample), s; the row spacing
/// when fewer than two rows have one, 1 s with fewer than two rows.
pub fn gyro_step_s(telemetry: &Telemetry) -> f64 {
    median_spacing(gyro_times(telemetry))
        .or_else(|| median_spacing(telemetry.t_s.iter().copied()))
        .unwrap_or(1.0)
}

/// Why a segment ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SegmentBreak {
    /// No row arrived for longer than the gap threshold.
    Gap,
    /// The gyro was silent for longer than it may be held.
    GyroSilent,
    /// The attitude was lost.
    Lost,
    /// The telemetry ended.
    End,
}

/// How a segment's attitude was acquired.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Acquisition {
    /// q-method from the photodiode Sun vector and the magnetometer.
    SunAndField,
    /// From the Sun vector alone (no magnetometer): the rotation about the Sun line is
    /// unobserved at first.
    SunOnly,
    /// Not acquired: the segment was skipped (`skipped` says why).
    None,
}

/// One segment of a run (`summary.json` `segments`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SegmentReport {
    /// First telemetry row of the segment.
    pub first_row: usize,
    /// Last telemetry row of the segment.
    pub last_row: usize,
    /// Time of the first row, s since the epoch.
    pub start_t_s: f64,
    /// Time of the last row, s since the epoch.
    pub end_t_s: f64,
    /// Rows in the segment.
    pub rows: usize,
    /// Rows the filter processed (from the acquisition on).
    pub rows_used: usize,
    /// The row the attitude was acquired at.
    pub acquired_row: Option<usize>,
    /// How the attitude was acquired.
    pub acquisition: Acquisition,
    /// The magnetometer row paired with the acquisition's photodiode row, when another.
    pub paired_field_row: Option<usize>,
    /// Why the segment ended.
    pub ended_by: SegmentBreak,
    /// Why nothing of the segment was used (no acquisition), when so.
    pub skipped: Option<String>,
    /// Why the attitude was declared lost, when it was.
    pub lost: Option<String>,
    /// The gyro bias at the acquisition and where it came from (the fit of
    /// [`crate::bias_fit`] or the prior); `None` for a skipped segment.
    pub initial_bias: Option<crate::bias_fit::InitialBias>,
    /// Sun-only acquisitions with albedo: whether the probe kept the acquired attitude or
    /// its half turn about the Sun line, and how clearly ([`crate::sun_line`]).
    pub about_sun_line: Option<crate::sun_line::AboutSunLine>,
}

impl SegmentReport {
    /// A segment from `first_row` at `start_t_s`, still open.
    pub(crate) fn open(first_row: usize, start_t_s: f64) -> Self {
        SegmentReport {
            first_row,
            last_row: first_row,
            start_t_s,
            end_t_s: start_t_s,
            rows: 0,
            rows_used: 0,
            acquired_row: None,
            acquisition: Acquisition::None,
            paired_field_row: None,
            ended_by: SegmentBreak::End,
            skipped: None,
            lost: None,
            about_sun_line: None,
            initial_bias: None,
        }
    }

    /// Closes the segment after `last_row` at `end_t_s`.
    pub(crate) fn close(&mut self, last_row: usize, end_t_s: f64, ended_by: SegmentBreak) {
        self.last_row = last_row.max(self.first_row);
        self.end_t_s = end_t_s;
        self.rows = self.last_row + 1 - self.first_row;
        self.ended_by = ended_by;
    }
}

/// The innovation half of the lost-attitude test: the fraction of the latest scalar
/// updates the gate rejected.
#[derive(Debug, Clone)]
pub(crate) struct InnovationWindow {
    latest: VecDeque<bool>,
    gated: usize,
    capacity: usize,
    lost_fraction: f64,
}

impl InnovationWindow {
    pub(crate) fn new(config: &SegmentConfig) -> Self {
        InnovationWindow {
            latest: VecDeque::with_capacity(config.lost_window_updates),
            gated: 0,
            capacity: config.lost_window_updates,
            lost_fraction: config.lost_gated_fraction,
        }
    }

    /// Adds one update (accepted or gated).
    pub(crate) fn push(&mut self, accepted: bool) {
        if self.latest.len() == self.capacity
            && let Some(old) = self.latest.pop_front()
        {
            self.gated -= usize::from(!old);
        }
        self.latest.push_back(accepted);
        self.gated += usize::from(!accepted);
    }

    /// The gated fraction of a full window when it reaches the lost fraction.
    pub(crate) fn lost(&self) -> Option<f64> {
        let fraction = self.gated as f64 / self.capacity as f64;
        (self.latest.len() == self.capacity && fraction >= self.lost_fraction).then_some(fraction)
    }

    /// Forgets every update (a new segment).
    pub(crate) fn clear(&mut self) {
        self.latest.clear();
        self.gated = 0;
    }
}

/// The largest 1-sigma attitude error, rad, of the attitude covariance `p_aa`; with
/// `sun_body`, only across the Sun line (the Sun-only attitude leaves the rotation about it
/// unobserved, so its sigma says nothing about being lost).
pub(crate) fn attitude_sigma_rad(p_aa: &Matrix3<f64>, sun_body: Option<&Vector3<f64>>) -> f64 {
    let p = match sun_body.and_then(|s| s.try_normalize(1e-12)) {
        Some(s) => {
            let across = Matrix3::identity() - s * s.transpose();
            across * p_aa * across
        }
        None => *p_aa,
    };
    let sym = 0.5 * (p + p.transpose());
    sym.symmetric_eigenvalues().max().max(0.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn telemetry(t_s: Vec<f64>, gyro_every: usize) -> Telemetry {
        let gyro = (0..t_s.len())
            .map(|k| k.is_multiple_of(gyro_every).then(Vector3::zeros))
            .collect();
        Telemetry {
            gyro_rad_s: gyro,
            mag_nt: None,
            pd_v: vec![],
            r_gcrf_km: None,
            temperature_c: vec![],
            current_a: vec![],
            t_s,
        }
    }

    #[test]
    fn derived_rules_follow_each_sensors_spacing() {
        // Rows at 10 Hz, the gyro on every tenth row (1 Hz).
        let tel = telemetry((0..200).map(|k| k as f64 * 0.1).collect(), 10);
        let rules = GapRules::new(&SegmentConfig::default(), &tel);
        assert!((rules.gyro_step_s - 1.0).abs() < 1e-9);
        assert!((rules.gyro_hold_s - 10.0).abs() < 1e-9);
        assert!((rules.gap_threshold_s - GAP_FLOOR_S).abs() < 1e-9);
        // Flight frames 42 s apart: ten spacings.
        let tel = telemetry((0..20).map(|k| k as f64 * 42.0).collect(), 1);
        let rules = GapRules::new(&SegmentConfig::default(), &tel);
        assert!((rules.gap_threshold_s - 420.0).abs() < 1e-9);
        // Frames of two rows 2 s apart (photodiodes, then the magnetometer), 42 s apart:
        // the frames' rhythm, not the 2 s inside them, sets the threshold.
        let t = (0..40)
            .map(|k| (k / 2) as f64 * 42.0 + (k % 2) as f64 * 2.0)
            .collect();
        let rules = GapRules::new(&SegmentConfig::default(), &telemetry(t, 1));
        assert!((rules.gap_threshold_s - 400.0).abs() < 1e-9);
        assert!((rules.gyro_hold_s - 400.0).abs() < 1e-9);
    }

    #[test]
    fn irregular_rows_are_not_gaps_but_long_silences_are() {
        let rules = GapRules {
            gap_threshold_s: 10.0,
            gyro_hold_s: 10.0,
            gyro_step_s: 1.0,
            pairing_tolerance_s: 10.0,
        };
        assert_eq!(rules.breaks(0.0, 3.0, 0.0), None);
        assert_eq!(rules.breaks(0.0, 10.5, 0.0), Some(SegmentBreak::Gap));
        assert_eq!(
            rules.breaks(20.0, 21.0, 9.0),
            Some(SegmentBreak::GyroSilent)
        );
    }

    #[test]
    fn window_reports_loss_only_when_full_and_mostly_gated() {
        let config = SegmentConfig {
            lost_window_updates: 4,
            ..SegmentConfig::default()
        };
        let mut w = InnovationWindow::new(&config);
        for accepted in [false, false, false] {
            w.push(accepted);
        }
        assert_eq!(w.lost(), None, "not full yet");
        w.push(true);
        assert_eq!(w.lost(), Some(0.75));
        for _ in 0..3 {
            w.push(true);
        }
        assert_eq!(w.lost(), None, "old gated updates leave the window");
        w.clear();
        assert_eq!(w.lost(), None);
    }

    #[test]
    fn sigma_across_the_sun_ignores_the_sun_axis() {
        let p = Matrix3::from_diagonal(&Vector3::new(1e-4, 1e-4, 1.0));
        let s = Vector3::z();
        assert!((attitude_sigma_rad(&p, Some(&s)) - 1e-2).abs() < 1e-12);
        assert!((attitude_sigma_rad(&p, None) - 1.0).abs() < 1e-12);
    }
}
