//! Monte Carlo over seeds: the accuracy table of the calibration-filter issue.

use std::fmt::Write;
use std::path::PathBuf;

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use pdcal::calibrate::{AlbedoModelType, RunConfig, albedo_model};
use pdcal::evaluate::{Evaluation, evaluate};
use pdcal::files::{Summary, summary};
use pdcal_filter::Mode;
use rayon::prelude::*;
use serde::Serialize;

/// One seed's figures of merit.
#[derive(Debug, Clone, Serialize)]
pub struct SeedResult {
    /// Seed.
    pub seed: u64,
    /// Worst normal error over photodiodes lit >= 5 min, deg.
    pub worst_normal_deg: f64,
    /// Worst |scale error| over photodiodes lit >= 5 min, %.
    pub worst_scale_percent: f64,
    /// Attitude error RMS over sunlit samples after 10 sunlit minutes, deg.
    pub attitude_rms_deg: f64,
    /// Final calibration-state errors inside 3 sigma (count inside, count).
    pub final_inside: (usize, usize),
    /// Photodiode residuals inside their 3-sigma bound.
    pub residual_inside: f64,
    /// Calibrated Sun-vector magnitude, mean and std.
    pub magnitude: (f64, f64),
    /// Estimates within 3 sigma of their final values after 10 sunlit minutes.
    pub converged: f64,
    /// Filter run time, s.
    pub runtime_s: f64,
}

fn one_seed(
    scenario: &pdcal_sim::Scenario,
    seed: u64,
    config: &RunConfig,
    albedo: &AlbedoModelType,
) -> Result<SeedResult> {
    let sim = pdcal::simulate::run(scenario, seed)?;
    let mut telemetry = sim.telemetry.clone();
    if matches!(config.mode, Mode::PhotodiodeOnly) {
        telemetry.mag_nt = None;
    }
    let outcome = pdcal::calibrate::run(&sim.meta, &telemetry, config, albedo)?;
    let eval: Evaluation = evaluate(
        &outcome.run.forward,
        &outcome.run.calibration,
        &sim.truth,
        &sim.constants,
    )?;
    let s: Summary = summary(&sim.meta, &outcome);
    let inside = (eval.consistency.final_states_within_3sigma
        * eval.consistency.final_states as f64)
        .round() as usize;
    Ok(SeedResult {
        seed,
        worst_normal_deg: eval.worst_normal_error_deg,
        worst_scale_percent: eval.worst_scale_error_percent,
        attitude_rms_deg: eval.attitude.rms_deg,
        final_inside: (inside, eval.consistency.final_states),
        residual_inside: s.residuals.fraction_within_3sigma,
        magnitude: (
            s.sun_vector_magnitude.calibrated.mean,
            s.sun_vector_magnitude.calibrated.std,
        ),
        converged: eval.consistency.converged_within_3sigma_of_final,
        runtime_s: outcome.runtime_s,
    })
}

/// Runs seeds `1..=n` and prints/writes the table.
pub fn run(
    n: u64,
    scenario_name: &str,
    photodiode_only: bool,
    config_file: Option<&std::path::Path>,
) -> Result<()> {
    let scenario = pdcal::simulate::load_scenario(scenario_name)?;
    let mut config = match config_file {
        Some(path) => pdcal::calibrate::load_config(path)?,
        None => RunConfig::default(),
    };
    if photodiode_only {
        config.mode = Mode::PhotodiodeOnly;
    }
    let albedo = albedo_model()?;
    let bar = ProgressBar::new(n);
    bar.set_style(ProgressStyle::with_template(
        "{bar:40} {pos}/{len} seeds, {elapsed} elapsed, eta {eta}",
    )?);
    let mut results: Vec<SeedResult> = (1..=n)
        .into_par_iter()
        .map(|seed| {
            let r =
                one_seed(&scenario, seed, &config, &albedo).with_context(|| format!("seed {seed}"));
            bar.inc(1);
            r
        })
        .collect::<Result<_>>()?;
    bar.finish_and_clear();
    results.sort_by_key(|r| r.seed);
    let mode = if photodiode_only {
        "photodiode-only"
    } else {
        "full"
    };
    let table = table(&scenario.name, mode, &results);
    print!("{table}");
    let dir = PathBuf::from("out/sim-calibrate").join(format!("{}-{mode}", scenario.name));
    std::fs::create_dir_all(&dir)?;
    pdcal::output::write_file_atomic(&dir.join("table.md"), table.as_bytes())?;
    pdcal::output::write_file_atomic(
        &dir.join("results.json"),
        serde_json::to_string_pretty(&results)?.as_bytes(),
    )?;
    eprintln!("written to {}", dir.display());
    Ok(())
}

