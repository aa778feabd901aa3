//! The gyro-bias fit at acquisition ([`pdcal_filter::bias_fit`]) against the truth: the bias
//! it reports lies within its 3 sigma of the true bias along the directions it claims, over
//! several seeds of the simulator, with the Sun alone and with the field; it is refused when
//! the window is too short, and with one vector fixed in the body frame it claims nothing
//! along that vector.

use crate::common;

use nalgebra::{Matrix3, Vector3};
use pdcal_attitude::normal_from_az_el;
use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_ephem::Reference;
use pdcal_filter::bias_fit::{BiasFit, FitInputs, FitPrior, fit_bias};
use pdcal_filter::init::{StartInputs, find_start, initial_scales};
use pdcal_filter::segments::GapRules;
use pdcal_filter::shared_rows::SharedRows;
use pdcal_filter::{FilterConfig, References, step_references};
use pdcal_photodiode::Photodiode;

const PYRAMID: &str = include_str!("../../../../fixtures/scenarios/weak/pyramid-head.ron");

/// The fit on the first segment from its acquisition row (nominal normals, `C` = maximum
/// output, the default prior), with that row's index.
fn fit_first_segment(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    stored: &[Reference],
    window_s: f64,
) -> (usize, Result<BiasFit, String>) {
    let references = References::from(stored);
    let use_mag = telemetry.mag_nt.is_some();
    let config = FilterConfig::default();
    let sigmas = config.resolve(meta.noise.as_ref());
    let scales = initial_scales(telemetry, &references, 10.0 * sigmas.photodiode_v).unwrap();
    let photodiodes: Vec<Photodiode> = meta
        .photodiodes
        .iter()
        .zip(&scales.scale_v)
        .map(|(p, &c)| Photodiode {
            scale_v: c,
            n_body: normal_from_az_el(p.azimuth_deg.to_radians(), p.elevation_deg.to_radians()),
            noise_v: sigmas.photodiode_v,
            fov_half_angle_rad: None,
        })
        .collect();
    let rules = GapRules::new(&config.segments, telemetry);
    let bias_sigma = config.initial_bias_sigma_deg_s.to_radians();
    let start = find_start(
        &StartInputs {
            telemetry,
            references,
            shared: &SharedRows::new(),
            photodiodes: &photodiodes,
            used: &scales.used,
            use_mag,
            mag_sigma_nt: sigmas.mag_nt,
            albedo: None,
            bias_rad_s: Vector3::zeros(),
            bias_sigma_rad_s: bias_sigma,
            rules,
            rate_without_gyro: None,
        },
        0..telemetry.len(),
        &config,
    )
    .unwrap()
    .unwrap();
    let inputs = FitInputs {
        telemetry,
        references,
        photodiodes: &photodiodes,
        used: &scales.used,
        use_mag,
        sun_sigma_rad: config.initial_sun_sigma_deg.to_radians(),
        mag_sigma_nt: sigmas.mag_nt,
        min_sun_fraction: config.min_sun_fraction,
        gyro_hold_s: rules.gyro_hold_s,
        window_s,
    };
    let prior = FitPrior {
        q0: start.q,
        attitude_cov: start.attitude_cov,
        bias_rad_s: Vector3::zeros(),
        bias_cov: Matrix3::identity() * bias_sigma * bias_sigma,
    };
    let fit = fit_bias(&inputs, start.index..telemetry.len(), &prior).unwrap();
    (start.index, fit)
}

