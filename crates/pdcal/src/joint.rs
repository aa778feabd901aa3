//! Several data sets of one spacecraft calibrated as one (`pdcal calibrate DIR1 DIR2 ...`):
//! the sets are put on one time line (seconds from the earliest set's epoch), each keeps
//! its own orbit for its references, and the filter sees the time between sets as a gap:
//! the calibration states carry over with their random walk grown over it, the attitude
//! and the gyro bias's correlations are re-acquired in each set.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use pdcal_dataset::{
    CurrentColumn, DatasetMeta, OrbitSpec, Samples, Telemetry, TelemetryStorage, TemperatureColumn,
    Vectors,
};
use pdcal_ephem::Reference;
use serde::Serialize;

/// Two nominal angles closer than this are the same mounting, deg.
const SAME_ANGLE_DEG: f64 = 1e-9;

/// One data set of a joint calibration (`summary.json` `datasets`).
#[derive(Debug, Clone, Serialize)]
pub struct SetSpan {
    /// dataset.ron `name`.
    pub name: String,
    /// The directory it was read from.
    pub dir: String,
    /// Its epoch.
    pub epoch_utc: String,
    /// Its epoch on the joint time line, s after the earliest set's epoch.
    pub offset_s: f64,
    /// Its first row in the joint telemetry (the rows of `estimates.csv` count from there).
    pub first_row: usize,
    /// Its rows.
    pub rows: usize,
}

/// The data sets on one time line.
pub struct Joint {
    /// The earliest set's metadata, named after all of them.
    pub meta: DatasetMeta,
    /// Every set's rows, in time order.
    pub telemetry: Telemetry,
    /// With several sets, every row's references, each from its own set's orbit; `None`
    /// for one set, whose references the caller computes from `meta` (stored or per row,
    /// as memory allows).
    pub references: Option<Vec<Reference>>,
    /// The sets, in time order.
    pub sets: Vec<SetSpan>,
}

/// Reads the data sets in `dirs` (never their truth) and joins them ([`join`]).
pub fn read(dirs: &[PathBuf]) -> Result<Vec<(PathBuf, DatasetMeta, Telemetry)>> {
    read_kept(dirs, None)
}

/// [`read`]; with `files = Some((dir, min_bytes))`, a set whose telemetry.csv has at least
/// `min_bytes` keeps its photodiode columns in files of `dir`
/// ([`pdcal_dataset::TelemetryStorage::Files`]): a long set read in memory that does not
/// grow with its photodiode samples.
pub fn read_kept(
    dirs: &[PathBuf],
    files: Option<(&Path, u64)>,
) -> Result<Vec<(PathBuf, DatasetMeta, Telemetry)>> {
    dirs.iter()
        .map(|dir| {
            let meta = pdcal_dataset::read_meta(dir)?;
            let bytes =
                std::fs::metadata(dir.join(pdcal_dataset::TELEMETRY_CSV)).map_or(0, |m| m.len());
            let storage = match files {
                Some((spill, min_bytes)) if bytes >= min_bytes => {
                    TelemetryStorage::Files(spill.to_path_buf())
                }
                _ => TelemetryStorage::Memory,
            };
            let telemetry = pdcal_dataset::read_telemetry_into(dir, &meta, &storage)?;
            Ok((dir.clone(), meta, telemetry))
        })
        .collect()
}

