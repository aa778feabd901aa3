//! Monte Carlo over seeds: the accuracy table of the calibration-filter issue.

use std::fmt::Write;
use std::path::PathBuf;

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use pdcal::calibrate::{AlbedoModelType, RunConfig, albedo_model};
use pdcal::evaluate::{Evaluation, evaluate};
use pdcal::files::{Summary, summary};
use pdcal_dataset::TruthSeries;
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
    /// Attitude error RMS over sunlit samples from 60 s after each acquisition, deg.
    pub attitude_settled_rms_deg: f64,
    /// Segments of the run, and how many ended with the attitude lost.
    pub segments: (usize, usize),
    /// Why the attitude was first declared lost, and at which row.
    pub first_lost: Option<(usize, String)>,
    /// With several sets: the smallest worst-normal (deg) and worst-scale (%) errors of the
    /// sets calibrated one by one.
    pub best_single: Option<(f64, f64)>,
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
    /// The consistency verdict of summary.json.
    pub verdict: &'static str,
    /// The final states by reported status, and those outside 3 sigma of the truth.
    pub by_status: pdcal::evaluate::StatusTally,
    /// Attitude errors about the Sun line inside their 3 sigma (converged sunlit samples).
    pub attitude_about_sun_inside: f64,
    /// Attitude errors across the Sun line inside their 3 sigma.
    pub attitude_across_sun_inside: f64,
}

/// Which rows a downlink keeps: `passes:ON/PERIOD` keeps ON seconds of every PERIOD
/// (5-min passes every 15 min: `passes:300/900`; 10 min on, 10 off: `passes:600/1200`),
/// starting at a phase drawn from the seed, so that the passes fall differently per seed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cut {
    /// Seconds kept per period.
    pub on_s: f64,
    /// Period, s.
    pub period_s: f64,
}

impl std::str::FromStr for Cut {
    type Err = anyhow::Error;

    fn from_str(s: &str) -> Result<Self> {
        let spec = s
            .strip_prefix("passes:")
            .context("a cut is passes:ON/PERIOD (seconds)")?;
        let (on, period) = spec
            .split_once('/')
            .context("a cut is passes:ON/PERIOD (seconds)")?;
        let cut = Cut {
            on_s: on.trim().parse().context("ON seconds")?,
            period_s: period.trim().parse().context("PERIOD seconds")?,
        };
        anyhow::ensure!(
            cut.on_s > 0.0 && cut.period_s > cut.on_s,
            "a cut needs 0 < ON < PERIOD"
        );
        Ok(cut)
    }
}

impl Cut {
    /// Whether time `t_s` is inside a pass, for the seed's phase.
    fn keeps(&self, seed: u64, t_s: f64) -> bool {
        // One number per seed: a splitmix64 step spreads consecutive seeds over the period.
        let mut z = seed.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        let phase = (z >> 11) as f64 / (1u64 << 53) as f64 * self.period_s;
        (t_s + phase).rem_euclid(self.period_s) < self.on_s
    }
}

/// Days between the data sets of a joint run (`--sets N`).
pub const SET_SPACING_DAYS: f64 = 30.0;

/// The seed's data set `j` of `sets`: the scenario with its epoch `j` months later, as
/// downlink `j` of the seed (the same hardware, its own noise, start attitude and gyro
/// bias), cut into passes when asked.
fn simulate_set(
    scenario: &pdcal_sim::Scenario,
    seed: u64,
    j: usize,
    cut: Option<Cut>,
) -> Result<pdcal_sim::SimOutput> {
    let mut scenario = scenario.clone();
    if j > 0 {
        let epoch = pdcal_dataset::EpochUtc::parse(&scenario.epoch_utc)
            .map_err(|e| anyhow::anyhow!("scenario epoch_utc: {e}"))?
            .epoch()
            + hifitime::Unit::Day * (SET_SPACING_DAYS * j as f64);
        let (y, mo, d, h, mi, s, _) = epoch.to_gregorian_utc();
        scenario.epoch_utc = format!("{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}Z");
        scenario.name = format!("{}-set{}", scenario.name, j + 1);
    }
    let mut sim = pdcal::simulate::run_downlink(&scenario, seed, j as u64)?;
    if let Some(cut) = cut {
        let t = sim.telemetry.t_s.clone();
        sim.telemetry = sim.telemetry.select_rows(|k| cut.keeps(seed, t[k]));
        let t = sim.truth.t_s.clone();
        sim.truth = sim.truth.select_rows(|k| cut.keeps(seed, t[k]));
    }
    Ok(sim)
}

