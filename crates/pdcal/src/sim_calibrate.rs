//! One seed of the simulate -> calibrate -> evaluate Monte Carlo (`cargo xtask
//! sim-calibrate`, the Python `pdcal.campaign`): both run this function, so a seed gives
//! the same figures of merit from either.

use anyhow::{Context, Result};
use serde::Serialize;

use crate::calibrate::{AlbedoModelType, RunConfig};
use crate::evaluate::{Evaluation, evaluate, evaluate_with_smoothed};
use crate::files::{Summary, summary};
use pdcal_dataset::TruthSeries;
use pdcal_filter::Mode;

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
    /// The consistency verdict of summary.json (`consistent`, `inconsistent`).
    pub verdict: String,
    /// The final states by reported status, and those outside 3 sigma of the truth.
    pub by_status: crate::evaluate::StatusTally,
    /// Attitude errors about the Sun line inside their 3 sigma (converged sunlit samples).
    pub attitude_about_sun_inside: f64,
    /// Attitude errors across the Sun line inside their 3 sigma.
    pub attitude_across_sun_inside: f64,
    /// The smoother's attitude (`estimates_smoothed.csv`) about and across the Sun line
    /// inside its 3 sigma, on the same kind of samples; NaN without the smoother.
    pub smoothed_attitude_sun_inside: (f64, f64),
    /// Running gyro-bias errors inside their 3 sigma, per axis (converged sunlit samples).
    pub gyro_bias_inside: f64,
    /// With several sets, the repeatability verdict (`repeatable`, `not-repeatable`,
    /// `not-checked`); empty for one set.
    pub repeatability: String,
    /// The parameters whose sets differ (one repeatability warning each).
    pub differing: Vec<String>,
    /// Gyro-bias changes between consecutive sets beyond the walk (warnings).
    pub bias_change_warnings: usize,
    /// The single repeatability tests of the calibration parameters (pairs and
    /// set-against-the-others) whose `|z|` exceeds 3, how many tests there were, and the
    /// sum of their `z^2`.
    pub repeat_tests_beyond_3: (usize, usize, f64),
    /// Sun-only acquisitions probed for the half turn about the Sun line
    /// (`segments[].about_sun_line`): how many, how many kept the half turn, and how many
    /// were not decided.
    pub about_sun_probes: (usize, usize, usize),
    /// Whether the rigid-body dynamics carried the attitude between samples, and the
    /// chi-square per dof of the gyro's rate test when `dynamics: Auto` ran it
    /// (`summary.json` `propagation`).
    pub dynamics: (bool, Option<f64>),
    /// The common rotation of the normals from the nominal mounting (`summary.json`
    /// `normals_rotation`); `None` when not fitted.
    pub normals_rotation: Option<pdcal_filter::CommonRotation>,
    /// The summary's warning of the mounting ([`crate::schema::mounting_warning`]): a
    /// turned head found, or one the data could not check.
    pub mounting_warning: Option<String>,
    /// The factor every reported sigma was multiplied by (`summary.json` `dispersion`);
    /// 1 when the configuration turns it off.
    pub sigma_factor: f64,
}

/// What a downlink keeps and what the filter is told, comma-separated parts:
/// `passes:ON/PERIOD` keeps ON seconds of every PERIOD (5-min passes every 15 min:
/// `passes:300/900`; 10 min on, 10 off: `passes:600/1200`), starting at a phase drawn from
/// the seed, so that the passes fall differently per seed; `every:S` keeps one row every S
/// seconds; `gyro-every:S` keeps the gyro samples every S seconds only; `no-gyro` drops the
/// gyro columns; `inertia-x:F` (or `-y`, `-z`) multiplies dataset.ron's inertia moment about
/// that axis by F (the filter's belief; the truth keeps the scenario's).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Cut {
    /// Passes: seconds kept per period and the period, s.
    pub passes: Option<(f64, f64)>,
    /// One row kept every this many seconds.
    pub every_s: Option<f64>,
    /// One gyro sample kept every this many seconds.
    pub gyro_every_s: Option<f64>,
    /// The gyro columns dropped.
    pub no_gyro: bool,
    /// The inertia axis (0, 1, 2) and the factor on its moment in dataset.ron.
    pub inertia_factor: Option<(usize, f64)>,
}

impl std::str::FromStr for Cut {
    type Err = anyhow::Error;

