//! The dynamics-aided propagation's switches: what is missing is said before the filter
//! runs, and `dynamics: Auto` with a 1 Hz gyro is the gyro-driven filter bit for bit.

mod common;

use common::Case;
use pdcal_dataset::Inertia;
use pdcal_filter::{Dynamics, FilterConfig, FilterError, Mode, RunInputs, calibrate};

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
    tel.gyro_rad_s.iter_mut().for_each(|g| *g = None);
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
