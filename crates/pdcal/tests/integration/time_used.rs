//! The time a photodiode's accepted updates stand for is its own cadence, not the rows':
//! with the gyro at 10 Hz and the photodiodes at 1 Hz (blank cells between), each accepted
//! photodiode update stands for a second, as on data at 1 Hz throughout. Counted per row,
//! it stood for a tenth, and six of seventeen photodiodes lit for many minutes were
//! demoted as "lit too little".

use pdcal::calibrate::RunConfig;

#[test]
fn an_update_stands_for_the_photodiodes_own_sample_period() {
    let tmp = tempfile::tempdir().unwrap();
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/scenarios/rates/rax2-like-gyro-10hz.ron"
    );
    let mut scenario = pdcal::simulate::load_scenario(path).unwrap();
    scenario.duration_s = 2400.0;
    let sim = pdcal::simulate::run(&scenario, 3).unwrap();
    let dir = pdcal::output::OutputDir::create(&tmp.path().join("out"), "calibrate").unwrap();
    let set = crate::common::downlink_set(sim, 0);
    let (outcome, _) =
        pdcal::calibrate::run_sets(vec![set], dir, &RunConfig::default(), None).unwrap();
    let run = &outcome.run;
    let mut checked = 0;
    for (i, used_s) in run.photodiode_time_used_s.iter().enumerate() {
        // The verdict's count of the photodiode's accepted updates.
        let updates = outcome.consistency.photodiodes[i].updates as f64;
        if updates < 60.0 {
            continue;
        }
        // One second per accepted update, less the first of each lit stretch (which
        // stands for the time since the photodiode's previous sample, one second too).
        assert!(
            (used_s - updates).abs() <= 0.02 * updates,
            "pd{:02}: {used_s:.1} s used for {updates} updates at 1 Hz",
            i + 1
        );
        checked += 1;
    }
    assert!(checked >= 5, "{checked} photodiodes lit a minute or more");
}
