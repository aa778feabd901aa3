//! What a run returns: per-step estimates, per-update residuals, the calibration and counts.
//! Plain data; the driver writes the files (`estimates.csv`, `residuals.csv`,
//! `calibration.ron`, `summary.json`).

use std::f64::consts::PI;

use nalgebra::{DMatrix, Matrix3};
use pdcal_attitude::Quat;

use crate::calibration::Calibration;
use crate::config::SensorSigmas;
use crate::filter::{Sensor, StateView, UpdateCounts};
use crate::guard::RepairLog;
use crate::layout::{ATTITUDE, StateLayout};
use crate::propagation::PropagationChoice;
use crate::screen::Rejections;
use crate::segments::{GapRules, SegmentReport};

/// Estimates after the updates of one sample (one `estimates.csv` row).
#[derive(Debug, Clone, PartialEq)]
pub struct StepEstimate {
    /// Telemetry row index.
    pub index: usize,
    /// Time, s since the dataset epoch.
    pub t_s: f64,
    /// The run's segment holding the row (`CalibrationRun::segments` index).
    pub segment: usize,
    /// Attitude, GCRF -> body, scalar last.
    pub q: Quat,
    /// 1-sigma attitude error about the body x, y, z axes, deg.
    pub attitude_sigma_deg: [f64; 3],
    /// The off-diagonal attitude covariances xy, xz, yz, deg^2: with the sigmas, the whole
    /// attitude covariance, so that its sigma about any direction (the Sun line) can be
    /// read back.
    pub attitude_cov_offdiag_deg2: [f64; 3],
    /// Gyro bias, scales, normals (az/el) and parameters with their sigmas.
    pub calibration: Calibration,
}

impl StepEstimate {
    /// The whole attitude covariance, deg^2 (the sigmas and the off-diagonal terms).
    pub fn attitude_cov_deg2(&self) -> Matrix3<f64> {
        let [sx, sy, sz] = self.attitude_sigma_deg;
        let [xy, xz, yz] = self.attitude_cov_offdiag_deg2;
        Matrix3::new(sx * sx, xy, xz, xy, sy * sy, yz, xz, yz, sz * sz)
    }

    /// Multiplies every sigma (attitude and calibration) by `factor`
    /// ([`crate::consistency::Dispersion`]).
    pub fn scale_sigmas(&mut self, factor: f64) {
        if factor == 1.0 {
            return;
        }
        self.set_attitude_cov_deg2(&(self.attitude_cov_deg2() * (factor * factor)));
        self.calibration.scale_sigmas(factor);
    }

    /// Sets the sigmas and off-diagonal terms from a whole attitude covariance, deg^2.
    pub fn set_attitude_cov_deg2(&mut self, p: &Matrix3<f64>) {
        self.attitude_sigma_deg = [0, 1, 2].map(|k| p[(k, k)].max(0.0).sqrt());
        self.attitude_cov_offdiag_deg2 = [(0, 1), (0, 2), (1, 2)].map(|(i, j)| p[(i, j)]);
    }
}

/// One scalar update (one `residuals.csv` row).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResidualRecord {
    /// Telemetry row index.
    pub index: usize,
    /// Time, s.
    pub t_s: f64,
    /// Sensor.
    pub sensor: Sensor,
    /// Measured value, V or nT.
    pub measured: f64,
    /// Measured minus predicted (Eq. 25), V or nT.
    pub residual: f64,
    /// `3 sqrt(H P H^T + R)`, V or nT.
    pub bound_3sigma: f64,
    /// Applied (true) or rejected by the gate.
    pub accepted: bool,
    /// The residual after the row's whole correction, linearised, V or nT
    /// ([`crate::consistency::Dispersion`]).
    pub post_fit: f64,
    /// Whether the attitude was held at the row (its sigma in the observed directions at
    /// most `segments.held_attitude_sigma_deg`): the rows whose bounds the consistency
    /// verdict judges ([`crate::consistency`]).
    pub attitude_held: bool,
    /// A photodiode sample outside the field of view at the estimate that read more than
    /// any light from there could give ([`crate::Filter::contradicted`]); never applied.
    pub contradicted: bool,
}

