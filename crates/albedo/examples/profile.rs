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

use std::hint::black_box;

use nalgebra::{Matrix3, Rotation3, Vector3};
use pdcal_albedo::{
    AU_KM, AlbedoIrradiance, AlbedoModel, AlbedoView, ReflectivityMap, authalic_radius_km,
};

/// RAX-2 photodiode azimuth/elevation, deg (docs/rax2-scenario.md).
const AZ_EL_DEG: [(f64, f64); 17] = pdcal_attitude::RAX2_TABLE1_AZ_EL_DEG;

struct Scene {
    r_sat: Vector3<f64>,
    r_sun: Vector3<f64>,
    rot: Matrix3<f64>,
    normals: Vec<Vector3<f64>>,
    cos_fov: Vec<f64>,
}

fn scene() -> Scene {
    let sun = Vector3::new(0.2, -0.9, 0.38).normalize();
    // Satellite 30 deg from the sub-solar point, 600 km altitude.
    let axis = sun.cross(&Vector3::z()).normalize();
    let sat = Rotation3::new(axis * 30f64.to_radians()) * sun;
    // Body to GCRF: an arbitrary attitude; n_gcrf = A^T n_body.
    let body_to_gcrf = Rotation3::new(Vector3::new(0.3, -0.5, 0.8).normalize() * 1.2);
    let normals = AZ_EL_DEG
        .iter()
        .map(|&(az, el): &(f64, f64)| {
            let (az, el) = (az.to_radians(), el.to_radians());
            body_to_gcrf * Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
        })
        .collect();
    Scene {
        r_sat: sat * (authalic_radius_km() + 600.0),
        r_sun: sun * AU_KM,
        // An Earth rotation angle of 40 deg about z (the crate takes any rotation).
        rot: Rotation3::from_axis_angle(&Vector3::z_axis(), 40f64.to_radians()).into_inner(),
        normals,
        cos_fov: vec![70f64.to_radians().cos(); 17],
    }
}

fn main() {
    let s = scene();
    let toms = ReflectivityMap::parse_toms_dat(
        "toms",
        include_str!("../../../fixtures/albedo/earthReflectivityMean_1p25x1.dat"),
    )
    .expect("shipped map");
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
