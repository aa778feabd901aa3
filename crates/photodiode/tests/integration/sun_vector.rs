//! Least-squares Sun vector: exact on noise-free, albedo-free RAX-2 outputs; explicit
//! "not observable" for the degenerate cases.

use crate::common;

use common::*;
use nalgebra::Vector3;
use pdcal_photodiode::*;
use rand::RngExt;

/// Table 1 of the paper (rax2-scenario.md), degrees.
const RAX2_AZ_EL_DEG: [(f64, f64); 17] = pdcal_attitude::RAX2_TABLE1_AZ_EL_DEG;

fn rax2(rng: &mut rand::rngs::StdRng) -> Vec<Photodiode> {
    RAX2_AZ_EL_DEG
        .iter()
        .map(|&(az, el)| Photodiode::from_az_el_deg(rng.random_range(3.5..3.9), az, el, 0.015))
        .collect()
}

/// Smallest singular value of the stacked lit normals, computed independently with nalgebra's
/// SVD of the m x 3 matrix.
fn sigma_min(normals: &[Vector3<f64>]) -> f64 {
    let h = nalgebra::DMatrix::from_fn(normals.len(), 3, |r, c| normals[r][c]);
    h.svd(false, false).singular_values.min()
}

#[test]
fn exact_on_noise_free_rax2_outputs() {
    let mut rng = rng(31);
    let pds = rax2(&mut rng);
    let model = MeasurementModel::cosine(pds.clone());
    let options = SunVectorOptions::default();
    let mut observable = 0;
    let mut worst = 0.0f64;
    for _ in 0..1000 {
        let sun = random_unit(&mut rng);
        let scene = Scene::new(nalgebra::Matrix3::identity(), &sun).unwrap();
        let mut out = vec![0.0; pds.len()];
        model.evaluate_all(&scene, &mut out).unwrap();
        let lit: Vec<_> = pds
            .iter()
            .zip(&out)
            .filter(|(pd, y)| **y > 3.0 * pd.noise_v)
            .map(|(pd, _)| pd.n_body)
            .collect();
        let expect_observable = lit.len() >= 3 && sigma_min(&lit) >= options.min_singular_value;
        match estimate_sun_vector(&pds, &out, None, &options).unwrap() {
            SunEstimate::Observable(s) => {
                assert!(expect_observable);
                assert_eq!(s.used, lit.len());
                let err = (s.vector_body - sun).norm();
                worst = worst.max(err);
                // Tolerance 1e-12: a 3x3 Cholesky solve with condition number
                // <= 17/0.1^2 = 1700 loses at most ~1e-13 from 1e-16 inputs.
                assert!(err < 1e-12, "LS error {err:e}");
                assert!((s.direction_body - sun).norm() < 1e-12);
                observable += 1;
            }
            SunEstimate::NotObservable { .. } => assert!(!expect_observable),
        }
    }
    eprintln!("RAX-2 LS: {observable}/1000 observable, worst |s - s_true| = {worst:.2e}");
    assert!(
        observable > 900,
        "the RAX-2 layout sees the Sun with >= 3 sensors almost always"
    );
}

#[test]
fn subtracting_known_albedo_and_offsets_recovers_the_sun() {
    let mut rng = rng(32);
    let pds = rax2(&mut rng);
    let sun = Vector3::new(0.3, -0.5, 0.8).normalize();
    let scene = Scene::new(nalgebra::Matrix3::identity(), &sun).unwrap();
    let known: Vec<f64> = (0..17).map(|_| rng.random_range(0.0..0.3)).collect();
    let mut out = vec![0.0; 17];
    MeasurementModel::cosine(pds.clone())
        .evaluate_all(&scene, &mut out)
        .unwrap();
    // Outputs with the known part added back; dark sensors then carry only the known part.
    let raw: Vec<f64> = out.iter().zip(&known).map(|(y, k)| y + k).collect();
    let SunEstimate::Observable(s) =
        estimate_sun_vector(&pds, &raw, Some(&known), &SunVectorOptions::default()).unwrap()
    else {
        panic!("observable geometry expected");
    };
    assert!((s.vector_body - sun).norm() < 1e-12);
}

fn three_pds(az_el_deg: [(f64, f64); 3]) -> Vec<Photodiode> {
    az_el_deg
        .iter()
        .map(|&(a, e)| Photodiode::from_az_el_deg(3.6, a, e, 0.015))
        .collect()
}

#[test]
fn two_lit_is_not_observable() {
    let pds = three_pds([(0.0, 0.0), (90.0, 0.0), (0.0, 90.0)]);
    let out = [2.0, 1.5, 0.0];
    let est = estimate_sun_vector(&pds, &out, None, &SunVectorOptions::default()).unwrap();
    assert_eq!(
        est,
        SunEstimate::NotObservable {
            used: 2,
            reason: NotObservableReason::TooFewLit
        }
    );
}

