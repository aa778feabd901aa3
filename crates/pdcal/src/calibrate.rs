//! `pdcal calibrate`: a dataset in, the calibration and its evidence out.

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use std::time::Instant;

use anyhow::{Context, Result, bail};
use pdcal_albedo::{AlbedoModel, MapChoice};

/// The albedo model type, re-exported for callers that hold one (xtask).
pub type AlbedoModelType = AlbedoModel;
use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_filter::{Algebra, Calibration, FilterConfig, Mode, Prepared, References, RunInputs};

use crate::output::OutputDir;
pub use crate::schema::{DatasetSummary, Outcome};
pub use crate::stream::CancelCheck;
use crate::stream::StreamSink;

/// The resolved run configuration: filter tuning and mode.
#[derive(Debug, Clone)]
pub struct RunConfig {
    /// Filter tuning.
    pub filter: FilterConfig,
    /// Full, photodiode-only or scale-only with a prior.
    pub mode: Mode,
    /// A magnetometer calibration (`--mag-cal`) applied to the telemetry before the filter.
    pub mag_cal: Option<pdcal_magcal::MagCalibration>,
    /// The file `mag_cal` was read from, named in every message about it.
    pub mag_cal_file: Option<PathBuf>,
    /// Calibrate the magnetometer from each run's own data first (`pdcal magcal`) and apply
    /// that (the Monte Carlo's `--magcal`); ignored when `mag_cal` is given.
    pub fit_mag_cal: bool,
    /// Passes of the magnetometer's rotation against the first calibration's attitude
    /// (`crate::mag_align`) in the Monte Carlo with a magnetometer calibration: 0 by default
    /// (docs/magcal.md, "The rotation against the body": each pass recovers only a few
    /// percent of the rotation).
    pub mag_align_passes: usize,
    /// How the magnetometer's rotation against the body, which the field magnitude cannot
    /// see, is found after a magnetometer calibration (docs/magcal.md).
    pub mag_align: MagAlign,
}

/// The magnetometer's rotation against the body after `--mag-cal` (docs/magcal.md, "The
/// rotation against the body").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum MagAlign {
    /// Left as the calibration gives it (the symmetric form's frame).
    Off,
    /// Solved against the attitude of a photodiode-only calibration of the same rows
    /// ([`crate::mag_align::against_photodiodes`]), then removed.
    #[default]
    Photodiodes,
}

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            filter: FilterConfig::default(),
            mode: Mode::Full,
            mag_cal: None,
            mag_cal_file: None,
            fit_mag_cal: false,
            mag_align_passes: 0,
            mag_align: MagAlign::default(),
        }
    }
}

/// Reads `--config`: either a filter configuration or a previous `calibration.ron`, which
/// becomes the prior of a scale-factors-only run (the paper's third data set).
pub fn load_config(path: &Path) -> Result<RunConfig> {
    let text =
        pdcal_dataset::bounded::read_text_bounded(path, pdcal_dataset::bounded::MAX_RON_BYTES)
            .with_context(|| format!("cannot read {}", pdcal_text::path(path)))?;
    match Calibration::from_ron_str(&text) {
        Ok(prior) => {
            return Ok(RunConfig {
                filter: FilterConfig::default(),
                mode: Mode::ScaleOnly { prior },
                ..RunConfig::default()
            });
        }
        // A calibration.ron with a bad value gets the calibration's own message, not the
        // filter configuration's "unknown field".
        Err(e) if has_field(&text, "gyro_bias_rad_s") && has_field(&text, "photodiodes") => {
            return Err(e).with_context(|| pdcal_text::path(path).to_string());
        }
        Err(_) => {}
    }
    if let Some(kind) = other_kind_of_file(&text) {
        bail!(
            "{}: this is {kind}, not a --config file; --config expects a filter configuration \
             (RON with fields such as photodiode_sigma_v, gate_sigmas) or the calibration.ron \
             of an earlier pdcal calibrate",
            pdcal_text::path(path)
        );
    }
    let filter =
        FilterConfig::from_ron_str(&text).with_context(|| pdcal_text::path(path).to_string())?;
    if filter.dynamics_gyro_step_s.is_some() {
        eprintln!(
            "pdcal: warning: {}: dynamics_gyro_step_s is no longer used: dynamics: Auto now \
             tests whether the gyro's rate changes between its samples beyond its noise \
             (summary.json propagation); use dynamics: On or Off to choose",
            pdcal_text::path(path)
        );
    }
    Ok(RunConfig {
        filter,
        ..RunConfig::default()
    })
}

