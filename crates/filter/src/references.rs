//! Reference vectors for every telemetry row, from the dataset's own orbit description.
//!
//! The one place where a dataset's `orbit` (a TLE, or position columns) becomes an
//! `OrbitSource`, so the driver's `calibrate` and `diagnose`, the benchmarks and the tests
//! see identical references. A run reads them through [`References`]: stored, one per row
//! ([`step_references`]), or computed when a row is reached ([`reference_model`]), which
//! gives the same values and keeps a long run's memory from growing with its rows.

use pdcal_dataset::{DatasetMeta, OrbitSpec, Telemetry};
use pdcal_ephem::{OrbitSource, PositionColumns, Reference, ReferenceModel, TleOrbit};

use crate::FilterError;

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

/// The reference model of the dataset (its epoch and orbit), for [`References::Computed`].
pub fn reference_model(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
) -> Result<ReferenceModel, FilterError> {
    ReferenceModel::new(meta.epoch_utc.epoch(), orbit_source(meta, telemetry)?).map_err(|source| {
        FilterError::Reference {
            index: None,
            t_s: 0.0,
            source,
        }
    })
}

/// Row `index`'s reference at time `t_s` from `model`.
fn reference_at(model: &ReferenceModel, index: usize, t_s: f64) -> Result<Reference, FilterError> {
    model.at(t_s).map_err(|source| FilterError::Reference {
        index: Some(index),
        t_s,
        source,
    })
}

/// One reference per telemetry row (orbit, Sun, IGRF-14 field, eclipse, Earth rotation).
pub fn step_references(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
) -> Result<Vec<Reference>, FilterError> {
    let model = reference_model(meta, telemetry)?;
    (telemetry.t_s.iter().enumerate())
        .map(|(index, &t_s)| reference_at(&model, index, t_s))
        .collect()
}

/// The reference of every telemetry row, as a run reads them.
#[derive(Clone, Copy)]
pub enum References<'a> {
    /// Computed before the run, one per row ([`step_references`]).
    Stored(&'a [Reference]),
    /// Computed from `model` when a row is reached, at the rows' times `t_s`: the same
    /// values as [`References::Stored`] without memory per row, for a row read more than
    /// once (the smoother's replays) at the cost of computing it again.
    Computed {
        /// The dataset's reference model ([`reference_model`]).
        model: &'a ReferenceModel,
        /// The telemetry's times, s.
        t_s: &'a [f64],
    },
}

impl<'a> From<&'a [Reference]> for References<'a> {
    fn from(stored: &'a [Reference]) -> Self {
        References::Stored(stored)
    }
}

impl<'a> From<&'a Vec<Reference>> for References<'a> {
    fn from(stored: &'a Vec<Reference>) -> Self {
        References::Stored(stored)
    }
}

impl References<'_> {
    /// Number of rows.
    pub fn len(&self) -> usize {
        match self {
            References::Stored(stored) => stored.len(),
            References::Computed { t_s, .. } => t_s.len(),
        }
    }

    /// True without rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Row `index`'s reference; an error past the last row or where the model fails.
    pub fn at(&self, index: usize) -> Result<Reference, FilterError> {
        let past_end = || FilterError::LengthMismatch {
            what: "references",
            expected: index + 1,
            found: self.len(),
        };
        match self {
            References::Stored(stored) => stored.get(index).copied().ok_or_else(past_end),
            References::Computed { model, t_s } => {
                let &t = t_s.get(index).ok_or_else(past_end)?;
                reference_at(model, index, t)
            }
        }
    }
}

/// The albedo `model`'s view from `reference`'s position and Sun into `view`; errors name
/// the telemetry row `index`.
pub(crate) fn albedo_into(
    reference: &Reference,
    model: &pdcal_albedo::AlbedoModel,
    view: &mut pdcal_albedo::AlbedoView,
    index: usize,
) -> Result<(), FilterError> {
    model
        .compute_into(
            view,
            &reference.r_gcrf_km,
            &reference.sun_gcrf_km,
            &reference.gcrf_to_itrf,
        )
        .map_err(|e| FilterError::Albedo {
            index,
            message: e.to_string(),
        })
}
