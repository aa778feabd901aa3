//! `simulate_rax2_2h`: the default scenario, 2 h at 1 Hz with TOMS albedo and penumbra.
//!
//! Run: `cargo bench -p pdcal-sim --bench simulate`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use pdcal_sim::{Scenario, simulate};

fn simulate_rax2_2h(c: &mut Criterion) {
    let scenario = Scenario::rax2_like().expect("the built-in scenario parses");
    let mut group = c.benchmark_group("simulate");
    group.sample_size(10);
    group.bench_function("simulate_rax2_2h", |b| {
        b.iter(|| simulate(black_box(&scenario), black_box(1)).expect("simulation runs"))
    });
    group.finish();
}

criterion_group!(benches, simulate_rax2_2h);
criterion_main!(benches);
