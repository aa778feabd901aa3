//! The crate's error: which file (the map or the export), where in it, and what is wrong.

use std::fmt;
use std::path::{Path, PathBuf};

use pdcal_dataset::{DatasetError, FileFaultKind};
pub(crate) use pdcal_text::quote;

/// An import that cannot be done, with the place of the fault.
///
/// Display follows the dataset reader's editor convention `FILE:LINE:COLUMN (NAME): what`:
/// `map.ron:14:19 (photodiodes[2].column): column "css_3" is not in export.csv's header
/// (line 1) ...`, `export.csv:57:4 (css_3): "abc" is not a number (photodiodes[2] of
/// map.ron:14)`. In the map the column is the character column; in the export it is the
/// cell number. Parts that are unknown are left out.
#[derive(Debug)]
pub struct ImportError(Box<Inner>);

#[derive(Debug)]
struct Inner {
    file: PathBuf,
    line: Option<usize>,
    column: Option<usize>,
    field: Option<String>,
    kind: ErrorKind,
}

/// What is wrong; [`ImportError`] adds where.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ErrorKind {
    /// A fault any reader of a user's file finds alike (not text, empty, an unknown
    /// `format_version`, a bad epoch, a CSV row's length, the CSV reader's own failure):
    /// the dataset reader's kinds.
    #[error(transparent)]
    File(FileFaultKind),
    /// A RON syntax or type error in the map, a map field the format does not define or a
    /// required one absent (the dataset reader's kinds).
    #[error(transparent)]
    Ron(pdcal_dataset::RonFaultKind),
    /// A column the map names that the export's header does not have.
    #[error(
        "column {} is not in {csv}'s header (line {header_line}), which has {}",
        quote(.name),
        .available
    )]
    UnknownColumn {
        /// The name in the map.
        name: String,
        /// The export's file name.
        csv: String,
        /// The header's line in the export (1 unless blank lines precede it).
        header_line: usize,
        /// The header's names, clipped.
        available: String,
    },
    /// A column the map names appears more than once in the export's header.
    #[error(
        "column {} appears twice in the header (cells {first} and {second}), so the map's \
         reference to it is ambiguous",
        quote(.name)
    )]
    AmbiguousColumn {
        /// The header name.
        name: String,
        /// 1-based cell of the first occurrence.
        first: usize,
        /// 1-based cell of the second.
        second: usize,
    },
    /// An empty column name in the map.
    #[error("the column name is empty")]
    EmptyColumnName,
    /// A unit the map gives that is not one of those allowed for the quantity.
    #[error("unit {} is not a unit of {quantity}: use one of {allowed}", quote(.unit))]
    UnknownUnit {
        /// The unit text.
        unit: String,
        /// What the column measures (`angular rate`).
        quantity: &'static str,
        /// The units allowed, comma-separated.
        allowed: String,
    },
    /// A column spec with both or neither of `column` and `columns`.
    #[error(
        "give exactly one of `column: \"HEADER\"` or `columns: [(\"HEADER\", 1.0), \
         (\"OTHER\", -1.0)]`"
    )]
    ColumnOrColumns,
    /// Two entries of the map that stand for different data (two axes of one vector
    /// sensor, two photodiodes, two currents) read the same export data.
    #[error("reads the same export data as {other}: {never}")]
    SharedColumn {
        /// The other entry's map path (`gyro.x`, `photodiodes[0]`).
        other: String,
        /// Which two never share a column, and why.
        never: &'static str,
    },
    /// A `columns` combination that cannot be used.
    #[error("the combination is refused: {reason}")]
    BadCombination {
        /// What is wrong.
        reason: String,
    },
    /// The header line names no delimiter clearly.
    #[error(
        "cannot tell the delimiter from the header line ({counts}): give `delimiter: Comma`, \
         `Semicolon`, `Tab` or `Whitespace` in the map"
    )]
    AmbiguousDelimiter {
        /// The candidates and how often each appears.
        counts: String,
    },
    /// A column spec with both or neither of `unit` and `counts`.
    #[error("give exactly one of `unit: \"...\"` or `counts: (gain: .., offset: .., unit: ..)`")]
    UnitOrCounts,
    /// A number in the map that is not finite or not allowed (zero gain).
    #[error("{value} is not allowed: {rule}")]
    BadMapNumber {
        /// The number as Rust prints it.
        value: String,
        /// The rule.
        rule: &'static str,
    },
    /// A temperature column without a valid photodiode or panel.
    #[error("{reason}")]
    BadTemperatureTarget {
        /// What is wrong.
        reason: String,
    },
    /// A current column whose name cannot make a `cur_<name>_A` header.
    #[error("{reason}")]
    BadCurrentName {
        /// What is wrong.
        reason: String,
    },
    /// A current outside the dataset's plausible range: a unit or conversion mistake.
    #[error(
        "{value} converts to {amperes} A, outside {low} .. {high} A{context}: a unit or conversion mistake (mA given as A?)"
    )]
    ImplausibleCurrent {
        /// The cell as written.
        value: String,
        /// Its value in amperes.
        amperes: f64,
        /// The range's lower end, A.
        low: f64,
        /// The range's upper end, A.
        high: f64,
        /// What the map reads the cell as.
        context: String,
    },
    /// A temperature outside the dataset's plausible range: a unit or conversion mistake.
    #[error(
        "{value} converts to {celsius:.2} C, outside {low} .. {high} C{context}: a unit or conversion mistake (kelvin given as C?)"
    )]
    ImplausibleTemperature {
        /// The cell as written.
        value: String,
        /// Its value in degrees Celsius.
        celsius: f64,
        /// The range's lower end, C.
        low: f64,
        /// The range's upper end, C.
        high: f64,
        /// What the map reads the cell as.
        context: String,
    },
    /// A value of the map that the dataset format refuses (a mounting angle out of range, a
    /// TLE checksum, a noise hint); the message is the dataset reader's.
    #[error("{message}")]
    Dataset {
        /// The dataset reader's message.
        message: String,
    },
    /// TLE lines that SGP4 cannot initialise.
    #[error("the TLE cannot be propagated: {message}")]
    Tle {
        /// The orbit crate's message, clipped.
        message: String,
    },
    /// A cell that does not parse as a number.
    #[error("{} is not a number{}", quote(.value), .context)]
    NotANumber {
        /// The cell text.
        value: String,
        /// Empty or ` (...)`: what the map reads this column as.
        context: String,
    },
    /// `NaN` or an infinity in a cell.
    #[error("{} is not a finite number{}", quote(.value), .context)]
    NotFinite {
        /// The cell text.
        value: String,
        /// Empty or ` (...)`.
        context: String,
    },
    /// A time cell that does not read in the map's time form.
    #[error("{} is not {form}: {reason}", quote(.value))]
    BadTime {
        /// The cell text.
        value: String,
        /// The form the map gives (`Unix seconds`).
        form: &'static str,
        /// Why.
        reason: String,
    },
    /// Times not strictly increasing.
    #[error(
        "time {} is not after the previous kept row's {} (line {previous_line}); rows must be in \
         time order: sort the export first",
        .value,
        .previous
    )]
    TimeNotIncreasing {
        /// This row's time as UTC.
        value: String,
        /// The previous kept row's time as UTC.
        previous: String,
        /// The previous kept row's line in the export.
        previous_line: usize,
    },
    /// A time equal to the previous kept row's, under `duplicate_times: Refuse`.
    #[error(
        "time {} is the same as the previous kept row's (line {previous_line}): the export \
         has several rows with one time tag; say in the map which to use, \
         `duplicate_times: KeepFirst` or `duplicate_times: Average`",
        .value
    )]
    DuplicateTime {
        /// The time as UTC.
        value: String,
        /// The previous kept row's line in the export.
        previous_line: usize,
    },
    /// No row has a usable time.
    #[error("no row with a time is left ({dropped} dropped: blank or sentinel time)")]
    NoRows {
        /// Rows dropped.
        dropped: usize,
    },
    /// The dataset built from the export is refused by the dataset writer (or cannot be
    /// written); the message is the dataset crate's, naming its own file.
    #[error("{0}")]
    Output(DatasetError),
}

