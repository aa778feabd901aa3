//! Orbit sources: the [`OrbitSource`] trait, a TLE propagated with SGP4 ([`TleOrbit`]), and
//! (in [`crate::columns`]) the dataset's position columns.

use hifitime::Epoch;
use nalgebra::Vector3;
use sgp4::chrono::{Datelike, Timelike};
use thiserror::Error;

use crate::{frames, time, tle};

/// Position and velocity of the spacecraft in GCRF.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitState {
    /// Position, km, GCRF.
    pub r_gcrf_km: Vector3<f64>,
    /// Velocity, km/s, GCRF axes (time derivative of `r_gcrf_km`).
    pub v_gcrf_km_s: Vector3<f64>,
}

/// Something that knows where the spacecraft is: a TLE, position columns, a SPICE kernel.
pub trait OrbitSource {
    /// Position and velocity in GCRF at the UTC epoch `t`.
    fn state_gcrf(&self, t: Epoch) -> Result<OrbitState, OrbitError>;

    /// Position in GCRF at `t`, km.
    fn position_gcrf_km(&self, t: Epoch) -> Result<Vector3<f64>, OrbitError> {
        self.state_gcrf(t).map(|s| s.r_gcrf_km)
    }
}

/// Which line of a two-line element set an error is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TleLine {
    /// Line 1 (epoch, drag terms).
    One,
    /// Line 2 (mean elements).
    Two,
}

impl std::fmt::Display for TleLine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TleLine::One => f.write_str("TLE line 1"),
            TleLine::Two => f.write_str("TLE line 2"),
        }
    }
}

/// Why an orbit could not be built or evaluated.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum OrbitError {
    /// A TLE line is shorter than the 69 columns of the format.
    #[error("{line} has {len} characters, a TLE line needs 69")]
    TleLength {
        /// The line concerned.
        line: TleLine,
        /// Its length after trimming trailing white space.
        len: usize,
    },
    /// Column 69 does not match the modulo-10 checksum of columns 1-68.
    #[error("{line} fails its checksum: column 69 is {stated:?}, columns 1-68 give {computed}")]
    TleChecksum {
        /// The line concerned.
        line: TleLine,
        /// The digit in column 69 (`None` if it is not a digit).
        stated: Option<char>,
        /// The checksum computed from columns 1-68.
        computed: u32,
    },
    /// The `sgp4` crate could not read the fields (its message names the line and columns).
    #[error("cannot parse the TLE: {0}")]
    TleFields(String),
    /// The mean elements at epoch are unusable for SGP4 (Vallado error codes 1 and 2).
    #[error("TLE of satellite {norad_id}: SGP4 cannot initialise (code {code}): {message}")]
    TleElements {
        /// NORAD catalogue number.
        norad_id: u64,
        /// Vallado's SGP4 error code: 1 eccentricity, 2 mean motion.
        code: u8,
        /// The `sgp4` crate's description.
        message: String,
    },
    /// SGP4 failed at a propagation time (Vallado error codes 1, 3, 4, 6).
    #[error(
        "SGP4 for satellite {norad_id} failed {tsince_min} min after epoch (code {code}): {message}"
    )]
    Propagation {
        /// NORAD catalogue number.
        norad_id: u64,
        /// Minutes since the TLE epoch.
        tsince_min: f64,
        /// Vallado's SGP4 error code: 1 mean eccentricity, 3 perturbed eccentricity,
        /// 4 semi-latus rectum < 0, 6 decayed (radius below the Earth's).
        code: u8,
        /// What went wrong.
        message: String,
    },
    /// A time outside the sampled span of a [`crate::columns::PositionColumns`] source.
    #[error(
        "t_s = {} s is outside the sampled span [{first_s}, {last_s}] s",
        pdcal_text::number(*.t_s)
    )]
    OutsideSpan {
        /// The requested time, s since the dataset epoch.
        t_s: f64,
        /// First sample, s.
        first_s: f64,
        /// Last sample, s.
        last_s: f64,
    },
    /// Position samples that cannot be interpolated.
    #[error("position sample {index}: {reason}")]
    BadSamples {
        /// 0-based index of the offending sample.
        index: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// A time conversion failed.
    #[error(transparent)]
    Time(#[from] time::TimeError),
}

/// A raw SGP4 state in TEME, the frame SGP4 works in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TemeState {
    /// Position, km, TEME.
    pub r_teme_km: Vector3<f64>,
    /// Velocity, km/s, TEME.
    pub v_teme_km_s: Vector3<f64>,
}

/// Earth equatorial radius of WGS-72, km (the SGP4 distance unit; the decay test uses it).
const WGS72_RADIUS_KM: f64 = 6378.135;

