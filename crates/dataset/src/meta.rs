//! dataset.ron: epoch, orbit source, nominal photodiode layout, noise hints.

use std::path::Path;

use hifitime::Epoch;
use nalgebra::Matrix3;
use pdcal_attitude::dynamics::RigidBody;
use serde::{Deserialize, Serialize};

use crate::error::{DatasetError, ErrorKind, FileFaultKind, text_of};
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
    /// Optional inertia tensor about the centre of mass, body frame (checked physical).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inertia_kg_m2: Option<Inertia>,
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
    #[serde(default)]
    inertia_kg_m2: Option<Inertia>,
}

/// The principal moments a spacecraft can have, kg m^2: from a chip-sized femtosatellite
/// (4 g over 3.5 cm: about 1e-6) with a decade of margin, to a space station (about 1e8)
/// with one. A moment outside is a unit mistake.
pub const MOMENT_RANGE_KG_M2: [f64; 2] = [1e-7, 1e9];

/// The inertia tensor about the centre of mass, body frame, kg m^2: the three moments and
/// the three products (`xy = J[0][1]`, the tensor's entry, not its negative); a product left
/// out is zero.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Inertia {
    /// `J_xx`, kg m^2.
    pub xx: f64,
    /// `J_yy`, kg m^2.
    pub yy: f64,
    /// `J_zz`, kg m^2.
    pub zz: f64,
    /// `J_xy = J_yx`, kg m^2.
    #[serde(default)]
    pub xy: f64,
    /// `J_xz = J_zx`, kg m^2.
    #[serde(default)]
    pub xz: f64,
    /// `J_yz = J_zy`, kg m^2.
    #[serde(default)]
    pub yz: f64,
}

impl Inertia {
    /// The symmetric tensor `J`, kg m^2.
    pub fn matrix(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.xx, self.xy, self.xz, self.xy, self.yy, self.yz, self.xz, self.yz, self.zz,
        )
    }

    /// The tensor's entries of a symmetric `J` (the upper triangle is read).
    pub fn from_matrix(j: &Matrix3<f64>) -> Self {
        Inertia {
            xx: j[(0, 0)],
            yy: j[(1, 1)],
            zz: j[(2, 2)],
            xy: j[(0, 1)],
            xz: j[(0, 2)],
            yz: j[(1, 2)],
        }
    }

    /// The rigid body of this tensor: finite, moments within a spacecraft's
    /// ([`MOMENT_RANGE_KG_M2`]), positive definite, principal moments obeying the triangle
    /// inequality ([`RigidBody::new`]), else why not, naming the entry at fault.
    pub fn rigid_body(&self) -> Result<RigidBody, String> {
        let entries = [
            ("xx", self.xx),
            ("yy", self.yy),
            ("zz", self.zz),
            ("xy", self.xy),
            ("xz", self.xz),
            ("yz", self.yz),
        ];
        if let Some((name, v)) = entries.iter().find(|(_, v)| !v.is_finite()) {
            return Err(format!("{name} = {v} is not a finite number"));
        }
        let [low, high] = MOMENT_RANGE_KG_M2;
        if let Some((name, v)) = entries[..3]
            .iter()
            .find(|(_, v)| *v > 0.0 && !(low..=high).contains(v))
        {
            return Err(format!(
                "{name} = {v:e} kg m^2 is outside any spacecraft's moments of inertia ({low:e} to \
                 {high:e} kg m^2): another unit (g cm^2 or g mm^2 as kg m^2)?"
            ));
        }
        RigidBody::new(self.matrix()).map_err(|e| e.to_string())
    }
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
    /// Field of view: the half-angle from the normal, degrees, `0 < fov_deg <= 90`, beyond
    /// which the photodiode sees nothing (neither the direct Sun nor albedo). Absent: the
    /// cosine law holds to 90 deg.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov_deg: Option<f64>,
}

