//! One test binary for the attitude math's integration tests: each module is one file of
//! tests, linked once instead of once per file.

mod common;

mod direction;
mod dynamics;
mod mekf;
mod quat;
mod vector_pairs;
