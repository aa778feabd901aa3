//! Physical plausibility of telemetry that the reader accepts as numbers: what cannot come
//! from working sensors on an orbiting spacecraft.
//!
//! Errors where calibrating would produce confident nonsense: a gyro that reads exactly 0
//! throughout (the attitude would be propagated as if the spacecraft did not rotate), a
//! gyro or magnetometer axis stuck at one value, a photodiode stuck at a nonzero value, a
//! photodiode column mostly above any plausible full scale (ADC counts written as volts).
//! Warnings where the run stays meaningful but the user should look: a photodiode that
//! reads 0 throughout (a dead channel: it is reported unused), a few photodiode samples
//! above the full scale (outliers), a field magnitude outside 10-70 uT on some rows (the
//! geomagnetic field in low Earth orbit stays inside; a magnetometer bias or units).

use anyhow::{Result, bail};
use nalgebra::Vector3;
use pdcal_dataset::{TELEMETRY_CSV, Telemetry, Vectors, photodiode_column};

/// Sampled rows below which a constant column is not called stuck.
pub const MIN_ROWS_FOR_STUCK: usize = 10;
/// Least spread of a magnetometer axis over a data set, nT: in orbit the field on any body
/// axis changes by hundreds of nT within a minute even without rotation, so a smaller
/// spread is a stuck sensor whose value carries a little jitter.
pub const MIN_FIELD_SPREAD_NT: f64 = 1.0;
/// How many times faster than the magnetometer's field turns in the body frame the gyro
/// may say the body turns before its units are suspect: the field direction turns with the
/// body rate across it (the field's own turn along an orbit is far slower), so the two agree
/// to a factor near 1; deg/s written as rad/s makes it 57.
pub const GYRO_OVER_FIELD_RATE_MAX: f64 = 10.0;
/// Field magnitude range of low Earth orbit, nT.
pub const FIELD_RANGE_NT: (f64, f64) = (10_000.0, 70_000.0);
/// Photodiode output above any plausible full scale, V.
pub const PHOTODIODE_MAX_V: f64 = 50.0;
/// Share of a photodiode's samples above [`PHOTODIODE_MAX_V`] from which the column is
/// taken for a unit mistake (an error) rather than outliers (a warning).
pub const UNIT_MISTAKE_SHARE: f64 = 0.1;

/// The value every sample of a column holds, if at least [`MIN_ROWS_FOR_STUCK`] are sampled
/// and all are equal.
fn stuck_value(values: impl Iterator<Item = f64>) -> Option<(f64, usize)> {
    let mut first = None;
    let mut n = 0;
    for v in values {
        n += 1;
        match first {
            None => first = Some(v),
            Some(f) if f != v => return None,
            Some(_) => {}
        }
    }
    first.filter(|_| n >= MIN_ROWS_FOR_STUCK).map(|f| (f, n))
}

fn axis(column: &Vectors, i: usize) -> impl Iterator<Item = f64> + '_ {
    column.iter().flatten().map(move |v| v[i])
}

