//! One test binary for the filter's integration tests: each module is one file of
//! tests, linked once instead of once per file.

mod common;

mod bias_fit;
mod calibrate;
mod dynamics;
mod filter;
mod references;
mod robust;
mod segments;
mod streaming;
mod sun_distance;
