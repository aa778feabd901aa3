//! `albedo_17pd`: the full model for 17 photodiodes (RAX-2 normals under a fixed attitude,
//! TOMS map, 600 km, lit Earth in view), against the naive all-cell loop and the onboard
//! approximation.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Matrix3, Rotation3, Vector3};
use pdcal_albedo::{
    AU_KM, AlbedoExpansion, AlbedoIrradiance, AlbedoModel, AlbedoView, ReflectivityMap,
    authalic_radius_km,
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

fn benches(c: &mut Criterion) {
    let s = scene();
    let toms = ReflectivityMap::parse_toms_dat(
        "toms",
        include_str!("../../../fixtures/albedo/earthReflectivityMean_1p25x1.dat"),
    )
    .expect("shipped map");
    let model = AlbedoModel::new(&toms);
    let coarse = AlbedoModel::new(&toms.coarsen(2, 2).expect("2 deg x 2.5 deg blocks"));
    let mut view = AlbedoView::with_capacity(4096);
    let mut out = [0.0; 17];
    model
        .compute_into(&mut view, &s.r_sat, &s.r_sun, &s.rot)
        .expect("valid scene");
    eprintln!("lit cells in view: {} of {}", view.len(), model.n_cells());

    c.bench_function("albedo_17pd", |b| {
        b.iter(|| {
            model
                .compute_into(&mut view, black_box(&s.r_sat), black_box(&s.r_sun), &s.rot)
                .expect("valid scene");
            view.ratios(black_box(&s.normals), &s.cos_fov, &mut out);
            black_box(out[0])
        })
    });

    if std::env::var("ALBEDO_SPLIT").is_ok() {
        // Minimum over many runs: robust to the other processes sharing the machine.
        let min_us = |f: &mut dyn FnMut()| {
            (0..3000)
                .map(|_| {
                    let t = std::time::Instant::now();
                    f();
                    t.elapsed().as_secs_f64() * 1e6
                })
                .fold(f64::INFINITY, f64::min)
        };
        let full = min_us(&mut || {
            model
                .compute_into(&mut view, &s.r_sat, &s.r_sun, &s.rot)
                .unwrap();
            view.ratios(&s.normals, &s.cos_fov, &mut out);
            black_box(out[0]);
        });
        let comp = min_us(&mut || {
            model
                .compute_into(&mut view, &s.r_sat, &s.r_sun, &s.rot)
                .unwrap();
        });
        let rat = min_us(&mut || {
            view.ratios(&s.normals, &s.cos_fov, &mut out);
            black_box(out[0]);
        });
        eprintln!(
            "min us: full {full:.2} compute {comp:.2} ratios {rat:.2} tiles {}",
            view.n_tiles()
        );
        c.bench_function("split_compute_only", |b| {
            b.iter(|| {
                model
                    .compute_into(&mut view, black_box(&s.r_sat), &s.r_sun, &s.rot)
                    .unwrap();
                black_box(view.len())
            })
        });
        c.bench_function("split_ratios_only", |b| {
            b.iter(|| {
                view.ratios(black_box(&s.normals), &s.cos_fov, &mut out);
                black_box(out[0])
            })
        });
    }
    let mut naive = [(0.0, Vector3::zeros()); 17];
    c.bench_function("albedo_17pd_naive", |b| {
        b.iter(|| {
            model
                .naive_ratios(
                    black_box(&s.r_sat),
                    &s.r_sun,
                    &s.rot,
                    &s.normals,
                    &s.cos_fov,
                    &mut naive,
                )
                .expect("valid scene");
            black_box(naive[0].0)
        })
    });

    model
        .compute_into(&mut view, &s.r_sat, &s.r_sun, &s.rot)
        .expect("valid scene");
    let mut expansion = AlbedoExpansion::from_view(&view);
    c.bench_function("albedo_approx_build", |b| {
        b.iter(|| {
            expansion.update(black_box(&view));
            black_box(expansion.max_ratio())
        })
    });
    c.bench_function("albedo_approx_eval_17pd", |b| {
        b.iter(|| {
            expansion.ratios(black_box(&s.normals), &s.cos_fov, &mut out);
            black_box(out[0])
        })
    });
    let mut coarse_view = AlbedoView::with_capacity(512);
    c.bench_function("albedo_approx_coarse_17pd", |b| {
        b.iter(|| {
            coarse
                .compute_into(&mut coarse_view, black_box(&s.r_sat), &s.r_sun, &s.rot)
                .expect("valid scene");
            expansion.update(&coarse_view);
            expansion.ratios(black_box(&s.normals), &s.cos_fov, &mut out);
            black_box(out[0])
        })
    });
}

criterion_group!(albedo, benches);
criterion_main!(albedo);
