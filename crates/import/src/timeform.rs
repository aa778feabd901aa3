//! The time column's forms: Unix seconds, GPS seconds, seconds from a stated UTC epoch, ISO
//! 8601 UTC text. Every form becomes a `hifitime::Epoch` held in TAI, so that differences are
//! elapsed SI seconds across leap seconds.

use hifitime::{Epoch, TimeScale};
use pdcal_ephem::time;
use serde::Deserialize;

/// How the export writes its time column.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum TimeForm {
    /// Seconds since 1970-01-01T00:00:00Z without leap seconds (POSIX time): every UTC day
    /// has 86400 of them, so a leap second has no Unix time of its own.
    Unix,
    /// GPS seconds: elapsed SI seconds since 1980-01-06T00:00:00Z (GPS time, TAI - 19 s).
    Gps,
    /// Elapsed SI seconds since `epoch_utc` (a mission elapsed time).
    Seconds {
        /// ISO 8601 UTC, `2011-11-04T18:29:45Z`.
        epoch_utc: String,
    },
    /// ISO 8601 UTC text per cell, `2011-11-04T18:29:45.250Z` (the `Z` is required).
    Iso,
}

impl TimeForm {
    /// The form's name in messages.
    pub fn describe(&self) -> &'static str {
        match self {
            TimeForm::Unix => "Unix seconds",
            TimeForm::Gps => "GPS seconds",
            TimeForm::Seconds { .. } => "seconds from the map's epoch_utc",
            TimeForm::Iso => "an ISO 8601 UTC time like \"2011-11-04T18:29:45Z\"",
        }
    }

    /// Whether cells are numbers (and so can hold a numeric sentinel).
    pub fn is_numeric(&self) -> bool {
        !matches!(self, TimeForm::Iso)
    }
}

/// The earliest and latest times an export may hold: Sputnik 1 to 2100. Outside them a time
/// column is in another form than the map says (milliseconds read as seconds, GPS seconds read
/// as Unix seconds far off, a counter read as an absolute time).
pub const PLAUSIBLE_UTC: (&str, &str) = ("1957-10-04T00:00:00Z", "2100-01-01T00:00:00Z");

/// A time form with its epoch resolved, ready to convert cells.
#[derive(Clone, Debug)]
pub(crate) struct TimeReader {
    form: TimeForm,
    /// The epoch of `Seconds`, held in TAI.
    epoch: Option<Epoch>,
    earliest: Epoch,
    latest: Epoch,
}

/// Why a time cell was refused.
pub(crate) struct TimeFault(pub String);

impl TimeReader {
    /// `Err` with the reason when the `Seconds` epoch is not ISO 8601 UTC.
    pub(crate) fn new(form: &TimeForm) -> Result<Self, String> {
        let epoch = match form {
            TimeForm::Seconds { epoch_utc } => Some(parse_utc(epoch_utc)?),
            _ => None,
        };
        let (earliest, latest) = (parse_utc(PLAUSIBLE_UTC.0)?, parse_utc(PLAUSIBLE_UTC.1)?);
        Ok(Self {
            form: form.clone(),
            epoch,
            earliest,
            latest,
        })
    }

    /// The epoch of a numeric cell `value` (finite, checked by the caller).
    pub(crate) fn read_number(&self, value: f64) -> Result<Epoch, TimeFault> {
        // Bounded before hifitime sees it: a number of 1e300 seconds saturates or overflows
        // inside hifitime's Duration, which must not decide what this reader says.
        const WIDEST_S: f64 = 1.0e11;
        if value.abs() > WIDEST_S {
            return Err(self.implausible(None));
        }
        let t = match (&self.form, self.epoch) {
            (TimeForm::Unix, _) => Epoch::from_unix_seconds(value).to_time_scale(TimeScale::TAI),
            (TimeForm::Gps, _) => Epoch::from_gpst_seconds(value).to_time_scale(TimeScale::TAI),
            (TimeForm::Seconds { .. }, Some(epoch)) => {
                time::offset(epoch, value).map_err(|e| TimeFault(e.to_string()))?
            }
            _ => return Err(TimeFault("the time form reads text, not numbers".into())),
        };
        self.check(t)
    }

    /// The epoch of a text cell (form `Iso`).
    pub(crate) fn read_text(&self, text: &str) -> Result<Epoch, TimeFault> {
        let t = parse_utc(text).map_err(TimeFault)?;
        self.check(t)
    }

