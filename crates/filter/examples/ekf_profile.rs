//! Runs `N` steps (first argument, default 2000) of the `ekf_step_17pd` benchmark's setup:
//! one propagation, 3 magnetometer and 17 photodiode scalar updates, 57 states, albedo from
//! the degree-4 expansion. For instruction counts, e.g.
//! `valgrind --tool=callgrind --toggle-collect='ekf_profile::run_steps' ekf_profile 2000`
//! (Ir per step = total / N; the setup is outside the collected function).
#![allow(missing_docs)]

#[path = "../benches/common/mod.rs"]
mod common;

use std::hint::black_box;

use common::{Setup, albedo, setup};
use nalgebra::Vector3;
use pdcal_albedo::AlbedoExpansion;
use pdcal_filter::{Algebra, Measurements};

#[inline(always)]
fn steps(s: &mut Setup, albedo: &AlbedoExpansion, steps: usize) {
    for _ in 0..steps {
        s.filter.propagate(&Vector3::new(1e-9, 0.0, 0.0), 0.0, 1.0);
        let meas = Measurements {
            mag_nt: Some(s.mag),
            pd_v: &s.pd_v,
            temperature_c: &[],
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
    let mut s = setup(17, Algebra::Structured, &albedo);
    // Warm up to the steady state the benchmark measures.
    warm_up(&mut s, &albedo, 200);
    run_steps(&mut s, &albedo, steps);
    // Native timing over 200 chunks of 100 steps: best (the machine is shared), median and
    // mean.
    let mut chunks: Vec<f64> = (0..200)
        .map(|_| {
            let start = std::time::Instant::now();
            warm_up(&mut s, &albedo, 100);
            start.elapsed().as_secs_f64() / 100.0
        })
        .collect();
    let mean = chunks.iter().sum::<f64>() / chunks.len() as f64;
    chunks.sort_by(f64::total_cmp);
    let (best, median) = (chunks[0], chunks[chunks.len() / 2]);
    let p = s.filter.covariance();
    println!(
        "best {:.2} us, median {:.2} us, mean {:.2} us per step; q = {:?}; scale[0] {:?}; P[0,0] {:e}; P[10,10] {:e}",
        best * 1e6,
        median * 1e6,
        mean * 1e6,
        s.filter.q(),
        s.filter.scales_v()[0],
        p[(0, 0)],
        p[(10, 10)]
    );
}
