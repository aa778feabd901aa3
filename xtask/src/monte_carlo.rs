//! Monte Carlo over seeds: the accuracy table of the calibration-filter issue.

use std::fmt::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use indicatif::{ProgressBar, ProgressStyle};
use pdcal::calibrate::{RunConfig, albedo_model};
pub use pdcal::sim_calibrate::Cut;
use pdcal::sim_calibrate::{SET_SPACING_DAYS, SeedResult, run_seed};
use pdcal_filter::Mode;
use rayon::prelude::*;

/// Runs seeds `1..=n` and prints/writes the table; with `keep_going`, a seed that ends
/// with an error is listed under the table instead of stopping the run.
pub fn run(
    n: u64,
    scenario_name: &str,
    photodiode_only: bool,
    config_file: Option<&std::path::Path>,
    (cut, sets): (Option<Cut>, usize),
    (magcal, mag_align_passes, no_mag_align): (bool, usize, bool),
    keep_going: bool,
) -> Result<()> {
    let scenario = pdcal::simulate::load_scenario(scenario_name)?;
    let mut config = match config_file {
        Some(path) => pdcal::calibrate::load_config(path)?,
        None => RunConfig::default(),
    };
    if photodiode_only {
        config.mode = Mode::PhotodiodeOnly;
    }
    config.fit_mag_cal = magcal;
    config.mag_align_passes = mag_align_passes;
    if no_mag_align {
        config.mag_align = pdcal::calibrate::MagAlign::Off;
    }
    let albedo = albedo_model()?;
    let bar = ProgressBar::new(n);
    bar.set_style(ProgressStyle::with_template(
        "{bar:40} {pos}/{len} seeds, {elapsed} elapsed, eta {eta}",
    )?);
    let outcomes: Vec<Result<SeedResult>> = (1..=n)
        .into_par_iter()
        .map(|seed| {
            let r = run_seed(&scenario, seed, &config, &albedo, (cut, sets))
                .map(|run| run.result)
                .with_context(|| format!("seed {seed}"));
            bar.inc(1);
            r
        })
        .collect();
    bar.finish_and_clear();
    let mut results = Vec::new();
    let mut failed = Vec::new();
    for outcome in outcomes {
        match outcome {
            Ok(r) => results.push(r),
            Err(e) if keep_going => failed.push(format!("{e:#}")),
            Err(e) => return Err(e),
        }
    }
    results.sort_by_key(|r| r.seed);
    if results.is_empty() {
        bail!(
            "no seed of {n} ended without an error: {}",
            failed.first().map_or("", String::as_str)
        );
    }
    let mut mode = if photodiode_only {
        "photodiode-only"
    } else {
        "full"
    }
    .to_owned();
    if let Some(cut) = cut {
        mode = format!("{mode}{}", cut.describe());
    }
    if sets > 1 {
        mode = format!("{mode}, {sets} sets {SET_SPACING_DAYS} days apart calibrated jointly");
    }
    if magcal {
        mode = format!("{mode}, magnetometer calibrated first (pdcal magcal)");
    }
    if magcal && no_mag_align {
        mode = format!("{mode}, its rotation left in (--no-mag-align)");
    } else if magcal {
        mode = format!("{mode}, its rotation against the photodiode-only attitude removed");
    }
    if magcal && mag_align_passes > 0 {
        mode = format!("{mode}, {mag_align_passes} passes of its rotation against the attitude");
    }
    let mut table = table(&scenario.name, &mode, &results);
    if !failed.is_empty() {
        let _ = writeln!(
            table,
            "\nSeeds that ended with an error ({} of {n}, not in the table):\n",
            failed.len()
        );
        for why in &failed {
            let _ = writeln!(table, "- {why}");
        }
    }
    print!("{table}");
    let mut tag = match cut {
        Some(cut) => cut.tag(),
        None => String::new(),
    };
    if sets > 1 {
        tag = format!("{tag}-{sets}-sets");
    }
    if magcal {
        tag = format!("{tag}-magcal");
    }
    if magcal && no_mag_align {
        tag = format!("{tag}-noalign");
    }
    if magcal && mag_align_passes > 0 {
        tag = format!("{tag}-align{mag_align_passes}");
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

/// Mean, least and largest of the finite values: a seed whose figure is not defined (no
/// photodiode lit 5 minutes, no sunlit sample after 10 minutes) gives NaN and is left out,
/// and [`defined`] says how many seeds the figure is over.
fn stats(values: impl Iterator<Item = f64> + Clone) -> (f64, f64, f64) {
    let values = values.filter(|x| x.is_finite());
    let n = values.clone().count().max(1) as f64;
    let mean = values.clone().sum::<f64>() / n;
    let max = values.clone().fold(f64::NEG_INFINITY, f64::max);
    let min = values.fold(f64::INFINITY, f64::min);
    (mean, min, max)
}

/// ` (seeds where defined: n of N)` when `figure` is not defined for every seed.
fn defined<'a>(
    r: impl IntoIterator<Item = &'a SeedResult>,
    figure: impl Fn(&SeedResult) -> f64,
) -> String {
    let (mut n, mut all) = (0, 0);
    for x in r {
        all += 1;
        n += usize::from(figure(x).is_finite());
    }
    if n < all {
        format!(" (seeds where defined: {n} of {all})")
    } else {
        String::new()
    }
}

/// The attitude errors about and across the Sun line of the runs that end `consistent`
/// alone: whether a run that does not warn can be taken at its sigmas (the misses of the
/// runs that do warn are said by their verdict).
fn sun_line_of_consistent_runs(s: &mut String, r: &[SeedResult]) {
    let quiet: Vec<&SeedResult> = r.iter().filter(|x| x.verdict == "consistent").collect();
    if quiet.is_empty() || quiet.len() == r.len() {
        return;
    }
    let defined = defined(quiet.iter().copied(), |x| x.attitude_across_sun_inside);
    let (about, about_worst, _) = stats(quiet.iter().map(|x| x.attitude_about_sun_inside));
    let (across, across_worst, _) = stats(quiet.iter().map(|x| x.attitude_across_sun_inside));
    let _ = writeln!(
        s,
        "| attitude errors about / across the Sun line inside 3-sigma, the {} runs that end `consistent`{defined} | {:.2} / {:.2} % | {:.2} / {:.2} % | 99.7 +- 0.5 % |",
        quiet.len(),
        100.0 * about,
        100.0 * across,
        100.0 * about_worst,
        100.0 * across_worst
    );
}

/// The smoother's attitude about and across the Sun line (`estimates_smoothed.csv`, the
/// same samples as the forward rows above), when the runs smoothed.
fn smoothed_sun_line(s: &mut String, r: &[SeedResult]) {
    let about = |x: &SeedResult| x.smoothed_attitude_sun_inside.0;
    let across = |x: &SeedResult| x.smoothed_attitude_sun_inside.1;
    if r.iter().all(|x| across(x).is_nan()) {
        return;
    }
    let defined = defined(r, across);
    let (m_about, w_about, _) = stats(r.iter().map(about));
    let (m_across, w_across, _) = stats(r.iter().map(across));
    let _ = writeln!(
        s,
        "| smoothed attitude errors about / across the Sun line inside 3-sigma{defined} | {:.2} / {:.2} % | {:.2} / {:.2} % | 99.7 +- 0.5 % |",
        100.0 * m_about,
        100.0 * m_across,
        100.0 * w_about,
        100.0 * w_across
    );
}

/// The Markdown accuracy table: mean and worst over seeds against the acceptance bounds.
pub fn table(scenario: &str, mode: &str, r: &[SeedResult]) -> String {
    let mut s = String::new();
    let seeds = r.len();
    let last = r.iter().map(|x| x.seed).max().unwrap_or(0);
    let which = match last == seeds as u64 {
        true => format!("seeds 1..={seeds}"),
        false => format!("{seeds} seeds of 1..={last}"),
    };
    let _ = writeln!(s, "### {scenario}, {mode} mode, {which}\n");
    let _ = writeln!(s, "| figure of merit | mean | worst | bound |");
    let _ = writeln!(s, "|---|---|---|---|");
    let (m, _, w) = stats(r.iter().map(|x| x.worst_normal_deg));
    let d = defined(r, |x| x.worst_normal_deg);
    let _ = writeln!(
        s,
        "| normal error, worst photodiode lit >= 5 min (deg){d} | {m:.3} | {w:.3} | <= 0.5 |"
    );
    let (m, _, w) = stats(r.iter().map(|x| x.worst_scale_percent));
    let d = defined(r, |x| x.worst_scale_percent);
    let _ = writeln!(
        s,
        "| scale error, worst photodiode lit >= 5 min (%){d} | {m:.3} | {w:.3} | <= 1 |"
    );
    let (m, _, w) = stats(r.iter().map(|x| x.attitude_rms_deg));
    let d = defined(r, |x| x.attitude_rms_deg);
    let _ = writeln!(
        s,
        "| attitude error RMS, sunlit after 10 min (deg){d} | {m:.3} | {w:.3} | <= 0.5 |"
    );
    let (m, _, w) = stats(r.iter().map(|x| x.attitude_settled_rms_deg));
    let d = defined(r, |x| x.attitude_settled_rms_deg);
    let _ = writeln!(
        s,
        "| attitude error RMS, sunlit from 60 s after each acquisition (deg){d} | {m:.3} | {w:.3} | <= 1 |"
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
    if r.iter().any(|x| !x.repeatability.is_empty()) {
        let count = |v: &str| r.iter().filter(|x| x.repeatability == v).count();
        let _ = writeln!(
            s,
            "| repeatability verdict: repeatable / not-repeatable / not-checked | {} / {} / {} | - | - |",
            count("repeatable"),
            count("not-repeatable"),
            count("not-checked")
        );
        let warned = r.iter().filter(|x| !x.differing.is_empty()).count();
        let warnings: usize = r.iter().map(|x| x.differing.len()).sum();
        let _ = writeln!(
            s,
            "| runs with a repeatability warning (warnings, all seeds: {warnings}) | {warned} / {} | - | - |",
            r.len()
        );
        let beyond: usize = r.iter().map(|x| x.repeat_tests_beyond_3.0).sum();
        let tests: usize = r.iter().map(|x| x.repeat_tests_beyond_3.1).sum();
        let sum_sq: f64 = r.iter().map(|x| x.repeat_tests_beyond_3.2).sum();
        let _ = writeln!(
            s,
            "| single repeatability tests with abs(z) > 3 (pooled {beyond}/{tests}; 0.27 % if the sigmas are honest) | {:.3} % | - | - |",
            100.0 * beyond as f64 / tests.max(1) as f64
        );
        let _ = writeln!(
            s,
            "| RMS of the single tests' z (1 if the sigmas are honest) | {:.3} | - | - |",
            (sum_sq / tests.max(1) as f64).sqrt()
        );
        let bias: usize = r.iter().map(|x| x.bias_change_warnings).sum();
        let with_bias = r.iter().filter(|x| x.bias_change_warnings > 0).count();
        let _ = writeln!(
            s,
            "| runs with a gyro-bias change beyond its walk (warnings: {bias}) | {with_bias} / {} | - | - |",
            r.len()
        );
    }
    let fitted: Vec<&pdcal_filter::CommonRotation> = r
        .iter()
        .filter_map(|x| x.normals_rotation.as_ref())
        .collect();
    if !fitted.is_empty() {
        let found: Vec<f64> = fitted
            .iter()
            .filter(|f| f.finding)
            .map(|f| f.angle_deg)
            .collect();
        let angles = if found.is_empty() {
            "-".to_owned()
        } else {
            let (_, least, largest) = stats(found.iter().copied());
            format!("{least:.1} .. {largest:.1} deg")
        };
        let _ = writeln!(
            s,
            "| runs whose normals are found turned together from the nominal mounting (fitted: {}; angles found: {angles}) | {} / {} | - | - |",
            fitted.len(),
            found.len(),
            r.len()
        );
    }
    let quiet: Vec<&SeedResult> = r
        .iter()
        .filter(|x| {
            x.verdict == "consistent"
                && x.repeatability != "not-repeatable"
                && !x.normals_rotation.as_ref().is_some_and(|f| f.finding)
        })
        .collect();
    let _ = writeln!(
        s,
        "| runs `consistent`, not `not-repeatable`, with no turned normals found | {} / {} | - | - |",
        quiet.len(),
        r.len()
    );
    let unchecked = quiet
        .iter()
        .filter(|x| x.mounting_warning.is_some())
        .count();
    let _ = writeln!(
        s,
        "| of those, runs that warn their mounting was not checked, or that the normals turned together beyond their prior | {unchecked} / {} | - | - |",
        quiet.len()
    );
    let silent: Vec<&SeedResult> = quiet
        .iter()
        .copied()
        .filter(|x| x.mounting_warning.is_none())
        .collect();
    let _ = writeln!(
        s,
        "| runs that say nothing (the above, and no such warning) | {} / {} | - | - |",
        silent.len(),
        r.len()
    );
    // What silence costs: a quiet run is harmless when every number it gives as a result
    // lies within its 3 sigma of the truth.
    let wrong = silent
        .iter()
        .filter(|x| {
            x.by_status.calibrated_outside_3sigma + x.by_status.weakly_determined_outside_3sigma > 0
        })
        .count();
    let _ = writeln!(
        s,
        "| of those, runs that give a `calibrated` or `weakly-determined` state outside its 3-sigma | {wrong} / {} | - | 0 |",
        silent.len()
    );
    let with_dynamics = r.iter().filter(|x| x.dynamics.0).count();
    let tested: Vec<f64> = r.iter().filter_map(|x| x.dynamics.1).collect();
    let chi = if tested.is_empty() {
        "not tested".to_owned()
    } else {
        let (lo, hi) = tested
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &c| {
                (lo.min(c), hi.max(c))
            });
        format!("the gyro's rate test, chi-square per dof {lo:.2}..{hi:.2}")
    };
    let _ = writeln!(
        s,
        "| runs propagated by the rigid-body dynamics ({chi}) | {with_dynamics} / {} | - | - |",
        r.len()
    );
    let (probes, turned, undecided) = r.iter().fold((0, 0, 0), |acc, x| {
        let p = x.about_sun_probes;
        (acc.0 + p.0, acc.1 + p.1, acc.2 + p.2)
    });
    if probes > 0 {
        let _ = writeln!(
            s,
            "| Sun-only acquisitions probed for the half turn about the Sun line: kept the half turn / not decided (all seeds: {probes}) | {turned} / {undecided} | - | - |"
        );
    }
    let (m, wi, _) = stats(r.iter().map(|x| x.attitude_about_sun_inside));
    let d = defined(r, |x| x.attitude_about_sun_inside);
    let _ = writeln!(
        s,
        "| attitude errors about the Sun line inside 3-sigma{d} | {:.2} % | {:.2} % | 99.7 +- 0.5 % |",
        100.0 * m,
        100.0 * wi
    );
    let (m, wi, _) = stats(r.iter().map(|x| x.attitude_across_sun_inside));
    let d = defined(r, |x| x.attitude_across_sun_inside);
    let _ = writeln!(
        s,
        "| attitude errors across the Sun line inside 3-sigma{d} | {:.2} % | {:.2} % | 99.7 +- 0.5 % |",
        100.0 * m,
        100.0 * wi
    );
    sun_line_of_consistent_runs(&mut s, r);
    smoothed_sun_line(&mut s, r);
    let (m, _, wi) = stats(r.iter().map(|x| x.sigma_factor));
    let _ = writeln!(
        s,
        "| factor on the reported sigmas from the residuals' spread after each step (`dispersion`) | {m:.2} | {wi:.2} | - |"
    );
    let (m, wi, _) = stats(r.iter().map(|x| x.gyro_bias_inside));
    let d = defined(r, |x| x.gyro_bias_inside);
    let _ = writeln!(
        s,
        "| gyro-bias errors inside 3-sigma (per axis, the running estimate){d} | {:.2} % | {:.2} % | 99.7 +- 0.5 % |",
        100.0 * m,
        100.0 * wi
    );
    let (m, wi, _) = stats(r.iter().map(|x| x.residual_inside));
    let d = defined(r, |x| x.residual_inside);
    let _ = writeln!(
        s,
        "| photodiode residuals inside 3-sigma{d} | {:.2} % | {:.2} % | >= 95 % |",
        100.0 * m,
        100.0 * wi
    );
    // A seed with no calibrated Sun-vector sample has no magnitude to average.
    let sampled = || r.iter().filter(|x| x.magnitude.0.is_finite());
    let n = sampled().count();
    let of = if n < r.len() {
        format!(" (seeds with a calibrated sample: {n} of {})", r.len())
    } else {
        String::new()
    };
    let (m, lo, hi) = stats(sampled().map(|x| x.magnitude.0));
    let _ = writeln!(
        s,
        "| calibrated sun-vector magnitude mean{of} | {m:.4} | {lo:.4} .. {hi:.4} | 0.99 .. 1.01 |"
    );
    let (m, _, w) = stats(sampled().map(|x| x.magnitude.1));
    let _ = writeln!(
        s,
        "| calibrated sun-vector magnitude std{of} | {m:.4} | {w:.4} | <= 0.02 |"
    );
    let (m, wi, _) = stats(r.iter().map(|x| x.converged));
    let d = defined(r, |x| x.converged);
    let _ = writeln!(
        s,
        "| estimates within 3-sigma of final after 10 sunlit min{d} | {:.2} % | {:.2} % | all |",
        100.0 * m,
        100.0 * wi
    );
    let (m, _, w) = stats(r.iter().map(|x| x.runtime_s));
    let _ = writeln!(s, "| filter run time (s) | {m:.2} | {w:.2} | - |");
    s
}
