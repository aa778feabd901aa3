//! The filter step allocates nothing once it has run (issue 7: "no heap allocation per
//! step"): the benchmark's 17-photodiode step, counted by dhat's allocator. Its own test
//! binary, since the allocator is global.

#[path = "../benches/common/mod.rs"]
mod bench_common;

use bench_common::{albedo, setup, step};
use pdcal_filter::Algebra;

#[global_allocator]
static ALLOC: dhat::Alloc = dhat::Alloc;

#[test]
fn filter_steps_allocate_nothing() {
    let _profiler = dhat::Profiler::builder().testing().build();
    let albedo = albedo();
    let mut s = setup(17, Algebra::Structured, &albedo);
    // The first step sizes the work space that grows to the largest step.
    step(&mut s, &albedo);
    let before = dhat::HeapStats::get();
    for _ in 0..200 {
        step(&mut s, &albedo);
    }
    let after = dhat::HeapStats::get();
    // Every one of the 200 steps made its 20 scalar updates (so the count covers them).
    assert_eq!(s.filter.records().len(), 20);
    assert!(s.filter.records().iter().all(|r| r.accepted));
    assert_eq!(
        after.total_blocks - before.total_blocks,
        0,
        "{} allocations ({} bytes) in 200 steps",
        after.total_blocks - before.total_blocks,
        after.total_bytes - before.total_bytes
    );
}
