//! The promises every rejection must keep, checked on the error a reader returned.

use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};

use pdcal_dataset::{DatasetError, ErrorKind, FileFaultKind};
use pdcal_filter::FilterError;
use pdcal_import::{ErrorKind as ImportKind, ImportError};
use pdcal_sim::ScenarioError;

use crate::Verdict;

/// The longest run of input characters a message may repeat. docs/dataset-format.md allows
/// "at most 80 characters" of an offending value; the margin lets a cut value keep the quote or
/// separator next to it that the input may share, without letting a whole cell through.
pub const QUOTE_LIMIT: usize = 100;

/// A promise a rejection breaks.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Problem {
    /// The message does not name the file the fault is in.
    FileNotNamed,
    /// A fault in a line-based part of a file without its line (and column, where the
    /// fault is in one cell or token).
    NoPosition,
    /// A line or column that is not in the file.
    PositionOutside {
        /// The line given.
        line: usize,
        /// The column given, if any.
        column: Option<usize>,
    },
    /// The message repeats more than [`QUOTE_LIMIT`] consecutive characters of the input.
    LongQuote,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Problem::FileNotNamed => write!(f, "the message does not name the file"),
            Problem::NoPosition => write!(f, "no line/column for a line-based fault"),
            Problem::PositionOutside { line, column } => {
                write!(f, "position {line}:{column:?} is not in the file")
            }
            Problem::LongQuote => write!(
                f,
                "quotes more than {QUOTE_LIMIT} consecutive characters of the input"
            ),
        }
    }
}

impl Problem {
    /// Whether this is the quoting problem, which the harness can leave out (see
    /// `fuzz/README.md`).
    pub fn is_long_quote(&self) -> bool {
        matches!(self, Problem::LongQuote)
    }
}

/// How precisely a dataset error must be placed.
enum Place {
    /// The file is enough (empty, unreadable).
    File,
    /// A line, or for values checked after parsing a RON file, a field path.
    LineOrField,
    /// A line (a whole CSV row or the header row).
    Line,
    /// A line and a column (one cell, one RON token).
    LineAndColumn,
}

impl Place {
    /// Whether an error's line, column and field path place it this precisely.
    fn given_by(&self, line: Option<usize>, column: Option<usize>, field: Option<&str>) -> bool {
        match self {
            Place::File => true,
            Place::LineOrField => {
                (line.is_some() && column.is_some()) || field.is_some_and(|f| !f.is_empty())
            }
            Place::Line => line.is_some(),
            Place::LineAndColumn => line.is_some() && column.is_some(),
        }
    }
}

/// Checks a result of the dataset reader; `files` are the paths written and their bytes.
pub(crate) fn dataset(result: Result<(), DatasetError>, files: &[(PathBuf, &[u8])]) -> Verdict {
    match result {
        Ok(()) => Verdict::Accepted,
        Err(e) => dataset_error(&e, files),
    }
}

/// Checks a joint run's reading and joining of several sets (`files` of every set, each
/// set's directory in `dirs`): a reader's fault as [`dataset`]'s; a fault across the sets
/// (layout, spacecraft, overlap, references) names the set's directory first.
pub(crate) fn joint(
    result: anyhow::Result<()>,
    files: &[(PathBuf, &[u8])],
    dirs: &[PathBuf],
    input: &[u8],
) -> Verdict {
    let Err(e) = result else {
        return Verdict::Accepted;
    };
    if let Some(d) = e.chain().find_map(|c| c.downcast_ref::<DatasetError>()) {
        return dataset_error(d, files);
    }
    let message = format!("{e:#}");
    let mut problems = Vec::new();
    let named = (dirs.iter()).find_map(|d| message.strip_prefix(&d.display().to_string()));
    match named {
        Some(rest) => problems.extend(long_quote(rest, input)),
        None => problems.push(Problem::FileNotNamed),
    }
    Verdict::Rejected { message, problems }
}

fn dataset_error(e: &DatasetError, files: &[(PathBuf, &[u8])]) -> Verdict {
    let message = e.to_string();
    let mut problems = Vec::new();
    let Some((path, bytes)) = files.iter().find(|(p, _)| p == e.file()) else {
        problems.push(Problem::FileNotNamed);
        return Verdict::Rejected { message, problems };
    };
    let Some(rest) = message.strip_prefix(&path.display().to_string()) else {
        problems.push(Problem::FileNotNamed);
        return Verdict::Rejected { message, problems };
    };
    let is_ron = path.extension().is_some_and(|x| x == "ron");
    let place = dataset_place(e.kind(), is_ron);
    if !place.given_by(e.line(), e.column(), e.field()) {
        problems.push(Problem::NoPosition);
    }
    if let Some(line) = e.line() {
        // RON columns count characters; CSV columns count cells, bounded only below.
        let column_bound = is_ron || matches!(e.kind(), ErrorKind::File(FileFaultKind::NotUtf8));
        if let Some(p) = outside(bytes, line, e.column(), column_bound) {
            problems.push(p);
        }
    }
    problems.extend(long_quote(rest, bytes));
    Verdict::Rejected { message, problems }
}