/// The mode a run actually used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModeUsed {
    /// Attitude, bias, scales, normals, with magnetometer.
    Full,
    /// Without magnetometer (requested or no `mag_*` columns).
    PhotodiodeOnly,
    /// Scales only, normals fixed at the prior (`with_magnetometer` tells whether the
    /// magnetometer was used).
    ScaleOnly {
        /// Whether magnetometer updates were made.
        with_magnetometer: bool,
    },
}

/// Everything a calibration run produces.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationRun {
    /// Mode used.
    pub mode: ModeUsed,
    /// Telemetry row where the filter starts (rows before it are skipped).
    pub start_index: usize,
    /// The initial estimates (C = max output, nominal normals or the prior, zero bias).
    pub initial: Calibration,
    /// Which photodiodes took part (false: never lit in the data set).
    pub used_photodiodes: Vec<bool>,
    /// Sensor sigmas used (config, hints, defaults).
    pub sensor_sigmas: SensorSigmas,
    /// Forward filter, one entry per row from `start_index`.
    pub forward: Vec<StepEstimate>,
    /// RTS smoother, same rows (when enabled).
    pub smoothed: Option<Vec<StepEstimate>>,
    /// Every scalar update of the forward filter.
    pub residuals: Vec<ResidualRecord>,
    /// Forward filter's final calibration.
    pub calibration: Calibration,
    /// Update counts per sensor class.
    pub counts: UpdateCounts,
    /// State layout (which covariance index is which state).
    pub layout: StateLayout,
    /// Forward filter's final error-state covariance (for NEES; normals in the tangent basis
    /// of the final normals).
    pub final_covariance: DMatrix<f64>,
    /// Samples rejected per sensor: screened against their neighbours before the filter,
    /// or gated by it.
    pub rejections: Rejections,
    /// Repairs of the forward covariance by the guard, with their rows.
    pub covariance_repairs: RepairLog,
    /// The segments of the run: the rows between gaps, silent gyros and lost attitudes,
    /// each with how its attitude was acquired, or why it was skipped.
    pub segments: Vec<SegmentReport>,
    /// The gap threshold, gyro hold and pairing tolerance the run used.
    pub segment_rules: GapRules,
    /// Per photodiode, the time its accepted updates cover, s (each update counts the
    /// length of the step to its row): the sunlit time the calibration used.
    pub photodiode_time_used_s: Vec<f64>,
    /// Per photodiode, the part of that time with the attitude held (its sigma in the
    /// observed directions within `segments.held_attitude_sigma_deg`), s.
    pub photodiode_time_held_s: Vec<f64>,
    /// The time the attitude was held since the gyro bias last started from its prior, s.
    pub bias_time_held_s: f64,
    /// The propagation between samples (the gyro-driven MEKF or the rigid-body dynamics)
    /// and why ([`crate::propagation`]).
    pub propagation: PropagationChoice,
    /// The multi-start ensemble that widened the covariances, when one ran
    /// ([`crate::ensemble`]).
    pub ensemble: Option<crate::ensemble::EnsembleReport>,
    /// The variance factor the reported covariances were scaled by
    /// ([`crate::consistency::Dispersion`]); absent when the configuration turns it off.
    pub dispersion: Option<crate::consistency::DispersionReport>,
    /// Each photodiode's output the final model predicts with no light at all (the Earth's
    /// umbra: its additive terms, a dark offset), V; what [`crate::dark`] tests the umbra
    /// samples against.
    pub umbra_output_v: Vec<f64>,
}

/// The estimate at one row from a state and its covariance (the forward filter's or the
/// smoother's).
pub(crate) fn step_estimate(
    index: usize,
    t_s: f64,
    segment: usize,
    q: Quat,
    view: &StateView<'_>,
    layout: &StateLayout,
    fixed: Option<&Calibration>,
) -> StepEstimate {
    let sig = |k: usize| {
        view.p[(ATTITUDE + k, ATTITUDE + k)]
            .max(0.0)
            .sqrt()
            .to_degrees()
    };
    StepEstimate {
        index,
        t_s,
        segment,
        q,
        attitude_sigma_deg: [sig(0), sig(1), sig(2)],
        attitude_cov_offdiag_deg2: [(0, 1), (0, 2), (1, 2)]
            .map(|(i, j)| view.p[(ATTITUDE + i, ATTITUDE + j)] * (180.0 / PI).powi(2)),
        calibration: view.calibration(layout, fixed),
    }
}
