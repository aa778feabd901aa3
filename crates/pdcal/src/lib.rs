//! The pdcal driver: the commands of `docs/cli-contract.md` as library functions, so that
//! `xtask` (Monte Carlo, demos) runs exactly what the binary runs.
//!
//! One of the few crates that touch files (docs/ARCHITECTURE.md, "Layering", lists them).
//! Every output directory is written whole or not at all ([`output::OutputDir`]).

pub mod axes;
pub mod calibrate;
pub mod checks;
pub mod cli;
pub mod default_run;
pub mod diagnose;
pub mod evaluate;
pub mod export_onboard;
pub mod figures;
pub mod files;
pub mod import;
pub mod joint;
pub mod mag_align;
pub mod magcal;
pub mod mounting;
pub mod onboard_sun;
pub mod output;
pub mod repeatability;
pub mod rows;
pub mod schema;
pub mod sim_calibrate;
pub mod simulate;
pub mod stats;
pub mod stream;
pub mod sunvec;
pub mod tables;
