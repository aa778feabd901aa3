//! The export as records: UTF-8 checked as it is read (the first bad byte placed by line and
//! column), a leading byte-order mark dropped, the delimiter given by the map or detected
//! from the header line, and cells trimmed of the blanks around them. Nothing is held but the
//! current record, so an export of any length is read in constant memory.

use std::cell::Cell;
use std::io::{self, BufRead, BufReader, Cursor, Read};
use std::path::Path;
use std::rc::Rc;

use csv::StringRecord;

use pdcal_dataset::FileFaultKind;

use crate::error::{ErrorKind, ImportError, clip};
use crate::map::Delimiter;

const BOM: &[u8] = b"\xef\xbb\xbf";

/// What the checking reader learned, shared with the code that reads records from it.
#[derive(Default)]
struct Seen {
    /// Line and character column of the first byte that is not UTF-8.
    bad: Cell<Option<(usize, usize)>>,
    /// Whether any character other than whitespace was read.
    text: Cell<bool>,
}

/// A reader that passes on bytes only once they are known to be UTF-8 (a character cut by
/// the end of a read is held back until its end arrives).
struct Utf8Check<R> {
    inner: R,
    seen: Rc<Seen>,
    /// Bytes of a character cut by the end of the previous read.
    carry: Vec<u8>,
    line: usize,
    column: usize,
}

impl<R: Read> Utf8Check<R> {
    fn count(&mut self, text: &str) {
        // A byte-order mark is no content (a file of nothing else is empty).
        let content = |c: char| !c.is_whitespace() && c != '\u{feff}';
        if !self.seen.text.get() && text.chars().any(content) {
            self.seen.text.set(true);
        }
        match text.rfind('\n') {
            Some(at) => {
                self.line += text.matches('\n').count();
                self.column = 1 + text[at + 1..].chars().count();
            }
            None => self.column += text.chars().count(),
        }
    }

    fn fault(&self) -> io::Error {
        self.seen.bad.set(Some((self.line, self.column)));
        io::Error::new(io::ErrorKind::InvalidData, "not UTF-8")
    }
}

impl<R: Read> Read for Utf8Check<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        // The buffered readers above ask for 64 KiB at a time; a buffer too small for a
        // held-back character is refused rather than handled byte by byte.
        if out.len() <= self.carry.len() {
            return Err(io::Error::other("read buffer too small"));
        }
        loop {
            let held = self.carry.len();
            out[..held].copy_from_slice(&self.carry);
            let n = match self.inner.read(&mut out[held..]) {
                Ok(n) => n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            if n == 0 {
                if held > 0 {
                    return Err(self.fault());
                }
                return Ok(0);
            }
            let total = held + n;
            let valid = match std::str::from_utf8(&out[..total]) {
                Ok(_) => total,
                Err(e) if e.error_len().is_none() => e.valid_up_to(),
                Err(e) => {
                    let text = std::str::from_utf8(&out[..e.valid_up_to()]).unwrap_or_default();
                    self.count(text);
                    return Err(self.fault());
                }
            };
            self.count(std::str::from_utf8(&out[..valid]).unwrap_or_default());
            self.carry = out[valid..total].to_vec();
            if valid > 0 {
                return Ok(valid);
            }
        }
    }
}

/// The export's records, one at a time.
pub(crate) struct Records<R: Read> {
    file: std::path::PathBuf,
    seen: Rc<Seen>,
    kind: Kind<R>,
    /// The delimiter in use, and whether it was detected rather than given.
    pub(crate) delimiter: Delimiter,
    pub(crate) detected: bool,
}

type Source<R> = pdcal_dataset::CrlfToLf<io::Chain<Cursor<Vec<u8>>, BufReader<Utf8Check<R>>>>;

enum Kind<R: Read> {
    Csv(csv::Reader<Source<R>>),
    Words {
        reader: BufReader<Source<R>>,
        line: usize,
        text: String,
    },
}

impl<R: Read> Records<R> {
    /// Opens `source` (named `file` in errors) with the map's delimiter, or the one the
    /// header line shows.
    pub(crate) fn open(
        file: &Path,
        source: R,
        delimiter: Option<Delimiter>,
    ) -> Result<Self, ImportError> {
        let seen = Rc::new(Seen::default());
        let mut reader = BufReader::with_capacity(
            1 << 16,
            Utf8Check {
                inner: source,
                seen: Rc::clone(&seen),
                carry: Vec::new(),
                line: 1,
                column: 1,
            },
        );
        let io_error = |e: io::Error| match seen.bad.get() {
            Some((line, column)) => {
                ImportError::at(file, line, Some(column), FileFaultKind::NotUtf8.into())
            }
            None => ImportError::whole_file(
                file,
                FileFaultKind::Csv {
                    message: clip(&e.to_string()),
                }
                .into(),
            ),
        };
        if reader.fill_buf().map_err(io_error)?.starts_with(BOM) {
            reader.consume(BOM.len());
        }
        // The lines up to the header (blank ones skipped), read again by the record reader.
        let mut head = Vec::new();
        let header = loop {
            let start = head.len();
            let n = reader.read_until(b'\n', &mut head).map_err(io_error)?;
            let line = String::from_utf8_lossy(&head[start..]);
            if n == 0 || !line.trim().is_empty() {
                break line.into_owned();
            }
        };
        let (delimiter, detected) = match delimiter {
            Some(d) => (d, false),
            None => (
                detect(&header).map_err(|kind| {
                    ImportError::at(
                        file,
                        1 + count_lines(&head[..head.len() - header.len()]),
                        None,
                        kind,
                    )
                })?,
                true,
            ),
        };
        let source = pdcal_dataset::CrlfToLf::new(Cursor::new(head).chain(reader));
        let kind = match delimiter.byte() {
            Some(byte) => Kind::Csv(
                csv::ReaderBuilder::new()
                    .has_headers(false)
                    .flexible(true)
                    .trim(csv::Trim::All)
                    .delimiter(byte)
                    .buffer_capacity(1 << 16)
                    .from_reader(source),
            ),
            None => Kind::Words {
                reader: BufReader::new(source),
                line: 0,
                text: String::new(),
            },
        };
        Ok(Records {
            file: file.to_path_buf(),
            seen,
            kind,
            delimiter,
            detected,
        })
    }

