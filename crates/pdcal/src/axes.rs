//! The sensor-axes check before a calibration (`pdcal_axes`): a gyro or magnetometer axis
//! recorded in the wrong order or sign, or the photodiode table in another frame, is a
//! finding, applied to the data (the run calibrates on the corrected data), reported in
//! the warnings and `summary.json` `sensor_axes` with the import-map change that fixes the
//! export at its source; what the data could not decide is a note of the consistency
//! verdict.

use std::borrow::Cow;

use anyhow::Result;
use nalgebra::{Matrix3, Vector3};
use pdcal_attitude::{az_el_from_normal, normal_from_az_el};
use pdcal_axes::{AxesCheck, Finding, Inputs, Sensor, Thresholds};
use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_filter::{FilterConfig, References};
use serde::Serialize;

/// One entry of `summary.json` `sensor_axes`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SensorAxesEntry {
    /// `gyro`, `magnetometer` or `photodiodes`.
    pub sensor: &'static str,
    /// `v_body = M v_sensor`.
    pub body_from_sensor: [[i8; 3]; 3],
    /// What the finding rests on.
    pub evidence: pdcal_axes::Evidence,
    /// Whether the data were corrected with it before calibrating (always, today).
    pub applied: bool,
}

/// The check on `meta` and `telemetry` (before any mounting correction), run on each data
/// set of a joint run alone (`set_rows`: each set's first row and row count; empty: one
/// set): each downlink has its own turn-on bias, which one fit over all of them would not
/// describe. A finding needs every set that could check to find the same matrix; a set that
/// finds none or another leaves the sensor undecided.
pub fn check(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    references: &References<'_>,
    config: &FilterConfig,
    set_rows: &[(usize, usize)],
) -> Result<AxesCheck> {
    let rows = telemetry.len();
    let mut refs = Vec::with_capacity(rows);
    let mut radius_km = Vec::with_capacity(rows);
    for k in 0..rows {
        let r = references.at(k)?;
        refs.push((r.sun_gcrf_unit, r.b_gcrf_nt));
        radius_km.push(r.r_gcrf_km.norm());
    }
    let gyro: Vec<Option<Vector3<f64>>> = (0..rows).map(|k| telemetry.gyro_rad_s.get(k)).collect();
    let mag: Vec<Option<Vector3<f64>>> = match &telemetry.mag_nt {
        Some(m) => (0..rows).map(|k| m.get(k)).collect(),
        None => Vec::new(),
    };
    let outputs: Vec<Vec<Option<f64>>> = telemetry
        .pd_v
        .iter()
        .map(|column| (0..rows).map(|k| column.get(k)).collect())
        .collect();
    let normals: Vec<Vector3<f64>> = meta
        .photodiodes
        .iter()
        .map(|m| normal_from_az_el(m.azimuth_deg.to_radians(), m.elevation_deg.to_radians()))
        .collect();
    let sigmas = config.resolve(meta.noise.as_ref());
    let sun = pdcal_axes::photodiode_sun(&outputs, &normals, sigmas.photodiode_v, &radius_km);
    let whole = [(0, rows)];
    let spans = if set_rows.len() > 1 {
        set_rows
    } else {
        &whole[..]
    };
    let results: Vec<AxesCheck> = spans
        .iter()
        .map(|&(first, n)| {
            let r = first.min(rows)..(first + n).min(rows);
            let inputs = Inputs {
                t_s: &telemetry.t_s[r.clone()],
                gyro_rad_s: &gyro[r.clone()],
                mag: if mag.is_empty() { &[] } else { &mag[r.clone()] },
                sun_photodiodes: &sun[r.clone()],
                references: &refs[r],
                gyro_bias_sigma_rad_s: config.initial_bias_sigma_deg_s.to_radians(),
            };
            pdcal_axes::check(&inputs, &Thresholds::default())
        })
        .collect();
    Ok(combine(results))
}

/// One result of the sets' own: their common finding, or none when a set that checked
/// disagrees (its notes kept, named by set).
fn combine(mut results: Vec<AxesCheck>) -> AxesCheck {
    if results.len() == 1 {
        return results.pop().unwrap_or_default();
    }
    let checked: Vec<&AxesCheck> = results.iter().filter(|r| !r.checks.is_empty()).collect();
    let first = checked.first().and_then(|r| r.finding.clone());
    let agree = first.as_ref().is_some_and(|f| {
        checked.iter().all(|r| {
            r.finding
                .as_ref()
                .is_some_and(|g| g.sensor == f.sensor && g.body_from_sensor == f.body_from_sensor)
        })
    });
    let mut out = AxesCheck {
        checks: results.iter().flat_map(|r| r.checks.clone()).collect(),
        stated_margin_nats: results
            .iter()
            .filter_map(|r| r.stated_margin_nats)
            .reduce(f64::min),
        ..AxesCheck::default()
    };
    for (k, r) in results.iter().enumerate() {
        for n in &r.not_checked {
            out.not_checked.push(pdcal_axes::NotChecked {
                sensor: n.sensor,
                reason: format!("set {}: {}", k + 1, n.reason),
            });
        }
    }
    if agree {
        out.finding = first;
    } else if let Some(f) = results.iter().find_map(|r| r.finding.as_ref()) {
        out.not_checked.push(pdcal_axes::NotChecked {
            sensor: f.sensor,
            reason: "the data sets do not agree on its axes (one set's finding is not every \
                     set's)"
                .to_owned(),
        });
    }
    out
}

/// Applies a finding to the data: a gyro's or magnetometer's samples are turned into the
/// body frame (`v_body = M v_sensor`), a photodiode table's normals likewise.
pub fn apply(result: &AxesCheck, meta: &mut DatasetMeta, telemetry: &mut Telemetry) {
    if let Some(finding) = &result.finding {
        transform(finding.sensor, &finding.matrix(), meta, telemetry);
    }
}

