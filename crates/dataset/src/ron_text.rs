//! RON in and out: one options set for reading and writing, error positions, and locating a
//! key in the text for checks that run after deserialisation.

use std::path::Path;

use ron::extensions::Extensions;
use ron::ser::PrettyConfig;
use serde::{Serialize, de::DeserializeOwned};

use crate::error::{DatasetError, ErrorKind, line_col};

/// `implicit_some` lets optional fields be written bare (`noise: (...)`), as the contract's
/// example does, while `Some(...)` is still accepted.
fn options() -> ron::Options {
    ron::Options::default().with_default_extension(Extensions::IMPLICIT_SOME)
}

/// Why a user's RON text did not deserialise, and where: the one mapping of ron's errors
/// for every reader of a user's RON file (dataset.ron and truth.ron here, the import map in
/// `pdcal-import`), each of which carries the kind as its error kind's `Ron`.
#[derive(Clone, Debug, PartialEq)]
pub struct RonFault {
    /// 1-based line of the offending token.
    pub line: usize,
    /// 1-based character column of the offending token.
    pub column: usize,
    /// What is wrong.
    pub kind: RonFaultKind,
}

/// What is wrong with a RON text ([`RonFault`]): the one list of these kinds and their
/// messages, which the dataset's and the import's error kinds both carry.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RonFaultKind {
    /// A syntax or type error (wrong type, bad value, unclosed bracket, ...): ron's
    /// description, clipped.
    #[error("{message}")]
    Ron {
        /// ron's description.
        message: String,
    },
    /// A field that the format does not define.
    #[error("unknown field `{name}`, expected one of {expected}")]
    UnknownField {
        /// The field found (clipped).
        name: String,
        /// The fields allowed there.
        expected: String,
    },
    /// A required field is absent.
    #[error("missing field `{name}`")]
    MissingField {
        /// The field that is required.
        name: String,
    },
}

/// Deserialises a user's RON text with the readers' options, mapping ron's 1-based span
/// start to the line and column of the offending token.
pub fn parse_ron<T: DeserializeOwned>(text: &str) -> Result<T, RonFault> {
    options().from_str(text).map_err(|e| {
        let kind = match e.code {
            ron::Error::NoSuchStructField {
                expected, found, ..
            } => RonFaultKind::UnknownField {
                name: crate::error::clip(&found),
                expected: expected.join(", "),
            },
            ron::Error::MissingStructField { field, .. } => RonFaultKind::MissingField {
                name: field.to_owned(),
            },
            other => RonFaultKind::Ron {
                message: pdcal_text::parser_message(&other.to_string()),
            },
        };
        let (line, column) = pdcal_text::skip_blanks(text, e.span.start.line, e.span.start.col);
        RonFault { line, column, kind }
    })
}

/// Deserialises RON, mapping ron's 1-based span start to line:column.
pub(crate) fn from_ron<T: DeserializeOwned>(file: &Path, text: &str) -> Result<T, DatasetError> {
    parse_ron(text)
        .map_err(|f| DatasetError::at(file, f.line, Some(f.column), ErrorKind::Ron(f.kind)))
}

/// Pretty RON: four-space indent, one list entry per line with the entry itself on one line
/// (depth limit 2), no struct names, trailing newline. Floats use ron's shortest round-trip form.
pub(crate) fn to_ron<T: Serialize>(file: &Path, value: &T) -> Result<String, DatasetError> {
    let config = PrettyConfig::new()
        .depth_limit(2)
        .indentor("    ")
        .new_line("\n");
    let mut text = options().to_string_pretty(value, config).map_err(|e| {
        DatasetError::whole_file(
            file,
            ErrorKind::Ron(RonFaultKind::Ron {
                message: e.to_string(),
            }),
        )
    })?;
    text.push('\n');
    Ok(text)
}

/// Line and column of the first `key:` in `text` (key not part of a longer identifier).
pub(crate) fn locate_key(text: &str, key: &str) -> Option<(usize, usize)> {
    let is_ident = |c: char| c.is_alphanumeric() || c == '_';
    text.match_indices(key)
        .find(|&(i, _)| {
            let before_ok = !text[..i].chars().next_back().is_some_and(is_ident);
            let after = text[i + key.len()..].trim_start();
            before_ok && after.starts_with(':')
        })
        .map(|(i, _)| line_col(text, i))
}

/// Line and column of the `n`-th (zero-based) `key:` outside `//` comments: the key of the
/// `n`-th list entry that gives an optional field.
pub(crate) fn locate_nth_key(text: &str, key: &str, n: usize) -> Option<(usize, usize)> {
    let is_ident = |c: char| c.is_alphanumeric() || c == '_';
    text.match_indices(key)
        .filter(|&(i, _)| {
            let line_start = text[..i].rfind('\n').map_or(0, |j| j + 1);
            let before_ok = !text[..i].chars().next_back().is_some_and(is_ident);
            let after = text[i + key.len()..].trim_start();
            before_ok && after.starts_with(':') && !text[line_start..i].contains("//")
        })
        .nth(n)
        .map(|(i, _)| line_col(text, i))
}

/// Line and column of the opening quote of the string literal holding `needle`.
pub(crate) fn locate_str(text: &str, needle: &str) -> Option<(usize, usize)> {
    if needle.is_empty() {
        return None;
    }
    let i = text.find(needle)?;
    let (line, col) = line_col(text, i);
    Some((line, col.saturating_sub(1).max(1)))
}
