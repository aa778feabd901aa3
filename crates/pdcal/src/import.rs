//! `pdcal import SOURCE.csv --map MAP.ron --out DATASET_DIR`: a ground-segment export in, a
//! dataset directory out (the conversion is `pdcal_import`; this is the file side).

use std::path::Path;

use anyhow::{Context, Result};
use pdcal_import::{Converted, DuplicateTimes, ImportError, ImportReport, Imported};

/// Reads the map and the export and converts (writes nothing).
pub fn import_files(source: &Path, map: &Path) -> Result<Imported> {
    let read = |path: &Path| {
        pdcal_dataset::bounded::read_bounded(path, u64::MAX - 1)
            .with_context(|| format!("cannot read {}", pdcal_text::path(path)))
    };
    let map_bytes =
        pdcal_dataset::bounded::read_bounded(map, pdcal_dataset::bounded::MAX_RON_BYTES)
            .with_context(|| format!("cannot read {}", pdcal_text::path(map)))?;
    let map = pdcal_import::parse_map(map, &map_bytes)?;
    Ok(pdcal_import::convert(&map, source, &read(source)?)?)
}

/// Imports `source` with `map` and writes the dataset into `out`, whole or not at all; `out`
/// is checked and locked before the export is read (the rule of `simulate --out`: a missing
/// or empty directory, or a dataset directory). The export is streamed: each row goes to
/// telemetry.csv in the staging directory as it is converted, so memory does not grow with
/// the export's length; the staged dataset is read back through the dataset reader's checks
/// before it is published.
pub fn run_to_dir(source: &Path, map: &Path, out: &Path) -> Result<Converted> {
    run_to_dir_forced(source, map, out, false)
}

/// [`run_to_dir`]; with `force`, an earlier import into `out` is replaced even when its
/// files were changed since (`--force`).
pub fn run_to_dir_forced(source: &Path, map: &Path, out: &Path, force: bool) -> Result<Converted> {
    let writer = pdcal_dataset::begin_dataset_as(out, "import", force)?;
    let map_bytes =
        pdcal_dataset::bounded::read_bounded(map, pdcal_dataset::bounded::MAX_RON_BYTES)
            .with_context(|| format!("cannot read {}", pdcal_text::path(map)))?;
    let map = pdcal_import::parse_map(map, &map_bytes)?;
    // Only a regular file, refused before it is opened, as every input of `calibrate`: a
    // FIFO with no writer would block the open, with `out` locked, for ever.
    let file = pdcal_dataset::bounded::open_regular(source)
        .with_context(|| format!("cannot read {}", pdcal_text::path(source)))?;
    let mut stream = writer.telemetry_stream(pdcal_import::layout(&map))?;
    let converted = pdcal_import::convert_stream(&map, source, file, |row| {
        stream.push(row).map_err(ImportError::from)
    })?;
    writer.finish_stream(&converted.meta, stream)?;
    Ok(converted)
}

/// The column map template of the export `source` (`pdcal import SOURCE
/// --print-map-template`): only its header and first row are read; a source that is not a
/// regular file is refused before it is opened (a pipe without a writer would block).
pub fn map_template(source: &Path) -> Result<String> {
    let meta =
        std::fs::metadata(source).with_context(|| format!("cannot read {}", source.display()))?;
    if !meta.is_file() {
        anyhow::bail!("cannot read {}: not a regular file", source.display());
    }
    let file =
        std::fs::File::open(source).with_context(|| format!("cannot read {}", source.display()))?;
    Ok(pdcal_import::map_template(source, file)?)
}

/// A dataset directory made from the skCUBE flight frames of `fixtures/flight/skcube`
/// (`adcs_frames.csv` with `skcube.map.ron`) in `out`, as `pdcal import
/// fixtures/flight/skcube/adcs_frames.csv --map fixtures/flight/skcube/skcube.map.ron --out
/// OUT` makes it; `fixtures` is the repository's `fixtures/` directory.
pub fn skcube_dataset(fixtures: &Path, out: &Path) -> Result<Converted> {
    let dir = fixtures.join("flight").join("skcube");
    run_to_dir(
        &dir.join("adcs_frames.csv"),
        &dir.join("skcube.map.ron"),
        out,
    )
}

/// The report as lines for the console: rows kept and dropped, the sentinel cells per
/// column, and one line per sensor with partial vectors.
pub fn report_lines(report: &ImportReport) -> Vec<String> {
    let mut lines = Vec::new();
    if let Some((delimiter, detected)) = report.delimiter {
        lines.push(if detected {
            format!(
                "delimiter: {} (detected from the header; `delimiter` in the map sets it)",
                delimiter.describe()
            )
        } else {
            format!("delimiter: {} (the map's)", delimiter.describe())
        });
    }
    lines.push(format!(
        "{} of {} rows kept ({} dropped with an empty time, {} with a sentinel time); epoch {}, \
         span {} s",
        report.rows_kept,
        report.rows_read,
        report.dropped_blank_time,
        report.dropped_sentinel_time,
        report.epoch_utc,
        report.span_s
    ));
    if report.duplicate_rows > 0 {
        let what = match report.duplicate_times {
            DuplicateTimes::Average => "averaged into the first row of their time",
            _ => "dropped: only the first row of each time kept",
        };
        lines.push(format!(
            "{} rows with the time of the previous row {what} (duplicate_times: {:?})",
            report.duplicate_rows, report.duplicate_times
        ));
    }
    if !report.sentinel_cells.is_empty() {
        let cells: Vec<String> = (report.sentinel_cells.iter())
            .map(|(_, label, n)| format!("{label} {n}"))
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
