//! The file system side: reading a dataset directory and writing one whole or not at all.

use std::fs;
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::Path;

use crate::bounded::{MAX_RON_BYTES, open_regular, read_bounded};
use crate::error::{DatasetError, ErrorKind, FileFaultKind, io_error, text_of};
use crate::manifest::Manifest;
use crate::meta::{DatasetMeta, parse_meta, render_meta};
use crate::publish::{Publication, PublishError, PublishErrorKind};
use crate::table::CsvRows;
use crate::telemetry::{Telemetry, TelemetryStorage, render_telemetry, telemetry_from_rows_in};
use crate::truth::{
    TruthConstants, TruthSeries, parse_truth_constants, parse_truth_series, render_truth_constants,
    render_truth_series,
};
use crate::{DATASET_RON, TELEMETRY_CSV, TRUTH_CSV, TRUTH_RON};

/// A whole dataset: metadata, telemetry and, for simulated sets, the truth.
#[derive(Clone, Debug, PartialEq)]
pub struct Dataset {
    /// dataset.ron.
    pub meta: DatasetMeta,
    /// telemetry.csv.
    pub telemetry: Telemetry,
    /// truth.csv and truth.ron, both or neither.
    pub truth: Option<(TruthSeries, TruthConstants)>,
}

fn read_text(file: &Path) -> Result<String, DatasetError> {
    read_text_at_most(file, u64::MAX - 1)
}

/// A RON file's text, at most [`MAX_RON_BYTES`].
fn read_ron_text(file: &Path) -> Result<String, DatasetError> {
    read_text_at_most(file, MAX_RON_BYTES)
}

fn read_text_at_most(file: &Path, max_bytes: u64) -> Result<String, DatasetError> {
    let bytes = read_bounded(file, max_bytes).map_err(|e| io_error(file, "cannot read", e))?;
    text_of(file, bytes)
}

/// Reads and validates `dir/dataset.ron`.
pub fn read_meta(dir: &Path) -> Result<DatasetMeta, DatasetError> {
    let file = dir.join(DATASET_RON);
    parse_meta(&file, &read_ron_text(&file)?)
}

/// Reads and validates `dir/telemetry.csv` against its dataset.ron.
///
/// The file is streamed, not held whole as text (a week at 1 Hz is hundreds of MB): one
/// pass checks that it is UTF-8 and not blank, as [`text_of`] does for the other files and
/// with the same errors, then the CSV reader parses it a buffer at a time.
pub fn read_telemetry(dir: &Path, meta: &DatasetMeta) -> Result<Telemetry, DatasetError> {
    read_telemetry_into(dir, meta, &TelemetryStorage::Memory)
}

/// [`read_telemetry`] into the columns of `storage`: with [`TelemetryStorage::Files`], a
/// set of any length in memory that does not grow with its rows.
pub fn read_telemetry_into(
    dir: &Path,
    meta: &DatasetMeta,
    storage: &TelemetryStorage,
) -> Result<Telemetry, DatasetError> {
    let file = dir.join(TELEMETRY_CSV);
    let bom = check_text_file(&file)?;
    let mut source = open_regular(&file).map_err(|e| io_error(&file, "cannot read", e))?;
    if bom {
        source
            .seek(SeekFrom::Start(BOM.len() as u64))
            .map_err(|e| io_error(&file, "cannot read", e))?;
    }
    telemetry_from_rows_in(CsvRows::from_reader(&file, source)?, meta, storage)
}

const BOM: &str = "\u{feff}";