    /// Reads the next record into `record`; its line, or `None` at the end. Blank lines are
    /// skipped.
    pub(crate) fn next(&mut self, record: &mut StringRecord) -> Result<Option<usize>, ImportError> {
        let result = match &mut self.kind {
            Kind::Csv(reader) => loop {
                match reader.read_record(record) {
                    Ok(false) => break Ok(None),
                    // A line of blanks only: a blank line.
                    Ok(true) if record.len() == 1 && record[0].is_empty() => continue,
                    Ok(true) => {
                        let line = record.position().map_or(1, |p| line_of(p.line()));
                        // One scan of the record's text; the cell only when there is one.
                        let spans = |c: &str| c.contains(['\n', '\r']);
                        if spans(record.as_slice())
                            && let Some(column) = record.iter().position(spans)
                        {
                            return Err(open_quote(&self.file, line, column + 1, &record[column]));
                        }
                        break Ok(Some(line));
                    }
                    Err(e) => break Err((e.position().map(|p| line_of(p.line())), e.to_string())),
                }
            },
            Kind::Words { reader, line, text } => loop {
                text.clear();
                match reader.read_line(text) {
                    Ok(0) => break Ok(None),
                    Ok(_) => {
                        *line += 1;
                        if text.trim().is_empty() {
                            continue;
                        }
                        record.clear();
                        for word in text.split_whitespace() {
                            record.push_field(word);
                        }
                        break Ok(Some(*line));
                    }
                    Err(e) => break Err((None, e.to_string())),
                }
            },
        };
        result.map_err(|(line, message)| match self.seen.bad.get() {
            Some((line, column)) => ImportError::at(
                &self.file,
                line,
                Some(column),
                FileFaultKind::NotUtf8.into(),
            ),
            None => {
                let kind = ErrorKind::from(FileFaultKind::Csv {
                    message: clip(&message),
                });
                match line {
                    Some(line) => ImportError::at(&self.file, line, None, kind),
                    None => ImportError::whole_file(&self.file, kind),
                }
            }
        })
    }

    /// Whether everything read so far was whitespace (with the end reached, the file is
    /// blank).
    pub(crate) fn blank_so_far(&self) -> bool {
        !self.seen.text.get()
    }
}

/// A cell that holds a line break: a quote opened and not closed on its line takes every
/// line after it into the cell, up to the next quote (a cell of an export never spans
/// lines).
fn open_quote(file: &Path, line: usize, column: usize, cell: &str) -> ImportError {
    let breaks = cell.matches('\n').count().max(1);
    ImportError::at(
        file,
        line,
        Some(column),
        FileFaultKind::Csv {
            message: format!(
                "a quoted cell runs over {breaks} line break(s) from here: a quote opened \
                 and not closed on its line takes the lines after it into one cell (close \
                 the quote or remove it)"
            ),
        }
        .into(),
    )
}

fn line_of(line: u64) -> usize {
    usize::try_from(line).unwrap_or(usize::MAX)
}

fn count_lines(bytes: &[u8]) -> usize {
    bytes.iter().filter(|&&b| b == b'\n').count()
}

/// The delimiter of a header line: the most frequent of `,` `;` tab outside double quotes;
/// whitespace when there is none of them and blanks separate several names; a comma (one
/// column) when there is nothing to separate. Two candidates equally frequent are refused.
pub(crate) fn detect(header: &str) -> Result<Delimiter, ErrorKind> {
    let mut counts = [0usize; 3];
    let mut quoted = false;
    for c in header.chars() {
        match c {
            '"' => quoted = !quoted,
            ',' if !quoted => counts[0] += 1,
            ';' if !quoted => counts[1] += 1,
            '\t' if !quoted => counts[2] += 1,
            _ => {}
        }
    }
    let candidates = [Delimiter::Comma, Delimiter::Semicolon, Delimiter::Tab];
    let most = counts.iter().copied().max().unwrap_or(0);
    if most == 0 {
        return Ok(if header.split_whitespace().nth(1).is_some() {
            Delimiter::Whitespace
        } else {
            Delimiter::Comma
        });
    }
    let tied: Vec<usize> = (0..3).filter(|&i| counts[i] == most).collect();
    match tied.as_slice() {
        [only] => Ok(candidates[*only]),
        _ => Err(ErrorKind::AmbiguousDelimiter {
            counts: format!(
                "{} commas, {} semicolons, {} tabs",
                counts[0], counts[1], counts[2]
            ),
        }),
    }
}
