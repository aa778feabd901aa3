//! `pdcal.calibrate`, `pdcal.Calibration` and `pdcal.evaluate`.
//!
//! A calibration runs `pdcal calibrate`'s own code ([`pdcal::calibrate::run_sets`]) into a
//! private temporary output directory: the files are the CLI's, byte for byte, and
//! `Calibration.write` publishes copies of them as the CLI publishes its own. The arrays are
//! read from those files when asked for.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use pdcal::calibrate::{CancelCheck, RunConfig};
use pdcal::output::{Manifest, OutputDir};
use pyo3::exceptions::PyImportError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::from_vec;
use crate::dataset::{Dataset, datasets};
use crate::errors::{argument, json_loads, py_err};

/// Time between two looks at Python's signal handlers during a calibration: a Ctrl-C is
/// answered within this (plus one poll interval of rows).
const SIGNAL_CHECK: Duration = Duration::from_millis(100);

/// A finished calibration: per-photodiode results, the run's time series, its files. The
/// files (those of `pdcal calibrate --out`) stay in a temporary directory while the object
/// lives (`$TMPDIR`; 40 MB for the 2 h set) and go with it.
#[pyclass(module = "pdcal", frozen)]
pub struct Calibration {
    /// Holds the published output while the object lives.
    tmp: tempfile::TempDir,
    summary_json: String,
    smoother: bool,
}

impl Calibration {
    /// The output directory, as `pdcal calibrate --out` would have written it.
    pub fn out(&self) -> PathBuf {
        self.tmp.path().join("calibration")
    }

    fn summary_value(&self) -> PyResult<serde_json::Value> {
        serde_json::from_str(&self.summary_json).map_err(py_err)
    }

    /// One number per photodiode from summary.json (NaN where it is null), parsed by
    /// Python's json, which reads the shortest round-trip text back exactly.
    fn per_photodiode(&self, py: Python<'_>, key: &str) -> PyResult<Vec<f64>> {
        let summary = self.summary(py)?;
        let mut values = Vec::new();
        for pd in summary.get_item("photodiodes")?.try_iter()? {
            let value: Option<f64> = pd?.get_item(key)?.extract()?;
            values.push(value.unwrap_or(f64::NAN));
        }
        Ok(values)
    }
}

/// A CSV of the output as a dict of columns: numbers as float64 arrays (empty cells NaN),
/// a column with text as a numpy array of str.
pub fn csv_columns<'py>(py: Python<'py>, path: &Path) -> PyResult<Bound<'py, PyDict>> {
    let mut reader = csv::Reader::from_path(path).map_err(py_err)?;
    let header: Vec<String> = reader
        .headers()
        .map_err(py_err)?
        .iter()
        .map(str::to_owned)
        .collect();
    let mut cells: Vec<Vec<String>> = vec![Vec::new(); header.len()];
    for record in reader.records() {
        let record = record.map_err(py_err)?;
        for (column, cell) in cells.iter_mut().zip(record.iter()) {
            column.push(cell.to_owned());
        }
    }
    let dict = PyDict::new(py);
    let np = py.import("numpy")?;
    for (name, column) in header.iter().zip(cells) {
        let numbers: Option<Vec<f64>> = (column.iter())
            .map(|c| {
                if c.is_empty() {
                    Some(f64::NAN)
                } else {
                    c.parse().ok()
                }
            })
            .collect();
        match numbers {
            Some(values) => dict.set_item(name, from_vec(py, values))?,
            None => dict.set_item(name, np.call_method1("asarray", (column,))?)?,
        }
    }
    Ok(dict)
}

/// Copies every file of the output `from` (as its manifest lists them) into `to`.
fn copy_output(from: &Path, to: &OutputDir) -> anyhow::Result<()> {
    let Some(manifest) = Manifest::read(from)? else {
        anyhow::bail!("{}: the calibration's output is gone", from.display());
    };
    for file in &manifest.files {
        let target = to.file(&file.name);
        if let Some(parent) = target.parent() {
            std::fs::create_dir_all(parent)
                .map_err(|e| anyhow::anyhow!("cannot create {}: {e}", parent.display()))?;
        }
        std::fs::copy(from.join(&file.name), &target)
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", target.display()))?;
    }
    Ok(())
}

