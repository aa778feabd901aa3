//! write -> read gives the same dataset bit for bit; output is deterministic; the output
//! directory is replaced only when that is safe.

use crate::common;

use std::fs;

use common::{bits, full_dataset, minimal_dataset};
use pdcal_dataset::{ErrorKind, read_dataset, render_dataset, write_dataset};

#[test]
fn full_dataset_round_trips_bit_for_bit() {
    let ds = full_dataset(60);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("set");
    write_dataset(&out, &ds).unwrap();
    let back = read_dataset(&out).unwrap();
    assert_eq!(back, ds);
    // Bit-level: -0.0, subnormals and extremes survive, empty cells stay empty.
    assert_eq!(bits(&back), bits(&ds));
    assert_eq!(back.telemetry.pd_v[0].get(0), None);
    assert_eq!(back.telemetry.gyro_rad_s.get(4), None);
    assert!(
        back.telemetry
            .gyro_rad_s
            .get(1)
            .unwrap()
            .x
            .is_sign_negative()
    );
}

#[test]
fn minimal_dataset_round_trips_bit_for_bit() {
    let ds = minimal_dataset(40);
    let dir = tempfile::tempdir().unwrap();
    write_dataset(dir.path(), &ds).unwrap();
    let back = read_dataset(dir.path()).unwrap();
    assert_eq!(back, ds);
    assert_eq!(bits(&back), bits(&ds));
    assert!(back.telemetry.mag_nt.is_none());
    assert!(back.truth.is_none());
    assert_eq!(
        back.meta.epoch_utc.as_str(),
        "2024-02-29 23:59:59.123456789 UTC"
    );
    for name in ["truth.csv", "truth.ron"] {
        assert!(!dir.path().join(name).exists());
    }
}

#[test]
fn output_is_deterministic() {
    let ds = full_dataset(30);
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    write_dataset(&a, &ds).unwrap();
    write_dataset(&b, &ds).unwrap();
    for name in ["dataset.ron", "telemetry.csv", "truth.csv", "truth.ron"] {
        assert_eq!(
            fs::read(a.join(name)).unwrap(),
            fs::read(b.join(name)).unwrap(),
            "{name}"
        );
    }
    assert_eq!(render_dataset(&ds).unwrap(), render_dataset(&ds).unwrap());
}

#[test]
fn dataset_ron_looks_like_the_contract() {
    let ds = full_dataset(3);
    let files = render_dataset(&ds).unwrap();
    let meta = &files[0].1;
    let truth = &files[3].1;
    // Shape of the contract's example: bare optional struct, one photodiode per line,
    // floats always with a decimal point.
    assert!(meta.starts_with("(\n    format_version: 1,\n"), "{meta}");
    assert!(
        meta.contains("    orbit: Tle(\n        line1: \"1 37853U"),
        "{meta}"
    );
    assert!(
        meta.contains("        (azimuth_deg: 17.0, elevation_deg: -10.0),\n"),
        "{meta}"
    );
    assert!(
        meta.contains("    noise: (\n        gyro_rad_s: 0.0008,\n"),
        "{meta}"
    );
    assert!(
        truth.contains("        Albedo(map: \"toms-mean-1p25x1\"),\n"),
        "{truth}"
    );
    assert!(
        truth.contains("        MagBias(nT: [150.0, -80.0, 0.30000000000000004]),\n"),
        "{truth}"
    );
    let telemetry = &files[1].1;
    assert!(telemetry.starts_with(
        "t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,mag_x_nT,mag_y_nT,mag_z_nT,pd01_V,pd02_V,"
    ));
}

#[test]
fn replaces_a_dataset_dir_but_nothing_else() {
    let ds = minimal_dataset(5);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("set");

    // Empty directory: replaced.
    fs::create_dir(&out).unwrap();
    write_dataset(&out, &ds).unwrap();
    // A dataset directory the same writer wrote: replaced.
    write_dataset(&out, &ds).unwrap();
    assert_eq!(read_dataset(&out).unwrap(), ds);
    // A file of it edited since: the user's, refused (and kept) unless forced.
    fs::write(out.join("telemetry.csv"), "edited").unwrap();
    let err = write_dataset(&out, &ds).unwrap_err();
    assert!(
        err.to_string().contains("was changed after pdcal wrote it"),
        "{err}"
    );
    assert_eq!(
        fs::read_to_string(out.join("telemetry.csv")).unwrap(),
        "edited"
    );
    pdcal_dataset::begin_dataset_as(&out, pdcal_dataset::LIBRARY_WRITE_COMMAND, true)
        .unwrap()
        .write(&ds)
        .unwrap();
    assert_eq!(read_dataset(&out).unwrap(), ds);

    // A directory with a foreign file: refused and untouched.
    fs::write(out.join("notes.txt"), "mine").unwrap();
    let err = write_dataset(&out, &ds).unwrap_err();
    assert!(
        matches!(err.kind(), ErrorKind::NotADatasetDir { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("notes.txt"), "{err}");
    assert_eq!(fs::read_to_string(out.join("notes.txt")).unwrap(), "mine");

    // A plain file: refused.
    let file = dir.path().join("file");
    fs::write(&file, "x").unwrap();
    let err = write_dataset(&file, &ds).unwrap_err();
    assert!(
        matches!(err.kind(), ErrorKind::NotADatasetDir { .. }),
        "{err}"
    );

    // No staging directories or locks left behind.
    let leftovers: Vec<_> = fs::read_dir(dir.path())
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".pdcal-"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn refuses_to_write_what_it_could_not_read() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("set");

    let mut ds = minimal_dataset(5);
    ds.telemetry.pd_v[1].set(2, Some(f64::NAN));
    let err = write_dataset(&out, &ds).unwrap_err();
    // Row index 2 is line 4 (header on line 1); pd02_V is column 6 (t_s, gyro x3, pd01).
    assert_eq!(
        err.to_string(),
        "telemetry.csv:4:6 (pd02_V): \"NaN\" is not a finite number"
    );

    let mut ds = minimal_dataset(5);
    ds.telemetry.pd_v[2].pop();
    let err = write_dataset(&out, &ds).unwrap_err();
    assert!(
        matches!(
            err.kind(),
            ErrorKind::WrongLength {
                expected: 5,
                found: 4
            }
        ),
        "{err}"
    );

    let mut ds = minimal_dataset(5);
    ds.telemetry.t_s[3] = ds.telemetry.t_s[2];
    let err = write_dataset(&out, &ds).unwrap_err();
    assert!(
        matches!(err.kind(), ErrorKind::TimeNotIncreasing { .. }),
        "{err}"
    );
    assert!(!out.exists());
}
