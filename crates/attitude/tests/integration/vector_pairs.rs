//! q-method and TRIAD: exact on noise-free pairs, errors on bad input, and a seeded
//! Monte Carlo against the first-order covariances of Shuster & Oh (1981).

use crate::common;

use nalgebra::{Matrix3, Vector3};
use pdcal_attitude::mekf::error_vector;
use pdcal_attitude::{AttitudeError, Quat, VectorPair, q_method, triad};
use rand::rngs::StdRng;

/// Noise-free solutions: the brief's bound. Observed errors are ~1e-15 rad; the
/// worst geometry drawn here (two vectors a few degrees apart) costs ~eps/sin(angle).
const EXACT_RAD: f64 = 1e-9;

#[test]
fn exact_on_noise_free_pairs() {
    let mut rng = common::rng(31);
    let (mut worst_q, mut worst_t): (f64, f64) = (0.0, 0.0);
    for trial in 0..500 {
        let truth = common::quat(&mut rng);
        let count = 2 + trial % 4;
        let pairs: Vec<VectorPair> = (0..count)
            .map(|_| {
                let r = common::unit3(&mut rng) * common::uniform(&mut rng, 0.1, 10.0);
                VectorPair::new(truth.to_body(&r), r, common::uniform(&mut rng, 0.1, 5.0))
            })
            .collect();
        let q = q_method(&pairs).expect("valid pairs");
        let t = triad(&pairs[0], &pairs[1]).expect("valid pairs");
        worst_q = worst_q.max(error_vector(&q, &truth).norm());
        worst_t = worst_t.max(error_vector(&t, &truth).norm());
    }
    eprintln!("noise-free: q-method worst {worst_q:e} rad, TRIAD worst {worst_t:e} rad");
    assert!(worst_q < EXACT_RAD && worst_t < EXACT_RAD);
}

#[test]
fn bad_input_is_an_error() {
    let x = Vector3::x();
    let y = Vector3::y();
    let good = VectorPair::new(x, x, 1.0);
    let other = VectorPair::new(y, y, 1.0);
    assert_eq!(
        q_method(&[good]),
        Err(AttitudeError::TooFewPairs { count: 1 })
    );
    assert_eq!(q_method(&[]), Err(AttitudeError::TooFewPairs { count: 0 }));
    let zero = VectorPair::new(Vector3::zeros(), y, 1.0);
    assert_eq!(
        q_method(&[good, zero]),
        Err(AttitudeError::ZeroVector {
            index: 1,
            what: "body vector"
        })
    );
    let nan = VectorPair::new(y, Vector3::new(f64::NAN, 0.0, 1.0), 1.0);
    assert_eq!(
        triad(&good, &nan),
        Err(AttitudeError::NonFinite {
            index: 1,
            what: "reference vector"
        })
    );
    let inf_weight = VectorPair::new(y, y, f64::INFINITY);
    assert!(matches!(
        q_method(&[inf_weight, good]),
        Err(AttitudeError::NonFinite { index: 0, .. })
    ));
    let negative = VectorPair::new(y, y, -1.0);
    assert!(matches!(
        q_method(&[good, negative]),
        Err(AttitudeError::NonPositiveWeight { index: 1, .. })
    ));
    // Parallel and anti-parallel vectors leave the rotation about them free.
    let anti = VectorPair::new(-x * 3.0, -x, 1.0);
    assert!(matches!(
        q_method(&[good, anti]),
        Err(AttitudeError::Parallel { frame: "body", .. })
    ));
    assert!(matches!(
        triad(&good, &anti),
        Err(AttitudeError::Parallel { .. })
    ));
    // Body vectors spread but reference vectors parallel.
    let mixed = VectorPair::new(y, x, 1.0);
    assert!(matches!(
        q_method(&[good, mixed]),
        Err(AttitudeError::Parallel {
            frame: "reference",
            ..
        })
    ));
    assert!(q_method(&[good, other]).is_ok() && triad(&good, &other).is_ok());
}

/// `b = normalize(A r + e)`, `e ~ N(0, sigma^2 (I - b b^T))`: the QUEST measurement
/// model (Shuster & Oh 1981), noise perpendicular to the true body vector.
fn noisy_body(rng: &mut StdRng, b: &Vector3<f64>, sigma: f64) -> Vector3<f64> {
    let g = common::gaussian3(rng) * sigma;
    (b + g - b * b.dot(&g)).normalize()
}

struct Geometry {
    truth: Quat,
    r1: Vector3<f64>,
    r2: Vector3<f64>,
    b1: Vector3<f64>,
    b2: Vector3<f64>,
    sigma1: f64,
    sigma2: f64,
}

