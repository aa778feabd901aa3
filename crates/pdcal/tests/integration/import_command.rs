//! `pdcal import` as a user runs it: the dataset written, one-line errors naming the map's or
//! the export's line, and `--out` checked before the export is read.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const PDCAL: &str = env!("CARGO_BIN_EXE_pdcal");

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/import")
        .join(name)
}

fn import(source: &Path, map: &Path, out: &Path) -> Output {
    Command::new(PDCAL)
        .arg("import")
        .arg(source)
        .arg("--map")
        .arg(map)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn the_fixture_imports_into_a_dataset_directory() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("ds");
    let o = import(&fixture("export.csv"), &fixture("map.ron"), &out);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains(
            "3503 of 3507 rows kept (1 dropped with an empty time, 3 with a sentinel time)"
        ),
        "{stdout}"
    );
    let ds = pdcal_dataset::read_dataset(&out).unwrap();
    assert_eq!(ds.telemetry.len(), 3503);
    assert!(ds.truth.is_none());
    // Importing again replaces the dataset directory.
    let o = import(&fixture("export.csv"), &fixture("map-positions.ron"), &out);
    assert!(o.status.success(), "{}", stderr(&o));
    let ds = pdcal_dataset::read_dataset(&out).unwrap();
    assert!(ds.telemetry.r_gcrf_km.is_some());
}

#[test]
fn errors_are_one_line_naming_the_file_and_line() {
    let tmp = tempfile::tempdir().unwrap();
    let map = tmp.path().join("map.ron");
    let text = std::fs::read_to_string(fixture("map.ron")).unwrap();
    std::fs::write(&map, text.replace("\"adc_ch05\"", "\"adc_ch5\"")).unwrap();
    let out = tmp.path().join("ds");
    let o = import(&fixture("export.csv"), &map, &out);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert_eq!(err.lines().count(), 1, "{err}");
    let want = format!(
        "pdcal: error: {}:21:18 (photodiodes[1].column): column \"adc_ch5\" is not in \
         export.csv's header (line 1)",
        map.display()
    );
    assert!(err.starts_with(&want), "{err}");
    assert!(!out.exists(), "nothing written on error");

    let csv = tmp.path().join("export.csv");
    let export = std::fs::read_to_string(fixture("export.csv")).unwrap();
    let bad = export.replacen("\n40001,208,", "\n40001,2x0,", 1);
    std::fs::write(&csv, bad).unwrap();
    let o = import(&csv, &fixture("map.ron"), &out);
    let err = stderr(&o);
    assert!(
        err.starts_with(&format!(
            "pdcal: error: {}:3:2 (adc_ch09): \"2x0\" is not a number",
            csv.display()
        )),
        "{err}"
    );
}

#[test]
fn a_foreign_out_directory_is_refused_before_reading() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    // The export does not exist: the refusal of --out must come first.
    let o = import(&tmp.path().join("missing.csv"), &fixture("map.ron"), &out);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(err.contains("refusing to write into it"), "{err}");
    assert!(err.contains("not a pdcal output"), "{err}");
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "mine"
    );
}

/// A `;`-separated export of two photodiodes read against a common reference channel, with
/// rows of one time tag, and its map (no `delimiter`: detected).
const SEMICOLON_CSV: &str = "\
unix;wx;wy;wz;V1;V2;VN
1320431385;1;2;3;2048;1500;1024
1320431386;1;2;3;2048;1500;1024
1320431386;3;4;5;2048;1500;1000
1320431387;1;2;3;4095;1500;1024
";

fn semicolon_map(extra: &str) -> String {
    let text = std::fs::read_to_string(fixture("map.ron")).unwrap();
    let tle: Vec<&str> = text.lines().filter(|l| l.contains("line")).collect();
    format!(
        r#"(
    format_version: 1,
    time: (column: "unix", form: Unix),
{extra}    gyro: (x: (column: "wx", unit: "deg/s"), y: (column: "wy", unit: "deg/s"), z: (column: "wz", unit: "deg/s")),
    photodiodes: [
        (columns: [("V1", 1.0), ("VN", -1.0)], counts: (gain: 0.001220703125, unit: "V"), sentinels: [4095], azimuth_deg: 0.0, elevation_deg: 0.0),
        (columns: [("V2", 1.0), ("VN", -1.0)], counts: (gain: 0.001220703125, unit: "V"), azimuth_deg: 90.0, elevation_deg: 0.0),
    ],
    orbit: Tle(
{}
{}
    ),
)
"#,
        tle[0], tle[1]
    )
}

#[test]
fn the_output_says_the_detected_delimiter_and_the_merged_rows() {
    let tmp = tempfile::tempdir().unwrap();
    let (csv, map) = (tmp.path().join("pass.csv"), tmp.path().join("map.ron"));
    std::fs::write(&csv, SEMICOLON_CSV).unwrap();
    std::fs::write(&map, semicolon_map("    duplicate_times: Average,\n")).unwrap();
    let out = tmp.path().join("ds");
    let o = import(&csv, &map, &out);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(
        lines[..4],
        [
            "delimiter: semicolon (';') (detected from the header; `delimiter` in the map sets it)",
            "3 of 4 rows kept (0 dropped with an empty time, 0 with a sentinel time); epoch \
             2011-11-04T18:29:45Z, span 2 s",
            "1 rows with the time of the previous row averaged into the first row of their time \
             (duplicate_times: Average)",
            "sentinel cells left empty: V1 - VN 1",
        ],
        "{stdout}"
    );
    let ds = pdcal_dataset::read_dataset(&out).unwrap();
    // pd01 at the merged time: (1024 + 1048) / 2 counts.
    assert_eq!(ds.telemetry.pd_v[0].get(1), Some(1036.0 * 5.0 / 4096.0));
    // Refused by default, with its own message.
    std::fs::write(&map, semicolon_map("")).unwrap();
    let o = import(&csv, &map, &tmp.path().join("ds2"));
    assert_eq!(
        stderr(&o),
        format!(
            "pdcal: error: {}:4:1 (unix): time 2011-11-04T18:29:46.000000Z is the same as the \
             previous kept row's (line 3): the export has several rows with one time tag; say \
             in the map which to use, `duplicate_times: KeepFirst` or `duplicate_times: \
             Average`\n",
            csv.display()
        )
    );
}