/// [`text_of`]'s checks on a file read a buffer at a time: UTF-8 (the error at the line and
/// column of the first bad byte, a leading byte-order mark counted as a character as there)
/// and not blank once a leading byte-order mark is removed. True when the file starts with
/// one.
fn check_text_file(file: &Path) -> Result<bool, DatasetError> {
    let read_error = |e| io_error(file, "cannot read", e);
    let mut source = open_regular(file).map_err(read_error)?;
    let mut buf = vec![0_u8; 1 << 16];
    // Bytes of a character cut by the end of the previous read, kept at the buffer's start.
    let mut carry = 0;
    let (mut line, mut column) = (1_usize, 1_usize);
    let (mut blank, mut bom, mut at_start) = (true, false, true);
    loop {
        let n = match source.read(&mut buf[carry..]) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(read_error(e)),
        };
        if n == 0 {
            if carry > 0 {
                return Err(DatasetError::at(
                    file,
                    line,
                    Some(column),
                    FileFaultKind::NotUtf8.into(),
                ));
            }
            break;
        }
        let end = carry + n;
        let (valid, bad) = match std::str::from_utf8(&buf[..end]) {
            Ok(text) => (text, None),
            Err(e) => {
                let up_to = e.valid_up_to();
                // The prefix up to `valid_up_to` is UTF-8 by definition.
                let text = std::str::from_utf8(&buf[..up_to]).unwrap_or_default();
                (text, Some((up_to, e.error_len())))
            }
        };
        let mut text = valid;
        if at_start && !text.is_empty() {
            at_start = false;
            if let Some(rest) = text.strip_prefix(BOM) {
                bom = true;
                column += 1;
                text = rest;
            }
        }
        blank = blank && text.trim().is_empty();
        for &b in text.as_bytes() {
            if b == b'\n' {
                line += 1;
                column = 1;
            } else if b & 0xC0 != 0x80 {
                column += 1;
            }
        }
        carry = match bad {
            None => 0,
            Some((_, Some(_))) => {
                return Err(DatasetError::at(
                    file,
                    line,
                    Some(column),
                    FileFaultKind::NotUtf8.into(),
                ));
            }
            Some((up_to, None)) => {
                buf.copy_within(up_to..end, 0);
                end - up_to
            }
        };
    }
    if blank {
        return Err(DatasetError::whole_file(file, FileFaultKind::Empty.into()));
    }
    Ok(bom)
}

/// Reads `dir/truth.csv` and `dir/truth.ron`: `None` when neither exists (flight data), an
/// error when only one does.
pub fn read_truth(
    dir: &Path,
    meta: &DatasetMeta,
) -> Result<Option<(TruthSeries, TruthConstants)>, DatasetError> {
    let csv_file = dir.join(TRUTH_CSV);
    let ron_file = dir.join(TRUTH_RON);
    let exists = |f: &Path| {
        f.try_exists()
            .map_err(|e| io_error(f, "cannot check for", e))
    };
    match (exists(&csv_file)?, exists(&ron_file)?) {
        (false, false) => Ok(None),
        (true, false) => Err(DatasetError::whole_file(
            &ron_file,
            ErrorKind::TruthIncomplete {
                missing: TRUTH_RON.into(),
            },
        )),
        (false, true) => Err(DatasetError::whole_file(
            &csv_file,
            ErrorKind::TruthIncomplete {
                missing: TRUTH_CSV.into(),
            },
        )),
        (true, true) => {
            let series = parse_truth_series(&csv_file, &read_text(&csv_file)?)?;
            let constants = parse_truth_constants(&ron_file, &read_ron_text(&ron_file)?, meta)?;
            Ok(Some((series, constants)))
        }
    }
}

/// Reads and validates a whole dataset directory.
pub fn read_dataset(dir: &Path) -> Result<Dataset, DatasetError> {
    let meta = read_meta(dir)?;
    let telemetry = read_telemetry(dir, &meta)?;
    let truth = read_truth(dir, &meta)?;
    Ok(Dataset {
        meta,
        telemetry,
        truth,
    })
}

/// The files of a dataset as text, `(file name, contents)` in a fixed order, after checking
/// that the reader accepts every one of them (so nothing is written that cannot be read).
///
/// Deterministic: the same dataset gives byte-identical text.
pub fn render_dataset(ds: &Dataset) -> Result<Vec<(&'static str, String)>, DatasetError> {
    crate::telemetry::check_shape(&ds.telemetry, &ds.meta)?;
    let meta_text = render_meta(&ds.meta)?;
    let telemetry_text = render_telemetry(&ds.telemetry);
    let meta = crate::meta::meta_from_str(&meta_text)?;
    crate::telemetry::telemetry_from_str(&telemetry_text, &meta)?;
    let mut files = vec![(DATASET_RON, meta_text), (TELEMETRY_CSV, telemetry_text)];
    if let Some((series, constants)) = &ds.truth {
        crate::truth::check_shape(series)?;
        let series_text = render_truth_series(series);
        let constants_text = render_truth_constants(constants)?;
        crate::truth::truth_series_from_str(&series_text)?;
        crate::truth::truth_constants_from_str(&constants_text, &meta)?;
        files.push((TRUTH_CSV, series_text));
        files.push((TRUTH_RON, constants_text));
    }
    Ok(files)
}

