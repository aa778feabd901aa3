//! The RAX-2-like TLE (docs/rax2-scenario.md) against `fixtures/reference/rax2_tle_teme.csv`
//! (python-sgp4 WGS-72 'i' for TEME; skyfield TEME -> GCRF, IAU 2006/2000A).

use crate::common;

use common::reference_rows;
use nalgebra::Vector3;
use pdcal_ephem::{OrbitSource, TleOrbit, time};
use serde::Deserialize;

const L1: &str = "1 37853U 11061D   11308.77065972  .00000000  00000-0  20000-4 0  9997";
const L2: &str = "2 37853 101.7000  50.0000 0300509 130.0000 230.0000 14.86144463  1000";

#[derive(Deserialize)]
struct Row {
    tsince_min: f64,
    utc: String,
    x_teme_km: f64,
    y_teme_km: f64,
    z_teme_km: f64,
    vx_teme_km_s: f64,
    vy_teme_km_s: f64,
    vz_teme_km_s: f64,
    x_gcrf_km: f64,
    y_gcrf_km: f64,
    z_gcrf_km: f64,
    vx_gcrf_km_s: f64,
    vy_gcrf_km_s: f64,
    vz_gcrf_km_s: f64,
}

#[test]
fn rax2_tle_in_teme_and_gcrf() {
    let tle = TleOrbit::from_lines(L1, L2).expect("the scenario TLE has valid checksums");
    for row in reference_rows::<Row>("rax2_tle_teme.csv") {
        // The utc column is the exact instant (the TLE epoch is 0.19 ms before 18:29:45Z).
        let t = time::parse_utc(&row.utc).expect("valid utc");
        assert!((time::seconds_between(tle.epoch(), t) / 60.0 - row.tsince_min).abs() < 1e-9);

        let teme = tle.state_teme(t).expect("propagates");
        let r_teme = Vector3::new(row.x_teme_km, row.y_teme_km, row.z_teme_km);
        let v_teme = Vector3::new(row.vx_teme_km_s, row.vy_teme_km_s, row.vz_teme_km_s);
        let dr_teme_m = (teme.r_teme_km - r_teme).norm() * 1e3;
        // TEME acceptance 1 m (measured 2.2e-5 m); a faithful port is at 1e-6 km, so 1e-6 km/s
        // is ample for v.
        assert!(
            dr_teme_m < 1.0,
            "t={}: TEME off by {dr_teme_m} m",
            row.tsince_min
        );
        assert!((teme.v_teme_km_s - v_teme).norm() < 1e-6);

        let gcrf = tle.state_gcrf(t).expect("propagates");
        let r_gcrf = Vector3::new(row.x_gcrf_km, row.y_gcrf_km, row.z_gcrf_km);
        let v_gcrf = Vector3::new(row.vx_gcrf_km_s, row.vy_gcrf_km_s, row.vz_gcrf_km_s);
        let dr_gcrf_m = (gcrf.r_gcrf_km - r_gcrf).norm() * 1e3;
        let dv_gcrf_mm_s = (gcrf.v_gcrf_km_s - v_gcrf).norm() * 1e6;
        // GCRF acceptance is 50 m (issue 2); we hold the README's 5 m for a full IAU-76/FK5
        // chain against skyfield's 2006/2000A (nutation models differ by < 0.1", truncation
        // <= 0.7 m). Measured: 0.68 m; dropping nutation would cost ~500 m.
        assert!(
            dr_gcrf_m < 5.0,
            "t={}: GCRF off by {dr_gcrf_m} m",
            row.tsince_min
        );
        // The same angle on a 7.5 km/s velocity: 5 m / 7000 km × 7.5 km/s ≈ 5.4 mm/s.
        // Measured: 0.75 mm/s.
        assert!(
            dv_gcrf_mm_s < 5.4,
            "t={}: GCRF v off by {dv_gcrf_mm_s} mm/s",
            row.tsince_min
        );
    }
}
