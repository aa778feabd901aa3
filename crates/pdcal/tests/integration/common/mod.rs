//! Helpers shared by the driver's integration tests.

/// Downlink `j` of the pyramid head of issue 20 as the Monte Carlo's `--sets` makes it (`j`
/// months after the first, seed `seed`), its magnetometer dropped (the flight set has
/// none): the Sun is the only vector.
pub fn pyramid_downlink(seed: u64, j: usize) -> pdcal_sim::SimOutput {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/scenarios/weak/pyramid-head.ron"
    );
    let scenario = pdcal::simulate::load_scenario(path).unwrap();
    let mut sim = pdcal::sim_calibrate::simulate_set(&scenario, seed, j, None).unwrap();
    sim.telemetry.mag_nt = None;
    sim
}

/// `sim` as the data set `downlink{j + 1}` of a joint calibration.
pub fn downlink_set(
    sim: pdcal_sim::SimOutput,
    j: usize,
) -> (
    std::path::PathBuf,
    pdcal_dataset::DatasetMeta,
    pdcal_dataset::Telemetry,
) {
    (format!("downlink{}", j + 1).into(), sim.meta, sim.telemetry)
}
