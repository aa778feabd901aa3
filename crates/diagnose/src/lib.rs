//! Discrepancy discovery: find where the measurements and the calibration model disagree,
//! name the missing effect, add it, and show the gap shrink (`pdcal diagnose`).
//!
//! This crate owns the diagnosis workflow of `docs/diagnose.md`:
//! 1. calibrate with the current model ([`BaseModel`] `cosine`, paper Eq. 11, or `paper`,
//!    Eq. 15) through `pdcal_filter::calibrate_with_model`;
//! 2. compute residuals over *every* sample ([`residuals`]): every photodiode sample from the
//!    filter's start (the filter itself uses only full-Sun samples inside 60 deg incidence),
//!    the magnetometer in the body frame, and the attitude step rotation the measurements
//!    forced beyond the gyro, from the smoothed attitude and the final calibration, with the
//!    regressors of every candidate;
//! 3. fit each candidate effect not yet in the model on those residuals ([`candidates`]) and
//!    score it: HAC Wald statistic (twice the log-likelihood gain, with a Newey-West
//!    covariance over telemetry rows, [`stats`]) over 2, minus the BIC penalty
//!    `k ln(N)/2`; the best is named only if its score exceeds a threshold set on control
//!    seeds ([`DEFAULT_THRESHOLD`]); `time-offset`, which the calibration absorbs before
//!    the residuals are formed, is scored instead by a refit ([`refit`]): the forward
//!    filter's innovation log-likelihood with the offset as a state against without;
//! 4. add it ([`ModelSpec`]): a photodiode term of `pdcal-photodiode` (fitted constants as
//!    `Fixed` parameters, or `Estimated` filter states for `time-offset` and `scale-drift`),
//!    or a correction of the telemetry (`mag-bias`, `gyro-scale`: the filter has no such
//!    states); calibrate again and measure the [`Gap`] before and after;
//! 5. repeat until nothing is significant or [`DiagnoseConfig::max_rounds`].
//!
//! It reads the dataset's metadata and telemetry only; truth, when given, is used for the
//! report's calibration errors and never for a decision. No file I/O: the `pdcal` driver
//! writes `diagnosis.json`, `report.md` and the figures.
//!
//! # Conventions
//! Quaternions scalar last, `v_B = A(q) v_I`; GCRF inertial; residual = measured minus
//! predicted (Eq. 25). Radians inside; degrees only in evidence text and figure axes.
//!
//! # Symbols
//! | paper / here | field | unit |
//! |---|---|---|
//! | `epsilon` (Eq. 25), photodiode | [`residuals::PdSample::residual_v`] | V |
//! | `C E_a/E_AM0` (Eq. 15) | [`residuals::PdSample::albedo_v`] | V |
//! | `(1 AU/r_sun)^2 C n^T A s` (Eq. 15, `C` at 1 AU) | [`residuals::PdSample::direct_v`] | V |
//! | `nu` (illuminated fraction) | [`residuals::PdSample::sun_fraction`] | - |
//! | `(1 AU/r_sun)^2 C n^T (w x s)` | [`residuals::PdSample::time_offset_v_s`] | V/s |
//! | magnetometer residual | [`residuals::MagSample::residual_nt`] | nT |
//! | attitude step beyond gyro | [`residuals::GyroSample::residual_rad`] | rad |
//!
//! # Why hand-written
//! The HAC (Newey-West) covariance and the Wald statistic are a few lines on nalgebra; the
//! statistics crates on crates.io offer OLS with HAC for dense designs, not the sparse,
//! per-row summed scores used here.

pub mod candidates;
pub mod consistency;
mod diagnose;
mod error;
pub mod fit;
mod forms;
pub mod model;
pub mod refit;
pub mod residuals;
mod run;
pub mod significance;
pub mod stats;

pub use candidates::{Signature, candidate_ids, score_candidates, score_one, signature};
pub use consistency::{Misfit, misfit};
pub use diagnose::{
    Action, DIAGNOSIS_FORMAT_VERSION, Diagnosis, DiagnosisSummary, Dropped, FinalCheck, Gap,
    Reformed, Rejected, Round, RoundSummary, Shrink, UNEXPLAINED, diagnose, diagnose_from, gap,
    shrink,
};
pub use error::DiagnoseError;
pub use fit::CandidateFit;
pub use model::{BaseModel, ModelSpec, changes_filter};
pub use refit::innovation_log_likelihood_gain;
pub use residuals::{Residuals, residuals};
pub use run::{
    DEFAULT_MAX_LAG, DEFAULT_MIN_SHRINK, DEFAULT_THRESHOLD, DiagnoseConfig, DiagnoseInputs,
    calibrate_and_residuals,
};
pub use significance::{MIN_PARAMETER_SIGMAS, Significance, chi_square_sigmas};
