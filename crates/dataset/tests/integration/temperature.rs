//! Temperature columns: per photodiode (`temp_pdNN_C`) and per panel (`temp_<panel>_C` with
//! dataset.ron's `panel`), their round trip, which photodiode reads which column, the held
//! values a model sees, and every way the reader refuses them.

use crate::common;

use common::{TLE1, TLE2, full_dataset};
use pdcal_dataset::{
    DatasetError, TemperatureColumn, meta_from_str, read_dataset, render_dataset,
    telemetry_from_str, write_dataset,
};

/// dataset.ron with three photodiodes, the first two on panel `xplus`; line numbers matter.
fn dataset_ron() -> String {
    format!(
        r#"(
    format_version: 1,
    name: "temperatures",
    epoch_utc: "2011-11-04T18:29:45Z",
    orbit: Tle(
        line1: "{TLE1}",
        line2: "{TLE2}",
    ),
    photodiodes: [
        (azimuth_deg: 17.0, elevation_deg: -10.0, panel: "xplus"),
        (azimuth_deg: 0.0, elevation_deg: 20.0, panel: "xplus"),
        (azimuth_deg: -17.0, elevation_deg: -10.0, panel: "zminus"),
    ],
)
"#
    )
}

/// Columns 11 and 12: pd01's own sensor and the `xplus` panel's; `zminus` has none.
const TELEMETRY: &str = "\
t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,mag_x_nT,mag_y_nT,mag_z_nT,pd01_V,pd02_V,pd03_V,temp_pd01_C,temp_xplus_C
0,0.01,0.02,0.03,100,200,300,1.5,2.5,0,,
1,0.01,0.02,0.03,,,,1.6,2.4,0,21.5,
2,0.01,0.02,0.03,100,200,300,1.7,2.3,0.1,,-3.25
3,0.01,0.02,0.03,,,,1.8,2.2,0.2,22.0,
4,0.01,0.02,0.03,,,,1.8,2.2,0.2,,-4
";

fn parse(meta_text: &str, telemetry: &str) -> Result<pdcal_dataset::Telemetry, DatasetError> {
    let meta = meta_from_str(meta_text)?;
    telemetry_from_str(telemetry, &meta)
}

fn fail(telemetry: &str) -> String {
    parse(&dataset_ron(), telemetry)
        .expect_err("bad input was accepted")
        .to_string()
}

/// TELEMETRY with header cell 11 (1-based) renamed.
fn with_column_11(name: &str) -> String {
    TELEMETRY.replacen("temp_pd01_C", name, 1)
}

#[test]
fn columns_are_read_in_file_order_with_blanks_as_none() {
    let tm = parse(&dataset_ron(), TELEMETRY).unwrap();
    assert_eq!(
        tm.temperature_c,
        vec![
            TemperatureColumn {
                name: "temp_pd01_C".into(),
                values: vec![None, Some(21.5), None, Some(22.0), None],
            },
            TemperatureColumn {
                name: "temp_xplus_C".into(),
                values: vec![None, None, Some(-3.25), None, Some(-4.0)],
            },
        ]
    );
}

#[test]
fn own_column_first_then_the_panel_then_none() {
    let meta = meta_from_str(&dataset_ron()).unwrap();
    let tm = telemetry_from_str(TELEMETRY, &meta).unwrap();
    // pd01 has both and reads its own; pd02 reads its panel; zminus has no column.
    assert_eq!(
        tm.photodiode_temperatures(&meta),
        vec![Some(0), Some(1), None]
    );
    // Column order does not matter.
    let swapped: String = TELEMETRY
        .lines()
        .map(|l| {
            let mut cells: Vec<&str> = l.split(',').collect();
            cells.swap(10, 11);
            cells.join(",") + "\n"
        })
        .collect();
    let tm = telemetry_from_str(&swapped, &meta).unwrap();
    assert_eq!(
        tm.photodiode_temperatures(&meta),
        vec![Some(1), Some(0), None]
    );
}

