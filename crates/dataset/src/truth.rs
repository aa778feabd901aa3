//! truth.csv and truth.ron: what a simulator knows and a spacecraft never does.

use std::path::Path;

use nalgebra::{Vector3, Vector4};
use serde::{Deserialize, Serialize};

use crate::error::{DatasetError, ErrorKind, text_of};
use crate::meta::{DatasetMeta, check_finite};
use crate::ron_text::{from_ron, to_ron};
use crate::table::{CsvRows, push_row, require, require3};
use crate::telemetry::columns::{R, T_S};
use pdcal_effects::Effect;

/// Column names of truth.csv that telemetry.csv does not share.
pub mod truth_columns {
    /// Attitude quaternion, scalar last.
    pub const Q: [&str; 4] = ["q_x", "q_y", "q_z", "q_w"];
    /// True angular velocity, body frame, rad/s.
    pub const W: [&str; 3] = ["w_x_rad_s", "w_y_rad_s", "w_z_rad_s"];
    /// True gyro bias, rad/s.
    pub const GYRO_BIAS: [&str; 3] = [
        "gyro_bias_x_rad_s",
        "gyro_bias_y_rad_s",
        "gyro_bias_z_rad_s",
    ];
    /// True unit sun vector, body frame.
    pub const SUN: [&str; 3] = ["sun_x", "sun_y", "sun_z"];
    /// Illuminated fraction of the solar disc.
    pub const ECLIPSE: &str = "eclipse";
    /// True (reference-model) magnetic field, body frame, nT.
    pub const MAG: [&str; 3] = ["mag_x_nT", "mag_y_nT", "mag_z_nT"];
}

use truth_columns::{ECLIPSE, GYRO_BIAS, MAG, Q, SUN, W};

/// The simulated truth time series (truth.csv), one `Vec` per column, all of one length;
/// every cell has a value.
///
/// # Conventions
/// `q` is scalar last, `[q_x, q_y, q_z, q_w]`, body relative to GCRF (Markley & Crassidis):
/// `v_B = A(q) v_I` with `A(q) = (q_w^2 - |q_v|^2) I + 2 q_v q_v^T - 2 q_w [q_v x]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TruthSeries {
    /// Sample times, s since `epoch_utc`, strictly increasing.
    pub t_s: Vec<f64>,
    /// Attitude quaternion `[x, y, z, w]`, scalar last.
    pub q: Vec<Vector4<f64>>,
    /// True angular velocity, body frame, rad/s.
    pub w_body_rad_s: Vec<Vector3<f64>>,
    /// True gyro bias, rad/s.
    pub gyro_bias_rad_s: Vec<Vector3<f64>>,
    /// True unit sun vector, body frame.
    pub sun_body: Vec<Vector3<f64>>,
    /// Illuminated fraction of the solar disc, 0 (umbra) to 1 (full sun).
    pub eclipse: Vec<f64>,
    /// True position, GCRF, km.
    pub r_gcrf_km: Vec<Vector3<f64>>,
    /// True, noise-free reference magnetic field, body frame, nT.
    pub mag_body_nt: Vec<Vector3<f64>>,
}

impl TruthSeries {
    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// The rows `k` for which `keep(k)` holds, in order.
    pub fn select_rows(&self, keep: impl Fn(usize) -> bool) -> TruthSeries {
        let rows: Vec<usize> = (0..self.len()).filter(|&k| keep(k)).collect();
        fn pick<T: Copy>(rows: &[usize], column: &[T]) -> Vec<T> {
            rows.iter().map(|&k| column[k]).collect()
        }
        TruthSeries {
            t_s: pick(&rows, &self.t_s),
            q: pick(&rows, &self.q),
            w_body_rad_s: pick(&rows, &self.w_body_rad_s),
            gyro_bias_rad_s: pick(&rows, &self.gyro_bias_rad_s),
            sun_body: pick(&rows, &self.sun_body),
            eclipse: pick(&rows, &self.eclipse),
            r_gcrf_km: pick(&rows, &self.r_gcrf_km),
            mag_body_nt: pick(&rows, &self.mag_body_nt),
        }
    }
}

/// The simulated truth constants (truth.ron).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TruthConstants {
    /// True photodiode parameters, `pdNN` order.
    pub photodiodes: Vec<TruePd>,
    /// What the truth contained beyond the base model; each effect at most once.
    pub effects: Vec<Effect>,
    /// The magnetometer's true errors, when the simulator gave it any (docs/magcal.md).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub magnetometer: Option<TrueMagnetometer>,
}

/// The magnetometer's true errors: `m = T B + b + sum_j c_j u_j + noise` in the sensor's
/// axes (docs/magcal.md; the calibration determines `(T T^T)^(1/2)`, not `T`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrueMagnetometer {
    /// `T` by rows: scale, soft iron and non-orthogonality.
    pub matrix: [[f64; 3]; 3],
    /// Hard-iron bias `b`, nT (file name `bias_nT`).
    #[serde(rename = "bias_nT")]
    pub bias_nt: [f64; 3],
    /// `c_j` of each channel that drives the sensor, by column name (`cur_px_A`), nT/A
    /// (file name `current_bias_nT_per_A`).
    #[serde(rename = "current_bias_nT_per_A")]
    pub current_bias_nt_per_a: Vec<(String, [f64; 3])>,
}

