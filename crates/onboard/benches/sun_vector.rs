//! One call of the onboard core: 17 photodiodes (RAX-2's head), without the Earth, with a
//! uniform Earth, and with TOMS grids of 10, 5 and 1.25 x 1 deg, in f32 and f64.
#![allow(
    missing_docs,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing
)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use pdcal_albedo::MapChoice;
use pdcal_attitude::{RAX2_TABLE1_AZ_EL_DEG, normal_from_az_el};
use pdcal_onboard::{
    Calibration, EARTH_RADIUS_KM, EarthInput, Options, Photodiode, Real, ReflectivityGrid,
    estimate_sun,
};

fn calibration<T: Real>() -> Calibration<T, 17> {
    Calibration {
        count: 17,
        photodiodes: RAX2_TABLE1_AZ_EL_DEG.map(|(az, el)| {
            let n: [f64; 3] = normal_from_az_el(az.to_radians(), el.to_radians()).into();
            let n = n.map(T::of);
            Photodiode::cosine(T::of(3.7), n, T::of(0.015))
        }),
    }
}

/// The outputs of the cosine model for a Sun between +x and +z, with 0.1 of albedo on the
/// photodiodes facing -z (the Earth below).
fn outputs<T: Real>(cal: &Calibration<T, 17>) -> [T; 17] {
    let sun = [0.6, 0.3, 0.74].map(T::of);
    cal.photodiodes.map(|p| {
        let cos = p.normal_body[0] * sun[0] + p.normal_body[1] * sun[1] + p.normal_body[2] * sun[2];
        let albedo = (-p.normal_body[2]).max(T::zero()) * T::of(0.1);
        p.scale_v * (cos.max(T::zero()) + albedo)
    })
}

fn toms(k_lat: usize, k_lon: usize) -> (usize, usize, Vec<u8>) {
    let map = MapChoice::TomsMean1p25x1
        .load()
        .unwrap()
        .coarsen(k_lat, k_lon)
        .unwrap();
    let bytes = map
        .values()
        .iter()
        .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect();
    (map.n_lat(), map.n_lon(), bytes)
}

fn earth<'a, T: Real>(grid: Option<&'a ReflectivityGrid<'a>>) -> EarthInput<'a, T> {
    // Earth below (-z), Earth-fixed frame turned from the body frame about x.
    let (s, c) = (0.3f64.sin(), 0.3f64.cos());
    EarthInput {
        earth_body: [0.0, 0.0, -1.0].map(T::of),
        orbit_radius_km: T::of(EARTH_RADIUS_KM + 600.0),
        ecef_from_body: Some([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]].map(|r| r.map(T::of))),
        grid,
    }
}

fn bench_type<T: Real>(c: &mut Criterion, name: &str) {
    let cal = calibration::<T>();
    let y = outputs(&cal);
    let options = Options::default();
    c.bench_function(&format!("sun_vector_{name}_no_earth"), |b| {
        b.iter(|| estimate_sun(black_box(&y), &cal, None, &options))
    });
    let uniform = EarthInput {
        ecef_from_body: None,
        ..earth::<T>(None)
    };
    c.bench_function(&format!("sun_vector_{name}_uniform"), |b| {
        b.iter(|| estimate_sun(black_box(&y), &cal, Some(&uniform), &options))
    });
    for (label, k_lat, k_lon) in [("10deg", 10, 8), ("5deg", 5, 4), ("1p25deg", 1, 1)] {
        let (n_lat, n_lon, bytes) = toms(k_lat, k_lon);
        let grid = ReflectivityGrid::new(n_lat, n_lon, &bytes).unwrap();
        let earth = earth::<T>(Some(&grid));
        c.bench_function(&format!("sun_vector_{name}_grid_{label}"), |b| {
            b.iter(|| estimate_sun(black_box(&y), &cal, Some(&earth), &options))
        });
    }
}

fn benches(c: &mut Criterion) {
    bench_type::<f32>(c, "f32");
    bench_type::<f64>(c, "f64");
}

criterion_group!(onboard, benches);
criterion_main!(onboard);
