//! One test binary for the dataset format's integration tests: each module is one file of
//! tests, linked once instead of once per file.

mod common;

mod bad_input;
mod current;
mod field_of_view;
mod from_columns;
mod hand_written;
mod inertia;
mod physical_ranges;
mod round_trip;
mod stream;
mod streamed_read;
mod temperature;
mod truncation;
