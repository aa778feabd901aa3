//! The one error type of the crate: where in which file, and what is wrong there.

use std::fmt;
use std::path::{Path, PathBuf};

/// A dataset that cannot be read or written, with the place of the fault.
///
/// Display follows the editor convention `FILE:LINE:COLUMN (NAME): what`, for example
/// `telemetry.csv:12:4 (pd03_V): "abc" is not a number`; parts that are unknown are left out
/// (`truth.ron (photodiodes[2].scale_V): ...`, `dataset.ron: file is empty`).
///
/// Boxed so that `Result<T, DatasetError>` stays one pointer wide on the happy path.
#[derive(Debug)]
pub struct DatasetError(Box<Inner>);

#[derive(Debug)]
struct Inner {
    file: PathBuf,
    line: Option<usize>,
    column: Option<usize>,
    field: Option<String>,
    kind: ErrorKind,
}

/// What is wrong with a dataset; [`DatasetError`] adds where.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The operating system refused (missing file, permissions, full disk).
    #[error("{action}: {source}")]
    Io {
        /// What was attempted (`cannot read`, `cannot rename ... to ...`).
        action: String,
        /// The cause.
        source: std::io::Error,
    },
    /// A fault any reader of a user's file finds alike (not text, empty, an unknown
    /// `format_version`, a bad epoch, a CSV row's length, the CSV reader's own failure).
    #[error(transparent)]
    File(FileFaultKind),
    /// A CSV file has a header row but no data rows.
    #[error("no data rows after the header")]
    NoRows,
    /// The first CSV row looks like data, not column names.
    #[error(
        "missing header row: the first row must name the columns, found {}",
        quote(value)
    )]
    MissingHeader {
        /// The first cell of the first row.
        value: String,
    },
    /// A RON syntax or type error, a field the format does not define or a required one
    /// absent.
    #[error(transparent)]
    Ron(crate::RonFaultKind),
    /// A TLE line whose checksum (column 69) does not match its digits.
    #[error(
        "TLE line {line_number} checksum fails: {}, the checksum of columns 1-68 is {computed}",
        checksum_stated(*.stated)
    )]
    BadTleChecksum {
        /// 1 or 2.
        line_number: u8,
        /// The character in column 69, if any.
        stated: Option<char>,
        /// The modulo-10 checksum of columns 1-68.
        computed: u32,
    },
    /// A TLE line that does not start with its line number.
    #[error("TLE line {line_number} must start with \"{line_number} \"")]
    BadTleLine {
        /// 1 or 2.
        line_number: u8,
    },
    /// A CSV column that the format does not define.
    #[error("unknown column {}{hint}", quote(.name))]
    UnknownColumn {
        /// The header found.
        name: String,
        /// A suggestion, empty or starting with `; `.
        hint: String,
    },
    /// A required CSV column is absent.
    #[error("missing column {name:?}{hint}")]
    MissingColumn {
        /// The header that is required.
        name: String,
        /// A reason, empty or starting with `; `.
        hint: String,
    },
    /// A CSV column appears twice.
    #[error("column {name:?} appears twice")]
    DuplicateColumn {
        /// The repeated header.
        name: String,
    },
    /// `r_*_km` columns with a TLE orbit.
    #[error("column {name:?} is only allowed with `orbit: PositionColumns` in dataset.ron")]
    UnexpectedPositionColumn {
        /// The header found.
        name: String,
    },
    /// The number of `pdNN_V` columns differs from the `photodiodes` entries of dataset.ron.
    #[error(
        "photodiode count mismatch: dataset.ron lists {in_meta} photodiodes, \
         {what} {found}"
    )]
    PhotodiodeCountMismatch {
        /// Entries in dataset.ron.
        in_meta: usize,
        /// What was counted, phrased to precede the count (`the header's pdNN_V columns number`).
        what: String,
        /// How many of those.
        found: usize,
    },
    /// Text that does not parse as a number.
    #[error("{} is not a number", quote(value))]
    NotANumber {
        /// The cell text.
        value: String,
    },
    /// `NaN` or an infinity.
    #[error("{} is not a finite number", quote(value))]
    NotFinite {
        /// The cell text (or the value's text when it came from RON or memory).
        value: String,
    },
    /// An empty cell where a value is required (`t_s`, every truth cell).
    #[error("empty cell; this column needs a value on every row")]
    EmptyCell,
    /// One or two components of a 3-vector sampled, the others empty.
    #[error("{present} has a value but {empty} is empty; a vector is sampled whole or not at all")]
    PartialVector {
        /// A header with a value.
        present: String,
        /// A header left empty.
        empty: String,
    },
    /// `t_s` not strictly increasing.
    #[error(
        "t_s {} is not greater than the previous row's {}",
        pdcal_text::number(*.value),
        pdcal_text::number(*.previous)
    )]
    TimeNotIncreasing {
        /// The previous row's time.
        previous: f64,
        /// This row's time.
        value: f64,
    },
    /// A value outside its allowed range (negative noise hint, eclipse above 1, ...).
    #[error("{value:?} is out of range: {rule}")]
    OutOfRange {
        /// The value.
        value: f64,
        /// The allowed range.
        rule: String,
    },
    /// A list whose length does not match what it describes.
    #[error("has {found} entries, expected {expected}")]
    WrongLength {
        /// The length required.
        expected: usize,
        /// The length found.
        found: usize,
    },
    /// Only one of truth.csv and truth.ron exists.
    #[error("{missing} is missing; truth.csv and truth.ron come together")]
    TruthIncomplete {
        /// The file that is absent.
        missing: String,
    },
    /// The output path holds something that is not a pdcal dataset.
    #[error("{reason}")]
    NotADatasetDir {
        /// What is there instead.
        reason: String,
    },
    /// The output directory cannot be written (locked by another run, a dangling symlink,
    /// not a directory).
    #[error("{message}")]
    Output {
        /// What is wrong with it.
        message: String,
    },
    /// A `temp_<panel>_C` column whose panel no photodiode in dataset.ron is on.
    #[error(
        "no photodiode in dataset.ron has panel: {panel:?}, so this temperature column would \
         be unused"
    )]
    UnreferencedPanel {
        /// The panel named by the column.
        panel: String,
    },
    /// A dataset.ron `panel` that cannot appear in a `temp_<panel>_C` column name.
    #[error("{value:?} is not a panel name: use a-z, 0-9 and _, not starting with pd and a digit")]
    BadPanelName {
        /// The name found.
        value: String,
    },
    /// dataset.ron's `inertia_kg_m2` is no rigid body's.
    #[error("not a rigid body's inertia: {reason}")]
    BadInertia {
        /// Which check failed, with the values.
        reason: String,
    },
    /// The same effect listed twice in truth.ron.
    #[error("effect {id:?} is listed twice")]
    DuplicateEffect {
        /// The effect id.
        id: String,
    },
}