    fn from_str(s: &str) -> Result<Self> {
        let mut cut = Cut::default();
        for part in s.split(',').map(str::trim) {
            let seconds = |v: &str| -> Result<f64> {
                let v: f64 = v.trim_end_matches('s').parse().context("seconds")?;
                anyhow::ensure!(v > 0.0 && v.is_finite(), "a spacing must be positive");
                Ok(v)
            };
            if let Some(v) = part.strip_prefix("every:") {
                cut.every_s = Some(seconds(v)?);
            } else if let Some(v) = part.strip_prefix("gyro-every:") {
                cut.gyro_every_s = Some(seconds(v)?);
            } else if part == "no-gyro" {
                cut.no_gyro = true;
            } else if let Some((axis, v)) = part
                .strip_prefix("inertia-")
                .and_then(|rest| rest.split_once(':'))
            {
                let axis = ["x", "y", "z"]
                    .iter()
                    .position(|a| *a == axis)
                    .context("inertia-x, inertia-y or inertia-z")?;
                let f: f64 = v.parse().context("inertia factor")?;
                anyhow::ensure!(
                    f > 0.0 && f.is_finite(),
                    "an inertia factor must be positive"
                );
                cut.inertia_factor = Some((axis, f));
            } else {
                let (on, period) = passes(part)?;
                cut.passes = Some((on, period));
            }
        }
        Ok(cut)
    }
}

/// `passes:ON/PERIOD`.
fn passes(s: &str) -> Result<(f64, f64)> {
    {
        let spec = s.strip_prefix("passes:").context(
            "a cut is passes:ON/PERIOD (seconds), every:S, gyro-every:S, no-gyro or inertia-x:F",
        )?;
        let (on, period) = spec
            .split_once('/')
            .context("a cut is passes:ON/PERIOD (seconds)")?;
        let on_s: f64 = on.trim().parse().context("ON seconds")?;
        let period_s: f64 = period.trim().parse().context("PERIOD seconds")?;
        anyhow::ensure!(on_s > 0.0 && period_s > on_s, "a cut needs 0 < ON < PERIOD");
        Ok((on_s, period_s))
    }
}

impl Cut {
    /// Whether time `t_s` is kept, for the seed's phase of the passes.
    fn keeps(&self, seed: u64, t_s: f64) -> bool {
        let in_pass = self
            .passes
            .is_none_or(|(on_s, period_s)| Self::in_pass(seed, t_s, on_s, period_s));
        in_pass && self.every_s.is_none_or(|s| on_grid(t_s, s))
    }

    /// Whether `t_s` is inside a pass of `on_s` every `period_s`, for the seed's phase.
    fn in_pass(seed: u64, t_s: f64, on_s: f64, period_s: f64) -> bool {
        // One number per seed: a splitmix64 step spreads consecutive seeds over the period.
        let mut z = seed.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        let phase = (z >> 11) as f64 / (1u64 << 53) as f64 * period_s;
        (t_s + phase).rem_euclid(period_s) < on_s
    }

    /// The parts as a table's title reads them (`, passes of 300 s every 900 s`).
    pub fn describe(&self) -> String {
        let mut out = String::new();
        if let Some((on, period)) = self.passes {
            out += &format!(", passes of {on} s every {period} s");
        }
        if let Some(s) = self.every_s {
            out += &format!(", one row every {s} s");
        }
        if let Some(s) = self.gyro_every_s {
            out += &format!(", gyro every {s} s");
        }
        if self.no_gyro {
            out += ", no gyro";
        }
        if let Some((axis, f)) = self.inertia_factor {
            out += &format!(
                ", filter's inertia {}{} x {f}",
                "xyz".as_bytes()[axis] as char,
                "xyz".as_bytes()[axis] as char
            );
        }
        out
    }

    /// The parts as an output directory's suffix (`-passes-300-900`).
    pub fn tag(&self) -> String {
        let mut out = String::new();
        if let Some((on, period)) = self.passes {
            out += &format!("-passes-{on}-{period}");
        }
        if let Some(s) = self.every_s {
            out += &format!("-every-{s}");
        }
        if let Some(s) = self.gyro_every_s {
            out += &format!("-gyro-every-{s}");
        }
        if self.no_gyro {
            out += "-no-gyro";
        }
        if let Some((axis, f)) = self.inertia_factor {
            out += &format!("-inertia-{}-{f}", "xyz".as_bytes()[axis] as char);
        }
        out
    }

    /// The gyro thinned or dropped and the inertia changed as asked.
    fn apply_sensors(&self, sim: &mut pdcal_sim::SimOutput) {
        if self.no_gyro {
            let rows = sim.telemetry.len();
            (0..rows).for_each(|k| sim.telemetry.gyro_rad_s.set(k, None));
        } else if let Some(s) = self.gyro_every_s {
            let t = &sim.telemetry.t_s;
            for (k, &t) in t.iter().enumerate() {
                if !on_grid(t, s) {
                    sim.telemetry.gyro_rad_s.set(k, None);
                }
            }
        }
        if let (Some((axis, f)), Some(inertia)) =
            (self.inertia_factor, sim.meta.inertia_kg_m2.as_mut())
        {
            match axis {
                0 => inertia.xx *= f,
                1 => inertia.yy *= f,
                _ => inertia.zz *= f,
            }
        }
    }
}