/// The truth of several sets on the joint time line.
fn joint_truth(sets: &[pdcal_sim::SimOutput], joint: &pdcal::joint::Joint) -> TruthSeries {
    let mut out = sets[0].truth.select_rows(|_| false);
    for (sim, span) in sets.iter().zip(&joint.sets) {
        let t = &sim.truth;
        out.t_s.extend(t.t_s.iter().map(|x| x + span.offset_s));
        out.q.extend_from_slice(&t.q);
        out.w_body_rad_s.extend_from_slice(&t.w_body_rad_s);
        out.gyro_bias_rad_s.extend_from_slice(&t.gyro_bias_rad_s);
        out.sun_body.extend_from_slice(&t.sun_body);
        out.eclipse.extend_from_slice(&t.eclipse);
        out.r_gcrf_km.extend_from_slice(&t.r_gcrf_km);
        out.mag_body_nt.extend_from_slice(&t.mag_body_nt);
    }
    out
}

/// Calibrates one set alone: its worst normal (deg) and scale (%) errors.
fn single_set_errors(
    sim: &pdcal_sim::SimOutput,
    config: &RunConfig,
    albedo: &AlbedoModelType,
) -> Result<(f64, f64)> {
    let outcome = pdcal::calibrate::run(&sim.meta, &sim.telemetry, config, albedo)?;
    let eval = evaluate(
        &outcome.run.forward,
        &outcome.run.calibration,
        &sim.truth,
        &sim.constants,
    )?;
    Ok((eval.worst_normal_error_deg, eval.worst_scale_error_percent))
}

fn one_seed(
    scenario: &pdcal_sim::Scenario,
    seed: u64,
    config: &RunConfig,
    albedo: &AlbedoModelType,
    (cut, sets): (Option<Cut>, usize),
) -> Result<SeedResult> {
    let sims: Vec<pdcal_sim::SimOutput> = (0..sets.max(1))
        .map(|j| simulate_set(scenario, seed, j, cut))
        .collect::<Result<_>>()?;
    if sims.iter().any(|s| s.constants != sims[0].constants) {
        anyhow::bail!("the sets of seed {seed} simulate different hardware");
    }
    let joint = pdcal::joint::join(
        sims.iter()
            .enumerate()
            .map(|(j, s)| {
                (
                    format!("set{}", j + 1).into(),
                    s.meta.clone(),
                    s.telemetry.clone(),
                )
            })
            .collect(),
    )?;
    let mut telemetry = joint.telemetry.clone();
    if matches!(config.mode, Mode::PhotodiodeOnly) {
        telemetry.mag_nt = None;
    }
    let references = match joint.references.clone() {
        Some(references) => references,
        None => pdcal_filter::step_references(&joint.meta, &joint.telemetry)?,
    };
    let outcome =
        pdcal::calibrate::run_with_references(&joint.meta, &telemetry, references, config, albedo)?;
    let truth = joint_truth(&sims, &joint);
    let s: Summary = summary(&joint.meta, &outcome);
    // The calibration as reported: a quantity the data did not determine at its prior.
    let eval: Evaluation = evaluate(
        &outcome.run.forward,
        &s.reported,
        &truth,
        &sims[0].constants,
    )?;
    let best_single = if sims.len() > 1 {
        let singles: Vec<(f64, f64)> = sims
            .iter()
            .map(|s| single_set_errors(s, config, albedo))
            .collect::<Result<_>>()?;
        Some((
            singles.iter().map(|s| s.0).fold(f64::INFINITY, f64::min),
            singles.iter().map(|s| s.1).fold(f64::INFINITY, f64::min),
        ))
    } else {
        None
    };

    check_numbers(&outcome.run)?;
    let inside = (eval.consistency.final_states_within_3sigma
        * eval.consistency.final_states as f64)
        .round() as usize;
    Ok(SeedResult {
        seed,
        worst_normal_deg: eval.worst_normal_error_deg,
        worst_scale_percent: eval.worst_scale_error_percent,
        attitude_rms_deg: eval.attitude.rms_deg,
        attitude_settled_rms_deg: eval.attitude_after_acquisition.rms_deg,
        segments: (
            outcome.run.segments.len(),
            outcome
                .run
                .segments
                .iter()
                .filter(|g| g.lost.is_some())
                .count(),
        ),
        best_single,
        first_lost: outcome
            .run
            .segments
            .iter()
            .find_map(|g| g.lost.clone().map(|why| (g.last_row, why))),
        final_inside: (inside, eval.consistency.final_states),
        residual_inside: s.residuals.fraction_within_3sigma,
        magnitude: (
            s.sun_vector_magnitude.calibrated.mean,
            s.sun_vector_magnitude.calibrated.std,
        ),
        converged: eval.consistency.converged_within_3sigma_of_final,
        runtime_s: outcome.runtime_s,
        verdict: s.consistency.verdict.as_str(),
        by_status: eval.consistency.by_status,
        attitude_about_sun_inside: eval.consistency.attitude_about_sun_within_3sigma,
        attitude_across_sun_inside: eval.consistency.attitude_across_sun_within_3sigma,
    })
}