#[test]
fn three_coplanar_lit_is_not_observable() {
    // Normals in the x-y plane, Sun in front of all three.
    let pds = three_pds([(-30.0, 0.0), (0.0, 0.0), (30.0, 0.0)]);
    let sun = Vector3::new(0.9, 0.1, 0.3).normalize();
    let out: Vec<f64> = pds.iter().map(|p| p.scale_v * p.n_body.dot(&sun)).collect();
    let est = estimate_sun_vector(&pds, &out, None, &SunVectorOptions::default()).unwrap();
    match est {
        SunEstimate::NotObservable {
            used: 3,
            reason: NotObservableReason::DegenerateGeometry { min_singular_value },
        } => assert!(min_singular_value < 1e-6),
        other => panic!("expected degenerate geometry, got {other:?}"),
    }
}

#[test]
fn all_dark_is_not_observable() {
    let mut rng = rng(33);
    let pds = rax2(&mut rng);
    let out = vec![0.01; 17]; // below 3 sigma = 0.045 V
    let est = estimate_sun_vector(&pds, &out, None, &SunVectorOptions::default()).unwrap();
    assert_eq!(
        est,
        SunEstimate::NotObservable {
            used: 0,
            reason: NotObservableReason::TooFewLit
        }
    );
}

#[test]
fn mismatched_lengths_and_bad_scales_are_errors() {
    let pds = three_pds([(0.0, 0.0), (90.0, 0.0), (0.0, 90.0)]);
    let options = SunVectorOptions::default();
    assert!(matches!(
        estimate_sun_vector(&pds, &[1.0, 1.0], None, &options),
        Err(PhotodiodeError::LengthMismatch { .. })
    ));
    let mut bad = pds.clone();
    bad[1].scale_v = 0.0;
    assert!(matches!(
        estimate_sun_vector(&bad, &[1.0, 1.0, 1.0], None, &options),
        Err(PhotodiodeError::BadValue { .. })
    ));
}

/// Earth light on photodiodes facing away from the Sun: with back-facing rejection those
/// equations are dropped and the Sun vector is exact again; without it the magnitude shrinks.
#[test]
fn back_facing_photodiodes_lit_by_albedo_are_dropped() {
    let mut rng = rng(33);
    let pds = rax2(&mut rng);
    let sun = Vector3::new(0.6, 0.2, 0.77).normalize();
    let scene = Scene::new(nalgebra::Matrix3::identity(), &sun).unwrap();
    let mut out = vec![0.0; 17];
    MeasurementModel::cosine(pds.clone())
        .evaluate_all(&scene, &mut out)
        .unwrap();
    // 0.5 V of "albedo" on every photodiode that faces away from the Sun.
    let mut back = 0;
    for (y, pd) in out.iter_mut().zip(&pds) {
        if pd.n_body.dot(&sun) <= 0.0 {
            *y += 0.5;
            back += 1;
        }
    }
    assert!(
        back >= 3,
        "the test needs several back-facing sensors, found {back}"
    );
    let on = SunVectorOptions::default();
    let off = SunVectorOptions {
        reject_backfacing: false,
        ..on
    };
    let SunEstimate::Observable(with) = estimate_sun_vector(&pds, &out, None, &on).unwrap() else {
        panic!("observable expected");
    };
    let SunEstimate::Observable(without) = estimate_sun_vector(&pds, &out, None, &off).unwrap()
    else {
        panic!("observable expected");
    };
    // Exact once the back-facing equations are gone (same 1e-12 argument as above).
    assert!(
        (with.vector_body - sun).norm() < 1e-12,
        "error {:e}",
        (with.vector_body - sun).norm()
    );
    assert!(
        (without.vector_body.norm() - 1.0).abs() > 0.05,
        "albedo must bias the plain fit"
    );
}

/// Outputs at another distance from the Sun than 1 AU give the unit Sun vector back when the
/// estimate is told the distance factor, and a vector of length `F` when it is not.
#[test]
fn the_sun_distance_factor_rescales_the_outputs() {
    let mut rng = rng(37);
    let pds = rax2(&mut rng);
    let model = MeasurementModel::cosine(pds.clone());
    let mut checked = 0;
    for factor in [0.967, 1.0, 1.034] {
        for _ in 0..200 {
            let sun = random_unit(&mut rng);
            let scene = Scene::new(nalgebra::Matrix3::identity(), &sun)
                .unwrap()
                .with_sun_distance_factor(factor);
            let mut out = vec![0.0; pds.len()];
            model.evaluate_all(&scene, &mut out).unwrap();
            let told = SunVectorOptions {
                sun_distance_factor: factor,
                ..SunVectorOptions::default()
            };
            let (SunEstimate::Observable(with), SunEstimate::Observable(without)) = (
                estimate_sun_vector(&pds, &out, None, &told).unwrap(),
                estimate_sun_vector(&pds, &out, None, &SunVectorOptions::default()).unwrap(),
            ) else {
                continue;
            };
            assert!((with.vector_body - sun).norm() < 1e-12);
            assert!((without.vector_body.norm() - factor).abs() < 1e-12);
            checked += 1;
        }
    }
    assert!(checked > 100, "{checked} observable samples");
    let bad = SunVectorOptions {
        sun_distance_factor: 0.0,
        ..SunVectorOptions::default()
    };
    assert!(estimate_sun_vector(&pds, &[1.0; 17], None, &bad).is_err());
}
