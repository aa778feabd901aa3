//! One test binary for the ephemeris and field integration tests against the reference tables: each module is one file of
//! tests, linked once instead of once per file.

mod common;

mod columns_interpolation;
mod eclipse;
mod frames_reference;
mod igrf;
mod rax2_orbit;
mod sgp4_verification;
mod sun_distance;
mod sun_reference;