#[pymethods]
impl Calibration {
    /// summary.json as a dict.
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        json_loads(py, &self.summary_json)
    }

    /// The sensor-axes findings (`summary.json` `sensor_axes`): a list of dicts with
    /// `sensor`, `body_from_sensor` (3x3 of -1/0/1, `v_body = M v_sensor`), `evidence` and
    /// `applied`; empty when every sensor's axes are as stated.
    #[getter]
    fn sensor_axes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.summary(py)?.get_item("sensor_axes")
    }

    /// Calibrated scale factors (output at 1 AU, normal incidence), V, (M,).
    #[getter]
    #[allow(non_snake_case)]
    fn scale_V<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
        Ok(from_vec(py, self.per_photodiode(py, "scale_V")?))
    }

    /// Their 1-sigma, V, (M,).
    #[getter]
    #[allow(non_snake_case)]
    fn scale_sigma_V<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
        Ok(from_vec(py, self.per_photodiode(py, "scale_sigma_V")?))
    }

    /// Calibrated azimuths, body frame, deg, (M,).
    #[getter]
    fn azimuth_deg<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
        Ok(from_vec(py, self.per_photodiode(py, "azimuth_deg")?))
    }

    /// Their 1-sigma, deg, (M,); NaN where undefined (elevation +-90 deg).
    #[getter]
    fn azimuth_sigma_deg<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
        Ok(from_vec(py, self.per_photodiode(py, "azimuth_sigma_deg")?))
    }

    /// Calibrated elevations, body frame, deg, (M,).
    #[getter]
    fn elevation_deg<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
        Ok(from_vec(py, self.per_photodiode(py, "elevation_deg")?))
    }

    /// Their 1-sigma, deg, (M,).
    #[getter]
    fn elevation_sigma_deg<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
        Ok(from_vec(
            py,
            self.per_photodiode(py, "elevation_sigma_deg")?,
        ))
    }

    /// The forward filter's estimates per row (estimates.csv) as a dict of arrays, keyed by
    /// the file's columns (`t_s`, `q_x` ... `q_w`, `pd01_scale_V`, ...). Read from the
    /// run's file at each access.
    #[getter]
    fn estimates<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        csv_columns(py, &self.out().join("estimates.csv"))
    }

    /// The smoothed estimates (estimates_smoothed.csv), or None without the smoother.
    #[getter]
    fn estimates_smoothed<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        (self.smoother)
            .then(|| csv_columns(py, &self.out().join("estimates_smoothed.csv")))
            .transpose()
    }

    /// The residuals per sample and sensor (residuals.csv) as a dict of arrays; `sensor`
    /// is an array of str.
    #[getter]
    fn residuals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        csv_columns(py, &self.out().join("residuals.csv"))
    }

    /// calibration.ron's text (a `config` prior for the next data set's calibration).
    #[getter]
    fn calibration_ron(&self) -> PyResult<String> {
        let path = self.out().join("calibration.ron");
        std::fs::read_to_string(&path)
            .map_err(|e| py_err(anyhow::anyhow!("cannot read {}: {e}", path.display())))
    }

    /// A pandas DataFrame of `estimates`, `estimates_smoothed` or `residuals` (needs pandas).
    #[pyo3(signature = (table="estimates"))]
    fn to_pandas<'py>(&self, py: Python<'py>, table: &str) -> PyResult<Bound<'py, PyAny>> {
        let pandas = py.import("pandas").map_err(|_| {
            PyImportError::new_err("Calibration.to_pandas needs pandas (pip install pandas)")
        })?;
        let columns = match table {
            "estimates" => self.estimates(py)?,
            "residuals" => self.residuals(py)?,
            "estimates_smoothed" => self
                .estimates_smoothed(py)?
                .ok_or_else(|| argument("this calibration ran without the smoother"))?,
            other => {
                return Err(argument(format!(
                    "table {other:?}: expected estimates, estimates_smoothed or residuals"
                )));
            }
        };
        pandas.call_method1("DataFrame", (columns,))
    }

    /// Writes the output files of `pdcal calibrate --out OUT_DIR` (the same bytes) into
    /// `out_dir`, under the CLI's rules: whole or not at all, never over files pdcal did not
    /// write.
    fn write(&self, py: Python<'_>, out_dir: PathBuf) -> PyResult<()> {
        let from = self.out();
        py.detach(|| {
            let dir = OutputDir::create(&out_dir, "calibrate")?;
            copy_output(&from, &dir)?;
            dir.commit()
        })
        .map_err(py_err)
    }

    fn __repr__(&self) -> String {
        let summary = self.summary_value().unwrap_or_default();
        format!(
            "pdcal.Calibration({}: {} photodiodes, mode {})",
            summary["dataset"],
            summary["photodiodes"].as_array().map_or(0, Vec::len),
            summary["mode"]
        )
    }
}

