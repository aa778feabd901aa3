//! The optional per-photodiode field of view (`fov_deg`): read, validated with the place of
//! the bad value, written only when set, so files without it read and write as before.

use crate::common;

use common::{TLE1, TLE2, full_dataset};
use pdcal_dataset::{meta_from_str, read_dataset, render_dataset, write_dataset};

/// dataset.ron with three photodiodes, the second and third with a field of view; line
/// numbers matter.
fn dataset_ron(second: &str, third: &str) -> String {
    format!(
        r#"(
    format_version: 1,
    name: "fov",
    epoch_utc: "2011-11-04T18:29:45Z",
    orbit: Tle(
        line1: "{TLE1}",
        line2: "{TLE2}",
    ),
    photodiodes: [
        (azimuth_deg: 17.0, elevation_deg: -10.0), // fov_deg: absent
        (azimuth_deg: 0.0, elevation_deg: 20.0, fov_deg: {second}),
        (azimuth_deg: -17.0, elevation_deg: -10.0, fov_deg: {third}),
    ],
)
"#
    )
}

#[test]
fn fields_of_view_are_read_in_degrees() {
    let meta = meta_from_str(&dataset_ron("70.0", "90.0")).unwrap();
    let fov: Vec<Option<f64>> = meta.photodiodes.iter().map(|m| m.fov_deg).collect();
    assert_eq!(fov, [None, Some(70.0), Some(90.0)]);
    assert_eq!(
        meta.photodiodes[1].fov_half_angle_rad(),
        Some(70f64.to_radians())
    );
    assert_eq!(meta.photodiodes[0].fov_half_angle_rad(), None);
}

#[test]
fn a_field_of_view_outside_0_to_90_deg_names_its_place() {
    for (second, third, line, column, index, value) in [
        ("0.0", "60.0", 11, 49, 1, "0"),
        ("60.0", "90.5", 12, 52, 2, "90.5"),
        ("-5.0", "60.0", 11, 49, 1, "-5"),
    ] {
        let err = meta_from_str(&dataset_ron(second, third)).unwrap_err();
        let text = err.to_string();
        assert!(
            text.starts_with(&format!(
                "dataset.ron:{line}:{column} (photodiodes[{index}].fov_deg): "
            )),
            "{text}"
        );
        assert!(text.contains(value) && text.contains("(0, 90]"), "{text}");
    }
    let err = meta_from_str(&dataset_ron("NaN", "60.0")).unwrap_err();
    assert!(err.to_string().contains("photodiodes[1].fov_deg"), "{err}");
}

#[test]
fn fields_of_view_round_trip_and_are_written_only_when_set() {
    let mut ds = full_dataset(5);
    ds.meta.photodiodes[3].fov_deg = Some(65.5);
    let dir = tempfile::tempdir().unwrap();
    write_dataset(dir.path(), &ds).unwrap();
    let back = read_dataset(dir.path()).unwrap();
    assert_eq!(back, ds);
    let files = render_dataset(&ds).unwrap();
    let meta = &files[0].1;
    assert_eq!(meta.matches("fov_deg").count(), 1, "{meta}");
    assert!(
        meta.contains("        (azimuth_deg: -162.0, elevation_deg: -10.0, fov_deg: 65.5),\n"),
        "{meta}"
    );
    ds.meta.photodiodes[3].fov_deg = None;
    assert!(!render_dataset(&ds).unwrap()[0].1.contains("fov_deg"));
}
