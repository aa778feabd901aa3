//! `pdcal.Dataset`: a dataset (`docs/dataset-format.md`) as numpy arrays; `pdcal.simulate`
//! and `pdcal.scenario`.
//!
//! Built from arrays, a dataset goes through the one reader: the metadata and the columns
//! are rendered as dataset.ron and telemetry.csv would be written and read back
//! ([`pdcal_dataset::meta_from_fields`], [`pdcal_dataset::telemetry_from_columns`]), so a
//! value the CLI refuses in a file is refused here with the same message, naming the line
//! and column of the file `Dataset.write` would write.

use std::path::PathBuf;

use nalgebra::{Vector3, Vector4};
use pdcal_dataset::{
    Effect, Inertia, MetaFields, NoiseHints, NominalMount, OrbitSpec, Telemetry, TruePd,
    TruthConstants, TruthSeries, columns, photodiode_column,
};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::arrays::{from_columns, from_vec, matrix, vector};
use crate::errors::{argument, json_loads, py_err};

/// A dataset: what a spacecraft downlinks (dataset.ron and telemetry.csv) and, from a
/// simulator, the truth. Arrays are numpy `float64`; a blank (not sampled) cell is NaN.
///
/// `Dataset(*, epoch_utc, t_s, gyro_rad_s, photodiodes_V, nominal_az_el_deg, ...)`, N rows
/// and M photodiodes (docs/dataset-format.md):
///
/// - `epoch_utc`: ISO 8601 UTC text (`"2011-11-04T18:29:45Z"`); `t_s` counts from it.
/// - `t_s` (N,): s, strictly increasing.
/// - `gyro_rad_s` (N, 3): body rate, rad/s; a row all NaN is a row without a gyro sample.
/// - `photodiodes_V` (N, M): raw outputs, V; NaN where not sampled.
/// - `nominal_az_el_deg` (M, 2): nominal azimuth and elevation, body frame, deg (paper
///   Eq. 16: `n = [cos el cos az, cos el sin az, sin el]`).
/// - `mag_nT` (N, 3) or None: magnetometer, body frame, nT (None: photodiode-only mode).
/// - `tle=(line1, line2)` or `positions_gcrf_km` (N, 3): the orbit, one of the two.
/// - `fov_deg` (M,) or None: field-of-view half-angle, deg, NaN for none.
/// - `panel`: list of M panel names or None.
/// - `temperatures_C`: dict of `temp_pdNN_C` / `temp_<panel>_C` columns, (N,) each.
/// - `noise`: dict of 1-sigma hints `gyro_rad_s`, `mag_nT`, `photodiode_V` (each optional).
/// - `name`: dataset.ron `name` (default `"dataset"`).
/// - `truth`: dict as the `truth` property gives it, or None.
///
/// Values are checked by the dataset reader (the files are rendered and read back), so a
/// bad value raises `ValueError` with the CLI's message for the file `write` would write.
#[pyclass(module = "pdcal", frozen)]
pub struct Dataset {
    /// The dataset.
    pub inner: pdcal_dataset::Dataset,
    /// The directory it was read from, if any (named in a joint calibration's summary).
    pub dir: Option<PathBuf>,
}

/// Three columns of a vector sensor, NaN where the row has no sample.
fn vec3_columns(column: &pdcal_dataset::Vectors) -> Vec<Vec<f64>> {
    (0..3)
        .map(|a| {
            column
                .iter()
                .map(|v| v.map_or(f64::NAN, |v| v[a]))
                .collect()
        })
        .collect()
}

/// Columns of fixed-size vectors (truth.csv's, which has no blanks).
fn fixed_columns<const N: usize>(rows: &[nalgebra::SVector<f64, N>]) -> Vec<Vec<f64>> {
    (0..N)
        .map(|a| rows.iter().map(|v| v[a]).collect())
        .collect()
}

/// Rows of fixed-size vectors from `N` columns of one matrix argument.
fn fixed_rows<const N: usize>(columns: &[Vec<f64>]) -> Vec<nalgebra::SVector<f64, N>> {
    let rows = columns.first().map_or(0, Vec::len);
    (0..rows)
        .map(|i| nalgebra::SVector::<f64, N>::from_fn(|a, _| columns[a][i]))
        .collect()
}

fn effect_ron(effect: &Effect) -> PyResult<String> {
    ron::to_string(effect).map_err(py_err)
}

