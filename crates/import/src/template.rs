//! A column map to start from, made from an export's header (`pdcal import SOURCE.csv
//! --print-map-template`): every column listed with its first value, the time, gyro and
//! magnetometer axes filled in where a header name says what it is, and every other column
//! a commented-out photodiode entry. What no name can tell (the photodiodes' mounting, the
//! orbit, a count's conversion) is left as `?` for the user: the map does not parse until
//! it is given, so a guess never passes for a fact.

use std::fmt::Write as _;
use std::io::Read;
use std::path::Path;

use csv::StringRecord;

use crate::ImportError;
use crate::map::Delimiter;
use crate::source::Records;

/// The map template for the export `source` (named `file` in errors): its header and first
/// data row are read, nothing more.
pub fn map_template<R: Read>(file: &Path, source: R) -> Result<String, ImportError> {
    let mut records = Records::open(file, source, None)?;
    let mut header = StringRecord::new();
    records.next(&mut header)?;
    let mut first = StringRecord::new();
    if records.next(&mut first)?.is_none() {
        first = StringRecord::new();
    }
    let names: Vec<&str> = header.iter().collect();
    let value = |i: usize| first.get(i).unwrap_or("");
    let stem = file
        .file_stem()
        .map_or(String::new(), |s| s.to_string_lossy().into_owned());
    let mut used = vec![false; names.len()];
    let time = names.iter().position(|n| is_time(n));
    if let Some(i) = time {
        used[i] = true;
    }
    let gyro = axes(&names, &mut used, &["gyro", "gyr", "rate", "omega"]);
    let mag = axes(&names, &mut used, &["mag", "tam", "field"]);

    let mut t = String::new();
    let _ = writeln!(
        t,
        "// Column map template for {} (`pdcal import --print-map-template`);\n\
         // the format is docs/import.md. Fill in every `?`, check every guess (marked\n\
         // `guessed`), uncomment one photodiode entry per photodiode in pdNN order and\n\
         // delete what the export lacks.\n\
         // The export's {} columns (header: first row's value):",
        pdcal_text::quote(&file.to_string_lossy()),
        names.len()
    );
    for (i, name) in names.iter().enumerate() {
        let _ = writeln!(
            t,
            "//   {}: {}",
            pdcal_text::quote(name),
            pdcal_text::quote(value(i))
        );
    }
    let _ = writeln!(
        t,
        "(\n    format_version: 1,\n    name: {},",
        ron_string(&stem)
    );
    if records.detected && records.delimiter != Delimiter::Comma {
        let _ = writeln!(t, "    delimiter: {:?},", records.delimiter);
    }
    match time {
        Some(i) => {
            let _ = writeln!(
                t,
                "    time: (column: {}, form: {}),   // guessed; forms: Unix, Gps, \
                 Seconds(epoch_utc: \"..Z\"), Iso",
                ron_string(names[i]),
                time_form(value(i))
            );
        }
        None => {
            let _ = writeln!(
                t,
                "    time: (column: ?, form: ?),   // Unix, Gps, Seconds(epoch_utc: \"..Z\"), Iso"
            );
        }
    }
    t.push_str(
        "    // sentinels: [65535, \"N/A\"],   // values meaning \"no value\" in every column; \
         a column's own: (column: .., sentinels: [-1])\n",
    );
    vector(&mut t, "gyro", &names, gyro, "rad/s or deg/s", gyro_unit);
    vector(&mut t, "mag", &names, mag, "nT, uT, mG or G", mag_unit);
    t.push_str(
        "    photodiodes: [   // (column, unit: \"V\" | \"mV\" or counts: (gain, offset, unit)), \
         mounting in the body frame\n",
    );
    // A column whose first cell is text is no photodiode.
    let numeric = |i: usize| value(i).trim().parse::<f64>().is_ok() || value(i).trim().is_empty();
    let candidates = (names.iter().enumerate()).filter(|&(i, _)| !used[i] && numeric(i));
    for (_, name) in candidates {
        let _ = writeln!(
            t,
            "        // (column: {}, unit: ?, azimuth_deg: ?, elevation_deg: ?),",
            ron_string(name)
        );
    }
    t.push_str(
        "    ],\n    orbit: Tle(line1: ?, line2: ?),   // or Positions(x: .., y: .., z: .., frame: Teme)\n\
         )\n",
    );
    Ok(t)
}

