//! Conical eclipse model (Montenbruck & Gill §3.4.2) against fixtures/reference/eclipse.csv,
//! plus region boundaries, continuity and range invariants.

use crate::common;

use common::reference_rows;
use nalgebra::Vector3;
use pdcal_ephem::eclipse::{
    EARTH_RADIUS_KM, EclipseRegion, SUN_RADIUS_KM, eclipse, illuminated_fraction,
    illuminated_fraction_with_radii,
};
use serde::Deserialize;

/// Acceptance bound of issue 2 on ν.
const ACCEPT_TOL: f64 = 0.01;
/// Same formula and radii: the table prints positions to 1e-6 km, which moves c by
/// ≤ 1e-6/6700 ≈ 1.5e-10 rad; with |dν/dc| ≤ 2/(π a) ≈ 140 /rad in LEO that is ≤ 2e-8.
const SAME_FORMULA_TOL: f64 = 1e-7;
/// Angles are printed to 1e-9 deg; position rounding adds < 1e-8 deg.
const ANGLE_TOL_DEG: f64 = 2e-8;
/// The reference computes c with acos, whose round-off near c = 0 is √(2ε) ≈ 2.1e-8 rad
/// ≈ 1.2e-6 deg (row 0 prints 8.5e-7 deg for an exactly anti-Sun satellite); the atan2 here
/// does not have it.
const SEPARATION_TOL_DEG: f64 = 2e-6;

#[derive(Debug, Deserialize)]
struct EclipseRow {
    id: u32,
    x_sat_km: f64,
    y_sat_km: f64,
    z_sat_km: f64,
    x_sun_km: f64,
    y_sun_km: f64,
    z_sun_km: f64,
    a_deg: f64,
    b_deg: f64,
    c_deg: f64,
    nu: f64,
    region: String,
    nu_bsk: f64,
}

fn rows() -> Vec<EclipseRow> {
    reference_rows("eclipse.csv")
}

fn positions(row: &EclipseRow) -> (Vector3<f64>, Vector3<f64>) {
    (
        Vector3::new(row.x_sat_km, row.y_sat_km, row.z_sat_km),
        Vector3::new(row.x_sun_km, row.y_sun_km, row.z_sun_km),
    )
}

#[test]
fn illuminated_fraction_matches_reference_table() {
    let rows = rows();
    assert_eq!(rows.len(), 30);
    let mut max_err: f64 = 0.0;
    for row in &rows {
        let (sat, sun) = positions(row);
        let nu = illuminated_fraction(&sat, &sun);
        let err = (nu - row.nu).abs();
        max_err = max_err.max(err);
        assert!(err < ACCEPT_TOL, "row {}: {nu} vs {}", row.id, row.nu);
        assert!(err < SAME_FORMULA_TOL, "row {}: {nu} vs {}", row.id, row.nu);
    }
    println!("eclipse.csv nu: max |error| = {max_err:.2e}");
}

#[test]
fn angles_and_regions_match_reference_table() {
    let (mut max_ab_deg, mut max_c_deg): (f64, f64) = (0.0, 0.0);
    for row in &rows() {
        let (sat, sun) = positions(row);
        let e = eclipse(&sat, &sun, EARTH_RADIUS_KM, SUN_RADIUS_KM);
        for (mine, theirs, tol) in [
            (e.sun_angle_rad, row.a_deg, ANGLE_TOL_DEG),
            (e.earth_angle_rad, row.b_deg, ANGLE_TOL_DEG),
            (e.separation_rad, row.c_deg, SEPARATION_TOL_DEG),
        ] {
            let err = (mine.to_degrees() - theirs).abs();
            if tol == SEPARATION_TOL_DEG {
                max_c_deg = max_c_deg.max(err);
            } else {
                max_ab_deg = max_ab_deg.max(err);
            }
            assert!(
                err < tol,
                "row {}: {} vs {theirs} deg",
                row.id,
                mine.to_degrees()
            );
        }
        let expected = match row.region.as_str() {
            "sun" => EclipseRegion::Sun,
            "penumbra" => EclipseRegion::Penumbra,
            "umbra" => EclipseRegion::Umbra,
            "annular" => EclipseRegion::Annular,
            other => panic!("row {}: unknown region {other}", row.id),
        };
        assert_eq!(e.region, expected, "row {}", row.id);
    }
    println!("eclipse.csv angles: max |error| a, b {max_ab_deg:.2e} deg, c {max_c_deg:.2e} deg");
}

#[test]
fn explicit_radii_reproduce_basilisk() {
    // Basilisk's radii (Earth 6378.1366 km, Sun 695000 km) with the same formula reproduce
    // `nu_bsk` to ≤ 7.5e-10 per the README; position rounding allows up to 2e-8 (see above).
    let mut max_err: f64 = 0.0;
    for row in &rows() {
        let (sat, sun) = positions(row);
        let nu = illuminated_fraction_with_radii(&sat, &sun, 6378.1366, 695_000.0);
        let err = (nu - row.nu_bsk).abs();
        max_err = max_err.max(err);
        assert!(
            err < SAME_FORMULA_TOL,
            "row {}: {nu} vs {}",
            row.id,
            row.nu_bsk
        );
    }
    println!("eclipse.csv nu_bsk with Basilisk radii: max |error| = {max_err:.2e}");
}

const AU_KM: f64 = 149_597_870.7;

