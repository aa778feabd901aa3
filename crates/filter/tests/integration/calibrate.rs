//! End-to-end tests of the calibration run on synthetic data built here (no simulator).

use crate::common;

use common::{Case, angle_deg};
use nalgebra::{Matrix3, Vector3};
use pdcal_filter::smoother::tangent_log_in;
use pdcal_filter::{
    CalibrationRun, Channel, FilterConfig, Mode, ModeUsed, RunInputs, Sensor, calibrate,
};

fn run(case: &Case, config: &FilterConfig, mode: &Mode) -> CalibrationRun {
    let (meta, tel, refs, _) = case.build();
    let inputs = RunInputs {
        meta: &meta,
        telemetry: &tel,
        references: (&refs).into(),
        albedo: None,
        set_first_rows: &[],
    };
    calibrate(&inputs, config, mode).expect("calibration runs")
}

fn no_smoother() -> FilterConfig {
    FilterConfig {
        smoother: false,
        ..FilterConfig::default()
    }
}

/// Worst normal error (deg) and worst relative scale error over all photodiodes.
fn worst_errors(case: &Case, run: &CalibrationRun) -> (f64, f64) {
    let mut worst = (0.0f64, 0.0f64);
    for (i, pd) in run.calibration.photodiodes.iter().enumerate() {
        worst.0 = worst.0.max(angle_deg(&pd.n_body(), &case.true_normals[i]));
        worst.1 = worst.1.max((pd.scale_v / case.true_scales[i] - 1.0).abs());
    }
    worst
}

/// NEES of the calibration states [C, d1, d2] of every photodiode at the end of the run.
fn calibration_nees(case: &Case, run: &CalibrationRun) -> (f64, usize) {
    let layout = &run.layout;
    let p = &run.final_covariance;
    let mut nees = 0.0;
    let mut dof = 0;
    for (i, pd) in run.calibration.photodiodes.iter().enumerate() {
        let n = pd.n_body();
        let (d1, d2) = tangent_log_in(&n, &case.true_normals[i], &layout.tangent_basis(i, &n));
        let e = Vector3::new(case.true_scales[i] - pd.scale_v, d1, d2);
        let (s, d) = (layout.scale(i), layout.normal(i).expect("normal states"));
        let idx = [s, d, d + 1];
        let block = Matrix3::from_fn(|r, c| p[(idx[r], idx[c])]);
        nees += (e.transpose() * block.try_inverse().expect("invertible") * e)[0];
        dof += 3;
    }
    (nees, dof)
}

/// Wilson-Hilferty approximation of the chi-square quantile with `dof` degrees of freedom at
/// standard-normal quantile `z` (relative error below 1e-3 for dof > 50).
fn chi2_quantile(dof: usize, z: f64) -> f64 {
    let k = dof as f64;
    let c = 2.0 / (9.0 * k);
    k * (1.0 - c + z * c.sqrt()).powi(3)
}

#[test]
fn noisy_rax2_layout_converges_consistently() {
    let case = Case::rax2(1, 1200);
    let run = run(&case, &no_smoother(), &Mode::Full);
    assert_eq!(run.mode, ModeUsed::Full);
    let (normal_deg, scale) = worst_errors(&case, &run);
    eprintln!(
        "noisy: worst normal error {normal_deg:.3} deg, worst scale error {:.3} %",
        100.0 * scale
    );
    // Acceptance of the project: 0.5 deg and 1 % after 20 minutes of full-Sun tumbling
    // (observed 0.3 deg and 0.4 %).
    assert!(normal_deg < 0.5, "{normal_deg}");
    assert!(scale < 0.01, "{scale}");
    // Tuned with the paper's 50 W/m^2 albedo uncertainty on albedo-free data: conservative,
    // so almost every residual is inside its bound.
    let pd: Vec<_> = run
        .residuals
        .iter()
        .filter(|r| matches!(r.sensor, Sensor::Photodiode(_)))
        .collect();
    let inside = pd
        .iter()
        .filter(|r| r.residual.abs() <= r.bound_3sigma)
        .count() as f64
        / pd.len() as f64;
    assert!(inside > 0.99, "{inside}");
}

