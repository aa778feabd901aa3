//! IGRF-14 synthesis against ppigrf 2.1.0 (fixtures/reference/igrf.csv, igrf_frames.csv),
//! against finite differences of its own potential, and against physical invariants.

use crate::common;

use std::str::FromStr;

use common::{FramesRow, reference_rows};

use hifitime::Epoch;
use nalgebra::Vector3;
use pdcal_ephem::igrf::{Igrf, IgrfError};
use serde::Deserialize;

/// Component tolerance against ppigrf (nT). The README gives 0.5 nT for the same model, of
/// which ≤ 0.25 nT comes from time conventions and float order; 1 nT is the acceptance bound
/// of issue 2. With ppigrf's time convention the expected error is ~1e-3 nT.
const REFERENCE_TOL_NT: f64 = 1.0;

#[derive(Debug, Deserialize)]
struct IgrfRow {
    id: u32,
    utc: String,
    lat_gd_deg: f64,
    lon_deg: f64,
    alt_km: f64,
    r_gc_km: f64,
    colat_gc_deg: f64,
    #[serde(rename = "B_r_nT")]
    b_r_nt: f64,
    #[serde(rename = "B_theta_nT")]
    b_theta_nt: f64,
    #[serde(rename = "B_phi_nT")]
    b_phi_nt: f64,
    #[serde(rename = "B_north_nT")]
    b_north_nt: f64,
    #[serde(rename = "B_east_nT")]
    b_east_nt: f64,
    #[serde(rename = "B_down_nT")]
    b_down_nt: f64,
    #[serde(rename = "F_nT")]
    f_nt: f64,
}

fn epoch(utc: &str) -> Epoch {
    Epoch::from_str(utc).expect("ISO 8601 UTC time parses")
}

fn model() -> Igrf {
    Igrf::igrf14().expect("embedded IGRF-14 parses")
}

#[test]
fn spherical_components_match_ppigrf() {
    let igrf = model();
    let rows: Vec<IgrfRow> = reference_rows("igrf.csv");
    assert_eq!(rows.len(), 60);
    let mut max_err: f64 = 0.0;
    for row in &rows {
        let b = igrf
            .field_spherical_nt(
                row.r_gc_km,
                row.colat_gc_deg.to_radians(),
                row.lon_deg.to_radians(),
                epoch(&row.utc),
            )
            .expect("reference point is inside the model");
        let reference = [row.b_r_nt, row.b_theta_nt, row.b_phi_nt];
        for (k, (mine, theirs)) in b.iter().zip(reference).enumerate() {
            let err = (mine - theirs).abs();
            max_err = max_err.max(err);
            assert!(
                err < REFERENCE_TOL_NT,
                "row {} component {k}: {mine} vs {theirs} nT",
                row.id
            );
        }
        let f = b.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(
            (f - row.f_nt).abs() < REFERENCE_TOL_NT,
            "row {} |B|",
            row.id
        );
    }
    println!("igrf.csv spherical components: max |error| = {max_err:.2e} nT");
}

/// WGS84 geodetic latitude and altitude to geocentric radius and colatitude (rad).
fn geodetic_to_geocentric(lat_gd_rad: f64, alt_km: f64) -> (f64, f64) {
    const A_KM: f64 = 6378.137;
    const F: f64 = 1.0 / 298.257223563;
    let e2 = F * (2.0 - F);
    let (s, c) = lat_gd_rad.sin_cos();
    let n = A_KM / (1.0 - e2 * s * s).sqrt();
    let rho = (n + alt_km) * c;
    let z = (n * (1.0 - e2) + alt_km) * s;
    (rho.hypot(z), rho.atan2(z))
}

