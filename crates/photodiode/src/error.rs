//! Typed errors of the photodiode crate.

use thiserror::Error;

/// Everything that can go wrong when building or evaluating a photodiode model.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PhotodiodeError {
    /// A vector that must be a direction is zero or not finite.
    #[error("{what} must be a finite non-zero vector, got [{x}, {y}, {z}]")]
    BadDirection {
        /// Which vector (`n_body`, `sun_gcrf`, ...).
        what: &'static str,
        /// x component as given.
        x: f64,
        /// y component as given.
        y: f64,
        /// z component as given.
        z: f64,
    },
    /// A scalar outside its allowed range.
    #[error("{what} = {value} is invalid: {rule}")]
    BadValue {
        /// Which quantity.
        what: String,
        /// The offending value.
        value: f64,
        /// The rule it breaks.
        rule: &'static str,
    },
    /// Photodiode index outside the model's list.
    #[error("photodiode index {index} out of range (model has {count})")]
    PhotodiodeIndex {
        /// Requested zero-based index.
        index: usize,
        /// Number of photodiodes in the model.
        count: usize,
    },
    /// Slices that must have one entry per photodiode differ in length.
    #[error("{what} has {found} entries, expected {expected} (one per photodiode)")]
    LengthMismatch {
        /// Which slice.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        found: usize,
    },
    /// A component with this effect id is already in the model.
    #[error("the model already has a component with id `{id}`")]
    DuplicateComponent {
        /// Effect id.
        id: String,
    },
    /// No component with this effect id is in the model.
    #[error("the model has no component with id `{id}`")]
    UnknownComponent {
        /// Effect id.
        id: String,
    },
    /// A parameter index outside the model's parameter list.
    #[error("parameter index {index} out of range (model has {count})")]
    ParameterIndex {
        /// Requested index.
        index: usize,
        /// Number of model parameters.
        count: usize,
    },
}
