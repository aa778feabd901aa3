//! One test per class of bad input: each names the file, the line and the column (or field),
//! and the message a user sees.

use crate::common;

use std::fs;

use common::{TLE1, TLE2};
use pdcal_dataset::{DatasetError, ErrorKind, FileFaultKind, RonFaultKind, read_dataset};

/// dataset.ron of the base dataset; line numbers matter to the tests below.
fn dataset_ron() -> String {
    format!(
        r#"(
    format_version: 1,
    name: "bad-input",
    epoch_utc: "2011-11-04T18:29:45Z",
    orbit: Tle(
        line1: "{TLE1}",
        line2: "{TLE2}",
    ),
    photodiodes: [
        (azimuth_deg: 17.0, elevation_deg: -10.0),
        (azimuth_deg: 0.0, elevation_deg: 20.0),
        (azimuth_deg: -17.0, elevation_deg: -10.0),
    ],
    noise: (gyro_rad_s: 0.0008, mag_nT: 320.0, photodiode_V: 0.015),
)
"#
    )
}

const TELEMETRY: &str = "\
t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,mag_x_nT,mag_y_nT,mag_z_nT,pd01_V,pd02_V,pd03_V
0,0.01,0.02,0.03,100,200,300,1.5,2.5,0
1,0.01,0.02,0.03,,,,1.6,2.4,0
2,0.01,0.02,0.03,100,200,300,1.7,2.3,0.1
3,0.01,0.02,0.03,,,,1.8,2.2,0.2
";

const TRUTH_CSV: &str = "\
t_s,q_x,q_y,q_z,q_w,w_x_rad_s,w_y_rad_s,w_z_rad_s,gyro_bias_x_rad_s,gyro_bias_y_rad_s,gyro_bias_z_rad_s,sun_x,sun_y,sun_z,eclipse,r_x_km,r_y_km,r_z_km,mag_x_nT,mag_y_nT,mag_z_nT
0,0,0,0,1,0.1,0.2,0.3,0.001,0.002,0.003,1,0,0,1,7000,0,0,20000,0,0
1,0,0,0,1,0.1,0.2,0.3,0.001,0.002,0.003,1,0,0,1,7000,0,0,20000,0,0
";

const TRUTH_RON: &str = r#"(
    photodiodes: [
        (scale_V: 3.62, azimuth_deg: 18.3, elevation_deg: -7.9),
        (scale_V: 3.70, azimuth_deg: 1.0, elevation_deg: 21.0),
        (scale_V: 3.55, azimuth_deg: -16.0, elevation_deg: -9.0),
    ],
    effects: [Albedo(map: "toms-mean-1p25x1"), DarkOffset(volts: [0.01, 0.02, 0.03])],
)
"#;

/// Writes the base dataset with `name` replaced by `text` (`None` removes the file) and
/// reads it.
fn read_with(name: &str, text: Option<&str>) -> Result<pdcal_dataset::Dataset, DatasetError> {
    let dir = tempfile::tempdir().unwrap();
    let files = [
        ("dataset.ron", dataset_ron()),
        ("telemetry.csv", TELEMETRY.to_owned()),
        ("truth.csv", TRUTH_CSV.to_owned()),
        ("truth.ron", TRUTH_RON.to_owned()),
    ];
    for (file, base) in files {
        let contents = if file == name {
            text.map(str::to_owned)
        } else {
            Some(base)
        };
        if let Some(contents) = contents {
            fs::write(dir.path().join(file), contents).unwrap();
        }
    }
    read_dataset(dir.path()).map_err(|e| {
        // Every error names a file inside the dataset directory.
        assert_eq!(e.file().parent(), Some(dir.path()), "{e}");
        e
    })
}

fn fail(name: &str, text: &str) -> DatasetError {
    read_with(name, Some(text)).expect_err("bad input was accepted")
}

/// The message without the temporary directory in front of the file name.
fn shown(e: &DatasetError) -> String {
    let full = e.to_string();
    let dir = e.file().parent().unwrap().display().to_string();
    full.strip_prefix(&format!("{dir}/"))
        .unwrap_or(&full)
        .to_owned()
}

