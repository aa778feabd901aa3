//! A dataset typed by hand, as another tool or a person with a text editor would, reads.

use crate::common;

use std::fs;

use common::{TLE1, TLE2};
use nalgebra::Vector3;
use pdcal_dataset::{OrbitSpec, read_dataset};

fn dataset_ron() -> String {
    format!(
        r#"// Written by hand: comments, odd spacing, `Some(..)` spelled out, fields reordered.
(
    name: "hand-made",
    format_version: 1,
    epoch_utc: "2011-11-04T18:29:45Z",
    orbit: Tle(
        line1: "{TLE1}",
        line2: "{TLE2}",
    ),
    photodiodes: [
        (azimuth_deg: 17.0, elevation_deg: -10.0),
        (elevation_deg: 20, azimuth_deg: 0.0),   // integers are fine for floats
    ],
    noise: Some((mag_nT: 320.0)),
)
"#
    )
}

// Columns shuffled, blanks after commas, CRLF line ends, empty cells for unsampled sensors.
const TELEMETRY: &str = "pd02_V, t_s, gyro_z_rad_s, gyro_x_rad_s, gyro_y_rad_s, pd01_V\r\n\
                         0.5, 0, 0.003, 0.001, 0.002, 3.1\r\n\
                         , 1.0, , , , 1e-3\r\n\
                         0.25, 2.5, -3E-2, 0.0, 4, \r\n";

const TRUTH_CSV: &str = "\
eclipse,t_s,q_w,q_x,q_y,q_z,w_x_rad_s,w_y_rad_s,w_z_rad_s,gyro_bias_x_rad_s,gyro_bias_y_rad_s,gyro_bias_z_rad_s,sun_x,sun_y,sun_z,r_x_km,r_y_km,r_z_km,mag_x_nT,mag_y_nT,mag_z_nT
1,0,1,0,0,0,0.1,0.2,0.3,0.001,0.002,0.003,1,0,0,7000,0,0,20000,0,0
0.5,1,0,1,0,0,0.1,0.2,0.3,0.001,0.002,0.003,0,1,0,0,7000,0,0,20000,0
";

const TRUTH_RON: &str = r#"(
    photodiodes: [
        (scale_V: 3.62, azimuth_deg: 18.3, elevation_deg: -7.9),
        (scale_V: 3.70, azimuth_deg: 1.0, elevation_deg: 21.0),
    ],
    effects: [
        Albedo(map: "toms-mean-1p25x1"),
        DarkOffset(volts: [0.01, 0.02]),
        Penumbra,
        MagBias(nT: [100.0, -50.0, 0.0]),
    ],
)
"#;

#[test]
fn hand_written_dataset_reads() {
    let dir = tempfile::tempdir().unwrap();
    fs::write(dir.path().join("dataset.ron"), dataset_ron()).unwrap();
    fs::write(dir.path().join("telemetry.csv"), TELEMETRY).unwrap();
    fs::write(dir.path().join("truth.csv"), TRUTH_CSV).unwrap();
    fs::write(dir.path().join("truth.ron"), TRUTH_RON).unwrap();
    let ds = read_dataset(dir.path()).unwrap();

    let meta = &ds.meta;
    assert_eq!(meta.name, "hand-made");
    assert!(matches!(meta.orbit, OrbitSpec::Tle { .. }));
    assert_eq!(meta.photodiodes[1].elevation_deg, 20.0);
    let noise = meta.noise.unwrap();
    assert_eq!((noise.gyro_rad_s, noise.mag_nt), (None, Some(320.0)));
    let epoch = hifitime::Epoch::from_gregorian_utc_hms(2011, 11, 4, 18, 29, 45);
    assert_eq!(meta.epoch_utc.epoch(), epoch);

    let tm = &ds.telemetry;
    assert_eq!(tm.t_s, [0.0, 1.0, 2.5]);
    assert_eq!(
        tm.gyro_rad_s.get(0),
        Some(Vector3::new(0.001, 0.002, 0.003))
    );
    assert_eq!(tm.gyro_rad_s.get(1), None);
    assert_eq!(tm.gyro_rad_s.get(2), Some(Vector3::new(0.0, 4.0, -0.03)));
    assert_eq!(tm.pd_v[0], [Some(3.1), Some(1e-3), None]);
    assert_eq!(tm.pd_v[1], [Some(0.5), None, Some(0.25)]);
    assert!(tm.mag_nt.is_none() && tm.r_gcrf_km.is_none());

    let (ts, tc) = ds.truth.as_ref().unwrap();
    assert_eq!(ts.q[1].as_slice(), [1.0, 0.0, 0.0, 0.0]); // [x, y, z, w] from shuffled columns
    assert_eq!(ts.eclipse, [1.0, 0.5]);
    assert_eq!(ts.sun_body[1], Vector3::y());
    assert_eq!(tc.photodiodes[1].scale_v, 3.70);
    let ids: Vec<_> = tc.effects.iter().map(|e| e.id().as_str()).collect();
    assert_eq!(ids, ["albedo", "dark-offset", "penumbra", "mag-bias"]);
}

#[test]
fn contract_example_shape_with_position_columns_reads() {
    // The contract's dataset.ron example, with `orbit: PositionColumns` and no noise block.
    let dir = tempfile::tempdir().unwrap();
    let meta = r#"(
    format_version: 1,
    name: "rax2-like-set1",
    epoch_utc: "2011-11-04T18:29:45Z",      // ISO 8601, UTC; t_s counts from here
    orbit: PositionColumns,
    photodiodes: [
        (azimuth_deg: 17.0, elevation_deg: -10.0),
    ],
)"#;
    fs::write(dir.path().join("dataset.ron"), meta).unwrap();
    fs::write(
        dir.path().join("telemetry.csv"),
        "t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,mag_x_nT,mag_y_nT,mag_z_nT,pd01_V,r_x_km,r_y_km,r_z_km\n\
         0,0,0,0,1,2,3,0.5,7000,0,0\n",
    )
    .unwrap();
    let ds = read_dataset(dir.path()).unwrap();
    assert_eq!(ds.meta.noise, None);
    assert_eq!(
        ds.telemetry.mag_nt,
        Some(vec![Some(Vector3::new(1.0, 2.0, 3.0))].into())
    );
    assert_eq!(
        ds.telemetry.r_gcrf_km,
        Some(vec![Some(Vector3::new(7000.0, 0.0, 0.0))].into())
    );
    assert!(ds.truth.is_none());
}
