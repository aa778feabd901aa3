//! `pdcal import`: a ground-segment CSV export and a column map (`map.ron`) in, a pdcal
//! dataset (`dataset.ron` + `telemetry.csv`, `docs/dataset-format.md`) out.
//!
//! The map (`docs/import.md`) names the time column and its form (Unix seconds, GPS
//! seconds, seconds from a stated UTC epoch, ISO 8601 UTC text), each sensor's column with a
//! unit or a linear conversion from raw counts, the photodiodes' nominal mounting, the orbit
//! (TLE lines, or position columns in km or m, GCRF/J2000 or TEME), noise hints and the
//! sentinel values that mean "no value". [`parse_map`] reads and checks a map on its own;
//! [`convert`] runs an export through it. Like the other core crates this one does no I/O: it
//! takes the files' bytes and names, and the `pdcal import` command reads them and publishes
//! the [`Imported::dataset`] with the dataset crate's atomic writer, so an output is whole or
//! absent.
//!
//! # Rules
//! - Every column the map names must be in the export's header, exactly once; an unknown one
//!   is an error at the map's line naming the column and the header's line.
//! - A cell is empty, a finite number, or (time, form `Iso`) ISO 8601 text; anything else is
//!   an error at the export's line and cell, quoting at most 80 characters of it.
//! - A cell equal to a sentinel (the map's global `sentinels` or the column's own) is an
//!   empty cell. A row whose time is empty or a sentinel is dropped and counted.
//! - A vector sensor (gyro, magnetometer, position) is sampled whole or not at all in a
//!   dataset: a row with only some of its components becomes empty for that sensor, counted
//!   in [`ImportReport::partial_vectors`].
//! - Kept rows must be in strictly increasing time order; an export out of order (merged
//!   passes, a wrapped counter) is refused naming both lines rather than sorted, because
//!   sorting would silently interleave the rows of a counter that wrapped. Rows whose time
//!   equals the previous kept row's are refused with their own message, or kept first or
//!   averaged as the map's `duplicate_times` says.
//! - The delimiter is the map's `delimiter`, or found from the header line; a numeric
//!   column may be a linear combination of export columns (`columns`), empty when any term
//!   is empty or a sentinel.
//! - [`convert_stream`] holds one row at a time (the command streams long exports through
//!   it); [`convert`] is the same loop collecting the rows in memory.
//! - The dataset's epoch is the first kept row's time (UTC, to the microsecond); `t_s` are
//!   elapsed SI seconds from it, across leap seconds.
//! - Mounting angles, TLE lines and noise hints go through the dataset reader's own checks,
//!   placed at the map's line.
//!
//! # Units and frames
//! Values are converted to the dataset's units (rad/s, nT, V, km) by [`Quantity`] factors:
//! 1 deg/s = pi/180 rad/s, 1 G = 1e5 nT, 1 mG = 100 nT, 1 uT = 1000 nT, 1 mV = 1e-3 V,
//! 1 m = 1e-3 km. Counts: `value = gain * count + offset` in the counts' unit, then the
//! factor. Positions in TEME are rotated to GCRF per row with
//! `pdcal_ephem::frames::teme_to_gcrf`; J2000 is written as GCRF.
//!
//! # Hand-written parts
//! The CSV grammar is the `csv` crate, the map is `ron` + serde, time scales and leap seconds
//! are hifitime through `pdcal_ephem::time`. Hand-written: the unit table (a dozen
//! constants; the unit crates, `uom` and the like, type quantities at compile time and parse
//! no unit text); the lookup of a map value's line, because serde gives no positions of
//! values once parsed (ron only places syntax errors), so the line is found by searching the
//! map text for the key or the string literal; and the plausibility window of times
//! ([`PLAUSIBLE_UTC`]), which catches a time column in another form than the map says.

mod convert;
mod error;
mod map;
mod source;
mod template;
mod timeform;
mod units;

pub use convert::{Converted, ImportReport, Imported, convert, convert_stream, layout};
pub use error::{ErrorKind, ImportError, shown};
pub use map::{
    Column, Counts, Delimiter, DuplicateTimes, ImportMap, MAP_FORMAT_VERSION, MapSpec, OrbitMap,
    PhotodiodeColumn, PositionFrame, TimeColumn, VectorColumns, parse_map,
};
pub use pdcal_dataset::FileFaultKind;
pub use template::map_template;
pub use timeform::{PLAUSIBLE_UTC, TimeForm};
pub use units::Quantity;