#[test]
fn held_values_carry_the_last_sample_and_start_unknown() {
    let meta = meta_from_str(&dataset_ron()).unwrap();
    let tm = telemetry_from_str(TELEMETRY, &meta).unwrap();
    let mut held = tm.held_temperatures(&meta);
    let rows: Vec<Vec<f64>> = (0..tm.len()).map(|k| held.at(k).to_vec()).collect();
    let same = |a: &[f64], b: &[f64]| {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
    };
    let nan = f64::NAN;
    let expected = [
        [nan, nan, nan],
        [21.5, nan, nan],
        [21.5, -3.25, nan],
        [22.0, -3.25, nan],
        [22.0, -4.0, nan],
    ];
    for (k, (row, want)) in rows.iter().zip(expected).enumerate() {
        assert!(same(row, &want), "row {k}: {row:?} != {want:?}");
    }
    // Skipping rows and going back give the same values as the sequential pass.
    let mut held = tm.held_temperatures(&meta);
    for k in [3, 2, 2, 0, 4] {
        assert!(same(held.at(k), &rows[k]), "row {k}");
    }
    assert!(same(held.at(99), &rows[4]));
}

#[test]
fn no_temperature_columns_give_an_empty_slice() {
    let text: String = TELEMETRY
        .lines()
        .map(|l| l.split(',').take(10).collect::<Vec<_>>().join(",") + "\n")
        .collect();
    let meta = meta_from_str(&dataset_ron()).unwrap();
    let tm = telemetry_from_str(&text, &meta).unwrap();
    assert!(tm.temperature_c.is_empty());
    assert_eq!(tm.photodiode_temperatures(&meta), vec![None, None, None]);
    let mut held = tm.held_temperatures(&meta);
    assert!(held.at(0).is_empty());
    assert!(held.at(3).is_empty());
}

#[test]
fn round_trip_is_bit_for_bit_and_panels_are_written_only_when_present() {
    let mut ds = full_dataset(20);
    ds.meta.photodiodes[0].panel = Some("xplus".into());
    ds.meta.photodiodes[1].panel = Some("y_2".into());
    let awkward = [-0.0, 5e-324, 0.1 + 0.2, -150.0, 150.0, -1.0 / 3.0];
    let rows = ds.telemetry.len();
    ds.telemetry.temperature_c = vec![
        TemperatureColumn {
            name: "temp_xplus_C".into(),
            values: (0..rows)
                .map(|k| (k % 3 != 2).then(|| awkward[k % awkward.len()]))
                .collect(),
        },
        TemperatureColumn {
            name: "temp_pd02_C".into(),
            values: (0..rows).map(|k| Some(20.0 + 0.123 * k as f64)).collect(),
        },
    ];
    let dir = tempfile::tempdir().unwrap();
    write_dataset(dir.path(), &ds).unwrap();
    let back = read_dataset(dir.path()).unwrap();
    assert_eq!(back, ds);
    let bits = |d: &pdcal_dataset::Dataset| -> Vec<Option<u64>> {
        (d.telemetry.temperature_c.iter())
            .flat_map(|c| c.values.iter().map(|v| v.map(f64::to_bits)))
            .collect()
    };
    assert_eq!(bits(&back), bits(&ds));
    assert!(
        back.telemetry.temperature_c[0].values[0]
            .unwrap()
            .is_sign_negative()
    );
    assert_eq!(back.telemetry.temperature_c[0].values[2], None);

    let files = render_dataset(&ds).unwrap();
    let meta = &files[0].1;
    assert!(
        meta.contains("        (azimuth_deg: 17.0, elevation_deg: -10.0, panel: \"xplus\"),\n"),
        "{meta}"
    );
    // An entry without a panel is written as before the field existed.
    assert!(
        meta.contains("        (azimuth_deg: -17.0, elevation_deg: -10.0),\n"),
        "{meta}"
    );
    let header = files[1].1.lines().next().unwrap();
    assert!(
        header.ends_with(",pd17_V,temp_xplus_C,temp_pd02_C"),
        "{header}"
    );
}