#[test]
fn geodetic_north_east_down_match_ppigrf() {
    // Position tolerances: the table prints r to 1e-6 km and colatitude to 1e-8 deg.
    const R_TOL_KM: f64 = 1e-5;
    const COLAT_TOL_DEG: f64 = 1e-7;
    let igrf = model();
    let rows: Vec<IgrfRow> = reference_rows("igrf.csv");
    let mut max_err: f64 = 0.0;
    for row in &rows {
        let lat_gd = row.lat_gd_deg.to_radians();
        let (r_km, colat) = geodetic_to_geocentric(lat_gd, row.alt_km);
        assert!((r_km - row.r_gc_km).abs() < R_TOL_KM, "row {} r", row.id);
        assert!(
            (colat.to_degrees() - row.colat_gc_deg).abs() < COLAT_TOL_DEG,
            "row {} colatitude",
            row.id
        );
        let [b_r, b_theta, b_phi] = igrf
            .field_spherical_nt(r_km, colat, row.lon_deg.to_radians(), epoch(&row.utc))
            .expect("reference point is inside the model");
        // The geodetic normal is the radial direction tilted north by δ = lat_gd − lat_gc.
        let delta = lat_gd - (std::f64::consts::FRAC_PI_2 - colat);
        let (sd, cd) = delta.sin_cos();
        let north = -sd * b_r - cd * b_theta;
        let down = -cd * b_r + sd * b_theta;
        for (mine, theirs) in [
            (north, row.b_north_nt),
            (b_phi, row.b_east_nt),
            (down, row.b_down_nt),
        ] {
            let err = (mine - theirs).abs();
            max_err = max_err.max(err);
            assert!(
                err < REFERENCE_TOL_NT,
                "row {}: {mine} vs {theirs} nT",
                row.id
            );
        }
    }
    println!("igrf.csv geodetic N/E/D: max |error| = {max_err:.2e} nT");
}

#[test]
fn ecef_vectors_match_igrf_frames() {
    let igrf = model();
    let rows: Vec<FramesRow> = reference_rows("igrf_frames.csv");
    assert_eq!(rows.len(), 10);
    let mut max_err: f64 = 0.0;
    for row in &rows {
        let r_ecef = Vector3::new(row.x_ecef_km, row.y_ecef_km, row.z_ecef_km);
        let b = igrf
            .field_ecef_nt(&r_ecef, epoch(&row.utc))
            .expect("reference point is inside the model");
        let reference = Vector3::new(row.bx_ecef_nt, row.by_ecef_nt, row.bz_ecef_nt);
        let err = (b - reference).amax();
        max_err = max_err.max(err);
        assert!(err < REFERENCE_TOL_NT, "row {}: {b} vs {reference}", row.id);
    }
    println!("igrf_frames.csv ECEF: max |error| = {max_err:.2e} nT");
}

#[test]
fn gcrf_vectors_match_igrf_frames() {
    // Direction: the acceptance bound of issue 2 (a GMST-only rotation is off by 0.04-0.36°).
    // The frames module (IAU-76/FK5, UT1 = UTC) differs from skyfield's IAU 2006/2000A chain
    // with true UT1 by ≤ 0.004°, both in the rotation of the field and of the position.
    const DIRECTION_TOL_DEG: f64 = 0.02;
    // Magnitude: the position error of ≤ 0.004° (≤ 0.5 km at 7000 km) times the field
    // gradient ≲ 3|B|/r ≈ 20 nT/km bounds |B| changes by ~10 nT.
    const MAGNITUDE_TOL_NT: f64 = 10.0;
    let igrf = model();
    let (mut max_angle_deg, mut max_mag_nt): (f64, f64) = (0.0, 0.0);
    for row in &reference_rows::<FramesRow>("igrf_frames.csv") {
        let r_gcrf = Vector3::new(row.x_gcrf_km, row.y_gcrf_km, row.z_gcrf_km);
        let b = igrf
            .field_gcrf_nt(&r_gcrf, epoch(&row.utc))
            .expect("reference point is inside the model");
        let reference = Vector3::new(row.bx_gcrf_nt, row.by_gcrf_nt, row.bz_gcrf_nt);
        let angle_deg = b.angle(&reference).to_degrees();
        let mag_err = (b.norm() - reference.norm()).abs();
        max_angle_deg = max_angle_deg.max(angle_deg);
        max_mag_nt = max_mag_nt.max(mag_err);
        assert!(
            angle_deg < DIRECTION_TOL_DEG,
            "row {}: {angle_deg} deg",
            row.id
        );
        assert!(
            mag_err < MAGNITUDE_TOL_NT,
            "row {}: |B| off by {mag_err} nT",
            row.id
        );
    }
    println!(
        "igrf_frames.csv GCRF: max angle {max_angle_deg:.2e} deg, max |B| error {max_mag_nt:.2e} nT"
    );
}