/// Checks `telemetry` (see the module documentation): `Err` for the first fault that makes
/// a calibration meaningless, otherwise the warnings, one line each, naming the column.
pub fn check_telemetry(telemetry: &Telemetry) -> Result<Vec<String>> {
    let f = TELEMETRY_CSV;
    let mut warnings = Vec::new();
    let gyro = &telemetry.gyro_rad_s;
    let sampled = gyro.iter().flatten().count();
    if sampled >= MIN_ROWS_FOR_STUCK && gyro.iter().flatten().all(|w| w == Vector3::zeros()) {
        bail!(
            "{f} (gyro_x_rad_s, gyro_y_rad_s, gyro_z_rad_s): the gyro reads exactly 0 on all \
             {sampled} sampled rows; a dead or disconnected gyro makes the attitude, and so the \
             calibration, meaningless"
        );
    }
    for (i, name) in ["x", "y", "z"].iter().enumerate() {
        if let Some((v, n)) = stuck_value(axis(gyro, i)) {
            bail!(
                "{f} (gyro_{name}_rad_s): stuck at {v:?} on all {n} sampled rows; a working \
                 gyro's noise never repeats exactly"
            );
        }
    }
    if let Some(mag) = &telemetry.mag_nt {
        for (i, name) in ["x", "y", "z"].iter().enumerate() {
            if let Some((v, n)) = stuck_value(axis(mag, i)) {
                bail!(
                    "{f} (mag_{name}_nT): stuck at {v:?} on all {n} sampled rows; a working \
                     magnetometer on a rotating spacecraft never reads the same twice throughout"
                );
            }
            let (lo, hi, n) = axis(mag, i).fold((f64::INFINITY, f64::NEG_INFINITY, 0), |acc, v| {
                (acc.0.min(v), acc.1.max(v), acc.2 + 1)
            });
            if n >= MIN_ROWS_FOR_STUCK && hi - lo < MIN_FIELD_SPREAD_NT {
                bail!(
                    "{f} (mag_{name}_nT): varies by only {:.3e} nT over all {n} sampled rows, \
                     less than {MIN_FIELD_SPREAD_NT} nT; an orbiting magnetometer sees the field \
                     change by far more (a stuck sensor with a little jitter added)",
                    hi - lo
                );
            }
        }
        if let Some(warning) = gyro_units(telemetry, mag) {
            warnings.push(warning);
        }
        let (lo, hi) = FIELD_RANGE_NT;
        let outside: Vec<(usize, f64)> = mag
            .iter()
            .enumerate()
            .filter_map(|(k, b)| b.map(|b| (k, b.norm())))
            .filter(|(_, n)| !(lo..=hi).contains(n))
            .collect();
        if let Some(&(k, norm)) = outside.first() {
            warnings.push(format!(
                "{f} (mag_x_nT, mag_y_nT, mag_z_nT): field magnitude outside {:.0}-{:.0} uT on \
                 {} of {} sampled rows (first at t_s = {:?}: {norm:.0} nT); check the units \
                 (nT) and the magnetometer's bias",
                lo / 1000.0,
                hi / 1000.0,
                outside.len(),
                mag.iter().flatten().count(),
                telemetry.t_s[k]
            ));
        }
    }
    check_positions(telemetry)?;
    for (i, column) in telemetry.pd_v.iter().enumerate() {
        let name = photodiode_column(i + 1);
        let sampled = column.iter().flatten().count();
        match stuck_value(column.iter().flatten()) {
            Some((0.0, n)) => warnings.push(format!(
                "{f} ({name}): 0 on all {n} sampled rows, a dead channel; it is not calibrated"
            )),
            Some((v, n)) => bail!(
                "{f} ({name}): stuck at {v:?} V on all {n} sampled rows; a photodiode on a \
                 rotating spacecraft cannot read one value throughout (leave its cells empty to \
                 calibrate the others)"
            ),
            None => {}
        }
        let above: Vec<(usize, f64)> = column
            .iter()
            .enumerate()
            .filter_map(|(k, v)| v.filter(|v| *v > PHOTODIODE_MAX_V).map(|v| (k, v)))
            .collect();
        let Some(&(k, v)) = above.first() else {
            continue;
        };
        let what = format!(
            "{f} ({name}): {} of {sampled} samples above {PHOTODIODE_MAX_V} V, beyond any \
             photodiode's full scale (first at t_s = {:?}: {v:?} V)",
            above.len(),
            telemetry.t_s[k]
        );
        if above.len() as f64 > UNIT_MISTAKE_SHARE * sampled as f64 {
            bail!("{what}; are these ADC counts rather than volts?");
        }
        warnings.push(format!("{what}; they are outliers"));
    }
    Ok(warnings)
}

/// The position columns (`orbit: PositionColumns`) as an orbit: every position above the
/// Earth and within the Moon's distance, consecutive positions no faster apart than the
/// escape speed ([`pdcal_dataset::rules::orbit_position`]). The error names the row.
fn check_positions(telemetry: &Telemetry) -> Result<()> {
    let Some(r) = &telemetry.r_gcrf_km else {
        return Ok(());
    };
    let mut previous = None;
    for (k, (t, p)) in telemetry.t_s.iter().zip(r).enumerate() {
        let Some(p) = p else { continue };
        if let Err(why) = pdcal_dataset::rules::orbit_position(previous, *t, &p) {
            bail!(
                "{TELEMETRY_CSV} (r_x_km, r_y_km, r_z_km), row {k} (t_s = {t:?}): {why}; \
                 these positions are not an orbit"
            );
        }
        previous = Some((*t, p));
    }
    Ok(())
}