/// Satellite at radius `r_km`, `psi_rad` from the anti-Sun axis; Sun on +x at 1 AU.
fn geometry(r_km: f64, psi_rad: f64) -> (Vector3<f64>, Vector3<f64>) {
    let sat = Vector3::new(-r_km * psi_rad.cos(), r_km * psi_rad.sin(), 0.0);
    (sat, Vector3::new(AU_KM, 0.0, 0.0))
}

fn region_at(r_km: f64, psi_rad: f64) -> EclipseRegion {
    let (sat, sun) = geometry(r_km, psi_rad);
    eclipse(&sat, &sun, EARTH_RADIUS_KM, SUN_RADIUS_KM).region
}

fn nu_at(r_km: f64, psi_rad: f64) -> f64 {
    let (sat, sun) = geometry(r_km, psi_rad);
    illuminated_fraction(&sat, &sun)
}

/// The ψ in [lo, hi] where the region switches from `inner` (at lo) to something else,
/// found by bisection to ~1e-15 rad.
fn boundary(r_km: f64, inner: EclipseRegion, mut lo: f64, mut hi: f64) -> f64 {
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if region_at(r_km, mid) == inner {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[test]
fn fraction_is_continuous_at_the_region_boundaries() {
    // One ULP-scale step (1e-12 rad) across a boundary may move ν by at most
    // |dν/dψ|·2e-12 ≲ 1e-9; 1e-6 allows for the square-root behaviour of ν near the outer
    // penumbra edge (ν ∝ δc^(3/2) there, so still ≪ 1e-6).
    const JUMP_TOL: f64 = 1e-6;
    const STEP_RAD: f64 = 1e-12;
    // LEO: umbra -> penumbra -> sun.
    let r_leo = 6778.137;
    let umbra_edge = boundary(r_leo, EclipseRegion::Umbra, 0.0, 1.5);
    let sun_edge = boundary(r_leo, EclipseRegion::Penumbra, umbra_edge + 1e-9, 1.5);
    assert_eq!(region_at(r_leo, sun_edge + 1e-6), EclipseRegion::Sun);
    assert!(nu_at(r_leo, umbra_edge + STEP_RAD) < JUMP_TOL);
    assert!(nu_at(r_leo, umbra_edge - STEP_RAD) == 0.0);
    assert!(1.0 - nu_at(r_leo, sun_edge - STEP_RAD) < JUMP_TOL);
    assert!(nu_at(r_leo, sun_edge + STEP_RAD) == 1.0);
    // Beyond the umbra's apex (~1.38e6 km): annular -> penumbra, ν → 1 − b²/a².
    let r_far = 1.5e6;
    assert_eq!(region_at(r_far, 0.0), EclipseRegion::Annular);
    let annular_edge = boundary(r_far, EclipseRegion::Annular, 0.0, 0.1);
    let inside = nu_at(r_far, annular_edge - STEP_RAD);
    let outside = nu_at(r_far, annular_edge + STEP_RAD);
    assert_eq!(
        region_at(r_far, annular_edge + 1e-9),
        EclipseRegion::Penumbra
    );
    assert!((inside - outside).abs() < JUMP_TOL, "{inside} vs {outside}");
}

#[test]
fn fraction_is_monotonic_and_bounded_through_the_shadow() {
    // A LEO sweep from the anti-Sun point towards the Sun in 1e-6 rad steps through the
    // shadow edge. |dν/dc| ≤ 2/(π a) ≈ 137 /rad and |dc/dψ| < 3 here, so one step moves ν by
    // < 4.1e-4; 1e-3 catches any jump, and ν must never decrease as ψ grows.
    const MAX_STEP_JUMP: f64 = 1e-3;
    // Round-off in the overlap area: ~100 ε relative to π a² (the b² and c·y terms cancel).
    const MONOTONIC_SLACK: f64 = 1e-12;
    let r_leo = 6778.137;
    let umbra_edge = boundary(r_leo, EclipseRegion::Umbra, 0.0, 1.5);
    let start = umbra_edge - 1e-3;
    let mut previous = nu_at(r_leo, start);
    let mut penumbra_steps = 0;
    for k in 1..20_000 {
        let psi = start + k as f64 * 1e-6;
        let nu = nu_at(r_leo, psi);
        assert!((0.0..=1.0).contains(&nu), "psi {psi}: {nu}");
        assert!(
            nu >= previous - MONOTONIC_SLACK,
            "psi {psi}: {nu} < {previous}"
        );
        assert!(
            nu - previous < MAX_STEP_JUMP,
            "psi {psi}: jump {}",
            nu - previous
        );
        if nu > 0.0 && nu < 1.0 {
            penumbra_steps += 1;
        }
        previous = nu;
    }
    assert_eq!(previous, 1.0, "the sweep ends in sunlight");
    assert!(penumbra_steps > 100, "the sweep resolves the penumbra");
}

#[test]
fn fraction_stays_in_unit_interval_for_any_geometry() {
    // Includes distances from inside the Earth to beyond the umbra's apex, and degenerate
    // positions (origin, inside the Earth, at the Sun), none of which may panic.
    for &r in &[
        0.0, 1000.0, 6378.137, 6500.0, 7000.0, 42164.0, 384_400.0, 1.6e6, 1e7,
    ] {
        for k in 0..=360 {
            let nu = nu_at(r, (k as f64).to_radians());
            assert!((0.0..=1.0).contains(&nu), "r {r} psi {k} deg: {nu}");
        }
    }
    let sun = Vector3::new(AU_KM, 0.0, 0.0);
    assert!((0.0..=1.0).contains(&illuminated_fraction(&sun, &sun)));
    assert!(illuminated_fraction(&Vector3::new(f64::NAN, 0.0, 0.0), &sun).is_nan());
}
