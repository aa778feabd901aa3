//! dataset.ron values that parse but are physically impossible: each is refused with the
//! field, and a value no longer than the quoting limit.

use crate::common;

use common::{TLE1, TLE2};
use pdcal_dataset::meta_from_str;

/// dataset.ron with `tle2` as line 2, one photodiode at `mount` and `noise` hints.
fn meta_text(tle2: &str, mount: &str, noise: &str) -> String {
    format!(
        "(\n    format_version: 1,\n    name: \"ranges\",\n    epoch_utc: \"2011-11-04T18:29:45Z\",\n    \
         orbit: Tle(\n        line1: \"{TLE1}\",\n        line2: \"{tle2}\",\n    ),\n    \
         photodiodes: [{mount}],\n    noise: ({noise}),\n)\n"
    )
}

const MOUNT: &str = "(azimuth_deg: 17.0, elevation_deg: -10.0)";
const NOISE: &str = "gyro_rad_s: 0.0008, mag_nT: 320.0, photodiode_V: 0.015";

/// TLE line 2 with columns `from..=to` (1-based) replaced, its checksum recomputed.
fn tle2_with(from: usize, to: usize, text: &str) -> String {
    let mut line = TLE2.to_owned();
    assert_eq!(text.len(), to - from + 1);
    line.replace_range(from - 1..to, text);
    let sum = pdcal_ephem::tle::checksum(&line);
    line.replace_range(68..69, &sum.to_string());
    line
}

fn error(text: &str) -> String {
    meta_from_str(text).unwrap_err().to_string()
}

#[test]
fn the_base_text_is_valid() {
    meta_from_str(&meta_text(TLE2, MOUNT, NOISE)).unwrap();
    meta_from_str(&meta_text(&tle2_with(9, 16, "180.0000"), MOUNT, NOISE)).unwrap();
}

#[test]
fn mount_angles_out_of_range_are_refused_naming_the_field() {
    let e = error(&meta_text(
        TLE2,
        "(azimuth_deg: 17.0, elevation_deg: 1000.0)",
        NOISE,
    ));
    assert_eq!(
        e,
        "dataset.ron (photodiodes[0].elevation_deg): 1000.0 is out of range: elevation must be \
         in [-90, 90] deg"
    );
    let e = error(&meta_text(
        TLE2,
        "(azimuth_deg: 1e308, elevation_deg: 0.0)",
        NOISE,
    ));
    assert_eq!(
        e,
        "dataset.ron (photodiodes[0].azimuth_deg): 1e308 is out of range: azimuth must be in \
         [-360, 360] deg"
    );
}

#[test]
fn tle_elements_out_of_range_or_decayed_are_refused_naming_the_columns() {
    let e = error(&meta_text(&tle2_with(9, 16, "400.0000"), MOUNT, NOISE));
    assert_eq!(
        e,
        "dataset.ron:7:16 (orbit.line2 inclination, columns 9-16): 400.0 is out of range: \
         inclination must be in [0, 180] deg"
    );
    let e = error(&meta_text(&tle2_with(53, 63, "25.00000000"), MOUNT, NOISE));
    assert_eq!(
        e,
        "dataset.ron:7:16 (orbit.line2 mean motion, columns 53-63): 25.0 is out of range: \
         mean motion must be in [0.05, 17] rev/day for an Earth orbit"
    );
    // 16.4 rev/day with e = 0.03: perigee far inside the atmosphere.
    let e = error(&meta_text(&tle2_with(53, 63, "16.40000000"), MOUNT, NOISE));
    assert!(
        e.starts_with("dataset.ron:7:16 (orbit.line2 mean motion, columns 53-63): ")
            && e.ends_with("is below 100 km: the orbit has decayed"),
        "{e}"
    );
    let e = error(&meta_text(&tle2_with(27, 33, "03x0509"), MOUNT, NOISE));
    assert_eq!(
        e,
        "dataset.ron:7:16 (orbit.line2 eccentricity, columns 27-33): \"03x0509\" is not a number"
    );
}

#[test]
fn an_absurd_noise_hint_is_refused_naming_the_field() {
    let e = error(&meta_text(
        TLE2,
        MOUNT,
        "gyro_rad_s: 0.0008, mag_nT: 320.0, photodiode_V: 1e308",
    ));
    assert_eq!(
        e,
        "dataset.ron (noise.photodiode_V): 1e308 is out of range: a 1-sigma noise must be \
         positive and at most 1e2 V"
    );
    let e = error(&meta_text(TLE2, MOUNT, "gyro_rad_s: 5.0"));
    assert_eq!(
        e,
        "dataset.ron (noise.gyro_rad_s): 5.0 is out of range: a 1-sigma noise must be positive \
         and at most 1e0 rad/s"
    );
}

#[test]
fn a_huge_cell_is_quoted_short() {
    let text = format!(
        "t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,pd01_V\n0,0.1,0.1,0.1,{}\n",
        "9".repeat(1000) + "x"
    );
    let meta = meta_from_str(&meta_text(TLE2, MOUNT, NOISE)).unwrap();
    let e = pdcal_dataset::telemetry_from_str(&text, &meta)
        .unwrap_err()
        .to_string();
    assert!(e.len() < 200, "{} characters: {e}", e.len());
    assert_eq!(
        e,
        format!(
            "telemetry.csv:2:5 (pd01_V): \"{}\"... (1001 bytes) is not a number",
            "9".repeat(80)
        )
    );
}