/// What a file passed as `--config` is when it is another pdcal file, recognised by the
/// fields only that kind has (so the message names it instead of an unexpected field).
fn other_kind_of_file(text: &str) -> Option<&'static str> {
    let has = |field: &str| has_field(text, field);
    let first_line = text.lines().next().unwrap_or("");
    if first_line.split(',').any(|c| c.trim() == "t_s") {
        Some("a CSV table (telemetry.csv or truth.csv)")
    } else if has("epoch_utc") && has("orbit") && !has("spacecraft") {
        Some("a dataset.ron (dataset metadata)")
    } else if has("duration_s") && has("spacecraft") {
        Some("a scenario (simulate --scenario)")
    } else if has("effects") && has("photodiodes") {
        Some("a truth.ron (simulated truth constants)")
    } else {
        None
    }
}

/// Whether RON `text` has a field named `field` (a whole word followed by `:`).
fn has_field(text: &str, field: &str) -> bool {
    text.match_indices(field).any(|(i, _)| {
        let before = text[..i].chars().next_back();
        let after = text[i + field.len()..].trim_start().chars().next();
        !before.is_some_and(|c| c.is_alphanumeric() || c == '_') && after == Some(':')
    })
}

/// The reflectivity map the filter uses: the paper's TOMS map.
pub const ALBEDO_MAP: MapChoice = MapChoice::TomsMean1p25x1;

/// The albedo model the filter uses ([`ALBEDO_MAP`]).
pub fn albedo_model() -> Result<AlbedoModel> {
    Ok(AlbedoModel::from_choice(&ALBEDO_MAP)?)
}

/// Calibrates a dataset held in memory (never its truth).
pub fn run(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    config: &RunConfig,
    albedo: &AlbedoModel,
) -> Result<Outcome> {
    let references = pdcal_filter::step_references(meta, telemetry)?;
    run_with_references(meta, telemetry, references, config, albedo, &[])
}

/// [`run`] with the references given: a joint calibration's ([`crate::joint::Joint`]),
/// each row's from its own set's orbit, and its `sets` (with several, their repeatability
/// is checked, [`crate::repeatability`]).
pub fn run_with_references(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    references: Vec<pdcal_ephem::Reference>,
    config: &RunConfig,
    albedo: &AlbedoModel,
    sets: &[crate::joint::SetSpan],
) -> Result<Outcome> {
    let mut warnings = crate::checks::check_telemetry(telemetry)?;
    warnings.extend(crate::checks::orbit_age(meta, telemetry, "dataset.ron"));
    let set_rows: Vec<(usize, usize)> = sets.iter().map(|s| (s.first_row, s.rows)).collect();
    let axes = crate::axes::check(
        meta,
        telemetry,
        &(&references).into(),
        &config.filter,
        &set_rows,
    )?;
    warnings.extend(axes.finding.iter().map(crate::axes::message));
    let (meta, telemetry) = crate::axes::corrected(&axes, meta, telemetry);
    let (meta, telemetry) = (meta.as_ref(), telemetry.as_ref());
    let mountings = crate::mounting::check(
        meta,
        telemetry,
        (&references).into(),
        &config.filter,
        albedo,
    )?;
    warnings.extend(mountings.iter().map(|f| f.message()));
    let (meta, telemetry) = crate::mounting::corrected(&mountings, meta, telemetry);
    let (meta, telemetry) = (meta.as_ref(), telemetry.as_ref());
    let later_sets: Vec<usize> = sets.iter().skip(1).map(|s| s.first_row).collect();
    let inputs = RunInputs {
        meta,
        telemetry,
        references: (&references).into(),
        albedo: Some(albedo),
        set_first_rows: &later_sets,
    };
    let start = Instant::now();
    let run = pdcal_filter::calibrate(&inputs, &config.filter, &config.mode)
        .with_context(|| filter_failed(&warnings))?;
    let runtime_s = start.elapsed().as_secs_f64();
    let sun_vector = crate::sunvec::metrics(
        meta,
        telemetry,
        inputs.references,
        &run,
        albedo,
        &config.filter,
    )?;
    let mut consistency = pdcal_filter::consistency::judge(
        &run.residuals,
        meta.photodiodes.len(),
        run.sensor_sigmas.photodiode_v,
        run.sensor_sigmas.mag_nt,
    );
    pdcal_filter::dark::judge(&mut consistency, telemetry, &inputs.references, &run)
        .context("the photodiodes in the umbra")?;
    let repeatability = repeatability_of(meta, telemetry, &references, sets, config, albedo);
    if let Some(r) = &repeatability {
        r.apply(&mut consistency, &mut warnings);
    }
    Ok(Outcome {
        residuals: crate::schema::residual_summary(&run.residuals),
        consistency,
        run,
        sun_vector,
        runtime_s,
        warnings,
        datasets: Vec::new(),
        mountings,
        repeatability,
        axes,
    })
}