fn replace_line(text: &str, line: usize, new: &str) -> String {
    let mut lines: Vec<&str> = text.lines().collect();
    lines[line - 1] = new;
    lines.join("\n") + "\n"
}

fn place(e: &DatasetError) -> (String, Option<usize>, Option<usize>, Option<&str>) {
    (e.file_name(), e.line(), e.column(), e.field())
}

#[test]
fn the_base_dataset_is_valid() {
    let ds = read_with("", None).unwrap();
    assert_eq!(ds.telemetry.len(), 4);
    assert!(ds.truth.is_some());
}

#[test]
fn unknown_field() {
    let text = replace_line(&dataset_ron(), 3, "    colour: \"red\",");
    let e = fail("dataset.ron", &text);
    assert_eq!(place(&e), ("dataset.ron".into(), Some(3), Some(5), None));
    assert!(
        matches!(e.kind(), ErrorKind::Ron(RonFaultKind::UnknownField { name, .. }) if name == "colour")
    );
    assert!(
        shown(&e).starts_with(
            "dataset.ron:3:5: unknown field `colour`, expected one of format_version, name,"
        ),
        "{}",
        shown(&e)
    );

    // Nested, in a photodiode entry.
    let text = replace_line(
        &dataset_ron(),
        11,
        "        (azimuth_deg: 0.0, elevation_deg: 20.0, roll_deg: 1.0),",
    );
    let e = fail("dataset.ron", &text);
    assert_eq!(place(&e), ("dataset.ron".into(), Some(11), Some(49), None));
    assert_eq!(
        shown(&e),
        "dataset.ron:11:49: unknown field `roll_deg`, expected one of azimuth_deg, elevation_deg, panel, fov_deg"
    );

    // And in truth.ron, inside an effect.
    let text = TRUTH_RON.replace("Albedo(map:", "Albedo(mop:");
    let e = fail("truth.ron", &text);
    assert_eq!(place(&e), ("truth.ron".into(), Some(7), Some(22), None));
    assert_eq!(
        shown(&e),
        "truth.ron:7:22: unknown field `mop`, expected one of map"
    );
}

#[test]
fn missing_field() {
    let text = replace_line(&dataset_ron(), 4, "");
    let e = fail("dataset.ron", &text);
    // ron reports a missing field where the struct closes: the last line.
    assert_eq!(place(&e), ("dataset.ron".into(), Some(15), Some(1), None));
    assert!(
        matches!(e.kind(), ErrorKind::Ron(RonFaultKind::MissingField { name }) if name == "epoch_utc")
    );
    assert_eq!(shown(&e), "dataset.ron:15:1: missing field `epoch_utc`");

    let text = replace_line(&dataset_ron(), 11, "        (azimuth_deg: 0.0),");
    let e = fail("dataset.ron", &text);
    assert_eq!(place(&e), ("dataset.ron".into(), Some(11), Some(26), None));
    assert_eq!(
        shown(&e),
        "dataset.ron:11:26: missing field `elevation_deg`"
    );
}

#[test]
fn wrong_type() {
    let text = replace_line(&dataset_ron(), 2, "    format_version: \"one\",");
    let e = fail("dataset.ron", &text);
    assert_eq!(place(&e), ("dataset.ron".into(), Some(2), Some(21), None));
    assert!(
        matches!(e.kind(), ErrorKind::Ron(RonFaultKind::Ron { .. })),
        "{e}"
    );
    assert_eq!(shown(&e), "dataset.ron:2:21: Expected integer");

    let text = replace_line(
        &dataset_ron(),
        12,
        "        (azimuth_deg: \"north\", elevation_deg: -10.0),",
    );
    let e = fail("dataset.ron", &text);
    assert_eq!(place(&e), ("dataset.ron".into(), Some(12), Some(23), None));
    assert_eq!(shown(&e), "dataset.ron:12:23: Expected float");

    // A list where a number belongs, in truth.ron.
    let text = TRUTH_RON.replace("scale_V: 3.70", "scale_V: [3.70]");
    let e = fail("truth.ron", &text);
    assert_eq!(place(&e), ("truth.ron".into(), Some(4), Some(19), None));
}

