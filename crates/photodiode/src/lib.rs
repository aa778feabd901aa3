//! Photodiode (coarse Sun sensor) measurement model of the paper's Section III.B (Eqs. 11-25),
//! extended to a run-time editable sum of effects, and the Sun vector measured by the
//! photodiodes.
//!
//! This crate owns:
//! - one sensor's parameters ([`Photodiode`]) and one sample's context ([`Scene`]);
//! - the interfaces the simulator (truth), the EKF and the diagnosis workflow share:
//!   [`Term`] (additive contribution), [`ScaleGain`] (factor on the scale factor) and
//!   [`OutputStage`] (non-additive stage on the sum, e.g. clipping), all [`Component`]s with an
//!   effect id and optional [`Parameter`]s; and [`MeasurementModel`], which holds the
//!   photodiodes and an ordered list of components, adds and removes them by id at run time,
//!   and returns the output and every partial derivative ([`Partials`]);
//! - one component per photodiode effect of `cli-contract.md` (module [`terms`]);
//! - the paper's named partials, Eqs. (20)-(24), as free functions ([`paper`]);
//! - the least-squares Sun vector and its "not observable" cases ([`estimate_sun_vector`]).
//!
//! # Model
//!
//! ```text
//! I_i = S( sum_k T_k(C_i g(t), n_i, scene) )          (Eq. 15 is T = sun + albedo, S = identity)
//! sun:         f C n^T A s|_R       if n^T s > 0 (and n^T s >= cos fov when a FOV is set)
//! albedo:      C E_a/E_AM0          ratio from the scene's AlbedoIrradiance at A^T n
//! fov-rolloff: f C c (r(theta) - 1) raised-cosine taper between start and cutoff
//! dark-offset: b_i
//! penumbra:    (sun_fraction - hard(sun_fraction)) C n^T s
//! time-offset: f C delta n^T (w x s)  first order of s(t - delta)
//! scale-drift: g = 1 + k t_s/3600   (a ScaleGain: every term sees C g)
//! saturation:  S(y) = min(y, max_V)  (an OutputStage)
//! ```
//!
//! Why three traits rather than one: saturation is not additive (its derivative multiplies
//! every other partial), and scale drift multiplies every C-proportional term (an additive
//! version would have to know which other terms are present). Writing them as a stage and a
//! gain keeps each exact and lets the model apply the chain rule once:
//! `dI/dC = S' g sum dT/dC_eff`, `dI/dk = S' C sum dT/dC_eff dg/dk`,
//! `dI/dmax = 1` when clipped. The sun-derived corrections (`fov-rolloff`, `time-offset`) carry
//! their own [`ShadowMode`], which should match the [`DirectSun`]'s; `penumbra` corrects only
//! the direct Sun, so its cross-terms with roll-off and time offset are neglected (they matter
//! only for the few seconds per orbit in penumbra, times a small correction).
//!
//! # Partials
//!
//! Attitude: the true attitude is `A(dq(a)) A_est` with `A(dq(a)) ~= I - [a x]`, so
//! `d(A s)/da = [(A s) x]` and `dI/da = C n^T [(A s) x]` (Eq. 20); gradients are returned as
//! columns (`C n x A s`). Normal: the gradient w.r.t. `n` as a free 3-vector; the filter maps it
//! to azimuth/elevation with [`Partials::d_az_el`] (Eqs. 23-24) or projects it on a tangent
//! plane. Eq. (24) as printed has a sign slip in the y component; the derivative of Eq. (16)
//! is used (see [`paper::d_output_d_elevation`]).
//!
//! Albedo: by default ([`AlbedoPartials::Neglected`]) its attitude and normal partials are
//! zero, as in the paper after Eq. (24); the scale partial `E_a/E_AM0` is always supplied
//! (the paper's Eq. 22 drops it too; it costs nothing and is exact). With
//! [`AlbedoPartials::Included`], `dI/da = C n^T [(A v) x]` and `dI/dn = C A v`,
//! `v = sum c u` over the gated cells (cells entering or leaving a sensor's field of view are
//! a discontinuity the gradient ignores). Including them makes the filter's linearisation
//! exact for the albedo part too: a photodiode that sees only the Earth (Sun behind it) then
//! informs attitude and its own normal instead of only its scale, and there is no bias from
//! ignoring the albedo slope when albedo is a large share of the output (Earth-facing sensors,
//! up to about 0.3 C). The cost: the filter trusts the albedo map's gradient, whose error is
//! of the same order as the albedo model error (the paper tunes 50 W/m^2, about 0.13 V), so
//! included partials should come with that error in R.
//!
//! # Conventions
//! - Attitude matrix `A` maps GCRF to body (`v_B = A v_I`); quaternions are scalar last
//!   (see `pdcal-attitude`). The Sun vector in the scene is `sun_body = A s|_R`, unit.
//! - Radians inside; degrees only in the `*_deg` constructors.
//! - Parameter names follow the output grammar: `pdNN_<name>_<unit>` (1-based NN) per
//!   photodiode, `<name>_<unit>` when shared.
//!
//! # Symbols
//! | paper | here | unit |
//! |---|---|---|
//! | `C_i` (Eq. 15) | [`Photodiode::scale_v`] | V |
//! | `n_i` (Eq. 16) | [`Photodiode::n_body`] | - |
//! | `alpha_i`, `epsilon_i` | [`Photodiode::az_el_rad`] | rad |
//! | `eta` sigma | [`Photodiode::noise_v`] | V |
//! | FOV half angle | [`Photodiode::fov_half_angle_rad`] | rad |
//! | `A` | [`Scene::attitude`] | - |
//! | `A s|_R` | [`Scene::sun_body`] | - |
//! | `E_a / E_AM0` (Eq. 13) | [`AlbedoIrradiance::ratio`] | - |
//! | `a` (MEKF attitude error) | [`Partials::d_attitude`] | rad |
//! | `I~_i` predicted | [`Partials::value_v`], [`MeasurementModel::evaluate`] | V |
//!
//! Why hand-written: no crate models coarse Sun sensors; the least squares is a 3x3 normal
//! equation solved with nalgebra's Cholesky and symmetric eigen-decomposition.

mod components;
mod error;
mod model;
pub mod paper;
mod sensor;
mod sun_vector;
mod term;
pub mod terms;

pub use components::{EffectModelOptions, add_effect, estimated_values_mut};
pub use error::PhotodiodeError;
pub use model::{MeasurementModel, Part, Partials};
pub use pdcal_albedo::AlbedoIrradiance;
pub use pdcal_effects::{Effect, EffectId};
pub use sensor::{Photodiode, Scene, ShadowMode};
pub use sun_vector::{
    LitThreshold, NotObservableReason, SunEstimate, SunVector, SunVectorOptions,
    estimate_sun_vector,
};
pub use term::{
    Component, ComponentId, OutputStage, Parameter, ParameterRole, ScaleGain, Sensitivity, Term,
    parameter_for,
};
pub use terms::{
    Albedo, AlbedoGain, AlbedoPartials, DarkOffset, DirectSun, FovRolloff, KELLY_MIN_KAPPA,
    KellyRolloff, Penumbra, Saturation, ScaleDrift, Temperature, TimeOffset,
};
