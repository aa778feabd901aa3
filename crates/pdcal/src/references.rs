//! Reference vectors for every telemetry row, from the dataset's own orbit description.
//!
//! The one place where a dataset's `orbit` (a TLE, or position columns) becomes an
//! `OrbitSource`, so `calibrate`, `diagnose` and xtask see identical references.

use anyhow::{Context, Result, bail};
use pdcal_dataset::{DatasetMeta, OrbitSpec, Telemetry};
use pdcal_ephem::{OrbitSource, PositionColumns, ReferenceModel, TleOrbit};
use pdcal_filter::StepReference;

/// The orbit source the dataset names.
pub fn orbit_source(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
) -> Result<Box<dyn OrbitSource + Send + Sync>> {
    match &meta.orbit {
        OrbitSpec::Tle { line1, line2 } => Ok(Box::new(
            TleOrbit::from_lines(line1, line2).context("dataset.ron orbit")?,
        )),
        OrbitSpec::PositionColumns => {
            let Some(r) = &telemetry.r_gcrf_km else {
                bail!("telemetry.csv: orbit PositionColumns needs r_x_km, r_y_km, r_z_km");
            };
            let (t, pos): (Vec<f64>, Vec<_>) = telemetry
                .t_s
                .iter()
                .zip(r)
                .filter_map(|(t, r)| r.map(|r| (*t, r)))
                .unzip();
            Ok(Box::new(
                PositionColumns::new(meta.epoch_utc.epoch(), t, pos)
                    .context("telemetry.csv position columns")?,
            ))
        }
    }
}

/// One reference per telemetry row.
pub fn step_references(meta: &DatasetMeta, telemetry: &Telemetry) -> Result<Vec<StepReference>> {
    let model = ReferenceModel::new(meta.epoch_utc.epoch(), orbit_source(meta, telemetry)?)?;
    telemetry
        .t_s
        .iter()
        .map(|&t_s| {
            let r = model
                .at(t_s)
                .with_context(|| format!("reference at t_s = {t_s}"))?;
            Ok(StepReference {
                r_gcrf_km: r.r_gcrf_km,
                sun_gcrf_km: r.sun_gcrf_km,
                sun_gcrf_unit: r.sun_gcrf_unit,
                b_gcrf_nt: r.b_gcrf_nt,
                sun_fraction: r.sun_fraction,
                gcrf_to_itrf: r.gcrf_to_itrf,
            })
        })
        .collect()
}
