//! The run's index page.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::ReportError;
use crate::render::{check_stem, write_files_atomically};

/// A table of text cells in a section of an index page: a short heading, an optional one-line
/// lead under it (a verdict and its reason), the details as a list, then the table under its
/// caption.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Table {
    /// The section's heading: a few words.
    pub title: String,
    /// One short line under the heading, e.g. `inconsistent: photodiode residuals 32 times
    /// the noise`.
    pub lead: Option<String>,
    /// The details, one sentence each, shown as a list under the lead.
    pub notes: Vec<String>,
    /// The table's caption: what a row is, in a line.
    pub caption: String,
    /// Column names.
    pub header: Vec<String>,
    /// Rows of cells (a row shorter than the header leaves the rest empty).
    pub rows: Vec<Vec<String>>,
}

impl Table {
    /// A table titled `title` (also its caption) with columns `header`.
    pub fn new(title: &str, header: &[&str], rows: Vec<Vec<String>>) -> Self {
        Table {
            title: title.to_owned(),
            lead: None,
            notes: Vec::new(),
            caption: title.to_owned(),
            header: header.iter().map(|h| (*h).to_owned()).collect(),
            rows,
        }
    }

    /// The same with its caption.
    pub fn with_caption(mut self, caption: &str) -> Self {
        self.caption = caption.to_owned();
        self
    }

    /// The same with a lead line under the heading.
    pub fn with_lead(mut self, lead: &str) -> Self {
        self.lead = Some(lead.to_owned());
        self
    }

    /// The same with the details listed under the lead.
    pub fn with_notes(mut self, notes: Vec<String>) -> Self {
        self.notes = notes;
        self
    }
}

/// [`index_html`] with `tables` first, before the summary rows: the result a user reads
/// first (for a calibration, the photodiode table and the segments).
pub fn index_html_with_tables<K, V, C, S>(
    out_dir: &Path,
    title: &str,
    tables: &[Table],
    summary_rows: &[(K, V)],
    figures: &[(C, S)],
) -> Result<PathBuf, ReportError>
where
    K: AsRef<str>,
    V: AsRef<str>,
    C: AsRef<str>,
    S: AsRef<str>,
{
    for (_, stem) in figures {
        check_stem(stem.as_ref())?;
    }
    let html = index_page(title, tables, summary_rows, figures);
    let path = out_dir.join("index.html");
    write_files_atomically(&[(&path, html.as_bytes())])?;
    Ok(path)
}

/// Write `<out_dir>/index.html` (atomically): `title`, a two-column table of
/// `summary_rows` (name, value), then each figure as `<stem>.png` with its caption, the image
/// linking to `<stem>.svg`. Self-contained: inline CSS, no scripts, no external assets; the
/// images are referenced relative to `out_dir`. All text is HTML-escaped. Returns the path.
///
/// Errors: a figure stem that is not a valid stem (see [`crate::Figure::stem`]), or an I/O
/// failure. The figures themselves are not checked for existence (the page may be written
/// before or after them).
pub fn index_html<K, V, C, S>(
    out_dir: &Path,
    title: &str,
    summary_rows: &[(K, V)],
    figures: &[(C, S)],
) -> Result<PathBuf, ReportError>
where
    K: AsRef<str>,
    V: AsRef<str>,
    C: AsRef<str>,
    S: AsRef<str>,
{
    index_html_with_tables(out_dir, title, &[], summary_rows, figures)
}

fn index_page<K, V, C, S>(
    title: &str,
    tables: &[Table],
    rows: &[(K, V)],
    figures: &[(C, S)],
) -> String
where
    K: AsRef<str>,
    V: AsRef<str>,
    C: AsRef<str>,
    S: AsRef<str>,
{
    let title = escape(title);
    let mut h = String::new();
    // `write!` into a String cannot fail; the results are ignored on purpose.
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <title>{title}</title>\n<style>\n{CSS}</style>\n</head>\n<body>\n<h1>{title}</h1>\n"
    );
    for table in tables {
        push_table(&mut h, table);
    }
    if !rows.is_empty() {
        h.push_str(
            "<h2>Summary</h2>\n<table>\n<caption>The run in figures; a value that could not \
             be computed says why</caption>\n",
        );
        for (k, v) in rows {
            let _ = writeln!(
                h,
                "<tr><th>{}</th><td>{}</td></tr>",
                escape(k.as_ref()),
                escape(v.as_ref())
            );
        }
        h.push_str("</table>\n");
    }
    if !figures.is_empty() {
        h.push_str("<h2>Figures</h2>\n");
    }
    for (caption, stem) in figures {
        let (caption, stem) = (escape(caption.as_ref()), escape(stem.as_ref()));
        let _ = writeln!(
            h,
            "<figure><a href=\"{stem}.svg\"><img src=\"{stem}.png\" alt=\"{caption}\"></a>\
             <figcaption>{caption} (<a href=\"{stem}.svg\">SVG</a>)</figcaption></figure>"
        );
    }
    h.push_str("</body>\n</html>\n");
    h
}

fn push_table(h: &mut String, table: &Table) {
    let _ = writeln!(h, "<section>\n<h2>{}</h2>", escape(&table.title));
    if let Some(lead) = &table.lead {
        let _ = writeln!(h, "<p class=\"lead\">{}</p>", escape(lead));
    }
    if !table.notes.is_empty() {
        h.push_str("<ul class=\"notes\">\n");
        for note in &table.notes {
            let _ = writeln!(h, "<li>{}</li>", escape(note));
        }
        h.push_str("</ul>\n");
    }
    let _ = writeln!(h, "<table>\n<caption>{}</caption>", escape(&table.caption));
    let cells = |tag: &str, row: &[String]| -> String {
        row.iter()
            .map(|c| format!("<{tag}>{}</{tag}>", escape(c)))
            .collect()
    };
    let _ = writeln!(h, "<tr>{}</tr>", cells("th", &table.header));
    for row in &table.rows {
        let _ = writeln!(h, "<tr>{}</tr>", cells("td", row));
    }
    h.push_str("</table>\n</section>\n");
}

const CSS: &str =
    "body { font-family: sans-serif; margin: 2em auto; max-width: 1250px; color: #222; }
table { border-collapse: collapse; margin-bottom: 2em; }
th, td { border: 1px solid #ccc; padding: 0.3em 0.8em; text-align: left; }
th { background: #f3f3f3; font-weight: normal; }
td { font-family: monospace; }
figure { margin: 0 0 2.5em 0; }
img { max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { margin-top: 0.4em; }
caption { caption-side: top; text-align: left; padding-bottom: 0.4em; color: #555; }
p.lead { font-size: 1.15em; font-weight: bold; margin: 0.3em 0 0.6em 0; }
ul.notes { margin: 0 0 1em 0; padding-left: 1.4em; max-width: 60em; line-height: 1.4; }
ul.notes li { margin-bottom: 0.3em; }
";

/// Escape text for HTML element content and double-quoted attributes.
pub(crate) fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}
