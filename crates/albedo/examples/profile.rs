//! The `albedo_17pd` benchmark scene (17 RAX-2 normals, TOMS map, 600 km) as a plain loop,
//! for profilers and instruction counts, which criterion's harness obscures:
//!
//! ```text
//! cargo build --profile bench -p pdcal-albedo --example profile
//! valgrind --tool=callgrind --toggle-collect='*AlbedoModel::compute_into*' \
//!     target/release/examples/profile compute 50
//! valgrind --tool=callgrind --toggle-collect='*AlbedoIrradiance>::ratios*' \
//!     target/release/examples/profile ratios 50
//! ```
//!
//! Arguments: the part to run (`compute`, `ratios`, anything else for both) and the number
//! of calls (default 1000). Prints the mean and best time per call (instruction counts are
//! those of callgrind divided by calls + 1: one warm-up call).

#[path = "../benches/common/mod.rs"]
mod common;

use std::hint::black_box;

use common::{scene, toms_map};
use pdcal_albedo::{AlbedoIrradiance, AlbedoModel, AlbedoView};

fn main() {
    let s = scene();
    let toms = toms_map();
    let model = AlbedoModel::new(&toms);
    let mut view = AlbedoView::with_capacity(4096);
    let mut out = [0.0; 17];
    let part = std::env::args().nth(1).unwrap_or_default();
    let n: usize = std::env::args()
        .nth(2)
        .and_then(|a| a.parse().ok())
        .unwrap_or(1000);
    model
        .compute_into(&mut view, &s.r_sat, &s.r_sun, &s.rot)
        .unwrap();
    let t = std::time::Instant::now();
    let mut best = f64::INFINITY;
    for _ in 0..n {
        let t0 = std::time::Instant::now();
        if part != "ratios" {
            model
                .compute_into(&mut view, black_box(&s.r_sat), &s.r_sun, &s.rot)
                .unwrap();
        }
        if part != "compute" {
            view.ratios(black_box(&s.normals), &s.cos_fov, &mut out);
        }
        best = best.min(t0.elapsed().as_secs_f64());
        black_box(out[0]);
    }
    eprintln!(
        "{part}: mean {:.2} us, best {:.2} us, cells {} tiles {}",
        t.elapsed().as_secs_f64() / n as f64 * 1e6,
        best * 1e6,
        view.len(),
        view.n_tiles()
    );
    eprintln!("slots {}", view.n_slots());
}
