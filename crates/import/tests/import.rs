//! The import on small hand-written exports: conversions against hand values, sentinels and
//! dropped rows, and every error naming its file, line and column.

use std::path::Path;

use pdcal_ephem::{frames, time};
use pdcal_import::{ErrorKind, FileFaultKind, ImportError, Imported, convert, parse_map};

const L1: &str = "1 37853U 11061D   11308.77065972  .00000000  00000-0  20000-4 0  9997";
const L2: &str = "2 37853 101.7000  50.0000 0300509 130.0000 230.0000 14.86144463  1000";

/// A map whose lines are known: line 4 names the time column, 7-9 the gyro, 12-14 the
/// magnetometer, 17-18 the photodiodes, 21-22 the TLE.
fn map_text() -> String {
    format!(
        r#"(
    format_version: 1,
    name: "hand",
    time: (column: "unix", form: Unix, sentinels: [-1]),
    sentinels: [65535],
    gyro: (
        x: (column: "wx", unit: "deg/s"),
        y: (column: "wy", unit: "deg/s"),
        z: (column: "wz", unit: "rad/s"),
    ),
    mag: (
        x: (column: "bx", unit: "mG"),
        y: (column: "by", unit: "G"),
        z: (column: "bz", unit: "uT"),
    ),
    photodiodes: [
        (column: "adc1", counts: (gain: 0.001, offset: -0.25, unit: "V"), azimuth_deg: 17.0, elevation_deg: -10.0),
        (column: "adc0", unit: "mV", sentinels: [-5], azimuth_deg: 0.0, elevation_deg: 20.0),
    ],
    orbit: Tle(
        line1: "{L1}",
        line2: "{L2}",
    ),
)
"#
    )
}

const CSV: &str = "\
adc0,wz,unix,wx,wy,bx,by,bz,adc1,status
1500,0.01,1320431385,1.8,0,300,0.2,25,1250,ok
-5,0.01,1320431386,1.8,,300,0.2,25,65535,ok
1500,0.01,-1,1.8,0,300,0.2,25,1250,ok
1500,0.01,,1.8,0,300,0.2,25,1250,ok
1600,0.02,1320431387.5,-90,45,65535,0.2,25,250,ok
";

fn import(map: &str, csv: &str) -> Result<Imported, ImportError> {
    let map = parse_map(Path::new("map.ron"), map.as_bytes())?;
    convert(&map, Path::new("export.csv"), csv.as_bytes())
}

fn error(map: &str, csv: &str) -> ImportError {
    match import(map, csv) {
        Ok(_) => panic!("accepted"),
        Err(e) => e,
    }
}