/// A RON string literal of `text` (Rust's escapes, which RON reads).
fn ron_string(text: &str) -> String {
    format!("{text:?}")
}

fn is_time(name: &str) -> bool {
    let n = name.to_ascii_lowercase();
    n == "t"
        || n == "t_s"
        || ["time", "unix", "utc", "epoch"]
            .iter()
            .any(|w| n.contains(w))
}

/// The form a time cell's text looks like: an ISO text, or seconds (Unix when in this
/// century's Unix range, else elapsed seconds of an epoch the user must give).
fn time_form(cell: &str) -> &'static str {
    match cell.trim().parse::<f64>() {
        Ok(x) if (9.0e8..4.1e9).contains(&x) => "Unix",
        Ok(_) => "Seconds(epoch_utc: ?)",
        Err(_) if cell.contains('T') => "Iso",
        Err(_) => "?",
    }
}

/// The three columns of a vector sensor whose names hold one of `words` and end in an axis
/// letter (`gyro_x_dps`, `magX`), when all three are there and not taken.
fn axes(names: &[&str], used: &mut [bool], words: &[&str]) -> Option<[usize; 3]> {
    let find = |axis: char| {
        names.iter().enumerate().position(|(i, n)| {
            let l = n.to_ascii_lowercase();
            !used[i] && words.iter().any(|w| l.contains(w)) && axis_of(&l) == Some(axis)
        })
    };
    let found = [find('x')?, find('y')?, find('z')?];
    for i in found {
        used[i] = true;
    }
    Some(found)
}

/// The axis a lower-case name ends in: `x` of `gyro_x`, `gyro_x_dps`, `gyrox`.
fn axis_of(name: &str) -> Option<char> {
    let parts: Vec<&str> = name.split(['_', '-', '.', ' ']).collect();
    let is_axis = |p: &str| matches!(p, "x" | "y" | "z");
    if let Some(p) = parts.iter().find(|p| is_axis(p)) {
        return p.chars().next();
    }
    let stem = parts.first().copied().unwrap_or("");
    let c = stem.chars().last()?;
    matches!(c, 'x' | 'y' | 'z').then_some(c)
}

fn gyro_unit(name: &str) -> Option<&'static str> {
    let l = name.to_ascii_lowercase();
    match () {
        _ if l.contains("dps") || l.contains("deg") => Some("deg/s"),
        _ if l.contains("rad") => Some("rad/s"),
        _ => None,
    }
}

fn mag_unit(name: &str) -> Option<&'static str> {
    let l = name.to_ascii_lowercase();
    match () {
        _ if l.ends_with("nt") => Some("nT"),
        _ if l.ends_with("ut") => Some("uT"),
        _ if l.ends_with("mg") => Some("mG"),
        _ if l.ends_with("_g") => Some("G"),
        _ => None,
    }
}

/// A vector sensor's entry: its columns and units where the names tell them, else
/// commented out with `?`.
fn vector(
    t: &mut String,
    key: &str,
    names: &[&str],
    found: Option<[usize; 3]>,
    units: &str,
    unit_of: fn(&str) -> Option<&'static str>,
) {
    let Some(columns) = found else {
        let _ = writeln!(
            t,
            "    // {key}: (x: (column: ?, unit: ?), y: .., z: ..),   // {units}"
        );
        return;
    };
    let _ = writeln!(
        t,
        "    {key}: (   // guessed from the names; body frame; {units}"
    );
    for (axis, i) in ['x', 'y', 'z'].into_iter().zip(columns) {
        let unit = unit_of(names[i]).map_or("?".to_owned(), |u| format!("{u:?}"));
        let _ = writeln!(
            t,
            "        {axis}: (column: {}, unit: {unit}),",
            ron_string(names[i])
        );
    }
    t.push_str("    ),\n");
}
