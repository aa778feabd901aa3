//! One test binary for the albedo model's integration tests: each module is one file of
//! tests, linked once instead of once per file.

mod common;

mod analytic;
mod approx;
mod invariants;
mod reference;
