//! The result a user reads first: the photodiode table (calibrated values with 1 sigma, the
//! nominal ones, the change, the sunlit time used and the part of it with the attitude
//! held, and a flag) and the segments of the run, as rows of text shared by index.html
//! and the printed summary of `pdcal calibrate`.

use std::fmt::Write as _;

use pdcal_report::Table;

use pdcal_filter::Consistency;
use pdcal_filter::identifiability::Status;

use crate::repeatability::Repeatability;
use crate::schema::Summary;

/// The photodiode table.
pub fn photodiode_table(summary: &Summary) -> Table {
    let header = [
        "pd",
        "C (V)",
        "azimuth (deg)",
        "elevation (deg)",
        "nominal C (V)",
        "nominal az / el (deg)",
        "normal change (deg)",
        "C change (%)",
        "sunlit used / held (min)",
        "status",
        "flag",
    ];
    let rows = summary
        .photodiodes
        .iter()
        .map(|p| {
            let azimuth_sigma = p
                .calibration
                .azimuth_sigma_deg
                .map_or("undefined".to_owned(), |s| format!("{s:.2}"));
            let (d, cal) = (&p.determination, &p.calibration);
            vec![
                format!("pd{:02}", p.index),
                or_undetermined(d.scale.status, || {
                    format!("{:.4} +- {:.4}", cal.scale_v, cal.scale_sigma_v)
                }),
                or_undetermined(d.azimuth.status, || {
                    format!("{:.2} +- {azimuth_sigma}", cal.azimuth_deg)
                }),
                or_undetermined(d.elevation.status, || {
                    format!("{:.2} +- {:.2}", cal.elevation_deg, cal.elevation_sigma_deg)
                }),
                format!("{:.4}", p.initial.scale_V),
                format!(
                    "{:.1} / {:.1}",
                    p.initial.azimuth_deg, p.initial.elevation_deg
                ),
                format!("{:.2}", p.normal_change_deg),
                format!("{:+.2}", p.scale_change_percent),
                format!("{:.1} / {:.1}", p.time_used_min, p.time_held_min),
                p.status.as_str().to_owned(),
                p.flag.clone().unwrap_or_default(),
            ]
        })
        .collect();
    let mut notes: Vec<String> = Vec::new();
    if let Some(d) = summary.dispersion.filter(|d| d.sigma_factor > 1.0) {
        notes.push(format!(
            "Sigmas multiplied by {:.2}, the residuals' spread after each step over the noise.",
            d.sigma_factor
        ));
    }
    if let Some(e) = &summary.ensemble {
        notes.push(format!(
            "Sigmas widened by the spread of {} of {} ensemble runs from other starts.",
            e.started, e.runs
        ));
    }
    notes.push("Nominal: the dataset.ron mounting, and the maximum output as C.".to_owned());
    notes.push(
        "\"not determined\": the data did not determine it; summary.json and calibration.ron \
         hold the nominal value and say why."
            .to_owned(),
    );
    Table::new("Photodiodes", &header, rows)
        .with_caption("Calibrated value +- 1 sigma per photodiode, beside its nominal value")
        .with_notes(notes)
}

/// A calibrated cell, or `not determined` where the data did not determine the quantity
/// (its number would be the prior's, not a result).
fn or_undetermined(status: Status, cell: impl FnOnce() -> String) -> String {
    match status {
        Status::NotDetermined => "not determined".to_owned(),
        _ => cell(),
    }
}

/// The consistency verdict: its reasons in the title, a row per sensor class and per
/// photodiode with updates (RMS against the noise, NIS against its band, inside 3 sigma
/// over held rows).
pub fn consistency_table(c: &Consistency) -> Table {
    let header = [
        "sensor",
        "updates",
        "residual RMS",
        "noise",
        "RMS / noise",
        "robust / noise",
        "mean NIS [99.9 % band]",
        "held updates",
        "inside 3 sigma (held)",
    ];
    let opt = |x: Option<f64>, f: &dyn Fn(f64) -> String| {
        x.map_or("not available: no updates".to_owned(), f)
    };
    let held = |x: Option<f64>, f: &dyn Fn(f64) -> String| {
        x.map_or("not available: no held updates".to_owned(), f)
    };
    let rows = c
        .sensors
        .iter()
        .chain(c.photodiodes.iter().filter(|p| p.updates > 0))
        .map(|ch| {
            vec![
                ch.channel.clone(),
                ch.updates.to_string(),
                opt(ch.residual_rms, &|x| format!("{x:.4e}")),
                format!("{:.4e}", ch.noise_sigma),
                opt(ch.rms_over_noise, &|x| format!("{x:.2}")),
                opt(ch.robust_over_noise, &|x| format!("{x:.2}")),
                match (ch.nis_mean, ch.nis_band) {
                    (Some(m), Some([lo, hi])) => format!("{m:.3} [{lo:.3}, {hi:.3}]"),
                    _ => "not available: no held updates".to_owned(),
                },
                ch.held_updates.to_string(),
                held(ch.fraction_within_3sigma, &|x| {
                    format!("{:.2} %", 100.0 * x)
                }),
            ]
        })
        .collect();
    let notes = (c.reasons.iter().cloned())
        .chain(c.notes.iter().map(|n| format!("Note: {n}")))
        .collect();
    Table::new("Consistency", &header, rows)
        .with_lead(&c.headline())
        .with_notes(notes)
        .with_caption(
            "Residuals per sensor class and per photodiode with updates: their spread against \
             the noise, the mean NIS against its band and the fraction inside 3 sigma of the \
             rows with the attitude held",
        )
}

