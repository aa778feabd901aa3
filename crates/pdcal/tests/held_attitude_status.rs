//! One downlink of the pyramid head of issue 20 (4 photodiodes 18 deg off +z, 5 s rows,
//! a turn-on gyro bias of up to 4 deg/s per axis, Sun only): the Sun stays 60 deg or more
//! from every normal, the maximum outputs are half the scale factors, and the filter ends
//! at an attitude tens of degrees off with its residuals `consistent`. Its attitude was
//! held (sigma across the Sun line within 5 deg) for under a minute, so no state it learnt
//! may be reported `calibrated`: against the simulator's truth, the states outside 3 sigma
//! are all `weakly-determined` or `not-determined`.

use pdcal::calibrate::{RunConfig, albedo_model};
use pdcal::sim_calibrate::run_seed;
use pdcal_filter::Mode;

#[test]
fn states_learnt_while_the_attitude_was_not_held_are_not_called_calibrated() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/scenarios/weak/pyramid-head.ron"
    );
    let scenario = pdcal::simulate::load_scenario(path).unwrap();
    let config = RunConfig {
        mode: Mode::PhotodiodeOnly,
        ..RunConfig::default()
    };
    let albedo = albedo_model().unwrap();
    let r = run_seed(&scenario, 6, &config, &albedo, (None, 1))
        .unwrap()
        .result;
    eprintln!("{:?} {:?}", r.verdict, r.by_status);
    // The residuals alone do not say it: the calibration's errors are absorbed.
    assert_eq!(r.verdict, "consistent", "{r:?}");
    let wrong =
        r.by_status.weakly_determined_outside_3sigma + r.by_status.not_determined_outside_3sigma;
    assert!(wrong >= 3, "{r:?}");
    assert_eq!(r.by_status.calibrated, 0, "{r:?}");
}
