//! Fuzz targets for pdcal's file readers, shared by the AFL++ harness (`src/bin/fuzz.rs`)
//! and the property tests (`tests/properties.rs`), so that both hold the readers to the same
//! promises: no input makes a reader panic, and every rejection
//!
//! - names the file it is about,
//! - points inside that file where the format is line-based (CSV and RON syntax: a line and
//!   a column; values checked after parsing may name their field instead),
//! - quotes at most [`QUOTE_LIMIT`] consecutive characters of the input.
//!
//! Each target writes its input to files in a scratch directory and calls the reader the
//! commands use (`read_dataset`, `load_scenario`, `load_config`, ...), so the byte-level
//! paths (non-UTF-8, byte-order mark) and the file names in messages are those a user sees.

mod check;
pub mod mutate;

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use pdcal_dataset::{DatasetMeta, TELEMETRY_CSV, TRUTH_CSV, TRUTH_RON};

pub use check::{Problem, QUOTE_LIMIT};

/// One reader under test.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// dataset.ron and telemetry.csv together through `read_dataset`; the input is the RON
    /// text, a NUL byte, then the CSV text.
    DatasetPair,
    /// dataset.ron alone through `read_meta`.
    DatasetRon,
    /// telemetry.csv through `read_telemetry`, against a fixed dataset.ron (the
    /// `PositionColumns` one when the input mentions `r_x_km`, else the TLE one).
    TelemetryCsv,
    /// truth.csv through `read_truth`, with fixed dataset.ron and truth.ron.
    TruthCsv,
    /// A scenario file through `pdcal::simulate::load_scenario` (`--scenario FILE.ron`).
    ScenarioRon,
    /// A config file through `pdcal::calibrate::load_config` (`--config FILE.ron`: a filter
    /// configuration or a previous calibration.ron).
    ConfigRon,
    /// An import column map through `pdcal::import::import_files` (`pdcal import --map`),
    /// run on a fixed small export (`seeds/fixed/export.csv`).
    ImportMap,
    /// A magcal.ron through `pdcal::magcal::load` (`calibrate --mag-cal FILE`).
    MagcalRon,
    /// Two data sets of a joint run through `pdcal::joint::read` and `join` (each set's
    /// reader, then the checks across the sets), as `calibrate SET1 SET2` runs them.
    JointSets,
}

impl Target {
    /// Every target, in the order of `fuzz/README.md`.
    pub const ALL: [Target; 9] = [
        Target::DatasetPair,
        Target::DatasetRon,
        Target::TelemetryCsv,
        Target::TruthCsv,
        Target::ScenarioRon,
        Target::ConfigRon,
        Target::ImportMap,
        Target::MagcalRon,
        Target::JointSets,
    ];

    /// The name on the command line and of the seed directory `fuzz/seeds/NAME`.
    pub fn name(self) -> &'static str {
        match self {
            Target::DatasetPair => "dataset-pair",
            Target::DatasetRon => "dataset-ron",
            Target::TelemetryCsv => "telemetry-csv",
            Target::TruthCsv => "truth-csv",
            Target::ScenarioRon => "scenario-ron",
            Target::ConfigRon => "config-ron",
            Target::ImportMap => "import-map",
            Target::MagcalRon => "magcal-ron",
            Target::JointSets => "joint-sets",
        }
    }

    /// The target called `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|t| t.name() == name)
    }

    /// The valid inputs the fuzzer starts from (the files of `fuzz/seeds/NAME`).
    pub fn seeds(self) -> Vec<&'static [u8]> {
        match self {
            Target::DatasetPair => vec![
                include_bytes!("../seeds/dataset-pair/tle.bin"),
                include_bytes!("../seeds/dataset-pair/positions.bin"),
            ],
            Target::DatasetRon => vec![TLE_META, POSITIONS_META],
            Target::TelemetryCsv => vec![
                include_bytes!("../seeds/telemetry-csv/tle.csv"),
                include_bytes!("../seeds/telemetry-csv/positions.csv"),
            ],
            Target::TruthCsv => vec![include_bytes!("../seeds/truth-csv/truth.csv")],
            Target::ScenarioRon => vec![include_bytes!("../seeds/scenario-ron/short.ron")],
            Target::ConfigRon => vec![
                include_bytes!("../seeds/config-ron/filter.ron"),
                include_bytes!("../seeds/config-ron/calibration.ron"),
            ],
            Target::ImportMap => vec![
                include_bytes!("../seeds/import-map/map.ron"),
                include_bytes!("../seeds/import-map/map-positions.ron"),
                include_bytes!("../seeds/import-map/map-shapes.ron"),
                include_bytes!("../seeds/import-map/map-currents.ron"),
            ],
            Target::MagcalRon => vec![include_bytes!("../seeds/magcal-ron/magcal.ron")],
            Target::JointSets => vec![include_bytes!("../seeds/joint-sets/two-sets.bin")],
        }
    }
}

