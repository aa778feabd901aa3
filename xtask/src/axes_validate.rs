//! `cargo xtask axes-validate`: the sensor-axes check (`pdcal::axes`) on simulated data:
//! every wrong signed permutation of the gyro, of the magnetometer and of the photodiode
//! table found (or said undecided), and the false findings on clean data, full,
//! photodiode-only and cut into passes.

use std::fmt::Write;

use anyhow::{Context, Result};
use nalgebra::Matrix3;
use pdcal::sim_calibrate::{Cut, simulate_set};
use pdcal_axes::{AxesCheck, Sensor, signed_permutations};
use pdcal_dataset::{DatasetMeta, Telemetry};
use rayon::prelude::*;

/// How each sensor's wrong permutations came out over the seeds.
#[derive(Default)]
struct Tally {
    right: usize,
    undecided: usize,
    wrong: Vec<String>,
    undecided_cases: Vec<String>,
}

/// Runs the check; prints the markdown tables.
pub fn run(scenario_name: &str, clean_seeds: u64, permuted_seeds: u64) -> Result<()> {
    let scenario = pdcal::simulate::load_scenario(scenario_name)?;
    let passes: Cut = "passes:300/900".parse()?;
    let clean: Vec<[(bool, usize); 3]> = (1..=clean_seeds)
        .into_par_iter()
        .map(|seed| -> Result<[(bool, usize); 3]> {
            let full = simulate_set(&scenario, seed, 0, None)?;
            let mut pd_only = full.telemetry.clone();
            pd_only.mag_nt = None;
            let cut = simulate_set(&scenario, seed, 0, Some(passes))?;
            let judge = |r: AxesCheck| (r.finding.is_some(), r.not_checked.len());
            Ok([
                judge(check(&full.meta, &full.telemetry)?),
                judge(check(&full.meta, &pd_only)?),
                judge(check(&cut.meta, &cut.telemetry)?),
            ])
        })
        .collect::<Result<_>>()?;
    let sensors = [Sensor::Gyro, Sensor::Magnetometer, Sensor::Photodiodes];
    let per_seed: Vec<Vec<(Sensor, usize, Outcome)>> = (1..=permuted_seeds)
        .into_par_iter()
        .map(|seed| -> Result<Vec<(Sensor, usize, Outcome)>> {
            let sim = simulate_set(&scenario, seed, 0, None)?;
            let mut out = Vec::new();
            for sensor in sensors {
                for (k, m) in signed_permutations().iter().enumerate().skip(1) {
                    let (meta, telemetry) = recorded(&sim.meta, &sim.telemetry, sensor, m);
                    let result = check(&meta, &telemetry)?;
                    let outcome = match result.finding {
                        Some(f) if f.sensor == sensor && f.matrix() == *m => Outcome::Right,
                        Some(f) => Outcome::Wrong(format!(
                            "seed {seed} {} #{k}: found {} {:?}",
                            sensor.as_str(),
                            f.sensor.as_str(),
                            f.body_from_sensor
                        )),
                        None => Outcome::Undecided(format!(
                            "seed {seed} {} #{k} {}",
                            sensor.as_str(),
                            result
                                .not_checked
                                .first()
                                .map_or(String::new(), |n| n.reason.clone())
                        )),
                    };
                    out.push((sensor, k, outcome));
                }
            }
            Ok(out)
        })
        .collect::<Result<_>>()?;
    print!(
        "{}",
        table(scenario_name, &clean, &per_seed, permuted_seeds)
    );
    Ok(())
}

enum Outcome {
    Right,
    Undecided(String),
    Wrong(String),
}

fn table(
    scenario: &str,
    clean: &[[(bool, usize); 3]],
    per_seed: &[Vec<(Sensor, usize, Outcome)>],
    permuted_seeds: u64,
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "\n{scenario}: clean runs (seeds 1..={})\n", clean.len());
    let _ = writeln!(
        s,
        "| case | runs with a finding | runs with an 'axes not checked' note |"
    );
    let _ = writeln!(s, "|---|---|---|");
    for (j, name) in ["full", "photodiode-only", "5-minute passes every 15 min"]
        .iter()
        .enumerate()
    {
        let findings = clean.iter().filter(|c| c[j].0).count();
        let notes = clean.iter().filter(|c| c[j].1 > 0).count();
        let _ = writeln!(
            s,
            "| {name} | {findings} / {} | {notes} / {} |",
            clean.len(),
            clean.len()
        );
    }
    let _ = writeln!(
        s,
        "\n{scenario}: each wrong signed permutation of one sensor (47 each, seeds 1..={permuted_seeds})\n"
    );
    let _ = writeln!(
        s,
        "| sensor | right matrix found | undecided | a wrong matrix found |"
    );
    let _ = writeln!(s, "|---|---|---|---|");
    let mut details = String::new();
    for sensor in [Sensor::Gyro, Sensor::Magnetometer, Sensor::Photodiodes] {
        let mut t = Tally::default();
        for (sen, _, outcome) in per_seed.iter().flatten() {
            if *sen != sensor {
                continue;
            }
            match outcome {
                Outcome::Right => t.right += 1,
                Outcome::Undecided(why) => {
                    t.undecided += 1;
                    t.undecided_cases.push(why.clone());
                }
                Outcome::Wrong(what) => t.wrong.push(what.clone()),
            }
        }
        let n = t.right + t.undecided + t.wrong.len();
        let _ = writeln!(
            s,
            "| {} | {} / {n} ({:.1} %) | {} | {} |",
            sensor.as_str(),
            t.right,
            100.0 * t.right as f64 / n.max(1) as f64,
            t.undecided,
            t.wrong.len()
        );
        for line in t.undecided_cases.iter().chain(&t.wrong) {
            let _ = writeln!(details, "- {line}");
        }
    }
    if !details.is_empty() {
        let _ = writeln!(s, "\nNot found right:\n\n{details}");
    }
    s
}

fn check(meta: &DatasetMeta, telemetry: &Telemetry) -> Result<AxesCheck> {
    let references = pdcal_filter::step_references(meta, telemetry)?;
    pdcal::axes::check(
        meta,
        telemetry,
        &(&references).into(),
        &pdcal_filter::FilterConfig::default(),
        &[],
    )
    .context("sensor-axes check")
}

/// The set as a sensor of axes `m` records it: `v_sensor = M^T v_body`.
fn recorded(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    sensor: Sensor,
    m: &Matrix3<f64>,
) -> (DatasetMeta, Telemetry) {
    let (mut meta, mut telemetry) = (meta.clone(), telemetry.clone());
    pdcal::axes::transform(sensor, &m.transpose(), &mut meta, &mut telemetry);
    (meta, telemetry)
}
