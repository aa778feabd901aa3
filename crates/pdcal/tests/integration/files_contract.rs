//! The file contracts of `docs/dataset-format.md` and `docs/cli-contract.md`, end to end:
//! simulate -> read gives identical numbers, the same seed gives byte-identical files, a
//! different seed different noise, and the output files carry the contract's keys.

use std::path::Path;

use pdcal_sim::Scenario;

/// The default scenario cut to `minutes` (the RAX-2-like set starts in eclipse and enters
/// sunlight at about 24 min).
fn short_rax2(minutes: f64) -> Scenario {
    let mut s = Scenario::rax2_like().unwrap();
    s.duration_s = minutes * 60.0;
    s
}

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .map(|e| {
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    out.sort();
    out
}

#[test]
fn simulate_read_round_trip_and_seeds() {
    let tmp = tempfile::tempdir().unwrap();
    let scenario = short_rax2(5.0);
    let (a, b, c) = (
        tmp.path().join("a"),
        tmp.path().join("b"),
        tmp.path().join("c"),
    );
    let sim = pdcal::simulate::run_to_dir(&scenario, 3, &a).unwrap();
    pdcal::simulate::run_to_dir(&scenario, 3, &b).unwrap();
    pdcal::simulate::run_to_dir(&scenario, 4, &c).unwrap();

    let names: Vec<String> = files(&a).into_iter().map(|(n, _)| n).collect();
    assert_eq!(
        names,
        [
            ".pdcal-manifest.json",
            "dataset.ron",
            "telemetry.csv",
            "truth.csv",
            "truth.ron"
        ]
    );
    assert_eq!(files(&a), files(&b), "same seed, same bytes");
    let telemetry = |d: &Path| std::fs::read(d.join("telemetry.csv")).unwrap();
    assert_ne!(telemetry(&a), telemetry(&c), "another seed, other noise");

    let read = pdcal_dataset::read_dataset(&a).unwrap();
    assert_eq!(
        read,
        sim.to_dataset(),
        "reading gives the simulated numbers bit for bit"
    );
}

fn keys(value: &serde_json::Value) -> Vec<String> {
    value.as_object().unwrap().keys().cloned().collect()
}

/// Snapshot of the contract's keys from a tiny seeded run: these names are a contract with
/// users' scripts (cli-contract.md), so a rename must fail here.
#[test]
fn calibrate_and_evaluate_outputs_carry_the_contract_keys() {
    let tmp = tempfile::tempdir().unwrap();
    let (dataset, out) = (tmp.path().join("set"), tmp.path().join("out"));
    pdcal::simulate::run_to_dir(&short_rax2(40.0), 5, &dataset).unwrap();
    pdcal::calibrate::run_dir(&dataset, &out, &pdcal::calibrate::RunConfig::default()).unwrap();
    pdcal::evaluate::run_dir(&dataset, &out).unwrap();

    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    for key in [
        "format_version",
        "dataset",
        "photodiodes",
        "gyro_bias_rad_s",
        "sun_vector_magnitude",
        "sun_direction_change_deg",
        "residuals",
        "runtime_s",
    ] {
        assert!(summary.get(key).is_some(), "summary.json lacks {key}");
    }
    let pd = &summary["photodiodes"][0];
    for key in [
        "index",
        "scale_V",
        "scale_sigma_V",
        "azimuth_deg",
        "azimuth_sigma_deg",
        "elevation_deg",
        "elevation_sigma_deg",
        "initial",
    ] {
        assert!(pd.get(key).is_some(), "summary.json photodiode lacks {key}");
    }
    assert_eq!(
        keys(&pd["initial"]),
        ["azimuth_deg", "elevation_deg", "scale_V"]
    );
    assert!(
        keys(&summary["sun_vector_magnitude"])
            .starts_with(&["calibrated".to_string(), "initial".to_string()])
    );
    for key in ["photodiode_rms_V", "fraction_within_3sigma"] {
        assert!(
            summary["residuals"].get(key).is_some(),
            "summary.json residuals lack {key}"
        );
    }

    let header = std::fs::read_to_string(out.join("estimates.csv")).unwrap();
    let header = header.lines().next().unwrap();
    assert!(header.starts_with(
        "t_s,q_x,q_y,q_z,q_w,att_sigma_x_deg,att_sigma_y_deg,att_sigma_z_deg,gyro_bias_x_rad_s,gyro_bias_y_rad_s,gyro_bias_z_rad_s,gyro_bias_sigma_x_rad_s"
    ));
    assert!(header.contains("pd01_scale_V,pd01_scale_sigma_V,pd01_azimuth_deg,pd01_azimuth_sigma_deg,pd01_elevation_deg,pd01_elevation_sigma_deg"));
    let residuals = std::fs::read_to_string(out.join("residuals.csv")).unwrap();
    assert!(residuals.starts_with("t_s,sensor,measured,residual,bound_3sigma,accepted"));

    let evaluation: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("evaluation.json")).unwrap()).unwrap();
    for key in ["photodiodes", "attitude", "consistency"] {
        assert!(evaluation.get(key).is_some(), "evaluation.json lacks {key}");
    }
    for key in ["scale_error_V", "scale_error_percent", "normal_error_deg"] {
        assert!(
            evaluation["photodiodes"][0].get(key).is_some(),
            "evaluation.json photodiode lacks {key}"
        );
    }
    // The smoother's attitude, from estimates_smoothed.csv, on the same samples.
    let smoothed = &evaluation["smoothed"];
    assert_eq!(
        smoothed["attitude"]["samples"],
        evaluation["attitude"]["samples"]
    );
    for key in [
        "attitude_within_3sigma",
        "attitude_about_sun_within_3sigma",
        "attitude_across_sun_within_3sigma",
    ] {
        let x = smoothed[key].as_f64();
        assert!(
            x.is_some_and(|x| (0.0..=1.0).contains(&x)),
            "evaluation.json smoothed.{key}: {x:?}"
        );
    }
    for name in [
        "fig04_residuals.png",
        "fig05_scale.svg",
        "fig12_attitude_sigma.png",
        "index.html",
        "calibration.ron",
    ] {
        assert!(out.join(name).is_file(), "{name} missing");
    }
    // index.html opens with the result: a row per photodiode, then the segments, then
    // the summary and the figures.
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    let at = |s: &str| {
        html.find(s)
            .unwrap_or_else(|| panic!("index.html lacks {s}"))
    };
    assert!(at("<h2>Photodiodes") < at("<h2>Segments") && at("<h2>Segments") < at("<h2>Summary"));
    assert!(at("<h2>Summary") < at("<h2>Figures"));
    let m = summary["photodiodes"].as_array().unwrap().len();
    for i in 1..=m {
        at(&format!("<td>pd{i:02}</td>"));
    }
    for key in ["normal_change_deg", "scale_change_percent", "time_used_min"] {
        assert!(pd.get(key).is_some(), "summary.json photodiode lacks {key}");
    }
    assert!(
        summary["segments"]
            .as_array()
            .is_some_and(|s| !s.is_empty())
    );
    assert!(summary["segment_rules"]["gap_threshold_s"].is_f64());
    // Where the first acquisition's gyro bias came from, and each segment's.
    let initial_bias = &summary["initial_bias"];
    assert_eq!(
        keys(initial_bias),
        [
            "bias_deg_s",
            "directions",
            "reason",
            "sigma_deg_s",
            "source",
            "span_s",
            "vectors"
        ]
    );
    let source = initial_bias["source"].as_str().unwrap();
    assert!(source == "fit" || source == "prior", "{source}");
    assert_eq!(initial_bias["reason"].is_null(), source == "fit");
    assert_eq!(initial_bias["sigma_deg_s"].as_array().unwrap().len(), 3);
    assert!(summary["segments"][0].get("initial_bias").is_some());
}

/// Outputs are written whole or not at all: a failing calibration leaves no directory.
#[test]
fn a_failed_calibration_leaves_nothing_behind() {
    let tmp = tempfile::tempdir().unwrap();
    let (dataset, out) = (tmp.path().join("set"), tmp.path().join("out"));
    pdcal::simulate::run_to_dir(&short_rax2(5.0), 6, &dataset).unwrap();
    // Corrupt one number: the reader must name the place and nothing may be written.
    let path = dataset.join("telemetry.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut cells: Vec<&str> = lines[3].split(',').collect();
    cells[1] = "abc";
    lines[3] = cells.join(",");
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    let Err(err) =
        pdcal::calibrate::run_dir(&dataset, &out, &pdcal::calibrate::RunConfig::default())
    else {
        panic!("a corrupt telemetry.csv must be refused");
    };
    let message = format!("{err:#}");
    assert!(message.contains("telemetry.csv:4:2"), "{message}");
    assert!(!out.exists());
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(
        leftovers.len(),
        1,
        "only the dataset remains: {leftovers:?}"
    );
}
