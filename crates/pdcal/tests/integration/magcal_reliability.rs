//! `pdcal magcal` and `calibrate --mag-cal` on hostile inputs (issue 47): a glitch in a
//! current column, magnetometer spikes, data in uT, a magcal.ron with impossible numbers,
//! and an `--out` that holds the input.

use std::path::Path;

use pdcal::magcal;

/// 1200 rows (20 min at 1 Hz) in sunlight of the magcal scenario: three panel currents
/// drive the magnetometer, `cur_my_A` drives nothing.
fn simulated(dir: &Path, seed: u64) -> pdcal_sim::SimOutput {
    let text = include_str!("../../../../fixtures/scenarios/magcal/rax2-like-magcal.ron");
    let mut scenario = pdcal_sim::Scenario::from_ron_str(text).expect("valid scenario");
    // Half an hour on from the scenario's epoch, past the eclipse exit at about 24 min.
    scenario.epoch_utc = "2011-11-04T18:59:45Z".into();
    scenario.duration_s = 1200.0;
    pdcal::simulate::run_downlink_to_dir(&scenario, seed, 0, dir).expect("simulates")
}

/// Writes `telemetry` over the data set in `dir`.
fn rewrite(dir: &Path, sim: &pdcal_sim::SimOutput, telemetry: pdcal_dataset::Telemetry) {
    let dataset = pdcal_dataset::Dataset {
        meta: sim.meta.clone(),
        telemetry,
        truth: None,
    };
    for (name, text) in pdcal_dataset::render_dataset(&dataset).unwrap() {
        std::fs::write(dir.join(name), text).unwrap();
    }
}

fn summary(out: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(out.join("magcal.json")).unwrap()).unwrap()
}

fn set_current(telemetry: &mut pdcal_dataset::Telemetry, name: &str, row: usize, amps: f64) {
    let column = (telemetry.current_a.iter_mut())
        .find(|c| c.name == name)
        .expect("column");
    column.values[row] = Some(amps);
}

fn kept(json: &serde_json::Value, name: &str) -> bool {
    (json["regressors"].as_array().unwrap().iter()).any(|r| r["name"] == name && r["kept"] == true)
}

fn screened_rows(json: &serde_json::Value) -> Vec<u64> {
    (json["rows_screened"].as_array().unwrap().iter())
        .map(|r| r["row"].as_u64().unwrap())
        .collect()
}

/// A 100 A glitch in one row of a current column is screened out and listed (the idle
/// column's regressor is then dropped as without it; the live column's row does not move
/// the bias); a constant column with one glitch is not tested (its evidence is one row).
#[test]
fn a_current_glitch_is_screened_and_one_row_is_no_evidence() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    let sim = simulated(&data, 11);
    magcal::run_dir_forced(&data, &tmp.path().join("clean"), false).expect("calibrates");
    let clean = summary(&tmp.path().join("clean"));
    assert!(!kept(&clean, "cur_my_A"), "{}", clean["regressors"]);

    for column in ["cur_my_A", "cur_px_A"] {
        let mut telemetry = sim.telemetry.clone();
        set_current(&mut telemetry, column, 600, 100.0);
        rewrite(&data, &sim, telemetry);
        let out = tmp.path().join(column);
        magcal::run_dir_forced(&data, &out, false).expect("calibrates");
        let json = summary(&out);
        assert_eq!(
            screened_rows(&json),
            [600],
            "{column}: {}",
            json["rows_screened"]
        );
        assert!(
            json["rows_screened"][0]["cause"]
                .as_str()
                .unwrap()
                .contains(column)
        );
        assert!(!kept(&json, "cur_my_A"), "{column}: {}", json["regressors"]);
        for a in 0..3 {
            let (b, b0) = (
                json["bias_nT"][a].as_f64().unwrap(),
                clean["bias_nT"][a].as_f64().unwrap(),
            );
            let sigma = clean["bias_sigma_nT"][a].as_f64().unwrap();
            assert!(
                (b - b0).abs() < sigma,
                "{column}: axis {a}: {b} against {b0} +- {sigma}"
            );
        }
        let csv = std::fs::read_to_string(out.join("rejected_rows.csv")).unwrap();
        assert!(
            csv.lines()
                .any(|l| l.starts_with("600,") && l.contains(column)),
            "{csv}"
        );
    }

    // An idle channel, 0 A throughout but for one row.
    let mut telemetry = sim.telemetry.clone();
    let mut idle = telemetry.current_a[0].clone();
    idle.name = "cur_idle_A".into();
    idle.values = vec![Some(0.0); telemetry.len()];
    idle.values[600] = Some(100.0);
    telemetry.current_a.push(idle);
    rewrite(&data, &sim, telemetry);
    let out = tmp.path().join("idle");
    magcal::run_dir_forced(&data, &out, false).expect("calibrates");
    let json = summary(&out);
    let idle = (json["regressors"].as_array().unwrap().iter())
        .find(|r| r["name"] == "cur_idle_A")
        .expect("tested");
    assert_eq!(idle["kept"], false, "{idle}");
    assert!(
        idle["reason"].as_str().unwrap().contains("rows' worth"),
        "{idle}"
    );
}

