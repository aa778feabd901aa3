//! `gcrf_to_itrf` against `fixtures/reference/igrf_frames.csv` (skyfield, IAU 2006/2000A,
//! true UT1, polar motion ignored).

use crate::common;

use common::{FramesRow, reference_rows};
use nalgebra::Vector3;
use pdcal_ephem::{frames, time};

fn rows() -> Vec<FramesRow> {
    reference_rows("igrf_frames.csv")
}

fn angle_deg(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    a.cross(b).norm().atan2(a.dot(b)).to_degrees()
}

/// Earth rotation rate, deg/s, to turn UT1 − UTC into the angle our UT1 = UTC costs.
const EARTH_RATE_DEG_S: f64 = 360.985_647_366 / 86_400.0;

#[test]
fn ecef_position_and_field_rotate_into_the_reference_gcrf() {
    let mut max_dir_deg = 0.0_f64;
    let mut max_b_deg = 0.0_f64;
    let mut max_residual_deg = 0.0_f64;
    for row in rows() {
        let t = time::parse_utc(&row.utc).expect("valid utc");
        let r_t = frames::gcrf_to_itrf(t).transpose();
        let x_gcrf = r_t * Vector3::new(row.x_ecef_km, row.y_ecef_km, row.z_ecef_km);
        let x_ref = Vector3::new(row.x_gcrf_km, row.y_gcrf_km, row.z_gcrf_km);
        let b_gcrf = r_t * Vector3::new(row.bx_ecef_nt, row.by_ecef_nt, row.bz_ecef_nt);
        let b_ref = Vector3::new(row.bx_gcrf_nt, row.by_gcrf_nt, row.bz_gcrf_nt);
        let dir = angle_deg(&x_gcrf, &x_ref);
        let b = angle_deg(&b_gcrf, &b_ref);
        // The model error proper: evaluate at UTC + (UT1 − UTC), which feeds the true UT1 to
        // GMST (precession-nutation move by < 1e-9 deg in that second).
        let t_ut1 = time::offset(t, row.ut1_minus_utc_s).expect("finite");
        let r_t_ut1 = frames::gcrf_to_itrf(t_ut1).transpose();
        let dir_ut1 = angle_deg(
            &(r_t_ut1 * Vector3::new(row.x_ecef_km, row.y_ecef_km, row.z_ecef_km)),
            &x_ref,
        );
        let b_ut1 = angle_deg(
            &(r_t_ut1 * Vector3::new(row.bx_ecef_nt, row.by_ecef_nt, row.bz_ecef_nt)),
            &b_ref,
        );
        max_residual_deg = max_residual_deg.max(dir_ut1).max(b_ut1);
        // UT1 = UTC costs at most |UT1 − UTC| × ω⊕ on top of that.
        let ut1_cost_deg = row.ut1_minus_utc_s.abs() * EARTH_RATE_DEG_S;
        assert!(
            dir <= ut1_cost_deg + 5e-5 && b <= ut1_cost_deg + 5e-5,
            "id {}",
            row.id
        );
        max_dir_deg = max_dir_deg.max(dir);
        max_b_deg = max_b_deg.max(b);
        assert!(
            (x_gcrf.norm() - x_ref.norm()).abs() < 1e-6,
            "id {}: a rotation keeps length",
            row.id
        );
    }
    // Acceptance bar of issue 2: inertial vectors within 0.02 deg. We allow 0.005 deg: the
    // UT1 = UTC choice costs up to 0.9 s × 0.0042 deg/s = 0.0038 deg, IAU 76/80 (truncated)
    // versus 2006/2000A well under 0.001 deg (fixtures/reference/README.md).
    // Measured: position 0.00147 deg, field 0.00127 deg (row 3 has UT1 - UTC = -0.36 s).
    assert!(
        max_dir_deg < 0.005,
        "position direction error {max_dir_deg} deg"
    );
    assert!(max_b_deg < 0.005, "field direction error {max_b_deg} deg");
    // With the true UT1 the model alone must be within 5e-5 deg (0.18 arcsec): IAU-1980 versus
    // 2000A nutation differs by < 0.1 arcsec, the series truncation by <= 0.019 arcsec, the
    // 2006 versus 1976 precession by a few mas over 2005-2030. Measured: 9.2e-6 deg (0.033").
    assert!(
        max_residual_deg < 5e-5,
        "model residual {max_residual_deg} deg"
    );
}
