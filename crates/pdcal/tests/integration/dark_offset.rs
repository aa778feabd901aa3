//! A constant added to one photodiode's output (a dark current, an ADC offset): in full
//! Sun its scale factor takes it up and its residuals stay at the noise, so the residual
//! statistics alone call the run consistent while the scale factor lies many of its sigmas
//! from the truth (a hostile run: +50 mV on a 3.7 V channel, 9.8 sigma). In the umbra no
//! light reaches it and the model predicts nothing: `calibrate` and `diagnose` read the
//! offset there and give one verdict, `inconsistent`, naming the photodiode; the clean data
//! stay `consistent` with no significant umbra level.

use pdcal::calibrate::RunConfig;
use pdcal_diagnose::BaseModel;
use pdcal_sim::Scenario;

const OFFSET_V: f64 = 0.05;
const PD: usize = 6;

#[test]
fn an_offset_read_in_the_umbra_makes_the_run_inconsistent_in_calibrate_and_diagnose() {
    let tmp = tempfile::tempdir().unwrap();
    let mut scenario = Scenario::rax2_like().unwrap();
    // Umbra for the first 24 min, then 16 min of Sun.
    scenario.duration_s = 2400.0;
    let clean = tmp.path().join("clean");
    let sim = pdcal::simulate::run_to_dir(&scenario, 3, &clean).unwrap();
    let true_scale_v = sim.true_photodiodes[PD].scale_v;
    let mut ds = pdcal_dataset::read_dataset(&clean).unwrap();
    ds.telemetry.pd_v[PD]
        .values_mut()
        .for_each(|v| *v += OFFSET_V);
    let offset = tmp.path().join("offset");
    pdcal_dataset::write_dataset(&offset, &ds).unwrap();

    for (dataset, expected) in [(&clean, "consistent"), (&offset, "inconsistent")] {
        let out = tmp.path().join(format!("cal-{expected}"));
        let (_, summary) =
            pdcal::calibrate::run_dirs(std::slice::from_ref(dataset), &out, &RunConfig::default())
                .unwrap();
        let summary = serde_json::to_value(&summary).unwrap();
        let c = &summary["consistency"];
        assert_eq!(c["verdict"], expected, "{c}");
        let level = &c["dark"][PD];
        assert_eq!(level["channel"], "pd07", "{level}");
        let median = level["median_v"].as_f64().unwrap();
        let pd = &summary["photodiodes"][PD];
        if expected == "inconsistent" {
            assert!((median - OFFSET_V).abs() < 0.005, "{level}");
            assert!(c["reasons"].to_string().contains("pd07: a median"), "{c}");
            // The offset moved the scale factor beyond its sigma; it is no calibration.
            let scale = pd["scale_V"].as_f64().unwrap();
            let sigma = pd["scale_sigma_V"].as_f64().unwrap();
            assert!((scale - true_scale_v).abs() > 3.0 * sigma, "{pd}");
            assert_ne!(pd["status"], "calibrated", "{pd}");
        } else {
            let levels = c["dark"].as_array().unwrap();
            assert!(levels.iter().all(|l| l["significant"] == false), "{c}");
        }

        let d = pdcal_dataset::read_dataset(dataset).unwrap();
        let outcome = pdcal::diagnose::run(&d.meta, &d.telemetry, BaseModel::Paper).unwrap();
        let diagnosis = serde_json::to_value(outcome.diagnosis.summary()).unwrap();
        let base = &diagnosis["base_consistency"];
        assert_eq!(base["verdict"], expected, "{base}");
    }
}