/// Joins data sets of one spacecraft: sorted by epoch, checked to share the photodiode
/// layout and the kind of orbit and not to overlap in time, their rows on the earliest
/// epoch's time line with each set's references from its own orbit.
pub fn join(mut sets: Vec<(PathBuf, DatasetMeta, Telemetry)>) -> Result<Joint> {
    if sets.is_empty() {
        bail!("no data set to calibrate");
    }
    sets.sort_by_key(|s| s.1.epoch_utc.epoch());
    for pair in sets.windows(2) {
        same_layout(&pair[0], &pair[1])?;
    }
    same_spacecraft(&sets)?;
    let first_epoch = sets[0].1.epoch_utc.epoch();
    let mut spans = Vec::with_capacity(sets.len());
    let mut references = Vec::new();
    let mut offsets_s = Vec::with_capacity(sets.len());
    let mut end_s = f64::NEG_INFINITY;
    let several = sets.len() > 1;
    let mut first_row = 0;
    for (dir, meta, telemetry) in &sets {
        if several {
            let refs = pdcal_filter::step_references(meta, telemetry)
                .with_context(|| format!("{}: references", pdcal_text::path(dir)))?;
            references.extend(refs);
        }
        let offset_s = (meta.epoch_utc.epoch() - first_epoch).to_seconds();
        if let Some(&t0) = telemetry.t_s.first()
            && offset_s + t0 <= end_s
        {
            bail!(
                "{}: its first row (t_s = {} s after {}) is not after the last row of the \
                 data set before it: data sets of one calibration must not overlap in time",
                pdcal_text::path(dir),
                pdcal_text::number(t0),
                meta.epoch_utc.as_str()
            );
        }
        end_s = telemetry.t_s.last().map_or(end_s, |t| offset_s + t);
        spans.push(SetSpan {
            name: meta.name.clone(),
            dir: dir.display().to_string(),
            epoch_utc: meta.epoch_utc.as_str().to_owned(),
            offset_s,
            first_row,
            rows: telemetry.len(),
        });
        first_row += telemetry.len();
        offsets_s.push(offset_s);
    }
    let mut meta = sets[0].1.clone();
    if sets.len() > 1 {
        meta.name = sets
            .iter()
            .map(|s| s.1.name.as_str())
            .collect::<Vec<_>>()
            .join(" + ");
    }
    let parts = offsets_s
        .into_iter()
        .zip(sets)
        .map(|(offset_s, (_, _, telemetry))| (offset_s, telemetry));
    Ok(Joint {
        meta,
        telemetry: concat(parts),
        references: several.then_some(references),
        sets: spans,
    })
}

/// Longest time between the first and the last set of a joint calibration, days: the
/// scale-factor random walk is meant for drifts within a mission year; sets further apart
/// are better calibrated separately and compared.
pub const MAX_JOINT_SPAN_DAYS: f64 = 366.0;

/// The checks across all sets that they are one spacecraft's and can run in one mode: every
/// set has a magnetometer or none has (a set without one cannot run in the joint full
/// mode, so it is an error naming it, not a silently skipped set), every TLE names the same
/// object, and the epochs lie within [`MAX_JOINT_SPAN_DAYS`].
fn same_spacecraft(sets: &[(PathBuf, DatasetMeta, Telemetry)]) -> Result<()> {
    let name = |dir: &Path| pdcal_text::path(dir);
    if let Some(with) = sets.iter().find(|s| s.2.mag_nt.is_some())
        && let Some(without) = sets.iter().find(|s| s.2.mag_nt.is_none())
    {
        bail!(
            "{}: has no magnetometer columns (mag_x_nT, mag_y_nT, mag_z_nT), but {} has: a \
             joint calibration runs in one mode, and this set cannot run in the full mode the \
             others need; calibrate it alone (photodiode-only), or the others without it",
            name(&without.0),
            name(&with.0)
        );
    }
    let object = |meta: &DatasetMeta| match &meta.orbit {
        OrbitSpec::Tle { line1, .. } => line1.get(2..7).map(|n| n.trim().to_owned()),
        OrbitSpec::PositionColumns => None,
    };
    if let Some(first) = sets.first()
        && let Some(a) = object(&first.1)
    {
        for (dir, meta, _) in &sets[1..] {
            if let Some(b) = object(meta)
                && a != b
            {
                bail!(
                    "{}: its TLE is of object {}, but {}'s is of object {}: data sets of one \
                     calibration must be one spacecraft's (another spacecraft's TLE?)",
                    name(dir),
                    pdcal_text::quote(&b),
                    name(&first.0),
                    pdcal_text::quote(&a)
                );
            }
        }
    }
    if let (Some(first), Some(last)) = (sets.first(), sets.last()) {
        let days = (last.1.epoch_utc.epoch() - first.1.epoch_utc.epoch()).to_seconds() / 86_400.0;
        if days > MAX_JOINT_SPAN_DAYS {
            bail!(
                "{}: its epoch is {days:.0} days after {}'s, more than the {MAX_JOINT_SPAN_DAYS} \
                 days one joint calibration spans; calibrate the sets separately and compare \
                 the results",
                name(&last.0),
                name(&first.0)
            );
        }
    }
    Ok(())
}