/// The repeatability of a joint calibration's `sets` ([`crate::repeatability`]), from each
/// set's own pass over `meta` and `telemetry` (as the joint run saw them); `None` for one set.
fn repeatability_of(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    references: &[pdcal_ephem::Reference],
    sets: &[crate::joint::SetSpan],
    config: &RunConfig,
    albedo: &AlbedoModel,
) -> Option<crate::repeatability::Repeatability> {
    (sets.len() > 1).then(|| {
        let own = crate::joint::own_estimates(
            meta,
            telemetry,
            references,
            sets,
            (&config.filter, &config.mode),
            albedo,
        );
        crate::repeatability::compare(
            &own,
            &crate::repeatability::Walks::of(&config.filter),
            config.filter.initial_bias_sigma_deg_s.to_radians(),
        )
    })
}

/// The physical checks of every set before they are joined ([`crate::checks`]), and the
/// age of its TLE: with several sets, a fault or warning names the set's directory and its
/// own times (joined, the times would be the joint time line's and no set would be named).
fn check_sets(sets: &[(PathBuf, DatasetMeta, Telemetry)]) -> Result<Vec<String>> {
    let mut warnings = Vec::new();
    for (dir, meta, telemetry) in sets {
        let prefix = if sets.len() > 1 {
            format!("{}: ", pdcal_text::path(dir))
        } else {
            String::new()
        };
        let found = crate::checks::check_telemetry(telemetry)
            .map_err(|e| anyhow::anyhow!("{prefix}{e:#}"))?;
        warnings.extend(found.into_iter().map(|w| format!("{prefix}{w}")));
        let dataset_ron = pdcal_text::path(dir.join("dataset.ron"));
        warnings.extend(crate::checks::orbit_age(meta, telemetry, &dataset_ron));
    }
    Ok(warnings)
}

/// The context of a failed filter run: the input's warnings so far (a TLE years from the
/// data puts every row in eclipse), which a failure would otherwise lose.
fn filter_failed(warnings: &[String]) -> String {
    match warnings.is_empty() {
        true => "calibration filter".to_owned(),
        false => format!(
            "calibration filter (the input's warnings, which may say why: {})",
            warnings.join("; ")
        ),
    }
}

/// Rows up to which [`run_dirs`] computes the references once and stores them (176 bytes
/// a row, 23 MB at most); above, each row's is computed when it is reached, so that memory
/// does not grow with the rows, at the price of computing it four times (the forward
/// pass, the smoother's replay, the Sun-vector metrics, the umbra levels of
/// [`pdcal_filter::dark`]). The same values either way. A
/// joint calibration of several sets stores them always (each set has its own orbit).
pub const STORED_REFERENCE_ROWS: usize = 1 << 17;

/// `pdcal calibrate DATASET_DIR --out OUT_DIR [--config FILE.ron]`: [`run_dirs`] of one
/// data set.
pub fn run_dir(dataset: &Path, out: &Path, config: &RunConfig) -> Result<Outcome> {
    Ok(run_dirs(&[dataset.to_path_buf()], out, config)?.0)
}

/// `pdcal calibrate DIR1 [DIR2 ...] --out OUT_DIR [--config FILE.ron]`: one calibration of
/// one or more data sets of the same spacecraft ([`crate::joint`]).
///
/// Streams ([`pdcal_filter::calibrate_streaming`]): the CSVs are written into the staging
/// directory as the rows are produced, the smoother works block by block, and the
/// returned [`Outcome`]'s `run` holds the estimates and residuals of every
/// [`crate::stream::stride_for`]-th row only (what the figures plot), no smoothed vector.
pub fn run_dirs(
    datasets: &[PathBuf],
    out: &Path,
    config: &RunConfig,
) -> Result<(Outcome, crate::schema::Summary)> {
    run_dirs_forced(datasets, out, config, false)
}