#[test]
fn noise_free_data_converges_to_truth() {
    let mut case = Case::rax2(2, 1800);
    case.pd_sigma_v = 0.0;
    case.mag_sigma_nt = 0.0;
    case.gyro_sigma_rad_s = 0.0;
    // The dataset hints are zero-noise; tune with the paper's values (R must stay above
    // the linearisation error while the initial errors are large).
    let config = FilterConfig {
        photodiode_sigma_v: Some(0.015),
        mag_sigma_nt: Some(320.0),
        gyro_sigma_rad_s: Some(1e-4),
        albedo_sigma_w_m2: 0.0,
        ..no_smoother()
    };
    let (meta, tel, refs, _) = case.build();
    let meta = pdcal_dataset::DatasetMeta {
        noise: None,
        inertia_kg_m2: None,
        ..meta
    };
    let inputs = RunInputs {
        meta: &meta,
        telemetry: &tel,
        references: (&refs).into(),
        albedo: None,
        set_first_rows: &[],
    };
    let run = calibrate(&inputs, &config, &Mode::Full).unwrap();
    let (normal_deg, scale) = worst_errors(&case, &run);
    eprintln!(
        "noise-free: worst normal error {normal_deg:.4} deg, worst scale error {:.4} %",
        100.0 * scale
    );
    // Without noise only the filter's own approximations remain: mostly the EKF's bias from
    // the first updates, linearised 10 deg away from the truth, which later data wash out
    // only slowly (observed 0.18 deg and 0.06 % after 30 minutes; 13 deg and 15 % at start).
    assert!(normal_deg < 0.25, "{normal_deg}");
    assert!(scale < 0.001, "{scale}");
}

#[test]
fn tilted_pole_photodiode_is_recovered() {
    let mut case = Case::rax2(3, 1200);
    // pd13 nominal at +90 deg elevation, truly tilted 5 deg towards azimuth 30 deg.
    let truth = pdcal_attitude::normal_from_az_el(30f64.to_radians(), 85f64.to_radians());
    case.true_normals[12] = truth;
    let run = run(&case, &no_smoother(), &Mode::Full);
    let pd = run.calibration.photodiodes[12];
    let err = angle_deg(&pd.n_body(), &truth);
    let n = pd.n_body();
    let (d1, d2) = tangent_log_in(&n, &truth, &run.layout.tangent_basis(12, &n));
    let d = run.layout.normal(12).unwrap();
    let p = &run.final_covariance;
    let cov = nalgebra::Matrix2::new(p[(d, d)], p[(d, d + 1)], p[(d + 1, d)], p[(d + 1, d + 1)]);
    let e = nalgebra::Vector2::new(d1, d2);
    let mahalanobis = (e.transpose() * cov.try_inverse().unwrap() * e)[0].sqrt();
    eprintln!(
        "pole: error {err:.3} deg, {mahalanobis:.2} sigma, az {:.2} (sigma {:?}) el {:.3}",
        pd.azimuth_deg, pd.azimuth_sigma_deg, pd.elevation_deg
    );
    assert!(err < 0.5, "{err}");
    assert!(mahalanobis < 3.0, "{mahalanobis}");
    // 5 deg off the pole, the azimuth is defined and close to the truth.
    assert!((pd.azimuth_deg - 30.0).abs() < 5.0);
    // pd14 (at the pole, untilted): its azimuth sigma is large or undefined, never small.
    let pole = run.calibration.photodiodes[13];
    assert!(
        pole.azimuth_sigma_deg.is_none_or(|s| s > 1.0),
        "{:?}",
        pole.azimuth_sigma_deg
    );
}

