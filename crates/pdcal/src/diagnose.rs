//! `pdcal diagnose DATASET_DIR --out OUT_DIR [--base-model cosine|paper]`: find, name and
//! add the effects the model is missing (`pdcal-diagnose`), and write `diagnosis.json`,
//! `report.md`, the residual-signature figures and `index.html`, whole or not at all.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_diagnose::{BaseModel, DiagnoseConfig, DiagnoseInputs, Diagnosis, Gap, Signature};
use pdcal_report::{BinRange, Figure, HistogramPanel, LineAxes, Mark, Series, histograms, lines};

use crate::output::{OutputDir, write_file};

/// Bins of the binned residual-signature figures.
const SIGNATURE_BINS: usize = 40;

/// A finished diagnosis and its run time.
pub struct DiagnoseOutcome {
    /// The diagnosis.
    pub diagnosis: Diagnosis,
    /// Wall-clock time of the diagnosis (all calibrations and fits), s.
    pub runtime_s: f64,
    /// Physical-plausibility warnings on the input ([`crate::checks`]), one line each.
    pub warnings: Vec<String>,
}

/// Diagnoses a dataset held in memory (its metadata and telemetry: never its truth).
pub fn run(meta: &DatasetMeta, telemetry: &Telemetry, base: BaseModel) -> Result<DiagnoseOutcome> {
    crate::calibrate::check_photodiode_count(meta.photodiodes.len(), &meta.name)?;
    if telemetry.len() < MIN_DIAGNOSE_ROWS {
        anyhow::bail!(
            "too little data to diagnose: {} rows; a diagnosis tests each effect's signature \
             against the residuals' own noise and needs at least {MIN_DIAGNOSE_ROWS} rows",
            telemetry.len()
        );
    }
    let mut warnings = crate::checks::check_telemetry(telemetry)?;
    warnings.extend(crate::checks::orbit_age(meta, telemetry, "dataset.ron"));
    let references = pdcal_filter::step_references(meta, telemetry)?;
    let albedo = crate::calibrate::albedo_model()?;
    let config = DiagnoseConfig::default();
    // The data as calibrate reads them: a sensor's axes found other than stated are turned
    // into the body frame, a photodiode that reads reversed is negated and one whose data
    // contradict any mounting is left out, each said, before the diagnosis, so that no
    // effect is sought in what a wiring fault explains.
    let axes = crate::axes::check(meta, telemetry, &(&references).into(), &config.filter, &[])?;
    warnings.extend(axes.finding.iter().map(crate::axes::message));
    warnings.extend(crate::axes::notes(&axes));
    let (meta, telemetry) = crate::axes::corrected(&axes, meta, telemetry);
    let (meta, telemetry) = (meta.as_ref(), telemetry.as_ref());
    let mountings = crate::mounting::check(
        meta,
        telemetry,
        (&references).into(),
        &config.filter,
        &albedo,
    )?;
    warnings.extend(mountings.iter().map(|f| f.message()));
    let (meta, telemetry) = crate::mounting::corrected(&mountings, meta, telemetry);
    let (meta, telemetry) = (meta.as_ref(), telemetry.as_ref());
    let albedo_map = crate::calibrate::ALBEDO_MAP.to_string();
    let inputs = DiagnoseInputs {
        meta,
        telemetry,
        references: &references,
        albedo: &albedo,
        albedo_map: &albedo_map,
    };
    let start = Instant::now();
    let diagnosis = pdcal_diagnose::diagnose(&inputs, base, &config).context("diagnosis")?;
    Ok(DiagnoseOutcome {
        diagnosis,
        runtime_s: start.elapsed().as_secs_f64(),
        warnings,
    })
}

/// Fewest telemetry rows a diagnosis runs on: its statistics (autocorrelation-robust Wald
/// tests, a BIC penalty) compare signatures with the residuals' own noise, which a few
/// dozen rows cannot estimate; below it the answer is "too little data", not a verdict.
pub const MIN_DIAGNOSE_ROWS: usize = 100;

/// `pdcal diagnose DATASET_DIR --out OUT_DIR [--base-model ...]`.
pub fn run_dir(dataset: &Path, out: &Path, base: BaseModel) -> Result<DiagnoseOutcome> {
    run_dir_forced(dataset, out, base, false)
}

/// [`run_dir`]; with `force`, an earlier diagnosis in `out` is replaced even when its files
/// were changed since (`--force`).
pub fn run_dir_forced(
    dataset: &Path,
    out: &Path,
    base: BaseModel,
    force: bool,
) -> Result<DiagnoseOutcome> {
    let dir = OutputDir::create_reading(out, "diagnose", force, &[dataset])?;
    let meta = pdcal_dataset::read_meta(dataset)?;
    let telemetry = pdcal_dataset::read_telemetry(dataset, &meta)?;
    let outcome = run(&meta, &telemetry, base)?;
    write_outputs(dir, &meta, &outcome)?;
    Ok(outcome)
}