/// [`run_dirs`]; with `force`, an earlier calibration in `out` is replaced even when its
/// files were changed since (`--force`).
pub fn run_dirs_forced(
    datasets: &[PathBuf],
    out: &Path,
    config: &RunConfig,
    force: bool,
) -> Result<(Outcome, crate::schema::Summary)> {
    run_dirs_kept(datasets, out, config, force, FILE_TELEMETRY_BYTES)
}

/// A telemetry.csv of at least this many bytes (about 140 000 rows of the rax2-like
/// layout) keeps its photodiode, gyro, magnetometer and position columns in files of the
/// output's staging directory, read
/// by blocks ([`pdcal_dataset::TelemetryStorage::Files`]); a smaller one is held in memory,
/// where it costs at most about 20 MB and is read without the cache's lookups.
pub const FILE_TELEMETRY_BYTES: u64 = 64 << 20;

/// [`run_dirs_forced`] with the size from which a set's columns are kept in
/// files instead of [`FILE_TELEMETRY_BYTES`] (0: always; the same outputs either way).
pub fn run_dirs_kept(
    datasets: &[PathBuf],
    out: &Path,
    config: &RunConfig,
    force: bool,
    file_telemetry_bytes: u64,
) -> Result<(Outcome, crate::schema::Summary)> {
    let inputs: Vec<&Path> = datasets.iter().map(PathBuf::as_path).collect();
    let dir = OutputDir::create_reading(out, "calibrate", force, &inputs)?;
    // Only meta and telemetry: calibrate never reads truth.*.
    let mut sets = crate::joint::read_kept(datasets, Some((dir.path(), file_telemetry_bytes)))?;
    let Some(cal) = &config.mag_cal else {
        return run_sets(sets, dir, config, None);
    };
    let mut config = config.clone();
    let mut worst_sigma_nt: f64 = 0.0;
    for (path, meta, telemetry) in &mut sets {
        let file = config
            .mag_cal_file
            .as_deref()
            .unwrap_or(Path::new("magcal.ron"));
        let sigma = with_mag_cal(&config, cal, meta, telemetry).with_context(|| {
            format!(
                "--mag-cal {} on {}",
                pdcal_text::path(file),
                pdcal_text::path(&path)
            )
        })?;
        worst_sigma_nt = worst_sigma_nt.max(sigma);
    }
    if config.mag_align == MagAlign::Photodiodes {
        let alignment = align_sets(&mut sets, &config)?;
        worst_sigma_nt = worst_sigma_nt.hypot(alignment.sigma_nt);
    }
    config.filter.mag_sigma_nt = Some(worst_sigma_nt);
    run_sets(sets, dir, &config, None)
}

/// The magnetometer's rotation against the photodiodes' frame, solved over every set at
/// once (it is the hardware's) and removed from each ([`crate::mag_align`]); said on
/// stderr, and when the fit is not consistent, why it was left in.
fn align_sets(
    sets: &mut [(PathBuf, DatasetMeta, Telemetry)],
    config: &RunConfig,
) -> Result<crate::mag_align::PhotodiodeAlignment> {
    let joint = crate::joint::join(sets.to_vec())?;
    let references = match joint.references {
        Some(references) => references,
        None => pdcal_filter::step_references(&joint.meta, &joint.telemetry)?,
    };
    let mut telemetry = joint.telemetry;
    let albedo = albedo_model()?;
    let mag_sigma_nt = config.filter.resolve(joint.meta.noise.as_ref()).mag_nt;
    let alignment =
        crate::mag_align::against_photodiodes(&mut telemetry, &references, mag_sigma_nt, |t| {
            photodiode_only_attitude(&joint.meta, t, &references, config, &albedo, &joint.sets)
        })?;
    eprintln!("{}", crate::mag_align::describe(&alignment));
    if let (None, Some(misalignment)) = (&alignment.refused, &alignment.misalignment) {
        for (_, _, telemetry) in sets.iter_mut() {
            crate::mag_align::apply(telemetry, misalignment);
        }
    }
    Ok(alignment)
}

