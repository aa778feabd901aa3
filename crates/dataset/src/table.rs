//! CSV reading shared by telemetry.csv and truth.csv: header, rows, and cells parsed into
//! numbers with the row and column of every fault; plus the float format of the writer.

use std::io::Read;
use std::path::Path;

use csv::{ReaderBuilder, StringRecord, Trim};
use nalgebra::Vector3;

use crate::error::{DatasetError, ErrorKind, FileFaultKind};

/// A CSV text being read row by row, from memory or streamed from a file (`R`). Cells are
/// trimmed of surrounding blanks, so `t_s, gyro_x_rad_s` is read like `t_s,gyro_x_rad_s`;
/// blank lines are skipped.
pub(crate) struct CsvRows<'a, R = &'a [u8]> {
    file: &'a Path,
    reader: csv::Reader<crate::CrlfToLf<R>>,
    record: StringRecord,
    /// The header cells.
    pub header: Vec<String>,
    /// Line of the header row (1 unless blank lines precede it).
    pub header_line: usize,
}

impl<'a> CsvRows<'a> {
    /// Reads the header row; refuses blank text and a first row that starts with a number.
    pub fn open(file: &'a Path, text: &'a str) -> Result<Self, DatasetError> {
        if text.trim().is_empty() {
            return Err(DatasetError::whole_file(file, FileFaultKind::Empty.into()));
        }
        CsvRows::from_reader(file, text.as_bytes())
    }
}

impl<'a, R: Read> CsvRows<'a, R> {
    /// [`CsvRows::open`] on text the caller has checked to be UTF-8 and not blank
    /// (`files::check_text_file`), read as it is needed.
    pub fn from_reader(file: &'a Path, source: R) -> Result<Self, DatasetError> {
        let reader = ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .trim(Trim::All)
            .buffer_capacity(1 << 16)
            .from_reader(crate::CrlfToLf::new(source));
        let mut rows = Self {
            file,
            reader,
            record: StringRecord::new(),
            header: Vec::new(),
            header_line: 1,
        };
        let Some(line) = rows.read_record()? else {
            return Err(DatasetError::whole_file(file, FileFaultKind::Empty.into()));
        };
        rows.header_line = line;
        rows.header = rows.record.iter().map(str::to_owned).collect();
        let first = rows.header.first().map_or("", String::as_str);
        if first.parse::<f64>().is_ok() {
            let kind = ErrorKind::MissingHeader {
                value: first.to_owned(),
            };
            return Err(DatasetError::at(file, line, Some(1), kind));
        }
        Ok(rows)
    }

    fn read_record(&mut self) -> Result<Option<usize>, DatasetError> {
        match self.reader.read_record(&mut self.record) {
            Ok(false) => Ok(None),
            Ok(true) => {
                Ok(Some(self.record.position().map_or(1, |p| {
                    usize::try_from(p.line()).unwrap_or(usize::MAX)
                })))
            }
            Err(e) => {
                let line = e
                    .position()
                    .map_or(1, |p| usize::try_from(p.line()).unwrap_or(usize::MAX));
                let kind = FileFaultKind::Csv {
                    message: e.to_string(),
                };
                Err(DatasetError::at(self.file, line, None, kind.into()))
            }
        }
    }

    /// Advances to the next data row and returns its line; `None` after the last row.
    pub fn next_row(&mut self) -> Result<Option<usize>, DatasetError> {
        let Some(line) = self.read_record()? else {
            return Ok(None);
        };
        if self.record.len() != self.header.len() {
            let kind = FileFaultKind::WrongCellCount {
                expected: self.header.len(),
                found: self.record.len(),
            };
            return Err(DatasetError::at(self.file, line, None, kind.into()));
        }
        Ok(Some(line))
    }

    /// An error about the cell in 0-based column `col` of the row at `line`.
    pub fn cell_error(&self, line: usize, col: usize, kind: ErrorKind) -> DatasetError {
        self.error(line, col, kind)
    }

    fn error(&self, line: usize, col: usize, kind: ErrorKind) -> DatasetError {
        let name = self.header.get(col).cloned().unwrap_or_default();
        DatasetError::at(self.file, line, Some(col + 1), kind).named(name)
    }

    /// The cell in 0-based column `col` of the current row: `None` when empty, else a finite
    /// number.
    pub fn opt(&self, line: usize, col: usize) -> Result<Option<f64>, DatasetError> {
        let text = self.record.get(col).unwrap_or("");
        if text.is_empty() {
            return Ok(None);
        }
        let value: f64 = text.parse().map_err(|_| {
            let kind = ErrorKind::NotANumber {
                value: text.to_owned(),
            };
            self.error(line, col, kind)
        })?;
        if !value.is_finite() {
            let kind = ErrorKind::NotFinite {
                value: text.to_owned(),
            };
            return Err(self.error(line, col, kind));
        }
        Ok(Some(value))
    }

