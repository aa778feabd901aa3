//! `pdcal export-onboard`: a calibration output directory as the onboard core's calibration
//! (`pdcal-onboard`): a C header with a const initializer of `pdcal_calibration` and the
//! reflectivity grid, and `onboard.ron`, the same values with their provenance.
//!
//! Each photodiode's scale and normal come from `calibration.ron`; a quantity whose status
//! in `summary.json` is not `calibrated` is exported at its nominal value (`summary.json`
//! `initial`: the value the calibration started from) and flagged. A photodiode the
//! calibration did not use (never lit, left out for a contradicted mounting) or whose
//! outputs it negated (the core takes positive scales only) is exported disabled. The
//! noise and the field of view are the data set's (`dataset.ron`); the dark offset is the
//! calibration's where it estimated one (`parameters`), else 0.

use std::f64::consts::FRAC_PI_2;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use pdcal_albedo::ReflectivityMap;
use pdcal_dataset::DatasetMeta;
use pdcal_filter::identifiability::{PdIdentifiability, Status};
use pdcal_filter::{Calibration, FilterConfig};
use serde::{Deserialize, Serialize};

use crate::output::{OutputDir, write_file};

/// The C header's file name.
pub const HEADER: &str = "pdcal_calibration.h";
/// The RON copy's file name.
pub const RON: &str = "onboard.ron";
/// Version of `onboard.ron`'s layout.
pub const ONBOARD_FORMAT_VERSION: u32 = 1;
/// The grid resolution when `--grid-deg` is not given, deg: 2 592 bytes.
pub const DEFAULT_GRID_DEG: f64 = 5.0;

/// `onboard.ron`: what the header holds, with where each value came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OnboardCalibration {
    /// [`ONBOARD_FORMAT_VERSION`].
    pub format_version: u32,
    /// Provenance: the calibration, the data set, the pdcal version and the date.
    pub provenance: Provenance,
    /// Per photodiode, `pdNN` order.
    pub photodiodes: Vec<OnboardPhotodiode>,
    /// The reflectivity grid.
    pub grid: OnboardGrid,
}

/// Where an export came from.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The calibration output directory.
    pub calibration_dir: String,
    /// `summary.json` `dataset`: the data set's name.
    pub dataset: String,
    /// The data set directory its noise and fields of view were read from.
    pub dataset_dir: String,
    /// The data set's epoch (dataset.ron `epoch_utc`).
    pub dataset_epoch_utc: String,
    /// The pdcal that wrote the export.
    pub pdcal_version: String,
    /// When, UTC.
    pub exported_utc: String,
    /// The reflectivity map the calibration's albedo model used.
    pub albedo_map: String,
}

/// One photodiode as the core reads it (`pdcal_onboard::Photodiode`), with its statuses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OnboardPhotodiode {
    /// `pdNN`.
    pub name: String,
    /// Scale factor at 1 AU, V.
    pub scale_v: f64,
    /// Unit normal, body frame (paper Eq. 16).
    pub normal_body: [f64; 3],
    /// Dark offset, V.
    pub dark_v: f64,
    /// Field-of-view half-angle, rad.
    pub fov_half_angle_rad: f64,
    /// Output noise, 1-sigma, V.
    pub noise_v: f64,
    /// 1-sigma of `scale_v`, V.
    pub scale_sigma_v: f64,
    /// 1-sigma of the normal's direction, rad.
    pub normal_sigma_rad: f64,
    /// Whether the core uses it.
    pub enabled: bool,
    /// Why not, when disabled.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub disabled_reason: Option<String>,
    /// Status of each parameter: `scale`, `azimuth`, `elevation` as `summary.json` gives
    /// them, `dark` as `calibrated` (estimated) or `not-estimated`.
    pub status: Vec<ParameterStatus>,
}

/// One parameter's status in the export.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParameterStatus {
    /// `scale`, `azimuth`, `elevation` or `dark`.
    pub parameter: String,
    /// `calibrated`, `weakly-determined`, `not-determined` or `not-estimated`.
    pub status: String,
    /// Whether the exported value is the nominal one (the status is not `calibrated`).
    pub nominal: bool,
    /// Why, when not `calibrated`.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub reason: String,
}