/// Writes `ds` into the directory `dir`, whole or not at all: [`begin_dataset`] then
/// [`DatasetWriter::write`].
pub fn write_dataset(dir: &Path, ds: &Dataset) -> Result<(), DatasetError> {
    let files = render_dataset(ds)?;
    begin_dataset(dir)?.write_rendered(&files)
}

/// A dataset directory being written (see [`crate::publish`]): its target checked and
/// locked, its staging directory ready, and the command that writes it (its manifest's).
#[derive(Debug)]
pub struct DatasetWriter {
    publication: Publication,
    command: String,
    force: bool,
}

/// The manifest `command` of a dataset written by [`write_dataset`] or [`begin_dataset`]
/// (a library or Python write rather than a pdcal command).
pub const LIBRARY_WRITE_COMMAND: &str = "dataset";

/// Starts writing a dataset into `dir`, before the dataset exists, as
/// [`LIBRARY_WRITE_COMMAND`]: [`begin_dataset_as`].
pub fn begin_dataset(dir: &Path) -> Result<DatasetWriter, DatasetError> {
    begin_dataset_as(dir, LIBRARY_WRITE_COMMAND, false)
}

/// Starts writing a dataset into `dir` for `command` (`simulate`, `import`), before the
/// dataset exists: an existing `dir` is replaced only when it is empty or holds a dataset
/// the same command wrote, unchanged since (or changed, with `force`) and with nothing
/// beside it ([`crate::manifest::replace_rule`]); anything else is refused with
/// [`ErrorKind::NotADatasetDir`] and left untouched. Missing parent directories are
/// created. Call it before simulating, so a bad `--out` costs nothing.
pub fn begin_dataset_as(
    dir: &Path,
    command: &str,
    force: bool,
) -> Result<DatasetWriter, DatasetError> {
    let rule = dataset_rule(command, force);
    Publication::begin(dir, &rule)
        .map(|publication| DatasetWriter {
            publication,
            command: command.to_owned(),
            force,
        })
        .map_err(publish_error)
}

impl DatasetWriter {
    /// Writes `ds` (after checking that the reader accepts every file) and publishes it in
    /// one step; on any failure an existing `dir` is kept as it was.
    pub fn write(self, ds: &Dataset) -> Result<(), DatasetError> {
        let files = render_dataset(ds)?;
        self.write_rendered(&files)
    }

    fn write_rendered(self, files: &[(&'static str, String)]) -> Result<(), DatasetError> {
        let staging = self.publication.path();
        for (name, text) in files {
            write_synced(&staging.join(name), text)?;
        }
        self.publish_staged()
    }

    /// The staging directory the files are written into before publication.
    pub(crate) fn staging(&self) -> &Path {
        self.publication.path()
    }

    /// Writes the manifest of what the staging directory holds, then publishes it.
    pub(crate) fn publish_staged(self) -> Result<(), DatasetError> {
        let staging = self.publication.path();
        Manifest::of_dir(staging, &self.command)
            .and_then(|m| m.write(staging))
            .map_err(|e| {
                DatasetError::whole_file(&e.path, ErrorKind::Output { message: e.message })
            })?;
        let rule = dataset_rule(&self.command, self.force);
        self.publication.publish(&rule).map_err(publish_error)
    }
}

fn publish_error(e: PublishError) -> DatasetError {
    let kind = match e.kind {
        PublishErrorKind::Io { action, cause } => ErrorKind::Io {
            action: format!("cannot {action}"),
            source: cause,
        },
        PublishErrorKind::Refused { reason } => ErrorKind::NotADatasetDir { reason },
        PublishErrorKind::NotADirectory => ErrorKind::NotADatasetDir {
            reason: "it is not a directory".into(),
        },
        other => ErrorKind::Output {
            message: other.to_string(),
        },
    };
    DatasetError::whole_file(&e.path, kind)
}

pub(crate) fn write_synced(file: &Path, text: &str) -> Result<(), DatasetError> {
    let mut f = fs::File::create(file).map_err(|e| io_error(file, "cannot create", e))?;
    f.write_all(text.as_bytes())
        .and_then(|()| f.sync_all())
        .map_err(|e| io_error(file, "cannot write", e))
}

/// The rule of [`begin_dataset_as`] for an existing directory.
fn dataset_rule(command: &str, force: bool) -> impl Fn(&Path) -> Result<(), String> + '_ {
    move |dir| {
        crate::manifest::replace_rule(
            dir,
            &crate::manifest::Replacing {
                command,
                force,
                late_files: &[],
            },
        )
    }
}