/// One spike of 9e6 nT in 1200 rows is screened out and listed, and the calibration is the
/// clean one's; 33 spikes either calibrate as well or are refused, never a calibration with
/// an impossible matrix or bias.
#[test]
fn magnetometer_spikes_are_screened_and_an_impossible_fit_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    let sim = simulated(&data, 12);
    for spikes in [1usize, 33] {
        let rows: Vec<usize> = (0..spikes).map(|k| 17 + 36 * k).collect();
        let mut telemetry = sim.telemetry.clone();
        let mag = telemetry.mag_nt.as_mut().unwrap();
        for &row in &rows {
            mag.set(
                row,
                mag.get(row).map(|m| nalgebra::Vector3::new(9e6, m.y, m.z)),
            );
        }
        rewrite(&data, &sim, telemetry);
        let out = tmp.path().join(format!("spikes{spikes}"));
        match magcal::run_dir_forced(&data, &out, false) {
            Ok(outcome) => {
                let json = summary(&out);
                assert!(
                    outcome.warnings.is_empty(),
                    "{spikes}: {:?}",
                    outcome.warnings
                );
                let rejected: Vec<u64> = (json["rejected_rows"].as_array().unwrap().iter())
                    .map(|v| v.as_u64().unwrap())
                    .collect();
                assert!(
                    rows.iter().all(|r| rejected.contains(&(*r as u64))),
                    "{rejected:?}"
                );
                let scales = outcome.calibration.matrix.singular_values();
                assert!(scales.min() > 0.9 && scales.max() < 1.1, "{scales}");
                assert!(outcome.calibration.params.bias_nt.norm() < 1e4);
            }
            Err(e) => {
                let e = pdcal::cli::error_text(&e);
                assert!(
                    spikes > 1 && e.contains("not a calibration"),
                    "{spikes}: {e}"
                );
            }
        }
    }
}

/// A field in uT (1000 times below IGRF's) is refused before the fit, the unit named.
#[test]
fn microtesla_data_are_refused_before_the_fit() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    let sim = simulated(&data, 13);
    let mut telemetry = sim.telemetry.clone();
    let mag = telemetry.mag_nt.as_mut().unwrap();
    for row in 0..mag.len() {
        mag.set(row, mag.get(row).map(|m| m / 1000.0));
    }
    rewrite(&data, &sim, telemetry);
    let out = tmp.path().join("out");
    let e = magcal::run_dir_forced(&data, &out, false).expect_err("refused");
    let e = pdcal::cli::error_text(&e);
    assert!(
        e.contains("uT") && e.contains("nT") && e.contains("IGRF"),
        "{e}"
    );
    assert!(!out.exists());
}

