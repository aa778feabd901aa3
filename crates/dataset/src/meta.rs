//! dataset.ron: epoch, orbit source, nominal photodiode layout, noise hints.

use std::path::Path;

use hifitime::Epoch;
use serde::{Deserialize, Serialize};

use crate::error::{DatasetError, ErrorKind, text_of};
use crate::ron_text::{from_ron, locate_key, locate_str, to_ron};

/// The only `format_version` this crate reads and writes.
pub const FORMAT_VERSION: u32 = 1;

/// The contents of dataset.ron, validated.
///
/// Fields mirror the file one to one (see `dataset-format.md`); angles stay in degrees here
/// because this is the I/O edge.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DatasetMeta {
    /// Always [`FORMAT_VERSION`] once read.
    pub format_version: u32,
    /// Free-text name of the data set (`rax2-like-set1`).
    pub name: String,
    /// Epoch that `t_s` counts from.
    pub epoch_utc: EpochUtc,
    /// Where the orbit comes from.
    pub orbit: OrbitSpec,
    /// Intended mounting of each photodiode, in `pdNN` order.
    pub photodiodes: Vec<NominalMount>,
    /// Optional 1-sigma noise hints for filter tuning.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise: Option<NoiseHints>,
}

/// dataset.ron as parsed, before the epoch text is checked.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMeta {
    format_version: u32,
    name: String,
    epoch_utc: String,
    orbit: OrbitSpec,
    photodiodes: Vec<NominalMount>,
    #[serde(default)]
    noise: Option<NoiseHints>,
}

/// Where the orbit comes from.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum OrbitSpec {
    /// A two-line element set; both lines carry valid checksums once read.
    Tle {
        /// Line 1, 69 characters.
        line1: String,
        /// Line 2, 69 characters.
        line2: String,
    },
    /// telemetry.csv carries `r_x_km`, `r_y_km`, `r_z_km` (GCRF).
    PositionColumns,
}

/// Intended (nominal) mounting of one photodiode, body frame, degrees.
///
/// The normal is `n = [cos(el)cos(az), cos(el)sin(az), sin(el)]`, paper Eq. (16).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NominalMount {
    /// Azimuth, degrees.
    pub azimuth_deg: f64,
    /// Elevation, degrees.
    pub elevation_deg: f64,
    /// The panel the photodiode sits on, whose `temp_<panel>_C` column gives its temperature
    /// when it has no `temp_pdNN_C` of its own ([`crate::is_panel_name`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub panel: Option<String>,
}

/// Optional 1-sigma noise hints for filter tuning; each may be absent.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoiseHints {
    /// Gyro white noise per sample, rad/s.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gyro_rad_s: Option<f64>,
    /// Magnetometer noise per axis, nT (file name `mag_nT`).
    #[serde(rename = "mag_nT", default, skip_serializing_if = "Option::is_none")]
    pub mag_nt: Option<f64>,
    /// Photodiode output noise, V (file name `photodiode_V`).
    #[serde(
        rename = "photodiode_V",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub photodiode_v: Option<f64>,
}

/// A UTC epoch kept as both the file's text (written back unchanged) and a [`hifitime::Epoch`].
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(into = "String")]
pub struct EpochUtc {
    text: String,
    epoch: Epoch,
}

impl EpochUtc {
    /// Parses `YYYY-MM-DDTHH:MM:SS[.fraction][Z| UTC]` (a space may replace the `T`); the
    /// time is UTC, so offsets like `+02:00` are refused.
    ///
    /// Hand-parsed rather than `Epoch::from_str` because hifitime also accepts other time
    /// scales and unwraps internally on some malformed text, and this reader must never panic.
    pub fn parse(text: &str) -> Result<Self, ErrorKind> {
        let bad = |reason: &str| ErrorKind::BadEpoch {
            value: text.to_owned(),
            reason: reason.to_owned(),
        };
        let fields = split_iso(text).ok_or_else(|| bad("expected YYYY-MM-DDTHH:MM:SS[.f]Z"))?;
        let [year, month, day, hour, minute, second] = fields.0;
        let epoch = Epoch::maybe_from_gregorian_utc(
            year as i32,
            month as u8,
            day as u8,
            hour as u8,
            minute as u8,
            second as u8,
            fields.1,
        )
        .map_err(|e| bad(&e.to_string()))?;
        Ok(Self {
            text: text.to_owned(),
            epoch,
        })
    }

