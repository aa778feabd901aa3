//! The physical checks of a photodiode's mounting, scale factor and a sensor noise figure:
//! one rule each, whichever file the value comes from (dataset.ron, a `--config` prior
//! calibration.ron, an import map through the dataset reader, Python through the same
//! reader), so that a value refused in one is refused in all, with the same words.

/// Largest plausible photodiode scale factor, V: beyond it a value is a unit slip (mV as
/// V) or garbage, and it would surface deep inside the filter (a covariance of 1e600).
pub const MAX_SCALE_V: f64 = 100.0;

/// A photodiode mounting's azimuth and elevation, deg: finite, elevation in [-90, 90],
/// azimuth in [-360, 360]. `Err((field, rule))` names the first field that breaks its rule.
pub fn mounting(azimuth_deg: f64, elevation_deg: f64) -> Result<(), (&'static str, &'static str)> {
    if !elevation_deg.is_finite() {
        return Err(("elevation_deg", "must be a finite number"));
    }
    if !azimuth_deg.is_finite() {
        return Err(("azimuth_deg", "must be a finite number"));
    }
    if !(-90.0..=90.0).contains(&elevation_deg) {
        return Err(("elevation_deg", "elevation must be in [-90, 90] deg"));
    }
    if !(-360.0..=360.0).contains(&azimuth_deg) {
        return Err(("azimuth_deg", "azimuth must be in [-360, 360] deg"));
    }
    Ok(())
}

/// A photodiode scale factor (output at 1 AU and normal incidence), V: positive, finite,
/// at most [`MAX_SCALE_V`].
pub fn scale_factor(scale_v: f64) -> Result<(), &'static str> {
    if scale_v > 0.0 && scale_v <= MAX_SCALE_V {
        Ok(())
    } else {
        Err("a scale factor must be positive and at most 100 V")
    }
}

/// A 1-sigma of a value whose plausible size is `max` (a scale factor's sigma, a noise):
/// non-negative, finite, at most `max`.
pub fn sigma(value: f64, max: f64) -> Result<(), String> {
    if value >= 0.0 && value <= max {
        Ok(())
    } else {
        Err(format!(
            "a 1-sigma must be non-negative and at most {max:e}"
        ))
    }
}

/// Upper bounds of a sensor's 1-sigma noise, by its dataset.ron name: beyond these a
/// 1-sigma is not a noise but a unit mistake (57 deg/s of gyro noise, more than the
/// geomagnetic field, more than any photodiode's full scale), and it would only surface
/// deep inside the filter.
pub const NOISE_MAX: [(&str, f64, &str); 3] = [
    ("gyro_rad_s", 1.0, "rad/s"),
    ("mag_nT", 1.0e5, "nT"),
    ("photodiode_V", 100.0, "V"),
];

/// A sensor's 1-sigma noise `value`, `name` one of [`NOISE_MAX`]'s (in its unit), whether
/// dataset.ron's hint or a `--config` sigma: positive and at most its bound. A NaN is
/// refused with the bound's words.
pub fn noise(name: &str, value: f64) -> Result<(), String> {
    let bound = NOISE_MAX.iter().find(|(n, _, _)| *n == name);
    match bound {
        Some((_, max, unit)) if value > *max || value.is_nan() => Err(format!(
            "a 1-sigma noise must be positive and at most {max:e} {unit}"
        )),
        _ if value <= 0.0 || value.is_nan() => Err("a 1-sigma noise must be positive".into()),
        _ => Ok(()),
    }
}

/// Equatorial radius of the Earth, km (WGS-84).
pub const EARTH_RADIUS_KM: f64 = 6378.137;
/// Lowest altitude of a position above the Earth's equatorial radius, km: below it no
/// orbit lasts (the Karman line; a decayed TLE is refused at a higher perigee).
pub const MIN_ALTITUDE_KM: f64 = 100.0;
/// Largest orbit radius, km: beyond the Moon's orbit, so that LEO, GEO and highly
/// elliptical orbits pass and metres written as kilometres (a LEO radius of 6.8e6) do not.
pub const MAX_ORBIT_RADIUS_KM: f64 = 1.0e6;
/// The Earth's gravitational parameter, km^3/s^2.
pub const MU_EARTH_KM3_S2: f64 = 398_600.441_8;
/// Factor on the escape speed beyond which two positions cannot be one orbit's.
pub const MAX_SPEED_OVER_ESCAPE: f64 = 1.1;

/// A position of `orbit: PositionColumns` at `t_s` against the physics of an orbit: its
/// radius above the Earth and below [`MAX_ORBIT_RADIUS_KM`], and, with the previous
/// position, a speed below the escape speed (chords are never longer than arcs). The
/// reason when not, with the likely slip.
pub fn orbit_position(
    previous: Option<(f64, nalgebra::Vector3<f64>)>,
    t_s: f64,
    r_km: &nalgebra::Vector3<f64>,
) -> Result<(), String> {
    let radius = r_km.norm();
    if radius < EARTH_RADIUS_KM {
        return Err(format!(
            "the position's radius, {radius:.1} km, is inside the Earth (radius \
             {EARTH_RADIUS_KM} km): positions must be km from the Earth's centre, GCRF"
        ));
    }
    if radius < EARTH_RADIUS_KM + MIN_ALTITUDE_KM {
        return Err(format!(
            "the position's radius, {radius:.1} km, is {:.1} km above the Earth's surface, \
             below the {MIN_ALTITUDE_KM} km where any orbit ends",
            radius - EARTH_RADIUS_KM
        ));
    }
    if radius > MAX_ORBIT_RADIUS_KM {
        return Err(format!(
            "the position's radius, {radius:.4e} km, is beyond {MAX_ORBIT_RADIUS_KM:e} km (past \
             the Moon): metres written in the _km columns?"
        ));
    }
    if let Some((t0, r0)) = previous {
        let dt = t_s - t0;
        let speed = (r_km - r0).norm() / dt;
        let escape = (2.0 * MU_EARTH_KM3_S2 / radius.min(r0.norm())).sqrt();
        if dt > 0.0 && speed > MAX_SPEED_OVER_ESCAPE * escape {
            return Err(format!(
                "the spacecraft would move at {speed:.2} km/s since the previous position \
                 ({dt} s earlier), above the escape speed at that radius, {escape:.2} km/s: \
                 positions in metres, a wrong t_s, or a jump in the position columns"
            ));
        }
    }
    Ok(())
}
