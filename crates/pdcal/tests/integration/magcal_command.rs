//! `pdcal magcal` end to end on a simulated set with magnetometer errors: the files of
//! docs/cli-contract.md, the corrected dataset, magcal.ron read back for `--mag-cal`, and a
//! broken magcal.ron refused with its place.

use std::path::Path;

use pdcal::magcal;

fn simulated(dir: &Path, seed: u64) -> pdcal_sim::SimOutput {
    let text = include_str!("../../../../fixtures/scenarios/magcal/rax2-like-magcal.ron");
    let mut scenario = pdcal_sim::Scenario::from_ron_str(text).expect("valid scenario");
    scenario.duration_s = 3600.0;
    pdcal::simulate::run_downlink_to_dir(&scenario, seed, 0, dir).expect("simulates")
}

#[test]
fn magcal_writes_its_files_and_a_corrected_dataset() {
    let tmp = tempfile::tempdir().unwrap();
    let (data, out) = (tmp.path().join("data"), tmp.path().join("out"));
    let sim = simulated(&data, 2);
    let outcome = magcal::run_dir_forced(&data, &out, false).expect("calibrates");
    for name in [
        "magcal.ron",
        "magcal.json",
        "index.html",
        "magnitude.png",
        "residual_time.png",
    ] {
        assert!(out.join(name).is_file(), "{name} missing");
    }
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("magcal.json")).unwrap()).unwrap();
    let before = json["residual_rms_nT"]["before"].as_f64().unwrap();
    let after = json["residual_rms_nT"]["after"].as_f64().unwrap();
    assert!(
        before > 2000.0 && after < 1.1 * 320.0,
        "{before} -> {after}"
    );
    assert_eq!(json["regressors"].as_array().unwrap().len(), 4);
    assert!(json["current_bias_nT_per_A"].get("cur_my_A").is_none());

    // The corrected dataset: the same rows, the magnetometer now matching the reference
    // magnitude, and what --mag-cal applies on the fly is the same correction.
    let dataset = out.join("dataset");
    let meta = pdcal_dataset::read_meta(&dataset).unwrap();
    let corrected = pdcal_dataset::read_telemetry(&dataset, &meta).unwrap();
    assert_eq!(corrected.len(), sim.telemetry.len());
    assert_eq!(corrected.pd_v, sim.telemetry.pd_v);
    assert!(dataset.join("truth.ron").is_file());
    let loaded = magcal::load(&out.join("magcal.ron")).expect("reads back");
    let mut on_the_fly = sim.telemetry.clone();
    let sigma_nt = magcal::apply(&mut on_the_fly, &loaded).expect("applies");
    // Its own uncertainty is a small fraction of the noise (tens of nT).
    assert!(sigma_nt > 0.0 && sigma_nt < 100.0, "{sigma_nt}");
    let (a, b) = (corrected.mag_nt.unwrap(), on_the_fly.mag_nt.unwrap());
    for (x, y) in a.iter().zip(&b) {
        let (x, y) = (x.unwrap(), y.unwrap());
        // The file's shortest round-trip floats and the RON round trip agree to 1e-6 nT.
        assert!((x - y).norm() < 1e-6, "{x} vs {y}");
    }
    let cal = &outcome.calibration;
    assert!((loaded.matrix - cal.matrix).abs().max() < 1e-12);
}

#[test]
fn a_broken_magcal_file_is_refused_with_its_place() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("magcal.ron");
    std::fs::write(
        &path,
        "(\n    convention: \"x\",\n    matrix_form: sideways,\n)\n",
    )
    .unwrap();
    let e = pdcal::cli::error_text(&magcal::load(&path).expect_err("refused"));
    assert!(e.contains("magcal.ron:3:"), "{e}");
    // A calibration needing a current column the dataset lacks names it.
    let data = tmp.path().join("data");
    let sim = simulated(&data, 5);
    let out = tmp.path().join("out");
    magcal::run_dir_forced(&data, &out, false).expect("calibrates");
    let loaded = magcal::load(&out.join("magcal.ron")).unwrap();
    let mut telemetry = sim.telemetry.clone();
    telemetry.current_a.retain(|c| c.name != "cur_px_A");
    let e = pdcal::cli::error_text(&magcal::apply(&mut telemetry, &loaded).expect_err("refused"));
    assert!(e.contains("cur_px_A"), "{e}");
}