/// An orbit from a two-line element set, propagated with the `sgp4` crate (WGS-72 constants,
/// Vallado's "improved" operation mode) and rotated from TEME to GCRF with
/// [`frames::teme_to_gcrf`].
#[derive(Debug, Clone)]
pub struct TleOrbit {
    constants: sgp4::Constants,
    norad_id: u64,
    epoch: Epoch,
}

impl TleOrbit {
    /// Parses and initialises a TLE, verifying both checksums ([`tle::checksum_ok`]).
    ///
    /// Trailing white space (CR of CRLF files) is ignored, and so is anything after
    /// column 69.
    pub fn from_lines(line1: &str, line2: &str) -> Result<Self, OrbitError> {
        let l1 = tle_columns(line1, TleLine::One)?;
        let l2 = tle_columns(line2, TleLine::Two)?;
        for (line, text) in [(TleLine::One, l1), (TleLine::Two, l2)] {
            if !tle::checksum_ok(text) {
                return Err(OrbitError::TleChecksum {
                    line,
                    stated: text.chars().nth(68),
                    computed: tle::checksum(text),
                });
            }
        }
        Self::from_checked_columns(l1, l2)
    }

    /// As [`TleOrbit::from_lines`] but without checksum verification, for test sets such as
    /// Vallado's SGP4-VER.TLE whose checksums are deliberately wrong. Like Vallado's reader it
    /// also takes a blank ephemeris type (column 63) or element-set number (columns 65-68),
    /// fields SGP4 does not use. Not for flight data.
    pub fn from_lines_ignoring_checksums(line1: &str, line2: &str) -> Result<Self, OrbitError> {
        let l1 = lenient_line1(tle_columns(line1, TleLine::One)?);
        let l2 = tle_columns(line2, TleLine::Two)?;
        // The `sgp4` crate always verifies checksums, so column 69 is rewritten with the
        // computed digit before handing the lines over.
        let fix = |text: &str| format!("{}{}", &text[..68], tle::checksum(text));
        Self::from_checked_columns(&fix(&l1), &fix(l2))
    }

    fn from_checked_columns(l1: &str, l2: &str) -> Result<Self, OrbitError> {
        let elements = sgp4::Elements::from_tle(None, l1.as_bytes(), l2.as_bytes())
            .map_err(|e| OrbitError::TleFields(e.to_string()))?;
        let norad_id = elements.norad_id;
        let init_error = |code, message: String| OrbitError::TleElements {
            norad_id,
            code,
            message,
        };
        let deg = std::f64::consts::PI / 180.0;
        let orbit = sgp4::Orbit::from_kozai_elements(
            &sgp4::WGS72,
            elements.inclination * deg,
            elements.right_ascension * deg,
            elements.eccentricity,
            elements.argument_of_perigee * deg,
            elements.mean_anomaly * deg,
            // rev/day -> rad/min
            elements.mean_motion * std::f64::consts::TAU / 1440.0,
        )
        .map_err(|e| init_error(2, e.to_string()))?;
        let constants = sgp4::Constants::new(
            sgp4::WGS72,
            sgp4::iau_epoch_to_sidereal_time,
            elements.epoch(),
            elements.drag_term,
            orbit,
        )
        .map_err(|e| init_error(1, e.to_string()))?;
        let epoch = epoch_of(&elements)?;
        Ok(Self {
            constants,
            norad_id,
            epoch,
        })
    }

    /// The TLE epoch (UTC).
    pub fn epoch(&self) -> Epoch {
        self.epoch
    }

    /// The NORAD catalogue number.
    pub fn norad_id(&self) -> u64 {
        self.norad_id
    }

    /// Raw SGP4 output in TEME, `tsince_min` minutes after the TLE epoch.
    pub fn propagate_teme(&self, tsince_min: f64) -> Result<TemeState, OrbitError> {
        let failure = |code, message: String| OrbitError::Propagation {
            norad_id: self.norad_id,
            tsince_min,
            code,
            message,
        };
        let prediction = self
            .constants
            .propagate(sgp4::MinutesSinceEpoch(tsince_min))
            .map_err(|e| failure(sgp4_error_code(&e), e.to_string()))?;
        let r_teme_km = Vector3::from(prediction.position);
        // The crate does not report decay; Vallado's code 6 is a radius below one Earth radius.
        if r_teme_km.norm() < WGS72_RADIUS_KM {
            return Err(failure(
                6,
                format!("decayed: radius {:.3} km", r_teme_km.norm()),
            ));
        }
        Ok(TemeState {
            r_teme_km,
            v_teme_km_s: Vector3::from(prediction.velocity),
        })
    }

    /// Raw SGP4 output in TEME at the UTC epoch `t`.
    pub fn state_teme(&self, t: Epoch) -> Result<TemeState, OrbitError> {
        self.propagate_teme(time::seconds_between(self.epoch, t) / 60.0)
    }
}

