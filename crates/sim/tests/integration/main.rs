//! One test binary for the simulator's integration tests: each module is one file of
//! tests, linked once instead of once per file.

mod magnetometer_errors;
mod temperature;
mod truth;
