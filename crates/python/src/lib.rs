//! The native module of the Python package `pdcal` (`pdcal._pdcal`): each function is a thin
//! call into the Rust library (`pdcal` and the crates below it), with numpy arrays in and
//! out and Rust errors raised as Python exceptions carrying the CLI's message.
//!
//! Long runs (simulate, calibrate, diagnose) release the GIL; a calibration polls Python's
//! signal handlers through the filter's cancellation hook ([`pdcal::calibrate::CancelCheck`]),
//! so Ctrl-C stops it with `KeyboardInterrupt` and nothing written.
//!
//! No `unsafe` here; PyO3's macros expand to FFI code, which is why this crate alone allows
//! what the workspace forbids.

use pyo3::prelude::*;

mod arrays;
mod calibration;
mod campaign;
mod dataset;
mod diagnosis;
mod errors;
mod magcal;
mod onboard;

/// The module `pdcal._pdcal`.
#[pymodule]
fn _pdcal(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<dataset::Dataset>()?;
    m.add_class::<calibration::Calibration>()?;
    m.add_class::<diagnosis::Diagnosis>()?;
    m.add_class::<magcal::MagCalibration>()?;
    m.add_function(wrap_pyfunction!(dataset::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(dataset::scenario, m)?)?;
    m.add_function(wrap_pyfunction!(calibration::calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(calibration::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(diagnosis::diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(magcal::magcal, m)?)?;
    m.add_function(wrap_pyfunction!(onboard::export_onboard, m)?)?;
    m.add_function(wrap_pyfunction!(onboard::sun_vector, m)?)?;
    m.add_function(wrap_pyfunction!(campaign::sim_calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(campaign::ron_to_json, m)?)?;
    Ok(())
}
