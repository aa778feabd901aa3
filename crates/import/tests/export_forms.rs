//! Exports in other shapes than comma-separated columns of one value each: the delimiter
//! (given or detected), linear combinations of columns, rows with one time tag, and names
//! from a hostile header in messages; each against hand values and exact messages.

use std::path::Path;

use pdcal_import::{
    Delimiter, DuplicateTimes, ErrorKind, FileFaultKind, ImportError, Imported, convert, parse_map,
};

const L1: &str = "1 37853U 11061D   11308.77065972  .00000000  00000-0  20000-4 0  9997";
const L2: &str = "2 37853 101.7000  50.0000 0300509 130.0000 230.0000 14.86144463  1000";

/// A photodiode-only map of a ground segment whose photodiodes are each the difference of
/// their channel and a common reference channel `VN`, in 12-bit counts of 5 V. `{extra}`
/// goes before the photodiodes (line 9 onwards); the photodiode entries are lines 10-11.
fn map_text(extra: &str) -> String {
    format!(
        r#"(
    format_version: 1,
    time: (column: "unix", form: Unix),
    gyro: (
        x: (column: "wx", unit: "deg/s"),
        y: (column: "wy", unit: "deg/s"),
        z: (column: "wz", unit: "deg/s"),
    ),
{extra}    photodiodes: [
        (columns: [("V5", 1.0), ("VN", -1.0)], counts: (gain: 0.001220703125, unit: "V"), sentinels: [4095], azimuth_deg: 0.0, elevation_deg: 0.0),
        (column: "V6", unit: "mV", azimuth_deg: 90.0, elevation_deg: 0.0),
    ],
    orbit: Tle(line1: "{L1}", line2: "{L2}"),
)
"#
    )
}

const CSV: &str = "\
unix,wx,wy,wz,V5,VN,V6
1320431385,1,2,3,2048,1024,1500
1320431386,1,2,3,2048,,1500
1320431387,1,2,3,4095,100,1500
1320431388,1,2,3,100,1100,1500
";

fn import(map: &str, csv: &str) -> Result<Imported, ImportError> {
    let map = parse_map(Path::new("map.ron"), map.as_bytes())?;
    convert(&map, Path::new("export.csv"), csv.as_bytes())
}