fn dataset_place(kind: &ErrorKind, is_ron: bool) -> Place {
    match kind {
        ErrorKind::Io { .. }
        | ErrorKind::File(FileFaultKind::Empty)
        | ErrorKind::TruthIncomplete { .. } => Place::File,
        ErrorKind::File(FileFaultKind::NotUtf8) => Place::LineAndColumn,
        ErrorKind::Ron(_) if is_ron => Place::LineAndColumn,
        _ if is_ron => Place::LineOrField,
        ErrorKind::MissingHeader { .. }
        | ErrorKind::NotANumber { .. }
        | ErrorKind::NotFinite { .. }
        | ErrorKind::EmptyCell
        | ErrorKind::PartialVector { .. }
        | ErrorKind::TimeNotIncreasing { .. }
        | ErrorKind::OutOfRange { .. }
        | ErrorKind::UnknownColumn { .. }
        | ErrorKind::DuplicateColumn { .. }
        | ErrorKind::UnexpectedPositionColumn { .. } => Place::LineAndColumn,
        _ => Place::Line,
    }
}

/// Checks a result of `pdcal::import::import_files`; `files` are the map and the export
/// written, with their bytes. An error that is not the import's own (the dataset writer
/// refusing what the import built) does not name either file and is a finding.
pub(crate) fn import(result: anyhow::Result<()>, files: &[(PathBuf, &[u8])]) -> Verdict {
    let Err(e) = result else {
        return Verdict::Accepted;
    };
    let message = format!("{e:#}");
    let mut problems = Vec::new();
    let own = e
        .chain()
        .find_map(|c| c.downcast_ref::<ImportError>())
        .filter(|i| !matches!(i.kind(), ImportKind::Output(_)));
    let located = own.and_then(|i| files.iter().find(|(p, _)| p == i.file()).map(|f| (i, f)));
    let Some((e, (path, bytes))) = located else {
        problems.push(Problem::FileNotNamed);
        return Verdict::Rejected { message, problems };
    };
    let Some(rest) = message.strip_prefix(&path.display().to_string()) else {
        problems.push(Problem::FileNotNamed);
        return Verdict::Rejected { message, problems };
    };
    let is_map = path.extension().is_some_and(|x| x == "ron");
    if !import_place(e.kind(), is_map).given_by(e.line(), e.column(), e.field()) {
        problems.push(Problem::NoPosition);
    }
    if let Some(line) = e.line() {
        // Map columns count characters; export columns count cells, bounded only below.
        let column_bound = is_map || matches!(e.kind(), ImportKind::File(FileFaultKind::NotUtf8));
        if let Some(p) = outside(bytes, line, e.column(), column_bound) {
            problems.push(p);
        }
    }
    problems.extend(long_quote(rest, bytes));
    Verdict::Rejected { message, problems }
}

fn import_place(kind: &ImportKind, is_map: bool) -> Place {
    match kind {
        ImportKind::File(FileFaultKind::Empty) | ImportKind::NoRows { .. } => Place::File,
        ImportKind::File(FileFaultKind::NotUtf8) => Place::LineAndColumn,
        ImportKind::Ron(_) => Place::LineAndColumn,
        _ if is_map => Place::LineOrField,
        ImportKind::File(FileFaultKind::WrongCellCount { .. })
        | ImportKind::File(FileFaultKind::Csv { .. })
        | ImportKind::AmbiguousDelimiter { .. } => Place::Line,
        _ => Place::LineAndColumn,
    }
}

/// Checks a result of `load_scenario` on the file `path` holding `bytes`.
pub(crate) fn scenario(result: anyhow::Result<()>, path: &Path, bytes: &[u8]) -> Verdict {
    let Err(e) = result else {
        return Verdict::Accepted;
    };
    let position = e
        .chain()
        .find_map(|c| c.downcast_ref::<ScenarioError>())
        .and_then(|s| match s {
            ScenarioError::Ron { line, column, .. } => Some(Some((*line, *column))),
            // Values checked after parsing name their field instead.
            ScenarioError::Invalid { .. } => Some(None),
            _ => None,
        });
    anyhow_verdict(&e, path, bytes, position)
}