#[test]
fn converts_units_counts_and_times_to_hand_values() {
    let imported = import(&map_text(), CSV).unwrap();
    let ds = &imported.dataset;
    let tm = &ds.telemetry;
    assert_eq!(tm.len(), 3, "two rows without a time are dropped");
    assert_eq!(ds.meta.epoch_utc.as_str(), "2011-11-04T18:29:45Z");
    assert_eq!(tm.t_s, [0.0, 1.0, 2.5]);
    let deg = std::f64::consts::PI / 180.0;
    let g = tm.gyro_rad_s.get(0).unwrap();
    assert!((g.x - 1.8 * deg).abs() < 1e-15 && g.y == 0.0 && g.z == 0.01);
    let g = tm.gyro_rad_s.get(2).unwrap();
    assert!((g.x + std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    assert!((g.y - std::f64::consts::FRAC_PI_4).abs() < 1e-15);
    // 300 mG = 30000 nT, 0.2 G = 20000 nT, 25 uT = 25000 nT.
    let b = tm.mag_nt.as_ref().unwrap().get(0).unwrap();
    assert_eq!([b.x, b.y, b.z], [30_000.0, 20_000.0, 25_000.0]);
    // pd01 is column adc1 in counts: 0.001 * 1250 - 0.25 = 1.0 V; pd02 is adc0 in mV.
    assert!((tm.pd_v[0].get(0).unwrap() - 1.0).abs() < 1e-15);
    assert_eq!(tm.pd_v[1].get(0), Some(1.5));
    assert!((tm.pd_v[0].get(2).unwrap() - 0.0).abs() < 1e-15);
    // Row 2: the global sentinel 65535 on adc1, the column's -5 on adc0, an empty gyro y.
    assert_eq!(tm.pd_v[0].get(1), None);
    assert_eq!(tm.pd_v[1].get(1), None);
    assert_eq!(tm.gyro_rad_s.get(1), None, "a partial vector is empty");
    assert_eq!(tm.mag_nt.as_ref().unwrap().get(2), None);
    let r = &imported.report;
    assert_eq!(
        (
            r.rows_read,
            r.rows_kept,
            r.dropped_sentinel_time,
            r.dropped_blank_time
        ),
        (5, 3, 1, 1)
    );
    // The empty gyro y of row 2; the sentinel magnetometer x of the last row.
    assert_eq!(
        r.partial_vectors,
        [("gyro".to_owned(), 1), ("mag".to_owned(), 1)]
    );
    let hits: Vec<(&str, usize)> = (r.sentinel_cells.iter())
        .map(|(path, _, n)| (path.as_str(), *n))
        .collect();
    assert_eq!(
        hits,
        [("mag.x", 1), ("photodiodes[0]", 1), ("photodiodes[1]", 1)]
    );
    assert_eq!(ds.meta.photodiodes[1].elevation_deg, 20.0);
    assert!(matches!(
        ds.meta.orbit,
        pdcal_dataset::OrbitSpec::Tle { .. }
    ));
}

#[test]
fn teme_positions_in_metres_become_gcrf_km() {
    let map = map_text().replace(
        &format!("orbit: Tle(\n        line1: \"{L1}\",\n        line2: \"{L2}\",\n    ),"),
        "orbit: Positions(\n        x: (column: \"px\", unit: \"m\"),\n        y: (column: \"py\", unit: \"m\"),\n        z: (column: \"pz\", unit: \"m\"),\n        frame: Teme,\n    ),",
    );
    let csv = "unix,wx,wy,wz,bx,by,bz,adc1,adc0,px,py,pz\n\
               1320431385,0,0,0,300,0.2,25,1250,1500,6878000,0,1000\n\
               1320431445,0,0,0,300,0.2,25,1250,1500,,0,1000\n";
    let imported = import(&map, csv).unwrap();
    let tm = &imported.dataset.telemetry;
    let r = tm.r_gcrf_km.as_ref().unwrap();
    let t0 = time::parse_utc("2011-11-04T18:29:45Z").unwrap();
    let want = frames::teme_to_gcrf(t0) * nalgebra::Vector3::new(6878.0, 0.0, 1.0);
    assert!((r.get(0).unwrap() - want).norm() < 1e-9, "{:?}", r.get(0));
    // TEME and GCRF differ by precession since 2000: about 0.15 deg in 2011.
    assert!((r.get(0).unwrap() - nalgebra::Vector3::new(6878.0, 0.0, 1.0)).norm() > 5.0);
    assert_eq!(r.get(1), None);
    assert!(matches!(
        imported.dataset.meta.orbit,
        pdcal_dataset::OrbitSpec::PositionColumns
    ));
    // GCRF columns are written unchanged.
    let gcrf = map.replace("frame: Teme", "frame: Gcrf");
    let imported = import(&gcrf, csv).unwrap();
    let r = imported.dataset.telemetry.r_gcrf_km.unwrap();
    assert_eq!(r.get(0), Some(nalgebra::Vector3::new(6878.0, 0.0, 1.0)));
}

#[test]
fn the_time_forms_give_the_same_dataset() {
    let unix = import(&map_text(), CSV).unwrap();
    let iso_csv = CSV
        .replace("1320431385,", "2011-11-04T18:29:45Z,")
        .replace("1320431386,", "2011-11-04T18:29:46Z,")
        .replace("1320431387.5,", "2011-11-04T18:29:47.5Z,");
    let iso = import(
        &map_text().replace("form: Unix, sentinels: [-1]", "form: Iso"),
        &iso_csv.replace(",-1,", ",,"),
    )
    .unwrap();
    assert_eq!(iso.dataset.telemetry, unix.dataset.telemetry);
    let gps_csv = CSV
        .replace("1320431385,", "1004466600,")
        .replace("1320431386,", "1004466601,")
        .replace("1320431387.5,", "1004466602.5,");
    let gps = import(&map_text().replace("form: Unix", "form: Gps"), &gps_csv).unwrap();
    assert_eq!(gps.dataset.telemetry, unix.dataset.telemetry);
    assert_eq!(gps.dataset.meta.epoch_utc, unix.dataset.meta.epoch_utc);
}

#[test]
fn an_unknown_column_names_the_map_line_and_the_header() {
    let e = error(&map_text().replace("\"adc0\"", "\"adc_0\""), CSV);
    assert_eq!(e.file(), Path::new("map.ron"));
    assert_eq!(e.line(), Some(18), "{e}");
    assert_eq!(e.field(), Some("photodiodes[1].column"));
    let text = e.to_string();
    assert!(
        text.starts_with("map.ron:18:18 (photodiodes[1].column): column \"adc_0\" is not in export.csv's header (line 1)"),
        "{text}"
    );
    assert!(text.contains("\"adc0\""), "lists the header: {text}");
}

#[test]
fn a_bad_cell_names_the_export_line_and_column() {
    let csv = CSV.replace("300,0.2,25,1250,ok\n-5", "300,0.2,25,12x50,ok\n-5");
    let e = error(&map_text(), &csv);
    assert_eq!(e.file(), Path::new("export.csv"));
    assert_eq!((e.line(), e.column()), (Some(2), Some(9)), "{e}");
    assert_eq!(
        e.to_string(),
        "export.csv:2:9 (adc1): \"12x50\" is not a number (photodiodes[0] of map.ron:17)"
    );
    // A huge cell is quoted cut.
    let huge = "9".repeat(5000) + "x";
    let e = error(&map_text(), &CSV.replace("12", &huge));
    let text = e.to_string();
    assert!(text.len() < 300, "{text}");
    assert!(text.contains("... (5003 bytes) is not a number"), "{text}");
    let e = error(
        &map_text(),
        &CSV.replace("0.01,1320431386", "NaN,1320431386"),
    );
    assert!(matches!(e.kind(), ErrorKind::NotFinite { .. }), "{e}");
    assert_eq!((e.line(), e.column()), (Some(3), Some(2)));
}

#[test]
fn an_unknown_unit_names_the_map_line() {
    let e = error(&map_text().replace("\"uT\"", "\"microtesla\""), CSV);
    assert_eq!(e.line(), Some(14), "{e}");
    assert_eq!(e.field(), Some("mag.z.unit"));
    assert!(
        e.to_string().contains(
            "unit \"microtesla\" is not a unit of magnetic field: use one of nT, uT, mG, G"
        ),
        "{e}"
    );
    // A unit of another quantity is unknown too.
    let e = error(
        &map_text().replace("unit: \"deg/s\"),\n        y", "unit: \"nT\"),\n        y"),
        CSV,
    );
    assert_eq!((e.line(), e.field()), (Some(7), Some("gyro.x.unit")), "{e}");
    let e = error(&map_text().replace("unit: \"V\"", "unit: \"volt\""), CSV);
    assert_eq!(
        (e.line(), e.field()),
        (Some(17), Some("photodiodes[0].counts.unit")),
        "{e}"
    );
    let e = error(&map_text().replace("gain: 0.001", "gain: 0.0"), CSV);
    assert_eq!(
        (e.line(), e.field()),
        (Some(17), Some("photodiodes[0].counts.gain")),
        "{e}"
    );
    let e = error(
        &map_text().replace("(column: \"wz\", unit: \"rad/s\")", "(column: \"wz\")"),
        CSV,
    );
    assert!(matches!(e.kind(), ErrorKind::UnitOrCounts), "{e}");
    assert_eq!(e.line(), Some(9));
}

#[test]
fn a_bad_tle_names_the_map_line() {
    // One digit changed: the checksum fails.
    let bad = L2.replace("101.7000", "101.8000");
    let e = error(&map_text().replace(L2, &bad), CSV);
    assert_eq!(e.file(), Path::new("map.ron"));
    assert_eq!(e.line(), Some(22), "{e}");
    assert!(e.to_string().contains("TLE line 2 checksum fails"), "{e}");
    // An inclination out of range, checksum fixed: the dataset format's rule.
    let line = L2.replace("101.7000", "201.7000");
    let sum = pdcal_ephem::tle::checksum(&line);
    let line = format!("{}{sum}", &line[..68]);
    let e = error(&map_text().replace(L2, &line), CSV);
    assert_eq!(e.line(), Some(22), "{e}");
    assert!(e.to_string().contains("inclination"), "{e}");
    // A mounting angle out of range is placed at its photodiode.
    let e = error(
        &map_text().replace("elevation_deg: 20.0", "elevation_deg: 200.0"),
        CSV,
    );
    assert_eq!(
        (e.line(), e.field()),
        (Some(18), Some("photodiodes[1].elevation_deg")),
        "{e}"
    );
}

#[test]
fn a_time_in_another_form_is_refused_at_its_cell() {
    // ISO text where the map says Unix seconds.
    let csv = CSV.replace("1320431386,", "2011-11-04T18:29:46Z,");
    let e = error(&map_text(), &csv);
    assert_eq!((e.line(), e.column()), (Some(3), Some(3)), "{e}");
    assert!(
        e.to_string().ends_with(
            "\"2011-11-04T18:29:46Z\" is not a number (time, Unix seconds of map.ron:4)"
        ),
        "{e}"
    );
    // Milliseconds where the map says seconds.
    let csv = CSV.replace("1320431386,", "1320431386000,");
    let e = error(&map_text(), &csv);
    assert!(matches!(e.kind(), ErrorKind::BadTime { .. }), "{e}");
    assert!(e.to_string().contains("milliseconds"), "{e}");
    // Numbers where the map says ISO text.
    let e = error(&map_text().replace("form: Unix", "form: Iso"), CSV);
    assert_eq!((e.line(), e.column()), (Some(2), Some(3)), "{e}");
    assert!(e.to_string().contains("is not an ISO 8601 UTC time"), "{e}");
    // A bad epoch of the Seconds form is placed in the map.
    let e = error(
        &map_text().replace("form: Unix", "form: Seconds(epoch_utc: \"2011-11-04\")"),
        CSV,
    );
    assert_eq!((e.file(), e.line()), (Path::new("map.ron"), Some(4)), "{e}");
}

#[test]
fn rows_out_of_order_are_refused_naming_both_lines() {
    let csv = CSV.replace("1320431387.5", "1320431385.5");
    let e = error(&map_text(), &csv);
    assert_eq!((e.line(), e.column()), (Some(6), Some(3)), "{e}");
    assert!(e.to_string().contains("(line 3)"), "{e}");
}

#[test]
fn map_syntax_and_shape_errors_are_placed() {
    let e = error(
        &map_text().replace("name: \"hand\",", "name: \"hand\",\n    colour: 3,"),
        CSV,
    );
    assert_eq!(e.line(), Some(4), "{e}");
    assert!(
        matches!(
            e.kind(),
            ErrorKind::Ron(pdcal_dataset::RonFaultKind::UnknownField { .. })
        ),
        "{e}"
    );
    let e = error(
        &map_text().replace("format_version: 1", "format_version: 2"),
        CSV,
    );
    assert_eq!(e.line(), Some(2), "{e}");
    let e = error("(format_version: 1", CSV);
    assert!(e.line().is_some(), "{e}");
    let e = error(&map_text(), "");
    assert!(
        matches!(e.kind(), ErrorKind::File(FileFaultKind::Empty)),
        "{e}"
    );
    let e = error(&map_text(), &CSV.replace(",ok\n1600", ",ok,extra\n1600"));
    assert_eq!((e.line(), e.column()), (Some(5), None), "{e}");
    let e = error(&map_text(), "adc0,wz,unix,wx,wy,bx,by,bz,adc1,adc1\n");
    assert_eq!((e.line(), e.column()), (Some(1), Some(10)), "{e}");
    let e = error(
        &map_text(),
        "adc0,wz,unix,wx,wy,bx,by,bz,adc1\n,,-1,,,,,,\n",
    );
    assert!(matches!(e.kind(), ErrorKind::NoRows { dropped: 1 }), "{e}");
}

/// `map_text` with `extra` inserted before the orbit, and `from` replaced by `to`.
fn map_with(extra: &str, from: &str, to: &str) -> String {
    map_text()
        .replace("    orbit: Tle(", &format!("{extra}    orbit: Tle("))
        .replace(from, to)
}

#[test]
fn text_sentinels_blank_cells_and_drop_rows() {
    let map = map_with(
        "",
        "sentinels: [65535],",
        r#"sentinels: [65535, "N/A", "NaN"],"#,
    )
    .replace(r#"sentinels: [-1]"#, r#"sentinels: [-1, "--"]"#);
    let csv = "\
adc0,wz,unix,wx,wy,bx,by,bz,adc1,status
1500,0.01,1320431385,1.8,0,300,0.2,25,1250,ok
N/A,0.01,1320431386,1.8,0,NaN,0.2,25, NaN ,ok
1500,0.01,--,1.8,0,300,0.2,25,1250,ok
1600,0.02,1320431387.5,-90,45,300,0.2,25,250,ok
";
    let imported = import(&map, csv).unwrap();
    let tm = &imported.dataset.telemetry;
    assert_eq!(
        tm.t_s,
        [0.0, 1.0, 2.5],
        "the row with time \"--\" is dropped"
    );
    assert_eq!(tm.pd_v[0].get(1), None);
    assert_eq!(tm.pd_v[1].get(1), None);
    assert_eq!(tm.mag_nt.as_ref().unwrap().get(1), None);
    assert_eq!(imported.report.dropped_sentinel_time, 1);
    let hits: Vec<(&str, usize)> = (imported.report.sentinel_cells.iter())
        .map(|(path, _, n)| (path.as_str(), *n))
        .collect();
    assert_eq!(
        hits,
        [("mag.x", 1), ("photodiodes[0]", 1), ("photodiodes[1]", 1)]
    );
    // Without the text sentinel, "NaN" is what it always was: not a finite number.
    let e = error(&map_text(), csv).to_string();
    assert!(e.starts_with("export.csv:3:6 (bx):"), "{e}");
    assert!(e.contains("\"NaN\" is not a finite number"), "{e}");
}

#[test]
fn a_blank_text_sentinel_is_refused_in_the_map() {
    let map = map_with("", "sentinels: [65535],", r#"sentinels: [65535, "  "],"#);
    let e = error(&map, CSV).to_string();
    assert!(e.starts_with("map.ron:5:"), "{e}");
    assert!(e.contains("must not be blank"), "{e}");
}

const TEMPERATURES: &str = r#"    temperatures: [
        (column: "therm", unit: "K", panel: "xplus"),
        (column: "t2", counts: (gain: 0.5, offset: -40.0, unit: "C"), photodiode: 2, sentinels: [255]),
    ],
"#;

#[test]
fn temperature_columns_become_the_dataset_columns_in_celsius() {
    let map = map_with(
        TEMPERATURES,
        "azimuth_deg: 17.0, elevation_deg: -10.0)",
        r#"azimuth_deg: 17.0, elevation_deg: -10.0, panel: "xplus")"#,
    );
    let csv = "\
adc0,wz,unix,wx,wy,bx,by,bz,adc1,therm,t2
1500,0.01,1320431385,1.8,0,300,0.2,25,1250,293.15,120
1500,0.01,1320431386,1.8,0,300,0.2,25,1250,,255
";
    let imported = import(&map, csv).unwrap();
    let columns = &imported.dataset.telemetry.temperature_c;
    let names: Vec<&str> = columns.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["temp_xplus_C", "temp_pd02_C"]);
    // 293.15 K = 20 C; 0.5 * 120 - 40 = 20 C; an empty cell and a sentinel are not sampled.
    assert!((columns[0].values[0].unwrap() - 20.0).abs() < 1e-12);
    assert_eq!(columns[1].values[0], Some(20.0));
    assert_eq!((columns[0].values[1], columns[1].values[1]), (None, None));
    let bad = csv.replace("293.15", "20.0");
    let e = error(&map, &bad).to_string();
    assert!(e.starts_with("export.csv:2:10 (therm):"), "{e}");
    assert!(e.contains("converts to -253.15 C"), "{e}");
}

#[test]
fn a_temperature_column_names_one_photodiode_or_panel() {
    let with_panel = |t: &str| {
        map_with(
            t,
            "azimuth_deg: 17.0, elevation_deg: -10.0)",
            r#"azimuth_deg: 17.0, elevation_deg: -10.0, panel: "xplus")"#,
        )
    };
    let cases = [
        (
            r#"    temperatures: [(column: "t2", unit: "C", photodiode: 3)],
"#,
            "photodiode 3 is not one of the map's photodiodes 1 ..= 2",
        ),
        (
            r#"    temperatures: [(column: "t2", unit: "C", panel: "zminus")],
"#,
            "no photodiode of the map names panel \"zminus\"",
        ),
        (
            r#"    temperatures: [(column: "t2", unit: "C", panel: "xplus", photodiode: 1)],
"#,
            "give exactly one of",
        ),
        (
            r#"    temperatures: [(column: "t2", unit: "C", photodiode: 1), (column: "t3", unit: "C", photodiode: 1)],
"#,
            "a second column for temp_pd01_C",
        ),
        (
            r#"    temperatures: [(column: "t2", unit: "F", photodiode: 1)],
"#,
            "unit \"F\" is not a unit of temperature: use one of C, K",
        ),
    ];
    for (entry, expected) in cases {
        let e = error(&with_panel(entry), CSV).to_string();
        assert!(e.starts_with("map.ron:20:"), "{e}");
        assert!(e.contains(expected), "{e}");
    }
}

#[test]
fn current_columns_become_the_dataset_columns_in_amperes() {
    let currents = r#"    currents: [
        (name: "px", column: "i1", unit: "mA"),
        (name: "battery", column: "i2", unit: "A"),
        (name: "torquer_z", column: "i3", counts: (gain: 0.002, offset: -0.5, unit: "A"), sentinels: [4095]),
    ],
"#;
    let map = map_with(currents, "", "");
    let csv = "\
adc0,wz,unix,wx,wy,bx,by,bz,adc1,i1,i2,i3
1500,0.01,1320431385,1.8,0,300,0.2,25,1250,250,1.5,300
1500,0.01,1320431386,1.8,0,300,0.2,25,1250,,0.25,4095
";
    let imported = import(&map, csv).unwrap();
    let columns = &imported.dataset.telemetry.current_a;
    let names: Vec<&str> = columns.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["cur_px_A", "cur_battery_A", "cur_torquer_z_A"]);
    // 250 mA = 0.25 A; 0.002 * 300 - 0.5 = 0.1 A; an empty cell and a sentinel are empty.
    assert!((columns[0].values[0].unwrap() - 0.25).abs() < 1e-15);
    assert_eq!(columns[1].values[0], Some(1.5));
    assert!((columns[2].values[0].unwrap() - 0.1).abs() < 1e-15);
    assert_eq!((columns[0].values[1], columns[2].values[1]), (None, None));
    // Milliamperes in an ampere column: refused at the cell, with the unit hint.
    let bad = csv.replace(",1.5,", ",1500,");
    let e = error(&map, &bad).to_string();
    assert!(e.starts_with("export.csv:2:11 (i2):"), "{e}");
    assert!(e.contains("mA given as A?"), "{e}");
}

#[test]
fn a_current_column_needs_a_channel_name() {
    for (entry, expected) in [
        (
            r#"    currents: [(name: "Px", column: "i1", unit: "A")],
"#,
            "\"Px\" is not a channel name",
        ),
        (
            r#"    currents: [(name: "px", column: "i1", unit: "A"), (name: "px", column: "i2", unit: "A")],
"#,
            "a second current named \"px\"",
        ),
        (
            r#"    currents: [(name: "px", column: "i1", unit: "uA")],
"#,
            "unit \"uA\" is not a unit of current: use one of A, mA",
        ),
    ] {
        let e = error(&map_with(entry, "", ""), CSV).to_string();
        assert!(e.starts_with("map.ron:20:"), "{e}");
        assert!(e.contains(expected), "{e}");
    }
}
