//! `read_telemetry` streams telemetry.csv instead of holding it as text: the same telemetry
//! and the same errors as the text reader, also where a character or a fault lies across
//! the reader's 64 KiB buffers.

use crate::common;

use std::fs;
use std::path::Path;

use common::{TLE1, TLE2};
use pdcal_dataset::{
    DatasetError, DatasetMeta, ErrorKind, FileFaultKind, meta_from_str, read_telemetry,
    telemetry_from_str,
};

fn meta() -> DatasetMeta {
    let text = format!(
        r#"(
    format_version: 1,
    name: "streamed",
    epoch_utc: "2011-11-04T18:29:45Z",
    orbit: Tle(line1: "{TLE1}", line2: "{TLE2}"),
    photodiodes: [(azimuth_deg: 17.0, elevation_deg: -10.0)],
)
"#
    );
    meta_from_str(&text).unwrap()
}

const HEADER: &str = "t_s,gyro_x_rad_s,gyro_y_rad_s,gyro_z_rad_s,pd01_V\n";

/// A header and `rows` rows, about 40 bytes each (several buffers from 2000 rows on).
fn text(rows: usize) -> String {
    let mut out = HEADER.to_owned();
    for k in 0..rows {
        out.push_str(&format!(
            "{k},0.0125,-0.0250,0.0375,{}\n",
            1.0 + k as f64 * 1e-3
        ));
    }
    out
}

fn read(bytes: &[u8]) -> Result<pdcal_dataset::Telemetry, DatasetError> {
    let dir = tempfile::tempdir().unwrap();
    fs::write(dir.path().join("telemetry.csv"), bytes).unwrap();
    read_telemetry(dir.path(), &meta())
}

fn place(e: &DatasetError) -> (Option<usize>, Option<usize>, String) {
    (e.line(), e.column(), e.kind().to_string())
}

#[test]
fn a_streamed_file_reads_like_its_text() {
    let text = text(8000);
    assert!(text.len() > 3 * (1 << 16));
    let from_text = telemetry_from_str(&text, &meta()).unwrap();
    assert_eq!(read(text.as_bytes()).unwrap(), from_text);
    // A byte-order mark is dropped.
    let with_bom = format!("\u{feff}{text}");
    assert_eq!(read(with_bom.as_bytes()).unwrap(), from_text);
}

#[test]
fn a_bad_cell_past_the_first_buffer_is_placed_as_in_the_text() {
    // A multi-byte character across the first buffer boundary, inside a cell.
    // Whatever the byte there, the character lands in some cell.
    let mut text = text(8000);
    text.insert((1 << 16) - 1, 'é');
    let from_text = telemetry_from_str(&text, &meta()).unwrap_err();
    let streamed = read(text.as_bytes()).unwrap_err();
    assert_eq!(place(&streamed), place(&from_text));
    assert!(matches!(streamed.kind(), ErrorKind::NotANumber { .. }));
}

/// 1-based line and character column of byte `offset` of `text`, as the text reader gives.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset];
    let line = 1 + before.matches('\n').count();
    let start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, 1 + before[start..].chars().count())
}

#[test]
fn bytes_that_are_not_utf8_are_placed_in_any_buffer() {
    let text = format!("\u{feff}{}", text(8000));
    for offset in [10, (1 << 16) - 1, 1 << 16, (1 << 17) + 7] {
        let at = offset.min(text.len());
        let at = (0..=at).rev().find(|&i| text.is_char_boundary(i)).unwrap();
        let mut bytes = text.as_bytes().to_vec();
        bytes.insert(at, 0xff);
        let e = read(&bytes).unwrap_err();
        let (line, column) = line_col(&text, at);
        assert_eq!(
            (e.line(), e.column()),
            (Some(line), Some(column)),
            "byte {at}"
        );
        assert!(matches!(e.kind(), ErrorKind::File(FileFaultKind::NotUtf8)));
    }
    // A character cut off by the end of the file.
    let mut bytes = text.as_bytes().to_vec();
    bytes.extend_from_slice(&"é".as_bytes()[..1]);
    let e = read(&bytes).unwrap_err();
    let (line, column) = line_col(&text, text.len());
    assert_eq!((e.line(), e.column()), (Some(line), Some(column)));
    assert!(matches!(e.kind(), ErrorKind::File(FileFaultKind::NotUtf8)));
}

#[test]
fn a_blank_file_is_empty() {
    for bytes in ["", " \n\t\n", "\u{feff}", "\u{feff}  \n"] {
        let e = read(bytes.as_bytes()).unwrap_err();
        assert!(
            matches!(e.kind(), ErrorKind::File(FileFaultKind::Empty)),
            "{bytes:?}: {e}"
        );
        assert_eq!(e.line(), None);
    }
    let missing = read_telemetry(Path::new("/nonexistent-pdcal-dir"), &meta()).unwrap_err();
    assert!(matches!(missing.kind(), ErrorKind::Io { .. }));
}
