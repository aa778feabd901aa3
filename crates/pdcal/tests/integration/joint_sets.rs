//! `pdcal calibrate DIR1 DIR2 --out OUT`: two downlinks of one spacecraft a month apart
//! calibrated as one (the second's epoch first on the command line, to show the order does
//! not matter); sets of different layouts or overlapping in time are refused with the
//! first difference named.

use std::path::{Path, PathBuf};

use pdcal::calibrate::{RunConfig, run_dirs};
use pdcal_sim::Scenario;

/// A 40-minute rax2-like set starting at `epoch_utc`, seed 8 (the same hardware each time).
fn simulate(dir: &Path, epoch_utc: &str) {
    let mut s = Scenario::rax2_like().unwrap();
    s.duration_s = 2400.0;
    s.epoch_utc = epoch_utc.to_owned();
    pdcal::simulate::run_to_dir(&s, 8, dir).unwrap();
}

fn two_sets(tmp: &Path) -> (PathBuf, PathBuf) {
    let (a, b) = (tmp.join("nov"), tmp.join("dec"));
    simulate(&a, "2011-11-04T18:00:00Z");
    simulate(&b, "2011-12-04T18:00:00Z");
    (a, b)
}

#[test]
fn two_downlinks_a_month_apart_are_one_calibration() {
    let tmp = tempfile::tempdir().unwrap();
    let (nov, dec) = two_sets(tmp.path());
    let out = tmp.path().join("joint");
    let (outcome, summary) =
        run_dirs(&[dec.clone(), nov.clone()], &out, &RunConfig::default()).unwrap();
    // In time order, the December set on the joint time line 30 days on.
    assert_eq!(summary.datasets.len(), 2);
    let (first, second) = (&summary.datasets[0], &summary.datasets[1]);
    assert_eq!(first.span.dir, nov.display().to_string());
    assert_eq!(first.span.first_row, 0);
    assert_eq!(second.span.first_row, first.span.rows);
    assert_eq!(second.span.offset_s, 30.0 * 86400.0);
    for set in &summary.datasets {
        assert!(set.residuals.count > 1000, "{set:?}");
        assert!(set.residuals.fraction_within_3sigma > 0.98, "{set:?}");
    }
    // Each set is at least one segment with its own acquisition; none spans both.
    let boundary = second.span.first_row;
    assert!(summary.segments.len() >= 2);
    assert!(
        summary
            .segments
            .iter()
            .all(|s| s.last_row < boundary || s.first_row >= boundary)
    );
    assert!(
        summary
            .segments
            .iter()
            .any(|s| s.first_row >= boundary && s.acquired_row.is_some())
    );
    assert_eq!(
        summary.dataset,
        format!("{} + {}", first.span.name, second.span.name)
    );
    // Calibrated against the truth both sets share.
    let constants = pdcal_dataset::read_truth(&nov, &pdcal_dataset::read_meta(&nov).unwrap())
        .unwrap()
        .unwrap()
        .1;
    for (t, e) in constants
        .photodiodes
        .iter()
        .zip(&outcome.run.calibration.photodiodes)
    {
        assert!((t.scale_v - e.scale_v).abs() < 4.0 * e.scale_sigma_v.max(0.01));
    }
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(json["datasets"].as_array().unwrap().len(), 2);
    assert!(json["datasets"][1]["residuals"]["photodiode_rms_V"].is_f64());
    // Each set's residuals on its own figure, linked from index.html.
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    for n in [1, 2] {
        let stem = format!("fig04_residuals_set{n}");
        assert!(out.join(format!("{stem}.png")).is_file(), "{stem} missing");
        assert!(html.contains(&format!("{stem}.svg")));
    }
}

#[test]
fn sets_of_another_layout_or_overlapping_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let (nov, dec) = two_sets(tmp.path());
    // Photodiode 3 mounted differently in the December dataset.ron.
    let path = dec.join("dataset.ron");
    let text = std::fs::read_to_string(&path).unwrap();
    let moved = text.replacen("azimuth_deg: -17.0", "azimuth_deg: -27.0", 1);
    assert_ne!(moved, text);
    std::fs::write(&path, moved).unwrap();
    let Err(err) = run_dirs(
        &[nov.clone(), dec.clone()],
        &tmp.path().join("o1"),
        &RunConfig::default(),
    ) else {
        panic!("another layout must be refused");
    };
    assert_eq!(
        format!("{err:#}"),
        format!(
            "{}: photodiode 3 azimuth_deg = -27, but {} has -17: data sets of one calibration \
             must share the photodiode layout",
            path.display(),
            nov.join("dataset.ron").display()
        )
    );
    assert!(!tmp.path().join("o1").exists());
    // The same set twice overlaps itself.
    let Err(err) = run_dirs(
        &[nov.clone(), nov],
        &tmp.path().join("o2"),
        &RunConfig::default(),
    ) else {
        panic!("overlapping sets must be refused");
    };
    assert!(
        format!("{err:#}").contains("must not overlap in time"),
        "{err:#}"
    );
}

/// A fault of one set of a joint run names that set, on its own time line.
#[test]
fn a_fault_of_one_set_names_the_set() {
    let tmp = tempfile::tempdir().unwrap();
    let (nov, dec) = two_sets(tmp.path());
    // December's gyro reads exactly 0 throughout (a dead gyro).
    let path = dec.join("telemetry.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let dead: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(k, line)| {
            let mut cells: Vec<&str> = line.split(',').collect();
            if k > 0 {
                cells[1..4].copy_from_slice(&["0", "0", "0"]);
            }
            cells.join(",")
        })
        .collect();
    std::fs::write(&path, dead.join("\n") + "\n").unwrap();
    let Err(err) = run_dirs(
        &[nov, dec.clone()],
        &tmp.path().join("o"),
        &RunConfig::default(),
    ) else {
        panic!("a dead gyro must be refused");
    };
    let shown = format!("{err:#}");
    assert!(
        shown.starts_with(&format!(
            "{}: telemetry.csv (gyro_x_rad_s, gyro_y_rad_s, gyro_z_rad_s): the gyro reads exactly 0",
            dec.display()
        )),
        "{shown}"
    );
}
