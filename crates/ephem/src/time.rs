//! UTC epochs with leap seconds (on top of `hifitime`) and `t_s` offsets.
//!
//! A dataset's `t_s` counts elapsed SI seconds from `epoch_utc`, so an offset that spans a
//! leap second lands one UTC label earlier than naive calendar arithmetic would:
//! 2016-12-31T23:59:59Z + 2 s = 2017-01-01T00:00:00Z (the second in between is 23:59:60).
//!
//! hifitime does arithmetic in the time scale an epoch is held in, and in its UTC scale a
//! day is always 86400 s. So [`parse_utc`] returns epochs held in TAI, and [`offset`] and
//! [`seconds_between`] work in TAI whatever scale their arguments are in: `t_s` is always
//! elapsed SI time.

use hifitime::{Duration, Epoch, TimeScale, Unit};
use thiserror::Error;

/// A UTC time string or offset that cannot be turned into an epoch.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum TimeError {
    /// The text is not `YYYY-MM-DDTHH:MM:SS[.fraction]Z`.
    #[error(
        "`{}` is not an ISO 8601 UTC time (YYYY-MM-DDTHH:MM:SS[.f]Z): {reason}",
        pdcal_text::clip(.input)
    )]
    Format {
        /// The text as given (the message quotes at most `text::QUOTE_MAX_CHARS` of it).
        input: String,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// The fields parse but do not name a real UTC instant (e.g. month 13, Feb 30).
    #[error("`{}` is not a valid UTC date and time: {reason}", pdcal_text::clip(.input))]
    Invalid {
        /// The text as given (the message quotes at most `text::QUOTE_MAX_CHARS` of it).
        input: String,
        /// hifitime's reason.
        reason: String,
    },
    /// An offset in seconds that is NaN or infinite.
    #[error("time offset t_s = {t_s} s is not finite")]
    NonFiniteOffset {
        /// The offending offset, s.
        t_s: f64,
    },
}

/// Parses an ISO 8601 UTC time such as `2011-11-04T18:29:45Z` or
/// `2011-11-04T18:29:44.999808Z` (up to nanosecond digits; a leap second `23:59:60` is
/// accepted where one was inserted). The trailing `Z` is required: a time without a zone is
/// ambiguous, and this crate only reads UTC.
pub fn parse_utc(input: &str) -> Result<Epoch, TimeError> {
    let format = |reason| TimeError::Format {
        input: input.to_owned(),
        reason,
    };
    let s = input.trim();
    let body = s
        .strip_suffix('Z')
        .ok_or_else(|| format("missing the trailing `Z` (UTC)"))?;
    let (date, time) = body
        .split_once('T')
        .ok_or_else(|| format("missing the `T` separator"))?;
    let date_fields: Vec<&str> = date.split('-').collect();
    let [year, month, day] = date_fields[..] else {
        return Err(format("the date is not YYYY-MM-DD"));
    };
    let (hms, fraction) = match time.split_once('.') {
        Some((hms, fraction)) => (hms, Some(fraction)),
        None => (time, None),
    };
    let time_fields: Vec<&str> = hms.split(':').collect();
    let [hour, minute, second] = time_fields[..] else {
        return Err(format("the time is not HH:MM:SS"));
    };
    let digits = |text: &str, width: usize, what| {
        if text.len() == width && text.bytes().all(|b| b.is_ascii_digit()) {
            text.parse::<u32>().map_err(|_| format(what))
        } else {
            Err(format(what))
        }
    };
    let year = digits(year, 4, "the year is not four digits")?;
    let month = digits(month, 2, "the month is not two digits")?;
    let day = digits(day, 2, "the day is not two digits")?;
    let hour = digits(hour, 2, "the hour is not two digits")?;
    let minute = digits(minute, 2, "the minute is not two digits")?;
    let second = digits(second, 2, "the second is not two digits")?;
    let nanos = match fraction {
        None => 0,
        Some(f) if (1..=9).contains(&f.len()) && f.bytes().all(|b| b.is_ascii_digit()) => {
            let padded = format!("{f:0<9}");
            padded
                .parse::<u32>()
                .map_err(|_| format("bad fractional seconds"))?
        }
        Some(_) => return Err(format("fractional seconds must be 1 to 9 digits")),
    };
    // The digit checks above bound every field to fit its type.
    let as_u8 = |v: u32| u8::try_from(v).map_err(|_| format("a field is out of range"));
    let year = i32::try_from(year).map_err(|_| format("the year is out of range"))?;
    let invalid = |reason: String| TimeError::Invalid {
        input: input.to_owned(),
        reason,
    };
    // Checked here: hifitime rolls some fields over (hour 24 is the next day's 00).
    if let Some(reason) = calendar_fault(year, month, day, [hour, minute, second]) {
        return Err(invalid(reason));
    }
    // hifitime folds second 60 onto 59, so a leap second is built as 23:59:59 + 1 s (TAI).
    let leap = second == 60;
    let utc = Epoch::maybe_from_gregorian_utc(
        year,
        as_u8(month)?,
        as_u8(day)?,
        as_u8(hour)?,
        as_u8(minute)?,
        as_u8(if leap { 59 } else { second })?,
        if leap { 0 } else { nanos },
    )
    .map_err(|_| {
        invalid("the date and time are outside what the time library can represent".into())
    })?;
    let tai = utc.to_time_scale(TimeScale::TAI);
    if !leap {
        return Ok(tai);
    }
    let (_, _, _, h, m, s, _) = utc_label(tai + 2 * Unit::Second).0.to_gregorian_utc();
    if (hour, minute, h, m, s) != (23, 59, 0, 0, 0) {
        return Err(invalid(
            "no leap second was inserted at the end of that day".into(),
        ));
    }
    Ok(tai + Unit::Second + f64::from(nanos) * Unit::Nanosecond)
}