/// Writes diagnosis.json, report.md, the figures and index.html into `dir` (created before
/// the computation) and publishes it in one step.
pub fn write_outputs(dir: OutputDir, meta: &DatasetMeta, outcome: &DiagnoseOutcome) -> Result<()> {
    let d = &outcome.diagnosis;
    let json = serde_json::to_string_pretty(&d.summary())?;
    write_file(&dir.file("diagnosis.json"), json.as_bytes())?;
    let figures = round_figures(dir.path(), d)?;
    let report = report_text(meta, outcome, &figures);
    write_file(&dir.file("report.md"), report.as_bytes())?;
    let rows = index_rows(d);
    pdcal_report::index_html(
        dir.path(),
        &format!("pdcal diagnose: {}", meta.name),
        &rows,
        &figures,
    )?;
    dir.commit()
}

/// Two figures per round: the binned signature before and after, and the residual
/// histograms of the affected sensor before and after.
fn round_figures(dir: &Path, d: &Diagnosis) -> Result<Vec<(String, String)>> {
    let mut out = Vec::new();
    for (n, round) in d.rounds.iter().enumerate() {
        let stem = format!("round{}_{}_signature", n + 1, round.found);
        let title = format!("Round {}: {} (residual signature)", n + 1, round.found);
        signature_figure(
            dir,
            &stem,
            &title,
            &round.signature_before,
            &round.signature_after,
        )?;
        out.push((
            format!(
                "Round {}: mean residual against the {} regressor, before and after adding it",
                n + 1,
                round.found
            ),
            stem,
        ));
        let stem = format!("round{}_{}_histogram", n + 1, round.found);
        let before = &round.signature_before.y;
        let after = &round.signature_after.y;
        let panels = [
            HistogramPanel {
                label: "before",
                values: before,
            },
            HistogramPanel {
                label: "after",
                values: after,
            },
        ];
        histograms(
            dir,
            &Figure::new(
                &stem,
                &format!("Round {}: {} residuals", n + 1, round.found),
            ),
            &round.signature_before.y_label,
            40,
            BinRange::Shared,
            &panels,
        )?;
        out.push((
            format!(
                "Round {}: residuals carrying the {} signature, before and after",
                n + 1,
                round.found
            ),
            stem,
        ));
    }
    Ok(out)
}

fn signature_figure(
    dir: &Path,
    stem: &str,
    title: &str,
    before: &Signature,
    after: &Signature,
) -> Result<()> {
    let (lo, hi) = before.x_range();
    let (x, y_before) = before.binned(lo, hi, SIGNATURE_BINS);
    let (_, y_after) = after.binned(lo, hi, SIGNATURE_BINS);
    let series = [
        Series::new("before", &y_before, Mark::Circle).with_colour([220, 40, 40]),
        Series::new("after", &y_after, Mark::Dot).with_colour([30, 80, 220]),
    ];
    lines(
        dir,
        &Figure::new(stem, title),
        &LineAxes::new(&before.x_label, &format!("mean {}", before.y_label)),
        &x,
        &series,
    )?;
    Ok(())
}

fn gap_line(g: &Gap) -> String {
    let mut s = format!(
        "photodiode RMS {:.4} V (noise {:.4}), {:.1} % inside 3 sigma, Sun-vector |s| {:.4} +- {:.4}",
        g.photodiode_rms_v,
        g.photodiode_noise_v,
        100.0 * g.fraction_within_3sigma,
        g.sun_vector_magnitude_mean,
        g.sun_vector_magnitude_std
    );
    if g.magnetometer_rms_nt.is_finite() {
        let _ = write!(
            s,
            ", magnetometer RMS {:.0} nT (noise {:.0})",
            g.magnetometer_rms_nt, g.magnetometer_noise_nt
        );
    }
    let _ = write!(
        s,
        ", attitude rate beyond gyro RMS {:.2e} rad/s",
        g.gyro_residual_rms_rad_s
    );
    s
}

