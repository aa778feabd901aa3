//! Errors of the filter crate.

use thiserror::Error;

/// Why a filter could not be built or run.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FilterError {
    /// A configuration field is out of range.
    #[error("filter config: {field} = {}: {rule}", pdcal_text::number(*.value))]
    Config {
        /// Field name as in the RON file.
        field: &'static str,
        /// Offending value.
        value: f64,
        /// What the field must satisfy.
        rule: &'static str,
    },
    /// A configuration field is out of range by a rule of its own words (a count, a name,
    /// a sensor noise checked by `pdcal_dataset::rules`); its value as a message shows it.
    #[error("filter config: {field} = {value}: {rule}")]
    ConfigValue {
        /// Field path as in the RON file (`parameter_sigmas[2].name_or_unit`).
        field: String,
        /// Offending value, as a message shows it.
        value: String,
        /// What the field must satisfy.
        rule: String,
    },
    /// A calibration's value breaks the rule every file's value of its kind obeys
    /// (`pdcal_dataset::rules`).
    #[error("calibration: {field} = {value}: {rule}")]
    Invalid {
        /// Field path as in the RON file (`photodiodes[2].scale_V`).
        field: String,
        /// Offending value, as a message shows it.
        value: String,
        /// What the field must satisfy.
        rule: String,
    },
    /// The run needs what the dataset does not give (the message says what and where it
    /// goes: the inertia in dataset.ron, gyro columns in telemetry.csv).
    #[error("{0}")]
    Missing(String),
    /// The RON text of a config or calibration could not be parsed or written.
    #[error("{what}: {message}")]
    Ron {
        /// `filter config` or `calibration`.
        what: &'static str,
        /// Parser message (with line and column).
        message: String,
    },
    /// Inputs disagree in length (photodiodes, references, samples).
    #[error("{what}: expected {expected}, found {found}")]
    LengthMismatch {
        /// Which input.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Length found.
        found: usize,
    },
    /// No sample satisfies the initialisation conditions.
    #[error("no usable sample to initialise the attitude ({reason})")]
    NoInitialSample {
        /// What was missing (full sun, magnetometer, observable Sun vector, geometry).
        reason: String,
    },
    /// No photodiode ever produced a lit output.
    #[error(
        "no photodiode output exceeds {threshold_v:.4} V: nothing to calibrate (every \
         photodiode sample lies below it, or there is none at all)"
    )]
    NoLitPhotodiode {
        /// Threshold used, V.
        threshold_v: f64,
    },
    /// A reference quantity or a measurement is not finite.
    #[error("sample {index} (t_s = {}): non-finite {what}", pdcal_text::number(*.t_s))]
    NonFinite {
        /// Sample index.
        index: usize,
        /// Sample time, s.
        t_s: f64,
        /// Which quantity.
        what: &'static str,
    },
    /// The covariance lost positive definiteness and could not be repaired (forward
    /// filter), or the smoother's inversion failed.
    #[error("covariance not positive definite at row {index}")]
    NotPositiveDefinite {
        /// Sample index.
        index: usize,
    },
    /// The filter's state became non-finite (a divergence the covariance guard cannot
    /// repair).
    #[error(
        "filter state not finite after row {index} (t_s = {})",
        pdcal_text::number(*.t_s)
    )]
    StateNotFinite {
        /// Telemetry row.
        index: usize,
        /// Its time, s.
        t_s: f64,
    },
    /// An error from the photodiode model.
    #[error(transparent)]
    Photodiode(#[from] pdcal_photodiode::PhotodiodeError),
    /// The dataset's orbit description could not be turned into an orbit source.
    #[error("{what}: {source}")]
    Orbit {
        /// Where the orbit came from (`dataset.ron orbit`, `telemetry.csv position columns`).
        what: &'static str,
        /// The ephemeris crate's error.
        source: pdcal_ephem::OrbitError,
    },
    /// `orbit: PositionColumns` without the position columns.
    #[error("telemetry.csv: orbit PositionColumns needs r_x_km, r_y_km, r_z_km")]
    MissingPositionColumns,
    /// A row's reference vectors could not be computed.
    #[error("reference{}: {source}", index.map(|i| format!(" at row {i} (t_s = {})", pdcal_text::number(*t_s))).unwrap_or_default())]
    Reference {
        /// Telemetry row (`None`: building the reference model).
        index: Option<usize>,
        /// Its time, s.
        t_s: f64,
        /// The ephemeris crate's error.
        source: pdcal_ephem::ReferenceError,
    },
    /// The run's sink asked to stop ([`crate::RunSink::cancelled`]): a user interrupt, not
    /// a fault of the data.
    #[error("calibration cancelled at row {index}")]
    Cancelled {
        /// The row the forward pass or the smoother had reached.
        index: usize,
    },
    /// An error from the albedo model.
    #[error("albedo at sample {index}: {message}")]
    Albedo {
        /// Sample index.
        index: usize,
        /// The albedo crate's message.
        message: String,
    },
}

/// [`FilterError::LengthMismatch`] unless `found == expected`.
pub(crate) fn check_len(
    what: &'static str,
    expected: usize,
    found: usize,
) -> Result<(), FilterError> {
    if expected == found {
        Ok(())
    } else {
        Err(FilterError::LengthMismatch {
            what,
            expected,
            found,
        })
    }
}

impl FilterError {
    /// A RON text of `what` that does not parse: ron's span, then its message with any
    /// token it quotes cut like every quoted value (ron repeats whole identifiers and
    /// strings of the input).
    pub(crate) fn ron_parse(what: &'static str, e: &ron::error::SpannedError) -> Self {
        FilterError::Ron {
            what,
            message: format!(
                "{}: {}",
                e.span,
                pdcal_text::parser_message(&e.code.to_string())
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_are_echoed_cut() {
        for e in [
            FilterError::StateNotFinite {
                index: 3,
                t_s: 1e300,
            },
            FilterError::NonFinite {
                index: 3,
                t_s: 1e300,
                what: "gyro",
            },
        ] {
            let shown = e.to_string();
            assert!(shown.contains("... (301 bytes)"), "{shown}");
            assert!(shown.len() < 160, "{} bytes: {shown}", shown.len());
        }
    }
}
