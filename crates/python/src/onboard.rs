//! `pdcal.export_onboard` and `pdcal.sun_vector`: the onboard Sun-vector core's calibration
//! and its run on every row, as `pdcal export-onboard` and `pdcal sun-vector` do them.

use std::path::PathBuf;

use pdcal::output::OutputDir;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::calibration::{Calibration, csv_columns};
use crate::dataset::Dataset;
use crate::errors::{argument, json_loads, py_err};

/// A calibration's output directory: a `pdcal.Calibration` or the path of one `pdcal
/// calibrate` wrote.
fn calibration_dir(value: &Bound<'_, PyAny>) -> PyResult<PathBuf> {
    if let Ok(c) = value.cast::<Calibration>() {
        return Ok(c.get().out());
    }
    value
        .extract::<PathBuf>()
        .map_err(|_| argument("calibration: expected a pdcal.Calibration or a directory path"))
}

/// `pdcal export-onboard`: writes `pdcal_calibration.h` and `onboard.ron` into `out` (whole
/// or not at all) from `calibration` (a `pdcal.Calibration` or a calibration directory) and
/// the data set it was made from (its noise and fields of view); returns `onboard.ron` as a
/// dict.
#[pyfunction]
#[pyo3(signature = (calibration, dataset, out, grid_deg=pdcal::export_onboard::DEFAULT_GRID_DEG, force=false))]
pub fn export_onboard<'py>(
    py: Python<'py>,
    calibration: &Bound<'py, PyAny>,
    dataset: &Dataset,
    out: PathBuf,
    grid_deg: f64,
    force: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let cal_dir = calibration_dir(calibration)?;
    let (dataset_dir, meta, _) = dataset.set();
    let export = py
        .detach(|| {
            let dir = OutputDir::create_forced(&out, "export-onboard", force)?;
            let export =
                pdcal::export_onboard::build_with_meta(&cal_dir, &dataset_dir, &meta, grid_deg)?;
            pdcal::export_onboard::write_export(dir, &export)?;
            Ok::<_, anyhow::Error>(export)
        })
        .map_err(py_err)?;
    json_loads(py, &serde_json::to_string(&export).map_err(py_err)?)
}

/// `pdcal sun-vector`: the onboard core (f32, a `grid_deg` reflectivity grid) on every row
/// of `dataset` with `calibration`'s export and attitude estimates; the columns of the CSV
/// (`t_s`, `sun_x`, ..., `valid`, `validity`, `n_used`, `albedo`, `attitude`) as a dict of
/// numpy arrays, and the CSV written to `out` when given.
#[pyfunction]
#[pyo3(signature = (dataset, calibration, grid_deg=pdcal::export_onboard::DEFAULT_GRID_DEG, out=None))]
pub fn sun_vector<'py>(
    py: Python<'py>,
    dataset: &Dataset,
    calibration: &Bound<'py, PyAny>,
    grid_deg: f64,
    out: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    let cal_dir = calibration_dir(calibration)?;
    let (dataset_dir, meta, telemetry) = dataset.set();
    let tmp = tempfile::Builder::new()
        .prefix("pdcal-sun-vector-")
        .tempdir()
        .map_err(|e| py_err(anyhow::anyhow!("cannot create a temporary directory: {e}")))?;
    let path = tmp.path().join("sun_vector.csv");
    py.detach(|| {
        let (csv, _) = pdcal::onboard_sun::sun_vector_csv(
            &meta,
            &telemetry,
            &dataset_dir,
            &cal_dir,
            grid_deg,
        )?;
        pdcal::output::write_file(&path, csv.as_bytes())?;
        if let Some(out) = &out {
            pdcal::output::write_file_atomic(out, csv.as_bytes())?;
        }
        Ok::<_, anyhow::Error>(())
    })
    .map_err(py_err)?;
    csv_columns(py, &path)
}