/// The human report (Markdown text).
pub fn report_text(
    meta: &DatasetMeta,
    outcome: &DiagnoseOutcome,
    figures: &[(String, String)],
) -> String {
    let d = &outcome.diagnosis;
    let mut s = String::new();
    let _ = writeln!(s, "# pdcal diagnose: {}\n", meta.name);
    let _ = writeln!(
        s,
        "Base model `{}`; verdict **{}**; final model: {}; {:.1} s.\n",
        d.base_model.as_str(),
        d.verdict(),
        final_model_text(d),
        outcome.runtime_s
    );
    for (n, r) in d.rounds.iter().enumerate() {
        let _ = writeln!(s, "## Round {}: {} ({:?})\n", n + 1, r.found, r.action);
        let _ = writeln!(s, "- evidence: {}", r.evidence);
        let _ = writeln!(
            s,
            "- score {:.1} nats above the BIC (threshold {:.1}); runner-up: {}",
            r.score,
            d.threshold,
            r.candidates
                .get(1)
                .map_or("none".to_owned(), |c| format!("{} {:.1}", c.id, c.score))
        );
        let _ = writeln!(s, "- kept: {}", effect_text(&r.effect));
        let _ = writeln!(s, "- its refit: {}", shrink_line(&r.shrink));
        let _ = writeln!(s, "- significance: {}", r.significance.text());
        for x in &r.rejected {
            let _ = writeln!(
                s,
                "- not named: {} (score {:.1}): {}",
                x.id, x.score, x.reason
            );
        }
        for x in &r.dropped {
            let _ = writeln!(
                s,
                "- dropped again: {} (score {:.1} without it, at most the threshold)",
                x.id, x.score
            );
        }
        for x in &r.reformed {
            let _ = writeln!(
                s,
                "- changed form: {} from {} to {} (photodiode residual sum of squares {:.4} -> {:.4} V^2)",
                x.id,
                effect_text(&x.from),
                effect_text(&x.to),
                x.photodiode_rss_v2[0],
                x.photodiode_rss_v2[1]
            );
        }
        let _ = writeln!(s, "- before: {}", gap_line(&r.gap_before));
        let _ = writeln!(s, "- after:  {}\n", gap_line(&r.gap_after));
    }
    let _ = writeln!(s, "## Final check\n");
    for c in d.final_candidates.iter() {
        let _ = writeln!(s, "- {} {:.1}: {}", c.id, c.score, c.evidence);
    }
    for x in &d.final_rejected {
        let _ = writeln!(
            s,
            "- not named: {} (score {:.1}): {}",
            x.id, x.score, x.reason
        );
    }
    let _ = writeln!(
        s,
        "\nNo further candidate above the threshold of {:.1} nats shrinks the gap.\n",
        d.threshold
    );
    for p in d.parameter_estimates() {
        let _ = writeln!(
            s,
            "- estimated {} = {:.4} +- {:.4} {} (1 sigma)",
            p.name, p.value, p.sigma, p.unit
        );
    }
    let _ = writeln!(s, "\nFinal gap: {}\n", gap_line(&d.final_gap));
    let _ = writeln!(s, "## Are the final residuals noise?\n");
    let _ = writeln!(s, "{}\n", misfit_text(&d.misfit));
    let _ = writeln!(s, "## Figures\n");
    for (caption, stem) in figures {
        let _ = writeln!(s, "- {caption}: {stem}.png, {stem}.svg");
    }
    s
}

fn final_model_text(d: &Diagnosis) -> String {
    let ids = d.final_spec.effect_ids();
    if ids.is_empty() {
        "direct Sun only".to_owned()
    } else {
        let names: Vec<&str> = ids.iter().map(|id| id.as_str()).collect();
        format!("direct Sun + {}", names.join(" + "))
    }
}

/// An effect in truth.ron's spelling (degrees, %/K), as a user compares it with a scenario.
fn effect_text(effect: &pdcal_dataset::Effect) -> String {
    ron::to_string(effect).unwrap_or_else(|_| effect.id().to_string())
}

fn shrink_line(x: &pdcal_diagnose::Shrink) -> String {
    format!(
        "{} RMS {:.4} -> {:.4} over {} samples it targets, {:.0} % of the excess removed, {:.1} nats",
        x.sensor,
        x.rms_before,
        x.rms_after,
        x.samples,
        100.0 * x.fraction_removed,
        x.nats
    )
}

/// The consistency check in words: consistent, or the misfit's size and where it is.
fn misfit_text(m: &pdcal_diagnose::Misfit) -> String {
    // The noise model holds the calibration's and the albedo map's uncertainty besides the
    // sensor noise: on weak data it is far wider than the noise, and both ratios are said.
    let against_noise = m.photodiode_rms_v / m.photodiode_noise_v;
    if m.explained {
        return format!(
            "Yes: photodiode RMS {:.4} V, {:.2} times the noise model's sigma (sensor noise, \
             the calibration's uncertainty, the albedo map's) and {against_noise:.2} times the \
             sensor noise alone ({:.4} V), {:.1} % inside 3 sigma, every photodiode consistent.",
            m.photodiode_rms_v,
            m.rms_ratio,
            m.photodiode_noise_v,
            100.0 * m.fraction_within_3sigma
        );
    }
    let mut s = format!(
        "No (`unexplained`): photodiode RMS {:.4} V, {:.2} times the noise model's sigma and \
         {against_noise:.2} times the sensor noise alone ({:.4} V), {:.1} % inside 3 sigma. \
         Concentrated in: {}.",
        m.photodiode_rms_v,
        m.rms_ratio,
        m.photodiode_noise_v,
        100.0 * m.fraction_within_3sigma,
        m.concentrated_in
    );
    for f in &m.failed {
        let _ = write!(s, "\n- {f}");
    }
    s
}

