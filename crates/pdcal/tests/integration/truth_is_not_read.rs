//! `calibrate` and `diagnose` never open `truth.*`: a dataset carrying truth files another
//! tool wrote (another truth.csv layout, truth.ron with effects outside pdcal's catalogue)
//! gives the same outputs as the same dataset without them.

use std::path::Path;

use pdcal_diagnose::BaseModel;

fn read(dir: &Path, name: &str) -> Vec<u8> {
    std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{}: {e}", dir.join(name).display()))
}

#[test]
fn foreign_truth_files_change_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let mut scenario = pdcal_sim::Scenario::rax2_like().unwrap();
    // Past the first eclipse (about 24 min) into sunlight.
    scenario.duration_s = 45.0 * 60.0;
    let clean = tmp.path().join("clean");
    pdcal::simulate::run_to_dir(&scenario, 5, &clean).unwrap();
    std::fs::remove_file(clean.join("truth.csv")).unwrap();
    std::fs::remove_file(clean.join("truth.ron")).unwrap();

    let foreign = tmp.path().join("foreign");
    std::fs::create_dir(&foreign).unwrap();
    for name in ["dataset.ron", "telemetry.csv"] {
        std::fs::copy(clean.join(name), foreign.join(name)).unwrap();
    }
    std::fs::write(
        foreign.join("truth.csv"),
        "time_utc,quat_scalar_first_w,quat_x,sun_sensor_mask\n2020-01-01T00:00:00Z,1,0,0x1f\n",
    )
    .unwrap();
    std::fs::write(
        foreign.join("truth.ron"),
        "(photodiodes: [], effects: [CloudCover(fraction: 0.6), Albedo(map: \"my-own\")], \
         spacecraft: \"other tool\")\n",
    )
    .unwrap();
    assert!(
        pdcal_dataset::read_dataset(&foreign).is_err(),
        "the foreign truth must be unreadable for pdcal, or the test proves nothing"
    );

    let config = pdcal::calibrate::RunConfig::default();
    let (out_clean, out_foreign) = (tmp.path().join("cal_clean"), tmp.path().join("cal_foreign"));
    pdcal::calibrate::run_dir(&clean, &out_clean, &config).unwrap();
    pdcal::calibrate::run_dir(&foreign, &out_foreign, &config).unwrap();
    for name in ["calibration.ron", "estimates.csv", "residuals.csv"] {
        assert!(
            read(&out_clean, name) == read(&out_foreign, name),
            "{name} differs"
        );
    }

    let (d_clean, d_foreign) = (
        tmp.path().join("diag_clean"),
        tmp.path().join("diag_foreign"),
    );
    pdcal::diagnose::run_dir(&clean, &d_clean, BaseModel::Paper).unwrap();
    pdcal::diagnose::run_dir(&foreign, &d_foreign, BaseModel::Paper).unwrap();
    assert!(
        read(&d_clean, "diagnosis.json") == read(&d_foreign, "diagnosis.json"),
        "diagnosis.json differs"
    );
}
