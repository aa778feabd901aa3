//! The one dataset reader and writer of pdcal.
//!
//! A *dataset* is a directory (`dataset-format.md`, format version 1):
//!
//! | file | type | required |
//! |---|---|---|
//! | `dataset.ron` | [`DatasetMeta`]: epoch, orbit source, nominal photodiode mounts, noise hints | yes |
//! | `telemetry.csv` | [`Telemetry`]: t, gyro, magnetometer, `pdNN_V`, positions, `temp_*_C` | yes |
//! | `truth.csv` | [`TruthSeries`]: attitude, rates, bias, sun, eclipse, position, field | simulators |
//! | `truth.ron` | [`TruthConstants`]: true photodiode parameters and the [`Effect`]s that were on | simulators |
//!
//! Every command reads through [`read_dataset`] (or its pieces [`read_meta`],
//! [`read_telemetry`], [`read_truth`]) and every writer goes through [`write_dataset`], so
//! the contract is enforced in one place. `calibrate` and `diagnose` call [`read_meta`] and
//! [`read_telemetry`] only; the truth is for evaluation.
//!
//! # Architecture invariant
//! This is the only library crate that touches files. The estimation, model and simulation
//! crates take and return the in-memory types defined here; only this crate, the `pdcal`
//! binary and xtask do I/O.
//!
//! # Reading
//! Strict: unknown RON fields and CSV columns are errors, every number must be finite,
//! `t_s` strictly increasing, the `pdNN_V` columns must match `photodiodes` in number and
//! name, `r_*_km` columns appear exactly with `orbit: PositionColumns`, and TLE checksums
//! must hold. Temperature columns are optional: `temp_pdNN_C` must name an existing
//! photodiode, `temp_<panel>_C` a panel some photodiode's `panel` names, and every value
//! lies in [`TEMPERATURE_RANGE_C`]. CSV column order is free and blanks around cells are
//! ignored; an empty cell means "not sampled". Every error is a [`DatasetError`] naming file, line, column (with its
//! header or RON field path) and the offending value, displayed as
//! `telemetry.csv:12:4 (pd03_V): "abc" is not a number`. No input makes the reader panic.
//!
//! # Writing
//! [`write_dataset`] renders all files in memory, re-reads them with the reader (nothing is
//! written that cannot be read back), then writes into a staging sibling directory and
//! swaps it into place in one step ([`publish`]). Floats are written in Rust's shortest round-trip form, so
//! `read(write(x)) == x` bit for bit; output is deterministic (fixed column order, no maps).
//!
//! # Units and names
//! Names carry units as in the files (`t_s`, `gyro_rad_s`, `mag_nt` for `mag_*_nT`,
//! `pd_v` for `pdNN_V`, `r_gcrf_km`); serde renames bridge to the file spelling
//! (`scale_V`, `mag_nT`, `photodiode_V`). Angles stay in degrees here: this is the I/O edge,
//! and consumers convert once.
//!
//! # Conventions
//! Quaternions in truth.csv are scalar last `[q_x, q_y, q_z, q_w]`, body relative to GCRF,
//! `v_B = A(q) v_I` (Markley & Crassidis). Photodiode normals from azimuth/elevation follow
//! paper Eq. (16): `n = [cos(el)cos(az), cos(el)sin(az), sin(el)]`.
//!
//! # Hand-written parts
//! The CSV grammar is the `csv` crate and RON is `ron`; only the column semantics are
//! hand-written. The ISO 8601 epoch is parsed by hand into
//! `hifitime::Epoch::maybe_from_gregorian_utc` because hifitime's string parser accepts other
//! time scales and can panic on some malformed text. The staging output directory is
//! hand-made ([`publish`]) because `tempfile` creates it with mode 0700.

pub mod bounded;
mod column;
mod current;
mod error;
mod files;
mod line_ends;
pub mod manifest;
mod meta;
pub mod publish;
mod ron_text;
pub mod rules;
mod spill;
mod stream;
mod table;
mod telemetry;
mod temperature;
mod truth;

pub use column::{Cell, Column, Samples, Vectors};
pub use current::{
    CURRENT_RANGE_A, CurrentColumn, MAX_CURRENT_NAME_CHARS, current_column, is_current_name,
};
pub use error::{DatasetError, ErrorKind, FileFaultKind, TextFault, decode_text};
pub use files::{
    Dataset, DatasetWriter, LIBRARY_WRITE_COMMAND, begin_dataset, begin_dataset_as, read_dataset,
    read_meta, read_telemetry, read_telemetry_into, read_truth, render_dataset, write_dataset,
};
pub use line_ends::CrlfToLf;
pub use meta::{
    DatasetMeta, EpochUtc, FORMAT_VERSION, Inertia, MetaFields, NoiseHints, NominalMount,
    OrbitSpec, meta_from_fields, meta_from_str,
};
pub use pdcal_effects::{Effect, EffectId};
pub use ron_text::{RonFault, RonFaultKind, parse_ron};
pub use stream::{TelemetryLayout, TelemetryStream};
pub use telemetry::{
    Telemetry, TelemetryRow, TelemetryStorage, columns, photodiode_column, telemetry_from_columns,
    telemetry_from_str,
};
pub use temperature::{
    HeldTemperatures, TEMPERATURE_RANGE_C, TemperatureColumn, is_panel_name,
    panel_temperature_column, photodiode_temperature_column,
};
pub use truth::{
    TrueMagnetometer, TruePd, TruthConstants, TruthSeries, truth_columns, truth_constants_from_str,
    truth_series_from_str,
};

/// File name of the metadata.
pub const DATASET_RON: &str = "dataset.ron";
/// File name of the measured time series.
pub const TELEMETRY_CSV: &str = "telemetry.csv";
/// File name of the truth time series.
pub const TRUTH_CSV: &str = "truth.csv";
/// File name of the truth constants.
pub const TRUTH_RON: &str = "truth.ron";
