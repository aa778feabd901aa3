//! The file system side: reading a dataset directory and writing one whole or not at all.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{DatasetError, ErrorKind, text_of};
use crate::meta::{DatasetMeta, parse_meta, render_meta};
use crate::telemetry::{Telemetry, parse_telemetry, render_telemetry};
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

fn io_error(file: &Path, action: &str, source: std::io::Error) -> DatasetError {
    DatasetError::whole_file(
        file,
        ErrorKind::Io {
            action: action.to_owned(),
            source,
        },
    )
}

fn read_text(file: &Path) -> Result<String, DatasetError> {
    let bytes = fs::read(file).map_err(|e| io_error(file, "cannot read", e))?;
    text_of(file, bytes)
}

/// Reads and validates `dir/dataset.ron`.
pub fn read_meta(dir: &Path) -> Result<DatasetMeta, DatasetError> {
    let file = dir.join(DATASET_RON);
    parse_meta(&file, &read_text(&file)?)
}

/// Reads and validates `dir/telemetry.csv` against its dataset.ron.
pub fn read_telemetry(dir: &Path, meta: &DatasetMeta) -> Result<Telemetry, DatasetError> {
    let file = dir.join(TELEMETRY_CSV);
    parse_telemetry(&file, &read_text(&file)?, meta)
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
            let constants = parse_truth_constants(&ron_file, &read_text(&ron_file)?, meta)?;
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

/// Writes `ds` into the directory `dir`, whole or not at all.
///
/// The files are written into a fresh hidden sibling directory (`.NAME.pdcal-tmp-PID-N`),
/// flushed to disk, and only then renamed to `dir`. If `dir` exists it is replaced, but only
/// when it is empty or a pdcal dataset directory (`dataset.ron`, plus at most
/// `telemetry.csv`, `truth.csv`, `truth.ron`, nothing else); anything else is refused with
/// [`ErrorKind::NotADatasetDir`] and left untouched. Missing parent directories are created.
/// On any failure the temporary directory is removed and an existing `dir` is kept (or put
/// back, if the failure came between the two renames of the swap).
pub fn write_dataset(dir: &Path, ds: &Dataset) -> Result<(), DatasetError> {
    let files = render_dataset(ds)?;
    let replacing = check_replaceable(dir)?;
    let parent = match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    fs::create_dir_all(&parent).map_err(|e| io_error(&parent, "cannot create", e))?;
    let staging = Scratch::new(&parent, dir)?;
    for (name, text) in &files {
        write_synced(&staging.path.join(name), text)?;
    }
    if replacing {
        let old = Scratch::new(&parent, dir)?;
        let old_copy = old.path.join("old");
        fs::rename(dir, &old_copy).map_err(|e| io_error(dir, "cannot move aside", e))?;
        if let Err(e) = fs::rename(&staging.path, dir) {
            // Put the previous dataset back; if even that fails, keep it where it is so
            // nothing is lost, and say where.
            let action = match fs::rename(&old_copy, dir) {
                Ok(()) => "cannot move the new dataset into place".to_owned(),
                Err(_) => {
                    let action = format!(
                        "cannot move the new dataset into place (the previous one is in {})",
                        old_copy.display()
                    );
                    old.keep();
                    action
                }
            };
            return Err(io_error(dir, &action, e));
        }
        // `old` is dropped here and removes the previous dataset.
    } else {
        fs::rename(&staging.path, dir)
            .map_err(|e| io_error(dir, "cannot move the new dataset into place", e))?;
    }
    staging.keep();
    Ok(())
}

fn write_synced(file: &Path, text: &str) -> Result<(), DatasetError> {
    let mut f = fs::File::create(file).map_err(|e| io_error(file, "cannot create", e))?;
    f.write_all(text.as_bytes())
        .and_then(|()| f.sync_all())
        .map_err(|e| io_error(file, "cannot write", e))
}

/// Whether `dir` exists and may be replaced; errors when it exists and may not.
fn check_replaceable(dir: &Path) -> Result<bool, DatasetError> {
    let refuse =
        |reason: String| DatasetError::whole_file(dir, ErrorKind::NotADatasetDir { reason });
    let meta = match fs::symlink_metadata(dir) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
        Err(e) => return Err(io_error(dir, "cannot inspect", e)),
    };
    if !meta.is_dir() {
        return Err(refuse("it is not a directory".into()));
    }
    let entries = fs::read_dir(dir).map_err(|e| io_error(dir, "cannot list", e))?;
    let mut names = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| io_error(dir, "cannot list", e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        let is_file = entry.file_type().is_ok_and(|t| t.is_file());
        let known = [DATASET_RON, TELEMETRY_CSV, TRUTH_CSV, TRUTH_RON].contains(&name.as_str());
        if !(is_file && known) {
            return Err(refuse(format!("it holds {name:?}")));
        }
        names.push(name);
    }
    if !names.is_empty() && !names.iter().any(|n| n == DATASET_RON) {
        return Err(refuse("it has no dataset.ron".into()));
    }
    Ok(true)
}

/// A hidden directory next to the target, removed on drop unless kept.
///
/// Hand-made rather than `tempfile::TempDir`, which creates directories with mode 0700 that
/// would become the dataset's own permissions after the rename.
struct Scratch {
    path: PathBuf,
    keep: bool,
}

impl Scratch {
    fn new(parent: &Path, target: &Path) -> Result<Self, DatasetError> {
        let stem = target
            .file_name()
            .map_or_else(|| "dataset".into(), |n| n.to_string_lossy().into_owned());
        let pid = std::process::id();
        let mut last_error = None;
        for n in 0..1000 {
            let path = parent.join(format!(".{stem}.pdcal-tmp-{pid}-{n}"));
            match fs::create_dir(&path) {
                Ok(()) => return Ok(Self { path, keep: false }),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last_error = Some(e),
                Err(e) => return Err(io_error(&path, "cannot create", e)),
            }
        }
        let e = last_error.unwrap_or_else(|| std::io::Error::other("no free name"));
        Err(io_error(
            parent,
            "cannot create a temporary directory in",
            e,
        ))
    }

    /// The directory was renamed into place: nothing to remove.
    fn keep(mut self) {
        self.keep = true;
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !self.keep {
            let _ = fs::remove_dir_all(&self.path);
        }
    }
}