/// The run configuration from `config`: None (the defaults), a path to a filter
/// configuration RON or a calibration.ron, or a `Calibration` (its calibration.ron: a
/// scale-factors-only run with it as the prior).
fn run_config(config: Option<&Bound<'_, PyAny>>) -> PyResult<RunConfig> {
    let Some(config) = config else {
        return Ok(RunConfig::default());
    };
    let path = match config.cast::<Calibration>() {
        Ok(cal) => cal.get().out().join("calibration.ron"),
        Err(_) => config.extract::<PathBuf>()?,
    };
    pdcal::calibrate::load_config(&path).map_err(py_err)
}

/// A check of Python's signal handlers at most every [`SIGNAL_CHECK`]; a raised exception
/// (KeyboardInterrupt) is kept in `raised` and stops the run.
fn signal_check(raised: Arc<Mutex<Option<PyErr>>>) -> CancelCheck {
    let mut last = Instant::now();
    Box::new(move || {
        if last.elapsed() < SIGNAL_CHECK {
            return false;
        }
        last = Instant::now();
        match Python::attach(|py| py.check_signals()) {
            Ok(()) => false,
            Err(e) => {
                if let Ok(mut slot) = raised.lock() {
                    *slot = Some(e);
                }
                true
            }
        }
    })
}

/// Calibrates one dataset or several of one spacecraft (a list: calibrated as one, as
/// `pdcal calibrate DIR1 DIR2`). `config`: None, a filter configuration or calibration.ron
/// path, or an earlier `Calibration` as the prior of a scale-factors-only run. `smoother`
/// runs the RTS smoother. Releases the GIL; Ctrl-C raises KeyboardInterrupt.
#[pyfunction]
#[pyo3(signature = (dataset, config=None, smoother=true))]
pub fn calibrate(
    py: Python<'_>,
    dataset: &Bound<'_, PyAny>,
    config: Option<&Bound<'_, PyAny>>,
    smoother: bool,
) -> PyResult<Calibration> {
    let sets = datasets(dataset)?;
    let mut config = run_config(config)?;
    config.filter.smoother = smoother;
    let tmp = tempfile::Builder::new()
        .prefix("pdcal-calibration-")
        .tempdir()
        .map_err(|e| py_err(anyhow::anyhow!("cannot create a temporary directory: {e}")))?;
    let out = tmp.path().join("calibration");
    let raised = Arc::new(Mutex::new(None));
    let check = Arc::clone(&raised);
    let result = py.detach(|| {
        let dir = OutputDir::create(&out, "calibrate")?;
        pdcal::calibrate::run_sets(sets, dir, &config, Some(signal_check(check)))
    });
    if let Some(e) = raised.lock().ok().and_then(|mut slot| slot.take()) {
        return Err(e);
    }
    let (_, summary) = result.map_err(py_err)?;
    Ok(Calibration {
        tmp,
        summary_json: serde_json::to_string(&summary).map_err(py_err)?,
        smoother,
    })
}

/// Compares a calibration with the dataset's truth (a simulated dataset): the contents of
/// `pdcal evaluate`'s evaluation.json as a dict.
#[pyfunction]
pub fn evaluate<'py>(
    py: Python<'py>,
    dataset: &Dataset,
    calibration: &Calibration,
) -> PyResult<Bound<'py, PyAny>> {
    let Some((truth, constants)) = &dataset.inner.truth else {
        return Err(argument(format!(
            "{}: evaluate needs truth.csv and truth.ron (a simulated dataset)",
            dataset.dir.as_deref().map_or_else(
                || dataset.inner.meta.name.clone(),
                |d| d.display().to_string()
            )
        )));
    };
    let evaluation =
        pdcal::evaluate::evaluate_output(truth, constants, &calibration.out()).map_err(py_err)?;
    let json = serde_json::to_string(&evaluation).map_err(py_err)?;
    json_loads(py, &json)
}