/// The attitude estimates (smoothed when there are) of a photodiode-only calibration of
/// `telemetry` with `config`'s tuning: the attitude in the frame the gyro and the
/// photodiodes define, for [`crate::mag_align::against_photodiodes`].
pub fn photodiode_only_attitude(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    references: &[pdcal_ephem::Reference],
    config: &RunConfig,
    albedo: &AlbedoModel,
    sets: &[crate::joint::SetSpan],
) -> Result<Vec<pdcal_filter::StepEstimate>> {
    let photodiode_only = RunConfig {
        mode: Mode::PhotodiodeOnly,
        ..config.clone()
    };
    let outcome = run_with_references(
        meta,
        telemetry,
        references.to_vec(),
        &photodiode_only,
        albedo,
        sets,
    )
    .context("the photodiode-only calibration")?;
    Ok(outcome.run.smoothed.unwrap_or(outcome.run.forward))
}

/// Corrects `telemetry`'s magnetometer with `cal` and returns the magnetometer noise the
/// filter should then use: the configured (or hinted) sigma and the correction's own
/// uncertainty added in quadrature (docs/magcal.md).
pub fn with_mag_cal(
    config: &RunConfig,
    cal: &pdcal_magcal::MagCalibration,
    meta: &DatasetMeta,
    telemetry: &mut Telemetry,
) -> Result<f64> {
    let cal_sigma = crate::magcal::apply(telemetry, cal)?;
    let base = config.filter.resolve(meta.noise.as_ref()).mag_nt;
    Ok(base.hypot(cal_sigma))
}

/// The largest number of photodiodes `calibrate` and `diagnose` accept
/// (docs/performance.md, "Many photodiodes"): the filter's state grows as `3 m`, its
/// covariance as `9 m^2` and the smoother's work per row as `27 m^3`, so beyond this count a
/// two-hour set takes more than an hour; a larger set is refused before any computation.
pub const MAX_PHOTODIODES: usize = 200;

/// Memory the streaming smoother's block of stored rows may take, bytes: the block shrinks
/// as the state grows, so that many photodiodes do not multiply the memory.
pub const SMOOTHER_BLOCK_BYTES: usize = 64 << 20;

/// Rows per block of the streaming smoother for `m` photodiodes: the filter's
/// [`pdcal_filter::SMOOTHER_BLOCK_ROWS`], fewer when one block of stored covariances (the
/// lower triangle of `n x n`, `n = 6 + 3 m`) would exceed [`SMOOTHER_BLOCK_BYTES`].
pub fn smoother_block_rows(m: usize) -> usize {
    let n = 6 + 3 * m;
    let per_row = 8 * (n * (n + 1) / 2 + 2 * n);
    (SMOOTHER_BLOCK_BYTES / per_row).clamp(16, pdcal_filter::SMOOTHER_BLOCK_ROWS)
}

/// Refuses a layout of more than [`MAX_PHOTODIODES`] photodiodes, naming the limit.
pub fn check_photodiode_count(m: usize, what: &str) -> Result<()> {
    if m > MAX_PHOTODIODES {
        bail!(
            "{what}: {m} photodiodes, more than the {MAX_PHOTODIODES} pdcal calibrates (the \
             filter's work grows as the cube of the count; docs/performance.md, \"Many \
             photodiodes\"); calibrate a subset of at most {MAX_PHOTODIODES} (the others' \
             columns left empty or removed) at a time"
        );
    }
    Ok(())
}

/// The references of a run: the stored ones when there are, else computed per row.
fn references_of<'a>(
    stored: Option<&'a [pdcal_ephem::Reference]>,
    model: &'a pdcal_filter::ReferenceModel,
    t_s: &'a [f64],
) -> References<'a> {
    match stored {
        Some(stored) => References::Stored(stored),
        None => References::Computed { model, t_s },
    }
}

