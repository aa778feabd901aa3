//! `pdcal.magcal` and `pdcal.MagCalibration` (docs/magcal.md).

use std::path::PathBuf;

use nalgebra::Matrix3;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pdcal::magcal::MagCalOutcome;
use pdcal::output::OutputDir;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::from_vec;
use crate::dataset::Dataset;
use crate::errors::{json_loads, py_err};

/// A magnetometer calibration (`pdcal magcal`): `T`, `b` and the current coefficients with
/// their sigmas and covariance, and the dataset it came from.
#[pyclass(module = "pdcal", frozen)]
pub struct MagCalibration {
    dataset: pdcal_dataset::Dataset,
    dir: Option<PathBuf>,
    outcome: MagCalOutcome,
    summary_json: String,
}

fn matrix3<'py>(py: Python<'py>, m: &Matrix3<f64>) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((3, 3), |(i, j)| m[(i, j)]).into_pyarray(py)
}

#[pymethods]
impl MagCalibration {
    /// magcal.json as a dict.
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_loads(py, &self.summary_json)
    }

    /// `T` (3x3, symmetric form).
    #[getter]
    fn matrix<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        matrix3(py, &self.outcome.calibration.matrix)
    }

    /// One sigma of each entry of `T`.
    #[getter]
    fn matrix_sigma<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        matrix3(py, &self.outcome.calibration.matrix_sigma())
    }

    /// The hard-iron bias `b`, nT.
    #[getter(bias_nT)]
    fn bias_nt<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        from_vec(
            py,
            self.outcome.calibration.params.bias_nt.as_slice().to_vec(),
        )
    }

    /// One sigma of `b`, nT.
    #[getter(bias_sigma_nT)]
    fn bias_sigma_nt<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        from_vec(
            py,
            self.outcome.calibration.bias_sigma_nt().as_slice().to_vec(),
        )
    }

    /// `c_j` of every kept regressor by column name, nT/A.
    #[getter(current_bias_nT_per_A)]
    fn current_bias<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let cal = &self.outcome.calibration;
        let dict = PyDict::new(py);
        for (name, c) in cal.regressors.iter().zip(&cal.params.coeff_nt) {
            dict.set_item(name, from_vec(py, c.as_slice().to_vec()))?;
        }
        Ok(dict)
    }

    /// The Fisher covariance, rows named by `parameters`.
    #[getter]
    fn covariance<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let c = &self.outcome.calibration.covariance;
        Array2::from_shape_fn(c.shape(), |(i, j)| c[(i, j)]).into_pyarray(py)
    }

    /// The names of the covariance's rows (`T11` .., `b_x` .., `cur_px_A_x` ..).
    #[getter]
    fn parameters(&self) -> Vec<String> {
        self.outcome.calibration.parameter_names()
    }

    /// Why the result should not be trusted (empty when the residuals agree with the noise).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.outcome.warnings.clone()
    }

    /// A copy of `dataset` with its magnetometer corrected (`pdcal calibrate --mag-cal`).
    fn apply(&self, dataset: &Dataset) -> PyResult<Dataset> {
        let mut inner = dataset.inner.clone();
        pdcal::magcal::apply(&mut inner.telemetry, &self.outcome.calibration).map_err(py_err)?;
        Ok(Dataset { inner, dir: None })
    }

    /// Writes the output files of `pdcal magcal --out OUT_DIR` into `out_dir`.
    fn write(&self, py: Python<'_>, out_dir: PathBuf) -> PyResult<()> {
        py.detach(|| {
            let dir = OutputDir::create(&out_dir, "magcal")?;
            pdcal::magcal::write_outputs(
                dir,
                self.dir.as_deref(),
                &self.dataset.meta,
                self.dataset.telemetry.clone(),
                &self.outcome,
            )
        })
        .map_err(py_err)
    }

    fn __repr__(&self) -> String {
        let cal = &self.outcome.calibration;
        format!(
            "pdcal.MagCalibration(residual {:.0} nT -> {:.0} nT, regressors {:?})",
            cal.residual_rms_before_nt, cal.residual_rms_after_nt, cal.regressors
        )
    }
}

/// Calibrates the magnetometer of `dataset` without attitude (`pdcal magcal`). Releases
/// the GIL.
#[pyfunction]
pub fn magcal(py: Python<'_>, dataset: &Dataset) -> PyResult<MagCalibration> {
    let (meta, telemetry) = (&dataset.inner.meta, &dataset.inner.telemetry);
    let outcome = py
        .detach(|| pdcal::magcal::run(meta, telemetry))
        .map_err(py_err)?;
    let summary_json =
        serde_json::to_string(&pdcal::magcal::summary_of(&outcome)).map_err(py_err)?;
    Ok(MagCalibration {
        dataset: dataset.inner.clone(),
        dir: dataset.dir.clone(),
        outcome,
        summary_json,
    })
}
