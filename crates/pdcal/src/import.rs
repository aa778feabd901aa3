//! `pdcal import SOURCE.csv --map MAP.ron --out DATASET_DIR`: a ground-segment export in, a
//! dataset directory out (the conversion is `pdcal_import`; this is the file side).

use std::path::Path;

use anyhow::{Context, Result};
use pdcal_import::{ImportReport, Imported};

/// Reads the map and the export and converts (writes nothing).
pub fn import_files(source: &Path, map: &Path) -> Result<Imported> {
    let read = |path: &Path| {
        pdcal_dataset::bounded::read_bounded(path, u64::MAX - 1)
            .with_context(|| format!("cannot read {}", path.display()))
    };
    let map_bytes =
        pdcal_dataset::bounded::read_bounded(map, pdcal_dataset::bounded::MAX_RON_BYTES)
            .with_context(|| format!("cannot read {}", map.display()))?;
    let map = pdcal_import::parse_map(map, &map_bytes)?;
    Ok(pdcal_import::convert(&map, source, &read(source)?)?)
}

/// Imports `source` with `map` and writes the dataset into `out`, whole or not at all; `out`
/// is checked and locked before the export is read (the rule of `simulate --out`: a missing
/// or empty directory, or a dataset directory).
pub fn run_to_dir(source: &Path, map: &Path, out: &Path) -> Result<Imported> {
    run_to_dir_forced(source, map, out, false)
}

/// [`run_to_dir`]; with `force`, an earlier import into `out` is replaced even when its
/// files were changed since (`--force`).
pub fn run_to_dir_forced(source: &Path, map: &Path, out: &Path, force: bool) -> Result<Imported> {
    let writer = pdcal_dataset::begin_dataset_as(out, "import", force)?;
    let imported = import_files(source, map)?;
    writer.write(&imported.dataset)?;
    Ok(imported)
}

/// The report as lines for the console: rows kept and dropped, the sentinel cells per
/// column, and one line per sensor with partial vectors.
pub fn report_lines(report: &ImportReport) -> Vec<String> {
    let mut lines = vec![format!(
        "{} of {} rows kept ({} dropped with an empty time, {} with a sentinel time); epoch {}, \
         span {} s",
        report.rows_kept,
        report.rows_read,
        report.dropped_blank_time,
        report.dropped_sentinel_time,
        report.epoch_utc,
        report.span_s
    )];
    if !report.sentinel_cells.is_empty() {
        let cells: Vec<String> = (report.sentinel_cells.iter())
            .map(|(_, header, n)| format!("{header} {n}"))
            .collect();
        lines.push(format!("sentinel cells left empty: {}", cells.join(", ")));
    }
    for (sensor, n) in &report.partial_vectors {
        lines.push(format!(
            "{n} rows with part of the {sensor} vector missing: {sensor} left empty there"
        ));
    }
    lines
}
