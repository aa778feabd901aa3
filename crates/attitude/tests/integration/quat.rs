//! The quaternion convention: golden attitude matrix, orthonormality, the nalgebra
//! mapping, attitude-matrix round trip and composition order.

use crate::common;

use std::f64::consts::FRAC_PI_2;

use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use pdcal_attitude::Quat;

/// Entries of products of a few unit-size numbers: a few tens of ulps.
const ROUNDING: f64 = 1e-14;

fn max_abs(m: &Matrix3<f64>) -> f64 {
    m.iter().fold(0.0, |acc, x| acc.max(x.abs()))
}

/// Largest componentwise difference of two quaternions (no sign folding).
fn component_diff(p: &Quat, q: &Quat) -> f64 {
    [p.x - q.x, p.y - q.y, p.z - q.z, p.w - q.w]
        .iter()
        .fold(0.0, |acc, d| acc.max(d.abs()))
}

#[test]
fn golden_ninety_degrees_about_z() {
    // Body frame turned +90 deg about z from the inertial frame: x_B = y_I, y_B = -x_I.
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let q = Quat {
        x: 0.0,
        y: 0.0,
        z: h,
        w: h,
    };
    let a = q.attitude_matrix();
    let expected = Matrix3::new(0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
    assert!(max_abs(&(a - expected)) < ROUNDING, "A = {a}");
    // Inertial x is seen along body -y, inertial y along body +x, z unchanged.
    let x_b = q.to_body(&Vector3::x());
    let y_b = q.to_body(&Vector3::y());
    assert!(
        (x_b - Vector3::new(0.0, -1.0, 0.0)).norm() < ROUNDING,
        "{x_b}"
    );
    assert!(
        (y_b - Vector3::new(1.0, 0.0, 0.0)).norm() < ROUNDING,
        "{y_b}"
    );
    assert!((q.to_body(&Vector3::z()) - Vector3::z()).norm() < ROUNDING);
}

#[test]
fn attitude_matrix_is_proper_orthogonal() {
    let mut rng = common::rng(11);
    for _ in 0..1000 {
        let a = common::quat(&mut rng).attitude_matrix();
        assert!(max_abs(&(a * a.transpose() - Matrix3::identity())) < ROUNDING);
        assert!((a.determinant() - 1.0).abs() < ROUNDING);
    }
}

#[test]
fn nalgebra_mapping_round_trip_and_transpose() {
    let mut rng = common::rng(12);
    for _ in 0..1000 {
        let q = common::quat(&mut rng);
        let na = q.to_nalgebra();
        let back = Quat::from_nalgebra(&na);
        // new_normalize of an already unit quaternion changes at most the last ulp.
        assert!(component_diff(&back, &q) < ROUNDING);
        assert!(
            max_abs(&(na.to_rotation_matrix().into_inner() - q.attitude_matrix().transpose()))
                < ROUNDING
        );
        // nalgebra's rotation takes body components to inertial ones.
        let v_i = common::unit3(&mut rng);
        assert!((na * q.to_body(&v_i) - v_i).norm() < ROUNDING);
    }
}

#[test]
fn attitude_matrix_round_trip() {
    let mut rng = common::rng(13);
    for _ in 0..1000 {
        let q = common::quat(&mut rng).canonical();
        let back = Quat::from_attitude_matrix(&q.attitude_matrix()).canonical();
        // Shepperd-type extraction: componentwise error a few ulps of the largest one.
        assert!(component_diff(&back, &q) < ROUNDING, "{q:?} vs {back:?}");
        assert!((back.norm() - 1.0).abs() < ROUNDING);
    }
}

#[test]
fn composition_order() {
    let mut rng = common::rng(14);
    for _ in 0..1000 {
        let p = common::quat(&mut rng);
        let q = common::quat(&mut rng);
        let pq = p.compose(&q);
        assert!(
            max_abs(&(pq.attitude_matrix() - p.attitude_matrix() * q.attitude_matrix())) < ROUNDING
        );
        // Markley's p ⊗ q is nalgebra's q * p.
        let na = Quat::from_nalgebra(&(q.to_nalgebra() * p.to_nalgebra()));
        assert!(component_diff(&pq, &na) < ROUNDING);
        assert!(
            max_abs(&(q.inverse().attitude_matrix() - q.attitude_matrix().transpose())) < ROUNDING
        );
    }
    // A case where the order visibly matters. Body turned +90 deg about x: inertial y
    // is seen along body -z. Body turned +90 deg about z: inertial y along body +x.
    let about = |axis: Vector3<f64>| {
        let active = Rotation3::from_axis_angle(&Unit::new_normalize(axis), FRAC_PI_2);
        Quat::from_attitude_matrix(&active.matrix().transpose())
    };
    let (qx, qz) = (about(Vector3::x()), about(Vector3::z()));
    // x first, then z: y_I -> -z (turn about x) -> -z (turn about z leaves z).
    let y_b = qz.compose(&qx).to_body(&Vector3::y());
    assert!(
        (y_b - Vector3::new(0.0, 0.0, -1.0)).norm() < ROUNDING,
        "{y_b}"
    );
    // z first, then x: y_I -> +x (turn about z) -> +x (turn about x leaves x).
    let y_b = qx.compose(&qz).to_body(&Vector3::y());
    assert!((y_b - Vector3::x()).norm() < ROUNDING, "{y_b}");
}

#[test]
fn angle_to_matches_nalgebra() {
    let mut rng = common::rng(15);
    for _ in 0..1000 {
        let p = common::quat(&mut rng);
        let q = common::quat(&mut rng);
        let reference = p.to_nalgebra().angle_to(&q.to_nalgebra());
        // acos near 1 loses sqrt(eps) ~ 1e-8 for tiny angles; random pairs are far apart.
        assert!((p.angle_to(&q) - reference).abs() < 1e-9);
    }
}