/// The first difference between two sets' photodiode layouts or orbit kinds, as an error.
fn same_layout(
    (dir_a, a, _): &(PathBuf, DatasetMeta, Telemetry),
    (dir_b, b, _): &(PathBuf, DatasetMeta, Telemetry),
) -> Result<()> {
    let name = |dir: &Path| pdcal_text::path(dir.join("dataset.ron"));
    if a.photodiodes.len() != b.photodiodes.len() {
        bail!(
            "{} has {} photodiodes, {} has {}: data sets of one calibration must share the \
             photodiode layout",
            name(dir_b),
            b.photodiodes.len(),
            name(dir_a),
            a.photodiodes.len()
        );
    }
    for (i, (pa, pb)) in a.photodiodes.iter().zip(&b.photodiodes).enumerate() {
        for (what, va, vb) in [
            ("azimuth_deg", pa.azimuth_deg, pb.azimuth_deg),
            ("elevation_deg", pa.elevation_deg, pb.elevation_deg),
        ] {
            if (va - vb).abs() > SAME_ANGLE_DEG {
                bail!(
                    "{}: photodiode {} {what} = {vb}, but {} has {va}: data sets of one \
                     calibration must share the photodiode layout",
                    name(dir_b),
                    i + 1,
                    name(dir_a)
                );
            }
        }
    }
    let kind = |o: &OrbitSpec| match o {
        OrbitSpec::Tle { .. } => "a TLE",
        OrbitSpec::PositionColumns => "position columns",
    };
    if kind(&a.orbit) != kind(&b.orbit) {
        bail!(
            "{}: the orbit is {}, but {} has {}: data sets of one calibration must give the \
             orbit the same way",
            name(dir_b),
            kind(&b.orbit),
            name(dir_a),
            kind(&a.orbit)
        );
    }
    Ok(())
}

/// The rows of every part, times shifted by its offset; a column one part lacks is blank
/// there (the magnetometer of a set that has none, a temperature another set did not log).
fn concat(parts: impl Iterator<Item = (f64, Telemetry)>) -> Telemetry {
    let mut parts: Vec<(f64, Telemetry)> = parts.collect();
    // One set is the joint telemetry itself, its times moved in place: no copy.
    if parts.len() == 1
        && let Some((offset_s, mut telemetry)) = parts.pop()
    {
        telemetry.t_s.iter_mut().for_each(|x| *x += offset_s);
        return telemetry;
    }
    let any_mag = parts.iter().any(|(_, t)| t.mag_nt.is_some());
    let all_positions = parts.iter().all(|(_, t)| t.r_gcrf_km.is_some());
    let m = parts.first().map_or(0, |(_, t)| t.pd_v.len());
    let mut names: Vec<String> = Vec::new();
    let mut currents: Vec<String> = Vec::new();
    for (_, t) in &parts {
        for c in &t.temperature_c {
            if !names.contains(&c.name) {
                names.push(c.name.clone());
            }
        }
        for c in &t.current_a {
            if !currents.contains(&c.name) {
                currents.push(c.name.clone());
            }
        }
    }
    let mut out = Telemetry {
        t_s: Vec::new(),
        gyro_rad_s: Vectors::new(),
        mag_nt: any_mag.then(Vectors::new),
        pd_v: vec![Samples::new(); m],
        r_gcrf_km: all_positions.then(Vectors::new),
        temperature_c: names
            .iter()
            .map(|name| TemperatureColumn {
                name: name.clone(),
                values: Vec::new(),
            })
            .collect(),
        current_a: currents
            .iter()
            .map(|name| CurrentColumn {
                name: name.clone(),
                values: Vec::new(),
            })
            .collect(),
    };
    // Each set is dropped once appended: the sets and the joint copy together never take
    // more than the joint rows and the largest set.
    for (offset_s, t) in parts {
        let rows = t.len();
        out.t_s.extend(t.t_s.iter().map(|x| x + offset_s));
        out.gyro_rad_s.extend(t.gyro_rad_s.iter());
        if let Some(mag) = out.mag_nt.as_mut() {
            match &t.mag_nt {
                Some(m) => mag.extend(m.iter()),
                None => mag.extend(std::iter::repeat_n(None, rows)),
            }
        }
        for (column, theirs) in out.pd_v.iter_mut().zip(&t.pd_v) {
            theirs.iter().for_each(|v| column.push(v));
        }
        if let (Some(r), Some(theirs)) = (out.r_gcrf_km.as_mut(), &t.r_gcrf_km) {
            r.extend(theirs.iter());
        }
        for column in &mut out.temperature_c {
            match t.temperature_c.iter().find(|c| c.name == column.name) {
                Some(theirs) => column.values.extend_from_slice(&theirs.values),
                None => column.values.extend(std::iter::repeat_n(None, rows)),
            }
        }
        for column in &mut out.current_a {
            match t.current_a.iter().find(|c| c.name == column.name) {
                Some(theirs) => column.values.extend_from_slice(&theirs.values),
                None => column.values.extend(std::iter::repeat_n(None, rows)),
            }
        }
    }
    out
}

