//! Sensors a data set does not have (issue 47): no `gyro_*` columns at all mean no gyro,
//! all-empty magnetometer columns mean photodiode-only; and `evaluate` against another data
//! set's truth is refused.

use std::path::Path;

use pdcal::calibrate::RunConfig;

/// The RAX-2-like set cut to 27 minutes (the first 3 sunlit minutes give the filter
/// something to do); dataset.ron carries the scenario's inertia.
fn short_rax2(epoch_utc: &str, dir: &Path) -> pdcal_sim::SimOutput {
    let mut scenario = pdcal_sim::Scenario::rax2_like().unwrap();
    scenario.duration_s = 27.0 * 60.0;
    scenario.epoch_utc = epoch_utc.to_owned();
    pdcal::simulate::run_to_dir(&scenario, 11, dir).unwrap()
}

/// telemetry.csv of `dir` without the columns named `drop`.
fn drop_columns(dir: &Path, drop: &[&str]) {
    let path = dir.join("telemetry.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let keep: Vec<bool> = header.iter().map(|h| !drop.contains(h)).collect();
    let pick = |line: &str| {
        (line.split(',').zip(&keep))
            .filter(|(_, k)| **k)
            .map(|(c, _)| c)
            .collect::<Vec<_>>()
            .join(",")
    };
    let mut out = pick(&header.join(","));
    for line in lines {
        out.push('\n');
        out.push_str(&pick(line));
    }
    out.push('\n');
    std::fs::write(&path, out).unwrap();
}

fn summary(out: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap()
}

/// With `inertia_kg_m2` given, a telemetry.csv without gyro columns reads as a gyro with no
/// sample and calibrates on the dynamics; without the magnetometer's columns too.
#[test]
fn no_gyro_columns_mean_no_gyro() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    let sim = short_rax2("2011-11-04T18:29:45Z", &data);
    assert!(sim.meta.inertia_kg_m2.is_some());
    drop_columns(&data, &["gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s"]);
    let meta = pdcal_dataset::read_meta(&data).unwrap();
    let telemetry = pdcal_dataset::read_telemetry(&data, &meta).expect("reads without a gyro");
    assert_eq!(telemetry.len(), sim.telemetry.len());
    assert!(telemetry.gyro_rad_s.iter().all(|w| w.is_none()));
    let out = tmp.path().join("out");
    pdcal::calibrate::run_dir(&data, &out, &RunConfig::default()).expect("calibrates");
    assert!(
        summary(&out)["propagation"]
            .to_string()
            .contains("dynamics")
    );

    // One gyro column of three is still a broken header.
    let partial = tmp.path().join("partial");
    short_rax2("2011-11-04T18:29:45Z", &partial);
    drop_columns(&partial, &["gyro_y_rad_s"]);
    let meta = pdcal_dataset::read_meta(&partial).unwrap();
    let e = pdcal_dataset::read_telemetry(&partial, &meta).expect_err("refused");
    assert!(e.to_string().contains("gyro_y_rad_s"), "{e}");
}

/// Magnetometer columns with every cell empty are a photodiode-only run, as without them.
#[test]
fn empty_magnetometer_columns_mean_photodiode_only() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    let mut sim = short_rax2("2011-11-04T18:29:45Z", &data);
    let mag = sim.telemetry.mag_nt.as_mut().unwrap();
    for k in 0..mag.len() {
        mag.set(k, None);
    }
    let dataset = pdcal_dataset::Dataset {
        meta: sim.meta.clone(),
        telemetry: sim.telemetry.clone(),
        truth: None,
    };
    for (name, text) in pdcal_dataset::render_dataset(&dataset).unwrap() {
        std::fs::write(data.join(name), text).unwrap();
    }
    assert!(
        std::fs::read_to_string(data.join("telemetry.csv"))
            .unwrap()
            .lines()
            .next()
            .unwrap()
            .contains("mag_x_nT")
    );
    let out = tmp.path().join("out");
    pdcal::calibrate::run_dir(&data, &out, &RunConfig::default()).expect("calibrates");
    let json = summary(&out);
    assert_eq!(json["magnetometer_used"], false, "{}", json["mode"]);
}

/// `evaluate` with a data set of the same layout but another epoch than the one calibrated
/// is refused, naming both; the calibrated one evaluates.
#[test]
fn evaluate_refuses_another_data_sets_truth() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b, out) = (
        tmp.path().join("a"),
        tmp.path().join("b"),
        tmp.path().join("out"),
    );
    short_rax2("2011-11-04T18:29:45Z", &a);
    short_rax2("2011-11-05T18:29:45Z", &b);
    pdcal::calibrate::run_dir(&a, &out, &RunConfig::default()).unwrap();
    let e = pdcal::evaluate::run_dir(&b, &out).expect_err("refused");
    let e = pdcal::cli::error_text(&e);
    assert!(
        e.contains("2011-11-04T18:29:45Z") && e.contains("2011-11-05T18:29:45Z"),
        "{e}"
    );
    assert!(!out.join("evaluation.json").exists());
    pdcal::evaluate::run_dir(&a, &out).expect("the calibrated set evaluates");
}

/// With the inertia given, a gyro that stops early (samples in the first rows only) is no
/// worse than none: the dynamics carry the attitude where it stops (no row skipped as
/// gyro-silent, no segment ended there), the run calibrates and the normals are not called
/// turned.
#[test]
fn where_the_gyro_stops_the_dynamics_carry_on() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    let mut scenario = pdcal_sim::Scenario::builtin("sso-6u").unwrap();
    scenario.duration_s = 1200.0;
    let sim = pdcal::simulate::run_to_dir(&scenario, 4, &data).unwrap();
    assert!(sim.meta.inertia_kg_m2.is_some());
    for kept_rows in [60, 10] {
        let mut telemetry = sim.telemetry.clone();
        for k in kept_rows..telemetry.len() {
            telemetry.gyro_rad_s.set(k, None);
        }
        let dataset = pdcal_dataset::Dataset {
            meta: sim.meta.clone(),
            telemetry,
            truth: None,
        };
        for (name, text) in pdcal_dataset::render_dataset(&dataset).unwrap() {
            std::fs::write(data.join(name), text).unwrap();
        }
        let out = tmp.path().join(format!("out{kept_rows}"));
        pdcal::calibrate::run_dir(&data, &out, &RunConfig::default())
            .unwrap_or_else(|e| panic!("gyro in {kept_rows} rows: {}", pdcal::cli::error_text(&e)));
        let json = summary(&out);
        assert_eq!(
            json["propagation"]["propagation"], "dynamics",
            "{}",
            json["propagation"]
        );
        let segments = json["segments"].as_array().unwrap();
        assert!(
            segments.iter().all(|s| s["ended_by"] != "gyro-silent"),
            "{kept_rows}: {segments:?}"
        );
        let turned = &json["normals_rotation"];
        assert!(
            turned.is_null() || turned["finding"] == false,
            "{kept_rows}: {turned}"
        );
    }
}