#[test]
fn missing_column() {
    // gyro_y_rad_s dropped from header and rows.
    let text: String = TELEMETRY
        .lines()
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            [&cells[..2], &cells[3..]].concat().join(",") + "\n"
        })
        .collect();
    let e = fail("telemetry.csv", &text);
    assert_eq!(place(&e), ("telemetry.csv".into(), Some(1), None, None));
    assert_eq!(
        shown(&e),
        "telemetry.csv:1: missing column \"gyro_y_rad_s\""
    );

    // Magnetometer columns come as a set of three.
    let text = TELEMETRY.replacen("mag_y_nT", "mag_q_nT", 1);
    let e = fail("telemetry.csv", &text);
    assert_eq!(
        place(&e),
        ("telemetry.csv".into(), Some(1), Some(6), Some("mag_q_nT"))
    );
    assert_eq!(
        shown(&e),
        "telemetry.csv:1:6 (mag_q_nT): unknown column \"mag_q_nT\""
    );

    // A delimiter at the end of the header: the empty name is said to be one.
    let mut lines: Vec<String> = TELEMETRY.lines().map(str::to_owned).collect();
    lines[0].push(',');
    let text = lines.join("\n") + "\n";
    let e = fail("telemetry.csv", &text);
    assert!(
        shown(&e).ends_with(
            "unknown column \"\"; the header has an empty name here: a delimiter at the end \
             of the header line, or two in a row"
        ),
        "{}",
        shown(&e)
    );

    // A truth.csv column.
    let text = TRUTH_CSV.replacen(",eclipse,", ",", 1);
    let e = fail("truth.csv", &text);
    assert_eq!(shown(&e), "truth.csv:1: missing column \"eclipse\"");
}

#[test]
fn nan_in_a_number() {
    let text = replace_line(TELEMETRY, 3, "1,0.01,0.02,0.03,,,,1.6,NaN,0");
    let e = fail("telemetry.csv", &text);
    assert_eq!(
        place(&e),
        ("telemetry.csv".into(), Some(3), Some(9), Some("pd02_V"))
    );
    assert_eq!(
        shown(&e),
        "telemetry.csv:3:9 (pd02_V): \"NaN\" is not a finite number"
    );

    // In truth.ron, where ron accepts NaN as a float literal.
    let text = TRUTH_RON.replace("scale_V: 3.55", "scale_V: NaN");
    let e = fail("truth.ron", &text);
    assert_eq!(
        place(&e),
        (
            "truth.ron".into(),
            None,
            None,
            Some("photodiodes[2].scale_V")
        )
    );
    assert_eq!(
        shown(&e),
        "truth.ron (photodiodes[2].scale_V): \"NaN\" is not a finite number"
    );
}

#[test]
fn inf_in_a_number() {
    let text = replace_line(TELEMETRY, 4, "2,0.01,-inf,0.03,100,200,300,1.7,2.3,0.1");
    let e = fail("telemetry.csv", &text);
    assert_eq!(
        place(&e),
        (
            "telemetry.csv".into(),
            Some(4),
            Some(3),
            Some("gyro_y_rad_s")
        )
    );
    assert_eq!(
        shown(&e),
        "telemetry.csv:4:3 (gyro_y_rad_s): \"-inf\" is not a finite number"
    );

    let text = replace_line(
        TRUTH_CSV,
        2,
        &TRUTH_CSV
            .lines()
            .nth(1)
            .unwrap()
            .replacen("7000", "infinity", 1),
    );
    let e = fail("truth.csv", &text);
    assert_eq!(
        shown(&e),
        "truth.csv:2:16 (r_x_km): \"infinity\" is not a finite number"
    );
}

