//! `pdcal sun-vector`: the onboard core (`pdcal-onboard`, in `f32` as a flight computer runs
//! it) on every telemetry row, with the calibration of `pdcal export-onboard` and the Earth
//! as the flight software would know it: the direction from the calibration run's attitude
//! estimates (`estimates.csv`) and the data set's orbit, the body-to-Earth-fixed rotation
//! for the reflectivity grid from the same attitude and the Earth's rotation. A row without
//! an attitude estimate runs without the Earth (only outputs above the albedo bound).

use std::path::Path;

use anyhow::{Context, Result, bail};
use nalgebra::{Matrix3, Vector3};
use pdcal_attitude::Quat;
use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_onboard::{AlbedoUse, EarthInput, Options, ReflectivityGrid, SunEstimate, Validity};

use crate::export_onboard::OnboardCalibration;

/// The calibration buffer of the driver: the core's largest.
pub const N: usize = pdcal_onboard::MAX_PHOTODIODES;

/// The columns of the output CSV.
pub const COLUMNS: [&str; 11] = [
    "t_s",
    "sun_x",
    "sun_y",
    "sun_z",
    "sigma_deg",
    "used",
    "valid",
    "validity",
    "n_used",
    "albedo",
    "attitude",
];

/// What the flight software knows at one telemetry row.
#[derive(Debug, Clone)]
pub struct RowInput {
    /// Row time, s.
    pub t_s: f64,
    /// Photodiode outputs, V (NaN where not sampled: the core leaves the channel out).
    pub outputs_v: Vec<f64>,
    /// `(1 AU / r_sun)^2`.
    pub sun_distance_factor: f64,
    /// The Earth seen from the estimated attitude, when the calibration has one here.
    pub earth: Option<EarthGeometry>,
}

/// The Earth in the body frame of an estimated attitude.
#[derive(Debug, Clone, Copy)]
pub struct EarthGeometry {
    /// Unit vector toward the Earth's centre, body frame.
    pub earth_body: [f64; 3],
    /// Orbit radius, km.
    pub orbit_radius_km: f64,
    /// Body to Earth-fixed (ITRF), `v_E = M v_B`.
    pub ecef_from_body: [[f64; 3]; 3],
}

impl EarthGeometry {
    /// From the spacecraft position (GCRF, km), the GCRF -> ITRF rotation and the attitude
    /// (`v_B = A(q) v_GCRF`).
    pub fn new(r_gcrf_km: &Vector3<f64>, gcrf_to_itrf: &Matrix3<f64>, q: &Quat) -> Self {
        let a = q.attitude_matrix();
        let earth_body = a * (-r_gcrf_km.normalize());
        let m = gcrf_to_itrf * a.transpose();
        EarthGeometry {
            earth_body: [earth_body.x, earth_body.y, earth_body.z],
            orbit_radius_km: r_gcrf_km.norm(),
            ecef_from_body: [0, 1, 2].map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]),
        }
    }
}

/// One row's estimate in `f64` for the CSV.
#[derive(Debug, Clone, Copy)]
pub struct RowEstimate {
    /// Unit Sun direction, body frame (zero when none).
    pub sun_body: [f64; 3],
    /// 1-sigma cone, deg.
    pub sigma_deg: f64,
    /// Bit `i`: photodiode `i` used.
    pub used_mask: u64,
    /// Photodiodes used.
    pub n_used: u32,
    /// The core's validity.
    pub validity: Validity,
    /// The albedo model subtracted.
    pub albedo: AlbedoUse,
}

impl<T: pdcal_onboard::Real> From<&SunEstimate<T>> for RowEstimate {
    fn from(e: &SunEstimate<T>) -> Self {
        RowEstimate {
            sun_body: e.sun_body.map(|x| x.to_f64_lossless()),
            sigma_deg: e.cone_sigma_rad.to_f64_lossless().to_degrees(),
            used_mask: e.used_mask,
            n_used: e.n_used,
            validity: e.validity,
            albedo: e.albedo,
        }
    }
}