#[test]
fn a_fault_in_the_last_row_of_a_streamed_export_leaves_the_old_dataset() {
    let tmp = tempfile::tempdir().unwrap();
    let (csv, map) = (tmp.path().join("pass.csv"), tmp.path().join("map.ron"));
    std::fs::write(&map, semicolon_map("    duplicate_times: KeepFirst,\n")).unwrap();
    std::fs::write(&csv, SEMICOLON_CSV).unwrap();
    let out = tmp.path().join("ds");
    assert!(import(&csv, &map, &out).status.success());
    let before = std::fs::read(out.join("telemetry.csv")).unwrap();
    // Many good rows are converted and staged before the last one is found bad.
    let mut long = SEMICOLON_CSV.to_owned();
    for k in 0..20_000 {
        long.push_str(&format!("{};1;2;3;2048;1500;1024\n", 1_320_431_388 + k));
    }
    long.push_str("1320451388;1;2;3;20x48;1500;1024\n");
    std::fs::write(&csv, long).unwrap();
    let o = import(&csv, &map, &out);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains(":20006:5 (V1): \"20x48\" is not a number"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read(out.join("telemetry.csv")).unwrap(), before);
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("pdcal"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

/// `--print-map-template` prints a map made from the export's header: time, gyro and
/// magnetometer filled in from the names, a commented-out photodiode entry per other
/// numeric column, `?` where no name can tell. Given what it leaves open, it imports.
#[test]
fn the_map_template_from_the_header_imports_once_filled_in() {
    let o = Command::new(PDCAL)
        .args(["import", "--print-map-template"])
        .arg(fixture("export.csv"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let template = String::from_utf8(o.stdout).unwrap();
    for line in [
        "    time: (column: \"time_unix\", form: Unix),",
        "        x: (column: \"gyro_x_dps\", unit: \"deg/s\"),",
        "        z: (column: \"mag_z_mG\", unit: \"mG\"),",
        "        // (column: \"adc_ch00\", unit: ?, azimuth_deg: ?, elevation_deg: ?),",
        "    orbit: Tle(line1: ?, line2: ?),",
    ] {
        assert!(template.contains(line), "no {line:?} in\n{template}");
    }
    // Text columns are no photodiode; the header is listed with the first values.
    assert!(!template.contains("(column: \"mode\""), "{template}");
    assert!(template.contains("//   \"mode\": \"SCI\""), "{template}");

    // Filled in from the fixture's map: its photodiodes and orbit.
    let map = std::fs::read_to_string(fixture("map.ron")).unwrap();
    let photodiodes: String = map
        .lines()
        .filter(|l| l.trim_start().starts_with("(column: \"adc_ch"))
        .map(|l| format!("{l}\n"))
        .collect();
    let orbit_at = map.find("    orbit: Tle(").unwrap();
    let orbit_end = orbit_at + map[orbit_at..].find("    ),\n").unwrap() + "    ),\n".len();
    let filled: String = template
        .lines()
        .filter(|l| !l.trim_start().starts_with("// (column:"))
        .map(|l| match l {
            "    orbit: Tle(line1: ?, line2: ?),   // or Positions(x: .., y: .., z: .., frame: Teme)" => {
                map[orbit_at..orbit_end].to_owned()
            }
            l if l.starts_with("    photodiodes: [") => format!("{l}\n{photodiodes}"),
            // The export's sentinels, which no header can tell.
            l if l.starts_with("    time: ") => concat!(
                "    time: (column: \"time_unix\", form: Unix, sentinels: [-1]),\n",
                "    sentinels: [65535],\n"
            )
            .to_owned(),
            l => format!("{l}\n"),
        })
        .collect();
    let tmp = tempfile::tempdir().unwrap();
    let filled_map = tmp.path().join("map.ron");
    std::fs::write(&filled_map, &filled).unwrap();
    let o = import(&fixture("export.csv"), &filled_map, &tmp.path().join("ds"));
    assert!(o.status.success(), "{}\n{filled}", stderr(&o));
    let meta = std::fs::read_to_string(tmp.path().join("ds/dataset.ron")).unwrap();
    assert!(meta.contains("name: \"export\""), "{meta}");
}

/// A current's conversion error is placed at the current's own entry in the map, not at
/// an earlier entry that reads the same export column (here the time).
#[test]
fn a_current_error_names_its_own_map_line() {
    let map = std::fs::read_to_string(fixture("map.ron")).unwrap();
    let map = map.replacen(
        "    orbit: Tle(",
        "    currents: [\n        (name: \"bus\", column: \"time_unix\", unit: \"A\"),\n    ],\n    orbit: Tle(",
        1,
    );
    let line = 1 + map[..map.find("(name: \"bus\"").unwrap()]
        .matches('\n')
        .count();
    let tmp = tempfile::tempdir().unwrap();
    let map_path = tmp.path().join("map.ron");
    std::fs::write(&map_path, &map).unwrap();
    let o = import(&fixture("export.csv"), &map_path, &tmp.path().join("ds"));
    let e = stderr(&o);
    assert!(!o.status.success());
    assert!(
        e.contains(&format!("(currents[0] of map.ron:{line})")),
        "{e}"
    );
}