/// The segments of the run: rows, time span, rows used, how the attitude was acquired and
/// why the segment ended; the title says how the attitude was carried between samples.
pub fn segment_table(summary: &Summary) -> Table {
    let header = [
        "segment",
        "rows",
        "time (s)",
        "rows used",
        "attitude",
        "ended by",
    ];
    let rows = summary
        .segments
        .iter()
        .enumerate()
        .map(|(n, s)| {
            let attitude = match (&s.skipped, s.acquired_row) {
                (Some(why), _) => format!("skipped: {why}"),
                (None, Some(row)) => {
                    let how = serde_json::to_value(s.acquisition)
                        .ok()
                        .and_then(|v| v.as_str().map(str::to_owned))
                        .unwrap_or_default();
                    match s.paired_field_row {
                        Some(field) => format!("{how} at row {row} (field of row {field})"),
                        None => format!("{how} at row {row}"),
                    }
                }
                (None, None) => "not acquired".to_owned(),
            };
            let ended = serde_json::to_value(s.ended_by)
                .ok()
                .and_then(|v| v.as_str().map(str::to_owned))
                .unwrap_or_default();
            let ended = match &s.lost {
                Some(why) => format!("{ended}: {why}"),
                None => ended,
            };
            vec![
                n.to_string(),
                format!("{}..={}", s.first_row, s.last_row),
                format!("{:.0}..{:.0}", s.start_t_s, s.end_t_s),
                s.rows_used.to_string(),
                attitude,
                ended,
            ]
        })
        .collect();
    let caption = format!(
        "Rows between gaps; propagation: {}",
        summary.propagation.describe()
    );
    Table::new("Segments", &header, rows).with_caption(&caption)
}

