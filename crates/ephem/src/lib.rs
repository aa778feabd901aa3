//! Ephemeris for pdcal: time, orbit, Sun, magnetic field and eclipse, all in GCRF.
//!
//! (Crate docs to be completed by the ephemeris work.)

pub mod eclipse;
pub mod igrf;
pub mod tle;