impl OrbitSource for TleOrbit {
    fn state_gcrf(&self, t: Epoch) -> Result<OrbitState, OrbitError> {
        let teme = self.state_teme(t)?;
        let m = frames::teme_to_gcrf(t);
        Ok(OrbitState {
            r_gcrf_km: m * teme.r_teme_km,
            v_gcrf_km_s: m * teme.v_teme_km_s,
        })
    }
}

/// The first 69 columns of a TLE line, or an error naming the line if it is shorter.
fn tle_columns(text: &str, line: TleLine) -> Result<&str, OrbitError> {
    let trimmed = text.trim_end();
    match trimmed.char_indices().nth(69) {
        _ if !trimmed.is_ascii() => Err(OrbitError::TleFields(format!("{line} is not ASCII"))),
        Some((cut, _)) => Ok(&trimmed[..cut]),
        None if trimmed.len() == 69 => Ok(trimmed),
        None => Err(OrbitError::TleLength {
            line,
            len: trimmed.len(),
        }),
    }
}

/// Line 1 with blank unused fields filled so that the `sgp4` crate parses it.
fn lenient_line1(l1: &str) -> String {
    let mut text = l1.to_owned();
    if text[62..63].trim().is_empty() {
        text.replace_range(62..63, "0");
    }
    if text[64..68].trim().is_empty() {
        text.replace_range(64..68, "   0");
    }
    text
}

/// Vallado's error code for a propagation error of the `sgp4` crate.
fn sgp4_error_code(e: &sgp4::Error) -> u8 {
    match e {
        sgp4::Error::OutOfRangeEccentricity { .. } => 1,
        sgp4::Error::OutOfRangePerturbedEccentricity { .. } => 3,
        sgp4::Error::NegativeSemiLatusRectum { .. } => 4,
    }
}

/// The TLE epoch as a hifitime UTC epoch (from the datetime the `sgp4` crate parsed, so
/// both agree on the instant).
fn epoch_of(elements: &sgp4::Elements) -> Result<Epoch, OrbitError> {
    let d = elements.datetime;
    let field = |v: u32| u8::try_from(v).unwrap_or(u8::MAX);
    Epoch::maybe_from_gregorian_utc(
        d.year(),
        field(d.month()),
        field(d.day()),
        field(d.hour()),
        field(d.minute()),
        field(d.second()),
        d.nanosecond(),
    )
    .map(|utc| utc.to_time_scale(hifitime::TimeScale::TAI))
    .map_err(|e| OrbitError::TleFields(format!("TLE epoch {d}: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    const L1: &str = "1 37853U 11061D   11308.77065972  .00000000  00000-0  20000-4 0  9997";
    const L2: &str = "2 37853 101.7000  50.0000 0300509 130.0000 230.0000 14.86144463  1000";

    #[test]
    fn checksum_errors_name_the_line() {
        let bad2 = L2.replace("101.7000", "101.7001");
        match TleOrbit::from_lines(L1, &bad2) {
            Err(OrbitError::TleChecksum {
                line: TleLine::Two,
                stated: Some('0'),
                computed: 1,
            }) => {}
            other => panic!("{other:?}"),
        }
        let bad1 = L1.replace("37853U", "37854U");
        assert!(matches!(
            TleOrbit::from_lines(&bad1, L2),
            Err(OrbitError::TleChecksum {
                line: TleLine::One,
                ..
            })
        ));
        // The checksum-skipping path takes the same text.
        assert!(TleOrbit::from_lines_ignoring_checksums(L1, &bad2).is_ok());
    }

    #[test]
    fn short_or_garbled_lines_are_errors_not_panics() {
        assert!(matches!(
            TleOrbit::from_lines(&L1[..60], L2),
            Err(OrbitError::TleLength {
                line: TleLine::One,
                len: 60
            })
        ));
        assert!(matches!(
            TleOrbit::from_lines_ignoring_checksums(L1, "2 garbage"),
            Err(OrbitError::TleLength {
                line: TleLine::Two,
                ..
            })
        ));
        let garbled = format!("{}x{}", &L2[..20], &L2[21..]);
        assert!(TleOrbit::from_lines_ignoring_checksums(L1, &garbled).is_err());
        assert!(
            TleOrbit::from_lines(
                "1 37853U 11061D   11308.77065972  .00000000  00000-0  2000é-4 0  9997",
                L2
            )
            .is_err()
        );
    }

    #[test]
    fn crlf_and_extra_columns_are_ignored() {
        let tle =
            TleOrbit::from_lines(&format!("{L1}\r"), &format!("{L2}  0.0 120.0 10.0\r")).unwrap();
        assert_eq!(tle.norad_id(), 37853);
        assert_eq!(time::format_utc(tle.epoch()), "2011-11-04T18:29:44.999808Z");
    }
}
