//! Reference vectors for every telemetry row, from the dataset's own orbit description.
//!
//! The one place where a dataset's `orbit` (a TLE, or position columns) becomes an
//! `OrbitSource`, so the driver's `calibrate` and `diagnose`, the benchmarks and the tests
//! see identical references.

use pdcal_dataset::{DatasetMeta, OrbitSpec, Telemetry};
use pdcal_ephem::{OrbitSource, PositionColumns, ReferenceModel, TleOrbit};

use crate::{FilterError, StepReference};

/// The orbit source the dataset names: its TLE, or its position columns.
pub fn orbit_source(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
) -> Result<Box<dyn OrbitSource + Send + Sync>, FilterError> {
    let orbit_error = |what| move |source| FilterError::Orbit { what, source };
    match &meta.orbit {
        OrbitSpec::Tle { line1, line2 } => Ok(Box::new(
            TleOrbit::from_lines(line1, line2).map_err(orbit_error("dataset.ron orbit"))?,
        )),
        OrbitSpec::PositionColumns => {
            let r = telemetry
                .r_gcrf_km
                .as_ref()
                .ok_or(FilterError::MissingPositionColumns)?;
            let (t, pos): (Vec<f64>, Vec<_>) = telemetry
                .t_s
                .iter()
                .zip(r)
                .filter_map(|(t, r)| r.map(|r| (*t, r)))
                .unzip();
            Ok(Box::new(
                PositionColumns::new(meta.epoch_utc.epoch(), t, pos)
                    .map_err(orbit_error("telemetry.csv position columns"))?,
            ))
        }
    }
}

/// One reference per telemetry row (orbit, Sun, IGRF-14 field, eclipse, Earth rotation).
pub fn step_references(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
) -> Result<Vec<StepReference>, FilterError> {
    let model = ReferenceModel::new(meta.epoch_utc.epoch(), orbit_source(meta, telemetry)?)
        .map_err(|source| FilterError::Reference {
            index: None,
            t_s: 0.0,
            source,
        })?;
    telemetry
        .t_s
        .iter()
        .enumerate()
        .map(|(index, &t_s)| {
            let r = model.at(t_s).map_err(|source| FilterError::Reference {
                index: Some(index),
                t_s,
                source,
            })?;
            Ok(StepReference::from(&r))
        })
        .collect()
}
