//! The photodiode calibration filter of the paper (Section III): a multiplicative extended
//! Kalman filter (MEKF) that estimates the attitude, the gyro bias and, per photodiode, the
//! scale factor and the normal direction, from a rate gyro, a magnetometer and the
//! photodiodes; plus the offline RTS smoother and the run over a dataset.
//!
//! This crate owns the filter ([`Filter`]), its tuning ([`FilterConfig`], RON), the run modes
//! ([`Mode`]), the initialisation ([`init`]), the run over a dataset ([`calibrate`]) in its
//! stages (prepared once, [`Prepared`]; the forward pass, [`ForwardPass`]; the smoother,
//! [`smoother`]), the calibration file type ([`Calibration`]) and the run's plain-data outputs
//! ([`CalibrationRun`]). It reads the dataset only through `pdcal-dataset`'s `DatasetMeta`
//! and `Telemetry`, never the truth; reference vectors come in as `pdcal_ephem::Reference`s (one per
//! telemetry row; stored or computed per row, [`References`]) and albedo
//! as `pdcal-albedo`'s model.
//!
//! # State and singularity-free normals
//!
//! Error state (see [`layout`]): `[a, beta, (C_i, d1_i, d2_i) per photodiode, extras]`.
//! Eq. (16)'s azimuth/elevation is singular at elevation +-90 deg, where RAX-2's photodiodes
//! 13-17 sit (the azimuth partial Eq. 23 vanishes there). Instead each normal carries a
//! 2-parameter correction `(d1, d2)` in its own tangent plane, in a basis carried from the
//! photodiode's initial normal ([`StateLayout::tangent_basis`], smooth everywhere except at
//! the antipode of that initial normal, which an estimate never reaches):
//! `n <- rotate_normal_in(n, basis, d1, d2)` after each update, then `d = 0`, exactly like the
//! multiplicative attitude reset. Azimuth, elevation and their sigmas are reported by mapping
//! the 2x2 tangent covariance ([`calibration::az_el_sigmas_in`]); the azimuth sigma is `None`
//! where it is undefined. (A single global basis breaks somewhere: one with its break on
//! the cube corner -(1,1,1)/sqrt(3), where the sso-6u scenario mounts photodiode 9, leaves
//! that sensor up to 14 sigma off.)
//!
//! # Filter
//!
//! - Propagation (Eqs. 8-10): bias-corrected gyro, `q <- dq(w dt) ⊗ q`, the MEKF's 6x6
//!   `Phi`, `Qd` (`pdcal_attitude::mekf`), calibration states a random walk (Eq. 19).
//!   `Phi` is the identity outside the 6x6 block, so only the first 6 rows and columns of
//!   `P` are recomputed.
//! - Updates (Eqs. 4-7): sequential scalar updates, every row of a step linearised at the
//!   prior (rows, predictions and variances built first, then one tight loop in
//!   `sequential`); `P -= w w^T`, `w = P H^T / sqrt(s)`: the standard form
//!   `P - K s K^T = (I - K H) P`, not the Joseph form, which equals it only for the optimal
//!   gain and in exact arithmetic (symmetry is kept by updating one triangle and
//!   mirroring; the dense reference filter, `dense`, uses the Joseph form);
//!   deferred within a step: `P H^T` of a later update is `P_0 H^T - W (W^T H^T)`, and at the
//!   end of the step one rank-k downdate of the lower triangle, mirrored so that `P` stays
//!   exactly symmetric (the kernels in `algebra`: run-time dispatched AVX2/AVX-512 through
//!   `pulp`, so a processor with AVX-512 uses it under the workspace's x86-64-v3 build).
//!   The attitude is not relinearised between the updates of one step
//!   (docs/performance.md measures the difference). The
//!   measurement variance adds the second-order (curvature) term of the measurement
//!   function under the prior covariance (see [`FilterConfig::second_order_noise`]). Photodiode rows (Eq. 15 with
//!   albedo; Eqs. 20-24 through the photodiode crate's partials, albedo partials as
//!   [`FilterConfig::albedo_partials`] says) have 6 non-zeros;
//!   magnetometer rows `[(A b) x]` 3. Innovation gate per scalar.
//! - Photodiodes are used only in full Sun (`sun_fraction >= 0.999`), when sampled, when the
//!   photodiode lit at least once in the data set, and when the predicted incidence angle is
//!   inside the configured field of view (60 deg by default, see [`FilterConfig`]).
//! - [`Algebra::Dense`] is the textbook version of the same filter ([`dense`]).
//!
//! # Conventions
//! - Quaternions scalar last, `v_B = A(q) v_I`; attitude error `q_true = dq(a) ⊗ q_est`,
//!   `a` a rotation vector in the body frame, `d(A s)/da = [(A s) x]`.
//! - GCRF inertial. Radians and SI inside; degrees only in [`Calibration`] and
//!   [`StepEstimate`] (I/O edges) and in [`FilterConfig`] fields named `_deg`.
//!
//! # Symbols
//! | paper | here | unit |
//! |---|---|---|
//! | `a` (Eq. 17) | states 0..3 | rad |
//! | `beta` (Eq. 17) | states 3..6, [`Filter::bias_rad_s`] | rad/s |
//! | `C_i` (Eq. 15) | [`Filter::scales_v`], `scale_V` | V |
//! | `n_i` (Eq. 16) | [`Filter::normals`] | - |
//! | `alpha_i`, `eps_i` (Eq. 16) | `azimuth_deg`, `elevation_deg` of [`PdCalibration`] | deg |
//! | `(d1_i, d2_i)` | tangent correction replacing `alpha_i`, `eps_i` as states | rad |
//! | `E_a / E_AM0` (Eq. 13) | albedo term of the model | - |
//! | `g` (albedo gain) | [`Filter::albedo_gain`]: albedo seen `(1 + g) E_a/E_AM0` | - |
//! | `R` photodiode | `sigma_pd^2 + max(0, (C albedo_sigma / E_AM0)^2 - (sigma_g dh/dg)^2)` | V^2 |
//! | `epsilon` (Eq. 25) | [`ResidualRecord::residual`] | V, nT |
//!
//! # Why hand-written
//! No crate provides an MEKF or RTS smoother with multiplicative attitude. The linear algebra
//! is nalgebra's for the small fixed-size parts, faer's for the smoother's dense `n x n`
//! Cholesky solve and products, and two short `pulp` kernels for the filter's covariance
//! update (why not faer there: see `algebra`).
//!
//! # Cost
//! Per step with `m` photodiodes (`n = 6 + 3 m` states, `k <= m + 3` scalar updates):
//! propagation `~36 n` multiply-adds (only the 6 attitude/bias rows change), each update
//! `6 n` for `P H^T` plus `n l` for the `l` pending downdates, and one rank-k downdate of the
//! lower triangle, `k n^2 / 2`: about `1.6e5` flops for 17 photodiodes. The smoother's step
//! is `O(n^3)` (Cholesky of the predicted covariance, `n` right-hand sides, two products).