impl Target {
    /// Hostile inputs of the issues' hand tests that the reader must refuse, keeping every
    /// promise of its errors (`hostile/TARGET/`); none for most targets.
    pub fn hostile(self) -> Vec<&'static [u8]> {
        match self {
            Target::ConfigRon => vec![
                include_bytes!("../hostile/config-ron/prior-elevation-1000.ron"),
                include_bytes!("../hostile/config-ron/prior-azimuth-1e9.ron"),
                include_bytes!("../hostile/config-ron/prior-scale-negative.ron"),
                include_bytes!("../hostile/config-ron/prior-scale-zero.ron"),
                include_bytes!("../hostile/config-ron/prior-scale-nan.ron"),
                include_bytes!("../hostile/config-ron/prior-scale-1e300.ron"),
            ],
            Target::MagcalRon => vec![
                include_bytes!("../hostile/magcal-ron/variance-nan.ron"),
                include_bytes!("../hostile/magcal-ron/variance-negative.ron"),
                include_bytes!("../hostile/magcal-ron/matrix-stretched.ron"),
                include_bytes!("../hostile/magcal-ron/bias-4.5e6.ron"),
            ],
            _ => Vec::new(),
        }
    }
}

const TLE_META: &[u8] = include_bytes!("../seeds/dataset-ron/tle.ron");
const POSITIONS_META: &[u8] = include_bytes!("../seeds/dataset-ron/positions.ron");
/// truth.ron of the seed dataset, matching [`TLE_META`]'s photodiodes.
const FIXED_TRUTH_RON: &[u8] = include_bytes!("../seeds/fixed/truth.ron");
/// The export the import maps are read against: the first rows of `fixtures/import/export.csv`.
pub(crate) const FIXED_EXPORT_CSV: &[u8] = include_bytes!("../seeds/fixed/export.csv");

/// What a reader made of one input.
#[derive(Debug)]
pub enum Verdict {
    /// The input was read.
    Accepted,
    /// The input was refused with `message` (as the CLI prints it); `problems` lists the
    /// promises the message breaks, empty when it keeps them all.
    Rejected {
        /// The error as displayed (`{:#}` for an `anyhow` chain).
        message: String,
        /// Broken promises.
        problems: Vec<Problem>,
    },
}

impl Verdict {
    /// The problems of a rejection; none for an accepted input.
    pub fn problems(&self) -> &[Problem] {
        match self {
            Verdict::Accepted => &[],
            Verdict::Rejected { problems, .. } => problems,
        }
    }
}

