//! Errors of a per-step albedo computation.

use thiserror::Error;

/// Errors from a per-step albedo computation.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum AlbedoError {
    /// An input vector or matrix has a NaN or infinite component.
    #[error("{what} is not finite")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// The Sun position is (nearly) at the Earth centre.
    #[error("Sun position has zero length")]
    ZeroSun,
    /// `gcrf_to_ecef` is not a rotation (|R^T R - I| too large).
    #[error("gcrf_to_ecef is not orthonormal (max |R^T R - I| = {deviation:e})")]
    NotRotation {
        /// Largest deviation of R^T R from identity.
        deviation: f64,
    },
}
