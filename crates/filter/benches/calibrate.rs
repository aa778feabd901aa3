//! The whole 2 h rax2-like data set (7201 rows, 17 photodiodes, TOMS albedo): `calibrate`
//! forward filter only (`calibrate_rax2_2h`) and with the RTS smoother
//! (`calibrate_rax2_2h_smoothed`), and the forward filter with the rigid-body dynamics on
//! (`calibrate_rax2_2h_dynamics`: the rate and dipole states, the gyro a measurement), and
//! photodiode-only forward filters without and with the multi-start ensemble
//! (`calibrate_rax2_2h_photodiode_only`, `..._ensemble`: eight more forward passes).
//! Simulation, references and the albedo map are built once
//! outside the timed loop; albedo evaluation per row is inside it (as in the driver).
#![allow(missing_docs)]

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use pdcal_albedo::{AlbedoModel, MapChoice};
use pdcal_filter::{
    Dynamics, EnsembleRuns, FilterConfig, Mode, RunInputs, calibrate, step_references,
};

fn bench(c: &mut Criterion) {
    let scenario = pdcal_sim::Scenario::rax2_like().unwrap();
    let sim = pdcal_sim::simulate(&scenario, 1).unwrap();
    let references = step_references(&sim.meta, &sim.telemetry).unwrap();
    let albedo = AlbedoModel::from_choice(&MapChoice::TomsMean1p25x1).unwrap();
    let inputs = RunInputs {
        meta: &sim.meta,
        telemetry: &sim.telemetry,
        references: (&references).into(),
        albedo: Some(&albedo),
        set_first_rows: &[],
    };
    let forward = FilterConfig {
        smoother: false,
        ..FilterConfig::default()
    };
    let mut group = c.benchmark_group("calibrate");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(8));
    group.bench_function("calibrate_rax2_2h", |b| {
        b.iter(|| calibrate(&inputs, &forward, &Mode::Full).unwrap())
    });
    let dynamics = FilterConfig {
        dynamics: Dynamics::On,
        ..forward.clone()
    };
    group.bench_function("calibrate_rax2_2h_dynamics", |b| {
        b.iter(|| calibrate(&inputs, &dynamics, &Mode::Full).unwrap())
    });
    let alone = FilterConfig {
        ensemble: EnsembleRuns::Off,
        ..forward.clone()
    };
    group.bench_function("calibrate_rax2_2h_photodiode_only", |b| {
        b.iter(|| calibrate(&inputs, &alone, &Mode::PhotodiodeOnly).unwrap())
    });
    group.bench_function("calibrate_rax2_2h_photodiode_only_ensemble", |b| {
        b.iter(|| calibrate(&inputs, &forward, &Mode::PhotodiodeOnly).unwrap())
    });
    group.bench_function("calibrate_rax2_2h_smoothed", |b| {
        b.iter(|| calibrate(&inputs, &FilterConfig::default(), &Mode::Full).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