fn parse_effect(index: usize, text: &str) -> PyResult<Effect> {
    ron::Options::default()
        .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
        .from_str(text)
        .map_err(|e| argument(format!("truth effects[{index}]: {e}")))
}

/// The keyword arguments of the constructor that describe the photodiodes.
struct Mounts<'a, 'py> {
    az_el_deg: &'a Bound<'py, PyAny>,
    fov_deg: Option<&'a Bound<'py, PyAny>>,
    panel: Option<Vec<Option<String>>>,
}

fn nominal_mounts(m: Mounts<'_, '_>) -> PyResult<Vec<NominalMount>> {
    let az_el = matrix(m.az_el_deg, "nominal_az_el_deg", Some(2))?;
    let n = az_el[0].len();
    let fov = match m.fov_deg {
        Some(f) => vector(f, "fov_deg")?,
        None => vec![f64::NAN; n],
    };
    let panel = m.panel.unwrap_or_else(|| vec![None; n]);
    if fov.len() != n || panel.len() != n {
        return Err(argument(format!(
            "nominal_az_el_deg has {n} photodiodes, fov_deg {} and panel {}",
            fov.len(),
            panel.len()
        )));
    }
    Ok((0..n)
        .map(|i| NominalMount {
            azimuth_deg: az_el[0][i],
            elevation_deg: az_el[1][i],
            panel: panel[i].clone(),
            fov_deg: Some(fov[i]).filter(|f| !f.is_nan()),
        })
        .collect())
}

fn noise_hints(noise: Option<&Bound<'_, PyDict>>) -> PyResult<Option<NoiseHints>> {
    let Some(noise) = noise else { return Ok(None) };
    let mut hints = NoiseHints::default();
    for (key, value) in noise.iter() {
        let key: String = key.extract()?;
        let value: Option<f64> = value.extract()?;
        match key.as_str() {
            "gyro_rad_s" => hints.gyro_rad_s = value,
            "mag_nT" => hints.mag_nt = value,
            "photodiode_V" => hints.photodiode_v = value,
            other => {
                return Err(argument(format!(
                    "noise: unknown key {other:?}, expected gyro_rad_s, mag_nT, photodiode_V"
                )));
            }
        }
    }
    Ok(Some(hints))
}

fn noise_dict<'py>(py: Python<'py>, noise: &NoiseHints) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item("gyro_rad_s", noise.gyro_rad_s)?;
    dict.set_item("mag_nT", noise.mag_nt)?;
    dict.set_item("photodiode_V", noise.photodiode_v)?;
    Ok(dict)
}

/// A 3x3 inertia tensor, kg m^2 (the reader checks it symmetric and physical).
fn inertia(value: &Bound<'_, PyAny>) -> PyResult<Inertia> {
    let cols = matrix(value, "inertia_kg_m2", Some(3))?;
    if cols.iter().any(|c| c.len() != 3) {
        return Err(pyo3::exceptions::PyValueError::new_err(
            "inertia_kg_m2: expected a 3x3 array",
        ));
    }
    let j = nalgebra::Matrix3::from_fn(|r, c| cols[c][r]);
    if (j - j.transpose()).abs().max() > 0.0 {
        return Err(pyo3::exceptions::PyValueError::new_err(
            "inertia_kg_m2: the tensor is not symmetric",
        ));
    }
    Ok(Inertia::from_matrix(&j))
}

/// Named telemetry columns in the writer's order: `t_s`, gyro, magnetometer, photodiodes,
/// positions, temperatures.
struct Columns(Vec<(String, Vec<f64>)>);

impl Columns {
    fn push3(&mut self, names: [&str; 3], value: &Bound<'_, PyAny>, what: &str) -> PyResult<()> {
        let cols = matrix(value, what, Some(3))?;
        self.0
            .extend(names.iter().map(|n| (*n).to_owned()).zip(cols));
        Ok(())
    }
}

