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
    /// The field's size is not in nT: the median of `|m| / |H|` is beyond what any
    /// magnetometer's scale and bias give (checked before the fit).
    #[error(
        "magnetometer calibration: the measured field is {ratio:.3e} times IGRF-14's along the orbit (median |H| {field_nt:.0} nT){}; the mag_*_nT columns must hold nT (uT reads 1000 times too small, G 100 000 times): convert them (docs/dataset-format.md) and run again",
        likely_unit.map(|u| format!(", as if the columns held {u}")).unwrap_or_default()
    )]
    FieldSize {
        /// Median of `|m| / |H|` over the rows.
        ratio: f64,
        /// Median reference magnitude, nT.
        field_nt: f64,
        /// The unit whose values read `ratio` times nT's, if one does.
        likely_unit: Option<&'static str>,
    },
    /// The fit's result is no magnetometer's (scale or bias out of any sensor's range).
    #[error(
        "magnetometer calibration: the fit is not a calibration: {0}; the data (spikes, a unit, the time tags or the orbit) are not described by the model"
    )]
    NotPhysical(String),
}