/// True parameters of one photodiode.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TruePd {
    /// Scale factor `C`, V (file name `scale_V`).
    #[serde(rename = "scale_V")]
    pub scale_v: f64,
    /// True azimuth, degrees.
    pub azimuth_deg: f64,
    /// True elevation, degrees.
    pub elevation_deg: f64,
}

struct Layout {
    t: usize,
    q: [usize; 4],
    w: [usize; 3],
    bias: [usize; 3],
    sun: [usize; 3],
    eclipse: usize,
    r: [usize; 3],
    mag: [usize; 3],
}

fn layout(rows: &CsvRows<'_>) -> Result<Layout, DatasetError> {
    let all: Vec<&str> = [T_S, ECLIPSE]
        .into_iter()
        .chain(Q)
        .chain(W)
        .chain(GYRO_BIAS)
        .chain(SUN)
        .chain(R)
        .chain(MAG)
        .collect();
    if let Some(col) = rows.header.iter().position(|h| !all.contains(&h.as_str())) {
        let kind = ErrorKind::UnknownColumn {
            name: rows.header[col].clone(),
            hint: String::new(),
        };
        return Err(rows.header_error(col, kind));
    }
    Ok(Layout {
        t: require(rows, T_S, "")?,
        q: [
            require(rows, Q[0], "")?,
            require(rows, Q[1], "")?,
            require(rows, Q[2], "")?,
            require(rows, Q[3], "")?,
        ],
        w: require3(rows, W)?,
        bias: require3(rows, GYRO_BIAS)?,
        sun: require3(rows, SUN)?,
        eclipse: require(rows, ECLIPSE, "")?,
        r: require3(rows, R)?,
        mag: require3(rows, MAG)?,
    })
}

/// How far from 1 a truth quaternion's norm may be: far above what writing its components
/// to six significant digits leaves (about 1e-6); a quaternion of norm 2 or 1e-9 is no
/// attitude, and evaluating against its normalisation would hide a broken writer.
pub const QUATERNION_NORM_TOLERANCE: f64 = 1e-3;

/// Parses and validates truth.csv text (file name `truth.csv` in errors).
pub fn truth_series_from_str(text: &str) -> Result<TruthSeries, DatasetError> {
    parse_truth_series(Path::new(crate::TRUTH_CSV), text)
}

pub(crate) fn parse_truth_series(file: &Path, text: &str) -> Result<TruthSeries, DatasetError> {
    let mut rows = CsvRows::open(file, text)?;
    let lay = layout(&rows)?;
    let mut ts = TruthSeries::default();
    while let Some(line) = rows.next_row()? {
        let t = rows.req(line, lay.t)?;
        rows.increasing(line, lay.t, ts.t_s.last().copied(), t)?;
        ts.t_s.push(t);
        let q = lay.q.map(|c| rows.req(line, c));
        let [x, y, z, w] = q;
        let q = Vector4::new(x?, y?, z?, w?);
        if (q.norm() - 1.0).abs() > QUATERNION_NORM_TOLERANCE {
            let kind = ErrorKind::OutOfRange {
                value: q.norm(),
                rule: format!(
                    "an attitude quaternion has unit norm (within {QUATERNION_NORM_TOLERANCE:e}); \
                     this one's norm is the value"
                ),
            };
            let err = DatasetError::at(file, line, Some(lay.q[0] + 1), kind);
            return Err(err.named("q_x, q_y, q_z, q_w"));
        }
        ts.q.push(q);
        ts.w_body_rad_s.push(rows.vec3_req(line, lay.w)?);
        ts.gyro_bias_rad_s.push(rows.vec3_req(line, lay.bias)?);
        ts.sun_body.push(rows.vec3_req(line, lay.sun)?);
        let eclipse = rows.req(line, lay.eclipse)?;
        if !(0.0..=1.0).contains(&eclipse) {
            let kind = ErrorKind::OutOfRange {
                value: eclipse,
                rule: "eclipse is a fraction from 0 to 1".into(),
            };
            let err = DatasetError::at(file, line, Some(lay.eclipse + 1), kind);
            return Err(err.named(ECLIPSE));
        }
        ts.eclipse.push(eclipse);
        ts.r_gcrf_km.push(rows.vec3_req(line, lay.r)?);
        ts.mag_body_nt.push(rows.vec3_req(line, lay.mag)?);
    }
    if ts.is_empty() {
        return Err(rows.no_rows());
    }
    Ok(ts)
}

/// Parses and validates truth.ron text against its dataset.ron (file name `truth.ron` in
/// errors).
pub fn truth_constants_from_str(
    text: &str,
    meta: &DatasetMeta,
) -> Result<TruthConstants, DatasetError> {
    parse_truth_constants(Path::new(crate::TRUTH_RON), text, meta)
}