impl ImportError {
    /// An error about a whole file.
    pub(crate) fn whole_file(file: &Path, kind: ErrorKind) -> Self {
        Self(Box::new(Inner {
            file: file.to_path_buf(),
            line: None,
            column: None,
            field: None,
            kind,
        }))
    }

    /// An error at a line and (optionally) column.
    pub(crate) fn at(file: &Path, line: usize, column: Option<usize>, kind: ErrorKind) -> Self {
        let mut e = Self::whole_file(file, kind);
        e.0.line = Some(line);
        e.0.column = column;
        e
    }

    /// An error at `place` when known, else about the whole file.
    pub(crate) fn maybe_at(file: &Path, place: Option<(usize, usize)>, kind: ErrorKind) -> Self {
        match place {
            Some((line, column)) => Self::at(file, line, Some(column), kind),
            None => Self::whole_file(file, kind),
        }
    }

    /// The same error naming a map field path or an export column header.
    pub(crate) fn named(mut self, field: impl Into<String>) -> Self {
        self.0.field = Some(field.into());
        self
    }

    /// The file the fault is in (the map or the export), as the caller named it; for
    /// [`ErrorKind::Output`] the dataset file the writer refused.
    pub fn file(&self) -> &Path {
        &self.0.file
    }

    /// 1-based line, as a text editor shows it.
    pub fn line(&self) -> Option<usize> {
        self.0.line
    }