/// Whether `t_s` falls on the grid of spacing `step_s` (within a millisecond).
fn on_grid(t_s: f64, step_s: f64) -> bool {
    let r = t_s.rem_euclid(step_s);
    r < 1e-3 || step_s - r < 1e-3
}

/// Days between the data sets of a joint run (`--sets N`).
pub const SET_SPACING_DAYS: f64 = 30.0;

/// The seed's data set `j` of `sets`: the scenario with its epoch `j` months later, as
/// downlink `j` of the seed (the same hardware, its own noise, start attitude and gyro
/// bias), cut into passes when asked.
pub fn simulate_set(
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
    let mut sim = crate::simulate::run_downlink(&scenario, seed, j as u64)?;
    if let Some(cut) = cut {
        let t = sim.telemetry.t_s.clone();
        sim.telemetry = sim.telemetry.select_rows(|k| cut.keeps(seed, t[k]));
        let t = sim.truth.t_s.clone();
        sim.truth = sim.truth.select_rows(|k| cut.keeps(seed, t[k]));
        cut.apply_sensors(&mut sim);
    }
    Ok(sim)
}

/// The truth of several sets on the joint time line.
fn joint_truth(sets: &[pdcal_sim::SimOutput], joint: &crate::joint::Joint) -> TruthSeries {
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
    let outcome = crate::calibrate::run(&sim.meta, &sim.telemetry, config, albedo)?;
    let eval = evaluate(
        &outcome.run.forward,
        &outcome.run.calibration,
        &sim.truth,
        &sim.constants,
    )?;
    Ok((eval.worst_normal_error_deg, eval.worst_scale_error_percent))
}

