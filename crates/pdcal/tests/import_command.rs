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
