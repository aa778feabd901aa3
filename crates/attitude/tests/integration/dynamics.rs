//! The rigid body's moment corrections (`RigidBody::with_moment_fractions`), the filter's
//! hypothesis about an uncertain inertia.

use nalgebra::{Matrix3, Vector3};
use pdcal_attitude::dynamics::RigidBody;

fn full_body() -> RigidBody {
    RigidBody::new(Matrix3::new(
        0.0314, 0.0012, -0.0008, 0.0012, 0.0290, 0.0005, -0.0008, 0.0005, 0.0050,
    ))
    .expect("physical")
}

#[test]
fn moment_fractions_scale_the_diagonal_keep_the_products_and_invert() {
    let body = full_body();
    let f = Vector3::new(0.15, -0.1, 0.05);
    let corrected = body.with_moment_fractions(&f).expect("positive definite");
    let (j0, j) = (body.inertia_kg_m2(), corrected.inertia_kg_m2());
    for r in 0..3 {
        for c in 0..3 {
            let expected = if r == c {
                j0[(r, c)] * (1.0 + f[r])
            } else {
                j0[(r, c)]
            };
            assert_eq!(j[(r, c)], expected, "({r}, {c})");
        }
    }
    let identity = j * corrected.inertia_inv();
    assert!(
        (identity - Matrix3::identity()).abs().max() < 1e-12,
        "{identity}"
    );
}

#[test]
fn moment_fractions_need_positive_definiteness_not_the_triangle_inequality() {
    // An axisymmetric long body: +20 % on Ixx puts it past Iyy + Izz, which a physical
    // body cannot be but an estimate may pass through; it stays invertible.
    let long = RigidBody::new(Matrix3::from_diagonal(&Vector3::new(0.0314, 0.0314, 0.005)))
        .expect("physical");
    let past = long
        .with_moment_fractions(&Vector3::new(0.2, 0.0, 0.0))
        .expect("positive definite");
    assert!(RigidBody::new(*past.inertia_kg_m2()).is_err());
    assert!(
        long.with_moment_fractions(&Vector3::new(0.0, -1.5, 0.0))
            .is_none()
    );
}