/// Seed `seed` of `scenario`: simulates its `sets` downlinks (a month apart, cut into
/// passes when asked), calibrates them jointly with `config`, evaluates against the truth;
/// with several sets, also each set alone. Fails if an estimate is not finite or the
/// covariance needed a repair.
pub fn run_seed(
    scenario: &pdcal_sim::Scenario,
    seed: u64,
    config: &RunConfig,
    albedo: &AlbedoModelType,
    (cut, sets): (Option<Cut>, usize),
) -> Result<SeedRun> {
    let sims: Vec<pdcal_sim::SimOutput> = (0..sets.max(1))
        .map(|j| simulate_set(scenario, seed, j, cut))
        .collect::<Result<_>>()?;
    if sims.iter().any(|s| s.constants != sims[0].constants) {
        anyhow::bail!("the sets of seed {seed} simulate different hardware");
    }
    let joint = crate::joint::join(
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
    let fitted = (config.fit_mag_cal && config.mag_cal.is_none() && telemetry.mag_nt.is_some())
        .then(|| crate::magcal::run(&joint.meta, &telemetry))
        .transpose()?
        .map(|outcome| outcome.calibration);
    let cal = fitted.or_else(|| config.mag_cal.clone());
    let references = match joint.references.clone() {
        Some(references) => references,
        None => pdcal_filter::step_references(&joint.meta, &joint.telemetry)?,
    };
    let mut config = config.clone();
    if let Some(cal) = &cal {
        let mut sigma = crate::calibrate::with_mag_cal(&config, cal, &joint.meta, &mut telemetry)?;
        if config.mag_align == crate::calibrate::MagAlign::Photodiodes {
            let mag_sigma_nt = config.filter.resolve(joint.meta.noise.as_ref()).mag_nt;
            let alignment = crate::mag_align::against_photodiodes(
                &mut telemetry,
                &references,
                mag_sigma_nt,
                |t| {
                    crate::calibrate::photodiode_only_attitude(
                        &joint.meta,
                        t,
                        &references,
                        &config,
                        albedo,
                        &joint.sets,
                    )
                },
            )?;
            // The Monte Carlo's record of the rotation found against the truth's.
            let truth = (sims[0].constants.magnetometer.as_ref())
                .and_then(|m| {
                    pdcal_magcal::align::polar(&nalgebra::Matrix3::from(m.matrix).transpose())
                })
                .map(|(_, q)| {
                    nalgebra::Rotation3::from_matrix(&q)
                        .scaled_axis()
                        .map(f64::to_degrees)
                });
            eprintln!(
                "seed {seed}: truth {:?} deg; {}",
                truth.map(|v| [v.x, v.y, v.z]),
                crate::mag_align::describe(&alignment)
            );
            sigma = sigma.hypot(alignment.sigma_nt);
        }
        config.filter.mag_sigma_nt = Some(sigma);
    }
    let config = &config;
    let calibrate = |telemetry: &pdcal_dataset::Telemetry| {
        crate::calibrate::run_with_references(
            &joint.meta,
            telemetry,
            references.clone(),
            config,
            albedo,
            &joint.sets,
        )
    };
    let mut outcome = calibrate(&telemetry)?;
    for _ in 0..config.mag_align_passes {
        let sigma = config.filter.resolve(joint.meta.noise.as_ref()).mag_nt;
        let estimates = (outcome.run.smoothed.as_ref()).unwrap_or(&outcome.run.forward);
        let misalignment = crate::mag_align::estimate(&telemetry, &references, estimates, sigma)?;
        crate::mag_align::apply(&mut telemetry, &misalignment);
        outcome = calibrate(&telemetry)?;
    }
    let truth = joint_truth(&sims, &joint);
    let s: Summary = summary(&joint.meta, &outcome);
    // The calibration as reported: a quantity the data did not determine at its prior.
    let eval: Evaluation = evaluate_with_smoothed(
        &outcome.run.forward,
        outcome.run.smoothed.as_deref(),
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
    let result = SeedResult {
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
        verdict: s.consistency.verdict.as_str().to_owned(),
        by_status: eval.consistency.by_status,
        attitude_about_sun_inside: eval.consistency.attitude_about_sun_within_3sigma,
        attitude_across_sun_inside: eval.consistency.attitude_across_sun_within_3sigma,
        smoothed_attitude_sun_inside: eval.smoothed.as_ref().map_or((f64::NAN, f64::NAN), |x| {
            (
                x.attitude_about_sun_within_3sigma,
                x.attitude_across_sun_within_3sigma,
            )
        }),
        gyro_bias_inside: eval.consistency.gyro_bias_within_3sigma,
        repeatability: s
            .repeatability
            .as_ref()
            .map_or(String::new(), |r| r.verdict.as_str().to_owned()),
        differing: s
            .repeatability
            .as_ref()
            .map_or(Vec::new(), |r| r.differing.clone()),
        bias_change_warnings: s
            .repeatability
            .as_ref()
            .map_or(0, |r| r.bias_warnings.len()),
        repeat_tests_beyond_3: s.repeatability.as_ref().map_or((0, 0, 0.0), tests_beyond_3),
        about_sun_probes: s
            .segments
            .iter()
            .filter_map(|g| g.about_sun_line.as_ref())
            .fold((0, 0, 0), |(n, turned, undecided), a| {
                (
                    n + 1,
                    turned + usize::from(a.turned),
                    undecided + usize::from(!a.decided),
                )
            }),
        dynamics: (
            s.propagation.dynamics(),
            s.propagation.gyro_rate_test.map(|t| t.chi_square_per_dof),
        ),
        normals_rotation: s.normals_rotation.clone(),
        mounting_warning: crate::schema::mounting_warning_of(&outcome.run),
        sigma_factor: s.dispersion.map_or(1.0, |d| d.sigma_factor),
    };
    Ok(SeedRun {
        result,
        evaluation: eval,
    })
}

/// The calibration parameters' repeatability tests with `|z| > 3`, all of them, and their
/// sum of `z^2`: each set-against-the-others once, each pair once (from its earlier set's
/// side).
fn tests_beyond_3(r: &crate::repeatability::Repeatability) -> (usize, usize, f64) {
    let z: Vec<f64> = r
        .sets
        .iter()
        .enumerate()
        .flat_map(|(k, set)| {
            set.parameters
                .iter()
                .filter(|p| !p.parameter.starts_with("gyro_bias"))
                .flat_map(move |p| {
                    p.vs_other_sets.into_iter().chain(
                        p.vs_sets
                            .iter()
                            .filter(move |d| d.set > k + 1)
                            .map(|d| d.normalised_difference),
                    )
                })
        })
        .collect();
    (
        z.iter().filter(|z| z.abs() > 3.0).count(),
        z.len(),
        z.iter().map(|z| z * z).sum(),
    )
}

/// One seed's run: the figures of merit of `results.json` and the evaluation they come from
/// (with the per-photodiode errors).
#[derive(Debug, Clone)]
pub struct SeedRun {
    /// The row of `results.json`.
    pub result: SeedResult,
    /// The joint calibration's evaluation against the truth.
    pub evaluation: Evaluation,
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