fn truth_from_dict(truth: &Bound<'_, PyDict>) -> PyResult<(TruthSeries, TruthConstants)> {
    let get = |key: &str| -> PyResult<Bound<'_, PyAny>> {
        truth
            .get_item(key)?
            .ok_or_else(|| argument(format!("truth: missing key {key:?}")))
    };
    let m3 = |key: &str| -> PyResult<Vec<Vector3<f64>>> {
        Ok(fixed_rows::<3>(&matrix(
            &get(key)?,
            &format!("truth[{key:?}]"),
            Some(3),
        )?))
    };
    let v = |key: &str| -> PyResult<Vec<f64>> { vector(&get(key)?, &format!("truth[{key:?}]")) };
    let q: Vec<Vector4<f64>> =
        fixed_rows::<4>(&matrix(&get("q_xyzw")?, "truth[\"q_xyzw\"]", Some(4))?);
    let series = TruthSeries {
        t_s: v("t_s")?,
        q,
        w_body_rad_s: m3("w_body_rad_s")?,
        gyro_bias_rad_s: m3("gyro_bias_rad_s")?,
        sun_body: m3("sun_body")?,
        eclipse: v("eclipse")?,
        r_gcrf_km: m3("r_gcrf_km")?,
        mag_body_nt: m3("mag_body_nT")?,
    };
    let (scale, az, el) = (v("scale_V")?, v("azimuth_deg")?, v("elevation_deg")?);
    if az.len() != scale.len() || el.len() != scale.len() {
        return Err(argument(
            "truth: scale_V, azimuth_deg and elevation_deg differ in length",
        ));
    }
    let photodiodes = (0..scale.len())
        .map(|i| TruePd {
            scale_v: scale[i],
            azimuth_deg: az[i],
            elevation_deg: el[i],
        })
        .collect();
    let effects = get("effects")?
        .extract::<Vec<String>>()?
        .iter()
        .enumerate()
        .map(|(i, text)| parse_effect(i, text))
        .collect::<PyResult<_>>()?;
    Ok((
        series,
        TruthConstants {
            photodiodes,
            effects,
            magnetometer: None,
        },
    ))
}

fn truth_dict<'py>(
    py: Python<'py>,
    series: &TruthSeries,
    constants: &TruthConstants,
) -> PyResult<Bound<'py, PyDict>> {
    let n = series.len();
    let dict = PyDict::new(py);
    dict.set_item("t_s", from_vec(py, series.t_s.clone()))?;
    dict.set_item("q_xyzw", from_columns(py, &fixed_columns(&series.q), n)?)?;
    let threes = [
        ("w_body_rad_s", &series.w_body_rad_s),
        ("gyro_bias_rad_s", &series.gyro_bias_rad_s),
        ("sun_body", &series.sun_body),
        ("r_gcrf_km", &series.r_gcrf_km),
        ("mag_body_nT", &series.mag_body_nt),
    ];
    for (key, rows) in threes {
        dict.set_item(key, from_columns(py, &fixed_columns(rows), n)?)?;
    }
    dict.set_item("eclipse", from_vec(py, series.eclipse.clone()))?;
    let pds = &constants.photodiodes;
    dict.set_item(
        "scale_V",
        from_vec(py, pds.iter().map(|p| p.scale_v).collect()),
    )?;
    dict.set_item(
        "azimuth_deg",
        from_vec(py, pds.iter().map(|p| p.azimuth_deg).collect()),
    )?;
    dict.set_item(
        "elevation_deg",
        from_vec(py, pds.iter().map(|p| p.elevation_deg).collect()),
    )?;
    let effects = (constants.effects.iter())
        .map(effect_ron)
        .collect::<PyResult<Vec<_>>>()?;
    dict.set_item("effects", PyList::new(py, effects)?)?;
    if let Some(magnetometer) = &constants.magnetometer {
        let json = serde_json::to_string(magnetometer).map_err(py_err)?;
        dict.set_item("magnetometer", json_loads(py, &json)?)?;
    }
    Ok(dict)
}

impl Dataset {
    fn telemetry(&self) -> &Telemetry {
        &self.inner.telemetry
    }

    /// Meta and telemetry with the directory they stand for, as a calibration takes them.
    pub fn set(&self) -> (PathBuf, pdcal_dataset::DatasetMeta, Telemetry) {
        let dir = (self.dir.clone()).unwrap_or_else(|| PathBuf::from(&self.inner.meta.name));
        (dir, self.inner.meta.clone(), self.inner.telemetry.clone())
    }
}

