//! `pdcal._pdcal.sim_calibrate`: one seed of `cargo xtask sim-calibrate` for
//! `pdcal.campaign`, and `pdcal._pdcal.ron_to_json` for its RON descriptions.
//!
//! The seed runs [`pdcal::sim_calibrate::run_seed`], the function xtask runs, so a campaign
//! row and a `results.json` row of the same scenario and seed carry the same numbers.

use std::path::PathBuf;
use std::sync::OnceLock;

use pdcal::calibrate::{AlbedoModelType, RunConfig};
use pdcal::sim_calibrate::{Cut, run_seed};
use pdcal_filter::Mode;
use pyo3::prelude::*;

use crate::dataset::scenario_arg;
use crate::errors::{argument, json_loads, py_err};

/// The filter's albedo model, loaded once per process (every seed of a worker shares it,
/// as xtask's seeds share theirs).
static ALBEDO: OnceLock<AlbedoModelType> = OnceLock::new();

fn albedo() -> anyhow::Result<&'static AlbedoModelType> {
    if let Some(model) = ALBEDO.get() {
        return Ok(model);
    }
    let model = pdcal::calibrate::albedo_model()?;
    Ok(ALBEDO.get_or_init(|| model))
}

/// One seed of the simulate -> calibrate -> evaluate Monte Carlo, as `cargo xtask
/// sim-calibrate` runs it: `scenario` (a built-in name, a RON file or a `pdcal.scenario`
/// dict), the filter `config` (a RON path, None for the defaults), `photodiode_only`,
/// `cut` (`"passes:ON/PERIOD"`) and `sets` (downlinks a month apart, calibrated jointly).
/// Returns the seed's row of xtask's results.json as a dict, plus `photodiodes`: the
/// evaluation's per-photodiode errors. Releases the GIL.
#[pyfunction]
#[pyo3(signature = (scenario=None, seed=1, config=None, photodiode_only=false, cut=None, sets=1))]
pub fn sim_calibrate<'py>(
    py: Python<'py>,
    scenario: Option<&Bound<'py, PyAny>>,
    seed: u64,
    config: Option<PathBuf>,
    photodiode_only: bool,
    cut: Option<String>,
    sets: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let scenario = scenario_arg(scenario)?;
    let mut run_config = match &config {
        Some(path) => pdcal::calibrate::load_config(path).map_err(py_err)?,
        None => RunConfig::default(),
    };
    if photodiode_only {
        run_config.mode = Mode::PhotodiodeOnly;
    }
    let cut: Option<Cut> = cut
        .map(|text| {
            text.parse::<Cut>()
                .map_err(|e| argument(format!("cut: {e:#}")))
        })
        .transpose()?;
    if sets == 0 {
        return Err(argument("sets: at least 1"));
    }
    let run = py
        .detach(|| {
            let albedo = albedo()?;
            run_seed(&scenario, seed, &run_config, albedo, (cut, sets))
        })
        .map_err(py_err)?;
    let mut value = serde_json::to_value(&run.result).map_err(py_err)?;
    value["photodiodes"] = serde_json::to_value(&run.evaluation.photodiodes).map_err(py_err)?;
    json_loads(py, &serde_json::to_string(&value).map_err(py_err)?)
}

/// A RON text as the equivalent JSON text: structs and maps as objects (field names as
/// keys), tuples and lists as arrays. Enum variant names are dropped, so a campaign
/// description spells its choices as fields.
#[pyfunction]
pub fn ron_to_json(text: &str) -> PyResult<String> {
    let value: ron::Value = ron::from_str(text).map_err(|e| argument(format!("RON: {e}")))?;
    serde_json::to_string(&value).map_err(py_err)
}