/// The calibration of [`run_dirs`] on data sets held in memory (each with the directory
/// it stands for, named in `summary.json` `datasets`), its outputs written into `dir` and
/// published there; `cancel` may stop it.
pub fn run_sets(
    sets: Vec<(PathBuf, DatasetMeta, Telemetry)>,
    dir: OutputDir,
    config: &RunConfig,
    cancel: Option<CancelCheck>,
) -> Result<(Outcome, crate::schema::Summary)> {
    if let Some((dir, meta, _)) = sets.first() {
        check_photodiode_count(meta.photodiodes.len(), &pdcal_text::path(dir))?;
    }
    let mut warnings = check_sets(&sets)?;
    let joint = crate::joint::join(sets)?;
    let mut meta = joint.meta;
    // Prepared (screened) once, here: the mounting check, the Sun-vector metrics and the
    // figures read the telemetry the filter reads, and never see a wild sample.
    let mut prepared = Prepared::new(&meta, Cow::Owned(joint.telemetry), &config.filter)
        .with_context(|| filter_failed(&warnings))?;
    let albedo = albedo_model()?;
    let reference_model = pdcal_filter::reference_model(&meta, prepared.telemetry())?;
    let stored = match joint.references {
        Some(joint) => Some(joint),
        None if prepared.telemetry().len() <= STORED_REFERENCE_ROWS => {
            Some(pdcal_filter::step_references(&meta, prepared.telemetry())?)
        }
        None => None,
    };
    let axes = crate::axes::check(
        &meta,
        prepared.telemetry(),
        &references_of(
            stored.as_deref(),
            &reference_model,
            &prepared.telemetry().t_s,
        ),
        &config.filter,
        &joint
            .sets
            .iter()
            .map(|s| (s.first_row, s.rows))
            .collect::<Vec<_>>(),
    )?;
    crate::axes::apply(&axes, &mut meta, prepared.telemetry_mut());
    warnings.extend(axes.finding.iter().map(crate::axes::message));
    let mountings = crate::mounting::check(
        &meta,
        prepared.telemetry(),
        references_of(
            stored.as_deref(),
            &reference_model,
            &prepared.telemetry().t_s,
        ),
        &config.filter,
        &albedo,
    )?;
    crate::mounting::apply(&mountings, &mut meta, prepared.telemetry_mut());
    warnings.extend(mountings.iter().map(|f| f.message()));
    let telemetry = prepared.telemetry();
    let references = references_of(stored.as_deref(), &reference_model, &telemetry.t_s);
    let set_starts: Vec<usize> = joint.sets.iter().map(|s| s.first_row).collect();
    let inputs = RunInputs {
        meta: &meta,
        telemetry,
        references,
        albedo: Some(&albedo),
        set_first_rows: &set_starts[1.min(set_starts.len())..],
    };
    let sigmas = prepared.sigmas();
    let mut sink = StreamSink::new(
        &dir,
        meta.photodiodes.len(),
        telemetry.len(),
        config.filter.smoother,
        &sigmas,
    )?
    .with_sets(&set_starts)
    .with_cancel(cancel);
    let start = Instant::now();
    let model =
        || pdcal_filter::paper_model(pdcal_filter::nominal_photodiodes(&meta), &config.filter);
    let mut run = pdcal_filter::calibrate_streaming(
        &inputs,
        &prepared,
        &config.mode,
        (model(), Some(&model)),
        Algebra::Structured,
        smoother_block_rows(meta.photodiodes.len()),
        &mut sink,
    )
    .with_context(|| filter_failed(&warnings))?;
    let runtime_s = start.elapsed().as_secs_f64();
    let streamed = sink.finish()?;
    run.forward = streamed.forward_sample;
    run.residuals = streamed.residual_sample;
    run.smoothed = None;
    let sun_vector = crate::sunvec::metrics_along(
        &meta,
        telemetry,
        references,
        &run,
        streamed.attitudes.rows()?,
        &albedo,
        &config.filter,
    )?;
    streamed.attitudes.remove()?;
    let mut consistency = streamed.consistency;
    pdcal_filter::dark::judge(&mut consistency, telemetry, &inputs.references, &run)
        .context("the photodiodes in the umbra")?;
    let repeatability = match stored.as_deref() {
        Some(stored) => repeatability_of(&meta, telemetry, stored, &joint.sets, config, &albedo),
        None => None,
    };
    if let Some(r) = &repeatability {
        r.apply(&mut consistency, &mut warnings);
    }
    let set_repeatability = |k: usize| repeatability.as_ref().and_then(|r| r.sets.get(k).cloned());
    let outcome = Outcome {
        run,
        sun_vector,
        residuals: streamed.residual_summary,
        consistency,
        runtime_s,
        warnings,
        // Listed for a joint calibration only: one set is the summary itself.
        datasets: match joint.sets.len() {
            1 => Vec::new(),
            _ => joint
                .sets
                .into_iter()
                .zip(streamed.set_residuals)
                .zip(streamed.set_consistency)
                .enumerate()
                .map(|(k, ((span, residuals), consistency))| DatasetSummary {
                    span,
                    residuals,
                    consistency,
                    repeatability: set_repeatability(k),
                })
                .collect(),
        },
        mountings,
        repeatability,
        axes,
    };
    let summary = crate::schema::summary(&meta, &outcome);
    crate::files::write_summary_and_figures(dir, telemetry, &outcome, &summary, None)?;
    Ok((outcome, summary))
}
