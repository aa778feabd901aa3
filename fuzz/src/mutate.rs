//! Seeded mutations of valid files for the property tests: the kinds of damage the issue
//! lists (truncation, byte flips, huge numbers, NaN and infinities, missing and extra columns
//! or fields, non-UTF-8, huge cells, duplicate keys) plus grammar characters, so that a
//! few thousand cases reach the readers' error paths rather than only their tokenisers.
//!
//! The generator is a hand-written SplitMix64 so that a seed names the same cases on every
//! platform and every version of every dependency.

use crate::{Target, join_pair, split_pair};

/// SplitMix64 (Steele, Lea & Flood 2014): tiny, fast, and good enough to pick mutations.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator whose whole sequence `seed` fixes.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n`; 0 when `n` is 0.
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            return 0;
        }
        // The modulo bias is below 2^-40 for the lengths used here.
        (self.next_u64() % n as u64) as usize
    }

    /// One element of a non-empty slice.
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// Numbers that overflow, underflow or are out of every range a field allows.
const HUGE: &[&str] = &[
    "1e308",
    "1e309",
    "-1e400",
    "1e-400",
    "18446744073709551616",
    "4294967296",
    "-1",
    "-0",
    "0x7f",
    "179769313486231570814527423731704356798070567525844996598917476803157260780028538760589558632766878171540458953514382464234321326889464182768467546703537516986049910576551282076245490090389328944075868508455133942304583236903222948165808559332123348274797826204144723168738177180919299881250404026184124858368.0",
];

/// Spellings of NaN and the infinities, in RON, Rust and CSV habits.
const NON_FINITE: &[&str] = &[
    "NaN",
    "nan",
    "inf",
    "-inf",
    "+inf",
    "Infinity",
    "-Infinity",
    "NAN",
];

/// Bytes that are not UTF-8: a lone 0xFF, a truncated two-byte sequence, a surrogate, a code
/// point above U+10FFFF, an overlong slash, a lone continuation byte.
const NOT_UTF8: &[&[u8]] = &[
    b"\xff",
    b"\xc3",
    b"\xed\xa0\x80",
    b"\xf4\x90\x80\x80",
    b"\xc0\xaf",
    b"\x80",
];

/// Characters and words that matter to the CSV or RON grammar.
const GRAMMAR: &[&str] = &[
    ",",
    "\n",
    "\r\n",
    "\r",
    "\"",
    "(",
    ")",
    "[",
    "]",
    ":",
    "//",
    "/*",
    "#",
    " ",
    "\t",
    "\0",
    "Some(",
    "None",
    "é",
    "\u{feff}",
    "r#\"",
    "'",
    "\\",
    "Tle(",
    "PositionColumns",
];

/// Column or field names to add: existing ones (duplicates) and near misses.
const NAMES: &[&str] = &[
    "t_s",
    "gyro_x_rad_s",
    "mag_x_nT",
    "pd01_V",
    "pd0_V",
    "pd001_V",
    "pd99_V",
    "pd18446744073709551616_V",
    "r_x_km",
    "q_w",
    "eclipse",
    "extra",
    "",
    "format_version",
    "name",
    "noise",
    "smoother",
    "duration_s",
    "column",
    "unit",
    "counts",
    "sentinels",
    "form",
    "temperatures",
    "photodiode",
    "\"N/A\"",
];

/// One kind of damage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mutation {
    /// Cut the file at a random byte.
    Truncate,
    /// XOR one to four bytes with random bits.
    FlipBytes,
    /// Replace a number (or insert at random) with an overflowing or out-of-range one.
    HugeNumber,
    /// Replace a number with NaN or an infinity.
    NonFinite,
    /// CSV: drop a column from the header, one row, or every row. RON: drop a line.
    MissingColumn,
    /// CSV: add a column to the header, one row or every row. RON: add a field line.
    ExtraColumn,
    /// CSV: rename a header cell to another one's name. RON: repeat a `key: value` line.
    DuplicateKey,
    /// Insert bytes that are not UTF-8.
    NotUtf8,
    /// Replace a number or cell with a text of hundreds to thousands of characters.
    HugeCell,
    /// Insert or overwrite one grammar character or word.
    Grammar,
    /// Delete a byte range.
    Delete,
    /// Copy a byte range to another place.
    Repeat,
    /// Swap two lines (CSV: times out of order; RON: fields out of place).
    SwapLines,
}

impl Mutation {
    /// Every mutation.
    pub const ALL: [Mutation; 13] = [
        Mutation::Truncate,
        Mutation::FlipBytes,
        Mutation::HugeNumber,
        Mutation::NonFinite,
        Mutation::MissingColumn,
        Mutation::ExtraColumn,
        Mutation::DuplicateKey,
        Mutation::NotUtf8,
        Mutation::HugeCell,
        Mutation::Grammar,
        Mutation::Delete,
        Mutation::Repeat,
        Mutation::SwapLines,
    ];