/// Checks a result of `load_config` on the file `path` holding `bytes`.
pub(crate) fn config(result: anyhow::Result<()>, path: &Path, bytes: &[u8]) -> Verdict {
    let Err(e) = result else {
        return Verdict::Accepted;
    };
    let position = e
        .chain()
        .find_map(|c| c.downcast_ref::<FilterError>())
        .and_then(|f| match f {
            // ron's message starts with its span, `LINE:COL` or `LINE:COL-LINE:COL`.
            FilterError::Ron { message, .. } => Some(ron_position(message)),
            FilterError::Config { .. } | FilterError::Invalid { .. } => Some(None),
            _ => None,
        });
    anyhow_verdict(&e, path, bytes, position)
}

/// A magcal.ron's rejection: a syntax or field error is `PATH:LINE:COLUMN: ...`, a value
/// checked after parsing names its field.
pub(crate) fn magcal(result: anyhow::Result<()>, path: &Path, bytes: &[u8]) -> Verdict {
    let Err(e) = result else {
        return Verdict::Accepted;
    };
    let message = format!("{e:#}");
    let shown = format!("{}:", path.display());
    let position = match message.strip_prefix(&shown) {
        Some(rest) if rest.starts_with(|c: char| c.is_ascii_digit()) => Some(ron_position(rest)),
        _ => Some(None),
    };
    anyhow_verdict(&e, path, bytes, position)
}

/// `position`: `None` when the error is not a RON one (an I/O error: the file is enough),
/// `Some(None)` for a value error that names its field, `Some(Some(..))` for a syntax error,
/// whose line and column must be in the file. A RON syntax error whose position could not be
/// read (`Some(Some((0, 0)))`) is [`Problem::NoPosition`].
fn anyhow_verdict(
    e: &anyhow::Error,
    path: &Path,
    bytes: &[u8],
    position: Option<Option<(usize, usize)>>,
) -> Verdict {
    let message = format!("{e:#}");
    let shown = path.display().to_string();
    let mut problems = Vec::new();
    if !message.contains(&shown) {
        problems.push(Problem::FileNotNamed);
    }
    if let Some(Some((line, column))) = position {
        if line == 0 || column == 0 {
            problems.push(Problem::NoPosition);
        } else if let Some(p) = outside(bytes, line, Some(column), true) {
            problems.push(p);
        }
    }
    problems.extend(long_quote(&message.replace(&shown, ""), bytes));
    Verdict::Rejected { message, problems }
}

/// The start of a ron span at the head of `message`; `(0, 0)` when there is none.
fn ron_position(message: &str) -> Option<(usize, usize)> {
    let head = message.split([':', '-']).take(2).collect::<Vec<_>>();
    let parsed = match head.as_slice() {
        [line, column] => line.trim().parse().ok().zip(column.trim().parse().ok()),
        _ => None,
    };
    Some(parsed.unwrap_or((0, 0)))
}

/// Whether `line` (1-based) and `column` (1-based characters when `column_bound`) lie in
/// `bytes`; the position just past the end counts as inside, as parsers report it for a
/// truncated file.
fn outside(
    bytes: &[u8],
    line: usize,
    column: Option<usize>,
    column_bound: bool,
) -> Option<Problem> {
    let problem = Problem::PositionOutside { line, column };
    let text = String::from_utf8_lossy(bytes);
    let lines: Vec<&str> = text.split('\n').collect();
    let Some(this) = line.checked_sub(1).and_then(|i| lines.get(i)) else {
        return Some(problem);
    };
    match column {
        Some(0) => Some(problem),
        Some(c) if column_bound && c > this.chars().count() + 1 => Some(problem),
        _ => None,
    }
}

/// [`Problem::LongQuote`] when `message` repeats more than [`QUOTE_LIMIT`] consecutive
/// characters of `input`.
///
/// Rabin-Karp over windows of `QUOTE_LIMIT + 1` characters, linear in both lengths: a search
/// of the input per window of the message cost milliseconds per input when ron lists every
/// expected field of a 16 KiB config.
fn long_quote(message: &str, input: &[u8]) -> Option<Problem> {
    let width = QUOTE_LIMIT + 1;
    let input: Vec<char> = String::from_utf8_lossy(input).chars().collect();
    let message: Vec<char> = message.chars().collect();
    if message.len() < width || input.len() < width {
        return None;
    }
    let mut where_in_input: HashMap<u64, Vec<usize>> = HashMap::new();
    for (start, hash) in window_hashes(&input, width) {
        where_in_input.entry(hash).or_default().push(start);
    }
    window_hashes(&message, width)
        .any(|(start, hash)| {
            let window = &message[start..start + width];
            where_in_input
                .get(&hash)
                .is_some_and(|starts| starts.iter().any(|&i| &input[i..i + width] == window))
        })
        .then_some(Problem::LongQuote)
}