/// The reflectivity grid: one byte a cell (`reflectivity = byte / 255`), `n_lat` rows from
/// the south pole by `n_lon` columns from longitude -180 deg.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OnboardGrid {
    /// Cell size, deg.
    pub cell_deg: f64,
    /// Rows.
    pub n_lat: usize,
    /// Columns.
    pub n_lon: usize,
    /// Memory of the cells, bytes.
    pub bytes: usize,
    /// The cells, row-major.
    pub cells: Vec<u8>,
}

impl OnboardCalibration {
    /// The core's calibration in `f32` (the C ABI's precision) or `f64`.
    pub fn core<T: pdcal_onboard::Real, const N: usize>(
        &self,
    ) -> Result<pdcal_onboard::Calibration<T, N>> {
        if self.photodiodes.len() > N.min(pdcal_onboard::MAX_PHOTODIODES) {
            bail!(
                "{} photodiodes: the onboard core takes at most {}",
                self.photodiodes.len(),
                N.min(pdcal_onboard::MAX_PHOTODIODES)
            );
        }
        let mut photodiodes = [pdcal_onboard::Photodiode::cosine(
            T::one(),
            [T::zero(), T::zero(), T::one()],
            T::zero(),
        ); N];
        for (slot, pd) in photodiodes.iter_mut().zip(&self.photodiodes) {
            *slot = pd.core();
        }
        Ok(pdcal_onboard::Calibration {
            count: self.photodiodes.len(),
            photodiodes,
        })
    }

    /// The grid as the core reads it.
    pub fn grid(&self) -> Option<pdcal_onboard::ReflectivityGrid<'_>> {
        pdcal_onboard::ReflectivityGrid::new(self.grid.n_lat, self.grid.n_lon, &self.grid.cells)
    }
}

impl OnboardPhotodiode {
    fn core<T: pdcal_onboard::Real>(&self) -> pdcal_onboard::Photodiode<T> {
        pdcal_onboard::Photodiode {
            scale_v: T::of(self.scale_v),
            normal_body: self.normal_body.map(T::of),
            dark_v: T::of(self.dark_v),
            fov_half_angle_rad: T::of(self.fov_half_angle_rad),
            noise_v: T::of(self.noise_v),
            scale_sigma_v: T::of(self.scale_sigma_v),
            normal_sigma_rad: T::of(self.normal_sigma_rad),
            enabled: self.enabled,
        }
    }
}

/// The part of `summary.json` the export reads.
#[derive(Debug, Deserialize)]
struct SummaryView {
    dataset: String,
    photodiodes: Vec<PdView>,
    #[serde(default)]
    datasets: Vec<SetView>,
    #[serde(default)]
    mounting_findings: Vec<FindingView>,
}

#[derive(Debug, Deserialize)]
struct PdView {
    used: bool,
    determination: PdIdentifiability,
    initial: InitialView,
}

#[derive(Debug, Deserialize)]
#[allow(non_snake_case)]
struct InitialView {
    scale_V: f64,
    azimuth_deg: f64,
    elevation_deg: f64,
}

#[derive(Debug, Deserialize)]
struct SetView {
    dir: String,
}

#[derive(Debug, Deserialize)]
struct FindingView {
    photodiode: usize,
    polarity_reversed: bool,
    action: String,
}

/// A calibration output directory read back: `calibration.ron` and the parts of
/// `summary.json` the export needs.
struct CalibrationDir {
    calibration: Calibration,
    summary: SummaryView,
}

fn read_calibration_dir(dir: &Path) -> Result<CalibrationDir> {
    let cal_path = dir.join("calibration.ron");
    let text =
        pdcal_dataset::bounded::read_text_bounded(&cal_path, pdcal_dataset::bounded::MAX_RON_BYTES)
            .with_context(|| format!("cannot read {}", cal_path.display()))?;
    let calibration =
        Calibration::from_ron_str(&text).with_context(|| format!("{}", cal_path.display()))?;
    let summary_path = dir.join("summary.json");
    let text = std::fs::read_to_string(&summary_path)
        .with_context(|| format!("cannot read {}", summary_path.display()))?;
    let summary: SummaryView = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a pdcal summary.json", summary_path.display()))?;
    if summary.photodiodes.len() != calibration.photodiodes.len() {
        bail!(
            "{}: {} photodiodes, but {} has {}",
            summary_path.display(),
            summary.photodiodes.len(),
            cal_path.display(),
            calibration.photodiodes.len()
        );
    }
    Ok(CalibrationDir {
        calibration,
        summary,
    })
}