    /// The epoch.
    pub fn epoch(&self) -> Epoch {
        self.epoch
    }

    /// The text as written in dataset.ron.
    pub fn as_str(&self) -> &str {
        &self.text
    }
}

impl From<EpochUtc> for String {
    fn from(value: EpochUtc) -> Self {
        value.text
    }
}

/// Splits strict ISO 8601 text into (year, month, day, hour, minute, second) and nanoseconds.
/// Every number is bounded by its digit count, so the casts in [`EpochUtc::parse`] are exact.
fn split_iso(text: &str) -> Option<([u32; 6], u32)> {
    let body = text
        .strip_suffix('Z')
        .or_else(|| text.strip_suffix(" UTC"))
        .unwrap_or(text);
    let b = body.as_bytes();
    let shape_ok = b.len() >= 19
        && b[4] == b'-'
        && b[7] == b'-'
        && (b[10] == b'T' || b[10] == b' ')
        && b[13] == b':'
        && b[16] == b':';
    if !shape_ok {
        return None;
    }
    let number = |range: std::ops::Range<usize>| -> Option<u32> {
        let digits = body.get(range)?;
        digits
            .bytes()
            .all(|c| c.is_ascii_digit())
            .then(|| digits.parse().ok())?
    };
    let fields = [
        number(0..4)?,
        number(5..7)?,
        number(8..10)?,
        number(11..13)?,
        number(14..16)?,
        number(17..19)?,
    ];
    let nanos = match body.get(19..)? {
        "" => 0,
        frac => {
            let digits = frac.strip_prefix('.')?;
            if digits.is_empty() || digits.len() > 9 {
                return None;
            }
            number(20..body.len())? * 10u32.pow(9 - digits.len() as u32)
        }
    };
    Some((fields, nanos))
}

/// Parses and validates the text of dataset.ron (file name `dataset.ron` in errors).
pub fn meta_from_str(text: &str) -> Result<DatasetMeta, DatasetError> {
    parse_meta(Path::new(crate::DATASET_RON), text)
}

pub(crate) fn parse_meta(file: &Path, text: &str) -> Result<DatasetMeta, DatasetError> {
    let text = text_of(file, text.as_bytes().to_vec())?;
    let raw: RawMeta = from_ron(file, &text)?;
    let at_key = |key: &str, kind: ErrorKind| match locate_key(&text, key) {
        Some((line, col)) => DatasetError::at(file, line, Some(col), kind).named(key),
        None => DatasetError::whole_file(file, kind).named(key),
    };
    if raw.format_version != FORMAT_VERSION {
        return Err(at_key(
            "format_version",
            ErrorKind::UnsupportedVersion {
                found: raw.format_version,
                known: FORMAT_VERSION,
            },
        ));
    }
    let epoch_utc = EpochUtc::parse(&raw.epoch_utc).map_err(|kind| at_key("epoch_utc", kind))?;
    check_orbit(file, &text, &raw.orbit)?;
    check_mounts(file, &text, &raw.photodiodes)?;
    if let Some(noise) = &raw.noise {
        check_noise(file, noise)?;
    }
    Ok(DatasetMeta {
        format_version: raw.format_version,
        name: raw.name,
        epoch_utc,
        orbit: raw.orbit,
        photodiodes: raw.photodiodes,
        noise: raw.noise,
    })
}