#[test]
fn a_truth_quaternion_off_unit_norm() {
    // Norm 2: refused at its line, named.
    let text = replace_line(
        TRUTH_CSV,
        3,
        "1,0,0,0,2,0.1,0.2,0.3,0.001,0.002,0.003,1,0,0,1,7000,0,0,20000,0,0",
    );
    let e = fail("truth.csv", &text);
    assert_eq!(
        place(&e),
        (
            "truth.csv".into(),
            Some(3),
            Some(2),
            Some("q_x, q_y, q_z, q_w")
        )
    );
    assert!(shown(&e).contains("unit norm"), "{}", shown(&e));
    // Written to six digits: accepted.
    let text = replace_line(
        TRUTH_CSV,
        3,
        "1,0.577350,0.577350,0.577350,0,0.1,0.2,0.3,0.001,0.002,0.003,1,0,0,1,7000,0,0,20000,0,0",
    );
    assert!(read_with("truth.csv", Some(&text)).is_ok());
}

#[test]
fn text_in_a_number() {
    let text = replace_line(TELEMETRY, 5, "3,0.01,0.02,0.03,,,,1.8,2.2,abc");
    let e = fail("telemetry.csv", &text);
    assert_eq!(
        place(&e),
        ("telemetry.csv".into(), Some(5), Some(10), Some("pd03_V"))
    );
    assert!(matches!(e.kind(), ErrorKind::NotANumber { value } if value == "abc"));
    assert_eq!(
        shown(&e),
        "telemetry.csv:5:10 (pd03_V): \"abc\" is not a number"
    );
    // With Windows line ends, the same line.
    let e = fail("telemetry.csv", &text.replace('\n', "\r\n"));
    assert_eq!(
        shown(&e),
        "telemetry.csv:5:10 (pd03_V): \"abc\" is not a number"
    );

    // A decimal comma splits the row into one cell too many.
    let text = replace_line(TELEMETRY, 2, "0,0.01,0.02,0.03,100,200,300,1.5,2,5,0");
    let e = fail("telemetry.csv", &text);
    assert_eq!(
        shown(&e),
        "telemetry.csv:2: row has 11 cells, the header has 10"
    );
}

#[test]
fn non_increasing_time() {
    let text = replace_line(TELEMETRY, 4, "1,0.01,0.02,0.03,100,200,300,1.7,2.3,0.1");
    let e = fail("telemetry.csv", &text);
    assert_eq!(
        place(&e),
        ("telemetry.csv".into(), Some(4), Some(1), Some("t_s"))
    );
    assert_eq!(
        shown(&e),
        "telemetry.csv:4:1 (t_s): t_s 1 is not greater than the previous row's 1"
    );

    let text = replace_line(TELEMETRY, 5, "0.5,0.01,0.02,0.03,,,,1.8,2.2,0.2");
    let e = fail("telemetry.csv", &text);
    assert_eq!(
        place(&e),
        ("telemetry.csv".into(), Some(5), Some(1), Some("t_s"))
    );

    // A missing time is not "not sampled".
    let text = replace_line(TELEMETRY, 3, ",0.01,0.02,0.03,,,,1.6,2.4,0");
    let e = fail("telemetry.csv", &text);
    assert_eq!(
        shown(&e),
        "telemetry.csv:3:1 (t_s): empty cell; this column needs a value on every row"
    );
}