/// Rows the gate rejects: magcal.json lists the first few and counts them all, and
/// rejected_rows.csv has every one, in order.
#[test]
fn many_rejected_rows_are_counted_listed_short_and_written_whole() {
    let tmp = tempfile::tempdir().unwrap();
    let (data, out) = (tmp.path().join("data"), tmp.path().join("out"));
    let mut sim = simulated(&data, 3);
    // Spikes along the field (a torquer firing): 120 rows read half again the field.
    let spiked: Vec<usize> = (0..120).map(|k| 100 + 25 * k).collect();
    let mag = sim.telemetry.mag_nt.as_mut().unwrap();
    for &row in &spiked {
        mag.set(row, mag.get(row).map(|m| m * 1.5));
    }
    let dataset = pdcal_dataset::Dataset {
        meta: sim.meta.clone(),
        telemetry: sim.telemetry.clone(),
        truth: None,
    };
    for (name, text) in pdcal_dataset::render_dataset(&dataset).unwrap() {
        std::fs::write(data.join(name), text).unwrap();
    }
    magcal::run_dir_forced(&data, &out, true).expect("calibrates");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("magcal.json")).unwrap()).unwrap();
    let listed: Vec<usize> = (json["rejected_rows"].as_array().unwrap().iter())
        .map(|v| v.as_u64().unwrap() as usize)
        .collect();
    let count = json["rows_rejected"].as_u64().unwrap() as usize;
    assert!(count >= spiked.len(), "{count} rejected");
    assert_eq!(listed.len(), magcal::REJECTED_ROWS_LISTED);
    assert_eq!(
        json["rejected_rows_truncated"],
        serde_json::Value::Bool(true)
    );
    let csv = std::fs::read_to_string(out.join("rejected_rows.csv")).unwrap();
    let rows: Vec<usize> = (csv.lines().skip(1))
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(rows.len(), count);
    assert_eq!(rows[..listed.len()], listed[..]);
    assert!(spiked.iter().all(|r| rows.contains(r)));
}

/// A current column without a sample is named as the cause, not reported as "0 usable rows
/// for 9 parameters".
#[test]
fn an_all_empty_current_column_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    simulated(&data, 3);
    let meta = pdcal_dataset::read_meta(&data).unwrap();
    let mut telemetry = pdcal_dataset::read_telemetry(&data, &meta).unwrap();
    let column = &mut telemetry.current_a[1];
    let name = format!("cur_{}_A", column.name);
    column.values.iter_mut().for_each(|v| *v = None);
    let Err(e) = magcal::run(&meta, &telemetry) else {
        panic!("calibrated without the rows of {name}");
    };
    let e = format!("{e:#}");
    assert!(
        e.contains(&format!("current column \"{name}\" has no sample"))
            && !e.contains("usable rows"),
        "{e}"
    );
}

/// A magnetometer axis that reads one value throughout is named as stuck, not reported as
/// "the scale factor not determined by the data".
#[test]
fn a_stuck_axis_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    simulated(&data, 4);
    let meta = pdcal_dataset::read_meta(&data).unwrap();
    let mut telemetry = pdcal_dataset::read_telemetry(&data, &meta).unwrap();
    let mag = telemetry.mag_nt.as_mut().unwrap();
    *mag = mag
        .iter()
        .map(|m| m.map(|m| nalgebra::Vector3::new(m.x, m.y, -123.0)))
        .collect();
    let Err(e) = magcal::run(&meta, &telemetry) else {
        panic!("calibrated a stuck z axis");
    };
    let e = format!("{e:#}");
    assert!(
        e.contains("mag_z_nT spans 0.000 nT (-123 .. -123 nT)") && e.contains("stuck or dead axis"),
        "{e}"
    );
}