/// Each claimed direction's error in the fit's own sigmas (the rows' variance is doubled
/// for the filter's second use of the rows) against the simulator's true bias at the
/// acquisition row; empty when the fit was refused.
fn simulated_errors(scenario: &pdcal_sim::Scenario, seed: u64, use_mag: bool) -> Vec<f64> {
    let sim = pdcal_sim::simulate(scenario, seed).unwrap();
    let mut telemetry = sim.telemetry.clone();
    if !use_mag {
        telemetry.mag_nt = None;
    }
    let stored = step_references(&sim.meta, &sim.telemetry).unwrap();
    let (start, fit) = fit_first_segment(&sim.meta, &telemetry, &stored, 120.0);
    let k = sim
        .truth
        .t_s
        .iter()
        .position(|&t| t == telemetry.t_s[start])
        .unwrap();
    let truth = sim.truth.gyro_bias_rad_s[k];
    match fit {
        Ok(fit) => fit
            .rows
            .iter()
            .map(|row| {
                let sigma = (0.5 * row.variance).sqrt();
                (row.direction.dot(&truth) - row.value_rad_s).abs() / sigma
            })
            .collect(),
        Err(why) => {
            assert!(!why.is_empty());
            Vec::new()
        }
    }
}

/// The issue-20 pyramid head, Sun alone, up to 4 deg/s of bias against a 5 deg/s prior:
/// most seeds give a fit, and its claimed directions hold the truth within 3 sigma. Ten
/// seeds: 26 directions claimed, 24 inside (seed 8's fit is off by 4.7 and 3.5 sigma on
/// two: an uncalibrated Sun vector's error larger than its sigma allows).
#[test]
fn recovers_the_true_bias_with_the_sun_alone() {
    let scenario = pdcal_sim::Scenario::from_ron_str(PYRAMID).unwrap();
    let errors: Vec<Vec<f64>> = (1..=10)
        .map(|seed| simulated_errors(&scenario, seed, false))
        .collect();
    let fitted = errors.iter().filter(|e| !e.is_empty()).count();
    let all: Vec<f64> = errors.iter().flatten().copied().collect();
    let inside = all.iter().filter(|&&e| e <= 3.0).count();
    assert!(fitted >= 8, "{errors:?}");
    assert!(inside as f64 >= 0.9 * all.len() as f64, "{errors:?}");
}

/// rax2-like with its magnetometer: every seed fits all three directions, inside 3 sigma.
#[test]
fn recovers_the_true_bias_with_the_field() {
    let scenario = pdcal_sim::Scenario::rax2_like().unwrap();
    for seed in 1..=4 {
        let errors = simulated_errors(&scenario, seed, true);
        assert_eq!(errors.len(), 3, "seed {seed}: {errors:?}");
        assert!(errors.iter().all(|&e| e <= 3.0), "seed {seed}: {errors:?}");
    }
}

/// A window of one interval (two 5 s rows) is refused as too short.
#[test]
fn refused_when_too_short() {
    let scenario = pdcal_sim::Scenario::from_ron_str(PYRAMID).unwrap();
    let sim = pdcal_sim::simulate(&scenario, 1).unwrap();
    let mut telemetry = sim.telemetry.clone();
    telemetry.mag_nt = None;
    let stored = step_references(&sim.meta, &sim.telemetry).unwrap();
    let (_, fit) = fit_first_segment(&sim.meta, &telemetry, &stored, 6.0);
    let why = fit.unwrap_err();
    assert!(why.starts_with("too short"), "{why}");
}

/// A body that does not turn, the Sun its only vector: the Sun stays fixed in the body
/// frame, so the bias along it is not observed and no claimed direction leans on it.
#[test]
fn claims_nothing_along_a_fixed_sun() {
    let mut case = common::Case::rax2(3, 240);
    case.rate_rad_s = Vector3::zeros();
    case.precession_rad_s = 0.0;
    case.with_mag = false;
    let (meta, telemetry, stored, attitudes) = case.build();
    let sun_body = attitudes[0].to_body(&common::Case::sun_gcrf());
    let (_, fit) = fit_first_segment(&meta, &telemetry, &stored, 120.0);
    if let Ok(fit) = fit {
        for row in &fit.rows {
            let along = row.direction.dot(&sun_body).abs();
            assert!(along < 0.2, "claimed along the Sun: {along}");
            let sigma = (0.5 * row.variance).sqrt();
            let error = (row.direction.dot(&case.bias_rad_s) - row.value_rad_s).abs();
            assert!(error <= 3.0 * sigma, "{error} > 3 x {sigma}");
        }
        assert!(fit.rows.len() <= 2, "{} directions", fit.rows.len());
    }
}
