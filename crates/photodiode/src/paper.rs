//! The paper's named measurement model and partials (Section III.B) as free functions of the
//! direct-Sun term, for the filter and for checking the general model against the paper.
//!
//! Gradients are returned as column vectors; the paper's row vectors are their transposes.

use nalgebra::Vector3;
use pdcal_attitude::{normal_from_az_el, normal_partials};

/// Eq. (15) without noise, with the rule of the scenario: the direct-Sun part is zero when
/// `n^T A s <= 0`. `albedo_ratio` is `E_a/E_AM0`.
pub fn predicted_output(
    scale_v: f64,
    n_body: &Vector3<f64>,
    sun_body: &Vector3<f64>,
    albedo_ratio: f64,
) -> f64 {
    scale_v * n_body.dot(sun_body).max(0.0) + scale_v * albedo_ratio
}

/// Eq. (20): `dI/da = C n^T [(A s) x]`, returned as the column `C (n x A s)`.
pub fn d_output_d_attitude(
    scale_v: f64,
    n_body: &Vector3<f64>,
    sun_body: &Vector3<f64>,
) -> Vector3<f64> {
    n_body.cross(sun_body) * scale_v
}

/// Eq. (21): the output does not depend on the gyro bias.
pub fn d_output_d_gyro_bias() -> Vector3<f64> {
    Vector3::zeros()
}

/// Eq. (22): `dI/dC = n^T A s`.
pub fn d_output_d_scale(n_body: &Vector3<f64>, sun_body: &Vector3<f64>) -> f64 {
    n_body.dot(sun_body)
}

/// Eq. (23): `dI/d alpha = C [-cos(el) sin(az), cos(el) cos(az), 0] A s`.
pub fn d_output_d_azimuth(
    scale_v: f64,
    azimuth_rad: f64,
    elevation_rad: f64,
    sun_body: &Vector3<f64>,
) -> f64 {
    scale_v * normal_partials(azimuth_rad, elevation_rad).0.dot(sun_body)
}

/// Eq. (24): `dI/d epsilon = C (dn/d el)^T A s` with `dn/d el = [-sin(el) cos(az),
/// -sin(el) sin(az), cos(el)]`. The paper prints `+sin(el) sin(az)` as the y component; the
/// derivative of Eq. (16) has the minus sign, which the finite-difference tests confirm.
pub fn d_output_d_elevation(
    scale_v: f64,
    azimuth_rad: f64,
    elevation_rad: f64,
    sun_body: &Vector3<f64>,
) -> f64 {
    scale_v * normal_partials(azimuth_rad, elevation_rad).1.dot(sun_body)
}

/// Eq. (25): the residual `measured - predicted`, with the prediction of Eq. (15) at the
/// estimated parameters and attitude.
pub fn residual_v(
    measured_v: f64,
    scale_v: f64,
    azimuth_rad: f64,
    elevation_rad: f64,
    sun_body: &Vector3<f64>,
    albedo_ratio: f64,
) -> f64 {
    measured_v
        - predicted_output(
            scale_v,
            &normal_from_az_el(azimuth_rad, elevation_rad),
            sun_body,
            albedo_ratio,
        )
}
