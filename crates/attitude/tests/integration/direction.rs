//! Photodiode normals: Eq. (16), its inverse, the Eq. (23)-(24) partials, and the
//! tangent-plane parametrisation.

use crate::common;

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::Vector3;
use pdcal_attitude::{
    TANGENT_BASIS_SINGULAR_DIRECTION, az_el_from_normal, normal_from_az_el, normal_partials,
    rotate_normal, rotate_normal_in, tangent_basis, tangent_basis_about,
};

/// Unit-size products and sums: tens of ulps.
const ROUNDING: f64 = 1e-14;

fn wrap(angle: f64) -> f64 {
    (angle + PI).rem_euclid(2.0 * PI) - PI
}

#[test]
fn normal_is_unit_and_round_trips_away_from_poles() {
    let mut rng = common::rng(41);
    let mut worst: f64 = 0.0;
    for _ in 0..2000 {
        let az = common::uniform(&mut rng, -PI, PI);
        // Within 1 deg of the poles azimuth loses digits as eps / cos(el); stop at 89 deg.
        let el = common::uniform(&mut rng, -89f64.to_radians(), 89f64.to_radians());
        let n = normal_from_az_el(az, el);
        assert!((n.norm() - 1.0).abs() < ROUNDING);
        let (az2, el2) = az_el_from_normal(&n);
        worst = worst.max(wrap(az2 - az).abs()).max((el2 - el).abs());
    }
    eprintln!("az/el round trip worst {worst:e} rad");
    // atan2 of exact-to-rounding components, divided by cos(el) >= 0.017: < 1e-13.
    assert!(worst < 1e-12);
    // The poles themselves: elevation exact, azimuth reported as 0.
    assert_eq!(az_el_from_normal(&Vector3::z()), (0.0, FRAC_PI_2));
    assert_eq!(az_el_from_normal(&-Vector3::z()), (0.0, -FRAC_PI_2));
}

#[test]
fn partials_match_central_differences() {
    // Step 1e-5 rad: truncation ~h^2/6 = 2e-11, rounding ~eps/h = 2e-11, so relative
    // errors ~1e-10 where a component is not tiny (> 1e-3), absolute 1e-9 elsewhere.
    let h = 1e-5;
    let mut rng = common::rng(42);
    let mut worst_rel: f64 = 0.0;
    for _ in 0..200 {
        let az = common::uniform(&mut rng, -PI, PI);
        let el = common::uniform(&mut rng, -FRAC_PI_2, FRAC_PI_2);
        let (d_az, d_el) = normal_partials(az, el);
        let fd_az = (normal_from_az_el(az + h, el) - normal_from_az_el(az - h, el)) / (2.0 * h);
        let fd_el = (normal_from_az_el(az, el + h) - normal_from_az_el(az, el - h)) / (2.0 * h);
        for (analytic, numeric) in [(d_az, fd_az), (d_el, fd_el)] {
            for k in 0..3 {
                let err = (analytic[k] - numeric[k]).abs();
                if analytic[k].abs() > 1e-3 {
                    worst_rel = worst_rel.max(err / analytic[k].abs());
                    assert!(err / analytic[k].abs() < 1e-6);
                } else {
                    assert!(err < 1e-9);
                }
            }
        }
    }
    eprintln!("normal_partials vs central differences: worst relative {worst_rel:e}");
}

#[test]
fn paper_eq_24_y_sign_is_corrected() {
    // Eq. (24) prints +sin(el) sin(az); the derivative of Eq. (16) is -sin(el) sin(az).
    let (az, el) = (30f64.to_radians(), 40f64.to_radians());
    let (_, d_el) = normal_partials(az, el);
    assert!((d_el.y + el.sin() * az.sin()).abs() < ROUNDING);
}