#[pymethods]
impl Dataset {
    /// A dataset from arrays (N rows, M photodiodes); blank cells are NaN. Exactly one of
    /// `tle` (two TLE lines) and `positions_gcrf_km` gives the orbit.
    #[new]
    #[pyo3(
        text_signature = "(*, epoch_utc, t_s, gyro_rad_s, photodiodes_V, nominal_az_el_deg, \
        mag_nT=None, tle=None, positions_gcrf_km=None, fov_deg=None, panel=None, \
        temperatures_C=None, noise=None, name='dataset', truth=None, inertia_kg_m2=None)"
    )]
    #[pyo3(signature = (
        *, epoch_utc, t_s, gyro_rad_s, photodiodes_V, nominal_az_el_deg, mag_nT=None, tle=None,
        positions_gcrf_km=None, fov_deg=None, panel=None, temperatures_C=None, noise=None,
        name="dataset".to_owned(), truth=None, inertia_kg_m2=None
    ))]
    #[allow(non_snake_case, clippy::too_many_arguments)]
    fn new(
        epoch_utc: String,
        t_s: &Bound<'_, PyAny>,
        gyro_rad_s: &Bound<'_, PyAny>,
        photodiodes_V: &Bound<'_, PyAny>,
        nominal_az_el_deg: &Bound<'_, PyAny>,
        mag_nT: Option<&Bound<'_, PyAny>>,
        tle: Option<(String, String)>,
        positions_gcrf_km: Option<&Bound<'_, PyAny>>,
        fov_deg: Option<&Bound<'_, PyAny>>,
        panel: Option<Vec<Option<String>>>,
        temperatures_C: Option<&Bound<'_, PyDict>>,
        noise: Option<&Bound<'_, PyDict>>,
        name: String,
        truth: Option<&Bound<'_, PyDict>>,
        inertia_kg_m2: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let photodiodes = nominal_mounts(Mounts {
            az_el_deg: nominal_az_el_deg,
            fov_deg,
            panel,
        })?;
        let fields = MetaFields {
            name,
            epoch_utc,
            orbit: match tle {
                Some((line1, line2)) => OrbitSpec::Tle { line1, line2 },
                None => OrbitSpec::PositionColumns,
            },
            photodiodes,
            noise: noise_hints(noise)?,
            inertia_kg_m2: inertia_kg_m2.map(inertia).transpose()?,
        };
        let meta = pdcal_dataset::meta_from_fields(&fields).map_err(py_err)?;
        let mut cols = Columns(vec![(columns::T_S.to_owned(), vector(t_s, "t_s")?)]);
        cols.push3(columns::GYRO, gyro_rad_s, "gyro_rad_s")?;
        if let Some(mag) = mag_nT {
            cols.push3(columns::MAG, mag, "mag_nT")?;
        }
        let pd = matrix(photodiodes_V, "photodiodes_V", None)?;
        cols.0.extend((1..).map(photodiode_column).zip(pd));
        if let Some(r) = positions_gcrf_km {
            cols.push3(columns::R, r, "positions_gcrf_km")?;
        }
        for (key, value) in temperatures_C.iter().flat_map(|d| d.iter()) {
            let key: String = key.extract()?;
            let values = vector(&value, &format!("temperatures_C[{key:?}]"))?;
            cols.0.push((key, values));
        }
        let telemetry = pdcal_dataset::telemetry_from_columns(&cols.0, &meta).map_err(py_err)?;
        let inner = pdcal_dataset::Dataset {
            meta,
            telemetry,
            truth: truth.map(truth_from_dict).transpose()?,
        };
        if inner.truth.is_some() {
            // The truth files through the reader too (shapes, finite values, effects).
            pdcal_dataset::render_dataset(&inner).map_err(py_err)?;
        }
        Ok(Dataset { inner, dir: None })
    }

    /// Reads a dataset directory (dataset.ron, telemetry.csv, and truth.* when present).
    #[staticmethod]
    fn read(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let inner = py
            .detach(|| pdcal_dataset::read_dataset(&path))
            .map_err(py_err)?;
        Ok(Dataset {
            inner,
            dir: Some(path),
        })
    }

    /// Writes the dataset directory, whole or not at all (as `pdcal simulate --out`).
    fn write(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| pdcal_dataset::write_dataset(&path, &self.inner))
            .map_err(py_err)
    }

    /// dataset.ron `name`.
    #[getter]
    fn name(&self) -> &str {
        &self.inner.meta.name
    }

    /// dataset.ron `epoch_utc`, as written.
    #[getter]
    fn epoch_utc(&self) -> &str {
        self.inner.meta.epoch_utc.as_str()
    }

    /// The two TLE lines, or None with position columns.
    #[getter]
    fn tle(&self) -> Option<(String, String)> {
        match &self.inner.meta.orbit {
            OrbitSpec::Tle { line1, line2 } => Some((line1.clone(), line2.clone())),
            OrbitSpec::PositionColumns => None,
        }
    }

    /// Rows of telemetry.
    #[getter]
    fn rows(&self) -> usize {
        self.telemetry().len()
    }

    /// Seconds since `epoch_utc`, (N,).
    #[getter]
    fn t_s<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        from_vec(py, self.telemetry().t_s.clone())
    }

    /// Gyro rate, body frame, rad/s, (N, 3).
    #[getter]
    fn gyro_rad_s<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let tm = self.telemetry();
        from_columns(py, &vec3_columns(&tm.gyro_rad_s), tm.len())
    }

    /// Magnetometer, body frame, nT, (N, 3); None without magnetometer columns.
    #[getter]
    #[allow(non_snake_case)]
    fn mag_nT<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, numpy::PyArray2<f64>>>> {
        let tm = self.telemetry();
        (tm.mag_nt.as_ref())
            .map(|m| from_columns(py, &vec3_columns(m), tm.len()))
            .transpose()
    }

    /// Photodiode outputs, V, (N, M).
    #[getter]
    #[allow(non_snake_case)]
    fn photodiodes_V<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let tm = self.telemetry();
        let cols: Vec<Vec<f64>> = (tm.pd_v.iter())
            .map(|s| s.iter().map(|x| x.unwrap_or(f64::NAN)).collect())
            .collect();
        from_columns(py, &cols, tm.len())
    }

    /// Position, GCRF, km, (N, 3); None with a TLE orbit.
    #[getter]
    fn positions_gcrf_km<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Option<Bound<'py, numpy::PyArray2<f64>>>> {
        let tm = self.telemetry();
        (tm.r_gcrf_km.as_ref())
            .map(|r| from_columns(py, &vec3_columns(r), tm.len()))
            .transpose()
    }

    /// The `temp_*_C` columns by header, degrees Celsius, each (N,).
    #[getter]
    #[allow(non_snake_case)]
    fn temperatures_C<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for c in &self.telemetry().temperature_c {
            let values = c.values.iter().map(|x| x.unwrap_or(f64::NAN)).collect();
            dict.set_item(&c.name, from_vec(py, values))?;
        }
        Ok(dict)
    }

    /// Nominal azimuth and elevation per photodiode, body frame, degrees, (M, 2).
    #[getter]
    fn nominal_az_el_deg<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Bound<'py, numpy::PyArray2<f64>>> {
        let pds = &self.inner.meta.photodiodes;
        let cols = vec![
            pds.iter().map(|p| p.azimuth_deg).collect(),
            pds.iter().map(|p| p.elevation_deg).collect(),
        ];
        from_columns(py, &cols, pds.len())
    }

    /// Field-of-view half-angle per photodiode, degrees, (M,); NaN where none is given.
    #[getter]
    fn fov_deg<'py>(&self, py: Python<'py>) -> Bound<'py, numpy::PyArray1<f64>> {
        let pds = &self.inner.meta.photodiodes;
        from_vec(
            py,
            pds.iter().map(|p| p.fov_deg.unwrap_or(f64::NAN)).collect(),
        )
    }

    /// The panel of each photodiode, or None.
    #[getter]
    fn panel(&self) -> Vec<Option<String>> {
        (self.inner.meta.photodiodes.iter())
            .map(|p| p.panel.clone())
            .collect()
    }

    /// The noise hints (`gyro_rad_s`, `mag_nT`, `photodiode_V`, each None when absent), or
    /// None.
    #[getter]
    fn noise<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        (self.inner.meta.noise.as_ref())
            .map(|n| noise_dict(py, n))
            .transpose()
    }

    /// The inertia tensor, body frame, kg m^2, (3, 3), or None.
    #[getter]
    fn inertia_kg_m2<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<Option<Bound<'py, numpy::PyArray2<f64>>>> {
        (self.inner.meta.inertia_kg_m2.as_ref())
            .map(|i| {
                let j = i.matrix();
                let cols: Vec<Vec<f64>> = (0..3)
                    .map(|c| (0..3).map(|r| j[(r, c)]).collect())
                    .collect();
                from_columns(py, &cols, 3)
            })
            .transpose()
    }

    /// The simulated truth (truth.csv and truth.ron) as a dict of arrays, or None: `t_s`,
    /// `q_xyzw` (scalar last, body relative to GCRF), `w_body_rad_s`, `gyro_bias_rad_s`,
    /// `sun_body`, `eclipse`, `r_gcrf_km`, `mag_body_nT`; per photodiode `scale_V`,
    /// `azimuth_deg`, `elevation_deg`; `effects` in truth.ron's spelling; `magnetometer`
    /// (its errors, when simulated: `matrix`, `bias_nT`, `current_bias_nT_per_A`).
    #[getter]
    fn truth<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        (self.inner.truth.as_ref())
            .map(|(s, c)| truth_dict(py, s, c))
            .transpose()
    }

    fn __repr__(&self) -> String {
        format!(
            "pdcal.Dataset({:?}: {} rows, {} photodiodes, epoch {})",
            self.inner.meta.name,
            self.telemetry().len(),
            self.inner.meta.photodiodes.len(),
            self.inner.meta.epoch_utc.as_str()
        )
    }

    /// Equal datasets: every field, bit for bit (NaN blanks equal).
    fn __eq__(&self, other: &Bound<'_, PyAny>) -> bool {
        other
            .cast::<Dataset>()
            .is_ok_and(|o| o.get().inner == self.inner)
    }
}

