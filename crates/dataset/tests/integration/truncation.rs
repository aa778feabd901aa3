//! Fuzz-ish: every prefix and many one-byte mutations of valid files are read without a
//! panic, and every error still names its file and a line inside the text.

use crate::common;

use pdcal_dataset::{
    DatasetError, meta_from_str, render_dataset, telemetry_from_str, truth_constants_from_str,
    truth_series_from_str,
};

fn files() -> Vec<(&'static str, String)> {
    render_dataset(&common::full_dataset(8)).unwrap()
}

/// An error must point inside the text it came from.
fn check(e: &DatasetError, text: &str) {
    let lines = text.lines().count().max(1);
    if let Some(line) = e.line() {
        assert!(
            (1..=lines + 1).contains(&line),
            "{e} (text has {lines} lines)"
        );
    }
    assert!(!e.to_string().is_empty());
}

fn parse_any(name: &str, text: &str, meta: &pdcal_dataset::DatasetMeta) -> Option<DatasetError> {
    match name {
        "dataset.ron" => meta_from_str(text).err(),
        "telemetry.csv" => telemetry_from_str(text, meta).err(),
        "truth.csv" => truth_series_from_str(text).err(),
        _ => truth_constants_from_str(text, meta).err(),
    }
}

#[test]
fn truncated_telemetry_never_panics() {
    let files = files();
    let meta = meta_from_str(&files[0].1).unwrap();
    let text = &files[1].1;
    let row_ends: Vec<usize> = text.match_indices('\n').map(|(i, _)| i + 1).collect();
    for cut in 0..=text.len() {
        let prefix = &text[..cut];
        match telemetry_from_str(prefix, &meta) {
            Ok(tm) => {
                // Only a cut after a complete row, or inside the last cell of a row (a shorter
                // number, or none: an empty cell), can be valid; it keeps the rows before it.
                let complete = row_ends.iter().filter(|&&end| end <= cut).count();
                assert!(
                    tm.len() == complete - 1 || tm.len() == complete,
                    "cut {cut}"
                );
            }
            Err(e) => check(&e, prefix),
        }
    }
}

#[test]
fn every_file_truncated_or_mutated_never_panics() {
    let files = files();
    let meta = meta_from_str(&files[0].1).unwrap();
    for (name, text) in &files {
        // Every prefix of the RON files; every 7th of the CSV files (telemetry has its own test).
        let step = if name.ends_with(".ron") { 1 } else { 7 };
        for cut in (0..=text.len()).step_by(step) {
            if let Some(e) = parse_any(name, &text[..cut], &meta) {
                check(&e, &text[..cut]);
            }
        }
        // One byte replaced by a character that matters to the grammar.
        for at in (0..text.len()).step_by(3) {
            for c in [",", "\n", "\"", "(", ")", "[", "x", "-", "9", "é"] {
                let mut mutated = text.clone();
                mutated.replace_range(at..at + 1, c);
                if let Some(e) = parse_any(name, &mutated, &meta) {
                    check(&e, &mutated);
                }
            }
        }
    }
}