/// Probe normals: random, the six axes (poles of Eq. 16 included), and the singular
/// direction with points approaching it.
fn probe_normals() -> Vec<Vector3<f64>> {
    let mut rng = common::rng(43);
    let mut out: Vec<Vector3<f64>> = (0..2000).map(|_| common::unit3(&mut rng)).collect();
    for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
        out.push(axis);
        out.push(-axis);
    }
    let s = TANGENT_BASIS_SINGULAR_DIRECTION;
    out.push(s);
    let off = s.cross(&Vector3::x()).normalize();
    for angle in [1e-9, 1e-6, 1.4e-5, 1e-4, 1e-2] {
        out.push((s + off * angle).normalize());
    }
    out
}

#[test]
fn tangent_basis_is_orthonormal_everywhere() {
    for n in probe_normals() {
        let (e1, e2) = tangent_basis(&n);
        for v in [e1, e2] {
            assert!((v.norm() - 1.0).abs() < ROUNDING, "n = {n}");
            assert!(v.dot(&n).abs() < ROUNDING, "n = {n}");
        }
        assert!(e1.dot(&e2).abs() < ROUNDING, "n = {n}");
        // Right-handed (e1, e2, n).
        assert!((e1.cross(&e2) - n).norm() < ROUNDING, "n = {n}");
    }
}

#[test]
fn tangent_basis_is_continuous_through_the_poles() {
    // Approaching +-z along different azimuths gives the same limit (the az/el
    // partials do not: their azimuth direction turns with az). A step of 1e-7 rad may
    // move the basis by ~1e-7 times a Lipschitz constant of order 1 this far (>= 55 deg)
    // from the singular direction; tolerance 1e-6.
    for pole_el in [FRAC_PI_2, -FRAC_PI_2] {
        let at_pole = tangent_basis(&normal_from_az_el(0.0, pole_el));
        for az_deg in [0.0, 45.0, 90.0, 180.0, -135.0] {
            let near =
                normal_from_az_el(f64::to_radians(az_deg), pole_el - pole_el.signum() * 1e-7);
            let (e1, e2) = tangent_basis(&near);
            assert!((e1 - at_pole.0).norm() < 1e-6 && (e2 - at_pole.1).norm() < 1e-6);
        }
    }
    // And everywhere at least 10 deg from the singular direction.
    let mut rng = common::rng(44);
    let mut worst: f64 = 0.0;
    for _ in 0..2000 {
        let n = common::unit3(&mut rng);
        if n.dot(&TANGENT_BASIS_SINGULAR_DIRECTION) > 10f64.to_radians().cos() {
            continue;
        }
        let moved = (n + common::unit3(&mut rng) * 1e-7).normalize();
        let (a, b) = (tangent_basis(&n), tangent_basis(&moved));
        worst = worst.max((a.0 - b.0).norm().max((a.1 - b.1).norm()) / (moved - n).norm());
    }
    // The basis turns like 2/sin(angle to the singular direction) near it: 11.5 at the
    // 10 deg edge; 100 flags a real jump (a discontinuity gives ~1e7).
    eprintln!(
        "tangent_basis: worst |d basis| / |d n| beyond 10 deg of the singularity: {worst:.2}"
    );
    assert!(worst < 100.0);
}

#[test]
fn rotate_normal_is_exact_and_its_derivative_is_the_basis() {
    // Step 1e-6: truncation ~h^2 = 1e-12, rounding eps/h = 2e-10; tolerance 1e-8.
    let h = 1e-6;
    let mut worst: f64 = 0.0;
    for n in probe_normals().into_iter().step_by(7) {
        let (e1, e2) = tangent_basis(&n);
        let d1 = (rotate_normal(&n, h, 0.0) - rotate_normal(&n, -h, 0.0)) / (2.0 * h);
        let d2 = (rotate_normal(&n, 0.0, h) - rotate_normal(&n, 0.0, -h)) / (2.0 * h);
        worst = worst.max((d1 - e1).norm()).max((d2 - e2).norm());
        assert!(
            (d1 - e1).norm() < 1e-8 && (d2 - e2).norm() < 1e-8,
            "n = {n}"
        );
        // A finite correction: unit result, rotated by exactly |(d1, d2)|.
        let (c1, c2) = (0.3, -0.4);
        let moved = rotate_normal(&n, c1, c2);
        assert!((moved.norm() - 1.0).abs() < ROUNDING);
        let angle = n.cross(&moved).norm().atan2(n.dot(&moved));
        assert!((angle - 0.5).abs() < 1e-12);
        assert_eq!(rotate_normal(&n, 0.0, 0.0), n.normalize());
    }
    eprintln!("rotate_normal derivative vs basis: worst {worst:e}");
}