/// The data set directory of a calibration: `dataset` when given, else the one
/// `summary.json` lists (a joint calibration lists its sets; the first one's noise and
/// fields of view are taken).
fn dataset_dir(cal: &CalibrationDir, cal_dir: &Path, dataset: Option<&Path>) -> Result<PathBuf> {
    if let Some(d) = dataset {
        return Ok(d.to_path_buf());
    }
    match cal.summary.datasets.first() {
        Some(set) => Ok(PathBuf::from(&set.dir)),
        None => bail!(
            "{}: summary.json does not name its data set directory (a single-set calibration); \
             pass the data set with --dataset DIR",
            cal_dir.display()
        ),
    }
}

/// The export of the calibration in `cal_dir` with the data set `dataset_dir` (its
/// noise and fields of view) and a grid of `grid_deg` cells.
pub fn build(cal_dir: &Path, dataset: Option<&Path>, grid_deg: f64) -> Result<OnboardCalibration> {
    let cal = read_calibration_dir(cal_dir)?;
    let dataset_dir = dataset_dir(&cal, cal_dir, dataset)?;
    let meta = pdcal_dataset::read_meta(&dataset_dir)?;
    build_from(&cal, cal_dir, &dataset_dir, &meta, grid_deg)
}

/// [`build`] with the data set's metadata in memory (`dataset_dir` names it in messages
/// and the provenance).
pub fn build_with_meta(
    cal_dir: &Path,
    dataset_dir: &Path,
    meta: &DatasetMeta,
    grid_deg: f64,
) -> Result<OnboardCalibration> {
    let cal = read_calibration_dir(cal_dir)?;
    build_from(&cal, cal_dir, dataset_dir, meta, grid_deg)
}

fn build_from(
    cal: &CalibrationDir,
    cal_dir: &Path,
    dataset_dir: &Path,
    meta: &DatasetMeta,
    grid_deg: f64,
) -> Result<OnboardCalibration> {
    let m = cal.calibration.photodiodes.len();
    if meta.photodiodes.len() != m {
        bail!(
            "{}: {} photodiodes, but the calibration {} has {m}",
            dataset_dir.join(pdcal_dataset::DATASET_RON).display(),
            meta.photodiodes.len(),
            cal_dir.join("calibration.ron").display()
        );
    }
    if m > pdcal_onboard::MAX_PHOTODIODES {
        bail!(
            "{}: {m} photodiodes; the onboard core takes at most {}",
            cal_dir.join("calibration.ron").display(),
            pdcal_onboard::MAX_PHOTODIODES
        );
    }
    let noise_v = FilterConfig::default()
        .resolve(meta.noise.as_ref())
        .photodiode_v;
    let map = crate::calibrate::ALBEDO_MAP
        .load()
        .context("the albedo map")?;
    let photodiodes = (0..m).map(|i| photodiode(cal, meta, i, noise_v)).collect();
    Ok(OnboardCalibration {
        format_version: ONBOARD_FORMAT_VERSION,
        provenance: Provenance {
            calibration_dir: cal_dir.display().to_string(),
            dataset: cal.summary.dataset.clone(),
            dataset_dir: dataset_dir.display().to_string(),
            dataset_epoch_utc: meta.epoch_utc.as_str().to_owned(),
            pdcal_version: env!("CARGO_PKG_VERSION").to_owned(),
            exported_utc: now_utc(),
            albedo_map: crate::calibrate::ALBEDO_MAP.to_string(),
        },
        photodiodes,
        grid: grid(&map, grid_deg)?,
    })
}

fn now_utc() -> String {
    hifitime::Epoch::now()
        .map(|e| e.to_gregorian_str(hifitime::TimeScale::UTC))
        .unwrap_or_else(|_| "unknown".to_owned())
}

