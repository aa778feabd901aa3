//! One filter step (propagation, `m_p` photodiode and 3 magnetometer scalar updates) for
//! `m_p` = 6, 17, 34, 68, 100, structured and dense. Albedo precomputed: the per-step
//! moment expansion of the TOMS map is built outside the timed loop (what a flight filter
//! would refresh once per step) and evaluated for the step's photodiodes inside it (one
//! batch call). Set-up in `common/mod.rs`, shared with `examples/ekf_profile.rs`. Also the
//! 17-photodiode step with the dynamics-aided propagation (rate states, rigid-body step,
//! gyro update).
#![allow(missing_docs)]

mod common;

use std::hint::black_box;

use common::{albedo, enable_dynamics, setup, step, step_dynamics};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use pdcal_filter::Algebra;

fn bench(c: &mut Criterion) {
    let albedo = albedo();
    let mut s = setup(17, Algebra::Structured, &albedo);
    c.bench_function("ekf_step_17pd", |b| {
        b.iter(|| step(black_box(&mut s), &albedo))
    });
    let mut d = setup(17, Algebra::Structured, &albedo);
    enable_dynamics(&mut d);
    c.bench_function("ekf_step_17pd_dynamics", |b| {
        b.iter(|| step_dynamics(black_box(&mut d), &albedo))
    });
    let mut group = c.benchmark_group("ekf_step");
    for m in [6, 17, 34, 68, 100] {
        let mut s = setup(m, Algebra::Structured, &albedo);
        group.bench_with_input(BenchmarkId::new("structured", m), &m, |b, _| {
            b.iter(|| step(black_box(&mut s), &albedo))
        });
    }
    for m in [6, 17, 34] {
        let mut s = setup(m, Algebra::Dense, &albedo);
        group.bench_with_input(BenchmarkId::new("dense", m), &m, |b, _| {
            b.iter(|| step(black_box(&mut s), &albedo))
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(std::time::Duration::from_secs(2)).warm_up_time(std::time::Duration::from_millis(500));
    targets = bench
}
criterion_main!(benches);
