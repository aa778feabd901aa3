//! The dynamics-aided propagation's switches: what is missing is said before the filter
//! runs, `dynamics: Auto` with a gyro whose samples carry the rate is the gyro-driven filter
//! bit for bit, and with one whose rate curves between samples it runs the dynamics.

use crate::common;

use common::Case;
use pdcal_dataset::Inertia;
use pdcal_filter::{
    Dynamics, FilterConfig, FilterError, Mode, PropagationKind, PropagationReason, RunInputs,
    calibrate,
};

fn config(dynamics: Dynamics) -> FilterConfig {
    FilterConfig {
        smoother: false,
        dynamics,
        ..FilterConfig::default()
    }
}

const RAX2_INERTIA: Inertia = Inertia {
    xx: 0.0314,
    yy: 0.0314,
    zz: 0.005,
    xy: 0.0,
    xz: 0.0,
    yz: 0.0,
};

#[test]
fn without_gyro_and_inertia_the_error_names_both() {
    let (meta, mut tel, refs, _) = Case::rax2(3, 120).build();
    tel.gyro_rad_s = std::iter::repeat_n(None, tel.len()).collect();
    let inputs = RunInputs {
        meta: &meta,
        telemetry: &tel,
        references: (&refs).into(),
        albedo: None,
        set_first_rows: &[],
    };
    let err = calibrate(&inputs, &config(Dynamics::Auto), &Mode::Full).unwrap_err();
    let FilterError::Missing(text) = &err else {
        panic!("{err}");
    };
    assert!(
        text.contains("no gyro sample") && text.contains("inertia_kg_m2"),
        "{text}"
    );
}

#[test]
fn dynamics_on_without_inertia_asks_for_it() {
    let (meta, tel, refs, _) = Case::rax2(3, 120).build();
    let inputs = RunInputs {
        meta: &meta,
        telemetry: &tel,
        references: (&refs).into(),
        albedo: None,
        set_first_rows: &[],
    };
    let err = calibrate(&inputs, &config(Dynamics::On), &Mode::Full).unwrap_err();
    assert!(err.to_string().contains("add inertia_kg_m2"), "{err}");
}

#[test]
fn auto_with_a_1_hz_gyro_is_the_gyro_driven_filter() {
    let (mut meta, tel, refs, _) = Case::rax2(5, 600).build();
    meta.inertia_kg_m2 = Some(RAX2_INERTIA);
    let run = |dynamics| {
        let inputs = RunInputs {
            meta: &meta,
            telemetry: &tel,
            references: (&refs).into(),
            albedo: None,
            set_first_rows: &[],
        };
        calibrate(&inputs, &config(dynamics), &Mode::Full).expect("runs")
    };
    let (auto, off, on) = (run(Dynamics::Auto), run(Dynamics::Off), run(Dynamics::On));
    assert_eq!(auto.calibration, off.calibration);
    // With dynamics the rate is a state: a different filter, still a calibration.
    assert_ne!(on.calibration, off.calibration);
    assert!(
        on.calibration
            .photodiodes
            .iter()
            .all(|p| p.scale_v.is_finite())
    );
}

/// The propagation `dynamics: Auto` picks for `case` with the inertia given.
fn auto_choice(case: &Case) -> pdcal_filter::PropagationChoice {
    let (mut meta, tel, refs, _) = case.build();
    meta.inertia_kg_m2 = Some(RAX2_INERTIA);
    let inputs = RunInputs {
        meta: &meta,
        telemetry: &tel,
        references: (&refs).into(),
        albedo: None,
        set_first_rows: &[],
    };
    calibrate(&inputs, &config(Dynamics::Auto), &Mode::Full)
        .expect("runs")
        .propagation
}

#[test]
fn auto_runs_the_dynamics_when_the_rate_curves_between_gyro_samples() {
    // The rate (3.6 deg/s across z) turns at 1.5 deg/s about z. At 1 Hz its change is
    // nearly linear over a sample and the interpolated gyro carries it; every 10 s the
    // middle sample's residual is its curvature, 0.063 x 0.026^2 x 10^2 / 2 = 2.1e-3
    // rad/s, twice the residual's noise (1.07e-3 per axis): chi-square per dof near 2.3.
    let fast = auto_choice(&Case::rax2(5, 600));
    assert_eq!(fast.propagation, PropagationKind::Gyro, "{fast:?}");
    assert_eq!(fast.reason, PropagationReason::RateCarried);
    let test = fast.gyro_rate_test.expect("tested");
    assert_eq!(test.residuals, 200);
    let slow = auto_choice(&Case {
        dt_s: 10.0,
        ..Case::rax2(5, 120)
    });
    assert_eq!(slow.propagation, PropagationKind::Dynamics, "{slow:?}");
    assert_eq!(slow.reason, PropagationReason::RateChanges);
    let chi = slow.gyro_rate_test.expect("tested").chi_square_per_dof;
    assert!((1.8..3.0).contains(&chi), "{chi}");
}

#[test]
fn auto_keeps_the_gyro_on_a_slow_tumble_sampled_slowly() {
    // 0.5 deg/s turning at 0.1 deg/s, a gyro every 5 s: the rate's curvature between
    // samples is far below the noise, as on the pyramid head of docs/validation.md.
    let choice = auto_choice(&Case {
        dt_s: 5.0,
        rate_rad_s: nalgebra::Vector3::new(0.3, -0.3, 0.25).map(f64::to_radians),
        precession_rad_s: 0.1f64.to_radians(),
        ..Case::rax2(5, 240)
    });
    assert_eq!(choice.propagation, PropagationKind::Gyro, "{choice:?}");
    assert_eq!(choice.reason, PropagationReason::RateCarried);
}
