//! The skCUBE flight frames (`fixtures/flight/skcube`) through `pdcal import` with their map:
//! the dataset the calibration tests start from, checked against the export's own cells.

use std::path::{Path, PathBuf};

use pdcal_dataset::OrbitSpec;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures")
}

#[test]
fn the_skcube_frames_import_to_a_photodiode_only_dataset() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("skcube");
    let converted = pdcal::import::skcube_dataset(&fixtures(), &out).unwrap();
    let ds = pdcal_dataset::read_dataset(&out).unwrap();
    assert_eq!(ds.meta, converted.meta);

    // 315 frames, none dropped, every time distinct.
    let report = &converted.report;
    assert_eq!((report.rows_read, report.rows_kept), (315, 315));
    assert_eq!(report.duplicate_rows, 0);
    assert!(report.sentinel_cells.is_empty() && report.partial_vectors.is_empty());
    let tm = &ds.telemetry;
    assert_eq!(tm.len(), 315);

    // Five photodiodes with face normals (no Z-), no magnetometer, the README's TLE.
    let mounts: Vec<(f64, f64)> = (ds.meta.photodiodes.iter())
        .map(|p| (p.azimuth_deg, p.elevation_deg))
        .collect();
    assert_eq!(
        mounts,
        [
            (0.0, 0.0),
            (180.0, 0.0),
            (90.0, 0.0),
            (-90.0, 0.0),
            (0.0, 90.0)
        ]
    );
    assert_eq!(tm.pd_v.len(), 5);
    assert!(tm.mag_nt.is_none() && tm.r_gcrf_km.is_none());
    match &ds.meta.orbit {
        OrbitSpec::Tle { line1, .. } => assert!(line1.starts_with("1 42789U 17036AA")),
        other => panic!("orbit {other:?}"),
    }

    // The first frame, 2017-06-23T07:02:55Z (t_rx_unix 1498201375): irradiation 50, 10,
    // 4, 9, 7 counts on X+, X-, Y+, Y-, Z+; gyro -96, -153, 64 counts.
    assert_eq!(ds.meta.epoch_utc.as_str(), "2017-06-23T07:02:55Z");
    assert_eq!(tm.t_s[0], 0.0);
    // One count is written as 0.01 V.
    for (pd, counts) in tm.pd_v.iter().zip([50.0, 10.0, 4.0, 9.0, 7.0]) {
        let got = pd.get(0).unwrap();
        assert!(
            (got - counts * 0.01).abs() < 1e-15,
            "{got} vs {counts} counts"
        );
    }
    let mdeg_s = 8.75e-3_f64.to_radians();
    let g = tm.gyro_rad_s.get(0).unwrap();
    for (got, counts) in [(g.x, -96.0), (g.y, -153.0), (g.z, 64.0)] {
        assert!(
            (got - counts * mdeg_s).abs() < 1e-15,
            "{got} vs {counts} counts"
        );
    }
    // The second frame, 42 s later; the last, 2017-06-28T21:00:57Z (Unix 1498683657):
    // Z+ 51 counts, gyro z 138 counts. Unix time has no leap second between them.
    assert_eq!(tm.t_s[1], 42.0);
    assert_eq!(tm.t_s[314], f64::from(1_498_683_657 - 1_498_201_375));
    assert!((tm.pd_v[4].get(314).unwrap() - 0.51).abs() < 1e-15);
    assert!((tm.gyro_rad_s.get(314).unwrap().z - 138.0 * mdeg_s).abs() < 1e-15);

    // Every output within 8 bits' 0 ..= 2.55 V as written, where calibrate's check of
    // outputs against a photodiode's full scale lets them through.
    for pd in &tm.pd_v {
        assert!(pd.iter().flatten().all(|v| (0.0..=2.55).contains(&v)));
    }
    // The noise hints are those of 8-bit counts and the guessed gyro.
    let noise = ds.meta.noise.unwrap();
    assert_eq!(noise.photodiode_v, Some(0.01));
    assert_eq!(noise.mag_nt, None);
}