/// A scenario from `pdcal.scenario()`'s dict: checked as a scenario file is.
fn scenario_from_dict(dict: &Bound<'_, PyDict>) -> PyResult<pdcal_sim::Scenario> {
    let json: String = (dict.py().import("json")?)
        .call_method1("dumps", (dict,))?
        .extract()?;
    let scenario: pdcal_sim::Scenario =
        serde_json::from_str(&json).map_err(|e| argument(format!("scenario: {e}")))?;
    scenario.validate().map_err(py_err)?;
    Ok(scenario)
}

/// The scenario of a `scenario` argument: a built-in name (`"rax2-like"` when None), a
/// scenario RON file, or a dict from `pdcal.scenario`.
pub fn scenario_arg(scenario: Option<&Bound<'_, PyAny>>) -> PyResult<pdcal_sim::Scenario> {
    Ok(match scenario {
        Some(s) if s.is_instance_of::<PyDict>() => scenario_from_dict(s.cast::<PyDict>()?)?,
        Some(s) => {
            let name: PathBuf = s.extract()?;
            pdcal::simulate::load_scenario(&name.to_string_lossy()).map_err(py_err)?
        }
        None => pdcal::simulate::load_scenario("rax2-like").map_err(py_err)?,
    })
}

/// Simulates a scenario (a built-in name, `"rax2-like"` when None, a scenario RON file, or
/// a dict from `pdcal.scenario`) with `seed`; the dataset carries the truth. `downlink`
/// picks one of the seed spacecraft's downlinks: the same hardware, its own noise, start
/// attitude and gyro bias (`pdcal simulate --downlink`).
#[pyfunction]
#[pyo3(signature = (scenario=None, seed=1, downlink=0))]
pub fn simulate(
    py: Python<'_>,
    scenario: Option<&Bound<'_, PyAny>>,
    seed: u64,
    downlink: u64,
) -> PyResult<Dataset> {
    let scenario = scenario_arg(scenario)?;
    let output = py
        .detach(|| pdcal::simulate::run_downlink(&scenario, seed, downlink))
        .map_err(py_err)?;
    Ok(Dataset {
        inner: output.to_dataset(),
        dir: None,
    })
}

/// A built-in scenario, or a scenario RON file, as a dict (edit it, e.g. `duration_s`, and
/// pass it to `simulate`).
#[pyfunction]
#[pyo3(signature = (name="rax2-like"))]
pub fn scenario<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
    let scenario = pdcal::simulate::load_scenario(name).map_err(py_err)?;
    let json = serde_json::to_string(&scenario).map_err(py_err)?;
    json_loads(py, &json)
}

/// The data sets of a calibration: one `Dataset` or a sequence of them.
pub fn datasets(
    value: &Bound<'_, PyAny>,
) -> PyResult<Vec<(PathBuf, pdcal_dataset::DatasetMeta, Telemetry)>> {
    if let Ok(one) = value.cast::<Dataset>() {
        return Ok(vec![one.get().set()]);
    }
    let items: Vec<Bound<'_, PyAny>> = value
        .try_iter()
        .map_err(|_| argument("expected a pdcal.Dataset or a list of them"))?
        .collect::<PyResult<_>>()?;
    items
        .iter()
        .map(|item| {
            item.cast::<Dataset>()
                .map(|d| d.get().set())
                .map_err(|_| argument("expected a pdcal.Dataset or a list of them"))
        })
        .collect()
}
