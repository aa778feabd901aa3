//! The check on a synthetic tumble: each sensor's wrong axes found, clean data quiet, and
//! what two sensors alone can and cannot decide.

use nalgebra::{Matrix3, Rotation3, Vector3};
use pdcal_axes::{Inputs, Sensor, Thresholds, check, signed_permutations};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal, UnitSphere};

/// A 2-hour tumble at 1 Hz: rates, magnetometer, the Sun direction, references.
struct Truth {
    t_s: Vec<f64>,
    gyro: Vec<Option<Vector3<f64>>>,
    mag: Vec<Option<Vector3<f64>>>,
    sun: Vec<Option<Vector3<f64>>>,
    references: Vec<(Vector3<f64>, Vector3<f64>)>,
}

/// `Tumble::Triaxial`: the rate about every axis varies; `Axisymmetric`: a torque-free
/// symmetric body, its z rate constant; `Spin`: about z only.
#[derive(Clone, Copy, PartialEq)]
enum Tumble {
    Triaxial,
    Axisymmetric,
    Spin,
}

fn tumble(seed: u64, rate_deg_s: f64, kind: Tumble) -> Truth {
    let mut rng = StdRng::seed_from_u64(seed);
    let gyro_noise = Normal::new(0.0, 0.00087).unwrap();
    let mag_noise = Normal::new(0.0, 320.0).unwrap();
    let sun_noise = Normal::new(0.0, 0.005).unwrap();
    let sun_inertial = Vector3::from(UnitSphere.sample(&mut rng));
    let field_axis = Vector3::from(UnitSphere.sample(&mut rng));
    let field_start = Vector3::from(UnitSphere.sample(&mut rng)) * 35_000.0;
    let bias = Vector3::from(UnitSphere.sample(&mut rng)) * 0.004;
    let w = rate_deg_s.to_radians();
    let mut attitude =
        Rotation3::from_scaled_axis(Vector3::from(UnitSphere.sample(&mut rng)) * 2.0);
    let mut truth = Truth {
        t_s: vec![],
        gyro: vec![],
        mag: vec![],
        sun: vec![],
        references: vec![],
    };
    for k in 0..7200 {
        let t = f64::from(k);
        let rate = match kind {
            Tumble::Spin => Vector3::new(0.0, 0.0, w),
            Tumble::Axisymmetric => Vector3::new(
                0.6 * w * (0.02 * t).cos(),
                0.6 * w * (0.02 * t).sin(),
                0.8 * w,
            ),
            Tumble::Triaxial => Vector3::new(
                0.6 * w * (0.02 * t).cos(),
                0.6 * w * (0.02 * t).sin(),
                0.8 * w * (0.013 * t).cos(),
            ),
        };
        let field = Rotation3::from_scaled_axis(field_axis * 0.0022 * t) * field_start;
        let noisy = |d: &Normal<f64>, rng: &mut StdRng| {
            Vector3::new(d.sample(rng), d.sample(rng), d.sample(rng))
        };
        truth.t_s.push(t);
        truth
            .gyro
            .push(Some(rate + bias + noisy(&gyro_noise, &mut rng)));
        truth
            .mag
            .push(Some(attitude * field + noisy(&mag_noise, &mut rng)));
        let lit = (t % 5700.0) < 3700.0;
        truth
            .sun
            .push(lit.then(|| (attitude * sun_inertial + noisy(&sun_noise, &mut rng)).normalize()));
        truth.references.push((sun_inertial, field));
        // v_B = A v_I turns as dA/dt = -[w]x A.
        for _ in 0..10 {
            attitude = Rotation3::from_scaled_axis(-rate * 0.1) * attitude;
        }
    }
    truth
}

/// The series as recorded by a sensor of axes `body_from_sensor`: `v_sensor = M^T v_body`.
fn recorded(
    v: &[Option<Vector3<f64>>],
    body_from_sensor: &Matrix3<f64>,
) -> Vec<Option<Vector3<f64>>> {
    v.iter()
        .map(|x| x.map(|x| body_from_sensor.transpose() * x))
        .collect()
}

fn run(
    truth: &Truth,
    gyro: &Matrix3<f64>,
    mag: Option<&Matrix3<f64>>,
    table: &Matrix3<f64>,
) -> pdcal_axes::AxesCheck {
    let g = recorded(&truth.gyro, gyro);
    let m = mag.map(|m| recorded(&truth.mag, m)).unwrap_or_default();
    let s = recorded(&truth.sun, table);
    let inputs = Inputs {
        t_s: &truth.t_s,
        gyro_rad_s: &g,
        mag: &m,
        sun_photodiodes: &s,
        references: &truth.references,
        gyro_bias_sigma_rad_s: 5f64.to_radians(),
    };
    check(&inputs, &Thresholds::default())
}