/// Photodiode `i` of the export.
fn photodiode(
    cal: &CalibrationDir,
    meta: &DatasetMeta,
    i: usize,
    noise_v: f64,
) -> OnboardPhotodiode {
    let pd = &cal.calibration.photodiodes[i];
    let view = &cal.summary.photodiodes[i];
    let d = &view.determination;
    let nominal = |s: Status| s != Status::Calibrated;
    // A quantity exported at its nominal value is that far from the calibration's estimate
    // at least: its sigma covers the difference.
    let scale_v = if nominal(d.scale.status) {
        view.initial.scale_V
    } else {
        pd.scale_v
    };
    let scale_sigma_v = pd.scale_sigma_v.hypot(scale_v - pd.scale_v);
    let azimuth_deg = if nominal(d.azimuth.status) {
        view.initial.azimuth_deg
    } else {
        pd.azimuth_deg
    };
    let elevation_deg = if nominal(d.elevation.status) {
        view.initial.elevation_deg
    } else {
        pd.elevation_deg
    };
    let normal =
        pdcal_attitude::normal_from_az_el(azimuth_deg.to_radians(), elevation_deg.to_radians());
    let moved_rad = normal.angle(&pd.n_body());
    let normal_sigma_rad = normal_sigma_rad(pd).hypot(moved_rad);
    let name = format!("pd{:02}", i + 1);
    let dark = cal
        .calibration
        .parameters
        .iter()
        .find(|p| p.name == format!("{name}_dark_offset_V"));
    let mut status: Vec<ParameterStatus> = [
        ("scale", &d.scale),
        ("azimuth", &d.azimuth),
        ("elevation", &d.elevation),
    ]
    .into_iter()
    .map(|(parameter, j)| ParameterStatus {
        parameter: parameter.to_owned(),
        status: j.status.as_str().to_owned(),
        nominal: nominal(j.status),
        reason: j.reason.clone(),
    })
    .collect();
    status.push(ParameterStatus {
        parameter: "dark".to_owned(),
        status: if dark.is_some() {
            "calibrated"
        } else {
            "not-estimated"
        }
        .to_owned(),
        nominal: dark.is_none(),
        reason: String::new(),
    });
    let disabled_reason = disabled_reason(cal, view, i, scale_v);
    OnboardPhotodiode {
        scale_v,
        normal_body: [normal.x, normal.y, normal.z],
        dark_v: dark.map_or(0.0, |p| p.value),
        fov_half_angle_rad: meta.photodiodes[i]
            .fov_half_angle_rad()
            .unwrap_or(FRAC_PI_2),
        noise_v,
        scale_sigma_v,
        normal_sigma_rad,
        enabled: disabled_reason.is_none(),
        disabled_reason,
        status,
        name,
    }
}

/// The 1-sigma of the normal's direction, rad: the larger of its tangent-plane sigmas
/// (the azimuth's shrinks with `cos(elevation)`; undefined at the pole, the elevation's
/// then stands for both).
fn normal_sigma_rad(pd: &pdcal_filter::PdCalibration) -> f64 {
    let el = pd.elevation_sigma_deg;
    let az = pd
        .azimuth_sigma_deg
        .map_or(el, |s| s * pd.elevation_deg.to_radians().cos().abs());
    el.max(az).to_radians()
}

fn disabled_reason(cal: &CalibrationDir, view: &PdView, i: usize, scale_v: f64) -> Option<String> {
    let finding = cal
        .summary
        .mounting_findings
        .iter()
        .find(|f| f.photodiode == i + 1);
    if let Some(f) = finding {
        if f.action == "excluded" {
            return Some("nominal mounting contradicted: left out by the calibration".to_owned());
        }
        if f.polarity_reversed {
            return Some(
                "polarity reversed: the calibration negated its outputs, the core takes them as read"
                    .to_owned(),
            );
        }
    }
    if !view.used {
        return Some("not used by the calibration (never lit)".to_owned());
    }
    if !(scale_v.is_finite() && scale_v > 0.0) {
        return Some(format!("scale factor {scale_v} V is not positive"));
    }
    None
}