#[test]
fn calibration_nees_is_chi_square() {
    let config = FilterConfig {
        albedo_sigma_w_m2: 0.0,
        ..no_smoother()
    };
    let (mut nees, mut dof) = (0.0, 0);
    for seed in 10..14 {
        let case = Case::rax2(seed, 1500);
        let (n, d) = calibration_nees(&case, &run(&case, &config, &Mode::Full));
        eprintln!("seed {seed}: NEES {n:.1} / {d}");
        nees += n;
        dof += d;
    }
    // Two-sided 99 % interval of a chi-square with `dof` (= 4 runs x 51) degrees of freedom.
    let (lo, hi) = (chi2_quantile(dof, -2.576), chi2_quantile(dof, 2.576));
    eprintln!("NEES {nees:.1} over {dof} dof, 99 % interval [{lo:.1}, {hi:.1}]");
    assert!(nees > lo && nees < hi, "NEES {nees} outside [{lo}, {hi}]");
}

#[test]
fn gate_rejects_an_injected_outlier() {
    let case = Case::rax2(4, 400);
    let (meta, mut tel, refs, _) = case.build();
    // A 3 V spike on pd01 at a row where the photodiode is lit.
    let k = (300..400)
        .find(|&k| tel.pd_v[0].get(k).is_some_and(|v| v > 2.0))
        .expect("pd01 lit in the window");
    if let Some(v) = tel.pd_v[0].get_mut(k) {
        *v += 3.0;
    }
    let inputs = RunInputs {
        meta: &meta,
        telemetry: &tel,
        references: (&refs).into(),
        albedo: None,
        set_first_rows: &[],
    };
    // By default the screening against the neighbouring samples takes it out first.
    let run = calibrate(&inputs, &no_smoother(), &Mode::Full).unwrap();
    let pd01 = run.rejections.get(Channel::Photodiode(0)).unwrap();
    assert_eq!(pd01.screened.first, vec![k]);
    assert!(
        !run.residuals
            .iter()
            .any(|r| r.index == k && r.sensor == Sensor::Photodiode(0))
    );
    // With the screening out of the way, the innovation gate rejects it.
    let unscreened = FilterConfig {
        outlier_sigmas: 1e9,
        ..no_smoother()
    };
    let run = calibrate(&inputs, &unscreened, &Mode::Full).unwrap();
    assert_eq!(run.rejections.screened_total(), 0);
    let record = run
        .residuals
        .iter()
        .find(|r| r.index == k && r.sensor == Sensor::Photodiode(0))
        .expect("the spike was considered");
    assert!(!record.accepted, "{record:?}");
    assert!(run.counts.photodiode.gated >= 1);
    let gated = &run.rejections.get(Channel::Photodiode(0)).unwrap().gated;
    assert!(gated.first.contains(&k), "{gated:?}");
    // Nothing else of note is gated (5 sigma: probability 6e-7 per Gaussian innovation).
    assert!(run.counts.photodiode.gated <= 2, "{:?}", run.counts);
}

#[test]
fn scale_only_mode_uses_the_prior_normals() {
    let truth_case = Case::rax2(5, 900);
    let mut prior = run(&truth_case, &no_smoother(), &Mode::Full).calibration;
    // Second data set: same normals, scales degraded by 5 %.
    let mut case = truth_case.clone();
    case.seed = 6;
    for c in &mut case.true_scales {
        *c *= 0.95;
    }
    for pd in &mut prior.photodiodes {
        pd.azimuth_sigma_deg = pd.azimuth_sigma_deg.or(Some(0.0));
    }
    let run = run(
        &case,
        &no_smoother(),
        &Mode::ScaleOnly {
            prior: prior.clone(),
        },
    );
    assert_eq!(
        run.mode,
        ModeUsed::ScaleOnly {
            with_magnetometer: true
        }
    );
    assert_eq!(run.layout.len(), 6 + 17);
    for (i, pd) in run.calibration.photodiodes.iter().enumerate() {
        // Fixed normals: the prior's azimuth, to the rounding of az/el -> n -> az/el.
        assert!((pd.azimuth_deg - prior.photodiodes[i].azimuth_deg).abs() < 1e-9);
        let err = pd.scale_v - case.true_scales[i];
        // Within 3 sigma and 1 % (the prior normals are off by up to 0.3 deg).
        assert!(
            err.abs() < 3.0 * pd.scale_sigma_v + 0.005 * pd.scale_v,
            "pd{} {err}",
            i + 1
        );
        assert!((err / case.true_scales[i]).abs() < 0.01);
    }
}