#[test]
fn bad_tle_checksum() {
    // One digit of the epoch day changed: 11308 -> 11309.
    let bad = TLE1.replacen("11308", "11309", 1);
    let text = dataset_ron().replace(TLE1, &bad);
    let e = fail("dataset.ron", &text);
    assert_eq!(
        place(&e),
        ("dataset.ron".into(), Some(6), Some(16), Some("orbit.line1"))
    );
    assert!(
        matches!(
            e.kind(),
            ErrorKind::BadTleChecksum {
                line_number: 1,
                stated: Some('7'),
                computed: 8
            }
        ),
        "{e}"
    );
    assert_eq!(
        shown(&e),
        "dataset.ron:6:16 (orbit.line1): TLE line 1 checksum fails: column 69 holds \"7\", the checksum of columns 1-68 is 8"
    );

    // Line 2, inclination 101.7000 -> 101.8000.
    let bad = TLE2.replacen("101.7000", "101.8000", 1);
    let text = dataset_ron().replace(TLE2, &bad);
    let e = fail("dataset.ron", &text);
    assert_eq!(
        place(&e),
        ("dataset.ron".into(), Some(7), Some(16), Some("orbit.line2"))
    );
    assert!(
        matches!(e.kind(), ErrorKind::BadTleChecksum { line_number: 2, .. }),
        "{e}"
    );

    // Lines swapped.
    let text = dataset_ron()
        .replace(TLE1, "SWAP")
        .replace(TLE2, TLE1)
        .replace("SWAP", TLE2);
    let e = fail("dataset.ron", &text);
    assert_eq!(
        shown(&e),
        "dataset.ron:6:16 (orbit.line1): TLE line 1 must start with \"1 \""
    );
}

#[test]
fn photodiode_count_mismatch() {
    let text = replace_line(&dataset_ron(), 12, "");
    let e = fail("dataset.ron", &text);
    // Found while reading telemetry.csv: the header is where the count is wrong.
    assert_eq!(place(&e), ("telemetry.csv".into(), Some(1), None, None));
    assert_eq!(
        shown(&e),
        "telemetry.csv:1: photodiode count mismatch: dataset.ron lists 2 photodiodes, \
         the header's pdNN_V columns number 3"
    );

    // truth.ron with one photodiode too few.
    let text = replace_line(TRUTH_RON, 5, "");
    let e = fail("truth.ron", &text);
    assert_eq!(
        shown(&e),
        "truth.ron (photodiodes): photodiode count mismatch: dataset.ron lists 3 photodiodes, \
         truth.ron's photodiodes number 2"
    );

    // Right count, wrong spelling.
    let text = TELEMETRY.replacen("pd03_V", "pd3_V", 1);
    let e = fail("telemetry.csv", &text);
    assert_eq!(
        shown(&e),
        "telemetry.csv:1:10 (pd3_V): unknown column \"pd3_V\"; photodiode columns are pd01_V .. pd03_V"
    );
}

#[test]
fn empty_file() {
    for name in ["dataset.ron", "telemetry.csv", "truth.csv", "truth.ron"] {
        for text in ["", " \n\t\n"] {
            let e = fail(name, text);
            assert_eq!(place(&e), (name.into(), None, None, None));
            assert_eq!(shown(&e), format!("{name}: file is empty"));
        }
    }
    // Header only.
    let e = fail("telemetry.csv", TELEMETRY.lines().next().unwrap());
    assert_eq!(shown(&e), "telemetry.csv:1: no data rows after the header");
}

#[test]
fn missing_header() {
    let text: String = TELEMETRY
        .lines()
        .skip(1)
        .map(|l| format!("{l}\n"))
        .collect();
    let e = fail("telemetry.csv", &text);
    assert_eq!(place(&e), ("telemetry.csv".into(), Some(1), Some(1), None));
    assert_eq!(
        shown(&e),
        "telemetry.csv:1:1: missing header row: the first row must name the columns, found \"0\""
    );
}