/// Each set's own estimate for the repeatability check ([`crate::repeatability`]): a
/// forward pass over the set's rows alone (the run's machinery, no smoother: the last row's
/// forward estimate is the set's whole information), from the same configuration and mode
/// as the joint run, with the statuses judged from its own covariance and residuals. Its
/// covariance is widened as a calibration of that set alone would widen it (the residuals'
/// spread and the multi-start ensemble, [`pdcal_filter::ensemble`]): without the ensemble a
/// set whose Sun-only start settled on a wrong solution holds it with the filter's own,
/// too small sigma, and the comparison of sets says "differs" where the data decided
/// nothing.
/// `meta` and `telemetry` are the joint run's (mountings corrected, screened), `references`
/// one per joint row. A set whose own pass fails is kept with the reason.
pub fn own_estimates(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    references: &[Reference],
    sets: &[SetSpan],
    (config, mode): (&pdcal_filter::FilterConfig, &pdcal_filter::Mode),
    albedo: &pdcal_albedo::AlbedoModel,
) -> Vec<crate::repeatability::SetInput> {
    sets.iter()
        .map(|span| {
            let rows = span.first_row..span.first_row + span.rows;
            let end_s = telemetry.t_s.get(rows.end.wrapping_sub(1)).copied();
            crate::repeatability::SetInput {
                name: span.name.clone(),
                end_s: end_s.unwrap_or(span.offset_s),
                estimate: own_estimate(meta, telemetry, references, rows, (config, mode), albedo),
            }
        })
        .collect()
}

/// The forward pass of one set's `rows` ([`own_estimates`]), or why it failed.
fn own_estimate(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    references: &[Reference],
    rows: std::ops::Range<usize>,
    (config, mode): (&pdcal_filter::FilterConfig, &pdcal_filter::Mode),
    albedo: &pdcal_albedo::AlbedoModel,
) -> Result<crate::repeatability::SetEstimate, String> {
    let part = telemetry.select_rows(|k| rows.contains(&k));
    let refs = references.get(rows).ok_or("no references for its rows")?;
    let mut filter = config.clone();
    filter.smoother = false;
    let prepared = pdcal_filter::Prepared::new(meta, std::borrow::Cow::Owned(part), &filter)
        .map_err(|e| format!("its own pass failed: {e}"))?;
    let inputs = pdcal_filter::RunInputs {
        meta,
        telemetry: prepared.telemetry(),
        references: pdcal_filter::References::Stored(refs),
        albedo: Some(albedo),
        set_first_rows: &[],
    };
    let sigmas = prepared.sigmas();
    let mut sink = VerdictSink(pdcal_filter::ConsistencyAccumulator::new(
        meta.photodiodes.len(),
        sigmas.photodiode_v,
        sigmas.mag_nt,
    ));
    let model = || pdcal_filter::paper_model(pdcal_filter::nominal_photodiodes(meta), &filter);
    let run = pdcal_filter::calibrate_streaming(
        &inputs,
        &prepared,
        mode,
        (model(), Some(&model)),
        pdcal_filter::Algebra::Structured,
        pdcal_filter::SMOOTHER_BLOCK_ROWS,
        &mut sink,
    )
    .map_err(|e| format!("its own pass failed: {e}"))?;
    let evidence = pdcal_filter::identifiability::Evidence::of_run(&run, sink.0.finish().verdict);
    Ok(crate::repeatability::SetEstimate {
        photodiodes: pdcal_filter::identifiability::judge_photodiodes(&evidence),
        gyro_bias: pdcal_filter::identifiability::judge_gyro_bias(&evidence),
        calibration: run.calibration,
    })
}

/// A run's sink that keeps only the consistency of its residuals.
struct VerdictSink(pdcal_filter::ConsistencyAccumulator);

impl pdcal_filter::RunSink for VerdictSink {
    fn forward(
        &mut self,
        _: &pdcal_filter::StepEstimate,
        residuals: &[pdcal_filter::ResidualRecord],
    ) {
        residuals.iter().for_each(|r| self.0.push(r));
    }

    fn smoothed(&mut self, _: &[pdcal_filter::StepEstimate]) {}
}