#[test]
fn photodiode_only_mode_converges() {
    let case = Case::rax2(7, 1800);
    let mut config = no_smoother();
    config.smoother = false;
    let (meta, tel, refs, truth) = case.build();
    let tel = pdcal_dataset::Telemetry {
        mag_nt: None,
        ..tel
    };
    let inputs = RunInputs {
        meta: &meta,
        telemetry: &tel,
        references: (&refs).into(),
        albedo: None,
        set_first_rows: &[],
    };
    let run = calibrate(&inputs, &config, &Mode::Full).unwrap();
    assert_eq!(run.mode, ModeUsed::PhotodiodeOnly);
    let (normal_deg, scale) = worst_errors(&case, &run);
    // The Sun direction in the body frame is what the photodiodes see; its error is the
    // attitude error across the Sun line.
    let last = run.forward.last().unwrap();
    let sun = Case::sun_gcrf();
    let sun_err = angle_deg(&last.q.to_body(&sun), &truth[last.index].to_body(&sun));
    eprintln!(
        "photodiode-only: worst normal {normal_deg:.3} deg, worst scale {:.3} %, Sun direction {sun_err:.3} deg",
        100.0 * scale
    );
    // Observed: 0.4 deg, 0.6 %, 0.05 deg: as good as with the magnetometer for the
    // calibration (the gyro carries the geometry); the rotation about the Sun line stays
    // unobserved (its sigma stays large).
    assert!(normal_deg < 1.0 && scale < 0.01);
    assert!(sun_err < 0.5);
}

#[test]
fn smoother_is_no_worse_than_the_filter() {
    let case = Case::rax2(8, 900);
    let (meta, tel, refs, truth) = case.build();
    let inputs = RunInputs {
        meta: &meta,
        telemetry: &tel,
        references: (&refs).into(),
        albedo: None,
        set_first_rows: &[],
    };
    let run = calibrate(&inputs, &FilterConfig::default(), &Mode::Full).unwrap();
    let smoothed = run.smoothed.as_ref().unwrap();
    assert_eq!(smoothed.len(), run.forward.len());
    let rms = |v: &[pdcal_filter::StepEstimate]| {
        (v.iter()
            .map(|e| e.q.angle_to(&truth[e.index]).to_degrees().powi(2))
            .sum::<f64>()
            / v.len() as f64)
            .sqrt()
    };
    let (f, s) = (rms(&run.forward), rms(smoothed));
    // Smoothed calibration at the first row vs the filter's at the first row.
    let first_err = |e: &pdcal_filter::StepEstimate| {
        e.calibration
            .photodiodes
            .iter()
            .enumerate()
            .map(|(i, p)| angle_deg(&p.n_body(), &case.true_normals[i]))
            .fold(0.0, f64::max)
    };
    eprintln!(
        "attitude RMS: filter {f:.3} deg, smoother {s:.3} deg; worst normal at row 0: filter {:.2}, smoother {:.3}",
        first_err(&run.forward[0]),
        first_err(&smoothed[0])
    );
    assert!(s <= f, "{s} > {f}");
    // The last smoothed step is the filter's.
    assert_eq!(smoothed.last().unwrap().q, run.forward.last().unwrap().q);
    // Smoothed sigmas never exceed the filter's.
    for (a, b) in smoothed.iter().zip(&run.forward) {
        for k in 0..3 {
            assert!(a.attitude_sigma_deg[k] <= b.attitude_sigma_deg[k] * (1.0 + 1e-9));
        }
    }
}

#[test]
fn start_skips_eclipse_and_photodiodes_never_lit_are_unused() {
    let mut case = Case::rax2(9, 500);
    case.eclipse = 0..120;
    // pd05 covered: outputs are noise around zero (negative values included).
    case.true_scales[4] = 0.0;
    let run = run(&case, &no_smoother(), &Mode::Full);
    assert!(run.start_index >= 120, "{}", run.start_index);
    assert!(!run.used_photodiodes[4]);
    assert!(run.used_photodiodes.iter().filter(|u| **u).count() == 16);
    assert!(run.counts.photodiode.unused_sensor > 0);
}