/// splitmix64: a seeded generator for reproducible test points without a rand dependency.
struct SplitMix(u64);

impl SplitMix {
    fn next_unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_unit()
    }
}

#[test]
fn analytic_gradient_matches_finite_differences_of_potential() {
    // Central differences with step h in r (km) and h_ang in θ, φ (rad).
    // Round-off: ε|V|/(step·scale) with |V| ≤ a·70000 nT ≈ 4.5e8 nT km, ε = 2.2e-16:
    //   r: 4.5e8·2.2e-16/1e-3 ≈ 1e-4 nT; θ, φ: 4.5e8·2.2e-16/(6371·1e-6·sin θ) ≲ 1e-3 nT
    //   for sin θ ≥ 0.02 (θ within 1.15°..178.85°).
    // Truncation: h²/6·|V'''| with |V'''| ≲ (n+3)³|V|/r³ (n ≤ 13) is < 1e-7 nT for both.
    // So 5e-3 nT bounds the difference with margin, while any sign or index error in the
    // analytic gradient is ≥ 1 nT.
    const H_R_KM: f64 = 1e-3;
    const H_ANG_RAD: f64 = 1e-6;
    const FD_TOL_NT: f64 = 5e-3;
    let igrf = model();
    let mut rng = SplitMix(0x1DEA_5EED);
    let first = epoch("1900-01-01T00:00:00Z");
    let span_s = (epoch("2030-01-01T00:00:00Z") - first).to_seconds();
    let mut max_err: f64 = 0.0;
    for i in 0..200 {
        let t = first + hifitime::Duration::from_seconds(rng.uniform(0.0, span_s));
        let coeffs = igrf.coefficients_at(t).expect("inside the model");
        let r = rng.uniform(6371.2, 12000.0);
        // Every tenth point within 1.3° of a pole.
        let colat = if i % 10 == 0 {
            let near = rng.uniform(0.02, 0.023);
            if i % 20 == 0 {
                near
            } else {
                std::f64::consts::PI - near
            }
        } else {
            rng.uniform(0.02, std::f64::consts::PI - 0.02)
        };
        let lon = rng.uniform(-std::f64::consts::PI, std::f64::consts::PI);
        let v = |r: f64, th: f64, ph: f64| coeffs.potential_nt_km(r, th, ph).expect("valid point");
        let fd = [
            -(v(r + H_R_KM, colat, lon) - v(r - H_R_KM, colat, lon)) / (2.0 * H_R_KM),
            -(v(r, colat + H_ANG_RAD, lon) - v(r, colat - H_ANG_RAD, lon)) / (2.0 * H_ANG_RAD * r),
            -(v(r, colat, lon + H_ANG_RAD) - v(r, colat, lon - H_ANG_RAD))
                / (2.0 * H_ANG_RAD * r * colat.sin()),
        ];
        let b = coeffs
            .field_spherical_nt(r, colat, lon)
            .expect("valid point");
        for k in 0..3 {
            let err = (b[k] - fd[k]).abs();
            max_err = max_err.max(err);
            assert!(
                err < FD_TOL_NT,
                "point {i} component {k}: {} vs {}",
                b[k],
                fd[k]
            );
        }
    }
    println!("analytic vs finite-difference gradient: max |error| = {max_err:.2e} nT");
}