    /// Applies this mutation to `bytes`.
    pub fn apply(self, bytes: &mut Vec<u8>, rng: &mut Rng) {
        let csv = looks_like_csv(bytes);
        match self {
            Mutation::Truncate => bytes.truncate(rng.below(bytes.len() + 1)),
            Mutation::FlipBytes => {
                for _ in 0..=rng.below(4) {
                    if bytes.is_empty() {
                        break;
                    }
                    let at = rng.below(bytes.len());
                    bytes[at] ^= (rng.next_u64() as u8).max(1);
                }
            }
            Mutation::HugeNumber => replace_number(bytes, rng.pick(HUGE).as_bytes(), rng),
            Mutation::NonFinite => replace_number(bytes, rng.pick(NON_FINITE).as_bytes(), rng),
            Mutation::MissingColumn if csv => edit_csv(bytes, rng, CsvEdit::Drop),
            Mutation::ExtraColumn if csv => edit_csv(bytes, rng, CsvEdit::Add),
            Mutation::DuplicateKey if csv => edit_csv(bytes, rng, CsvEdit::Rename),
            Mutation::MissingColumn => {
                let mut lines = split_lines(bytes);
                if !lines.is_empty() {
                    lines.remove(rng.below(lines.len()));
                }
                *bytes = lines.concat();
            }
            Mutation::ExtraColumn => {
                let mut lines = split_lines(bytes);
                let line = format!("    {}: {},\n", rng.pick(NAMES), rng.pick(HUGE));
                lines.insert(rng.below(lines.len() + 1), line.into_bytes());
                *bytes = lines.concat();
            }
            Mutation::DuplicateKey => {
                let mut lines = split_lines(bytes);
                let keyed: Vec<usize> = (0..lines.len())
                    .filter(|&i| lines[i].contains(&b':'))
                    .collect();
                if !keyed.is_empty() {
                    let line = lines[*rng.pick(&keyed)].clone();
                    lines.insert(rng.below(lines.len() + 1), line);
                }
                *bytes = lines.concat();
            }
            Mutation::NotUtf8 => {
                let at = rng.below(bytes.len() + 1);
                bytes.splice(at..at, rng.pick(NOT_UTF8).iter().copied());
            }
            Mutation::HugeCell => {
                let n = 100 + rng.below(5000);
                let filler = *rng.pick(b"x9\" (0");
                let mut cell = vec![filler; n];
                if filler == b'0' {
                    cell.insert(0, b'1');
                }
                replace_number(bytes, &cell, rng);
            }
            Mutation::Grammar => {
                let word = rng.pick(GRAMMAR).as_bytes();
                let at = rng.below(bytes.len() + 1);
                let end = if rng.below(2) == 0 {
                    at
                } else {
                    (at + 1).min(bytes.len())
                };
                bytes.splice(at..end, word.iter().copied());
            }
            Mutation::Delete => {
                let (a, b) = range(bytes.len(), rng);
                bytes.drain(a..b);
            }
            Mutation::Repeat => {
                let (a, b) = range(bytes.len(), rng);
                let piece = bytes[a..b].to_vec();
                let at = rng.below(bytes.len() + 1);
                bytes.splice(at..at, piece);
            }
            Mutation::SwapLines => {
                let mut lines = split_lines(bytes);
                if lines.len() >= 2 {
                    let i = rng.below(lines.len());
                    let j = rng.below(lines.len());
                    lines.swap(i, j);
                }
                *bytes = lines.concat();
            }
        }
    }
}

/// A mutated copy of `seed` for `target`, with the mutations applied (one to three). For
/// [`Target::DatasetPair`] each part is mutated on its own, one or both, so that the CSV
/// mutations see a CSV file.
pub fn mutate(target: Target, seed: &[u8], rng: &mut Rng) -> (Vec<u8>, Vec<Mutation>) {
    let mut applied = Vec::new();
    let mut damage = |bytes: &mut Vec<u8>, rng: &mut Rng| {
        for _ in 0..=rng.below(3) {
            let m = *rng.pick(&Mutation::ALL);
            m.apply(bytes, rng);
            applied.push(m);
        }
    };
    if target == Target::DatasetPair {
        let (ron, csv) = split_pair(seed);
        let (mut ron, mut csv) = (ron.to_vec(), csv.to_vec());
        match rng.below(3) {
            0 => damage(&mut ron, rng),
            1 => damage(&mut csv, rng),
            _ => {
                damage(&mut ron, rng);
                damage(&mut csv, rng);
            }
        }
        (join_pair(&ron, &csv), applied)
    } else {
        let mut bytes = seed.to_vec();
        damage(&mut bytes, rng);
        (bytes, applied)
    }
}

/// A CSV file's first line has commas and no RON brackets.
fn looks_like_csv(bytes: &[u8]) -> bool {
    let first = bytes.split(|&b| b == b'\n').next().unwrap_or_default();
    first.contains(&b',') && !first.contains(&b'(')
}

/// Lines with their line ends.
fn split_lines(bytes: &[u8]) -> Vec<Vec<u8>> {
    bytes
        .split_inclusive(|&b| b == b'\n')
        .map(<[u8]>::to_vec)
        .collect()
}