/// What is wrong with a user's file that every reader of one finds alike: the one list of
/// these kinds and their messages, which the dataset's and the import's error kinds both
/// carry (`ErrorKind::File`), as they carry [`crate::RonFaultKind`].
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FileFaultKind {
    /// The bytes are not UTF-8 text.
    #[error("not UTF-8 text")]
    NotUtf8,
    /// The file has no content (only whitespace at most).
    #[error("file is empty")]
    Empty,
    /// `format_version` is not one this reader knows.
    #[error("format_version {found} is not supported (this reader knows {known})")]
    UnsupportedVersion {
        /// The version in the file.
        found: u32,
        /// The version this reader knows.
        known: u32,
    },
    /// An epoch that is not ISO 8601 UTC.
    #[error(
        "{} is not an ISO 8601 UTC time like \"2011-11-04T18:29:45Z\": {reason}",
        quote(value)
    )]
    BadEpoch {
        /// The text found.
        value: String,
        /// Why it was refused.
        reason: String,
    },
    /// A CSV row with a different number of cells than the header.
    #[error("row has {found} cells, the header has {expected}")]
    WrongCellCount {
        /// Cells in the header.
        expected: usize,
        /// Cells in this row.
        found: usize,
    },
    /// A CSV reader failure that is none of the above.
    #[error("{message}")]
    Csv {
        /// The csv crate's description.
        message: String,
    },
}

impl From<FileFaultKind> for ErrorKind {
    fn from(kind: FileFaultKind) -> Self {
        ErrorKind::File(kind)
    }
}

impl DatasetError {
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

    /// An error at a CSV cell or RON position.
    pub(crate) fn at(file: &Path, line: usize, column: Option<usize>, kind: ErrorKind) -> Self {
        let mut e = Self::whole_file(file, kind);
        e.0.line = Some(line);
        e.0.column = column;
        e
    }

    /// The same error naming a column header or field path.
    pub(crate) fn named(mut self, field: impl Into<String>) -> Self {
        self.0.field = Some(field.into());
        self
    }