/// Fails unless every estimate is finite and the covariance never needed a repair (the
/// guard factors it every 1024 rows and checks its diagonal every row).
fn check_numbers(run: &pdcal_filter::CalibrationRun) -> Result<()> {
    anyhow::ensure!(
        run.covariance_repairs.count == 0,
        "the covariance needed {} repairs (first: {:?})",
        run.covariance_repairs.count,
        run.covariance_repairs.first.first()
    );
    let finite = |e: &pdcal_filter::StepEstimate| {
        [e.q.x, e.q.y, e.q.z, e.q.w]
            .iter()
            .chain(&e.attitude_sigma_deg)
            .chain(&e.calibration.gyro_bias_rad_s)
            .chain(
                e.calibration
                    .photodiodes
                    .iter()
                    .flat_map(|p| {
                        [
                            p.scale_v,
                            p.scale_sigma_v,
                            p.elevation_deg,
                            p.elevation_sigma_deg,
                        ]
                    })
                    .collect::<Vec<_>>()
                    .iter(),
            )
            .all(|x| x.is_finite())
    };
    let all = run.forward.iter().chain(run.smoothed.iter().flatten());
    anyhow::ensure!(all.clone().all(finite), "a non-finite estimate");
    Ok(())
}

/// Runs seeds `1..=n` and prints/writes the table.
pub fn run(
    n: u64,
    scenario_name: &str,
    photodiode_only: bool,
    config_file: Option<&std::path::Path>,
    (cut, sets): (Option<Cut>, usize),
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
            let r = one_seed(&scenario, seed, &config, &albedo, (cut, sets))
                .with_context(|| format!("seed {seed}"));
            bar.inc(1);
            r
        })
        .collect::<Result<_>>()?;
    bar.finish_and_clear();
    results.sort_by_key(|r| r.seed);
    let mut mode = if photodiode_only {
        "photodiode-only"
    } else {
        "full"
    }
    .to_owned();
    if let Some(cut) = cut {
        mode = format!("{mode}, passes of {} s every {} s", cut.on_s, cut.period_s);
    }
    if sets > 1 {
        mode = format!("{mode}, {sets} sets {SET_SPACING_DAYS} days apart calibrated jointly");
    }
    let table = table(&scenario.name, &mode, &results);
    print!("{table}");
    let mut tag = match cut {
        Some(cut) => format!("-passes-{}-{}", cut.on_s, cut.period_s),
        None => String::new(),
    };
    if sets > 1 {
        tag = format!("{tag}-{sets}-sets");
    }
    let dir = PathBuf::from("out/sim-calibrate").join(format!(
        "{}-{}{tag}",
        scenario.name,
        if photodiode_only {
            "photodiode-only"
        } else {
            "full"
        }
    ));
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
    let (m, _, w) = stats(r.iter().map(|x| x.attitude_settled_rms_deg));
    let _ = writeln!(
        s,
        "| attitude error RMS, sunlit from 60 s after each acquisition (deg) | {m:.3} | {w:.3} | <= 1 |"
    );
    if r.iter().all(|x| x.best_single.is_some()) {
        let best = |f: fn(&(f64, f64)) -> f64| {
            r.iter()
                .filter_map(|x| x.best_single.as_ref().map(f))
                .collect::<Vec<f64>>()
        };
        let (m, _, w) = stats(best(|b| b.0).into_iter());
        let _ = writeln!(
            s,
            "| best single set: normal error, worst photodiode (deg) | {m:.3} | {w:.3} | - |"
        );
        let (m, _, w) = stats(best(|b| b.1).into_iter());
        let _ = writeln!(
            s,
            "| best single set: scale error, worst photodiode (%) | {m:.3} | {w:.3} | - |"
        );
        let no_worse = r
            .iter()
            .filter(|x| {
                x.best_single.is_some_and(|b| {
                    x.worst_normal_deg <= b.0 + 1e-9 && x.worst_scale_percent <= b.1 + 1e-9
                })
            })
            .count();
        let _ = writeln!(
            s,
            "| seeds whose joint errors are no worse than the best single set's | {no_worse} / {} | - | all |",
            r.len()
        );
    }
    let (m, lo, hi) = stats(r.iter().map(|x| x.segments.0 as f64));
    let lost: usize = r.iter().map(|x| x.segments.1).sum();
    let _ = writeln!(
        s,
        "| segments per run (lost attitudes, all seeds: {lost}) | {m:.1} | {lo:.0} .. {hi:.0} | - |"
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
    let tally = r
        .iter()
        .fold(pdcal::evaluate::StatusTally::default(), |mut t, x| {
            let b = &x.by_status;
            t.calibrated += b.calibrated;
            t.calibrated_outside_3sigma += b.calibrated_outside_3sigma;
            t.weakly_determined += b.weakly_determined;
            t.weakly_determined_outside_3sigma += b.weakly_determined_outside_3sigma;
            t.not_determined += b.not_determined;
            t.not_determined_outside_3sigma += b.not_determined_outside_3sigma;
            t
        });
    let _ = writeln!(
        s,
        "| reported `calibrated` states inside 3-sigma (pooled; outside: {} of {}) | {:.2} % | - | >= 99 % |",
        tally.calibrated_outside_3sigma,
        tally.calibrated,
        100.0 * (1.0 - tally.calibrated_outside_3sigma as f64 / tally.calibrated.max(1) as f64)
    );
    let _ = writeln!(
        s,
        "| states weakly-determined / not-determined (outside 3-sigma) | {} ({}) / {} ({}) | - | - |",
        tally.weakly_determined,
        tally.weakly_determined_outside_3sigma,
        tally.not_determined,
        tally.not_determined_outside_3sigma
    );
    let consistent = r.iter().filter(|x| x.verdict == "consistent").count();
    let _ = writeln!(
        s,
        "| runs whose residuals are `consistent` | {consistent} / {} | - | - |",
        r.len()
    );
    let (m, wi, _) = stats(r.iter().map(|x| x.attitude_about_sun_inside));
    let _ = writeln!(
        s,
        "| attitude errors about the Sun line inside 3-sigma | {:.2} % | {:.2} % | 99.7 +- 0.5 % |",
        100.0 * m,
        100.0 * wi
    );
    let (m, wi, _) = stats(r.iter().map(|x| x.attitude_across_sun_inside));
    let _ = writeln!(
        s,
        "| attitude errors across the Sun line inside 3-sigma | {:.2} % | {:.2} % | 99.7 +- 0.5 % |",
        100.0 * m,
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
