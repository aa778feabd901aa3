//! `albedo_17pd`: the full model for 17 photodiodes (RAX-2 normals under a fixed attitude,
//! TOMS map, 600 km, lit Earth in view), against the naive all-cell loop and the onboard
//! approximation.

mod common;

use std::hint::black_box;

use common::{scene, toms_map};
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Vector3;
use pdcal_albedo::{AlbedoExpansion, AlbedoIrradiance, AlbedoModel, AlbedoView};

fn benches(c: &mut Criterion) {
    let s = scene();
    let toms = toms_map();
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
    // What the filter calls once per step: ratio and gradient for all 17, four per pass.
    let mut with_vectors = vec![(0.0, Vector3::zeros()); s.normals.len()];
    c.bench_function("albedo_approx_batch_vectors_17pd", |b| {
        b.iter(|| {
            expansion.ratios_and_vectors(black_box(&s.normals), &s.cos_fov, &mut with_vectors);
            black_box(with_vectors[0].0)
        })
    });
    c.bench_function("albedo_approx_single_vectors_17pd", |b| {
        b.iter(|| {
            for ((n, &cf), slot) in s.normals.iter().zip(&s.cos_fov).zip(&mut with_vectors) {
                *slot = expansion.ratio_and_vector(black_box(n), cf);
            }
            black_box(with_vectors[0].0)
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