/// `(start, hash)` of every window of `width` characters, by a rolling polynomial hash.
fn window_hashes(chars: &[char], width: usize) -> impl Iterator<Item = (usize, u64)> + '_ {
    const BASE: u64 = 1_000_003;
    let top = (1..width).fold(1u64, |p, _| p.wrapping_mul(BASE));
    let mut hash = 0u64;
    chars.iter().enumerate().filter_map(move |(i, &c)| {
        if i >= width {
            let leaving = u64::from(chars[i - width]);
            hash = hash.wrapping_sub(leaving.wrapping_mul(top));
        }
        hash = hash.wrapping_mul(BASE).wrapping_add(u64::from(c));
        (i + 1 >= width).then(|| (i + 1 - width, hash))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_long_quote_is_found_only_past_the_limit() {
        let cell = "x".repeat(QUOTE_LIMIT + 1);
        let input = format!("t_s\n{cell}\n");
        let whole = format!("{cell:?} is not a number");
        assert_eq!(
            long_quote(&whole, input.as_bytes()),
            Some(Problem::LongQuote)
        );
        let cut = format!("{:?}... is not a number", &cell[..QUOTE_LIMIT]);
        assert_eq!(long_quote(&cut, input.as_bytes()), None);
        // A run that ends the message counts too.
        assert_eq!(
            long_quote(&format!("found {cell}"), input.as_bytes()),
            Some(Problem::LongQuote)
        );
    }

    #[test]
    fn ron_positions_come_from_the_span_at_the_head() {
        assert_eq!(ron_position("3:7: Expected comma"), Some((3, 7)));
        assert_eq!(ron_position("3:7-3:9: Unexpected"), Some((3, 7)));
        assert_eq!(ron_position("Unexpected end of RON"), Some((0, 0)));
    }

    #[test]
    fn positions_outside_the_text_are_found() {
        let text = b"ab\ncd";
        assert_eq!(outside(text, 2, Some(3), true), None);
        assert!(outside(text, 2, Some(4), true).is_some());
        assert_eq!(outside(text, 2, Some(40), false), None);
        assert!(outside(text, 3, None, true).is_some());
        assert!(outside(text, 0, None, true).is_some());
        assert!(outside(text, 1, Some(0), false).is_some());
    }

    #[test]
    fn a_dataset_error_must_name_the_file_written() {
        let e = pdcal_dataset::meta_from_str("").unwrap_err();
        let named = dataset(Err(e), &[(PathBuf::from("dataset.ron"), b"")]);
        assert!(named.problems().is_empty(), "{named:?}");
        let e = pdcal_dataset::meta_from_str("").unwrap_err();
        let elsewhere = dataset(Err(e), &[(PathBuf::from("dir/dataset.ron"), b"")]);
        assert_eq!(elsewhere.problems(), [Problem::FileNotNamed]);
    }

    #[test]
    fn an_import_error_is_placed_in_the_map_or_the_export() {
        let dir = std::env::temp_dir().join(format!("pdcal-check-import-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let map = dir.join("map.ron");
        let csv = dir.join("export.csv");
        let map_text = crate::Target::ImportMap.seeds()[0];
        let good = std::str::from_utf8(map_text).unwrap();
        let bad = good.replace("\"adc_ch05\"", "\"adc_ch5\"");
        std::fs::write(&map, &bad).unwrap();
        std::fs::write(&csv, crate::FIXED_EXPORT_CSV).unwrap();
        let result = pdcal::import::import_files(&csv, &map).map(drop);
        let files = [
            (map.clone(), bad.as_bytes()),
            (csv.clone(), crate::FIXED_EXPORT_CSV),
        ];
        let verdict = import(result, &files);
        assert!(
            matches!(&verdict, Verdict::Rejected { problems, .. } if problems.is_empty()),
            "{verdict:?}"
        );
        // The same error checked against other files: the file it names was not written.
        let result = pdcal::import::import_files(&csv, &map).map(drop);
        let verdict = import(result, &files[1..]);
        assert_eq!(verdict.problems(), [Problem::FileNotNamed]);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_ron_syntax_error_needs_its_line_and_column() {
        let text = "(\n    format_version: 1,\n    name: \"a\" \"b\",\n)\n";
        let e = pdcal_dataset::meta_from_str(text).unwrap_err();
        assert!(e.line().is_some(), "{e}");
        let verdict = dataset(Err(e), &[(PathBuf::from("dataset.ron"), text.as_bytes())]);
        assert!(verdict.problems().is_empty(), "{verdict:?}");
        // The same error against a one-line file points outside it.
        let e = pdcal_dataset::meta_from_str(text).unwrap_err();
        let verdict = dataset(Err(e), &[(PathBuf::from("dataset.ron"), b"(")]);
        assert!(
            matches!(verdict.problems(), [Problem::PositionOutside { .. }]),
            "{verdict:?}"
        );
    }
}
