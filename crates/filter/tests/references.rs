//! `step_references` from either orbit description of the dataset contract: a TLE, or
//! position columns (the same orbit written out), and the error without the columns.

use pdcal_dataset::OrbitSpec;
use pdcal_filter::{FilterError, References, reference_model, step_references};

#[test]
fn position_columns_give_the_tle_s_references() {
    let mut scenario = pdcal_sim::Scenario::rax2_like().unwrap();
    scenario.duration_s = 120.0;
    let sim = pdcal_sim::simulate(&scenario, 1).unwrap();
    assert!(matches!(sim.meta.orbit, OrbitSpec::Tle { .. }));
    let from_tle = step_references(&sim.meta, &sim.telemetry).unwrap();
    assert_eq!(from_tle.len(), sim.telemetry.t_s.len());

    // The same orbit as position columns: every row's position from the TLE.
    let mut meta = sim.meta.clone();
    meta.orbit = OrbitSpec::PositionColumns;
    let mut telemetry = sim.telemetry.clone();
    telemetry.r_gcrf_km = Some(from_tle.iter().map(|r| Some(r.r_gcrf_km)).collect());
    let from_columns = step_references(&meta, &telemetry).unwrap();
    for (a, b) in from_tle.iter().zip(&from_columns) {
        // At the sample times the interpolant passes through the samples: rounding only.
        assert!((a.r_gcrf_km - b.r_gcrf_km).norm() < 1e-9);
        assert!((a.sun_gcrf_unit - b.sun_gcrf_unit).norm() < 1e-12);
        assert!((a.b_gcrf_nt - b.b_gcrf_nt).norm() < 1e-6);
        assert_eq!(a.sun_fraction, b.sun_fraction);
        assert_eq!(a.gcrf_to_itrf, b.gcrf_to_itrf);
    }

    // Position columns named but absent: a typed error naming the missing columns.
    telemetry.r_gcrf_km = None;
    let err = step_references(&meta, &telemetry).unwrap_err();
    assert_eq!(err, FilterError::MissingPositionColumns);
    assert!(err.to_string().contains("r_x_km, r_y_km, r_z_km"), "{err}");
}

/// `References::Computed` gives every row the value `step_references` stores, in any order
/// of access (the smoother's replays go back), and an error past the last row.
#[test]
fn computed_references_equal_the_stored_ones() {
    let mut scenario = pdcal_sim::Scenario::rax2_like().unwrap();
    scenario.duration_s = 60.0;
    let sim = pdcal_sim::simulate(&scenario, 2).unwrap();
    let stored = step_references(&sim.meta, &sim.telemetry).unwrap();
    let model = reference_model(&sim.meta, &sim.telemetry).unwrap();
    let computed = References::Computed {
        model: &model,
        t_s: &sim.telemetry.t_s,
    };
    assert_eq!(computed.len(), stored.len());
    for k in (0..stored.len()).rev().chain(0..stored.len()) {
        assert_eq!(computed.at(k).unwrap(), stored[k], "row {k}");
    }
    let past = stored.len();
    assert!(matches!(
        computed.at(past),
        Err(FilterError::LengthMismatch { .. })
    ));
    assert!(matches!(
        References::from(&stored).at(past),
        Err(FilterError::LengthMismatch { .. })
    ));
}
