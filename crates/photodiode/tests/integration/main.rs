//! One test binary for the measurement model's integration tests: each module is one file of
//! tests, linked once instead of once per file.

mod common;

mod model;
mod partials;
mod sun_vector;