/// Which field of a date and time that does not exist is wrong, in words (`2011-02 has 28
/// days, not 30`); `None` when every field is in its range.
fn calendar_fault(
    year: i32,
    month: u32,
    day: u32,
    [hour, minute, second]: [u32; 3],
) -> Option<String> {
    let leap_year = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
    let days = match month {
        2 if leap_year => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    };
    Some(if !(1..=12).contains(&month) {
        format!("there is no month {month} (1 to 12)")
    } else if day == 0 || day > days {
        format!("{year:04}-{month:02} has {days} days, not {day}")
    } else if hour > 23 {
        format!("there is no hour {hour} (0 to 23)")
    } else if minute > 59 {
        format!("there is no minute {minute} (0 to 59)")
    } else if second > 60 {
        format!("there is no second {second} (0 to 59, 60 in a leap second)")
    } else {
        return None;
    })
}

/// Formats an epoch as ISO 8601 UTC with microseconds, e.g. `2011-11-04T18:29:44.999808Z`
/// (a leap second reads `23:59:60.xxxxxxZ`).
pub fn format_utc(t: Epoch) -> String {
    let (label, in_leap) = utc_label(t);
    let (y, mo, d, h, mi, s, ns) = label.to_gregorian_utc();
    let s = if in_leap { 60 } else { s };
    format!(
        "{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}.{:06}Z",
        ns / 1000
    )
}

/// The epoch `t_s` elapsed SI seconds after `epoch` (negative goes back), held in TAI.
pub fn offset(epoch: Epoch, t_s: f64) -> Result<Epoch, TimeError> {
    if !t_s.is_finite() {
        return Err(TimeError::NonFiniteOffset { t_s });
    }
    Ok(epoch.to_time_scale(TimeScale::TAI) + t_s * Unit::Second)
}

/// Elapsed SI seconds from `from` to `to` (the inverse of [`offset`]).
pub fn seconds_between(from: Epoch, to: Epoch) -> f64 {
    (to.to_time_scale(TimeScale::TAI) - from.to_time_scale(TimeScale::TAI)).to_seconds()
}

/// TAI − UTC at `t`, s (the whole leap seconds in force since 1972).
///
/// Computed here rather than with hifitime's TAI -> UTC conversion, which (4.3) looks the
/// leap-second table up with the TAI instant and so answers one second too many during the
/// last 37 s of a day that ends with a leap second.
pub fn tai_minus_utc_s(t: Epoch) -> f64 {
    let tai_s = t.to_time_scale(TimeScale::TAI).to_tai_duration();
    // hifitime's table is keyed by the UTC label (seconds since J1900) at which a count starts.
    let count_at_label = |label: Duration| {
        Epoch::from_duration(label, TimeScale::TAI)
            .leap_seconds(true)
            .unwrap_or(0.0)
    };
    // The count looked up at the TAI instant is right except in the last 37 s before a step,
    // where it is already the new one; the count at the label that guess implies is the one
    // in force in both cases.
    let guess = count_at_label(tai_s);
    count_at_label(tai_s - guess * Unit::Second)
}

