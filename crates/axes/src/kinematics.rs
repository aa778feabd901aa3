//! The three checks' residuals for given sensor matrices.

use nalgebra::{Matrix3, Rotation3, Vector3};

/// One step of a vector sensor between two rows: the vector at both (unit, the sensor's
/// stated frame), the gyro's mean rate over the step (its stated frame) and the step.
#[derive(Debug, Clone, Copy)]
pub struct Step {
    pub from: Vector3<f64>,
    pub to: Vector3<f64>,
    pub rate_rad_s: Vector3<f64>,
    pub dt_s: f64,
}

/// One row with both directions: the Sun from the photodiodes and the field (unit, their
/// stated frames), and the cosine of the angle between the references.
#[derive(Debug, Clone, Copy)]
pub struct Angle {
    pub sun: Vector3<f64>,
    pub field: Vector3<f64>,
    pub cos_ref: f64,
}

/// Smallest robust scale of a kinematic residual, rad (and of a cosine residual).
pub const SCALE_FLOOR: f64 = 1e-4;

/// `1.4826` times the median absolute value: a Gaussian's sigma from its spread.
pub fn robust_scale(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return SCALE_FLOOR;
    }
    values.iter_mut().for_each(|v| *v = v.abs());
    let mid = values.len() / 2;
    let (_, median, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    (1.4826 * *median).max(SCALE_FLOOR)
}

/// The residual components of the gyro carrying the vector sensor's direction from row to
/// row, body frame: `S_v v' - exp(-[(S_g w - b) dt]x) S_v v`, with the gyro bias `b` fitted
/// (iteratively reweighted Gauss-Newton with Cauchy weights at the residuals' own robust
/// scale); the bias is returned with them.
pub fn step_residuals(
    steps: &[Step],
    body_from_gyro: &Matrix3<f64>,
    body_from_vector: &Matrix3<f64>,
    bias_sigma_rad_s: Option<f64>,
) -> (Vec<f64>, Vector3<f64>) {
    // The bias's Gaussian prior, in the currency of the Cauchy cost's curvature at 0.
    let prior = bias_sigma_rad_s.map_or(0.0, |s| 1.0 / (2.0 * s * s));
    let mut bias = Vector3::zeros();
    let mut residuals = step_components(steps, body_from_gyro, body_from_vector, &bias);
    for _ in 0..4 {
        let scale = robust_scale(&mut residuals.clone());
        let mut normal = Matrix3::zeros();
        let mut rhs = Vector3::zeros();
        for (step, r) in steps.iter().zip(residuals.chunks_exact(3)) {
            let r = Vector3::new(r[0], r[1], r[2]);
            let carried = carried(step, body_from_gyro, body_from_vector, &bias);
            // d(carried)/d(bias) = -[carried]x dt (a bias lowers the rate the gyro gives).
            let jacobian = carried.cross_matrix() * step.dt_s;
            let weight = 1.0 / (scale * scale + r.norm_squared() / 3.0);
            normal += jacobian.transpose() * jacobian * weight;
            rhs += jacobian.transpose() * r * weight;
        }
        rhs += bias * prior;
        let Some(inverse) = (normal + Matrix3::identity() * (prior + 1e-12)).try_inverse() else {
            break;
        };
        // r = to - carried(b); carried(b + d) = carried(b) - J d, so r(b + d) = r + J d.
        bias -= inverse * rhs;
        residuals = step_components(steps, body_from_gyro, body_from_vector, &bias);
    }
    (residuals, bias)
}

fn carried(
    step: &Step,
    body_from_gyro: &Matrix3<f64>,
    body_from_vector: &Matrix3<f64>,
    bias: &Vector3<f64>,
) -> Vector3<f64> {
    let rate = body_from_gyro * step.rate_rad_s - bias;
    Rotation3::new(-rate * step.dt_s) * (body_from_vector * step.from)
}

fn step_components(
    steps: &[Step],
    body_from_gyro: &Matrix3<f64>,
    body_from_vector: &Matrix3<f64>,
    bias: &Vector3<f64>,
) -> Vec<f64> {
    steps
        .iter()
        .flat_map(|s| {
            let r = body_from_vector * s.to - carried(s, body_from_gyro, body_from_vector, bias);
            [r.x, r.y, r.z]
        })
        .collect()
}

/// The cosine residuals `(S_p s) . (S_m b) - cos_ref`.
pub fn angle_residuals(
    angles: &[Angle],
    body_from_photodiodes: &Matrix3<f64>,
    body_from_magnetometer: &Matrix3<f64>,
) -> Vec<f64> {
    angles
        .iter()
        .map(|a| {
            (body_from_photodiodes * a.sun).dot(&(body_from_magnetometer * a.field)) - a.cos_ref
        })
        .collect()
}

/// The Gaussian prior's cost of a bias, nats.
pub fn bias_cost(bias: &Vector3<f64>, bias_sigma_rad_s: Option<f64>) -> f64 {
    bias_sigma_rad_s.map_or(0.0, |s| bias.norm_squared() / (2.0 * s * s))
}

/// The Cauchy cost (negative log-likelihood less its constant) of `residuals` at `scale`.
pub fn cauchy_cost(residuals: &[f64], scale: f64) -> f64 {
    residuals.iter().map(|r| (r / scale).powi(2).ln_1p()).sum()
}