#[test]
fn other_classes() {
    // A sensor vector sampled in part.
    let e = fail(
        "telemetry.csv",
        &replace_line(TELEMETRY, 3, "1,0.01,,0.03,,,,1.6,2.4,0"),
    );
    assert_eq!(
        shown(&e),
        "telemetry.csv:3:3 (gyro_y_rad_s): gyro_x_rad_s has a value but gyro_y_rad_s is empty; \
         a vector is sampled whole or not at all"
    );
    // Position columns with a TLE orbit.
    let text = TELEMETRY
        .lines()
        .enumerate()
        .map(|(i, l)| format!("{l},{}\n", if i == 0 { "r_x_km" } else { "1" }))
        .collect::<String>();
    let e = fail("telemetry.csv", &text);
    assert_eq!(
        shown(&e),
        "telemetry.csv:1:11 (r_x_km): column \"r_x_km\" is only allowed with `orbit: PositionColumns` in dataset.ron"
    );
    // Positions required by the orbit.
    let text = dataset_ron().replace(
        &format!("Tle(\n        line1: \"{TLE1}\",\n        line2: \"{TLE2}\",\n    )"),
        "PositionColumns",
    );
    let e = fail("dataset.ron", &text);
    assert_eq!(
        shown(&e),
        "telemetry.csv:1: missing column \"r_x_km\"; orbit: PositionColumns needs r_x_km, r_y_km, r_z_km"
    );
    // Duplicate column.
    let text = TELEMETRY.replacen("mag_z_nT", "mag_x_nT", 1);
    let e = fail("telemetry.csv", &text);
    assert_eq!(
        shown(&e),
        "telemetry.csv:1:7 (mag_x_nT): column \"mag_x_nT\" appears twice"
    );
    // A photodiode column twice is the same fault, not a photodiode count mismatch.
    let text = TELEMETRY.replacen("pd03_V", "pd01_V", 1);
    let e = fail("telemetry.csv", &text);
    assert_eq!(
        shown(&e),
        "telemetry.csv:1:10 (pd01_V): column \"pd01_V\" appears twice"
    );
    // And one added: four pdNN_V headers for three photodiodes.
    let text = TELEMETRY
        .lines()
        .enumerate()
        .map(|(i, l)| format!("{l},{}\n", if i == 0 { "pd01_V" } else { "1" }))
        .collect::<String>();
    let e = fail("telemetry.csv", &text);
    assert_eq!(
        shown(&e),
        "telemetry.csv:1:11 (pd01_V): column \"pd01_V\" appears twice"
    );
    // Epoch and version.
    let text = dataset_ron().replace("18:29:45Z", "18:29:45+02:00");
    let e = fail("dataset.ron", &text);
    assert_eq!(
        place(&e),
        ("dataset.ron".into(), Some(4), Some(5), Some("epoch_utc"))
    );
    assert!(
        matches!(e.kind(), ErrorKind::File(FileFaultKind::BadEpoch { .. })),
        "{e}"
    );
    let text = dataset_ron().replace("format_version: 1", "format_version: 2");
    let e = fail("dataset.ron", &text);
    assert_eq!(
        shown(&e),
        "dataset.ron:2:5 (format_version): format_version 2 is not supported (this reader knows 1)"
    );
    // Truth files come in pairs; eclipse is a fraction; effect lists are per photodiode.
    let e = read_with("truth.ron", None).unwrap_err();
    assert_eq!(
        shown(&e),
        "truth.ron: truth.ron is missing; truth.csv and truth.ron come together"
    );
    let text = TRUTH_CSV.replacen(",1,7000,", ",1.5,7000,", 1);
    let e = fail("truth.csv", &text);
    assert_eq!(
        shown(&e),
        "truth.csv:2:15 (eclipse): 1.5 is out of range: eclipse is a fraction from 0 to 1"
    );
    let text = TRUTH_RON.replace("[0.01, 0.02, 0.03]", "[0.01, 0.02]");
    let e = fail("truth.ron", &text);
    assert_eq!(
        shown(&e),
        "truth.ron (effects[1].volts): has 2 entries, expected 3"
    );
    // Not UTF-8.
    let dir = tempfile::tempdir().unwrap();
    fs::write(dir.path().join("dataset.ron"), dataset_ron()).unwrap();
    fs::write(dir.path().join("telemetry.csv"), b"t_s,gyro\n0,\xff\n").unwrap();
    let e = read_dataset(dir.path()).unwrap_err();
    assert_eq!((e.line(), e.column()), (Some(2), Some(3)));
    assert!(matches!(e.kind(), ErrorKind::File(FileFaultKind::NotUtf8)));
    // A missing directory or file.
    let e = read_dataset(&dir.path().join("nowhere")).unwrap_err();
    assert_eq!(e.file_name(), "dataset.ron");
    assert!(matches!(e.kind(), ErrorKind::Io { .. }));
}