/// The map coarsened to `cell_deg` cells, area-weighted, one byte a cell.
pub fn grid(map: &ReflectivityMap, cell_deg: f64) -> Result<OnboardGrid> {
    let n_lat = cells_of(180.0, cell_deg)?;
    let n_lon = cells_of(360.0, cell_deg)?;
    let mut cells = Vec::with_capacity(n_lat * n_lon);
    for row in 0..n_lat {
        for column in 0..n_lon {
            let mean = area_mean(map, (row, n_lat), (column, n_lon));
            cells.push((mean * 255.0).round().clamp(0.0, 255.0) as u8);
        }
    }
    Ok(OnboardGrid {
        cell_deg,
        n_lat,
        n_lon,
        bytes: cells.len(),
        cells,
    })
}

/// Cells of `cell_deg` in `span_deg`, when they divide it and the grid stays within the
/// core's largest (0.1 deg cells).
fn cells_of(span_deg: f64, cell_deg: f64) -> Result<usize> {
    let n = span_deg / cell_deg;
    let whole = n.round();
    if !(cell_deg.is_finite() && (0.1..=90.0).contains(&cell_deg)) || (n - whole).abs() > 1e-9 {
        bail!(
            "--grid-deg {cell_deg}: the cell size must divide 180 deg (10, 5, 2.5, 1.25, 1, ...) \
             and be between 0.1 and 90 deg"
        );
    }
    Ok(whole as usize)
}

/// The area-weighted mean reflectivity of the map over cell `(row, column)` of an
/// `n_lat x n_lon` grid: each map cell weighs its overlap's area (longitude span times the
/// difference of the sines of latitude).
fn area_mean(
    map: &ReflectivityMap,
    (row, n_lat): (usize, usize),
    (column, n_lon): (usize, usize),
) -> f64 {
    let band = |k: usize, n: usize, span: f64, start: f64| {
        (
            start + span * k as f64 / n as f64,
            start + span * (k + 1) as f64 / n as f64,
        )
    };
    let (lat0, lat1) = band(row, n_lat, 180.0, -90.0);
    let (lon0, lon1) = band(column, n_lon, 360.0, -180.0);
    let (mut sum, mut area) = (0.0, 0.0);
    for i in 0..map.n_lat() {
        let (a0, a1) = band(i, map.n_lat(), 180.0, -90.0);
        let (lo, hi) = (a0.max(lat0), a1.min(lat1));
        if hi <= lo {
            continue;
        }
        let lat_weight = hi.to_radians().sin() - lo.to_radians().sin();
        for j in 0..map.n_lon() {
            let (b0, b1) = band(j, map.n_lon(), 360.0, -180.0);
            let lon_weight = b1.min(lon1) - b0.max(lon0);
            if lon_weight <= 0.0 {
                continue;
            }
            let w = lat_weight * lon_weight;
            sum += w * map.get(i, j).unwrap_or(0.0);
            area += w;
        }
    }
    if area > 0.0 { sum / area } else { 0.0 }
}

/// `pdcal export-onboard CAL_DIR --out DIR`: writes the header and `onboard.ron` into
/// `out`, whole or not at all.
pub fn run_to_dir(
    cal_dir: &Path,
    dataset: Option<&Path>,
    grid_deg: f64,
    out: &Path,
    force: bool,
) -> Result<OnboardCalibration> {
    let dir = OutputDir::create_forced(out, "export-onboard", force)?;
    let export = build(cal_dir, dataset, grid_deg)?;
    write_export(dir, &export)?;
    Ok(export)
}

/// Writes the header and `onboard.ron` of `export` into `dir` (created before the
/// computation) and publishes it.
pub fn write_export(dir: OutputDir, export: &OnboardCalibration) -> Result<()> {
    write_file(&dir.file(HEADER), c_header(export).as_bytes())?;
    let ron = ron::ser::to_string_pretty(export, ron::ser::PrettyConfig::default())
        .context("onboard.ron")?;
    write_file(&dir.file(RON), ron.as_bytes())?;
    dir.commit()
}

/// Reads an `onboard.ron` back.
pub fn load(path: &Path) -> Result<OnboardCalibration> {
    let text = pdcal_dataset::bounded::read_text_bounded(path, 16 << 20)
        .with_context(|| format!("cannot read {}", path.display()))?;
    let export: OnboardCalibration =
        ron::from_str(&text).with_context(|| format!("{}", path.display()))?;
    if export.grid.cells.len() != export.grid.n_lat * export.grid.n_lon {
        bail!(
            "{}: the grid has {} cells, not {} x {}",
            path.display(),
            export.grid.cells.len(),
            export.grid.n_lat,
            export.grid.n_lon
        );
    }
    Ok(export)
}