/// The core on one row in `T`: with the Earth (and `grid`) when `use_earth` and the row
/// has one, else with the albedo bound.
pub fn estimate_row<T: pdcal_onboard::Real>(
    row: &RowInput,
    calibration: &pdcal_onboard::Calibration<T, N>,
    grid: Option<&ReflectivityGrid<'_>>,
    use_earth: bool,
) -> SunEstimate<T> {
    let mut outputs = [T::zero(); N];
    for (o, v) in outputs.iter_mut().zip(&row.outputs_v) {
        *o = T::of(*v);
    }
    let options = Options {
        sun_distance_factor: T::of(row.sun_distance_factor),
        ..Options::default()
    };
    let earth = row.earth.filter(|_| use_earth).map(|e| EarthInput {
        earth_body: e.earth_body.map(T::of),
        orbit_radius_km: T::of(e.orbit_radius_km),
        ecef_from_body: Some(e.ecef_from_body.map(|r| r.map(T::of))),
        grid,
    });
    pdcal_onboard::estimate_sun(&outputs, calibration, earth.as_ref(), &options)
}

/// The attitude estimates of `estimates.csv` in `cal_dir`: `(t_s, q)`, in file order.
pub fn read_attitudes(cal_dir: &Path) -> Result<Vec<(f64, Quat)>> {
    let path = cal_dir.join("estimates.csv");
    let mut reader =
        csv::Reader::from_path(&path).with_context(|| format!("cannot read {}", path.display()))?;
    let header = reader
        .headers()
        .with_context(|| format!("{}: cannot read the header row", path.display()))?
        .clone();
    let columns: Vec<usize> = ["t_s", "q_x", "q_y", "q_z", "q_w"]
        .iter()
        .map(|name| {
            header
                .iter()
                .position(|h| h == *name)
                .with_context(|| format!("{}: missing column {name}", path.display()))
        })
        .collect::<Result<_>>()?;
    let mut out = Vec::new();
    for (line, record) in reader.records().enumerate() {
        let record = record.with_context(|| format!("{}:{}", path.display(), line + 2))?;
        let mut v = [0.0; 5];
        for (x, &c) in v.iter_mut().zip(&columns) {
            let text = record.get(c).unwrap_or("");
            *x = text.parse().map_err(|_| {
                anyhow::anyhow!(
                    "{}:{}:{} ({}): {} is not a number",
                    path.display(),
                    line + 2,
                    c + 1,
                    header.get(c).unwrap_or("?"),
                    pdcal_text::quote(text)
                )
            })?;
        }
        let q = Quat::new_normalized(v[1], v[2], v[3], v[4]).with_context(|| {
            format!(
                "{}:{} (q_x, q_y, q_z, q_w): not a quaternion",
                path.display(),
                line + 2
            )
        })?;
        out.push((v[0], q));
    }
    Ok(out)
}

/// Every telemetry row's inputs: outputs, distance factor and, where `attitudes` has the
/// row's time, the Earth.
pub fn row_inputs(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    attitudes: &[(f64, Quat)],
) -> Result<Vec<RowInput>> {
    let model = pdcal_filter::references::reference_model(meta, telemetry)?;
    let mut by_time: Vec<(f64, Quat)> = attitudes.to_vec();
    by_time.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut rows = Vec::with_capacity(telemetry.len());
    for (k, &t_s) in telemetry.t_s.iter().enumerate() {
        let reference = model
            .at(t_s)
            .with_context(|| format!("the references at row {k} (t = {t_s} s)"))?;
        let q = by_time
            .binary_search_by(|(t, _)| t.total_cmp(&t_s))
            .ok()
            .map(|i| by_time[i].1);
        rows.push(RowInput {
            t_s,
            outputs_v: telemetry
                .pd_v
                .iter()
                .map(|c| c.get(k).unwrap_or(f64::NAN))
                .collect(),
            sun_distance_factor: reference.sun_distance_factor(),
            earth: q.map(|q| EarthGeometry::new(&reference.r_gcrf_km, &reference.gcrf_to_itrf, &q)),
        });
    }
    Ok(rows)
}

