//! Sensor frames found, not assumed: the rax2-like set with one sensor's axes recorded in a
//! wrong signed permutation (a reversed gyro axis, a swapped magnetometer pair, a cyclic
//! gyro, the photodiode table turned or mirrored) is named with the right matrix before the
//! filter, and the clean set is not.

use std::sync::OnceLock;

use nalgebra::{Matrix3, Vector3};
use pdcal::calibrate::{RunConfig, albedo_model};
use pdcal_axes::{AxesCheck, Sensor};
use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_sim::SimOutput;

fn sim() -> &'static SimOutput {
    static SIM: OnceLock<SimOutput> = OnceLock::new();
    SIM.get_or_init(|| {
        let scenario = pdcal_sim::Scenario::rax2_like().unwrap();
        pdcal::simulate::run(&scenario, 2).unwrap()
    })
}

/// The set as a sensor of axes `body_from_sensor` records it: `v_sensor = M^T v_body`.
fn recorded(sensor: Sensor, m: &Matrix3<f64>, photodiode_only: bool) -> (DatasetMeta, Telemetry) {
    let mut meta = sim().meta.clone();
    let mut telemetry = sim().telemetry.clone();
    if photodiode_only {
        telemetry.mag_nt = None;
    }
    pdcal::axes::transform(sensor, &m.transpose(), &mut meta, &mut telemetry);
    (meta, telemetry)
}

fn axes(meta: &DatasetMeta, telemetry: &Telemetry) -> AxesCheck {
    let references = pdcal_filter::step_references(meta, telemetry).unwrap();
    pdcal::axes::check(
        meta,
        telemetry,
        &(&references).into(),
        &pdcal_filter::FilterConfig::default(),
        &[],
    )
    .unwrap()
}

fn found(sensor: Sensor, m: Matrix3<f64>, photodiode_only: bool) -> Option<(Sensor, Matrix3<f64>)> {
    let (meta, telemetry) = recorded(sensor, &m, photodiode_only);
    axes(&meta, &telemetry)
        .finding
        .map(|f| (f.sensor, f.matrix()))
}

fn m(rows: [[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_row_slice(&rows.concat())
}

#[test]
fn the_clean_set_has_no_finding() {
    let result = axes(&sim().meta, &sim().telemetry);
    assert_eq!(result.finding, None, "{result:?}");
    // rax2-like is axisymmetric (its z rate constant): a reversed gyro z is the stated gyro
    // with another bias, and the check says it could not tell them apart.
    assert!(
        result.not_checked.iter().all(|n| n.sensor == Sensor::Gyro),
        "{result:?}"
    );
}

#[test]
fn a_reversed_gyro_axis_a_cyclic_gyro_and_a_swapped_magnetometer_are_found() {
    let reversed_y = m([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]]);
    assert_eq!(
        found(Sensor::Gyro, reversed_y, false),
        Some((Sensor::Gyro, reversed_y))
    );
    let cyclic = m([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    assert_eq!(
        found(Sensor::Gyro, cyclic, false),
        Some((Sensor::Gyro, cyclic))
    );
    let swap_xy = m([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]);
    assert_eq!(
        found(Sensor::Magnetometer, swap_xy, false),
        Some((Sensor::Magnetometer, swap_xy))
    );
    let reversed_z = m([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]);
    assert_eq!(
        found(Sensor::Magnetometer, reversed_z, false),
        Some((Sensor::Magnetometer, reversed_z))
    );
}

#[test]
fn a_turned_and_a_mirrored_photodiode_table_are_found() {
    let turned_z = m([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]);
    assert_eq!(
        found(Sensor::Photodiodes, turned_z, false),
        Some((Sensor::Photodiodes, turned_z))
    );
    let mirrored_x = m([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    assert_eq!(
        found(Sensor::Photodiodes, mirrored_x, false),
        Some((Sensor::Photodiodes, mirrored_x))
    );
}

#[test]
fn photodiode_only_data_check_the_gyro_against_the_sun_direction() {
    let swap_xy = m([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]);
    assert_eq!(
        found(Sensor::Gyro, swap_xy, true),
        Some((Sensor::Gyro, swap_xy))
    );
}

#[test]
fn a_reversed_gyro_axis_is_applied_and_the_run_calibrates_as_the_clean_one() {
    let reversed_x = m([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    let (meta, telemetry) = recorded(Sensor::Gyro, &reversed_x, false);
    let outcome = pdcal::calibrate::run(
        &meta,
        &telemetry,
        &RunConfig::default(),
        &albedo_model().unwrap(),
    )
    .unwrap();
    let summary = pdcal::files::summary(&meta, &outcome);
    assert_eq!(summary.sensor_axes.len(), 1);
    assert_eq!(summary.sensor_axes[0].sensor, "gyro");
    assert_eq!(
        summary.sensor_axes[0].body_from_sensor,
        [[-1, 0, 0], [0, 1, 0], [0, 0, 1]]
    );
    assert!(summary.sensor_axes[0].applied);
    let warning = outcome
        .warnings
        .iter()
        .find(|w| w.starts_with("sensor axes:"))
        .unwrap();
    assert!(
        warning.contains("in the import map, gyro.x: negate its gain"),
        "{warning}"
    );
    assert!(outcome.mountings.is_empty(), "{:?}", outcome.mountings);
    assert_eq!(
        outcome.consistency.verdict,
        pdcal_filter::Verdict::Consistent
    );
    // The clean run's bounds (docs/validation.md, rax2-like full mode).
    for (i, (cal, truth)) in outcome
        .run
        .calibration
        .photodiodes
        .iter()
        .zip(&sim().true_photodiodes)
        .enumerate()
    {
        let normal_error = cal.n_body().angle(&truth.n_body).to_degrees();
        let scale_error = 100.0 * (cal.scale_v / truth.scale_v - 1.0).abs();
        assert!(
            normal_error <= 0.3 && scale_error <= 0.5,
            "pd{:02}: {normal_error} deg, {scale_error} %",
            i + 1
        );
    }
    // The gyro was turned back, not its x rate taken up by the bias.
    let bias = Vector3::from(outcome.run.calibration.gyro_bias_rad_s);
    assert!(bias.norm() < 0.02, "{bias:?}");
}
