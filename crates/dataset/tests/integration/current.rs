//! Current columns `cur_<name>_A`: their round trip, and the ways the reader refuses them.

use crate::common;

use common::{TLE1, TLE2};
use pdcal_dataset::{DatasetError, meta_from_str, render_dataset, telemetry_from_str};

fn dataset_ron() -> String {
    format!(
        r#"(
    format_version: 1,
    name: "currents",
    epoch_utc: "2011-11-04T18:29:45Z",
    orbit: Tle(
        line1: "{TLE1}",
        line2: "{TLE2}",
    ),
    photodiodes: [
        (azimuth_deg: 17.0, elevation_deg: -10.0),
    ],
)
"#
    )
}

const TELEMETRY: &str = "\
t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,mag_x_nT,mag_y_nT,mag_z_nT,pd01_V,cur_px_A,cur_battery_A
0,0.01,0.02,0.03,100,200,300,1.5,0.25,
1,0.01,0.02,0.03,100,200,300,1.6,0.125,-0.5
";

fn parse(telemetry: &str) -> Result<pdcal_dataset::Telemetry, DatasetError> {
    telemetry_from_str(telemetry, &meta_from_str(&dataset_ron())?)
}

#[test]
fn current_columns_round_trip() {
    let tm = parse(TELEMETRY).expect("valid");
    let names: Vec<&str> = tm.current_a.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["cur_px_A", "cur_battery_A"]);
    assert_eq!(tm.current_a[0].values, [Some(0.25), Some(0.125)]);
    assert_eq!(tm.current_a[1].values, [None, Some(-0.5)]);
    let meta = meta_from_str(&dataset_ron()).expect("valid");
    let dataset = pdcal_dataset::Dataset {
        meta: meta.clone(),
        telemetry: tm.clone(),
        truth: None,
    };
    let files = render_dataset(&dataset).expect("renders");
    let text = &files
        .iter()
        .find(|(name, _)| *name == pdcal_dataset::TELEMETRY_CSV)
        .expect("telemetry.csv")
        .1;
    assert_eq!(telemetry_from_str(text, &meta).expect("reads back"), tm);
    // A selection of rows keeps the columns.
    let second = tm.select_rows(|k| k == 1);
    assert_eq!(second.current_a[1].values, [Some(-0.5)]);
}

#[test]
fn bad_current_columns_are_refused_at_their_cell() {
    let e = parse(&TELEMETRY.replace("cur_px_A", "cur_px_mA"))
        .expect_err("refused")
        .to_string();
    assert!(e.contains("telemetry.csv:1:9"), "{e}");
    assert!(e.contains("cur_<name>_A"), "{e}");
    let e = parse(&TELEMETRY.replace(",0.125,", ",125,"))
        .expect_err("refused")
        .to_string();
    assert!(e.contains("telemetry.csv:3:9"), "{e}");
    assert!(e.contains("a current must lie within -100 .. 100 A"), "{e}");
}

/// A channel name longer than [`pdcal_dataset::MAX_CURRENT_NAME_CHARS`] is refused at its
/// header cell when the set is read, not after a fit whose figure it cannot name; the
/// message quotes it cut to 80 characters.
#[test]
fn a_current_name_too_long_for_a_file_is_refused_when_read() {
    let longest = "a".repeat(pdcal_dataset::MAX_CURRENT_NAME_CHARS);
    let ok = TELEMETRY.replace("cur_px_A", &format!("cur_{longest}_A"));
    parse(&ok).expect("the longest name is valid");
    let long = "a".repeat(2000);
    let e = parse(&TELEMETRY.replace("cur_px_A", &format!("cur_{long}_A")))
        .expect_err("refused")
        .to_string();
    assert_eq!(
        e,
        format!(
            "telemetry.csv:1:9 (cur_{a76}... (2006 bytes)): unknown column \"cur_{a76}\"... (2006 \
             bytes); current columns are cur_<name>_A (<name>: 1 to 64 of a-z, 0-9, _; amperes)",
            a76 = "a".repeat(76)
        )
    );
}

/// A time of 300 digits is echoed cut, as every value.
#[test]
fn a_huge_time_is_echoed_cut() {
    let rows = TELEMETRY.replace("\n0,", "\n1e300,");
    let e = parse(&rows).expect_err("refused").to_string();
    assert!(
        e.starts_with("telemetry.csv:3:1 (t_s): t_s 1 is not greater than the previous row's 1000"),
        "{e}"
    );
    assert!(e.ends_with("... (301 bytes)"), "{e}");
    assert!(e.len() < 250, "{} bytes: {e}", e.len());
}
