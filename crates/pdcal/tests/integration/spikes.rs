//! `pdcal calibrate` on a data set with one wild cell in a photodiode, the gyro and the
//! magnetometer: the run completes and `summary.json` lists each rejected sample with its
//! row; `pdcal diagnose` reads them as the filter does, screened.

use pdcal_sim::Scenario;

/// A 40-minute rax2-like set in `dataset` with one wild cell in the brightest photodiode
/// at row 2001, the gyro's z at row 2011 and the magnetometer's x at row 2021: the row and
/// the photodiode.
fn wild_set(dataset: &std::path::Path) -> (usize, usize) {
    let mut scenario = Scenario::rax2_like().unwrap();
    // Sunlight from about 24 min: row 2001 is lit.
    scenario.duration_s = 2400.0;
    pdcal::simulate::run_to_dir(&scenario, 2, dataset).unwrap();
    let mut ds = pdcal_dataset::read_dataset(dataset).unwrap();
    let row = 2001;
    let pd = (0..ds.telemetry.pd_v.len())
        .max_by(|&a, &b| {
            let v = |i: usize| ds.telemetry.pd_v[i].get(row).unwrap_or(0.0);
            v(a).total_cmp(&v(b))
        })
        .unwrap();
    ds.telemetry.pd_v[pd].set(row, Some(1e300));
    let mut gyro = ds.telemetry.gyro_rad_s.get(row + 10).unwrap();
    gyro.z = 1e300;
    ds.telemetry.gyro_rad_s.set(row + 10, Some(gyro));
    let mag = ds.telemetry.mag_nt.as_mut().unwrap();
    let mut field = mag.get(row + 20).unwrap();
    field.x = -1e6;
    mag.set(row + 20, Some(field));
    std::fs::remove_dir_all(dataset).unwrap();
    pdcal_dataset::write_dataset(dataset, &ds).unwrap();
    (row, pd)
}

#[test]
fn wild_cells_are_listed_with_their_rows_in_the_summary() {
    let tmp = tempfile::tempdir().unwrap();
    let (dataset, out) = (tmp.path().join("set"), tmp.path().join("out"));
    let (row, pd) = wild_set(&dataset);
    pdcal::calibrate::run_dir(&dataset, &out, &pdcal::calibrate::RunConfig::default()).unwrap();
    let summary: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    let rejected = summary["rejected_samples"].as_array().unwrap();
    let entry = |name: &str| {
        rejected
            .iter()
            .find(|e| e["sensor"] == name)
            .unwrap_or_else(|| panic!("no entry for {name}: {rejected:?}"))
    };
    let pd_name = format!("pd{:02}", pd + 1);
    for (name, at) in [
        (pd_name.as_str(), row),
        ("gyro", row + 10),
        ("mag", row + 20),
    ] {
        assert_eq!(entry(name)["screened"], 1, "{name}: {}", entry(name));
        assert_eq!(
            entry(name)["screened_rows"],
            serde_json::json!([at]),
            "{name}"
        );
    }
    let screened: u64 = rejected
        .iter()
        .map(|e| e["screened"].as_u64().unwrap())
        .sum();
    assert_eq!(screened, 3, "nothing else screened: {rejected:?}");
    assert_eq!(summary["covariance_repairs"]["count"], 0);
    // The calibrated photodiode is sane (its initial scale was not the wild cell).
    let scale = summary["photodiodes"][pd]["scale_V"].as_f64().unwrap();
    assert!(scale > 1.0 && scale < 10.0, "scale {scale}");
}

/// The diagnosis's residuals are those of the telemetry the filter read: the gyro sample
/// of 1e300 rad/s the screening removed is no attitude-rate residual.
#[test]
fn diagnose_reads_the_screened_telemetry() {
    let tmp = tempfile::tempdir().unwrap();
    let dataset = tmp.path().join("set");
    wild_set(&dataset);
    let ds = pdcal_dataset::read_dataset(&dataset).unwrap();
    let outcome =
        pdcal::diagnose::run(&ds.meta, &ds.telemetry, pdcal_diagnose::BaseModel::Paper).unwrap();
    let gap = &outcome.diagnosis.final_gap;
    assert!(
        gap.gyro_residual_rms_rad_s < 0.1,
        "attitude rate beyond gyro RMS {} rad/s",
        gap.gyro_residual_rms_rad_s
    );
}