/// Runs `target`'s reader on `input`, with its files written into `scratch` (an existing
/// directory that this target alone uses). Panics only when the reader does, or when the
/// scratch directory cannot be written, which is a broken harness, not a finding.
pub fn exercise(target: Target, input: &[u8], scratch: &Path) -> Verdict {
    let write = |name: &str, bytes: &[u8]| -> PathBuf {
        let path = scratch.join(name);
        // A fresh file rather than a truncated one: ext4 flushes a file that is truncated and
        // rewritten when it is closed, which cost milliseconds per input on a disk.
        let _ = fs::remove_file(&path);
        if let Err(e) = fs::write(&path, bytes) {
            panic!("fuzz harness: cannot write {}: {e}", path.display());
        }
        path
    };
    match target {
        Target::DatasetPair => {
            let (ron, csv) = split_pair(input);
            let files = [
                (write(pdcal_dataset::DATASET_RON, ron), ron),
                (write(TELEMETRY_CSV, csv), csv),
            ];
            check::dataset(pdcal_dataset::read_dataset(scratch).map(drop), &files)
        }
        Target::DatasetRon => {
            let files = [(write(pdcal_dataset::DATASET_RON, input), input)];
            check::dataset(pdcal_dataset::read_meta(scratch).map(drop), &files)
        }
        Target::TelemetryCsv => {
            let files = [(write(TELEMETRY_CSV, input), input)];
            let meta = fixed_meta(contains(input, b"r_x_km"));
            check::dataset(
                pdcal_dataset::read_telemetry(scratch, meta).map(drop),
                &files,
            )
        }
        Target::TruthCsv => {
            let files = [
                (write(TRUTH_CSV, input), input),
                (write(TRUTH_RON, FIXED_TRUTH_RON), FIXED_TRUTH_RON),
            ];
            let meta = fixed_meta(false);
            check::dataset(pdcal_dataset::read_truth(scratch, meta).map(drop), &files)
        }
        Target::ScenarioRon => {
            let path = write("scenario.ron", input);
            // load_scenario takes the command-line text; a scratch path that is not UTF-8
            // would test the harness, not the reader.
            let arg = path.to_string_lossy();
            let result = pdcal::simulate::load_scenario(&arg).map(drop);
            check::scenario(result, &path, input)
        }
        Target::ConfigRon => {
            let path = write("config.ron", input);
            let result = pdcal::calibrate::load_config(&path).map(drop);
            check::config(result, &path, input)
        }
        Target::ImportMap => {
            let files = [
                (write("map.ron", input), input),
                (write("export.csv", FIXED_EXPORT_CSV), FIXED_EXPORT_CSV),
            ];
            let result = pdcal::import::import_files(&files[1].0, &files[0].0).map(drop);
            check::import(result, &files)
        }
        Target::MagcalRon => {
            let path = write("magcal.ron", input);
            let result = pdcal::magcal::load(&path).map(drop);
            check::magcal(result, &path, input)
        }
        Target::JointSets => {
            let mut parts = input.splitn(4, |&b| b == 0);
            let dirs = [scratch.join("set1"), scratch.join("set2")];
            let mut files = Vec::new();
            for dir in &dirs {
                if let Err(e) = fs::create_dir_all(dir) {
                    panic!("fuzz harness: cannot create {}: {e}", dir.display());
                }
                for name in [pdcal_dataset::DATASET_RON, TELEMETRY_CSV] {
                    let bytes = parts.next().unwrap_or_default();
                    let inside =
                        format!("{}/{name}", dir.file_name().unwrap_or_default().display());
                    files.push((write(&inside, bytes), bytes));
                }
            }
            let result = pdcal::joint::read(&dirs)
                .and_then(pdcal::joint::join)
                .map(drop);
            check::joint(result, &files, &dirs, input)
        }
    }
}

/// The dataset.ron and telemetry.csv parts of a [`Target::DatasetPair`] input: before and
/// after the first NUL byte (all of it is dataset.ron when there is none).
pub fn split_pair(input: &[u8]) -> (&[u8], &[u8]) {
    match input.iter().position(|&b| b == 0) {
        Some(i) => (&input[..i], &input[i + 1..]),
        None => (input, &[]),
    }
}

/// A [`Target::DatasetPair`] input from its two parts.
pub fn join_pair(ron: &[u8], csv: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(ron.len() + 1 + csv.len());
    out.extend_from_slice(ron);
    out.push(0);
    out.extend_from_slice(csv);
    out
}

fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    haystack.windows(needle.len()).any(|w| w == needle)
}

/// The seed dataset.ron with a TLE orbit, or its `PositionColumns` twin, parsed once.
fn fixed_meta(positions: bool) -> &'static DatasetMeta {
    static TLE: OnceLock<DatasetMeta> = OnceLock::new();
    static POSITIONS: OnceLock<DatasetMeta> = OnceLock::new();
    let (cell, bytes) = if positions {
        (&POSITIONS, POSITIONS_META)
    } else {
        (&TLE, TLE_META)
    };
    cell.get_or_init(|| {
        let text = std::str::from_utf8(bytes).expect("seed dataset.ron is UTF-8");
        pdcal_dataset::meta_from_str(text).expect("seed dataset.ron is valid")
    })
}

/// A directory for one target's files, removed when dropped.
#[derive(Debug)]
pub struct Scratch {
    path: PathBuf,
}

impl Scratch {
    /// Creates `PARENT/pdcal-fuzz-TAG-PID` afresh; `tag` keeps concurrent users of one
    /// process apart. `PARENT` is, unless given, `/dev/shm` where it exists (every input is
    /// written to a file, and memory keeps that off the disk), else the system's temporary
    /// directory.
    pub fn new(parent: Option<&Path>, tag: &str) -> std::io::Result<Self> {
        let shm = Path::new("/dev/shm");
        let parent = match parent {
            Some(p) => p.to_path_buf(),
            None if shm.is_dir() => shm.to_path_buf(),
            None => std::env::temp_dir(),
        };
        let path = parent.join(format!("pdcal-fuzz-{tag}-{}", std::process::id()));
        if path.exists() {
            fs::remove_dir_all(&path)?;
        }
        fs::create_dir_all(&path)?;
        Ok(Self { path })
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = fs::remove_dir_all(&self.path);
    }
}