#[test]
fn a_panel_without_a_column_is_fine() {
    // zminus (pd03) has no column in TELEMETRY; already read above, checked explicitly here.
    let meta = meta_from_str(&dataset_ron()).unwrap();
    assert_eq!(meta.photodiodes[2].panel.as_deref(), Some("zminus"));
    assert!(telemetry_from_str(TELEMETRY, &meta).is_ok());
}

#[test]
fn per_photodiode_column_of_a_missing_photodiode() {
    assert_eq!(
        fail(&with_column_11("temp_pd04_C")),
        "telemetry.csv:1:11 (temp_pd04_C): unknown column \"temp_pd04_C\"; photodiode \
         temperature columns are temp_pd01_C .. temp_pd03_C"
    );
    // Unpadded spelling and photodiode zero are not photodiode columns either.
    for name in ["temp_pd1_C", "temp_pd00_C"] {
        assert_eq!(
            fail(&with_column_11(name)),
            format!(
                "telemetry.csv:1:11 ({name}): unknown column \"{name}\"; photodiode \
                 temperature columns are temp_pd01_C .. temp_pd03_C"
            )
        );
    }
}

#[test]
fn panel_column_no_photodiode_refers_to() {
    assert_eq!(
        fail(&with_column_11("temp_yplus_C")),
        "telemetry.csv:1:11 (temp_yplus_C): no photodiode in dataset.ron has panel: \
         \"yplus\", so this temperature column would be unused"
    );
}

#[test]
fn malformed_temperature_header() {
    for name in ["temp_Xplus_C", "temp_pd1a_C", "temp_xplus_K", "temp__C"] {
        assert_eq!(
            fail(&with_column_11(name)),
            format!(
                "telemetry.csv:1:11 ({name}): unknown column \"{name}\"; temperature columns \
                 are temp_pdNN_C (one photodiode) or temp_<panel>_C (<panel>: a-z, 0-9, _ as \
                 in dataset.ron)"
            )
        );
    }
}

#[test]
fn repeated_temperature_column() {
    assert_eq!(
        fail(&with_column_11("temp_xplus_C")),
        "telemetry.csv:1:12 (temp_xplus_C): column \"temp_xplus_C\" appears twice"
    );
}

#[test]
fn implausible_or_non_finite_temperature() {
    let bad = |cell: &str| TELEMETRY.replacen(",21.5,", &format!(",{cell},"), 1);
    assert_eq!(
        fail(&bad("293.15")),
        "telemetry.csv:3:11 (temp_pd01_C): 293.15 is out of range: a temperature must lie \
         within -150 .. 150 C"
    );
    assert_eq!(
        fail(&bad("-150.5")),
        "telemetry.csv:3:11 (temp_pd01_C): -150.5 is out of range: a temperature must lie \
         within -150 .. 150 C"
    );
    assert_eq!(
        fail(&bad("NaN")),
        "telemetry.csv:3:11 (temp_pd01_C): \"NaN\" is not a finite number"
    );
    assert_eq!(
        fail(&bad("warm")),
        "telemetry.csv:3:11 (temp_pd01_C): \"warm\" is not a number"
    );
    // The bounds themselves are plausible.
    assert!(parse(&dataset_ron(), &bad("-150")).is_ok());
    assert!(parse(&dataset_ron(), &bad("150")).is_ok());
}

#[test]
fn bad_panel_name_in_dataset_ron() {
    let text = dataset_ron().replacen("panel: \"zminus\"", "panel: \"Z-\"", 1);
    assert_eq!(
        meta_from_str(&text).unwrap_err().to_string(),
        "dataset.ron:12:59 (photodiodes[2].panel): \"Z-\" is not a panel name: use a-z, 0-9 \
         and _, not starting with pd and a digit"
    );
    let text = dataset_ron().replacen("panel: \"zminus\"", "panel: \"pd3\"", 1);
    assert!(
        meta_from_str(&text)
            .unwrap_err()
            .to_string()
            .contains("(photodiodes[2].panel): \"pd3\" is not a panel name")
    );
}
