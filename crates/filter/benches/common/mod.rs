//! The filter-step benchmark's set-up, shared with `examples/ekf_profile.rs` (which
//! includes this file by path).

#![allow(dead_code, missing_docs)]

use nalgebra::{Matrix3, Vector3};
use pdcal_albedo::{AlbedoExpansion, AlbedoModel, AlbedoView, MapChoice};
use pdcal_attitude::{GyroNoise, Quat};
use pdcal_ephem::Reference;
use pdcal_filter::{
    Algebra, Filter, FilterConfig, FilterNoise, InitialState, Measurements, StateLayout,
    paper_model,
};
use pdcal_photodiode::{Photodiode, Scene};

/// `m` normals spread over the sphere (Fibonacci lattice).
pub fn normals(m: usize) -> Vec<Vector3<f64>> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..m)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / m as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            Vector3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

pub struct Setup {
    pub filter: Filter,
    pub reference: Reference,
    pub pd_v: Vec<Option<f64>>,
    pub mag: Vector3<f64>,
}

pub fn setup(m: usize, algebra: Algebra, albedo: &AlbedoExpansion) -> Setup {
    let ns = normals(m);
    let pds: Vec<Photodiode> = ns
        .iter()
        .map(|n| Photodiode::new(3.7, *n, 0.015).unwrap())
        .collect();
    let model = paper_model(pds, &FilterConfig::default());
    let layout = StateLayout::new(&model, true);
    let q = Quat::new_normalized(0.1, -0.3, 0.2, 0.9).unwrap();
    let init = InitialState {
        q,
        attitude_cov: Matrix3::identity() * 1e-3,
        bias_rad_s: Vector3::zeros(),
        bias_sigma_rad_s: 1e-2,
        scale_v: vec![3.7; m],
        scale_sigma_v: vec![0.5; m],
        n_body: ns.clone(),
        normal_sigma_rad: 0.17,
        extra_sigma: vec![],
        used: vec![true; m],
    };
    let noise = FilterNoise {
        gyro: GyroNoise {
            sigma_v_rad_sqrt_s: 1.3e-3,
            sigma_u_rad_s_sqrt_s: 2e-6,
        },
        rate_change_fraction: 0.3,
        scale_walk_var_per_s: vec![1e-9; m],
        normal_walk_var_per_s: 1e-12,
        extra_walk_var_per_s: vec![],
        photodiode_sigma_v: 0.015,
        albedo_sigma_ratio: 50.0 / 1367.0,
        albedo_gain: Some(pdcal_filter::AlbedoGainNoise {
            sigma: 0.2,
            time_s: 360.0,
        }),
        mag_sigma_nt: 320.0,
        gate_sigmas: 5.0,
        // Every photodiode is updated (the benchmark counts m_p updates per step).
        cos_fov: -1.0,
        min_sun_fraction: 0.999,
        second_order: true,
    };
    let filter = Filter::new(model, layout, init, noise, algebra).unwrap();
    let sun = Vector3::new(0.8, 0.5, 0.33).normalize();
    let reference = Reference {
        r_gcrf_km: Vector3::new(7000.0, 0.0, 0.0),
        sun_gcrf_km: sun * 1.496e8,
        sun_gcrf_unit: sun,
        b_gcrf_nt: Vector3::new(20_000.0, -5_000.0, 25_000.0),
        sun_fraction: 1.0,
        gcrf_to_itrf: Matrix3::identity(),
    };
    // Measurements equal to the predictions: the state stays put, P reaches a steady state.
    let a = q.attitude_matrix();
    let scene = Scene::new(a, &sun).unwrap().with_albedo(albedo);
    let pd_v = (0..m)
        .map(|i| Some(filter.model().evaluate(i, &scene).unwrap()))
        .collect();
    Setup {
        mag: a * reference.b_gcrf_nt,
        filter,
        reference,
        pd_v,
    }
}

pub fn step(s: &mut Setup, albedo: &AlbedoExpansion) {
    s.filter.propagate(&Vector3::new(1e-9, 0.0, 0.0), 0.0, 1.0);
    let meas = Measurements {
        mag_nt: Some(s.mag),
        pd_v: &s.pd_v,
        temperature_c: &[],
    };
    s.filter
        .update(0.0, &meas, &s.reference, Some(albedo))
        .unwrap();
}

/// The same step with the dynamics-aided propagation ([`pdcal_filter::rate`]): a 1 s
/// rigid-body step at rest (as [`step`]: the measurements stay the predictions), the gyro
/// update, the photodiode and magnetometer updates.
pub fn enable_dynamics(s: &mut Setup) {
    let body = pdcal_attitude::dynamics::RigidBody::new(Matrix3::from_diagonal(&Vector3::new(
        0.0314, 0.0314, 0.005,
    )))
    .unwrap();
    let model = pdcal_filter::rate::RateModel {
        body,
        torque_psd: 1e-8,
        bias_walk_var_per_s: 4e-12,
        dipole_walk_var_per_s: 1e-8,
        inertia_sigma_fraction: 0.15,
    };
    s.filter
        .enable_dynamics(model, (Vector3::new(1e-9, 0.0, 0.0), 1e-3), 1.0, 8.7e-4);
}

pub fn step_dynamics(s: &mut Setup, albedo: &AlbedoExpansion) {
    let (r, b) = (s.reference.r_gcrf_km, s.reference.b_gcrf_nt);
    let env = pdcal_filter::rate::StepEnvironment {
        r_gcrf_km: [r, r],
        b_gcrf_nt: [b, b],
    };
    s.filter.propagate_dynamics(&env, 1.0);
    let gyro = s.filter.rate_body_rad_s() + s.filter.bias_rad_s();
    s.filter.update_gyro(&gyro).unwrap();
    let meas = Measurements {
        mag_nt: Some(s.mag),
        pd_v: &s.pd_v,
        temperature_c: &[],
    };
    s.filter
        .update(0.0, &meas, &s.reference, Some(albedo))
        .unwrap();
}

pub fn albedo() -> AlbedoExpansion {
    let model = AlbedoModel::from_choice(&MapChoice::TomsMean1p25x1).unwrap();
    let mut view = AlbedoView::new();
    let sun = Vector3::new(0.8, 0.5, 0.33).normalize() * 1.496e8;
    model
        .compute_into(
            &mut view,
            &Vector3::new(7000.0, 0.0, 0.0),
            &sun,
            &Matrix3::identity(),
        )
        .unwrap();
    AlbedoExpansion::from_view(&view)
}
