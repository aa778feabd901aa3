//! The Earth ellipsoid Basilisk uses and its authalic sphere, on which the cells lie.

/// Astronomical unit, km (the value Basilisk uses).
pub const AU_KM: f64 = 149_597_870.693;
/// Earth equatorial radius used by Basilisk (`REQ_EARTH`), km.
pub const REQ_EARTH_KM: f64 = 6378.1366;
/// Earth polar radius used by Basilisk (`RP_EARTH`), km.
pub const RP_EARTH_KM: f64 = 6356.7519;

/// Authalic radius of the Basilisk Earth ellipsoid, km (6371.0068): the radius of the sphere
/// with the ellipsoid's area.
pub fn authalic_radius_km() -> f64 {
    let e = eccentricity();
    let t0 = REQ_EARTH_KM * REQ_EARTH_KM * 0.5;
    let t1 = (1.0 - e * e) / 2.0 / e;
    let t2 = ((1.0 + e) / (1.0 - e)).ln();
    (t0 * (1.0 + t1 * t2)).sqrt()
}

fn eccentricity() -> f64 {
    (1.0 - (RP_EARTH_KM / REQ_EARTH_KM).powi(2)).sqrt()
}

/// Authalic latitude beta(phi) of geodetic latitude `phi` (rad), Basilisk's truncated series:
/// beta = phi - t0 sin 2phi + t1 sin 4phi - t2 sin 6phi.
pub fn authalic_latitude(phi: f64) -> f64 {
    let e2 = eccentricity().powi(2);
    let (e4, e6) = (e2 * e2, e2 * e2 * e2);
    let t0 = e2 / 3.0 + 31.0 * e4 / 180.0 + 59.0 * e6 / 560.0;
    let t1 = 17.0 * e4 / 360.0 + 61.0 * e6 / 1260.0;
    let t2 = 383.0 * e6 / 45360.0;
    phi - (t0 * (2.0 * phi).sin() - t1 * (4.0 * phi).sin() + t2 * (6.0 * phi).sin())
}
