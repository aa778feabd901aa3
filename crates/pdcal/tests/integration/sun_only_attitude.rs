//! Photodiode-only mode: the Sun is the only vector, so the rotation about the Sun line is
//! unobserved. Its sigma must grow with what the gyro lets it do and stay large; an error
//! about the Sun line of tens of degrees must lie inside its 3 sigma, as must the error
//! across it (the part the photodiodes see). Simulated rax2-like data, against the truth.

use pdcal::calibrate::{RunConfig, albedo_model};
use pdcal::sim_calibrate::run_seed;
use pdcal_filter::Mode;

#[test]
fn attitude_errors_about_and_across_the_sun_line_lie_inside_three_sigma() {
    let mut scenario = pdcal_sim::Scenario::rax2_like().unwrap();
    // Sunlight from about 24 min: 36 min of lit rows.
    scenario.duration_s = 3600.0;
    let config = RunConfig {
        mode: Mode::PhotodiodeOnly,
        ..RunConfig::default()
    };
    let albedo = albedo_model().unwrap();
    for seed in [1, 3] {
        let r = run_seed(&scenario, seed, &config, &albedo, (None, 1))
            .unwrap()
            .result;
        eprintln!(
            "seed {seed}: about {:.4}, across {:.4}, segments {:?}",
            r.attitude_about_sun_inside, r.attitude_across_sun_inside, r.segments
        );
        // The acceptance is 99.7 +- 0.5 % over 20 seeds of two hours; one short run is
        // allowed a little more scatter. Without the reset's rotation of the attitude error
        // frame, seed 3 has its error about the Sun line inside 3 sigma never, across it a third
        // of the time.
        assert!(r.attitude_about_sun_inside >= 0.98, "seed {seed}: {r:?}");
        assert!(r.attitude_across_sun_inside >= 0.98, "seed {seed}: {r:?}");
        assert_eq!(r.segments.1, 0, "no attitude loss: {r:?}");
    }
}