pub(crate) fn parse_truth_constants(
    file: &Path,
    text: &str,
    meta: &DatasetMeta,
) -> Result<TruthConstants, DatasetError> {
    let text = text_of(file, text.as_bytes().to_vec())?;
    let tc: TruthConstants = from_ron(file, &text)?;
    check_constants(file, &tc, meta)?;
    Ok(tc)
}

fn check_constants(
    file: &Path,
    tc: &TruthConstants,
    meta: &DatasetMeta,
) -> Result<(), DatasetError> {
    let n = meta.photodiodes.len();
    if tc.photodiodes.len() != n {
        let kind = ErrorKind::PhotodiodeCountMismatch {
            in_meta: n,
            what: "truth.ron's photodiodes number".into(),
            found: tc.photodiodes.len(),
        };
        return Err(DatasetError::whole_file(file, kind).named("photodiodes"));
    }
    for (i, pd) in tc.photodiodes.iter().enumerate() {
        let fields = [
            ("scale_V", pd.scale_v),
            ("azimuth_deg", pd.azimuth_deg),
            ("elevation_deg", pd.elevation_deg),
        ];
        for (name, v) in fields {
            check_finite(file, v, || format!("photodiodes[{i}].{name}"))?;
        }
    }
    for (i, effect) in tc.effects.iter().enumerate() {
        if tc.effects[..i].iter().any(|e| e.id() == effect.id()) {
            let kind = ErrorKind::DuplicateEffect {
                id: effect.id().to_string(),
            };
            return Err(DatasetError::whole_file(file, kind).named(format!("effects[{i}]")));
        }
        check_effect(file, i, effect, n)?;
    }
    Ok(())
}

/// The catalogue's checks of one effect, as the reader's error kinds.
fn check_effect(file: &Path, i: usize, effect: &Effect, n: usize) -> Result<(), DatasetError> {
    let record = pdcal_effects::record::EffectRecord::from(effect.clone());
    for (name, v) in record.numbers() {
        check_finite(file, v, || format!("effects[{i}].{name}"))?;
    }
    if let Some((name, values)) = effect.per_photodiode()
        && values.len() != n
    {
        let kind = ErrorKind::WrongLength {
            expected: n,
            found: values.len(),
        };
        return Err(DatasetError::whole_file(file, kind).named(format!("effects[{i}].{name}")));
    }
    effect.check(n).map_err(|bad| {
        let kind = ErrorKind::OutOfRange {
            value: bad.value,
            rule: bad.rule,
        };
        DatasetError::whole_file(file, kind).named(format!("effects[{i}].{}", bad.field))
    })
}

/// Checks that every truth.csv column has one entry per row.
pub(crate) fn check_shape(ts: &TruthSeries) -> Result<(), DatasetError> {
    let lengths = [
        ("q", ts.q.len()),
        ("w_body_rad_s", ts.w_body_rad_s.len()),
        ("gyro_bias_rad_s", ts.gyro_bias_rad_s.len()),
        ("sun_body", ts.sun_body.len()),
        ("eclipse", ts.eclipse.len()),
        ("r_gcrf_km", ts.r_gcrf_km.len()),
        ("mag_body_nt", ts.mag_body_nt.len()),
    ];
    for (name, len) in lengths {
        if len != ts.len() {
            let kind = ErrorKind::WrongLength {
                expected: ts.len(),
                found: len,
            };
            return Err(DatasetError::whole_file(Path::new(crate::TRUTH_CSV), kind).named(name));
        }
    }
    Ok(())
}

/// truth.csv text in the contract's column order. Call [`check_shape`] first.
pub(crate) fn render_truth_series(ts: &TruthSeries) -> String {
    let header: Vec<&str> = [T_S]
        .into_iter()
        .chain(Q)
        .chain(W)
        .chain(GYRO_BIAS)
        .chain(SUN)
        .chain([ECLIPSE])
        .chain(R)
        .chain(MAG)
        .collect();
    let mut out = header.join(",");
    out.push('\n');
    let v3 = |v: Option<&Vector3<f64>>| v.map_or([None; 3], |v| [Some(v.x), Some(v.y), Some(v.z)]);
    for k in 0..ts.len() {
        let mut cells = vec![ts.t_s.get(k).copied()];
        cells.extend(
            ts.q.get(k)
                .map_or([None; 4], |q| [Some(q.x), Some(q.y), Some(q.z), Some(q.w)]),
        );
        cells.extend(v3(ts.w_body_rad_s.get(k)));
        cells.extend(v3(ts.gyro_bias_rad_s.get(k)));
        cells.extend(v3(ts.sun_body.get(k)));
        cells.push(ts.eclipse.get(k).copied());
        cells.extend(v3(ts.r_gcrf_km.get(k)));
        cells.extend(v3(ts.mag_body_nt.get(k)));
        push_row(&mut out, cells);
    }
    out
}

/// truth.ron text.
pub(crate) fn render_truth_constants(tc: &TruthConstants) -> Result<String, DatasetError> {
    to_ron(Path::new(crate::TRUTH_RON), tc)
}
