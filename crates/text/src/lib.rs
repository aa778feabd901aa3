//! Input text quoted in error messages, cut to a bounded length: the one implementation
//! every reader and catalogue uses (the effect catalogue's names, the UTC parser of
//! `pdcal-ephem`, the dataset, scenario, configuration and import readers and the driver,
//! each depending on this crate directly), so that all of them cut the same way.

/// Characters of an offending value quoted in a message; longer values are cut, so that a
/// 50 MB cell does not become a 50 MB error message.
pub const QUOTE_MAX_CHARS: usize = 80;

/// `text` for a message, unquoted (a library's own message quoting the input): at most
/// [`QUOTE_MAX_CHARS`] characters of it, and the full length when cut; control characters
/// escaped ([`escape_controls`]).
pub fn clip(text: &str) -> String {
    match text.char_indices().nth(QUOTE_MAX_CHARS) {
        None => escape_controls(text),
        Some((cut, _)) => format!(
            "{}... ({} bytes)",
            escape_controls(&text[..cut]),
            text.len()
        ),
    }
}

/// `text` with its control characters (ESC, NUL, a carriage return...) escaped as Rust
/// writes them (`\u{1b}`, `\0`, `\r`), so that echoed input cannot drive the terminal or
/// split a one-line message.
pub fn escape_controls(text: &str) -> String {
    if !text.chars().any(char::is_control) {
        return text.to_owned();
    }
    text.chars()
        .map(|c| {
            if c.is_control() {
                c.escape_debug().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

/// A path for a message (an input, an output directory, the `-> OUT` line): control
/// characters escaped as [`clip`] escapes them, not cut (a path names the file to fix, and
/// the system bounds its length); bytes that are not UTF-8 shown as U+FFFD.
pub fn path(path: impl AsRef<std::path::Path>) -> String {
    escape_controls(&path.as_ref().to_string_lossy())
}

/// `text` quoted for a message: Rust string syntax, at most [`QUOTE_MAX_CHARS`] characters
/// of it, and the full length when cut (`"aaaa..."... (52428800 bytes)`).
pub fn quote(text: &str) -> String {
    match text.char_indices().nth(QUOTE_MAX_CHARS) {
        None => format!("{text:?}"),
        Some((cut, _)) => format!("{:?}... ({} bytes)", &text[..cut], text.len()),
    }
}

/// A parser's message for a user, in our words where the parser speaks of its own
/// internals (ron's "Exceeded recursion limit, try increasing `ron::Options::recursion_limit`
/// ...", which the user cannot do), then [`clip`]ped. The valid names a parser lists after
/// "expected one of" are the program's own, and what the user needs to fix a typo: only the
/// part before them, which quotes the input, is cut.
pub fn parser_message(message: &str) -> String {
    if message.contains("recursion limit") {
        return "nested too deeply: more brackets inside brackets than any pdcal file has"
            .to_owned();
    }
    match message.find(EXPECTED_ONE_OF) {
        Some(at) => format!(
            "{}{}",
            clip(&message[..at]),
            escape_controls(&message[at..])
        ),
        None => clip(message),
    }
}

/// Where a parser's message starts listing the valid names.
const EXPECTED_ONE_OF: &str = ", expected one of ";

/// A number for a message: `Display` writes every digit (`1e300` is 301 characters), so it
/// is cut like any quoted value.
pub fn number(value: f64) -> String {
    clip(&value.to_string())
}

/// 1-based line and character column of byte offset `offset` in `text`.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = text.get(..offset).unwrap_or(text);
    let line = 1 + before.matches('\n').count();
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = 1 + before[line_start..].chars().count();
    (line, column)
}

/// ron's span for a wrong value can start at the blank before it; the 1-based `line` and
/// `col` moved to the token itself, as an editor user expects. Positions outside the text
/// are returned unchanged.
pub fn skip_blanks(text: &str, line: usize, col: usize) -> (usize, usize) {
    let line_start = if line <= 1 {
        Some(0)
    } else {
        text.match_indices('\n').nth(line - 2).map(|(i, _)| i + 1)
    };
    let offset = line_start.and_then(|start| {
        let rest = text.get(start..)?;
        let within = rest.char_indices().nth(col.checked_sub(1)?)?.0;
        Some(start + within)
    });
    let Some(offset) = offset else {
        return (line, col);
    };
    let blanks = text[offset..].len() - text[offset..].trim_start().len();
    if offset + blanks >= text.len() {
        return (line, col);
    }
    line_col(text, offset + blanks)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_valid_names_a_parser_lists_are_never_cut() {
        let message = "Unexpected variant named `Median` in enum `DuplicateTimes`, expected one \
                       of `Refuse`, `KeepFirst`, `Average`";
        assert!(message.len() > QUOTE_MAX_CHARS);
        assert_eq!(parser_message(message), message);
        // The input quoted before the list is cut as any quoted value.
        let long = format!(
            "Unexpected variant named `{}`, expected one of `A`",
            "x".repeat(500)
        );
        let shown = parser_message(&long);
        assert!(
            shown.ends_with("... (527 bytes), expected one of `A`"),
            "{shown}"
        );
    }

    #[test]
    fn short_text_is_kept_and_long_text_cut_with_its_length() {
        assert_eq!(clip("abc"), "abc");
        assert_eq!(quote("abc"), "\"abc\"");
        let long = "x".repeat(200);
        assert_eq!(
            clip(&long),
            format!("{}... (200 bytes)", "x".repeat(QUOTE_MAX_CHARS))
        );
        assert_eq!(
            quote(&long),
            format!("\"{}\"... (200 bytes)", "x".repeat(QUOTE_MAX_CHARS))
        );
    }

    #[test]
    fn paths_are_escaped_not_cut() {
        let long = format!("/tmp/{}/out\u{1b}[31mRED\u{7}", "d".repeat(200));
        let shown = path(std::path::Path::new(&long));
        assert_eq!(
            shown,
            format!("/tmp/{}/out\\u{{1b}}[31mRED\\u{{7}}", "d".repeat(200))
        );
    }

    #[test]
    fn huge_numbers_are_cut() {
        assert_eq!(number(1.5), "1.5");
        assert!(number(1e300).chars().count() < QUOTE_MAX_CHARS + 20);
        assert!(number(-1e-300).chars().count() < QUOTE_MAX_CHARS + 20);
    }
}