    /// Like [`Self::opt`], but an empty cell is an error.
    pub fn req(&self, line: usize, col: usize) -> Result<f64, DatasetError> {
        self.opt(line, col)?
            .ok_or_else(|| self.error(line, col, ErrorKind::EmptyCell))
    }

    /// Three cells forming a vector: all empty gives `None`; partly empty is an error.
    pub fn vec3(
        &self,
        line: usize,
        cols: [usize; 3],
    ) -> Result<Option<Vector3<f64>>, DatasetError> {
        let values = [
            self.opt(line, cols[0])?,
            self.opt(line, cols[1])?,
            self.opt(line, cols[2])?,
        ];
        match values {
            [Some(x), Some(y), Some(z)] => Ok(Some(Vector3::new(x, y, z))),
            [None, None, None] => Ok(None),
            _ => {
                let present = values.iter().position(Option::is_some).unwrap_or(0);
                let empty = values.iter().position(Option::is_none).unwrap_or(0);
                let name = |i: usize| self.header.get(cols[i]).cloned().unwrap_or_default();
                let kind = ErrorKind::PartialVector {
                    present: name(present),
                    empty: name(empty),
                };
                Err(self.error(line, cols[empty], kind))
            }
        }
    }

    /// Three required cells.
    pub fn vec3_req(&self, line: usize, cols: [usize; 3]) -> Result<Vector3<f64>, DatasetError> {
        Ok(Vector3::new(
            self.req(line, cols[0])?,
            self.req(line, cols[1])?,
            self.req(line, cols[2])?,
        ))
    }

    /// Checks `t_s` in column `col` is above `previous`.
    pub fn increasing(
        &self,
        line: usize,
        col: usize,
        previous: Option<f64>,
        value: f64,
    ) -> Result<(), DatasetError> {
        match previous {
            Some(previous) if value <= previous => {
                Err(self.error(line, col, ErrorKind::TimeNotIncreasing { previous, value }))
            }
            _ => Ok(()),
        }
    }

    /// An error about header cell `col`.
    pub fn header_error(&self, col: usize, kind: ErrorKind) -> DatasetError {
        self.error(self.header_line, col, kind)
    }

    /// An error about the header row as a whole.
    pub fn header_row_error(&self, kind: ErrorKind) -> DatasetError {
        DatasetError::at(self.file, self.header_line, None, kind)
    }

    /// The no-data-rows error.
    pub fn no_rows(&self) -> DatasetError {
        DatasetError::at(self.file, self.header_line, None, ErrorKind::NoRows)
    }
}

/// Index of `name` in `header`; refuses a name that appears twice.
pub(crate) fn find<R: Read>(
    rows: &CsvRows<'_, R>,
    name: &str,
) -> Result<Option<usize>, DatasetError> {
    let mut hits = rows.header.iter().enumerate().filter(|(_, h)| *h == name);
    let first = hits.next().map(|(i, _)| i);
    match hits.next() {
        Some((second, _)) => Err(rows.header_error(
            second,
            ErrorKind::DuplicateColumn {
                name: name.to_owned(),
            },
        )),
        None => Ok(first),
    }
}

/// Index of a required column.
pub(crate) fn require<R: Read>(
    rows: &CsvRows<'_, R>,
    name: &str,
    hint: &str,
) -> Result<usize, DatasetError> {
    find(rows, name)?.ok_or_else(|| {
        rows.header_row_error(ErrorKind::MissingColumn {
            name: name.to_owned(),
            hint: hint.to_owned(),
        })
    })
}

/// Indices of three required columns.
pub(crate) fn require3<R: Read>(
    rows: &CsvRows<'_, R>,
    names: [&str; 3],
) -> Result<[usize; 3], DatasetError> {
    Ok([
        require(rows, names[0], "")?,
        require(rows, names[1], "")?,
        require(rows, names[2], "")?,
    ])
}

/// Writes `x` in the shortest text that parses back to the same bits (Rust's float `Debug`:
/// shortest round-trip digits, exponent form only below 1e-4 or from 1e16 on, so tiny values
/// do not become hundreds of zeros as with `Display`).
pub(crate) fn push_f64(out: &mut String, x: f64) {
    use std::fmt::Write;
    // Writing to a String cannot fail.
    let _ = write!(out, "{x:?}");
}

/// Appends one CSV row: `cells` joined by commas, then a newline.
pub(crate) fn push_row<I: IntoIterator<Item = Option<f64>>>(out: &mut String, cells: I) {
    for (i, cell) in cells.into_iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        if let Some(x) = cell {
            push_f64(out, x);
        }
    }
    out.push('\n');
}
