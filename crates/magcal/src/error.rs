//! What can stop a magnetometer calibration.

use pdcal_ephem::ReferenceError;

/// Failure of [`crate::calibrate`] or of building its samples.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MagCalError {
    /// Fewer usable rows than the parameters to estimate (plus a margin for the noise).
    #[error(
        "magnetometer calibration: {rows} usable rows for {parameters} parameters (need at least {needed})"
    )]
    TooFewRows {
        /// Rows with a full magnetometer sample, a reference and every regressor.
        rows: usize,
        /// Parameters of the model.
        parameters: usize,
        /// Least number of rows accepted.
        needed: usize,
    },
    /// The data do not determine the model: the field directions seen in the sensor frame
    /// do not span enough of the sphere (or regressors are collinear with each other).
    #[error("magnetometer calibration: {0} not determined by the data")]
    NotDetermined(String),
    /// A sample's reference field could not be computed.
    #[error("magnetometer calibration, row {row}: {source}")]
    Reference {
        /// 0-based telemetry row.
        row: usize,
        /// What the reference model said.
        source: ReferenceError,
    },
    /// A sample and the regressor names disagree.
    #[error(
        "magnetometer calibration: row {row} has {found} regressor values, expected {expected}"
    )]
    RegressorCount {
        /// 0-based telemetry row.
        row: usize,
        /// Regressor names given.
        expected: usize,
        /// Values in the sample.
        found: usize,
    },
}