fn check_orbit(file: &Path, text: &str, orbit: &OrbitSpec) -> Result<(), DatasetError> {
    let OrbitSpec::Tle { line1, line2 } = orbit else {
        return Ok(());
    };
    for (number, key, line) in [(1u8, "line1", line1), (2u8, "line2", line2)] {
        let kind = if !line.starts_with(&format!("{number} ")) {
            Some(ErrorKind::BadTleLine {
                line_number: number,
            })
        } else if !pdcal_ephem::tle::checksum_ok(line) {
            Some(ErrorKind::BadTleChecksum {
                line_number: number,
                stated: line.chars().nth(68),
                computed: pdcal_ephem::tle::checksum(line),
            })
        } else {
            None
        };
        if let Some(kind) = kind {
            let place = locate_str(text, line).or_else(|| locate_key(text, key));
            let err = match place {
                Some((l, c)) => DatasetError::at(file, l, Some(c), kind),
                None => DatasetError::whole_file(file, kind),
            };
            return Err(err.named(format!("orbit.{key}")));
        }
    }
    Ok(())
}

fn check_mounts(file: &Path, text: &str, mounts: &[NominalMount]) -> Result<(), DatasetError> {
    for (i, m) in mounts.iter().enumerate() {
        for (name, v) in [
            ("azimuth_deg", m.azimuth_deg),
            ("elevation_deg", m.elevation_deg),
        ] {
            check_finite(file, v, || format!("photodiodes[{i}].{name}"))?;
        }
        if let Some(panel) = &m.panel
            && !crate::is_panel_name(panel)
        {
            let kind = ErrorKind::BadPanelName {
                value: panel.clone(),
            };
            // The quoted literal as written; an escaped spelling is not found, and then the
            // field path alone places the error.
            let err = match text.find(&format!("\"{panel}\"")) {
                Some(at) => {
                    let (line, col) = crate::error::line_col(text, at);
                    DatasetError::at(file, line, Some(col), kind)
                }
                None => DatasetError::whole_file(file, kind),
            };
            return Err(err.named(format!("photodiodes[{i}].panel")));
        }
    }
    Ok(())
}

fn check_noise(file: &Path, noise: &NoiseHints) -> Result<(), DatasetError> {
    let hints = [
        ("gyro_rad_s", noise.gyro_rad_s),
        ("mag_nT", noise.mag_nt),
        ("photodiode_V", noise.photodiode_v),
    ];
    for (name, value) in hints {
        let Some(v) = value else { continue };
        check_finite(file, v, || format!("noise.{name}"))?;
        if v <= 0.0 {
            let kind = ErrorKind::OutOfRange {
                value: v,
                rule: "a 1-sigma noise must be positive".into(),
            };
            return Err(DatasetError::whole_file(file, kind).named(format!("noise.{name}")));
        }
    }
    Ok(())
}

/// `NotFinite` naming a RON field path (no line: serde does not keep value positions).
pub(crate) fn check_finite(
    file: &Path,
    v: f64,
    field: impl FnOnce() -> String,
) -> Result<(), DatasetError> {
    if v.is_finite() {
        return Ok(());
    }
    let kind = ErrorKind::NotFinite {
        value: format!("{v:?}"),
    };
    Err(DatasetError::whole_file(file, kind).named(field()))
}

/// Pretty RON for dataset.ron, shaped like the contract's example.
pub(crate) fn render_meta(meta: &DatasetMeta) -> Result<String, DatasetError> {
    to_ron(Path::new(crate::DATASET_RON), meta)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn epoch_forms() {
        let a = EpochUtc::parse("2011-11-04T18:29:45Z").unwrap().epoch();
        let b = EpochUtc::parse("2011-11-04 18:29:45 UTC").unwrap().epoch();
        let c = EpochUtc::parse("2011-11-04T18:29:45.5").unwrap().epoch();
        assert_eq!(a, Epoch::from_gregorian_utc_hms(2011, 11, 4, 18, 29, 45));
        assert_eq!(a, b);
        assert_eq!((c - a).to_seconds(), 0.5);
        for bad in [
            "",
            "2011-11-04",
            "2011-13-04T18:29:45Z",
            "2011-11-04T18:29:45+02:00",
            "2011-11-04T18:29:45.Z",
            "2011-11-04T18:29:45 TAI",
            "2011-11-04T18:29:4éZ",
            "+011-11-04T18:29:45Z",
        ] {
            assert!(EpochUtc::parse(bad).is_err(), "{bad}");
        }
    }
}
