//! Synthetic magnetometer data along a RAX-2-like orbit: a tumbling spacecraft, three body
//! panels whose currents follow the Sun's incidence and the illumination, and a magnetometer
//! with known errors.

use nalgebra::{Matrix3, Rotation3, Vector3};
use pdcal_ephem::{ReferenceModel, TleOrbit, time};
use pdcal_magcal::{Sample, sample_along_orbit};
use rand::SeedableRng;
use rand::rngs::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal, Uniform};

const L1: &str = "1 37853U 11061D   11308.77065972  .00000000  00000-0  20000-4 0  9997";
const L2: &str = "2 37853 101.7000  50.0000 0300509 130.0000 230.0000 14.86144463  1000";

/// The true magnetometer errors.
#[derive(Debug, Clone)]
pub struct Truth {
    pub t: Matrix3<f64>,
    pub bias_nt: Vector3<f64>,
    pub coeff_nt: Vec<Vector3<f64>>,
    pub noise_nt: f64,
}

impl Truth {
    /// The symmetric factor `(T T^T)^(1/2)`, what the magnitude determines.
    pub fn symmetric(&self) -> Matrix3<f64> {
        let e = (self.t * self.t.transpose()).symmetric_eigen();
        e.eigenvectors
            * Matrix3::from_diagonal(&e.eigenvalues.map(f64::sqrt))
            * e.eigenvectors.transpose()
    }
}

/// Errors drawn like the acceptance: hard iron 2-5 uT per axis, scale and soft
/// iron up to 5 %, non-orthogonality 1-2 deg, 200-800 nT/A on each true regressor.
pub fn draw_truth(seed: u64, true_regressors: usize) -> Truth {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let sign = |rng: &mut ChaCha8Rng| {
        if Uniform::new(0.0, 1.0).unwrap().sample(rng) < 0.5 {
            -1.0
        } else {
            1.0
        }
    };
    let mag = |lo: f64, hi: f64, rng: &mut ChaCha8Rng| {
        sign(rng) * Uniform::new(lo, hi).unwrap().sample(rng)
    };
    let mut soft = Matrix3::identity();
    for a in 0..3 {
        soft[(a, a)] += mag(0.0, 0.05, &mut rng);
        for b in a + 1..3 {
            let v = mag(0.0, 0.03, &mut rng);
            soft[(a, b)] = v;
            soft[(b, a)] = v;
        }
    }
    let deg = std::f64::consts::PI / 180.0;
    let mut nonortho = Matrix3::identity();
    nonortho[(0, 1)] = mag(1.0 * deg, 2.0 * deg, &mut rng);
    nonortho[(0, 2)] = mag(1.0 * deg, 2.0 * deg, &mut rng);
    nonortho[(1, 2)] = mag(1.0 * deg, 2.0 * deg, &mut rng);
    let bias_nt = Vector3::from_fn(|_, _| mag(2000.0, 5000.0, &mut rng));
    let coeff_nt = (0..true_regressors)
        .map(|_| Vector3::from_fn(|_, _| mag(200.0, 800.0, &mut rng)))
        .collect();
    Truth {
        t: soft * nonortho,
        bias_nt,
        coeff_nt,
        noise_nt: 320.0,
    }
}

/// The panels' outward normals (body frame).
const PANELS: [[f64; 3]; 4] = [
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, 0.0, -1.0],
    [-1.0, 0.0, 0.0],
];

/// `rows` samples every `step_s` seconds; the first `truth.coeff_nt.len()` regressors drive
/// the bias, the rest of the `regressors` panel currents drive nothing.
pub fn simulate(
    truth: &Truth,
    seed: u64,
    rows: usize,
    step_s: f64,
    regressors: usize,
) -> Vec<Sample> {
    let epoch = time::parse_utc("2011-11-04T18:29:45Z").expect("valid epoch");
    let orbit = TleOrbit::from_lines(L1, L2).expect("valid TLE");
    let model = ReferenceModel::new(epoch, Box::new(orbit)).expect("IGRF parses");
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    let axis = Vector3::new(0.3, -0.5, 0.8).normalize();
    let rate = 2.0_f64.to_radians();
    (0..rows)
        .map(|k| {
            let t_s = k as f64 * step_s;
            let reference = model.at(t_s).expect("in range");
            // A slowly precessing spin, so every body direction meets the field.
            let precess = Rotation3::from_axis_angle(&Vector3::z_axis(), 0.013 * t_s);
            let spin = Rotation3::from_axis_angle(
                &nalgebra::Unit::new_normalize(precess * axis),
                rate * t_s,
            );
            let b_body = spin * reference.b_gcrf_nt;
            let sun_body = spin * reference.sun_gcrf_unit;
            let u: Vec<f64> = PANELS
                .iter()
                .take(regressors)
                .map(|n| 0.5 * reference.sun_fraction * Vector3::from(*n).dot(&sun_body).max(0.0))
                .collect();
            let noise = Vector3::from_fn(|_, _| {
                let z: f64 = StandardNormal.sample(&mut rng);
                truth.noise_nt * z
            });
            let m = truth.t * b_body
                + truth.bias_nt
                + truth
                    .coeff_nt
                    .iter()
                    .zip(&u)
                    .fold(Vector3::zeros(), |acc, (c, uj)| acc + c * *uj)
                + noise;
            sample_along_orbit(&model, k, t_s, m, u).expect("in range")
        })
        .collect()
}

/// Regressor names `cur_<panel>_A`.
pub fn names(regressors: usize) -> Vec<String> {
    ["cur_px_A", "cur_py_A", "cur_mz_A", "cur_mx_A"][..regressors]
        .iter()
        .map(|s| s.to_string())
        .collect()
}