    fn check(&self, t: Epoch) -> Result<Epoch, TimeFault> {
        if t < self.earliest || t > self.latest {
            return Err(self.implausible(Some(t)));
        }
        Ok(t)
    }

    fn implausible(&self, t: Option<Epoch>) -> TimeFault {
        let when = t.map_or_else(
            || "far outside".to_owned(),
            |t| format!("{}, outside", time::format_utc(t)),
        );
        let hint = match self.form {
            TimeForm::Unix => "; milliseconds or GPS seconds instead of Unix seconds?",
            TimeForm::Gps => "; milliseconds or Unix seconds instead of GPS seconds?",
            TimeForm::Seconds { .. } => "; an absolute time instead of seconds from epoch_utc?",
            TimeForm::Iso => "",
        };
        TimeFault(format!(
            "it reads as {when} {} .. {}{hint}",
            &PLAUSIBLE_UTC.0[..10],
            &PLAUSIBLE_UTC.1[..10]
        ))
    }
}

/// [`time::parse_utc`] with its reason only: its message repeats the whole input, which the
/// caller quotes clipped instead.
fn parse_utc(text: &str) -> Result<Epoch, String> {
    time::parse_utc(text).map_err(|e| match e {
        time::TimeError::Format { reason, .. } => reason.to_owned(),
        time::TimeError::Invalid { reason, .. } => crate::error::clip(&reason),
        other => crate::error::clip(&other.to_string()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(form: TimeForm, value: f64) -> Epoch {
        match TimeReader::new(&form).unwrap().read_number(value) {
            Ok(t) => t,
            Err(TimeFault(why)) => panic!("{why}"),
        }
    }

    #[test]
    fn the_forms_agree_on_one_instant() {
        let iso = time::parse_utc("2011-11-04T18:29:45Z").unwrap();
        // date -u -d 2011-11-04T18:29:45Z +%s
        let unix = at(TimeForm::Unix, 1_320_431_385.0);
        // GPS: 1980-01-06 to 2011-11-04T18:29:45 UTC is 1004466585 UTC-label seconds, plus
        // the 15 leap seconds inserted in between (TAI-UTC 19 s in 1980, 34 s in 2011).
        let gps = at(TimeForm::Gps, 1_004_466_600.0);
        let mission = at(
            TimeForm::Seconds {
                epoch_utc: "2011-11-04T18:00:00Z".into(),
            },
            1785.0,
        );
        let text = TimeReader::new(&TimeForm::Iso)
            .unwrap()
            .read_text("2011-11-04T18:29:45Z")
            .unwrap_or_else(|TimeFault(w)| panic!("{w}"));
        for (name, t) in [
            ("unix", unix),
            ("gps", gps),
            ("seconds", mission),
            ("iso", text),
        ] {
            let off = time::seconds_between(iso, t);
            assert!(off.abs() < 1e-6, "{name}: {off} s");
        }
    }

    #[test]
    fn unix_time_skips_the_leap_second() {
        // 2016-12-31T23:59:59Z and 2017-01-01T00:00:00Z are one Unix second apart, two SI
        // seconds apart (23:59:60 in between).
        let a = at(TimeForm::Unix, 1_483_228_799.0);
        let b = at(TimeForm::Unix, 1_483_228_800.0);
        assert!((time::seconds_between(a, b) - 2.0).abs() < 1e-9);
        // GPS seconds count through it.
        let g = at(TimeForm::Gps, 1_167_264_018.0);
        assert!(time::seconds_between(b, g).abs() < 1e-6);
    }

    #[test]
    fn a_time_in_another_form_is_implausible() {
        let unix = TimeReader::new(&TimeForm::Unix).unwrap();
        // Milliseconds read as seconds: year 43813.
        let Err(TimeFault(why)) = unix.read_number(1_320_431_385_000.0) else {
            panic!("milliseconds accepted as Unix seconds");
        };
        assert!(why.contains("milliseconds"), "{why}");
        assert!(unix.read_number(1e300).is_err());
        let iso = TimeReader::new(&TimeForm::Iso).unwrap();
        assert!(iso.read_number(1_320_431_385.0).is_err());
        assert!(iso.read_text("1320431385").is_err());
        assert!(
            TimeReader::new(&TimeForm::Seconds {
                epoch_utc: "yesterday".into()
            })
            .is_err()
        );
    }
}