    /// The file, as the caller named it (`dir/telemetry.csv`), or just its name when the
    /// text did not come from disk.
    pub fn file(&self) -> &Path {
        &self.0.file
    }

    /// The file's name without its directory (`telemetry.csv`).
    pub fn file_name(&self) -> String {
        let file = &self.0.file;
        file.file_name()
            .map_or_else(|| pdcal_text::path(file), pdcal_text::path)
    }

    /// 1-based line, as a text editor shows it.
    pub fn line(&self) -> Option<usize> {
        self.0.line
    }

    /// 1-based column: the CSV cell number, or the character column in RON.
    pub fn column(&self) -> Option<usize> {
        self.0.column
    }

    /// The CSV header of that column, or the RON field path (`photodiodes[3].azimuth_deg`).
    pub fn field(&self) -> Option<&str> {
        self.0.field.as_deref()
    }

    /// What is wrong.
    pub fn kind(&self) -> &ErrorKind {
        &self.0.kind
    }
}

impl fmt::Display for DatasetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let e = &self.0;
        write!(f, "{}", pdcal_text::path(&e.file))?;
        if let Some(line) = e.line {
            write!(f, ":{line}")?;
            if let Some(column) = e.column {
                write!(f, ":{column}")?;
            }
        }
        if let Some(field) = &e.field {
            // A header or field path comes from the file too: cut and escaped like any
            // quoted value.
            write!(f, " ({})", clip(field))?;
        }
        write!(f, ": {}", e.kind)
    }
}

// The kind's text is part of Display, so it is not also returned as `source` (that would
// print it twice in an `anyhow` chain).
impl std::error::Error for DatasetError {}

pub(crate) use pdcal_text::{clip, quote};

pub(crate) use pdcal_text::line_col;

/// Why a user's file is not text to read: the one check of every reader of a user's text
/// file (here and in `pdcal-import`), each of which turns it into its own error kind.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TextFault {
    /// Not UTF-8: the 1-based line and character column of the first invalid byte.
    NotUtf8 {
        /// Line of the first invalid byte.
        line: usize,
        /// Character column of the first invalid byte.
        column: usize,
    },
    /// Blank (only whitespace at most).
    Empty,
}

impl TextFault {
    /// The 1-based line and character column of the fault, `None` for the whole file.
    pub fn place(&self) -> Option<(usize, usize)> {
        match *self {
            TextFault::NotUtf8 { line, column } => Some((line, column)),
            TextFault::Empty => None,
        }
    }

    /// The fault's kind, as every reader reports it.
    pub fn kind(&self) -> FileFaultKind {
        match self {
            TextFault::NotUtf8 { .. } => FileFaultKind::NotUtf8,
            TextFault::Empty => FileFaultKind::Empty,
        }
    }
}

/// Checks the bytes are UTF-8 and not blank; strips a leading byte-order mark.
pub fn decode_text(bytes: Vec<u8>) -> Result<String, TextFault> {
    let text = String::from_utf8(bytes).map_err(|e| {
        let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let before = String::from_utf8_lossy(valid);
        let (line, column) = line_col(&before, before.len());
        TextFault::NotUtf8 { line, column }
    })?;
    let text = match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_owned(),
        None => text,
    };
    if text.trim().is_empty() {
        return Err(TextFault::Empty);
    }
    Ok(text)
}

/// [`decode_text`] with the fault as this crate's error.
pub(crate) fn text_of(file: &Path, bytes: Vec<u8>) -> Result<String, DatasetError> {
    decode_text(bytes).map_err(|fault| {
        let kind = fault.kind().into();
        match fault.place() {
            Some((line, column)) => DatasetError::at(file, line, Some(column), kind),
            None => DatasetError::whole_file(file, kind),
        }
    })
}

/// An I/O failure on `file` while doing `action` ("cannot read", ...).
pub(crate) fn io_error(
    file: &std::path::Path,
    action: &str,
    source: std::io::Error,
) -> DatasetError {
    DatasetError::whole_file(
        file,
        ErrorKind::Io {
            action: action.to_owned(),
            source,
        },
    )
}

/// What column 69 of a TLE line holds, for the checksum message.
fn checksum_stated(stated: Option<char>) -> String {
    match stated {
        Some(c) => format!("column 69 holds {}", quote(&c.to_string())),
        None => "the line ends before column 69, the checksum digit".to_owned(),
    }
}
