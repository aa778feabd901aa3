//! Model invariants: output zero with the Sun behind a photodiode, the sum of the terms is the
//! output, run-time editing of the component list and its parameter layout.

use crate::common;

use common::*;
use pdcal_photodiode::*;

fn everything(pds: Vec<Photodiode>) -> MeasurementModel {
    let n = pds.len();
    let mut model = MeasurementModel::paper(pds);
    model
        .add_term(FovRolloff::from_deg(60.0, 88.0).unwrap())
        .unwrap();
    model.add_term(DarkOffset::new(&vec![0.02; n])).unwrap();
    model.add_term(Penumbra).unwrap();
    model.add_term(TimeOffset::new(0.5)).unwrap();
    model.add_gain(ScaleDrift::shared(0.02)).unwrap();
    model
}

#[test]
fn output_is_zero_when_the_sun_is_behind_the_photodiode() {
    // Every sun-derived term, without albedo or offsets, must give exactly zero for n^T s <= 0.
    for_states(
        21,
        STATES,
        |s| s.cos_sun() <= 0.0,
        |s| {
            let mut model = MeasurementModel::cosine(vec![s.pd]);
            model
                .add_term(FovRolloff::from_deg(50.0, 80.0).unwrap())
                .unwrap();
            model.add_term(Penumbra).unwrap();
            model.add_term(TimeOffset::new(1.5)).unwrap();
            model.add_gain(ScaleDrift::shared(0.05)).unwrap();
            let scene = Scene {
                albedo: None,
                ..s.scene()
            };
            assert_eq!(model.evaluate(0, &scene).unwrap(), 0.0);
            let p = model.partials(0, &scene).unwrap();
            assert_eq!(p.value_v, 0.0);
            assert_eq!(
                p.d_attitude.norm() + p.d_normal.norm() + p.d_scale.abs(),
                0.0
            );
        },
    );
}

#[test]
fn output_is_zero_outside_the_field_of_view() {
    for_states(
        22,
        STATES,
        |s| s.cos_sun() > 0.0 && s.cos_sun() < 0.5,
        |s| {
            let pd = s.pd.with_fov_half_angle_rad(Some(60f64.to_radians()));
            let model = MeasurementModel::cosine(vec![pd]);
            assert_eq!(model.evaluate(0, &s.scene()).unwrap(), 0.0);
        },
    );
}

#[test]
fn hard_shadow_switches_at_half_and_penumbra_scales() {
    let pd = Photodiode::from_az_el_deg(3.6, 0.0, 0.0, 0.015);
    let sun = nalgebra::Vector3::new(1.0, 0.0, 0.0);
    let scene = Scene::new(nalgebra::Matrix3::identity(), &sun).unwrap();
    let hard = MeasurementModel::cosine(vec![pd]);
    let mut corrected = MeasurementModel::cosine(vec![pd]);
    corrected.add_term(Penumbra).unwrap();
    let mut soft = MeasurementModel::new(vec![pd]);
    soft.add_term(DirectSun {
        shadow: ShadowMode::Penumbra,
    })
    .unwrap();
    for f in [0.0, 0.3, 0.5, 0.51, 0.9, 1.0] {
        let sc = scene.with_sun_fraction(f);
        let expect_hard = if f > 0.5 { 3.6 } else { 0.0 };
        assert_eq!(hard.evaluate(0, &sc).unwrap(), expect_hard);
        // Penumbra mode and hard + correction agree to rounding (one subtraction).
        assert!((soft.evaluate(0, &sc).unwrap() - 3.6 * f).abs() < 1e-15);
        assert!((corrected.evaluate(0, &sc).unwrap() - 3.6 * f).abs() < 1e-14);
    }
}

#[test]
fn sum_of_terms_equals_model_output() {
    for_states(
        23,
        STATES,
        |_| true,
        |s| {
            let model = everything(vec![s.pd, s.pd]);
            let scene = s.scene();
            let parts = model.contributions(1, &scene).unwrap();
            assert_eq!(parts.len(), 7 - 1, "terms only (the gain is not a term)");
            let sum: f64 = parts.iter().map(|(_, v)| v).sum();
            let out = model.evaluate(1, &scene).unwrap();
            // Same additions in the same order: equal to rounding of a 6-term sum.
            assert!(
                (sum - out).abs() <= 1e-14 * out.abs().max(1.0),
                "{sum} vs {out}"
            );
            let via_partials = model.partials(1, &scene).unwrap().value_v;
            assert!((via_partials - out).abs() <= 1e-14 * out.abs().max(1.0));
        },
    );
}

