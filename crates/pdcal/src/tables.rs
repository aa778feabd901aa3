//! The result a user reads first: the photodiode table (calibrated values with 1 sigma, the
//! nominal ones, the change, the sunlit time used and a flag) and the segments of the run,
//! as rows of text shared by index.html and the printed summary of `pdcal calibrate`.

use std::fmt::Write as _;

use pdcal_report::Table;

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
        "sunlit used (min)",
        "flag",
    ];
    let rows = summary
        .photodiodes
        .iter()
        .map(|p| {
            let azimuth_sigma = p
                .azimuth_sigma_deg
                .map_or("undefined".to_owned(), |s| format!("{s:.2}"));
            vec![
                format!("pd{:02}", p.index),
                format!("{:.4} +- {:.4}", p.scale_V, p.scale_sigma_V),
                format!("{:.2} +- {azimuth_sigma}", p.azimuth_deg),
                format!("{:.2} +- {:.2}", p.elevation_deg, p.elevation_sigma_deg),
                format!("{:.4}", p.initial.scale_V),
                format!(
                    "{:.1} / {:.1}",
                    p.initial.azimuth_deg, p.initial.elevation_deg
                ),
                format!("{:.2}", p.normal_change_deg),
                format!("{:+.2}", p.scale_change_percent),
                format!("{:.1}", p.time_used_min),
                p.flag.clone().unwrap_or_default(),
            ]
        })
        .collect();
    Table::new(
        "Photodiodes (calibrated value +- 1 sigma; nominal: the dataset.ron mounting, and \
         the maximum output as C)",
        &header,
        rows,
    )
}

/// The segments of the run: rows, time span, rows used, how the attitude was acquired and
/// why the segment ended.
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
    Table::new("Segments (rows between gaps)", &header, rows)
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
    let _ = writeln!(s, "{}", table.title);
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

/// The printed summary of `pdcal calibrate`: the photodiode table and the segments.
pub fn console_summary(summary: &Summary) -> String {
    format!(
        "{}\n{}",
        text(&photodiode_table(summary)),
        text(&segment_table(summary))
    )
}
