//! `pdcal magcal` checks the sensors' axes as `calibrate` does (the magnetometer against the
//! gyro and the photodiodes): each fault is reported in magcal.json `sensor_axes` with the
//! right matrix (not applied: the magnitude fit does not depend on the axes), the clean set
//! has none, and the fit is the same either way.

use std::sync::OnceLock;

use nalgebra::Matrix3;
use pdcal_axes::Sensor;
use pdcal_sim::SimOutput;

fn sim() -> &'static SimOutput {
    static SIM: OnceLock<SimOutput> = OnceLock::new();
    SIM.get_or_init(|| {
        let text = include_str!("../../../../fixtures/scenarios/magcal/rax2-like-magcal.ron");
        let mut scenario = pdcal_sim::Scenario::from_ron_str(text).unwrap();
        scenario.duration_s = 3600.0;
        pdcal::simulate::run_downlink(&scenario, 4, 0).unwrap()
    })
}

fn m(rows: [[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_row_slice(&rows.concat())
}

/// magcal on the set with `sensor` recorded in axes `body_from_sensor`.
fn magcal(fault: Option<(Sensor, Matrix3<f64>)>) -> pdcal::magcal::MagCalOutcome {
    let (mut meta, mut telemetry) = (sim().meta.clone(), sim().telemetry.clone());
    if let Some((sensor, body_from_sensor)) = fault {
        pdcal::axes::transform(
            sensor,
            &body_from_sensor.transpose(),
            &mut meta,
            &mut telemetry,
        );
    }
    pdcal::magcal::run(&meta, &telemetry).unwrap()
}

#[test]
fn magcal_names_each_sensors_wrong_axes_and_not_the_clean_ones() {
    let clean = magcal(None);
    assert_eq!(clean.axes.finding, None, "{:?}", clean.axes);
    let cases = [
        (
            Sensor::Magnetometer,
            "magnetometer",
            m([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]),
        ),
        (
            Sensor::Magnetometer,
            "magnetometer",
            m([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
        ),
        (
            Sensor::Gyro,
            "gyro",
            m([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
        ),
        (
            Sensor::Photodiodes,
            "photodiodes",
            m([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
        ),
        (
            Sensor::Photodiodes,
            "photodiodes",
            m([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
        ),
    ];
    for (fault, name, matrix) in cases {
        let outcome = magcal(Some((fault, matrix)));
        let finding = outcome
            .axes
            .finding
            .as_ref()
            .unwrap_or_else(|| panic!("{name}: {:?}", outcome.axes));
        assert_eq!((finding.sensor.as_str(), finding.matrix()), (name, matrix));
        let entries = pdcal::axes::entries_applied(&outcome.axes, false);
        assert_eq!(entries.len(), 1);
        assert!(!entries[0].applied);
        assert!(
            outcome
                .warnings
                .iter()
                .any(|w| w.contains("not applied by magcal")),
            "{:?}",
            outcome.warnings
        );
    }
}