fn index_rows(d: &Diagnosis) -> Vec<(String, String)> {
    let mut rows = vec![
        ("base model".to_owned(), d.base_model.as_str().to_owned()),
        ("verdict".to_owned(), d.verdict()),
    ];
    for (n, r) in d.rounds.iter().enumerate() {
        rows.push((
            format!("round {}: {} (score {:.0})", n + 1, r.found, r.score),
            format!(
                "photodiode RMS {:.4} -> {:.4} V",
                r.gap_before.photodiode_rms_v, r.gap_after.photodiode_rms_v
            ),
        ));
    }
    rows
}

/// One line per round and the final check, for the terminal.
pub fn console_summary(outcome: &DiagnoseOutcome) -> String {
    let d = &outcome.diagnosis;
    let mut s = format!(
        "diagnose from `{}`: verdict {} ({:.1} s)\n",
        d.base_model.as_str(),
        d.verdict(),
        outcome.runtime_s
    );
    for (n, r) in d.rounds.iter().enumerate() {
        let _ = writeln!(s, "  round {}: {} (score {:.1})", n + 1, r.found, r.score);
        let _ = writeln!(s, "    {}", r.evidence);
        let _ = writeln!(s, "    refit: {}", shrink_line(&r.shrink));
        let _ = writeln!(s, "    significance: {}", r.significance.text());
        for x in &r.rejected {
            let _ = writeln!(s, "    not named: {} ({:.1}): {}", x.id, x.score, x.reason);
        }
        for x in &r.dropped {
            let _ = writeln!(s, "    dropped again: {} ({:.1} without it)", x.id, x.score);
        }
        for x in &r.reformed {
            let _ = writeln!(s, "    changed form: {} to {}", x.id, effect_text(&x.to));
        }
        let _ = writeln!(s, "    before: {}", gap_line(&r.gap_before));
        let _ = writeln!(s, "    after:  {}", gap_line(&r.gap_after));
    }
    for p in d.parameter_estimates() {
        let _ = writeln!(
            s,
            "  estimated {} = {:.4} +- {:.4} {}",
            p.name, p.value, p.sigma, p.unit
        );
    }
    match d.final_candidates.first() {
        Some(c) => {
            let why = if c.score > d.threshold {
                "above it, but its refit is not named: below"
            } else {
                "below it"
            };
            let _ = writeln!(
                s,
                "  then none: best remaining {} at {:.1} (threshold {:.1}; {why})",
                c.id, c.score, d.threshold
            );
        }
        None => {
            let _ = writeln!(s, "  then none: no candidate left");
        }
    }
    for x in &d.final_rejected {
        let _ = writeln!(s, "  not named: {} ({:.1}): {}", x.id, x.score, x.reason);
    }
    let _ = writeln!(
        s,
        "  residuals: {}",
        misfit_text(&d.misfit).replace('\n', "\n  ")
    );
    for (which, c) in [
        ("first model", &d.base_consistency),
        ("final model", &d.consistency),
    ] {
        let _ = writeln!(
            s,
            "  consistency of the {which}'s filter residuals (as calibrate judges it): {}{}",
            c.verdict.as_str(),
            if c.reasons.is_empty() {
                String::new()
            } else {
                format!(" ({})", c.reasons.join("; "))
            }
        );
    }
    for note in &d.consistency.notes {
        let _ = writeln!(s, "    note: {note}");
    }
    if let Some(why) = verdicts_differ(&d.misfit, &d.consistency) {
        let _ = writeln!(s, "  {why}");
    }
    s
}

/// Why the post-fit residuals and calibrate's verdict can disagree, when they do: they
/// judge different residuals, and neither answer cancels the other.
fn verdicts_differ(
    misfit: &pdcal_diagnose::Misfit,
    c: &pdcal_filter::consistency::Consistency,
) -> Option<String> {
    let filter_consistent = c.verdict == pdcal_filter::consistency::Verdict::Consistent;
    let pd = c.sensors.first()?;
    (misfit.explained != filter_consistent).then(|| {
        format!(
            "the two answers judge different residuals: calibrate's verdict, the filter's {} \
             accepted photodiode updates ({} of them with the attitude held) against the sensor \
             noise, each made at the attitude the filter held then; the residuals above, every \
             photodiode sample at the smoothed attitude and the final calibration, rows the \
             filter did not use included (eclipse, high incidence, albedo only). A model that \
             explains the data passes both; here {} does not",
            pd.updates,
            pd.held_updates,
            if misfit.explained {
                "the filter's updates"
            } else {
                "the smoothed, final model"
            }
        )
    })
}
