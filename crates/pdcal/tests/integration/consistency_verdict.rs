//! The one consistency verdict: `calibrate` (summary.json) and `diagnose` (diagnosis.json's
//! first model, the same paper model) judge the same residuals alike. Residuals ten times
//! the declared noise are `inconsistent` in both, whatever the filter's bounds say; the
//! same data with the true noise declared are `consistent` in both.

use pdcal::calibrate::RunConfig;
use pdcal_diagnose::BaseModel;
use pdcal_sim::Scenario;

fn verdict(summary: &serde_json::Value) -> String {
    summary["consistency"]["verdict"]
        .as_str()
        .unwrap_or_else(|| panic!("no consistency verdict in {summary}"))
        .to_owned()
}

#[test]
fn calibrate_and_diagnose_give_one_verdict_on_residuals_beyond_the_noise() {
    let tmp = tempfile::tempdir().unwrap();
    let mut scenario = Scenario::rax2_like().unwrap();
    // Sunlight from about 24 min: 16 min of lit rows.
    scenario.duration_s = 2400.0;
    let clean = tmp.path().join("clean");
    pdcal::simulate::run_to_dir(&scenario, 3, &clean).unwrap();
    let mut ds = pdcal_dataset::read_dataset(&clean).unwrap();
    let true_noise_v = ds.meta.noise.as_ref().unwrap().photodiode_v.unwrap();
    // The same data, its photodiode noise declared ten times too small: the residuals
    // are then ten times the noise the model claims.
    ds.meta.noise.as_mut().unwrap().photodiode_v = Some(true_noise_v / 10.0);
    let wrong = tmp.path().join("wrong");
    pdcal_dataset::write_dataset(&wrong, &ds).unwrap();

    for (dataset, expected) in [(&clean, "consistent"), (&wrong, "inconsistent")] {
        let out = tmp.path().join(format!("cal-{expected}"));
        let (_, summary) =
            pdcal::calibrate::run_dirs(std::slice::from_ref(dataset), &out, &RunConfig::default())
                .unwrap();
        let summary = serde_json::to_value(&summary).unwrap();
        assert_eq!(verdict(&summary), expected, "{}", summary["consistency"]);
        let photodiode = &summary["consistency"]["sensors"][0];
        let ratio = photodiode["rms_over_noise"].as_f64().unwrap();
        if expected == "inconsistent" {
            assert!(ratio > 5.0, "RMS over the declared noise {ratio}");
            let reasons = summary["consistency"]["reasons"].to_string();
            assert!(reasons.contains("times the noise"), "{reasons}");
            // The quantities cannot be called calibrated on residuals the model denies.
            for pd in summary["photodiodes"].as_array().unwrap() {
                assert_ne!(pd["status"], "calibrated", "{pd}");
            }
        } else {
            assert!(ratio < 3.0, "RMS over the noise {ratio}");
        }

        let d = pdcal_dataset::read_dataset(dataset).unwrap();
        let outcome = pdcal::diagnose::run(&d.meta, &d.telemetry, BaseModel::Paper).unwrap();
        let diagnosis = serde_json::to_value(outcome.diagnosis.summary()).unwrap();
        assert_eq!(
            diagnosis["base_consistency"]["verdict"], expected,
            "{}",
            diagnosis["base_consistency"]
        );
        if expected == "inconsistent" {
            assert_eq!(diagnosis["consistency"]["verdict"], "inconsistent");
            let v = outcome.diagnosis.verdict();
            assert!(v.contains("unexplained"), "diagnose verdict {v}");
        }
    }
}
