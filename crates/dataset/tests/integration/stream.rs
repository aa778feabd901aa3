//! A dataset written row by row (`TelemetryStream`): the same files as the whole-dataset
//! writer, and nothing published when a row breaks the reader's rules.

use nalgebra::Vector3;
use pdcal_dataset::{
    DatasetMeta, EpochUtc, NominalMount, OrbitSpec, TelemetryLayout, TelemetryRow, begin_dataset,
    read_dataset, write_dataset,
};

fn meta() -> DatasetMeta {
    DatasetMeta {
        format_version: pdcal_dataset::FORMAT_VERSION,
        name: "stream".into(),
        epoch_utc: EpochUtc::parse("2011-11-04T18:29:45Z").unwrap(),
        orbit: OrbitSpec::Tle {
            line1: "1 37853U 11061D   11308.77065972  .00000000  00000-0  20000-4 0  9997".into(),
            line2: "2 37853 101.7000  50.0000 0300509 130.0000 230.0000 14.86144463  1000".into(),
        },
        photodiodes: vec![
            NominalMount {
                azimuth_deg: 0.0,
                elevation_deg: 0.0,
                panel: None,
                fov_deg: None,
            };
            2
        ],
        noise: None,
        inertia_kg_m2: None,
    }
}

fn rows() -> Vec<TelemetryRow> {
    (0..5)
        .map(|k| TelemetryRow {
            t_s: f64::from(k) * 0.5,
            gyro_rad_s: (k != 2).then(|| Vector3::new(0.01, -0.02, 1e-7)),
            mag_nt: Some(Vector3::new(20000.0, -1.5, 3.0e4)),
            pd_v: vec![Some(0.1 * f64::from(k)), (k != 3).then_some(1.0 / 3.0)],
            r_gcrf_km: None,
            temperature_c: vec![],
            current_a: vec![(k != 1).then_some(0.125 * f64::from(k))],
        })
        .collect()
}

fn layout() -> TelemetryLayout {
    TelemetryLayout {
        photodiodes: 2,
        magnetometer: true,
        positions: false,
        temperatures: vec![],
        currents: vec!["cur_px_A".into()],
    }
}

#[test]
fn streamed_rows_give_the_files_of_the_whole_dataset_writer() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("streamed"), tmp.path().join("whole"));
    let writer = begin_dataset(&a).unwrap();
    let mut stream = writer.telemetry_stream(layout()).unwrap();
    for row in rows() {
        stream.push(&row).unwrap();
    }
    assert_eq!(stream.rows(), 5);
    writer.finish_stream(&meta(), stream).unwrap();
    let read = read_dataset(&a).unwrap();
    write_dataset(&b, &read).unwrap();
    for file in ["dataset.ron", "telemetry.csv"] {
        assert_eq!(
            std::fs::read(a.join(file)).unwrap(),
            std::fs::read(b.join(file)).unwrap(),
            "{file}"
        );
    }
    assert_eq!(read.telemetry.pd_v[1].get(3), None);
    assert_eq!(read.telemetry.gyro_rad_s.get(2), None);
}

#[test]
fn a_row_the_reader_refuses_publishes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("ds");
    let writer = begin_dataset(&out).unwrap();
    let mut stream = writer.telemetry_stream(layout()).unwrap();
    let mut rows = rows();
    rows[3].t_s = 0.5;
    for row in &rows {
        stream.push(row).unwrap();
    }
    let e = writer
        .finish_stream(&meta(), stream)
        .unwrap_err()
        .to_string();
    assert!(e.contains("telemetry.csv:5:1 (t_s)"), "{e}");
    assert!(!out.exists());
    // A row of another shape than the layout is refused as it is pushed.
    let writer = begin_dataset(&out).unwrap();
    let mut stream = writer.telemetry_stream(layout()).unwrap();
    let mut row = rows[0].clone();
    row.pd_v.push(None);
    assert!(stream.push(&row).is_err());
}