fn stats(values: impl Iterator<Item = f64> + Clone) -> (f64, f64, f64) {
    let n = values.clone().count().max(1) as f64;
    let mean = values.clone().sum::<f64>() / n;
    let max = values.clone().fold(f64::NEG_INFINITY, f64::max);
    let min = values.fold(f64::INFINITY, f64::min);
    (mean, min, max)
}

/// The Markdown accuracy table: mean and worst over seeds against the acceptance bounds.
pub fn table(scenario: &str, mode: &str, r: &[SeedResult]) -> String {
    let mut s = String::new();
    let seeds = r.len();
    let _ = writeln!(s, "### {scenario}, {mode} mode, seeds 1..={seeds}\n");
    let _ = writeln!(s, "| figure of merit | mean | worst | bound |");
    let _ = writeln!(s, "|---|---|---|---|");
    let (m, _, w) = stats(r.iter().map(|x| x.worst_normal_deg));
    let _ = writeln!(
        s,
        "| normal error, worst photodiode lit >= 5 min (deg) | {m:.3} | {w:.3} | <= 0.5 |"
    );
    let (m, _, w) = stats(r.iter().map(|x| x.worst_scale_percent));
    let _ = writeln!(
        s,
        "| scale error, worst photodiode lit >= 5 min (%) | {m:.3} | {w:.3} | <= 1 |"
    );
    let (m, _, w) = stats(r.iter().map(|x| x.attitude_rms_deg));
    let _ = writeln!(
        s,
        "| attitude error RMS, sunlit after 10 min (deg) | {m:.3} | {w:.3} | <= 0.5 |"
    );
    let inside: usize = r.iter().map(|x| x.final_inside.0).sum();
    let total: usize = r.iter().map(|x| x.final_inside.1).sum();
    let (_, wi, _) = stats(
        r.iter()
            .map(|x| x.final_inside.0 as f64 / x.final_inside.1.max(1) as f64),
    );
    let _ = writeln!(
        s,
        "| final calibration states inside 3-sigma (pooled {inside}/{total}) | {:.2} % | {:.2} % | 99.7 +- 0.5 % |",
        100.0 * inside as f64 / total.max(1) as f64,
        100.0 * wi
    );
    let (m, wi, _) = stats(r.iter().map(|x| x.residual_inside));
    let _ = writeln!(
        s,
        "| photodiode residuals inside 3-sigma | {:.2} % | {:.2} % | >= 95 % |",
        100.0 * m,
        100.0 * wi
    );
    let (m, lo, hi) = stats(r.iter().map(|x| x.magnitude.0));
    let _ = writeln!(
        s,
        "| calibrated sun-vector magnitude mean | {m:.4} | {lo:.4} .. {hi:.4} | 0.99 .. 1.01 |"
    );
    let (m, _, w) = stats(r.iter().map(|x| x.magnitude.1));
    let _ = writeln!(
        s,
        "| calibrated sun-vector magnitude std | {m:.4} | {w:.4} | <= 0.02 |"
    );
    let (m, wi, _) = stats(r.iter().map(|x| x.converged));
    let _ = writeln!(
        s,
        "| estimates within 3-sigma of final after 10 sunlit min | {:.2} % | {:.2} % | all |",
        100.0 * m,
        100.0 * wi
    );
    let (m, _, w) = stats(r.iter().map(|x| x.runtime_s));
    let _ = writeln!(s, "| filter run time (s) | {m:.2} | {w:.2} | - |");
    s
}