#[test]
fn dark_offset_present_in_eclipse() {
    for_states(
        24,
        10,
        |_| true,
        |s| {
            let mut model = MeasurementModel::cosine(vec![s.pd]);
            model.add_term(DarkOffset::new(&[0.037])).unwrap();
            let scene = s.scene().with_sun_fraction(0.0);
            assert_eq!(model.evaluate(0, &scene).unwrap(), 0.037);
        },
    );
}

#[test]
fn saturation_clips_the_sum() {
    let pd = Photodiode::from_az_el_deg(3.6, 0.0, 0.0, 0.015);
    let sun = nalgebra::Vector3::new(1.0, 0.0, 0.0);
    let scene = Scene::new(nalgebra::Matrix3::identity(), &sun).unwrap();
    let mut model = MeasurementModel::cosine(vec![pd]);
    model.add_term(DarkOffset::new(&[0.1])).unwrap();
    model.add_stage(Saturation::shared(3.5)).unwrap();
    assert_eq!(model.pre_stage_output(0, &scene).unwrap(), 3.7);
    assert_eq!(model.evaluate(0, &scene).unwrap(), 3.5);
    let p = model.partials(0, &scene).unwrap();
    assert_eq!((p.d_scale, p.d_attitude.norm()), (0.0, 0.0));
    assert_eq!(p.d_parameters, vec![0.0, 1.0]);
}

#[test]
fn components_are_added_and_removed_by_id() {
    let pds = vec![Photodiode::from_az_el_deg(3.6, 0.0, 0.0, 0.015); 2];
    let mut model = everything(pds);
    assert_eq!(
        model
            .ids()
            .iter()
            .map(|id| id.to_string())
            .collect::<Vec<_>>(),
        [
            "sun",
            "albedo",
            "fov-rolloff",
            "dark-offset",
            "penumbra",
            "time-offset",
            "scale-drift"
        ]
    );
    assert_eq!(model.ids()[0], ComponentId::Sun);
    assert_eq!(
        model.add_term(Penumbra),
        Err(PhotodiodeError::DuplicateComponent {
            id: "penumbra".into()
        })
    );
    assert_eq!(
        model.add_stage(Saturation::per_photodiode(&[3.0, 3.0, 3.0])),
        Err(PhotodiodeError::PhotodiodeIndex { index: 2, count: 2 })
    );
    let names: Vec<_> = model.parameters().map(|(_, p)| p.name.clone()).collect();
    assert_eq!(
        names,
        [
            "fov_rolloff_start_rad",
            "fov_rolloff_cutoff_rad",
            "pd01_dark_offset_V",
            "pd02_dark_offset_V",
            "time_offset_s",
            "scale_drift_per_h"
        ]
    );
    assert_eq!(
        model.parameter_index(EffectId::DarkOffset, "pd02_dark_offset_V"),
        Some(3)
    );
    model.set_parameter(3, 0.5).unwrap();
    assert_eq!(model.parameters().nth(3).unwrap().1.value, 0.5);
    assert!(model.remove(EffectId::DarkOffset).is_ok());
    assert_eq!(
        model.parameter_index(EffectId::TimeOffset, "time_offset_s"),
        Some(2)
    );
    assert!(matches!(
        model.remove(EffectId::DarkOffset),
        Err(PhotodiodeError::UnknownComponent { .. })
    ));
    assert!(matches!(
        model.set_parameter(9, 1.0),
        Err(PhotodiodeError::ParameterIndex { index: 9, count: 4 })
    ));
    assert!(matches!(
        model.evaluate(
            5,
            &Scene::new(nalgebra::Matrix3::identity(), &nalgebra::Vector3::x()).unwrap()
        ),
        Err(PhotodiodeError::PhotodiodeIndex { index: 5, count: 2 })
    ));
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    assert!(Scene::new(nalgebra::Matrix3::identity(), &nalgebra::Vector3::zeros()).is_err());
    assert!(Photodiode::new(3.0, nalgebra::Vector3::new(f64::NAN, 0.0, 1.0), 0.01).is_err());
    assert!(FovRolloff::from_deg(70.0, 60.0).is_err());
    assert!(FovRolloff::from_deg(-1.0, 60.0).is_err());
    assert!(FovRolloff::from_deg(10.0, 91.0).is_err());
}

#[test]
fn degree_and_radian_constructors_agree() {
    let a = Photodiode::from_az_el_deg(3.5, 17.0, -10.0, 0.015);
    let b = Photodiode::from_az_el_rad(3.5, 17f64.to_radians(), (-10f64).to_radians(), 0.015);
    assert_eq!(a, b);
    let (az, el) = a.az_el_rad();
    assert!((az - 17f64.to_radians()).abs() < 1e-15 && (el + 10f64.to_radians()).abs() < 1e-15);
    assert!((a.n_body.norm() - 1.0).abs() < 1e-15);
}