/// `pdcal sun-vector DATASET --calibration CAL_DIR --out FILE`: the export of `cal_dir`
/// (grid of `grid_deg` cells), the core in `f32` on every row, the CSV written whole or not
/// at all. Returns the rows' estimates.
pub fn run_to_file(
    dataset: &Path,
    cal_dir: &Path,
    grid_deg: f64,
    out: &Path,
) -> Result<Vec<RowEstimate>> {
    let meta = pdcal_dataset::read_meta(dataset)?;
    let telemetry = pdcal_dataset::read_telemetry(dataset, &meta)?;
    let (csv, estimates) = sun_vector_csv(&meta, &telemetry, dataset, cal_dir, grid_deg)?;
    crate::output::write_file_atomic(out, csv.as_bytes())?;
    Ok(estimates)
}

/// The CSV text of `pdcal sun-vector` and its rows' estimates for a data set in memory
/// (`dataset_dir` names it in messages and the export's provenance).
pub fn sun_vector_csv(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    dataset_dir: &Path,
    cal_dir: &Path,
    grid_deg: f64,
) -> Result<(String, Vec<RowEstimate>)> {
    let export = crate::export_onboard::build_with_meta(cal_dir, dataset_dir, meta, grid_deg)?;
    let attitudes = read_attitudes(cal_dir)?;
    let rows = row_inputs(meta, telemetry, &attitudes)?;
    let estimates = estimate_rows::<f32>(&rows, &export)?;
    Ok((csv_text(&rows, &estimates)?, estimates))
}

/// The core in `T` on every row, with the Earth where the row has one.
pub fn estimate_rows<T: pdcal_onboard::Real>(
    rows: &[RowInput],
    export: &OnboardCalibration,
) -> Result<Vec<RowEstimate>> {
    let calibration = export.core::<T, N>()?;
    let Some(grid) = export.grid() else {
        bail!(
            "the reflectivity grid ({} x {}) is not one the core takes",
            export.grid.n_lat,
            export.grid.n_lon
        );
    };
    Ok(rows
        .iter()
        .map(|row| RowEstimate::from(&estimate_row(row, &calibration, Some(&grid), true)))
        .collect())
}

/// `valid`, `eclipse`, `too-few-lit`, ...: the CSV's `validity`.
pub fn validity_name(v: Validity) -> &'static str {
    match v {
        Validity::Valid => "valid",
        Validity::Eclipse => "eclipse",
        Validity::TooFewLit => "too-few-lit",
        Validity::DegenerateGeometry => "degenerate-geometry",
        Validity::Contradictory => "contradictory",
        Validity::Dim => "dim",
        Validity::InvalidInput => "invalid-input",
    }
}

fn albedo_name(a: AlbedoUse) -> &'static str {
    match a {
        AlbedoUse::Bound => "bound",
        AlbedoUse::Uniform => "uniform",
        AlbedoUse::Grid => "grid",
    }
}

/// `pd01 pd03 ...`: the photodiodes of a used mask.
pub fn used_names(mask: u64) -> String {
    (0..64)
        .filter(|i| mask & (1u64 << i) != 0)
        .map(|i| format!("pd{:02}", i + 1))
        .collect::<Vec<_>>()
        .join(" ")
}

/// The CSV text of [`COLUMNS`].
pub fn csv_text(rows: &[RowInput], estimates: &[RowEstimate]) -> Result<String> {
    let mut writer = csv::Writer::from_writer(Vec::new());
    writer.write_record(COLUMNS)?;
    for (row, e) in rows.iter().zip(estimates) {
        let has_direction = e.sun_body.iter().any(|x| *x != 0.0);
        let num = |x: f64| match has_direction && x.is_finite() {
            true => format!("{x:?}"),
            false => String::new(),
        };
        writer.write_record([
            format!("{:?}", row.t_s),
            num(e.sun_body[0]),
            num(e.sun_body[1]),
            num(e.sun_body[2]),
            num(e.sigma_deg),
            used_names(e.used_mask),
            u8::from(e.validity == Validity::Valid).to_string(),
            validity_name(e.validity).to_owned(),
            e.n_used.to_string(),
            albedo_name(e.albedo).to_owned(),
            match row.earth {
                Some(_) => "estimated",
                None => "none",
            }
            .to_owned(),
        ])?;
    }
    let bytes = writer.into_inner().context("sun-vector CSV")?;
    Ok(String::from_utf8(bytes)?)
}
