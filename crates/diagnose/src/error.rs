//! Errors of the diagnosis.

use thiserror::Error;

/// Why a diagnosis could not be made.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DiagnoseError {
    /// The calibration filter failed (bad inputs, no usable start).
    #[error("calibration filter: {0}")]
    Filter(#[from] pdcal_filter::FilterError),
    /// The measurement model rejected a component or a scene.
    #[error("measurement model: {0}")]
    Photodiode(#[from] pdcal_photodiode::PhotodiodeError),
    /// The albedo model failed at a telemetry row.
    #[error("albedo at telemetry row {index}: {message}")]
    Albedo {
        /// Telemetry row.
        index: usize,
        /// The albedo error.
        message: String,
    },
    /// Inputs disagree in length.
    #[error("{what}: expected {expected}, found {found}")]
    LengthMismatch {
        /// Which input.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Found length.
        found: usize,
    },
    /// A configuration value is out of range.
    #[error("diagnose config: {field} = {value}: {rule}")]
    Config {
        /// Field name.
        field: &'static str,
        /// Offending value.
        value: f64,
        /// What it must satisfy.
        rule: &'static str,
    },
    /// An unknown base-model name.
    #[error("unknown base model `{0}` (expected cosine or paper)")]
    BaseModel(String),
}
