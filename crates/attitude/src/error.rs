//! Errors of the attitude crate.

use thiserror::Error;

/// Why an attitude could not be determined from vector pairs.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum AttitudeError {
    /// Fewer than two pairs were given.
    #[error("attitude from vector pairs needs at least 2 pairs, got {count}")]
    TooFewPairs {
        /// Number of pairs given.
        count: usize,
    },
    /// A vector or weight of a pair is NaN or infinite.
    #[error("pair {index}: non-finite {what}")]
    NonFinite {
        /// Index of the offending pair.
        index: usize,
        /// Which quantity: "body vector", "reference vector" or "weight".
        what: &'static str,
    },
    /// A vector of a pair has zero length.
    #[error("pair {index}: zero-length {what}")]
    ZeroVector {
        /// Index of the offending pair.
        index: usize,
        /// Which vector: "body vector" or "reference vector".
        what: &'static str,
    },
    /// A weight is not strictly positive.
    #[error("pair {index}: weight {weight} is not positive")]
    NonPositiveWeight {
        /// Index of the offending pair.
        index: usize,
        /// The weight given.
        weight: f64,
    },
    /// All vectors of one frame are parallel (or anti-parallel): the rotation about
    /// their common direction is unobservable.
    #[error(
        "all {frame} vectors are parallel (largest sine of the angle between two is {max_sin:e})"
    )]
    Parallel {
        /// "body" or "reference".
        frame: &'static str,
        /// Largest `|u_0 x u_j|` over the pairs, compared with the tolerance.
        max_sin: f64,
    },
    /// The largest eigenvalue of Davenport's K matrix is not separated from the next,
    /// so the optimal quaternion is not unique.
    #[error("q-method: largest eigenvalue of K not unique (gap {gap:e} of total weight)")]
    Degenerate {
        /// Gap between the two largest eigenvalues divided by the sum of weights.
        gap: f64,
    },
}
