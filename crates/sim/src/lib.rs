//! Truth simulator of a tumbling spacecraft with photodiodes, a rate gyro and a
//! magnetometer: the data sets pdcal calibrates, with the truth to judge it by.
//!
//! This crate owns:
//! - rigid-body attitude dynamics ([`dynamics`]): Euler's equations with a full inertia
//!   tensor, quaternion kinematics, gravity-gradient and magnetic-dipole torques, RK4 with
//!   substeps and its measured accuracy;
//! - the scenario configuration ([`Scenario`], RON, `deny_unknown_fields`, [`Scenario::validate`])
//!   and the built-in scenarios `rax2-like` (the default, `docs/rax2-scenario.md`) and
//!   `sso-6u`, embedded from `fixtures/scenarios/`;
//! - the run ([`simulate`]): orbit, Sun, field and eclipse from `pdcal-ephem`, albedo from
//!   `pdcal-albedo`, photodiode outputs from `pdcal-photodiode`'s [`pdcal_photodiode::MeasurementModel`]
//!   terms (the same terms the filter uses), seeded sensor noise, and the effect library of
//!   `cli-contract.md`; the output is the `pdcal-dataset` types ([`SimOutput::to_dataset`]).
//!
//! It does no file I/O: the `pdcal` binary writes the data set with `pdcal-dataset`.
//!
//! # Conventions
//! Quaternions scalar last, `v_B = A(q) v_I`, `A(q) = (q_w^2 - |q_v|^2) I + 2 q_v q_v^T -
//! 2 q_w [q_v x]` (Markley & Crassidis); GCRF is the inertial frame. Kinematics
//! `q_dot = Xi(q) w / 2` (Markley & Crassidis Eq. 3.21). Times are seconds since the
//! scenario epoch, held internally in whole microseconds.
//!
//! # Symbols
//! | symbol | field | unit |
//! |---|---|---|
//! | `J` | [`scenario::Spacecraft::inertia_kg_m2`] | kg m^2 |
//! | `w` | [`dynamics::AttitudeState::w_body_rad_s`] | rad/s |
//! | `m` (residual dipole) | [`scenario::Spacecraft::dipole_a_m2`] | A m^2 |
//! | `C_i` (paper Eq. 15) | `TruePd::scale_v` | V |
//! | `alpha_i`, `epsilon_i` (Eq. 16) | `TruePd::azimuth_deg`, `elevation_deg` | deg |
//! | `nu` (eclipse) | `TruthSeries::eclipse` | - |
//! | gyro bias `beta` | `TruthSeries::gyro_bias_rad_s` | rad/s |
//!
//! # Sensor models
//! - Photodiodes: the photodiode crate's model at the true scene (hard-edged Sun, plus the
//!   terms of the effects that are on) plus white Gaussian noise, then output stages
//!   (saturation clips after noise). No clipping at zero: eclipse outputs are noise around
//!   zero (plus any dark offset), the Gaussian the filter assumes. `time-offset` samples
//!   the scene at `t - seconds` exactly rather than through the model's first-order term.
//! - Gyro: `(1 + e) w + beta + noise`; `beta` starts from a seeded draw and random-walks
//!   at the gyro's sample times.
//! - Magnetometer: `A B_ref + bias + noise`, `B_ref` from IGRF-14.
//! - Temperatures (only with the scenario's `temperature`): a first-order thermal model per
//!   photodiode driven by its sunlight ([`scenario::Thermal`]); its true value enters the
//!   photodiode scenes (the `temperature` effect), its noisy samples the `temp_pdNN_C`
//!   columns.
//!
//! # Randomness
//! One seed; independent ChaCha8 streams per purpose (true parameters, initial state,
//! gyro bias, gyro noise, bias walk, magnetometer noise, photodiode noise, temperature
//! noise), so changing one
//! sensor's rate does not change another sensor's noise.
//!
//! # Performance
//! The albedo cell model dominates (about 70 % of the run, in `pdcal-albedo`); the
//! ephemeris of every row and the noise-free photodiode outputs are computed in parallel
//! with rayon (each row is a pure function of the truth, so results do not depend on the
//! thread count), the dynamics and the noise sequentially. `cargo bench -p pdcal-sim
//! --bench simulate` (`simulate_rax2_2h`: 7201 rows, 17 photodiodes, TOMS albedo) measured
//! 0.78 s wall on a 2-core machine under a load average of 8, which is 0.39 s of CPU time
//! per run (`perf stat`).
//!
//! # Hand-written parts
//! RK4 is a dozen lines on nalgebra's static vectors; the ODE crates would add a
//! dependency for no gain at a fixed step.

pub mod dynamics;
mod random;
pub mod scenario;
mod simulate;

pub use scenario::{
    BUILTIN_NAMES, CurrentChannel, CurrentSource, MagErrors, Scenario, ScenarioError, Thermal,
};
pub use simulate::{SimError, SimOutput, simulate, simulate_downlink, truth_model};
