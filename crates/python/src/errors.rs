//! Rust errors as Python exceptions, with the message the CLI prints after `pdcal: error: `.

use pyo3::PyErr;
use pyo3::exceptions::{PyOSError, PyValueError};

/// `OSError` when the operating system refused (a missing file, permissions, a full disk),
/// else `ValueError`; the message is [`pdcal::cli::error_text`] of the chain, as on the CLI.
pub fn to_py(error: anyhow::Error) -> PyErr {
    let text = pdcal::cli::error_text(&error);
    let io = error.chain().any(|cause| {
        cause.is::<std::io::Error>()
            || cause
                .downcast_ref::<pdcal_dataset::DatasetError>()
                .is_some_and(|e| matches!(e.kind(), pdcal_dataset::ErrorKind::Io { .. }))
    });
    if io {
        PyOSError::new_err(text)
    } else {
        PyValueError::new_err(text)
    }
}

/// [`to_py`] of any error the library returns.
pub fn py_err<E: Into<anyhow::Error>>(error: E) -> PyErr {
    to_py(error.into())
}

/// A `ValueError` about an argument (its shape or type), which no file can have.
pub fn argument(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

/// Python's `json.loads` of `text` (exact for the shortest round-trip floats serde writes).
pub fn json_loads<'py>(
    py: pyo3::Python<'py>,
    text: &str,
) -> pyo3::PyResult<pyo3::Bound<'py, pyo3::PyAny>> {
    use pyo3::types::PyAnyMethods;
    py.import("json")?.call_method1("loads", (text,))
}
