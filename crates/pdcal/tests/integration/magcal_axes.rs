//! `pdcal magcal` checks the sensors' axes as `calibrate` does (the magnetometer against the
//! gyro and the photodiodes): each fault is reported in magcal.json `sensor_axes` with the
//! right matrix (not applied: the magnitude fit does not depend on the axes), the clean set
//! has none, and the fit is the same either way.

use std::sync::OnceLock;

use nalgebra::Matrix3;
use pdcal_attitude::{az_el_from_normal, normal_from_az_el};
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

#[derive(Clone, Copy)]
enum Fault {
    Gyro,
    Magnetometer,
    Table,
}

fn m(rows: [[f64; 3]; 3]) -> Matrix3<f64> {
    Matrix3::from_row_slice(&rows.concat())
}

/// magcal on the set with `fault`'s sensor recorded in axes `body_from_sensor`.
fn magcal(fault: Option<(Fault, Matrix3<f64>)>) -> pdcal::magcal::MagCalOutcome {
    let (mut meta, mut telemetry) = (sim().meta.clone(), sim().telemetry.clone());
    if let Some((fault, body_from_sensor)) = fault {
        let to_sensor = body_from_sensor.transpose();
        match fault {
            Fault::Gyro => telemetry.gyro_rad_s.map_in_place(|v| to_sensor * v),
            Fault::Magnetometer => telemetry
                .mag_nt
                .as_mut()
                .unwrap()
                .map_in_place(|v| to_sensor * v),
            Fault::Table => {
                for mount in &mut meta.photodiodes {
                    let n = normal_from_az_el(
                        mount.azimuth_deg.to_radians(),
                        mount.elevation_deg.to_radians(),
                    );
                    let (az, el) = az_el_from_normal(&(to_sensor * n));
                    (mount.azimuth_deg, mount.elevation_deg) = (az.to_degrees(), el.to_degrees());
                }
            }
        }
    }
    pdcal::magcal::run(&meta, &telemetry).unwrap()
}

#[test]
fn magcal_names_each_sensors_wrong_axes_and_not_the_clean_ones() {
    let clean = magcal(None);
    assert_eq!(clean.axes.finding, None, "{:?}", clean.axes);
    let cases = [
        (
            Fault::Magnetometer,
            "magnetometer",
            m([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]),
        ),
        (
            Fault::Magnetometer,
            "magnetometer",
            m([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
        ),
        (
            Fault::Gyro,
            "gyro",
            m([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]),
        ),
        (
            Fault::Table,
            "photodiodes",
            m([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
        ),
        (
            Fault::Table,
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
