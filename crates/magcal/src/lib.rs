//! Attitude-independent magnetometer calibration with a current-driven bias
//! (docs/magcal.md; Springmann & Cutler, JGCD 35(4), 2012, the paper's reference [19];
//! Alonso & Shuster's TWOSTEP, references [17]-[18]).
//!
//! The model, in the sensor's axes:
//!
//! `m_k = T B_k + b + sum_j c_j u_jk + noise`
//!
//! `B_k` the true field, `T` scale factors, soft iron and non-orthogonality, `b` the hard-iron
//! bias, `u_jk` telemetry channels (panel and battery currents, torquer commands) each driving
//! a bias `c_j`. Only the field's magnitude is compared with the reference (IGRF-14 along the
//! orbit, [`pdcal_ephem::ReferenceModel`]), so a rotation of the sensor is invisible: `T` is
//! estimated in its symmetric form (the polar factor `(T T^T)^(1/2)`), the rotation left for
//! an attitude-aware step.
//!
//! Steps: a closed-form linear start ([`start`]), Levenberg-Marquardt on the magnitude
//! residual with its variance, gating of outlier rows, the covariance from the Fisher
//! information, and backward selection of the regressors by the diagnosis's evidence rule
//! ([`fit`]). No I/O: the driver reads the dataset and writes the results.

pub mod align;
mod error;
pub mod fit;
pub mod model;
pub mod screen;
pub(crate) mod start;

pub use align::{AlignSample, Misalignment};
pub use error::MagCalError;
pub use fit::{MagCalConfig, MagCalibration, RegressorDecision, Sample, calibrate};
pub use model::{MatrixForm, Params, RowFit};
pub use screen::{ScreenedRow, not_physical};

use nalgebra::Vector3;
use pdcal_ephem::ReferenceModel;

/// A [`Sample`] of telemetry row `row` with the reference field's magnitude at `t_s` from
/// `model` (IGRF-14 at the orbit's position).
pub fn sample_along_orbit(
    model: &ReferenceModel,
    row: usize,
    t_s: f64,
    mag_nt: Vector3<f64>,
    u: Vec<f64>,
) -> Result<Sample, MagCalError> {
    let reference = model
        .at(t_s)
        .map_err(|source| MagCalError::Reference { row, source })?;
    Ok(Sample {
        row,
        t_s,
        mag_nt,
        field_nt: reference.b_gcrf_nt.norm(),
        u,
    })
}