/// A sun-like and a field-like direction 50 deg apart; noise small enough (0.1 and
/// 0.3 deg) that second-order terms are ~1e-3 of the first-order covariance.
fn geometry(rng: &mut StdRng) -> Geometry {
    let truth = common::quat(rng);
    let r1 = common::unit3(rng);
    let perp = r1.cross(&common::unit3(rng)).normalize();
    let angle = 50f64.to_radians();
    let r2 = r1 * angle.cos() + perp * angle.sin();
    Geometry {
        truth,
        r1,
        r2,
        b1: truth.to_body(&r1),
        b2: truth.to_body(&r2),
        sigma1: 0.1f64.to_radians(),
        sigma2: 0.3f64.to_radians(),
    }
}

/// Per-axis RMS of `errors` over sqrt(diag(P)), and the mean NEES `e^T P^-1 e`.
fn consistency(errors: &[Vector3<f64>], p: &Matrix3<f64>) -> ([f64; 3], f64) {
    let n = errors.len() as f64;
    let p_inv = p.try_inverse().expect("covariance is invertible");
    let mut ratios = [0.0; 3];
    for (axis, ratio) in ratios.iter_mut().enumerate() {
        let ms = errors.iter().map(|e| e[axis] * e[axis]).sum::<f64>() / n;
        *ratio = (ms / p[(axis, axis)]).sqrt();
    }
    let nees = errors
        .iter()
        .map(|e| (e.transpose() * p_inv * e)[0])
        .sum::<f64>()
        / n;
    (ratios, nees)
}

/// Draws: the brief asks for >= 2000. With N = 4000 the sample RMS has a relative
/// standard deviation of 1/sqrt(2N) = 1.1 %, so the ratio band [0.8, 1.25] is about
/// 20 sigma wide (it bounds model error, not sampling luck); the mean NEES has standard
/// deviation sqrt(6/N) = 0.039 around 3, and [2.8, 3.2] is 5 sigma.
const DRAWS: usize = 4000;
const RATIO_BAND: (f64, f64) = (0.8, 1.25);
const NEES_BAND: (f64, f64) = (2.8, 3.2);

fn assert_consistent(name: &str, errors: &[Vector3<f64>], p: &Matrix3<f64>) {
    let (ratios, nees) = consistency(errors, p);
    eprintln!(
        "{name}: RMS / predicted sigma per body axis {ratios:.4?}, mean NEES {nees:.4} (3 expected)"
    );
    for r in ratios {
        assert!(
            (RATIO_BAND.0..=RATIO_BAND.1).contains(&r),
            "{name}: ratio {r}"
        );
    }
    assert!(
        (NEES_BAND.0..=NEES_BAND.1).contains(&nees),
        "{name}: NEES {nees}"
    );
}

#[test]
fn q_method_monte_carlo_matches_quest_covariance() {
    let mut rng = common::rng(32);
    let g = geometry(&mut rng);
    let (w1, w2) = (g.sigma1.powi(-2), g.sigma2.powi(-2));
    let errors: Vec<Vector3<f64>> = (0..DRAWS)
        .map(|_| {
            let pairs = [
                VectorPair::new(noisy_body(&mut rng, &g.b1, g.sigma1), g.r1, w1),
                VectorPair::new(noisy_body(&mut rng, &g.b2, g.sigma2), g.r2, w2),
            ];
            error_vector(&q_method(&pairs).expect("valid pairs"), &g.truth)
        })
        .collect();
    // Shuster's QUEST covariance, body frame: P = (sum w_i (I - b_i b_i^T))^-1.
    let id = Matrix3::identity();
    let info = (id - g.b1 * g.b1.transpose()) * w1 + (id - g.b2 * g.b2.transpose()) * w2;
    let p = info.try_inverse().expect("two non-parallel vectors");
    assert_consistent("q-method", &errors, &p);
}

#[test]
fn triad_monte_carlo_matches_shuster_oh_covariance() {
    let mut rng = common::rng(33);
    let g = geometry(&mut rng);
    let errors: Vec<Vector3<f64>> = (0..DRAWS)
        .map(|_| {
            let first = VectorPair::new(noisy_body(&mut rng, &g.b1, g.sigma1), g.r1, 1.0);
            let second = VectorPair::new(noisy_body(&mut rng, &g.b2, g.sigma2), g.r2, 1.0);
            error_vector(&triad(&first, &second).expect("valid pairs"), &g.truth)
        })
        .collect();
    // Shuster & Oh (1981): P = s1^2 I + |b1 x b2|^-2 [(s2^2 - s1^2) b1 b1^T
    //                          + s1^2 (b1.b2)(b1 b2^T + b2 b1^T)].
    let (s1, s2) = (g.sigma1.powi(2), g.sigma2.powi(2));
    let sin2 = g.b1.cross(&g.b2).norm_squared();
    let p = Matrix3::identity() * s1
        + (g.b1 * g.b1.transpose() * (s2 - s1)
            + (g.b1 * g.b2.transpose() + g.b2 * g.b1.transpose()) * (s1 * g.b1.dot(&g.b2)))
            / sin2;
    assert_consistent("TRIAD", &errors, &p);
}