    /// 1-based column: the character column in the map, the cell number in the export.
    pub fn column(&self) -> Option<usize> {
        self.0.column
    }

    /// The map's field path (`photodiodes[3].column`) or the export's column header.
    pub fn field(&self) -> Option<&str> {
        self.0.field.as_deref()
    }

    /// What is wrong.
    pub fn kind(&self) -> &ErrorKind {
        &self.0.kind
    }
}

impl From<DatasetError> for ImportError {
    fn from(e: DatasetError) -> Self {
        let file = e.file().to_path_buf();
        Self::whole_file(&file, ErrorKind::Output(e))
    }
}

impl fmt::Display for ImportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let e = &self.0;
        if let ErrorKind::Output(inner) = &e.kind {
            // The dataset error names its own file and place.
            return write!(f, "{inner}");
        }
        write!(f, "{}", pdcal_text::path(&e.file))?;
        if let Some(line) = e.line {
            write!(f, ":{line}")?;
            if let Some(column) = e.column {
                write!(f, ":{column}")?;
            }
        }
        if let Some(field) = &e.field {
            write!(f, " ({})", shown(field))?;
        }
        write!(f, ": {}", e.kind)
    }
}

// The kind's text is part of Display, so it is not also returned as `source` (that would
// print it twice in an `anyhow` chain).
impl std::error::Error for ImportError {}

pub(crate) use pdcal_text::{clip, line_col, number};

/// A name from the input for a message: as it is when it is short and printable, else
/// quoted, with control characters escaped and cut to the limit of [`quote`] (so an ESC in
/// a header cannot reach the terminal and a 100 MB header is not repeated).
pub fn shown(name: &str) -> String {
    if name.chars().any(|c| c.is_control()) {
        quote(name)
    } else {
        clip(name)
    }
}

/// The dataset reader's text check ([`pdcal_dataset::decode_text`]) with the fault as this
/// crate's error.
pub(crate) fn text_of(file: &Path, bytes: Vec<u8>) -> Result<String, ImportError> {
    pdcal_dataset::decode_text(bytes)
        .map_err(|fault| ImportError::maybe_at(file, fault.place(), fault.kind().into()))
}

impl From<FileFaultKind> for ErrorKind {
    fn from(kind: FileFaultKind) -> Self {
        ErrorKind::File(kind)
    }
}

impl From<pdcal_dataset::RonFaultKind> for ErrorKind {
    fn from(kind: pdcal_dataset::RonFaultKind) -> Self {
        ErrorKind::Ron(kind)
    }
}