#[test]
fn surface_field_magnitude_is_within_known_bounds() {
    // Since 2000 the main field at the surface spans about 22,000 nT (South Atlantic anomaly)
    // to 67,000 nT (south of Australia, near the south magnetic pole). The dipole has decayed
    // by ~9 % since 1900, when the maximum exceeded 67,000 nT, so the grid covers 2000-2030.
    // The anomaly's minimum falls by ~30 nT/yr: on this grid at r = a it is 22,911 nT in 2000
    // and 21,949 nT at the end of the 2025-2030 extrapolation, hence a floor of 21,500 nT.
    const F_MIN_NT: f64 = 21_500.0;
    const F_MAX_NT: f64 = 67_000.0;
    let igrf = model();
    for utc in [
        "2000-01-01T00:00:00Z",
        "2011-11-04T18:29:45Z",
        "2020-06-01T00:00:00Z",
        "2029-12-31T00:00:00Z",
    ] {
        let mut extremes = (f64::INFINITY, 0.0f64);
        let coeffs = igrf.coefficients_at(epoch(utc)).expect("inside the model");
        for i in 0..=36 {
            for j in 0..72 {
                let colat = (5.0 * i as f64).to_radians();
                let lon = (5.0 * j as f64).to_radians();
                let b = coeffs
                    .field_spherical_nt(6371.2, colat, lon)
                    .expect("valid point");
                let f = b.iter().map(|x| x * x).sum::<f64>().sqrt();
                extremes = (extremes.0.min(f), extremes.1.max(f));
                assert!(
                    (F_MIN_NT..=F_MAX_NT).contains(&f),
                    "{utc} colat {i} lon {j}: {f} nT"
                );
            }
        }
        println!(
            "{utc}: surface |B| on the grid {:.0} to {:.0} nT",
            extremes.0, extremes.1
        );
    }
}

#[test]
fn field_is_continuous_through_the_poles() {
    // Near the axis the ECEF field must approach its on-axis value; the field gradient is
    // ≲ 3|B|/r ≈ 15 nT/km at 7000 km, so 1e-6 km off-axis moves B by < 1e-4 nT.
    const POLE_TOL_NT: f64 = 1e-3;
    let igrf = model();
    let t = epoch("2011-11-04T18:29:45Z");
    for z in [7000.0, -7000.0] {
        let on_axis = igrf
            .field_ecef_nt(&Vector3::new(0.0, 0.0, z), t)
            .expect("valid");
        for (x, y) in [(1e-6, 0.0), (0.0, 1e-6), (-1e-6, -1e-6)] {
            let near = igrf
                .field_ecef_nt(&Vector3::new(x, y, z), t)
                .expect("valid");
            assert!((near - on_axis).amax() < POLE_TOL_NT, "{near} vs {on_axis}");
        }
        assert!(on_axis.norm() > 20_000.0 && on_axis.iter().all(|c| c.is_finite()));
    }
}

#[test]
fn time_interpolation_follows_elapsed_time_and_secular_variation() {
    let igrf = model();
    // At an epoch the coefficients are the file's column (g10 = −29350.0 nT in 2025).
    let at_2025 = igrf
        .coefficients_at(epoch("2025-01-01T00:00:00Z"))
        .expect("valid");
    assert_eq!(at_2025.g[1][0], -29350.0);
    // 2027-07-03T00:00 is 913 of the 1826 days from 2025 to 2030 (no leap seconds in between):
    // exactly half way, so g10 = (−29350.0 − 29287.0)/2 and h11 = (4545.5 + 4438.0)/2.
    let mid = igrf
        .coefficients_at(epoch("2027-07-03T00:00:00Z"))
        .expect("valid");
    assert!((mid.g[1][0] + 29318.5).abs() < 1e-9);
    assert!((mid.h[1][1] - 4491.75).abs() < 1e-9);
    // The last column is valid up to and including 2030-01-01, and nothing after it.
    assert!(igrf.coefficients_at(epoch("2030-01-01T00:00:00Z")).is_ok());
    for utc in ["2030-01-01T00:00:01Z", "1899-12-31T23:59:59Z"] {
        let err = igrf.field_spherical_nt(7000.0, 1.0, 0.0, epoch(utc));
        assert!(
            matches!(err, Err(IgrfError::OutOfRange { .. })),
            "{utc}: {err:?}"
        );
    }
}

#[test]
fn invalid_positions_are_rejected() {
    let igrf = model();
    let t = epoch("2011-11-04T18:29:45Z");
    for (r, colat, lon) in [
        (0.0, 1.0, 0.0),
        (-7000.0, 1.0, 0.0),
        (7000.0, -0.1, 0.0),
        (7000.0, 3.2, 0.0),
        (f64::NAN, 1.0, 0.0),
        (7000.0, 1.0, f64::INFINITY),
    ] {
        let result = igrf.field_spherical_nt(r, colat, lon, t);
        assert!(
            matches!(result, Err(IgrfError::InvalidPosition { .. })),
            "{r} {colat} {lon}"
        );
    }
    assert!(igrf.field_ecef_nt(&Vector3::zeros(), t).is_err());
}