/// A magcal.ron with a NaN or negative variance, a matrix no magnetometer has or a bias
/// beyond any CubeSat's is refused by `--mag-cal`, the file named; a mismatch found while
/// applying it names the file too.
#[test]
fn a_magcal_file_with_impossible_numbers_is_refused_naming_it() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    let sim = simulated(&data, 14);
    let out = tmp.path().join("out");
    magcal::run_dir_forced(&data, &out, false).expect("calibrates");
    let text = std::fs::read_to_string(out.join("magcal.ron")).unwrap();
    let good: magcal::MagCalFile = ron::from_str(&text).unwrap();
    type Edit = fn(&mut magcal::MagCalFile);
    let edits: [(&str, Edit); 6] = [
        ("variance", |f| f.covariance[7][7] = f64::NAN),
        ("variance", |f| f.covariance[2][2] = -1e8),
        ("scale factors", |f| {
            f.matrix = [[109.0, 0.0, 0.0], [0.0, 148.0, 0.0], [0.0, 0.0, 26.0]]
        }),
        ("hard-iron bias", |f| f.bias_nt = [4.5e6, 0.0, 0.0]),
        ("noise", |f| f.noise_sigma_nt = f64::NAN),
        ("matrix_form is Diagonal", |f| {
            f.matrix_form = pdcal_magcal::MatrixForm::Diagonal;
            f.matrix[0][1] = 0.02;
            f.matrix[1][0] = 0.02;
        }),
    ];
    for (i, (what, edit)) in edits.iter().enumerate() {
        let mut file = good.clone();
        edit(&mut file);
        let path = tmp.path().join(format!("bad{i}.ron"));
        std::fs::write(&path, ron::ser::to_string(&file).unwrap()).unwrap();
        let e = pdcal::cli::error_text(&magcal::load(&path).expect_err(what));
        assert!(
            e.contains(&format!("bad{i}.ron")) && e.contains(what),
            "{e}"
        );
    }

    let path = out.join("magcal.ron");
    let loaded = magcal::load(&path).unwrap();
    let needed = loaded.regressors.first().expect("a current kept").clone();
    let config = pdcal::calibrate::RunConfig {
        mag_cal: Some(loaded),
        mag_cal_file: Some(path.clone()),
        ..pdcal::calibrate::RunConfig::default()
    };
    let mut telemetry = sim.telemetry.clone();
    telemetry.current_a.retain(|c| c.name != needed);
    rewrite(&data, &sim, telemetry);
    let e = pdcal::calibrate::run_dirs_forced(&[data], &tmp.path().join("cal"), &config, false)
        .map(|_| ())
        .expect_err("refused");
    let e = pdcal::cli::error_text(&e);
    assert!(
        e.contains(&needed) && e.contains(&path.display().to_string()),
        "{e}"
    );
}

/// `magcal OUT/dataset --out OUT` would replace its own input: refused, the input kept.
#[test]
fn an_out_holding_the_input_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let (data, out) = (tmp.path().join("data"), tmp.path().join("out"));
    simulated(&data, 15);
    magcal::run_dir_forced(&data, &out, false).expect("calibrates");
    let input = out.join("dataset");
    let before = std::fs::read(input.join("telemetry.csv")).unwrap();
    let e = magcal::run_dir_forced(&input, &out, true).expect_err("refused");
    let e = pdcal::cli::error_text(&e);
    assert!(e.contains("holds the input"), "{e}");
    assert_eq!(std::fs::read(input.join("telemetry.csv")).unwrap(), before);
    // The same for calibrate given a data set inside its --out.
    let e = pdcal::calibrate::run_dirs_forced(
        std::slice::from_ref(&input),
        &out,
        &pdcal::calibrate::RunConfig::default(),
        true,
    )
    .map(|_| ())
    .expect_err("refused");
    assert!(pdcal::cli::error_text(&e).contains("holds the input"));
}