fn error(map: &str, csv: &str) -> String {
    match import(map, csv) {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_combination_is_converted_as_one_value_and_blank_when_a_term_is() {
    let imported = import(&map_text(""), CSV).unwrap();
    let pd = &imported.dataset.telemetry.pd_v;
    let volt = 5.0 / 4096.0;
    // (2048 - 1024) counts = 1.25 V.
    assert_eq!(pd[0].get(0), Some(1024.0 * volt));
    assert_eq!(pd[0].get(0), Some(1.25));
    // An empty reference cell blanks the combination; a sentinel in a term too (counted).
    assert_eq!(pd[0].get(1), None);
    assert_eq!(pd[0].get(2), None);
    // A negative difference is kept: the dataset's outputs are raw.
    assert_eq!(pd[0].get(3), Some(-1000.0 * volt));
    assert_eq!(pd[1].get(1), Some(1.5));
    let report = &imported.report;
    assert_eq!(
        report.sentinel_cells,
        [("photodiodes[0]".to_owned(), "V5 - VN".to_owned(), 1)]
    );
}

#[test]
fn any_numeric_column_may_be_a_combination() {
    // A gyro axis as the mean of two redundant axes.
    let map = map_text("").replace(
        r#"z: (column: "wz", unit: "deg/s"),"#,
        r#"z: (columns: [("wz", 0.5), ("wx", 0.5)], unit: "deg/s"),"#,
    );
    let imported = import(&map, CSV).unwrap();
    let g = imported.dataset.telemetry.gyro_rad_s.get(0).unwrap();
    assert!((g.z - 2.0_f64.to_radians()).abs() < 1e-15, "{g:?}");
}

#[test]
fn a_bad_combination_is_refused_in_the_map() {
    let cases = [
        (
            r#"columns: [("V5", 1.0), ("VN", -1.0)]"#,
            r#"columns: []"#,
            "map.ron:11: (photodiodes[0]): give exactly one of",
        ),
        (
            r#"("VN", -1.0)"#,
            r#"("VN", 0.0)"#,
            "map.ron:10:21 (photodiodes[0].columns): the combination is refused: the coefficient \
             of \"VN\" is 0: it must be finite and nonzero",
        ),
        (
            r#"("VN", -1.0)"#,
            r#"("V5", -1.0)"#,
            "map.ron:10:21 (photodiodes[0].columns): the combination is refused: column \"V5\" \
             appears twice: give it once with the sum of its coefficients",
        ),
        (
            r#"(columns: [("V5", 1.0), ("VN", -1.0)],"#,
            r#"(column: "V5", columns: [("V5", 1.0), ("VN", -1.0)],"#,
            "map.ron:10:18 (photodiodes[0]): give exactly one of `column: \"HEADER\"` or \
             `columns: [(\"HEADER\", 1.0), (\"OTHER\", -1.0)]`",
        ),
        (
            r#"("VN", -1.0)"#,
            r#"("Vref", -1.0)"#,
            "map.ron:10:34 (photodiodes[0].columns): column \"Vref\" is not in export.csv's header \
             (line 1), which has \"unix\", \"wx\", \"wy\", \"wz\", \"V5\", \"VN\", \"V6\"",
        ),
    ];
    for (from, to, expected) in cases {
        let e = error(&map_text("").replace(from, to), CSV);
        if expected.contains("map.ron:11: ") {
            // An empty list has no name to place it by: the photodiode's line.
            assert!(e.starts_with("map.ron:10:"), "{e}");
            assert!(
                e.contains(
                    "(photodiodes[0].columns): the combination is refused: the list is empty"
                ),
                "{e}"
            );
        } else {
            assert_eq!(e, expected);
        }
    }
    // A bad cell of a term names that cell, and the map's photodiode.
    let e = error(&map_text(""), &CSV.replace(",1024,", ",10x24,"));
    assert_eq!(
        e,
        "export.csv:2:6 (VN): \"10x24\" is not a number (photodiodes[0] of map.ron:10)"
    );
}

#[test]
fn the_delimiter_is_the_maps_or_the_headers() {
    // Whitespace-separated text has no empty cells: an export without them.
    let full = CSV.replace("2048,,1500", "2048,1000,1500");
    let comma = import(&map_text(""), &full).unwrap();
    assert_eq!(comma.report.delimiter, Some((Delimiter::Comma, true)));
    for (delimiter, separator) in [("Semicolon", ";"), ("Tab", "\t"), ("Whitespace", "   ")] {
        let csv = full.replace(',', separator);
        let given = map_text(&format!("    delimiter: {delimiter},\n"));
        let imported = import(&given, &csv).unwrap();
        assert_eq!(imported.dataset, comma.dataset, "{delimiter}");
        assert!(!imported.report.delimiter.unwrap().1);
        // The same export without the map's word: found from the header.
        let detected = import(&map_text(""), &csv).unwrap();
        assert_eq!(detected.dataset, comma.dataset, "{delimiter} detected");
        let (found, was_detected) = detected.report.delimiter.unwrap();
        assert!(was_detected);
        assert_eq!(format!("{found:?}"), delimiter);
    }
    // A `;` export with a comma in a quoted header name is still `;`.
    let csv = CSV.replace(',', ";").replacen("V6", "\"V6, mV\"", 1);
    let map = map_text("").replace("\"V6\"", "\"V6, mV\"");
    let imported = import(&map, &csv).unwrap();
    assert_eq!(
        imported.report.delimiter,
        Some((Delimiter::Semicolon, true))
    );
    // As many commas as semicolons: the map must say.
    let csv = "unix;wx,wy;wz,V5;VN,V6\n1,2,3,4,5,6,7\n";
    assert_eq!(
        error(&map_text(""), csv),
        "export.csv:1: cannot tell the delimiter from the header line (3 commas, 3 semicolons, \
         0 tabs): give `delimiter: Comma`, `Semicolon`, `Tab` or `Whitespace` in the map"
    );
    // The map's delimiter is used even when the header suggests another.
    let e = error(&map_text("    delimiter: Semicolon,\n"), CSV);
    assert!(
        e.starts_with(
            "map.ron:3:20 (time.column): column \"unix\" is not in export.csv's header (line 1), \
             which has \"unix,wx,wy,wz,V5,VN,V6\""
        ),
        "{e}"
    );
}

const DUPLICATES: &str = "\
unix,wx,wy,wz,V5,VN,V6
1320431385,1,2,3,2048,1024,1500
1320431386,1,2,3,2048,1024,1500
1320431386,3,4,,2048,1048,
1320431386,5,6,7,,1024,1000
1320431387,1,2,3,2048,1024,1500
";

#[test]
fn rows_of_one_time_are_refused_with_their_own_message() {
    assert_eq!(
        error(&map_text(""), DUPLICATES),
        "export.csv:4:1 (unix): time 2011-11-04T18:29:46.000000Z is the same as the previous \
         kept row's (line 3): the export has several rows with one time tag; say in the map \
         which to use, `duplicate_times: KeepFirst` or `duplicate_times: Average`"
    );
    // An earlier time is still out of order, with its own advice.
    let e = error(
        &map_text("    duplicate_times: KeepFirst,\n"),
        &DUPLICATES.replace("1320431387,", "1320431380,"),
    );
    assert!(
        e.ends_with("rows must be in time order: sort the export first"),
        "{e}"
    );
}

#[test]
fn keep_first_drops_the_later_rows_of_a_time() {
    let map = map_text("    duplicate_times: KeepFirst,\n");
    let imported = import(&map, DUPLICATES).unwrap();
    let tm = &imported.dataset.telemetry;
    assert_eq!(tm.t_s, [0.0, 1.0, 2.0]);
    assert_eq!(tm.pd_v[1].get(1), Some(1.5));
    assert_eq!(imported.report.duplicate_rows, 2);
    assert_eq!(imported.report.duplicate_times, DuplicateTimes::KeepFirst);
    // The dropped rows count for nothing else (their partial gyro is not counted as kept).
    assert_eq!(imported.report.rows_kept, 3);
}

#[test]
fn average_merges_the_rows_of_a_time_cell_by_cell() {
    let map = map_text("    duplicate_times: Average,\n");
    let imported = import(&map, DUPLICATES).unwrap();
    let tm = &imported.dataset.telemetry;
    assert_eq!(tm.t_s, [0.0, 1.0, 2.0]);
    let deg = 1.0_f64.to_radians();
    // Gyro: the rows where the vector is whole (1,2,3) and (5,6,7); the partial one is not.
    let g = tm.gyro_rad_s.get(1).unwrap();
    assert!(
        (g - nalgebra::Vector3::new(3.0, 4.0, 5.0) * deg).norm() < 1e-15,
        "{g:?}"
    );
    // pd01 = V5 - VN: 1024 and 1000 counts (the third row's V5 is empty).
    let volt = 5.0 / 4096.0;
    assert!((tm.pd_v[0].get(1).unwrap() - 1012.0 * volt).abs() < 1e-15);
    // pd02: 1.5 V and 1.0 V (the second row's is empty).
    assert_eq!(tm.pd_v[1].get(1), Some(1.25));
    // Rows of a time alone are unchanged, bit for bit.
    assert_eq!(tm.pd_v[0].get(0), Some(1.25));
    assert_eq!(imported.report.duplicate_rows, 2);
    assert_eq!(imported.report.partial_vectors, [("gyro".to_owned(), 1)]);
}

#[test]
fn a_hostile_header_name_is_escaped_and_cut_in_messages() {
    // An escape sequence in a header name reaches a message escaped.
    let csv = CSV.replace("VN", "V\u{1b}[2JN");
    let map = map_text("").replace("\"VN\"", "\"V\\u{1b}[2JN\"");
    let e = error(&map, &csv.replace(",1024,", ",x,"));
    assert_eq!(
        e,
        "export.csv:2:6 (\"V\\u{1b}[2JN\"): \"x\" is not a number (photodiodes[0] of map.ron:10)"
    );
    assert!(!e.contains('\u{1b}'));
    // A 1 MB header name is listed cut, with the number of columns.
    let long = "H".repeat(1 << 20);
    let csv = CSV.replacen("wy", &long, 1);
    let e = error(&map_text(""), &csv);
    assert!(e.len() < 400, "{} bytes", e.len());
    assert!(e.contains("\"unix\", \"wx\", \"HHHH"), "{e}");
    assert!(e.ends_with("... (7 columns)"), "{e}");
}

#[test]
fn a_repeated_header_the_map_uses_is_its_own_error() {
    let csv = CSV.replace("V6", "V5");
    assert_eq!(
        error(&map_text("").replace("\"V6\"", "\"V5x\""), &csv)
            .lines()
            .count(),
        1
    );
    let e = error(&map_text(""), &csv);
    assert_eq!(
        e,
        "export.csv:1:7 (V5): column \"V5\" appears twice in the header (cells 5 and 7), so the \
         map's reference to it is ambiguous"
    );
}

#[test]
fn streaming_and_in_memory_give_the_same_rows() {
    let map = parse_map(Path::new("map.ron"), map_text("").as_bytes()).unwrap();
    let mut rows = Vec::new();
    let converted =
        pdcal_import::convert_stream(&map, Path::new("export.csv"), CSV.as_bytes(), |row| {
            rows.push(row.clone());
            Ok(())
        })
        .unwrap();
    let whole = import(&map_text(""), CSV).unwrap();
    assert_eq!(converted.meta, whole.dataset.meta);
    assert_eq!(converted.report, whole.report);
    assert_eq!(rows.len(), whole.dataset.telemetry.len());
    for (k, row) in rows.iter().enumerate() {
        assert_eq!(row.t_s, whole.dataset.telemetry.t_s[k]);
        assert_eq!(row.pd_v[0], whole.dataset.telemetry.pd_v[0].get(k));
    }
    // A sink's error stops the conversion and is returned as is.
    let e = pdcal_import::convert_stream(&map, Path::new("export.csv"), CSV.as_bytes(), |_| {
        Err(parse_map(Path::new("other.ron"), b"").unwrap_err())
    })
    .unwrap_err();
    assert!(
        matches!(e.kind(), ErrorKind::File(FileFaultKind::Empty)),
        "{e}"
    );
}

#[test]
fn the_streamed_export_is_checked_as_text_like_the_map() {
    // A byte-order mark alone, or blanks, are an empty file.
    for text in ["\u{feff}", "\u{feff} \n\t\n", "\n\n"] {
        assert_eq!(
            error(&map_text(""), text),
            "export.csv: file is empty",
            "{text:?}"
        );
    }
    // A byte-order mark before the header is dropped.
    let with_bom = format!("\u{feff}{CSV}");
    let plain = import(&map_text(""), CSV).unwrap();
    assert_eq!(
        import(&map_text(""), &with_bom).unwrap().dataset,
        plain.dataset
    );
    // A byte that is not UTF-8 is placed by line and character column, also far into a
    // long export (beyond the first read buffer) and after a cut multi-byte character.
    let mut long = CSV.to_owned();
    for k in 0..5000 {
        long.push_str(&format!("{},1,2,3,2048,1024,1500\n", 1_320_431_389 + k));
    }
    let mut bytes = long.into_bytes();
    bytes.extend_from_slice("1320436389,1,2,3,\u{e9}\u{e9}".as_bytes());
    bytes.extend_from_slice(b"\xff,1024,1500\n");
    let map = parse_map(Path::new("map.ron"), map_text("").as_bytes()).unwrap();
    let e = convert(&map, Path::new("export.csv"), &bytes).unwrap_err();
    assert_eq!(e.to_string(), "export.csv:5006:20: not UTF-8 text");
}

#[test]
fn the_maps_inertia_reaches_dataset_ron_and_a_bad_one_is_the_readers_error() {
    let map = map_text("    inertia_kg_m2: (xx: 0.0314, yy: 0.0314, zz: 0.005, xy: 0.001),\n");
    let imported = import(&map, CSV).unwrap();
    let j = imported.dataset.meta.inertia_kg_m2.unwrap().matrix();
    assert_eq!((j[(0, 0)], j[(2, 2)], j[(1, 0)]), (0.0314, 0.005, 0.001));
    assert_eq!(
        import(&map_text(""), CSV)
            .unwrap()
            .dataset
            .meta
            .inertia_kg_m2,
        None
    );
    let bad = map_text("    inertia_kg_m2: (xx: 1.0, yy: 1.0, zz: 3.0),\n");
    let e = error(&bad, CSV);
    assert!(e.contains("not a rigid body's inertia"), "{e}");
}

#[test]
fn a_map_without_gyro_columns_imports_rows_without_a_gyro() {
    let gyro = "    gyro: (\n        x: (column: \"wx\", unit: \"deg/s\"),\n        y: (column: \"wy\", unit: \"deg/s\"),\n        z: (column: \"wz\", unit: \"deg/s\"),\n    ),\n";
    let map =
        map_text("    inertia_kg_m2: (xx: 0.0314, yy: 0.0314, zz: 0.005),\n").replace(gyro, "");
    assert!(!map.contains("gyro"), "{map}");
    let csv = "unix,V5,VN,V6\n1320431385,2048,1024,1500\n1320431386,2048,1000,1500\n";
    let imported = import(&map, csv).unwrap();
    let tm = &imported.dataset.telemetry;
    assert_eq!(tm.gyro_rad_s, vec![None, None]);
    // The photodiodes keep their columns: (2048 - 1000) counts of 5/4096 V.
    assert!((tm.pd_v[0].get(1).unwrap() - 1048.0 * 0.001220703125).abs() < 1e-12);
    assert!((tm.pd_v[1].get(0).unwrap() - 1.5).abs() < 1e-12);
    assert!(imported.dataset.meta.inertia_kg_m2.is_some());
}

/// A Windows export (`\r\n` line ends) is placed line for line as the same export with `\n`:
/// the duplicate-time message and a bad cell name the lines an editor shows.
#[test]
fn line_ends_of_a_windows_export_do_not_move_the_lines_named() {
    let crlf = DUPLICATES.replace('\n', "\r\n");
    assert_eq!(
        error(&map_text(""), &crlf),
        error(&map_text(""), DUPLICATES)
    );
    let bad = CSV.replace("1320431387,1,2,3,4095", "1320431387,1,2x,3,4095");
    let lf = error(&map_text(""), &bad);
    assert!(lf.starts_with("export.csv:4:3 (wy)"), "{lf}");
    assert_eq!(error(&map_text(""), &bad.replace('\n', "\r\n")), lf);
    // A lone `\r` inside a line is not a line end the reader drops.
    let imported = import(&map_text(""), &CSV.replace('\n', "\r\n")).unwrap();
    assert_eq!(imported.dataset.telemetry.t_s, [0.0, 1.0, 2.0, 3.0]);
}

/// A quote opened and not closed takes every later line into one cell: refused at the
/// line and cell it opens, never read as a shorter export.
#[test]
fn a_quote_left_open_is_refused_where_it_opens() {
    let csv = CSV.replace(
        "1320431386,1,2,3,2048,,1500",
        "1320431386,1,2,3,2048,\"oops,1500",
    );
    let e = error(&map_text(""), &csv);
    assert!(
        e.starts_with("export.csv:3:6:") && e.contains("a quote opened and not closed"),
        "{e}"
    );
    // Quotes closed on their line are cells like any other.
    let quoted = CSV.replace(
        "1320431386,1,2,3,2048,,1500",
        "1320431386,1,2,3,\"2048\",,1500",
    );
    assert_eq!(rows_read(&quoted), 4);
}

/// A line of blanks is a blank line.
#[test]
fn a_line_of_blanks_is_skipped() {
    let csv = CSV.replace(
        "1320431386,1,2,3,2048,,1500\n",
        "1320431386,1,2,3,2048,,1500\n   \n",
    );
    assert_eq!(rows_read(&csv), 4);
}

/// Two photodiodes, or two currents, that read the same export data (an entry copied from
/// the one above and its column not renamed) are refused at the later entry's line, as two
/// axes of one sensor are: the second would be "calibrated" as a copy of the first.
#[test]
fn two_photodiodes_or_two_currents_never_share_a_column() {
    let shared = |map: &str| match parse_map(Path::new("map.ron"), map.as_bytes()) {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    };
    let pds = map_text("").replace(
        "(column: \"V6\", unit: \"mV\"",
        "(column: \"V5\", unit: \"mV\"",
    );
    // The same data scaled (counts and mV) is the same data.
    let pds = pds.replace(
        "(columns: [(\"V5\", 1.0), (\"VN\", -1.0)], counts: (gain: 0.001220703125, unit: \"V\"), \
         sentinels: [4095],",
        "(column: \"V5\", unit: \"V\",",
    );
    assert_eq!(
        shared(&pds),
        "map.ron:11:36 (photodiodes[1]): reads the same export data as photodiodes[0]: two \
         photodiodes never share a column (each is a sensor of its own)"
    );
    // A combination is the same data whatever the order of its terms.
    let pds = map_text("").replace(
        "(column: \"V6\", unit: \"mV\"",
        "(columns: [(\"VN\", -1.0), (\"V5\", 1.0)], unit: \"mV\"",
    );
    assert!(
        shared(&pds).starts_with("map.ron:11:")
            && shared(&pds).contains("(photodiodes[1]): reads the same export data as"),
        "{}",
        shared(&pds)
    );
    let currents = map_text(
        "    currents: [\n        (name: \"px\", column: \"V6\", unit: \"A\"),\n        \
         (name: \"py\", column: \"wx\", unit: \"A\"),\n        (name: \"pz\", column: \
         \"V6\", unit: \"mA\"),\n    ],\n",
    );
    assert_eq!(
        shared(&currents),
        "map.ron:12:10 (currents[2]): reads the same export data as currents[0]: two currents \
         never share a column"
    );
}

/// The rows `csv` imports to with the base map.
fn rows_read(csv: &str) -> usize {
    import(&map_text(""), csv)
        .unwrap()
        .dataset
        .telemetry
        .t_s
        .len()
}

/// A gyro axis whose column was copied from the axis above and not renamed is refused.
#[test]
fn two_axes_of_one_sensor_never_share_a_column() {
    let map = map_text("").replace("y: (column: \"wy\"", "y: (column: \"wx\"");
    let e = match parse_map(Path::new("map.ron"), map.as_bytes()) {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    };
    assert!(
        e.starts_with("map.ron:6:9 ")
            && e.contains("(gyro.y): reads the same export data as gyro.x"),
        "{e}"
    );
}

/// A current's name longer than a file name allows is refused in the map, before any row
/// is read (it becomes `cur_<name>_A` and `magcal`'s figure of it).
#[test]
fn a_current_name_too_long_for_a_file_is_refused_in_the_map() {
    let named = |name: &str| {
        map_text(&format!(
            "    currents: [(name: \"{name}\", column: \"V6\", unit: \"A\")],\n"
        ))
    };
    let longest = "a".repeat(pdcal_dataset::MAX_CURRENT_NAME_CHARS);
    parse_map(Path::new("map.ron"), named(&longest).as_bytes()).expect("the longest is valid");
    let e = match parse_map(Path::new("map.ron"), named(&"a".repeat(65)).as_bytes()) {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    };
    assert!(
        e.starts_with("map.ron:9:")
            && e.contains("(currents[0].name): ")
            && e.contains("is not a channel name (1 to 64 of a-z, 0-9, _)"),
        "{e}"
    );
}