/// A C float literal that reads back as the same `f32`.
fn c_float(x: f64) -> String {
    let f = x as f32;
    if f.is_finite() {
        format!("{f:e}f")
    } else {
        "0.0f".to_owned()
    }
}

/// The C header: the core's types (unless `pdcal_onboard.h` defined them first), the grid
/// cells and a const `pdcal_calibration` initializer, each photodiode commented with its
/// statuses.
pub fn c_header(export: &OnboardCalibration) -> String {
    let p = &export.provenance;
    let g = &export.grid;
    let mut h = String::new();
    let _ = writeln!(
        h,
        "/* {HEADER}: the onboard calibration, written by pdcal export-onboard."
    );
    let _ = writeln!(h, " * Calibration: {}", c_comment(&p.calibration_dir));
    let _ = writeln!(
        h,
        " * Data set: {} ({}), epoch {}",
        c_comment(&p.dataset),
        c_comment(&p.dataset_dir),
        p.dataset_epoch_utc
    );
    let _ = writeln!(
        h,
        " * pdcal {}, exported {}",
        p.pdcal_version, p.exported_utc
    );
    let _ = writeln!(
        h,
        " * Reflectivity grid: {} coarsened to {} deg cells, {} x {} = {} bytes.",
        p.albedo_map, g.cell_deg, g.n_lat, g.n_lon, g.bytes
    );
    let _ = writeln!(
        h,
        " * A parameter marked NOMINAL was not calibrated: it holds its nominal value. */"
    );
    h.push_str(C_PREAMBLE);
    let _ = writeln!(
        h,
        "#define PDCAL_CALIBRATION_COUNT {}u",
        export.photodiodes.len()
    );
    let _ = writeln!(h, "#define PDCAL_GRID_N_LAT {}u", g.n_lat);
    let _ = writeln!(h, "#define PDCAL_GRID_N_LON {}u\n", g.n_lon);
    let _ = writeln!(
        h,
        "/* Reflectivity = byte / 255; rows from the south pole, columns from -180 deg. */"
    );
    let _ = writeln!(
        h,
        "static const uint8_t pdcal_grid_cells[{} * {}] = {{",
        g.n_lat, g.n_lon
    );
    for row in g.cells.chunks(g.n_lon.max(1)) {
        let line: Vec<String> = row.iter().map(u8::to_string).collect();
        let _ = writeln!(h, "    {},", line.join(","));
    }
    h.push_str("};\n\n");
    let _ = writeln!(
        h,
        "static const pdcal_grid pdcal_grid_default = {{ PDCAL_GRID_N_LAT, PDCAL_GRID_N_LON, pdcal_grid_cells }};\n"
    );
    h.push_str("static const pdcal_calibration pdcal_calibration_default = {\n");
    let _ = writeln!(h, "    PDCAL_CALIBRATION_COUNT,");
    h.push_str("    {\n");
    for pd in &export.photodiodes {
        let _ = writeln!(h, "        /* {} */", photodiode_comment(pd));
        let n = pd.normal_body.map(c_float);
        let _ = writeln!(
            h,
            "        {{ {}, {{ {}, {}, {} }}, {}, {}, {}, {}, {}, {} }},",
            c_float(pd.scale_v),
            n[0],
            n[1],
            n[2],
            c_float(pd.dark_v),
            c_float(pd.fov_half_angle_rad),
            c_float(pd.noise_v),
            c_float(pd.scale_sigma_v),
            c_float(pd.normal_sigma_rad),
            if pd.enabled { "true" } else { "false" }
        );
    }
    h.push_str("    }\n};\n\n#endif /* PDCAL_CALIBRATION_H */\n");
    h
}

/// The types of `pdcal_onboard.h` (`pdcal_onboard::ffi`), defined here unless that header
/// was included first, so the header compiles on its own.
const C_PREAMBLE: &str = "\n#ifndef PDCAL_CALIBRATION_H
#define PDCAL_CALIBRATION_H

#include <stdbool.h>
#include <stdint.h>