/// `table` as aligned plain text, under its title.
pub fn text(table: &Table) -> String {
    let columns = table.header.len();
    let mut widths: Vec<usize> = table.header.iter().map(|h| h.chars().count()).collect();
    for row in &table.rows {
        for (w, cell) in widths.iter_mut().zip(row) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let mut s = String::new();
    match &table.lead {
        Some(lead) => writeln!(s, "{}: {lead}", table.title),
        None if table.caption != table.title => {
            writeln!(s, "{} ({})", table.title, table.caption)
        }
        None => writeln!(s, "{}", table.title),
    }
    .ok();
    for note in &table.notes {
        let _ = writeln!(s, "  - {note}");
    }
    let line = |s: &mut String, cells: &[String]| {
        let padded: Vec<String> = cells
            .iter()
            .zip(&widths)
            .map(|(c, w)| format!("{c:<w$}"))
            .collect();
        let _ = writeln!(s, "  {}", padded.join("  ").trim_end());
    };
    line(&mut s, &table.header);
    let rule: Vec<String> = widths
        .iter()
        .take(columns)
        .map(|w| "-".repeat(*w))
        .collect();
    line(&mut s, &rule);
    for row in &table.rows {
        line(&mut s, row);
    }
    s
}

/// The printed summary of `pdcal calibrate`: the photodiode table, the consistency, the
/// repeatability of a joint run (its verdict and one line per warning) and the segments.
pub fn console_summary(summary: &Summary) -> String {
    format!(
        "{}\n{}\n{}{}{}",
        text(&photodiode_table(summary)),
        text(&consistency_table(&summary.consistency)),
        repeatability_lines(summary),
        normals_rotation_line(summary),
        text(&shortened(segment_table(summary), CONSOLE_SEGMENTS))
    )
}

/// The title of the normals' common rotation (`summary.json` `normals_rotation`).
pub const NORMALS_ROTATION_TITLE: &str = "Normals turned together from the nominal mounting";

/// The normals' common rotation in one line, finding or not, so that a rotation the data
/// determined is read even where it is no finding, or why it was not fitted.
pub fn normals_rotation_line(summary: &Summary) -> String {
    normals_rotation_text(summary).map_or_else(String::new, |t| {
        format!("{NORMALS_ROTATION_TITLE}: {t}\n\n")
    })
}

/// The normals' common rotation described, or why it was not fitted.
pub fn normals_rotation_text(summary: &Summary) -> Option<String> {
    match &summary.normals_rotation {
        Some(r) => Some(r.describe()),
        None => summary
            .normals_rotation_not_fitted
            .as_ref()
            .map(|why| format!("not fitted: {why}")),
    }
}

/// The repeatability verdict of a joint run in one line, then one line per warning (the
/// per-set detail is in summary.json and index.html); empty for one data set.
pub fn repeatability_lines(summary: &Summary) -> String {
    let Some(r) = &summary.repeatability else {
        return String::new();
    };
    let mut s = format!("{}\n", repeatability_title(r, summary.datasets.len()));
    for w in r.warnings.iter().chain(&r.bias_warnings) {
        let _ = writeln!(s, "  {w}");
    }
    s.push('\n');
    s
}

fn repeatability_title(r: &Repeatability, sets: usize) -> String {
    format!(
        "Repeatability across the {sets} data sets: {} ({} comparisons, threshold {:.2} sigma \
         for {:.2} % family-wise false alarms; each set's own estimates in summary.json \
         datasets[k].repeatability)",
        r.verdict.as_str().to_uppercase(),
        r.comparisons,
        r.threshold_sigmas,
        100.0 * r.family_false_alarm_rate
    )
}

/// Each parameter's own estimate per data set (`+- 1 sigma`, and its normalised difference
/// from the other sets, or from the previous set for the gyro bias), and which sets differ.
pub fn repeatability_table(summary: &Summary) -> Option<Table> {
    let r = summary.repeatability.as_ref()?;
    let sets: Vec<&crate::repeatability::SetRepeatability> = summary
        .datasets
        .iter()
        .filter_map(|d| d.repeatability.as_ref())
        .collect();
    let mut header = vec!["parameter".to_owned()];
    header.extend((1..=sets.len()).map(|k| format!("set {k}")));
    header.push("verdict".to_owned());
    let parameters = sets.first().map_or(0, |s| s.parameters.len());
    let rows = (0..parameters)
        .map(|j| {
            let mut row = vec![sets[0].parameters[j].parameter.clone()];
            row.extend(sets.iter().map(|s| repeat_cell(&s.parameters[j])));
            let differ: Vec<String> = sets
                .iter()
                .enumerate()
                .filter(|(_, s)| matches!(s.parameters[j].verdict.as_str(), "differs" | "changed"))
                .map(|(k, _)| (k + 1).to_string())
                .collect();
            row.push(match differ.is_empty() {
                true => "-".to_owned(),
                false => format!("differs in sets {}", differ.join(", ")),
            });
            row
        })
        .collect();
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    Some(
        Table::new("Repeatability", &header, rows)
            .with_lead(&repeatability_title(r, sets.len()))
            .with_caption(
                "Each set's own estimate +- 1 sigma, with its normalised difference (z) from \
                 the other sets",
            ),
    )
}

/// A set's own estimate of a parameter, `+- 1 sigma`, with its normalised difference from
/// the others; or why there is none.
fn repeat_cell(p: &crate::repeatability::ParameterRepeat) -> String {
    let (Some(x), Some(sigma)) = (p.estimate, p.sigma) else {
        return "not determined".to_owned();
    };
    let z = p
        .vs_other_sets
        .or_else(|| (p.vs_sets.len() == 1).then(|| p.vs_sets[0].normalised_difference));
    let value = if p.parameter.ends_with("_rad_s") {
        format!("{:.4} +- {:.4} deg/s", x.to_degrees(), sigma.to_degrees())
    } else if p.parameter.ends_with("_V") {
        format!("{x:.4} +- {sigma:.4}")
    } else {
        format!("{x:.2} +- {sigma:.2}")
    };
    match z {
        Some(z) => format!("{value} (z {z:+.1})"),
        None => value,
    }
}

/// Segments the printed summary shows at most (the first and last half of them): the
/// printed output stays short for any number of segments; every one is in summary.json and
/// index.html.
pub const CONSOLE_SEGMENTS: usize = 20;

/// `table` with at most `keep` rows: the first and last `keep / 2`, and between them one
/// row saying how many are left out and where they are.
pub fn shortened(mut table: Table, keep: usize) -> Table {
    let n = table.rows.len();
    if n <= keep {
        return table;
    }
    let half = keep / 2;
    let tail = table.rows.split_off(n - half);
    table.rows.truncate(half);
    table.rows.push(vec![
        "...".to_owned(),
        format!("{} segments more (summary.json segments)", n - 2 * half),
    ]);
    table.rows.extend(tail);
    table
}