/// A random non-empty range of at most 64 bytes, or an empty one when `len` is 0.
fn range(len: usize, rng: &mut Rng) -> (usize, usize) {
    let a = rng.below(len);
    let b = (a + 1 + rng.below(64)).min(len);
    (a.min(b), b)
}

/// Replaces a random number token with `with`, or inserts `with` at a random place when
/// there is no number.
fn replace_number(bytes: &mut Vec<u8>, with: &[u8], rng: &mut Rng) {
    let numbers = number_tokens(bytes);
    let (a, b) = if numbers.is_empty() {
        let at = rng.below(bytes.len() + 1);
        (at, at)
    } else {
        *rng.pick(&numbers)
    };
    bytes.splice(a..b, with.iter().copied());
}

/// Byte ranges of the numbers in `bytes`: a digit run, with a sign, point and exponent,
/// that does not continue an identifier (so `pd01_V` is not a number).
fn number_tokens(bytes: &[u8]) -> Vec<(usize, usize)> {
    let is_ident = |b: u8| b.is_ascii_alphanumeric() || b == b'_';
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let starts = bytes[i].is_ascii_digit() && (i == 0 || !is_ident(bytes[i - 1]));
        if !starts {
            i += 1;
            continue;
        }
        let a = if i > 0 && bytes[i - 1] == b'-' {
            i - 1
        } else {
            i
        };
        let mut b = i;
        while b < bytes.len()
            && (bytes[b].is_ascii_digit()
                || bytes[b] == b'.'
                || bytes[b] == b'e'
                || bytes[b] == b'E'
                || ((bytes[b] == b'-' || bytes[b] == b'+') && matches!(bytes[b - 1], b'e' | b'E')))
        {
            b += 1;
        }
        out.push((a, b));
        i = b.max(i + 1);
    }
    out
}

#[derive(Clone, Copy)]
enum CsvEdit {
    Drop,
    Add,
    Rename,
}

/// Edits the cells of a CSV text: in the header only, in one data row, or in every row.
fn edit_csv(bytes: &mut Vec<u8>, rng: &mut Rng, edit: CsvEdit) {
    let mut rows: Vec<Vec<Vec<u8>>> = split_lines(bytes)
        .into_iter()
        .map(|line| {
            let body = line.strip_suffix(b"\n").unwrap_or(&line);
            body.split(|&b| b == b',').map(<[u8]>::to_vec).collect()
        })
        .collect();
    let Some(width) = rows.first().map(Vec::len) else {
        return;
    };
    let col = rng.below(width + 1);
    let chosen: Vec<usize> = match rng.below(3) {
        0 => vec![0],
        1 => vec![rng.below(rows.len())],
        _ => (0..rows.len()).collect(),
    };
    let name = rng.pick(NAMES).as_bytes().to_vec();
    let value = rng.pick(HUGE).as_bytes().to_vec();
    for r in chosen {
        let row = &mut rows[r];
        let at = col.min(row.len());
        match edit {
            CsvEdit::Drop if at < row.len() => {
                row.remove(at);
            }
            CsvEdit::Drop => {}
            CsvEdit::Add => {
                let cell = if r == 0 { name.clone() } else { value.clone() };
                row.insert(at, cell);
            }
            CsvEdit::Rename if r == 0 && at < row.len() => {
                let other = rng.below(row.len());
                row[at] = row[other].clone();
            }
            CsvEdit::Rename => {}
        }
    }
    let mut out = Vec::with_capacity(bytes.len() + 64);
    for row in rows {
        out.extend_from_slice(&row.join(&b','));
        out.push(b'\n');
    }
    *bytes = out;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn number_tokens_skip_identifiers_and_keep_exponents() {
        let text = b"pd01_V,t_s\n-1.5e-3,12\n";
        let found: Vec<&[u8]> = number_tokens(text)
            .into_iter()
            .map(|(a, b)| &text[a..b])
            .collect();
        assert_eq!(found, [&b"-1.5e-3"[..], b"12"]);
    }

    #[test]
    fn csv_edits_change_the_chosen_column() {
        let mut rng = Rng::new(3);
        let seed = b"a,b,c\n1,2,3\n4,5,6\n".to_vec();
        let mut changed = 0;
        for _ in 0..50 {
            let mut bytes = seed.clone();
            edit_csv(&mut bytes, &mut rng, CsvEdit::Drop);
            changed += usize::from(bytes != seed);
        }
        assert!(changed > 25, "{changed} of 50 drops changed the text");
    }

    #[test]
    fn the_same_seed_gives_the_same_cases() {
        let seed = Target::TelemetryCsv.seeds()[0];
        let run = |s| {
            let mut rng = Rng::new(s);
            (0..20)
                .map(|_| mutate(Target::TelemetryCsv, seed, &mut rng).0)
                .collect::<Vec<_>>()
        };
        assert_eq!(run(7), run(7));
        assert_ne!(run(7), run(8));
    }
}