mod algebra;
pub mod bias_fit;
pub mod bounded;
pub mod calibration;
pub mod common_rotation;
pub mod config;
pub mod consistency;
pub mod dark;
pub mod dense;
pub mod ensemble;
mod error;
pub mod filter;
pub mod forward;
pub mod gate;
pub mod guard;
pub mod identifiability;
pub mod init;
pub mod layout;
pub mod mounting;
pub mod output;
pub mod prepare;
pub mod propagation;
pub mod quantiles;
pub mod rate;
pub mod references;
pub mod run;
pub mod screen;
pub mod segments;
mod sequential;
pub mod shared_rows;
pub mod smoother;
pub mod sun_line;

pub use bias_fit::{BiasSource, InitialBias};
pub use bounded::{Bounded, LISTED_ROWS};
pub use calibration::{Calibration, ParameterEstimate, PdCalibration};
pub use common_rotation::CommonRotation;
pub use config::{
    BiasAcrossSets, Dynamics, EnsembleRuns, FilterConfig, Mode, ParameterSigma, SensorSigmas,
};
pub use consistency::{Consistency, ConsistencyAccumulator, Dispersion, DispersionReport, Verdict};
pub use error::FilterError;
pub use filter::{
    AlbedoGainNoise, Algebra, Filter, FilterNoise, FilterState, InitialState, Measurements,
    Nominal, Propagation, Sensor, SensorCounts, UpdateCounts, UpdateRecord,
};
pub use forward::ForwardPass;
pub use guard::{CovarianceRepair, RepairKind, RepairLog};
pub use layout::StateLayout;
pub use output::{CalibrationRun, ModeUsed, ResidualRecord, StepEstimate};
/// The per-row reference model [`reference_model`] returns.
pub use pdcal_ephem::ReferenceModel;
pub use prepare::{Prepared, RunInputs};
pub use propagation::{PropagationChoice, PropagationKind, PropagationReason};
pub use references::{References, orbit_source, reference_model, step_references};
pub use run::{
    CANCEL_POLL_ROWS, MAX_DENSE_KEPT, RunSink, SMOOTHER_BLOCK_ROWS, calibrate, calibrate_streaming,
    calibrate_streaming_kept, calibrate_with_model, kept_every, nominal_photodiodes,
    nominal_step_s, paper_model,
};
pub use screen::{Channel, ChannelRejections, Rejections, RowList};
pub use segments::{
    Acquisition, GapRules, SegmentBreak, SegmentConfig, SegmentReport, gyro_step_s, median_spacing,
};
