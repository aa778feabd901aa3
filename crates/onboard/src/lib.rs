//! The onboard Sun-vector core: the Sun direction in the body frame from calibrated
//! photodiodes, with Earth albedo compensated, small and safe enough for a flight computer.
//!
//! `#![no_std]`, no allocation, and no panic on any input: the clippy lints that would let a
//! panic in (indexing, unwrap, integer overflow, `panic!`) are denied in `Cargo.toml`, every
//! public function returns a result with a validity flag instead, and the C test harness
//! (`c/`) links the core into a `no_std` static library whose panic handler is an undefined
//! symbol, so a panic path that survives optimisation fails the link.
//!
//! Per call ([`estimate_sun`]): each photodiode's output (V) and its calibration
//! ([`Calibration`]: scale, normal, dark offset, field of view, noise and the calibration's
//! own sigmas); optionally the Earth as seen from the spacecraft ([`EarthInput`]: the Earth
//! direction in the body frame and the orbit radius from the flight software's own attitude
//! and position, and for a reflectivity grid the body-to-Earth-fixed rotation); optionally a
//! compact reflectivity grid ([`ReflectivityGrid`], one byte a cell). It returns the Sun unit
//! vector in the body frame, its covariance and 1-sigma cone, the photodiodes used and a
//! [`Validity`] with its reason.
//!
//! The measurement model is pdcal's (paper Eq. 15 with the albedo of Eq. 13):
//! `I_i = C_i F (max(0, n_i . s) + E_i(s)) + b_i`, with `F = (1 AU / r_sun)^2`, `E_i` the
//! albedo irradiance on photodiode `i` over the Sun's, `b_i` the dark offset, both terms
//! gated by the photodiode's field of view. The least squares of
//! [`pdcal_photodiode::sun_vector`] (one equation `(I_i - b_i)/(C_i F) - E_i = n_i . s` per
//! lit photodiode) is solved with weights from the noise and the calibration's sigmas, and
//! the albedo `E_i` recomputed at each new estimate (a fixed number of passes).
//!
//! Arithmetic is generic over [`Real`] (`f32` for FPUs without double precision, `f64`);
//! the tests check one against the other. Square roots and trigonometry come from the
//! `libm` crate in every build, so the flight library and a ground tool agree to the bit.
//!
//! Written here rather than taken from a crate: nalgebra's fixed-size types are `no_std`
//! but panic on some inputs (indexing, `unwrap` in decompositions), and the core needs only
//! 3-vectors and 3x3 symmetric solves.
#![no_std]

mod albedo;
mod calibration;
pub mod ffi;
mod linalg;
mod real;
mod sun;

pub use albedo::{EARTH_RADIUS_KM, ReflectivityGrid, albedo_ratios};
pub use calibration::{Calibration, MAX_PHOTODIODES, Photodiode};
pub use real::Real;
pub use sun::{AlbedoUse, EarthInput, Options, SunEstimate, Validity, estimate_sun};
