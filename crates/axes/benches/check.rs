//! The sensor-axes check on a 2-hour 1 Hz tumble (gyro, magnetometer, the Sun direction):
//! what it adds to every calibration.
#![allow(missing_docs)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::{Rotation3, Vector3};
use pdcal_axes::{Inputs, Thresholds, check};

type Series = Vec<Option<Vector3<f64>>>;

/// The rows of a tumble.
#[derive(Default)]
struct Rows {
    t_s: Vec<f64>,
    gyro: Series,
    mag: Series,
    sun: Series,
    references: Vec<(Vector3<f64>, Vector3<f64>)>,
}

/// Noise-free rows of a tri-axial tumble at 4 deg/s (the check's cost does not depend on
/// the noise), the Sun hidden 2000 s of every 5700.
fn tumble() -> Rows {
    let sun = Vector3::new(0.3, -0.5, 0.81).normalize();
    let field0 = Vector3::new(20_000.0, -15_000.0, 25_000.0);
    let w = 4f64.to_radians();
    let mut attitude = Rotation3::from_scaled_axis(Vector3::new(0.4, 1.1, -0.7));
    let mut rows = Rows::default();
    for k in 0..7200 {
        let t = f64::from(k);
        let rate = Vector3::new(
            0.6 * w * (0.02 * t).cos(),
            0.6 * w * (0.02 * t).sin(),
            0.8 * w * (0.013 * t).cos(),
        );
        let field = Rotation3::from_scaled_axis(Vector3::new(0.0, 0.0, 0.0022 * t)) * field0;
        rows.t_s.push(t);
        rows.gyro.push(Some(rate));
        rows.mag.push(Some(attitude * field));
        rows.sun
            .push(((t % 5700.0) < 3700.0).then(|| attitude * sun));
        rows.references.push((sun, field));
        attitude = Rotation3::from_scaled_axis(-rate) * attitude;
    }
    rows
}

fn bench(c: &mut Criterion) {
    let rows = tumble();
    let inputs = Inputs {
        t_s: &rows.t_s,
        gyro_rad_s: &rows.gyro,
        mag: &rows.mag,
        sun_photodiodes: &rows.sun,
        references: &rows.references,
        gyro_bias_sigma_rad_s: 5f64.to_radians(),
    };
    let thresholds = Thresholds::default();
    let mut group = c.benchmark_group("axes");
    group.sample_size(10);
    group.bench_function("check_2h_1hz_gyro_mag_sun", |b| {
        b.iter(|| check(black_box(&inputs), &thresholds))
    });
    group.finish();
}

criterion_group!(axes, bench);
criterion_main!(axes);