impl NominalMount {
    /// The field-of-view half-angle in radians, if the entry gives one (the model's
    /// `fov_half_angle_rad`).
    pub fn fov_half_angle_rad(&self) -> Option<f64> {
        self.fov_deg.map(f64::to_radians)
    }
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
    /// time is UTC, so offsets like `+02:00` are refused. The one ISO 8601 parser of the
    /// workspace reads it ([`pdcal_ephem::time::parse_utc`], which also knows the leap
    /// seconds) once the forms dataset.ron allows are brought to its `...THH:MM:SSZ`.
    pub fn parse(text: &str) -> Result<Self, ErrorKind> {
        let epoch = pdcal_ephem::time::parse_utc(&canonical_iso(text)).map_err(|e| {
            ErrorKind::from(FileFaultKind::BadEpoch {
                value: text.to_owned(),
                reason: time_reason(e),
            })
        })?;
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

/// dataset.ron's epoch forms as `parse_utc` reads them: the zone `Z`, ` UTC` or none (UTC
/// either way), and a space or a `T` between date and time.
fn canonical_iso(text: &str) -> String {
    let body = text
        .strip_suffix('Z')
        .or_else(|| text.strip_suffix(" UTC"))
        .unwrap_or(text);
    let mut canonical = String::with_capacity(body.len() + 1);
    for (i, c) in body.char_indices() {
        canonical.push(if i == 10 && c == ' ' { 'T' } else { c });
    }
    canonical.push('Z');
    canonical
}

/// Why the time parser refused an epoch, without its quotation of the text (the message of
/// `BadEpoch` quotes it).
fn time_reason(e: pdcal_ephem::time::TimeError) -> String {
    use pdcal_ephem::time::TimeError;
    match e {
        TimeError::Format { reason, .. } => {
            format!("{reason} (expected YYYY-MM-DDTHH:MM:SS[.f]Z)")
        }
        TimeError::Invalid { reason, .. } => reason,
        other => other.to_string(),
    }
}

/// dataset.ron's fields as a program holds them, not yet checked: [`meta_from_fields`] turns
/// them into a [`DatasetMeta`] through the reader.
#[derive(Clone, Debug, PartialEq)]
pub struct MetaFields {
    /// Free-text name of the data set.
    pub name: String,
    /// ISO 8601 UTC text, as dataset.ron's `epoch_utc`.
    pub epoch_utc: String,
    /// Where the orbit comes from.
    pub orbit: OrbitSpec,
    /// Intended mounting of each photodiode, in `pdNN` order.
    pub photodiodes: Vec<NominalMount>,
    /// Optional 1-sigma noise hints.
    pub noise: Option<NoiseHints>,
    /// Optional inertia tensor, kg m^2.
    pub inertia_kg_m2: Option<Inertia>,
}

/// dataset.ron's layout, field for field as [`DatasetMeta`] serialises.
#[derive(Serialize)]
struct MetaText<'a> {
    format_version: u32,
    name: &'a str,
    epoch_utc: &'a str,
    orbit: &'a OrbitSpec,
    photodiodes: &'a [NominalMount],
    #[serde(skip_serializing_if = "Option::is_none")]
    noise: &'a Option<NoiseHints>,
    #[serde(skip_serializing_if = "Option::is_none")]
    inertia_kg_m2: &'a Option<Inertia>,
}

/// The metadata of `fields`, checked by the one reader: they are rendered as the writer
/// renders dataset.ron and read back, so a value the reader refuses gets the reader's error,
/// naming the line and column of the dataset.ron the writer would write.
pub fn meta_from_fields(fields: &MetaFields) -> Result<DatasetMeta, DatasetError> {
    let text = to_ron(
        Path::new(crate::DATASET_RON),
        &MetaText {
            format_version: FORMAT_VERSION,
            name: &fields.name,
            epoch_utc: &fields.epoch_utc,
            orbit: &fields.orbit,
            photodiodes: &fields.photodiodes,
            noise: &fields.noise,
            inertia_kg_m2: &fields.inertia_kg_m2,
        },
    )?;
    meta_from_str(&text)
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
            FileFaultKind::UnsupportedVersion {
                found: raw.format_version,
                known: FORMAT_VERSION,
            }
            .into(),
        ));
    }
    let epoch_utc = EpochUtc::parse(&raw.epoch_utc).map_err(|kind| at_key("epoch_utc", kind))?;
    check_orbit(file, &text, &raw.orbit)?;
    check_mounts(file, &text, &raw.photodiodes)?;
    if let Some(noise) = &raw.noise {
        check_noise(file, noise)?;
    }
    if let Some(inertia) = &raw.inertia_kg_m2 {
        inertia
            .rigid_body()
            .map_err(|reason| at_key("inertia_kg_m2", ErrorKind::BadInertia { reason }))?;
    }
    Ok(DatasetMeta {
        format_version: raw.format_version,
        name: raw.name,
        epoch_utc,
        orbit: raw.orbit,
        photodiodes: raw.photodiodes,
        noise: raw.noise,
        inertia_kg_m2: raw.inertia_kg_m2,
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
    check_tle_elements(file, text, line2)
}

/// Earth's gravitational parameter, km^3/s^2, and equatorial radius, km (WGS-72, as SGP4).
const MU_KM3_S2: f64 = 398_600.8;
const EARTH_RADIUS_KM: f64 = 6378.135;
/// Perigee altitude below which an orbit has decayed (the atmosphere ends it within hours).
pub const DECAYED_PERIGEE_KM: f64 = 100.0;
/// Mean motion range of an Earth orbit SGP4 handles, rev/day (beyond the Moon below).
pub const MEAN_MOTION_REV_DAY: (f64, f64) = (0.05, 17.0);

/// The orbital elements of TLE line 2 within their physical ranges: inclination 0-180 deg,
/// eccentricity below 1, a plausible mean motion, and a perigee above the atmosphere.
fn check_tle_elements(file: &Path, text: &str, line2: &str) -> Result<(), DatasetError> {
    let fail = |field: &str, columns: &str, kind: ErrorKind| {
        let err = match locate_str(text, line2) {
            Some((l, c)) => DatasetError::at(file, l, Some(c), kind),
            None => DatasetError::whole_file(file, kind),
        };
        Err(err.named(format!("orbit.line2 {field}, columns {columns}")))
    };
    // Fixed columns (1-based, inclusive) of the TLE format; eccentricity has an implied
    // leading "0.".
    let field = |from: usize, to: usize| line2.get(from - 1..to).map(str::trim).unwrap_or("");
    let number = |from: usize, to: usize, implied: &str| {
        let t = field(from, to);
        format!("{implied}{t}")
            .parse::<f64>()
            .map_err(|_| ErrorKind::NotANumber {
                value: t.to_owned(),
            })
    };
    let inclination = match number(9, 16, "") {
        Ok(v) => v,
        Err(kind) => return fail("inclination", "9-16", kind),
    };
    if !(0.0..=180.0).contains(&inclination) {
        let kind = ErrorKind::OutOfRange {
            value: inclination,
            rule: "inclination must be in [0, 180] deg".into(),
        };
        return fail("inclination", "9-16", kind);
    }
    let eccentricity = match number(27, 33, "0.") {
        Ok(v) => v,
        Err(kind) => return fail("eccentricity", "27-33", kind),
    };
    let mean_motion = match number(53, 63, "") {
        Ok(v) => v,
        Err(kind) => return fail("mean motion", "53-63", kind),
    };
    let (lo, hi) = MEAN_MOTION_REV_DAY;
    if !(lo..=hi).contains(&mean_motion) {
        let kind = ErrorKind::OutOfRange {
            value: mean_motion,
            rule: format!("mean motion must be in [{lo}, {hi}] rev/day for an Earth orbit"),
        };
        return fail("mean motion", "53-63", kind);
    }
    let n_rad_s = mean_motion * std::f64::consts::TAU / 86_400.0;
    let semi_major_km = (MU_KM3_S2 / (n_rad_s * n_rad_s)).cbrt();
    let perigee_km = semi_major_km * (1.0 - eccentricity) - EARTH_RADIUS_KM;
    if perigee_km < DECAYED_PERIGEE_KM {
        let kind = ErrorKind::OutOfRange {
            value: perigee_km,
            rule: format!(
                "perigee altitude (km, from mean motion {mean_motion} rev/day and eccentricity \
                 {eccentricity}) is below {DECAYED_PERIGEE_KM} km: the orbit has decayed"
            ),
        };
        return fail("mean motion", "53-63", kind);
    }
    Ok(())
}

fn check_mounts(file: &Path, text: &str, mounts: &[NominalMount]) -> Result<(), DatasetError> {
    let mut fov_seen = 0;
    for (i, m) in mounts.iter().enumerate() {
        if let Some(fov) = m.fov_deg {
            if !(fov > 0.0 && fov <= 90.0) {
                let kind = ErrorKind::OutOfRange {
                    value: fov,
                    rule: "a field-of-view half-angle must be in (0, 90] deg".into(),
                };
                // The entries before this one that give the field hold the earlier keys.
                let err = match crate::ron_text::locate_nth_key(text, "fov_deg", fov_seen) {
                    Some((line, col)) => DatasetError::at(file, line, Some(col), kind),
                    None => DatasetError::whole_file(file, kind),
                };
                return Err(err.named(format!("photodiodes[{i}].fov_deg")));
            }
            fov_seen += 1;
        }
        for (name, v) in [
            ("azimuth_deg", m.azimuth_deg),
            ("elevation_deg", m.elevation_deg),
        ] {
            check_finite(file, v, || format!("photodiodes[{i}].{name}"))?;
        }
        if let Err((name, rule)) = crate::rules::mounting(m.azimuth_deg, m.elevation_deg) {
            let value = match name {
                "azimuth_deg" => m.azimuth_deg,
                _ => m.elevation_deg,
            };
            let kind = ErrorKind::OutOfRange {
                value,
                rule: rule.into(),
            };
            return Err(
                DatasetError::whole_file(file, kind).named(format!("photodiodes[{i}].{name}"))
            );
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
        if let Err(rule) = crate::rules::noise(name, v) {
            let kind = ErrorKind::OutOfRange { value: v, rule };
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

    /// A leap second is a real instant of UTC: `23:59:60.5` on 2016-12-31 lies half a
    /// second after `23:59:60` and 1.5 s before the next day; on a day without one it is
    /// refused.
    #[test]
    fn a_leap_second_epoch_is_read_where_one_was_inserted() {
        let leap = EpochUtc::parse("2016-12-31T23:59:60.5Z").unwrap().epoch();
        let next_day = EpochUtc::parse("2017-01-01 00:00:00 UTC").unwrap().epoch();
        assert!(((next_day - leap).to_seconds() - 0.5).abs() < 1e-9);
        let before = EpochUtc::parse("2016-12-31T23:59:59Z").unwrap().epoch();
        assert!(((next_day - before).to_seconds() - 2.0).abs() < 1e-9);
        let e = EpochUtc::parse("2015-12-31T23:59:60Z").unwrap_err();
        assert!(
            matches!(e, ErrorKind::File(FileFaultKind::BadEpoch { .. })),
            "{e}"
        );
    }

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
