//! The Sun: the [`SunEphemeris`] trait and the Astronomical Almanac's low-precision Sun.

use hifitime::Epoch;
use nalgebra::Vector3;

use crate::frames;

/// Astronomical unit, km (IAU 2012).
pub const AU_KM: f64 = 149_597_870.7;

/// `(1 AU / r)^2` with `r` the distance from the spacecraft at `r_sat_gcrf_km` to the Sun at
/// `sun_gcrf_km` (geocentric): the direct solar irradiance at the spacecraft relative to its
/// value at 1 AU. A non-finite or zero distance gives a non-finite factor, which callers
/// that check their inputs reject.
pub fn sun_distance_factor(r_sat_gcrf_km: &Vector3<f64>, sun_gcrf_km: &Vector3<f64>) -> f64 {
    (AU_KM / (sun_gcrf_km - r_sat_gcrf_km).norm()).powi(2)
}

/// Where the Sun is, seen from the Earth's centre.
pub trait SunEphemeris {
    /// Geocentric Sun position in GCRF at the UTC epoch `t`, km.
    fn sun_gcrf_km(&self, t: Epoch) -> Vector3<f64>;

    /// Unit vector from the Earth's centre to the Sun, GCRF.
    fn sun_dir_gcrf(&self, t: Epoch) -> Vector3<f64> {
        self.sun_gcrf_km(t).normalize()
    }
}

/// The Astronomical Almanac's low-precision solar coordinates (section C, "Low precision
/// formulas for the Sun", good to 0.01° for 1950-2050), precessed from the mean equator and
/// equinox of date to J2000 with IAU-76 precession and to GCRF with the frame bias.
///
/// The Almanac's mean longitude L includes the annual aberration (−20.496″), so its λ is an
/// *apparent* longitude; 20.496″ is added back to give the *astrometric* (geometric, light-time
/// corrected) direction that an attitude reference uses. Against DE421 (`sun_gcrf.csv`,
/// 2000-2035) the direction error is ≤ 0.0068° (0.0095° without the aberration term) and
/// the distance error ≤ 0.0070 %.
#[derive(Debug, Clone, Copy, Default)]
pub struct LowPrecisionSun;

/// Annual aberration constant, rad (20.49552″).
const ABERRATION_RAD: f64 = 20.495_52 / 3600.0 * std::f64::consts::PI / 180.0;

impl LowPrecisionSun {
    /// Sun in the mean equator and equinox of date, km.
    pub fn sun_mean_of_date_km(t: Epoch) -> Vector3<f64> {
        // n: days of TT since J2000.0 (the Almanac uses UT; the 66 s difference moves the Sun by
        // 0.0008°, so the better-defined TT is used).
        let n = t.to_jde_tt_days() - 2_451_545.0;
        let l_deg = 280.460 + 0.985_647_4 * n;
        let g = (357.528 + 0.985_600_3 * n).to_radians();
        let lambda =
            (l_deg + 1.915 * g.sin() + 0.020 * (2.0 * g).sin()).to_radians() + ABERRATION_RAD;
        let eps = (23.439 - 0.000_000_4 * n).to_radians();
        let r_km = (1.000_14 - 0.016_71 * g.cos() - 0.000_14 * (2.0 * g).cos()) * AU_KM;
        r_km * Vector3::new(
            lambda.cos(),
            eps.cos() * lambda.sin(),
            eps.sin() * lambda.sin(),
        )
    }
}

impl SunEphemeris for LowPrecisionSun {
    fn sun_gcrf_km(&self, t: Epoch) -> Vector3<f64> {
        // mean of date -> mean J2000 (Pᵀ) -> GCRF (Bᵀ)
        let to_gcrf = (frames::precession_iau76(t) * frames::frame_bias()).transpose();
        to_gcrf * Self::sun_mean_of_date_km(t)
    }
}