/// The UTC label of `t` as a hifitime UTC-scale epoch, and whether `t` falls inside an
/// inserted leap second (then the label is 23:59:59 plus the fraction).
fn utc_label(t: Epoch) -> (Epoch, bool) {
    let tai_s = t.to_time_scale(TimeScale::TAI).to_tai_duration();
    let count = tai_minus_utc_s(t);
    let label = tai_s - count * Unit::Second;
    // Only inside an inserted second does the label already read the next day (whose count
    // is one more) while the old count still holds.
    let label_count = Epoch::from_duration(label, TimeScale::TAI).leap_seconds(true);
    let in_leap = label_count.unwrap_or(0.0) != count;
    let label = if in_leap { label - Unit::Second } else { label };
    (Epoch::from_duration(label, TimeScale::UTC), in_leap)
}

/// Julian date of the UTC calendar label of `t` (the UT1 = UTC argument of sidereal time);
/// during a leap second it holds at 23:59:59 plus the fraction.
pub fn jd_utc(t: Epoch) -> f64 {
    utc_label(t).0.to_jde_utc_days()
}

/// TT − UTC at `t`, s: 32.184 s plus the leap seconds in force.
pub fn tt_minus_utc_s(t: Epoch) -> f64 {
    32.184 + tai_minus_utc_s(t)
}

/// A `hifitime` duration of `s` seconds (convenience for callers that hold f64 seconds).
pub fn seconds(s: f64) -> Duration {
    s * Unit::Second
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_whole_and_fractional_seconds() {
        let t = parse_utc("2011-11-04T18:29:45Z").unwrap();
        assert_eq!(t, Epoch::from_gregorian_utc(2011, 11, 4, 18, 29, 45, 0));
        let f = parse_utc("2011-11-04T18:29:44.999808Z").unwrap();
        // 192 µs exactly: both are integer nanoseconds.
        assert!((seconds_between(f, t) - 192e-6).abs() < 1e-12);
        assert_eq!(format_utc(f), "2011-11-04T18:29:44.999808Z");
    }

    #[test]
    fn rejects_malformed_text_with_a_reason() {
        for bad in [
            "2011-11-04 18:29:45Z",
            "2011-11-04T18:29:45",
            "2011-11-4T18:29:45Z",
            "2011-11-04T18:29Z",
            "2011-11-04T18:29:45.Z",
            "2011-11-04T18:29:45.1234567890Z",
            "2011-1x-04T18:29:45Z",
            "",
        ] {
            assert!(
                matches!(parse_utc(bad), Err(TimeError::Format { .. })),
                "{bad}"
            );
        }
        assert!(matches!(
            parse_utc("2011-02-30T00:00:00Z"),
            Err(TimeError::Invalid { .. })
        ));
        // The reason names the field, in words, not the time library's error variant.
        for (bad, reason) in [
            ("2011-02-30T00:00:00Z", "2011-02 has 28 days, not 30"),
            ("2012-02-30T00:00:00Z", "2012-02 has 29 days, not 30"),
            ("2011-04-31T00:00:00Z", "2011-04 has 30 days, not 31"),
            ("2011-13-01T00:00:00Z", "there is no month 13 (1 to 12)"),
            ("2011-00-01T00:00:00Z", "there is no month 0 (1 to 12)"),
            ("2011-01-01T24:00:00Z", "there is no hour 24 (0 to 23)"),
        ] {
            let message = parse_utc(bad).unwrap_err().to_string();
            assert!(message.ends_with(reason), "{bad}: {message}");
        }
        assert!(matches!(
            parse_utc("2011-13-01T00:00:00Z"),
            Err(TimeError::Invalid { .. })
        ));
    }

    #[test]
    fn offsets_round_trip_and_reject_nan() {
        let t0 = parse_utc("2011-11-04T18:29:45Z").unwrap();
        let t1 = offset(t0, 7200.25).unwrap();
        assert!((seconds_between(t0, t1) - 7200.25).abs() < 1e-9);
        // Absurd offsets saturate inside hifitime rather than panic.
        let _ = offset(t0, 1e300);
        assert!(matches!(
            offset(t0, f64::NAN),
            Err(TimeError::NonFiniteOffset { .. })
        ));
    }
}