/// Over consecutive rows at most 2 s apart with both sensors sampled: the gyro's rate
/// across the field times the step, and the field direction's angle between the rows.
fn turns_per_row<'a>(
    telemetry: &'a Telemetry,
    mag: &'a Vectors,
) -> impl Iterator<Item = (f64, f64)> + 'a {
    (1..telemetry.len()).filter_map(move |k| {
        let dt = telemetry.t_s[k] - telemetry.t_s[k - 1];
        let (w, b0, b1) = (
            telemetry.gyro_rad_s.get(k - 1)?,
            mag.get(k - 1)?,
            mag.get(k)?,
        );
        let b0_unit = b0.try_normalize(0.0)?;
        if !(dt > 0.0 && dt <= 2.0) || b1.norm() == 0.0 {
            return None;
        }
        let across = w - b0_unit * w.dot(&b0_unit);
        Some((across.norm() * dt, b0.angle(&b1)))
    })
}

/// A warning when the gyro says the body turns far faster than the magnetometer's field
/// turns in the body frame ([`GYRO_OVER_FIELD_RATE_MAX`]): the medians, over consecutive rows
/// at most 2 s apart with both sensors sampled, of the gyro's rate across the field times
/// the step and of the field direction's angle between the rows.
fn gyro_units(telemetry: &Telemetry, mag: &Vectors) -> Option<String> {
    // One median at a time, each over its own pass: a long set holds one column of them.
    let median_of = |part: fn((f64, f64)) -> f64| {
        let mut v: Vec<f64> = turns_per_row(telemetry, mag).map(part).collect();
        if v.len() < MIN_ROWS_FOR_STUCK {
            return None;
        }
        let mid = v.len() / 2;
        Some(*v.select_nth_unstable_by(mid, f64::total_cmp).1)
    };
    let p = median_of(|(predicted, _)| predicted)?;
    let o = median_of(|(_, observed)| observed)?;
    let ratio = p / o;
    (ratio > GYRO_OVER_FIELD_RATE_MAX).then(|| {
        format!(
            "{TELEMETRY_CSV} (gyro_x_rad_s, gyro_y_rad_s, gyro_z_rad_s): the gyro says the body \
             turns {ratio:.0} times faster than the magnetometer's field turns in the body \
             frame (median {:.3} against {:.3} deg per row); are the rates in deg/s rather \
             than rad/s (a factor of 57.3)?",
            p.to_degrees(),
            o.to_degrees()
        )
    })
}

/// Farthest a TLE's epoch may lie from its data set's rows, days, before the run says so: a
/// year, the span beyond which a joint calibration refuses its sets
/// ([`crate::joint::MAX_JOINT_SPAN_DAYS`]). Elements a year old place a low-orbit spacecraft
/// anywhere along its orbit; a gap of years is a time tag read in the wrong scale or epoch.
pub const MAX_TLE_AGE_DAYS: f64 = crate::joint::MAX_JOINT_SPAN_DAYS;

/// A warning when the data set `name`'s TLE epoch lies more than [`MAX_TLE_AGE_DAYS`] from
/// its first or last row; `None` for position columns, or a TLE the reader has not accepted
/// (its own error says why).
pub fn orbit_age(
    meta: &pdcal_dataset::DatasetMeta,
    telemetry: &Telemetry,
    name: &str,
) -> Option<String> {
    let pdcal_dataset::OrbitSpec::Tle { line1, line2 } = &meta.orbit else {
        return None;
    };
    let tle = pdcal_ephem::TleOrbit::from_lines(line1, line2).ok()?;
    let start = meta.epoch_utc.epoch();
    let span_s = telemetry.t_s.last().copied().unwrap_or(0.0);
    let end = start + hifitime::Unit::Second * span_s;
    let days = |t: hifitime::Epoch| (t - tle.epoch()).to_seconds().abs() / 86_400.0;
    // The row farther from the TLE is the one quoted.
    let (age, row, at) = match days(end) > days(start) {
        true => (days(end), "last row", end),
        false => (days(start), "first row", start),
    };
    let utc = pdcal_ephem::time::format_utc;
    (age > MAX_TLE_AGE_DAYS).then(|| {
        format!(
            "{name}: the TLE's epoch {} lies {age:.0} days from the data ({row} {}): \
             elements that old put the spacecraft anywhere along its orbit, so the eclipses \
             and the albedo's footprint are not the data's; a gap of years is a time column \
             read in the wrong scale or epoch (see the map's `time`)",
            utc(tle.epoch()),
            utc(at)
        )
    })
}
