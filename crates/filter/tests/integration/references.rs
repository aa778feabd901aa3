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

/// `SharedRows` (the rows an ensemble's passes share) gives every row the reference and the
/// albedo view a pass computes alone, whatever the order the passes ask in (members a few
/// rows behind, a probe going back, rows long evicted), and computes the initial scales once.
#[test]
fn shared_rows_give_each_row_what_a_pass_computes_alone() {
    use pdcal_albedo::{AlbedoIrradiance, AlbedoModel, AlbedoView, MapChoice};
    use pdcal_ephem::Reference;
    use pdcal_filter::shared_rows::SharedRows;

    let mut scenario = pdcal_sim::Scenario::rax2_like().unwrap();
    scenario.duration_s = 40.0;
    let sim = pdcal_sim::simulate(&scenario, 4).unwrap();
    let model = reference_model(&sim.meta, &sim.telemetry).unwrap();
    let albedo = AlbedoModel::from_choice(&MapChoice::TomsMean1p25x1).unwrap();
    // Normals in GCRF: nadir, and 60 deg from it.
    let normals = |r: &Reference| {
        let nadir = -r.r_gcrf_km.normalize();
        let side = nadir.cross(&r.sun_gcrf_unit).normalize();
        [nadir, (nadir + side * 3f64.sqrt()).normalize()]
    };
    let alone = |r: &Reference| {
        let mut view = AlbedoView::new();
        albedo
            .compute_into(&mut view, &r.r_gcrf_km, &r.sun_gcrf_km, &r.gcrf_to_itrf)
            .unwrap();
        normals(r).map(|n| view.ratio_and_vector(&n, 0.0))
    };
    // Forty rows a second apart from the first time of the orbit whose nadir sees a lit
    // Earth, so that the views compared are not all zero.
    let lit_s = (0..60)
        .map(|k| 100.0 * f64::from(k))
        .find(|&t| alone(&model.at(t).unwrap())[0].0 > 0.05)
        .expect("a lit Earth below within 100 minutes");
    let t_s: Vec<f64> = (0..40).map(|k| lit_s + f64::from(k)).collect();
    let computed = References::Computed {
        model: &model,
        t_s: &t_s,
    };
    let stored: Vec<Reference> = t_s.iter().map(|&t| model.at(t).unwrap()).collect();
    let n = stored.len();
    let shared = SharedRows::new();
    // Two passes in step, one a few rows behind, then back to the start and forward again.
    let order = (0..n)
        .flat_map(|k| [k, k, k.saturating_sub(3)])
        .chain((0..n).rev())
        .chain(0..n);
    let mut held = Vec::new();
    for k in order {
        let reference = shared.reference(&computed, k).unwrap();
        assert_eq!(reference, stored[k], "row {k}");
        let view = shared.albedo(&reference, &albedo, k).unwrap();
        assert_eq!(
            normals(&stored[k]).map(|n| view.ratio_and_vector(&n, 0.0)),
            alone(&stored[k]),
            "row {k}"
        );
        // A view still read by a pass is never refilled under it.
        held.push((k, view));
        if held.len() > 12 {
            let (j, old) = held.remove(0);
            assert_eq!(
                normals(&stored[j]).map(|n| old.ratio_and_vector(&n, 0.0)),
                alone(&stored[j]),
                "row {j}"
            );
        }
    }
    let sim_references = References::Computed {
        model: &model,
        t_s: &sim.telemetry.t_s,
    };
    let scales = || pdcal_filter::init::initial_scales(&sim.telemetry, &sim_references, 0.01);
    let mut calls = 0;
    for _ in 0..3 {
        let initial = shared
            .initial_scales(|| {
                calls += 1;
                scales()
            })
            .unwrap();
        assert_eq!(initial, scales().unwrap());
    }
    assert_eq!(calls, 1);
}
