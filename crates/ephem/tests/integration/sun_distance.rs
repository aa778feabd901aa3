//! The Sun's distance factor `(1 AU / r)^2` against the known extremes of the Earth's orbit
//! (eccentricity 0.0167: perihelion early January, aphelion early July).

use nalgebra::Vector3;
use pdcal_ephem::sun::AU_KM;
use pdcal_ephem::{LowPrecisionSun, SunEphemeris, sun_distance_factor, time};

fn factor_at(utc: &str, r_sat_gcrf_km: &Vector3<f64>) -> f64 {
    let t = time::parse_utc(utc).expect("valid epoch");
    sun_distance_factor(r_sat_gcrf_km, &LowPrecisionSun.sun_gcrf_km(t))
}

#[test]
fn perihelion_and_aphelion_bracket_the_year() {
    let e: f64 = 0.016_71;
    let geocentre = Vector3::zeros();
    let perihelion = factor_at("2012-01-05T00:00:00Z", &geocentre);
    let aphelion = factor_at("2012-07-05T00:00:00Z", &geocentre);
    // (1/(1-e))^2 and (1/(1+e))^2, to the Almanac series' 1e-4 in distance.
    assert!(
        (perihelion - (1.0 - e).powi(-2)).abs() < 5e-4,
        "{perihelion}"
    );
    assert!((aphelion - (1.0 + e).powi(-2)).abs() < 5e-4, "{aphelion}");
    assert!(((perihelion / aphelion) - 1.0 - 0.069).abs() < 2e-3);
}

#[test]
fn the_distance_is_from_the_spacecraft() {
    let sun = Vector3::new(AU_KM, 0.0, 0.0);
    assert_eq!(sun_distance_factor(&Vector3::zeros(), &sun), 1.0);
    let toward = sun_distance_factor(&Vector3::new(7000.0, 0.0, 0.0), &sun);
    let expect = (AU_KM / (AU_KM - 7000.0)).powi(2);
    assert!((toward - expect).abs() < 1e-15, "{toward} vs {expect}");
    assert!(!sun_distance_factor(&sun, &sun).is_finite());
}
