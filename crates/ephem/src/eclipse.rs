//! Eclipse by the Earth: the illuminated fraction ν of the solar disc, conical shadow with
//! penumbra (Montenbruck & Gill, *Satellite Orbits*, 2000, §3.4.2).
//!
//! Earth and Sun are spheres seen as flat discs from the satellite:
//! - a = asin(R_S / |s − r|), the apparent radius of the Sun,
//! - b = asin(R_E / |r|), the apparent radius of the Earth,
//! - c, the angle between the centres, seen from the satellite (r: satellite, s: Sun, both
//!   geocentric; the frame does not matter as long as both are in the same one, GCRF here).
//!
//! Then ν = 1 if c ≥ a + b (sunlight); ν = 0 if c < b − a (umbra); ν = 1 − b²/a² if c < a − b
//! (annular: the Earth disc lies inside the Sun disc); otherwise (penumbra), with
//! x = (c² + a² − b²)/(2c), y = √(a² − x²) and A = a² acos(x/a) + b² acos((c − x)/b) − c y
//! (the overlap area), ν = 1 − A/(π a²).
//!
//! The overlap A is evaluated in a cancellation-safe form (Heron's formula for the chord,
//! atan2 for the angles; see `classify`): the textbook acos form loses digits when the Sun
//! disc is small against the Earth's, and was seen to make ν non-monotonic by ~1e-5 near the
//! LEO umbra edge.
//!
//! The flat-disc overlap differs from the exact spherical-cap overlap by ≤ 2.3e-4 in LEO
//! penumbra (fixtures/reference/README.md), far below photodiode noise.

use nalgebra::Vector3;

/// Earth equatorial radius R_E (km), WGS84.
pub const EARTH_RADIUS_KM: f64 = 6378.137;

/// Solar radius R_S (km), Montenbruck & Gill.
pub const SUN_RADIUS_KM: f64 = 696_000.0;

/// Which branch of the conical model applies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EclipseRegion {
    /// The whole solar disc is visible (c ≥ a + b).
    Sun,
    /// Part of the solar disc is hidden by the Earth's limb.
    Penumbra,
    /// The solar disc is hidden completely (c < b − a).
    Umbra,
    /// The Earth disc lies wholly inside the solar disc (c < a − b); far from the Earth only.
    Annular,
}

/// The eclipse geometry at one instant: the angles of M&G §3.4.2, the region and ν.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Eclipse {
    /// Apparent solar radius a (rad).
    pub sun_angle_rad: f64,
    /// Apparent Earth radius b (rad).
    pub earth_angle_rad: f64,
    /// Angle c between the centres of the two discs, seen from the satellite (rad).
    pub separation_rad: f64,
    /// Which branch applies.
    pub region: EclipseRegion,
    /// Illuminated fraction ν of the solar disc, in [0, 1].
    pub nu: f64,
}

/// Illuminated fraction ν in [0, 1] for the satellite at `r_sat_gcrf_km` and the Sun at
/// `r_sun_gcrf_km` (both geocentric, km), with R_E = 6378.137 km and R_S = 696000 km.
pub fn illuminated_fraction(r_sat_gcrf_km: &Vector3<f64>, r_sun_gcrf_km: &Vector3<f64>) -> f64 {
    eclipse(r_sat_gcrf_km, r_sun_gcrf_km, EARTH_RADIUS_KM, SUN_RADIUS_KM).nu
}

/// [`illuminated_fraction`] with explicit Earth and Sun radii (km).
pub fn illuminated_fraction_with_radii(
    r_sat_gcrf_km: &Vector3<f64>,
    r_sun_gcrf_km: &Vector3<f64>,
    earth_radius_km: f64,
    sun_radius_km: f64,
) -> f64 {
    eclipse(r_sat_gcrf_km, r_sun_gcrf_km, earth_radius_km, sun_radius_km).nu
}

/// The full eclipse geometry (angles, region and ν) with explicit radii (km).
///
/// Degenerate inputs do not panic: inside the Earth (or the Sun) the apparent radius is
/// clamped to 90°, which gives a finite ν in [0, 1] that has no physical meaning. Non-finite
/// inputs give ν = NaN (reported with region `Penumbra`).
pub fn eclipse(
    r_sat_gcrf_km: &Vector3<f64>,
    r_sun_gcrf_km: &Vector3<f64>,
    earth_radius_km: f64,
    sun_radius_km: f64,
) -> Eclipse {
    let to_sun = r_sun_gcrf_km - r_sat_gcrf_km;
    let (r_norm, d_norm) = (r_sat_gcrf_km.norm(), to_sun.norm());
    let a = (sun_radius_km / d_norm).min(1.0).asin();
    let b = (earth_radius_km / r_norm).min(1.0).asin();
    // Angle between −r (towards the Earth's centre) and s − r; atan2 keeps full precision
    // near 0 and π where acos would not.
    let c = r_sat_gcrf_km
        .cross(&to_sun)
        .norm()
        .atan2(-r_sat_gcrf_km.dot(&to_sun));
    let (region, nu) = classify(a, b, c);
    Eclipse {
        sun_angle_rad: a,
        earth_angle_rad: b,
        separation_rad: c,
        region,
        nu,
    }
}

/// The branches of M&G §3.4.2 for disc radii a (Sun), b (Earth) and separation c (rad).
fn classify(a: f64, b: f64, c: f64) -> (EclipseRegion, f64) {
    if a.is_nan() || b.is_nan() || c.is_nan() {
        return (EclipseRegion::Penumbra, f64::NAN);
    }
    if c >= a + b {
        (EclipseRegion::Sun, 1.0)
    } else if c < b - a || (c <= 0.0 && b >= a) {
        (EclipseRegion::Umbra, 0.0)
    } else if c < a - b || c <= 0.0 {
        (EclipseRegion::Annular, 1.0 - b * b / (a * a))
    } else {
        // The chord through the two intersection points of the limbs lies at distance x from
        // the Sun's centre and c − x from the Earth's, with half-length y. The sun disc is
        // tiny next to the Earth's (a ≈ 0.27°, b up to 90°), so the textbook
        // acos((c − x)/b) loses ~sqrt(ε) near 1 and y = √(a² − x²) cancels; instead y comes
        // from Heron's formula (the triangle a, b, c has height y over base c), the angles
        // from atan2, and x from (c − b)(c + b), which is exact enough when c ≈ b.
        let x = ((c - b) * (c + b) + a * a) / (2.0 * c);
        let c_minus_x = ((c - a) * (c + a) + b * b) / (2.0 * c);
        let y = 2.0 * triangle_area(a, b, c) / c;
        let overlap = a * a * y.atan2(x) + b * b * y.atan2(c_minus_x) - c * y;
        let nu = 1.0 - overlap / (std::f64::consts::PI * a * a);
        (EclipseRegion::Penumbra, nu.clamp(0.0, 1.0))
    }
}

/// Area of the triangle with sides p, q, r, by Kahan's cancellation-safe Heron formula
/// (W. Kahan, "Miscalculating Area and Angles of a Needle-like Triangle", 2014). Returns 0
/// for sides that do not form a triangle.
fn triangle_area(p: f64, q: f64, r: f64) -> f64 {
    let mut s = [p, q, r];
    s.sort_by(|u, v| v.total_cmp(u));
    let [p, q, r] = s;
    let product = (p + (q + r)) * (r - (p - q)) * (r + (p - q)) * (p + (q - r));
    0.25 * product.max(0.0).sqrt()
}