fn found(result: &pdcal_axes::AxesCheck) -> Option<(Sensor, Matrix3<f64>)> {
    result.finding.as_ref().map(|f| (f.sensor, f.matrix()))
}

#[test]
fn clean_data_gives_no_finding_and_checks_every_sensor() {
    for seed in 1..=3 {
        let truth = tumble(seed, 4.0, Tumble::Triaxial);
        let i = Matrix3::identity();
        let result = run(&truth, &i, Some(&i), &i);
        assert_eq!(result.finding, None, "seed {seed}");
        assert!(
            result.not_checked.is_empty(),
            "seed {seed}: {:?}",
            result.not_checked
        );
    }
}

#[test]
fn every_wrong_gyro_and_a_spread_of_magnetometer_permutations_are_found() {
    let truth = tumble(4, 4.0, Tumble::Triaxial);
    let i = Matrix3::identity();
    for (k, p) in signed_permutations().iter().enumerate().skip(1) {
        let result = run(&truth, p, Some(&i), &i);
        assert_eq!(
            found(&result),
            Some((Sensor::Gyro, *p)),
            "gyro permutation {k}: {result:?}"
        );
        // Every third magnetometer permutation (and every axis reversed): the acceptance
        // runs all of them (`cargo xtask axes-validate`).
        if k % 3 != 1 && *p != -i {
            continue;
        }
        let result = run(&truth, &i, Some(p), &i);
        if *p == -i {
            // Every axis reversed: the field turns the same way, and only its angle to the
            // Sun changes sign, which a table reversed in every axis does too.
            assert_eq!(result.finding, None, "{result:?}");
            assert!(!result.not_checked.is_empty());
        } else {
            assert_eq!(
                found(&result),
                Some((Sensor::Magnetometer, *p)),
                "magnetometer permutation {k}: {result:?}"
            );
        }
    }
}

#[test]
fn a_spread_of_wrong_photodiode_table_frames_is_found() {
    let truth = tumble(5, 4.0, Tumble::Triaxial);
    let i = Matrix3::identity();
    for (k, p) in signed_permutations()
        .iter()
        .enumerate()
        .skip(1)
        .filter(|(k, p)| k % 3 == 2 || **p == -Matrix3::identity())
    {
        let result = run(&truth, &i, Some(&i), p);
        if *p == -i {
            assert_eq!(result.finding, None, "{result:?}");
            assert!(!result.not_checked.is_empty());
        } else {
            assert_eq!(
                found(&result),
                Some((Sensor::Photodiodes, *p)),
                "table {k}: {result:?}"
            );
        }
    }
}

#[test]
fn without_a_magnetometer_the_gyro_is_checked_against_the_photodiodes() {
    let truth = tumble(6, 4.0, Tumble::Triaxial);
    let i = Matrix3::identity();
    let reversed_y = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0);
    let result = run(&truth, &reversed_y, None, &i);
    assert_eq!(found(&result), Some((Sensor::Gyro, reversed_y)));
    assert_eq!(run(&truth, &i, None, &i).finding, None);
}

#[test]
fn a_spin_about_one_axis_leaves_a_swap_of_the_others_undecided() {
    let truth = tumble(7, 4.0, Tumble::Spin);
    let i = Matrix3::identity();
    let swap_xy = Matrix3::new(0.0, 1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
    let result = run(&truth, &swap_xy, None, &i);
    // The gyro reads (0, 0, w) whatever x and y are: nothing to find, and it says so.
    assert_eq!(result.finding, None);
    assert!(
        result.not_checked.iter().any(|n| n.sensor == Sensor::Gyro),
        "{result:?}"
    );
}

#[test]
fn an_axisymmetric_tumble_leaves_the_symmetry_axis_sign_to_the_bias_prior() {
    // z turns at a constant 3.2 deg/s: z reversed is the stated gyro with a bias of 6.4
    // deg/s, which a 5 deg/s prior does not rule out.
    let truth = tumble(8, 4.0, Tumble::Axisymmetric);
    let i = Matrix3::identity();
    let reversed_z = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0);
    let result = run(&truth, &reversed_z, Some(&i), &i);
    assert_eq!(result.finding, None, "{result:?}");
    assert!(
        result.not_checked.iter().any(|n| n.sensor == Sensor::Gyro),
        "{result:?}"
    );
    // A transverse axis reversed is no such twin.
    let reversed_y = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0);
    assert_eq!(
        found(&run(&truth, &reversed_y, Some(&i), &i)).map(|f| f.0),
        Some(Sensor::Gyro)
    );
}