#ifndef PDCAL_ONBOARD_H
#define PDCAL_MAX_PHOTODIODES 64
typedef struct pdcal_photodiode {
    float scale_v;
    float normal_body[3];
    float dark_v;
    float fov_half_angle_rad;
    float noise_v;
    float scale_sigma_v;
    float normal_sigma_rad;
    bool enabled;
} pdcal_photodiode;
typedef struct pdcal_calibration {
    uint32_t count;
    pdcal_photodiode photodiodes[PDCAL_MAX_PHOTODIODES];
} pdcal_calibration;
typedef struct pdcal_grid {
    uint32_t n_lat;
    uint32_t n_lon;
    const uint8_t *cells;
} pdcal_grid;
#endif

";

/// `pd03 enabled; NOMINAL: scale (not-determined: why)`.
fn photodiode_comment(pd: &OnboardPhotodiode) -> String {
    let mut text = pd.name.clone();
    match &pd.disabled_reason {
        Some(why) => {
            let _ = write!(text, " DISABLED: {}", c_comment_text(why));
        }
        None => text.push_str(" enabled"),
    }
    let flagged: Vec<String> = pd
        .status
        .iter()
        .filter(|s| s.nominal && s.parameter != "dark")
        .map(|s| match s.reason.is_empty() {
            true => format!("{} {}", s.parameter, s.status),
            false => format!(
                "{} {} ({})",
                s.parameter,
                s.status,
                c_comment_text(&s.reason)
            ),
        })
        .collect();
    if !flagged.is_empty() {
        let _ = write!(text, "; NOMINAL: {}", flagged.join("; "));
    }
    let dark = pd.status.iter().find(|s| s.parameter == "dark");
    if dark.is_some_and(|s| s.nominal) {
        text.push_str("; dark offset not estimated (0)");
    }
    text
}

/// User text (a path, a data set's name) inside a C comment: clipped, then
/// [`c_comment_text`].
fn c_comment(text: &str) -> String {
    c_comment_text(&pdcal_text::clip(text))
}

/// Text safe inside a C comment: no `*/`, one line.
fn c_comment_text(text: &str) -> String {
    text.replace("*/", "* /").replace(['\n', '\r'], " ")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 1 x 1.25 deg map (TOMS's layout) of 1 north of 30 N and 0 elsewhere.
    fn north_cap() -> ReflectivityMap {
        let text: String = (0..288)
            .map(|_| {
                // TOMS lines are longitude bands; columns run from the north.
                (0..180)
                    .map(|col| if col < 60 { "100" } else { "0" })
                    .collect::<Vec<_>>()
                    .join(" ")
            })
            .collect::<Vec<_>>()
            .join("\n");
        ReflectivityMap::parse_toms_dat("cap", &text).unwrap()
    }

    #[test]
    fn the_grid_is_the_maps_area_mean_from_the_south_pole() {
        let g = grid(&north_cap(), 10.0).unwrap();
        assert_eq!((g.n_lat, g.n_lon, g.bytes), (18, 36, 648));
        // Rows 0..12 cover -90..30 deg (dark); 12..18 cover 30..90 (white).
        for (row, cells) in g.cells.chunks(36).enumerate() {
            let want = if row >= 12 { 255 } else { 0 };
            assert!(cells.iter().all(|&c| c == want), "row {row}: {cells:?}");
        }
        // A cell straddling the edge takes the white part's share of its area.
        let g = grid(&north_cap(), 45.0).unwrap();
        let sin = |deg: f64| deg.to_radians().sin();
        let lower = (sin(45.0) - sin(30.0)) / sin(45.0);
        assert_eq!(g.cells[3 * 8], 255, "45..90 N: all white");
        assert_eq!(
            g.cells[2 * 8],
            (lower * 255.0).round() as u8,
            "0..45 N by area"
        );
    }

    #[test]
    fn a_cell_size_that_does_not_divide_180_is_refused() {
        let map = north_cap();
        assert!(grid(&map, 7.0).is_err());
        assert!(grid(&map, 0.0).is_err());
        assert!(grid(&map, f64::NAN).is_err());
        assert_eq!(grid(&map, 1.25).unwrap().bytes, 144 * 288);
    }
}