/// Turns `sensor`'s vectors in the data by `m` (`v -> m v`): [`apply`] with a finding's
/// matrix; with its transpose, the data as a sensor of those axes records them.
pub fn transform(
    sensor: Sensor,
    m: &Matrix3<f64>,
    meta: &mut DatasetMeta,
    telemetry: &mut Telemetry,
) {
    match sensor {
        Sensor::Gyro => telemetry.gyro_rad_s.map_in_place(|v| m * v),
        Sensor::Magnetometer => {
            if let Some(mag) = telemetry.mag_nt.as_mut() {
                mag.map_in_place(|v| m * v);
            }
        }
        Sensor::Photodiodes => {
            for mount in &mut meta.photodiodes {
                let n = m * normal_from_az_el(
                    mount.azimuth_deg.to_radians(),
                    mount.elevation_deg.to_radians(),
                );
                let (az, el) = az_el_from_normal(&n);
                mount.azimuth_deg = az.to_degrees();
                mount.elevation_deg = el.to_degrees();
            }
        }
    }
}

/// `meta` and `telemetry` with the finding applied ([`apply`]): borrowed as they are when
/// there is none, copied and corrected otherwise.
pub fn corrected<'a>(
    result: &AxesCheck,
    meta: &'a DatasetMeta,
    telemetry: &'a Telemetry,
) -> (Cow<'a, DatasetMeta>, Cow<'a, Telemetry>) {
    if result.finding.is_none() {
        return (Cow::Borrowed(meta), Cow::Borrowed(telemetry));
    }
    let (mut meta, mut telemetry) = (meta.clone(), telemetry.clone());
    apply(result, &mut meta, &mut telemetry);
    (Cow::Owned(meta), Cow::Owned(telemetry))
}

/// `summary.json` `sensor_axes`: one entry per finding, applied.
pub fn entries(result: &AxesCheck) -> Vec<SensorAxesEntry> {
    entries_applied(result, true)
}

/// One entry per finding, `applied` as given.
pub fn entries_applied(result: &AxesCheck, applied: bool) -> Vec<SensorAxesEntry> {
    result
        .finding
        .iter()
        .map(|f| SensorAxesEntry {
            sensor: f.sensor.as_str(),
            body_from_sensor: f.body_from_sensor,
            evidence: f.evidence.clone(),
            applied,
        })
        .collect()
}

/// The warning of a finding: what was found, on what evidence, that it was applied, and the
/// import-map change that fixes the export at its source.
pub fn message(finding: &Finding) -> String {
    let e = &finding.evidence;
    let twins = if e.twins.is_empty() {
        String::new()
    } else {
        format!(
            "; {} other matrix(es) fit as well but for the gyro bias, which its prior ranks \
             below this one",
            e.twins.len()
        )
    };
    format!(
        "sensor axes: the {} reads in axes other than the body's: v_body = {} v_{} \
         ({:.0} nats over the stated axes, {:.0} over the next hypothesis{twins}); the data \
         were corrected with it before calibrating. Fix the export at its source: {}",
        finding.sensor.as_str(),
        matrix_text(&finding.matrix()),
        finding.sensor.as_str(),
        e.log_odds_nats,
        e.runner_up_nats,
        fix_text(finding)
    )
}

/// The warning of a finding `magcal` reports without applying it.
pub fn message_not_applied(finding: &Finding) -> String {
    message(finding).replace(
        "the data were corrected with it before calibrating",
        "not applied by magcal (its magnitude fit does not depend on the axes; calibrate \
         finds and applies them)",
    )
}

/// The notes of what the check could not decide, for the consistency verdict.
pub fn notes(result: &AxesCheck) -> Vec<String> {
    result
        .not_checked
        .iter()
        .map(|n| format!("{} axes not checked: {}", n.sensor.as_str(), n.reason))
        .collect()
}

fn matrix_text(m: &Matrix3<f64>) -> String {
    let rows: Vec<String> = (0..3)
        .map(|r| {
            let cells: Vec<String> = (0..3).map(|c| format!("{:.0}", m[(r, c)])).collect();
            format!("[{}]", cells.join(", "))
        })
        .collect();
    format!("[{}]", rows.join(", "))
}

/// The import map's change: each body axis reads the export column of the sensor axis the
/// finding maps to it, with its gain's sign reversed where the matrix says -1.
fn fix_text(finding: &Finding) -> String {
    const AXES: [&str; 3] = ["x", "y", "z"];
    let m = finding.body_from_sensor;
    match finding.sensor {
        Sensor::Photodiodes => format!(
            "the photodiode table is in another frame; write each nominal normal n as {} n \
             (dataset.ron's azimuths and elevations, or the import map's `photodiodes`)",
            matrix_text(&finding.matrix())
        ),
        sensor => {
            let section = if sensor == Sensor::Gyro {
                "gyro"
            } else {
                "magnetometer"
            };
            let parts: Vec<String> = (0..3)
                .filter_map(|r| {
                    let c = (0..3).find(|&c| m[r][c] != 0)?;
                    let same = c == r && m[r][c] > 0;
                    (!same).then(|| match (c == r, m[r][c] < 0) {
                        (true, _) => format!("{section}.{}: negate its gain", AXES[r]),
                        (false, negated) => format!(
                            "{section}.{} reads the column {section}.{} read{}",
                            AXES[r],
                            AXES[c],
                            if negated { ", its gain negated" } else { "" }
                        ),
                    })
                })
                .collect();
            format!("in the import map, {}", parts.join("; "))
        }
    }
}
