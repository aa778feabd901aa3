//! `pdcal.diagnose` and `pdcal.Diagnosis`.

use std::path::PathBuf;

use pdcal::diagnose::DiagnoseOutcome;
use pdcal::output::OutputDir;
use pyo3::prelude::*;

use crate::dataset::Dataset;
use crate::errors::{json_loads, py_err};

/// A finished diagnosis: the verdict, the rounds and the gap figures of diagnosis.json.
#[pyclass(module = "pdcal", frozen)]
pub struct Diagnosis {
    meta: pdcal_dataset::DatasetMeta,
    outcome: DiagnoseOutcome,
    summary_json: String,
}

impl Diagnosis {
    fn field<'py>(&self, py: Python<'py>, key: &str) -> PyResult<Bound<'py, PyAny>> {
        self.summary(py)?.get_item(key)
    }
}

#[pymethods]
impl Diagnosis {
    /// diagnosis.json as a dict.
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_loads(py, &self.summary_json)
    }

    /// The verdict: effects found, strongest first, joined by `+` (then `unexplained`), or
    /// `none`.
    #[getter]
    fn verdict(&self) -> String {
        self.outcome.diagnosis.summary().verdict
    }

    /// The rounds (what was found, the evidence, the gap before and after), as dicts.
    #[getter]
    fn rounds<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.field(py, "rounds")
    }

    /// The effects of the final model.
    #[getter]
    fn final_model<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.field(py, "final_model")
    }

    /// Physical-plausibility warnings on the input.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.outcome.warnings.clone()
    }

    /// Writes the output files of `pdcal diagnose --out OUT_DIR` into `out_dir`.
    fn write(&self, py: Python<'_>, out_dir: PathBuf) -> PyResult<()> {
        py.detach(|| {
            let dir = OutputDir::create(&out_dir, "diagnose")?;
            pdcal::diagnose::write_outputs(dir, &self.meta, &self.outcome)
        })
        .map_err(py_err)
    }

    fn __repr__(&self) -> String {
        format!("pdcal.Diagnosis(verdict {:?})", self.verdict())
    }
}

/// Finds the effects the model lacks (`pdcal diagnose`), starting from `base_model`
/// (`"paper"`, Eq. 15, or `"cosine"`, Eq. 11). Releases the GIL.
#[pyfunction]
#[pyo3(signature = (dataset, base_model="paper"))]
pub fn diagnose(py: Python<'_>, dataset: &Dataset, base_model: &str) -> PyResult<Diagnosis> {
    let base: pdcal_diagnose::BaseModel = base_model.parse().map_err(py_err)?;
    let (meta, telemetry) = (&dataset.inner.meta, &dataset.inner.telemetry);
    let outcome = py
        .detach(|| pdcal::diagnose::run(meta, telemetry, base))
        .map_err(py_err)?;
    let summary_json = serde_json::to_string(&outcome.diagnosis.summary()).map_err(py_err)?;
    Ok(Diagnosis {
        meta: meta.clone(),
        outcome,
        summary_json,
    })
}