/// A sensor mounted on the fixed basis' break (the corner direction -(1,1,1)/sqrt(3), as
/// the sso-6u scenario's canted photodiode 9 is): the basis about its own initial normal
/// is orthonormal, right-handed and continuous in a whole neighbourhood, where the fixed
/// basis jumps.
#[test]
fn basis_about_a_reference_is_smooth_at_the_fixed_break() {
    let reference = TANGENT_BASIS_SINGULAR_DIRECTION;
    let mut rng = common::rng(47);
    let mut worst_jump_about: f64 = 0.0;
    let mut worst_jump_fixed: f64 = 0.0;
    for _ in 0..500 {
        // Two normals 1e-6 rad apart within 5 deg of the reference.
        let tilt = common::uniform(&mut rng, 0.0, 5f64.to_radians());
        let dir = common::uniform(&mut rng, -PI, PI);
        let n = rotate_normal(&reference, tilt * dir.cos(), tilt * dir.sin());
        let m = rotate_normal(&n, 1e-6, 0.0);
        let (a1, a2) = tangent_basis_about(&n, &reference);
        assert!((a1.norm() - 1.0).abs() < ROUNDING && (a2.norm() - 1.0).abs() < ROUNDING);
        assert!(
            a1.dot(&n).abs() < ROUNDING
                && a2.dot(&n).abs() < ROUNDING
                && a1.dot(&a2).abs() < ROUNDING
        );
        assert!((a1.cross(&a2) - n).norm() < 1e-12, "right-handed");
        let (b1, _) = tangent_basis_about(&m, &reference);
        worst_jump_about = worst_jump_about.max((a1 - b1).norm());
        worst_jump_fixed = worst_jump_fixed.max((tangent_basis(&n).0 - tangent_basis(&m).0).norm());
    }
    // Smooth: a 1e-6 rad step moves the basis by O(1e-6); near its break the fixed basis
    // turns as 1/distance, over a hundred times faster (a filter's reset then scrambles the
    // meaning of the normal's covariance).
    assert!(
        worst_jump_about < 1e-5,
        "basis about the reference jumped {worst_jump_about:e}"
    );
    assert!(
        worst_jump_fixed > 100.0 * worst_jump_about,
        "fixed {worst_jump_fixed:e}, about {worst_jump_about:e}"
    );
}

/// `rotate_normal_in` with a basis from `tangent_basis_about` moves along that basis.
#[test]
fn rotate_normal_in_a_given_basis_has_the_basis_as_derivative() {
    let reference = TANGENT_BASIS_SINGULAR_DIRECTION;
    let n = rotate_normal(&reference, 0.01, -0.02);
    let (e1, e2) = tangent_basis_about(&n, &reference);
    let h = 1e-6;
    let d1 = (rotate_normal_in(&n, (&e1, &e2), h, 0.0) - rotate_normal_in(&n, (&e1, &e2), -h, 0.0))
        / (2.0 * h);
    let d2 = (rotate_normal_in(&n, (&e1, &e2), 0.0, h) - rotate_normal_in(&n, (&e1, &e2), 0.0, -h))
        / (2.0 * h);
    // Central difference of a smooth unit-size function at h = 1e-6: error ~h^2 + eps/h.
    assert!((d1 - e1).norm() < 1e-8 && (d2 - e2).norm() < 1e-8);
}

#[test]
fn angle_differences_wrap_into_the_half_open_turn() {
    for (d, w) in [
        (190.0, -170.0),
        (-190.0, 170.0),
        (180.0, -180.0),
        (-180.0, -180.0),
        (725.0, 5.0),
    ] {
        let got = pdcal_attitude::wrap_deg(d);
        assert!((got - w).abs() < 1e-12, "{d} -> {got}");
    }
}
