//! Runs `N` steps (first argument, default 2000) of the `ekf_step_17pd` benchmark's setup:
//! one propagation, 3 magnetometer and 17 photodiode scalar updates, 57 states, albedo from
//! the degree-4 expansion. For instruction counts, e.g.
//! `valgrind --tool=callgrind --toggle-collect='ekf_profile::run_steps' ekf_profile 2000`
//! (Ir per step = total / N; the setup is outside the collected function).
#![allow(missing_docs)]

use std::hint::black_box;

use nalgebra::{Matrix3, Vector3};
use pdcal_albedo::{AlbedoExpansion, AlbedoModel, AlbedoView, MapChoice};
use pdcal_attitude::{GyroNoise, Quat};
use pdcal_filter::{
    Algebra, Filter, FilterConfig, FilterNoise, InitialState, Measurements, StateLayout,
    StepReference, paper_model,
};
use pdcal_photodiode::{Photodiode, Scene};

/// `m` normals spread over the sphere (Fibonacci lattice), as in `benches/ekf.rs`.
fn normals(m: usize) -> Vec<Vector3<f64>> {
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

struct Setup {
    filter: Filter,
    reference: StepReference,
    pd_v: Vec<Option<f64>>,
    mag: Vector3<f64>,
}

fn setup(m: usize, albedo: &AlbedoExpansion) -> Setup {
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
        mag_sigma_nt: 320.0,
        gate_sigmas: 5.0,
        cos_fov: -1.0,
        min_sun_fraction: 0.999,
        second_order: true,
    };
    let filter = Filter::new(model, layout, init, noise, Algebra::Structured).unwrap();
    let sun = Vector3::new(0.8, 0.5, 0.33).normalize();
    let reference = StepReference {
        r_gcrf_km: Vector3::new(7000.0, 0.0, 0.0),
        sun_gcrf_km: sun * 1.496e8,
        sun_gcrf_unit: sun,
        b_gcrf_nt: Vector3::new(20_000.0, -5_000.0, 25_000.0),
        sun_fraction: 1.0,
        gcrf_to_itrf: Matrix3::identity(),
    };
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

fn albedo() -> AlbedoExpansion {
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

#[inline(always)]
fn steps(s: &mut Setup, albedo: &AlbedoExpansion, steps: usize) {
    for _ in 0..steps {
        s.filter.propagate(&Vector3::new(1e-9, 0.0, 0.0), 0.0, 1.0);
        let meas = Measurements {
            mag_nt: Some(s.mag),
            pd_v: &s.pd_v,
        };
        black_box(&mut s.filter)
            .update(0.0, &meas, &s.reference, Some(albedo))
            .unwrap();
    }
}

/// The measured steps (the function callgrind collects).
#[inline(never)]
fn run_steps(s: &mut Setup, albedo: &AlbedoExpansion, n: usize) {
    steps(s, albedo, n);
}

/// Steps before the measured ones (not collected).
#[inline(never)]
fn warm_up(s: &mut Setup, albedo: &AlbedoExpansion, n: usize) {
    steps(s, albedo, n);
}

fn main() {
    let steps: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(2000);
    let albedo = albedo();
    let mut s = setup(17, &albedo);
    // Warm up to the steady state the benchmark measures.
    warm_up(&mut s, &albedo, 200);
    run_steps(&mut s, &albedo, steps);
    // Native timing: best of 200 chunks of 100 steps (the machine is shared).
    let mut best = f64::INFINITY;
    for _ in 0..200 {
        let start = std::time::Instant::now();
        warm_up(&mut s, &albedo, 100);
        best = best.min(start.elapsed().as_secs_f64() / 100.0);
    }
    let p = s.filter.covariance();
    println!(
        "best {:.2} us per step; q = {:?}; scale[0] {:?}; P[0,0] {:e}; P[10,10] {:e}",
        best * 1e6,
        s.filter.q(),
        s.filter.scales_v()[0],
        p[(0, 0)],
        p[(10, 10)]
    );
}
