//! Every figure function writes a decodable PNG of the requested size and an SVG with its
//! title, atomically, and rejects structural errors with typed errors.

use std::path::Path;

use pdcal_report::{
    BinRange, BoundsPanel, DirectionSet, Figure, HistogramPanel, LineAxes, Mark, ReportError,
    Series, Written, YScale, bin_counts, histograms, index_html, lines, mean_std,
    series_with_bounds, sphere_directions,
};

const PNG_SIGNATURE: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0D, 0x0A, 0x1A, 0x0A];

fn check_png(path: &Path, width: u32, height: u32) -> image::RgbImage {
    let bytes = std::fs::read(path).expect("png written");
    assert_eq!(bytes[..8], PNG_SIGNATURE, "{} is not a PNG", path.display());
    let img = image::load_from_memory(&bytes)
        .expect("png decodes")
        .to_rgb8();
    assert_eq!(img.dimensions(), (width, height), "{}", path.display());
    img
}

fn check_svg(path: &Path, title: &str) -> String {
    let text = std::fs::read_to_string(path).expect("svg written");
    assert!(
        text.starts_with("<svg"),
        "{} does not start with <svg",
        path.display()
    );
    assert!(text.contains(title), "{} lacks its title", path.display());
    assert!(
        text.trim_end().ends_with("</svg>"),
        "{} is truncated",
        path.display()
    );
    text
}

/// The directory holds exactly `names` (no temporary or partial files).
fn assert_only(dir: &Path, names: &[&str]) {
    let mut found: Vec<String> = std::fs::read_dir(dir)
        .expect("dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    found.sort();
    let mut want: Vec<String> = names.iter().map(|s| s.to_string()).collect();
    want.sort();
    assert_eq!(found, want);
}

fn check_written(w: &Written, dir: &Path, stem: &str) {
    assert_eq!(w.png, dir.join(format!("{stem}.png")));
    assert_eq!(w.svg, dir.join(format!("{stem}.svg")));
}

fn count_colour(img: &image::RgbImage, rgb: [u8; 3]) -> usize {
    img.pixels().filter(|p| p.0 == rgb).count()
}

fn time(n: usize) -> Vec<f64> {
    (0..n).map(|i| i as f64 / 60.0).collect()
}

#[test]
fn series_with_bounds_writes_three_panels_with_gaps() {
    let dir = tempfile::tempdir().expect("tempdir");
    let t = time(600);
    let sigma: Vec<f64> = t.iter().map(|x| 0.05 + 0.5 * (-x).exp()).collect();
    let value: Vec<f64> = t
        .iter()
        .enumerate()
        .map(|(i, x)| {
            if (200..300).contains(&i) {
                f64::NAN
            } else {
                0.05 * (7.0 * x).sin()
            }
        })
        .collect();
    let centre: Vec<f64> = t.iter().map(|x| 3.5 + 0.1 * x).collect();
    let panels = [
        BoundsPanel::new("photodiode 1", "residual (V)", &t, &value, &sigma),
        BoundsPanel::new("photodiode 2", "residual (V)", &t, &value, &sigma)
            .with_y_range(-0.5, 0.5),
        BoundsPanel::new("photodiode 3", "C (V)", &t, &centre, &sigma).around(&centre),
    ];
    let fig = Figure::new("residuals", "Residuals and bounds").with_size(900, 1000);
    let w =
        series_with_bounds(dir.path(), &fig, "time (min)", "residual", &panels).expect("figure");
    check_written(&w, dir.path(), "residuals");
    let img = check_png(&w.png, 900, 1000);
    let svg = check_svg(&w.svg, "Residuals and bounds");
    assert!(svg.contains("photodiode 3") && svg.contains("time (min)"));
    // Dots (blue) and bound lines (red) are drawn in the PNG: hundreds of pixels each.
    assert!(count_colour(&img, [31, 119, 180]) > 500);
    assert!(count_colour(&img, [214, 39, 40]) > 500);
    assert_only(dir.path(), &["residuals.png", "residuals.svg"]);
}

#[test]
fn lines_draws_17_distinct_colours_and_a_legend() {
    let dir = tempfile::tempdir().expect("tempdir");
    let t = time(720);
    let ys: Vec<Vec<f64>> = (0..17)
        .map(|k| t.iter().map(|x| (x + k as f64).sin() + k as f64).collect())
        .collect();
    let names: Vec<String> = (1..=17).map(|k| format!("PD {k}")).collect();
    let series: Vec<Series<'_>> = ys
        .iter()
        .zip(&names)
        .map(|(y, n)| Series::new(n, y, Mark::Line))
        .collect();
    let fig = Figure::new("raw", "Raw outputs");
    let axes = LineAxes::new("time (min)", "output (V)");
    let w = lines(dir.path(), &fig, &axes, &t, &series).expect("figure");
    let img = check_png(&w.png, 1200, 800);
    let svg = check_svg(&w.svg, "Raw outputs");
    assert!(svg.contains("PD 17"), "legend lists the last series");
    // The first 17 palette colours, each visible (line plus legend sample).
    let palette: [[u8; 3]; 17] = [
        [31, 119, 180],
        [255, 127, 14],
        [44, 160, 44],
        [214, 39, 40],
        [148, 103, 189],
        [140, 86, 75],
        [227, 119, 194],
        [127, 127, 127],
        [188, 189, 34],
        [23, 190, 207],
        [0, 0, 128],
        [128, 0, 0],
        [0, 128, 128],
        [0, 0, 0],
        [230, 171, 2],
        [197, 27, 125],
        [27, 94, 32],
    ];
    for rgb in palette {
        assert!(count_colour(&img, rgb) > 50, "colour {rgb:?} missing");
    }
    assert_only(dir.path(), &["raw.png", "raw.svg"]);
}

#[test]
fn lines_log_scale_and_point_marks() {
    let dir = tempfile::tempdir().expect("tempdir");
    let t = time(300);
    let a: Vec<f64> = t.iter().map(|x| 10.0 * (-x).exp() + 0.2).collect();
    let b: Vec<f64> = t
        .iter()
        .map(|x| if *x > 2.0 { -1.0 } else { 0.5 + x })
        .collect();
    let fig = Figure::new("sigma", "Attitude sigma").with_size(640, 480);
    let axes = LineAxes::new("time (min)", "1σ (deg)").with_y_scale(YScale::Log10);
    let series = [
        Series::new("x", &a, Mark::Circle),
        Series::new("y", &b, Mark::Dot).with_colour([1, 2, 3]),
    ];
    let w = lines(dir.path(), &fig, &axes, &t, &series).expect("figure");
    let img = check_png(&w.png, 640, 480);
    check_svg(&w.svg, "Attitude sigma");
    assert!(count_colour(&img, [1, 2, 3]) > 50, "explicit colour used");
    // A log axis with a non-positive fixed range is rejected.
    let bad = axes.with_y_range(0.0, 1.0);
    let err = lines(dir.path(), &fig.with_size(640, 480), &bad, &t, &series).unwrap_err();
    assert!(matches!(err, ReportError::InvalidArgument { .. }), "{err}");
}

#[test]
fn histograms_print_mean_std_and_count() {
    let dir = tempfile::tempdir().expect("tempdir");
    let a = [1.0, 2.0, 3.0, 4.0, f64::NAN];
    let b = [0.9, 1.0, 1.1];
    let fig = Figure::new("hist", "Magnitude").with_size(1000, 500);
    let panels = [
        HistogramPanel {
            label: "initial",
            values: &a,
        },
        HistogramPanel {
            label: "calibrated",
            values: &b,
        },
    ];
    let w = histograms(
        dir.path(),
        &fig,
        "magnitude (-)",
        10,
        BinRange::Shared,
        &panels,
    )
    .expect("figure");
    check_png(&w.png, 1000, 500);
    let svg = check_svg(&w.svg, "Magnitude");
    // mean 2.5, sample std sqrt(5/3) = 1.291 (NaN ignored); second panel 1.000 / 0.100.
    for text in [
        "mean = 2.500",
        "std = 1.29",
        "n = 4",
        "mean = 1.000",
        "std = 0.100",
        "n = 3",
    ] {
        assert!(svg.contains(text), "svg lacks {text:?}");
    }
    for bins in [0, 1001] {
        let err = histograms(dir.path(), &fig, "x", bins, BinRange::Shared, &panels).unwrap_err();
        assert!(matches!(err, ReportError::InvalidArgument { .. }), "{err}");
    }
    let fixed = BinRange::Fixed { lo: 1.0, hi: 1.0 };
    assert!(histograms(dir.path(), &fig, "x", 5, fixed, &panels).is_err());
    assert_only(dir.path(), &["hist.png", "hist.svg"]);
}

#[test]
fn histogram_numbers() {
    // Population of known moments: mean 2.5, sample variance 5/3.
    let (m, s, n) = mean_std(&[1.0, 2.0, f64::INFINITY, 3.0, 4.0]).expect("finite values");
    assert_eq!((m, n), (2.5, 4));
    assert!((s - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
    assert_eq!(mean_std(&[f64::NAN]), None);
    assert_eq!(mean_std(&[7.0]), Some((7.0, 0.0, 1)));
    // Edges: lo is in the first bin, hi in the last, outside values are dropped.
    assert_eq!(
        bin_counts(&[0.0, 0.49, 0.5, 1.0, 1.5, -0.1, f64::NAN], 2, (0.0, 1.0)),
        vec![2, 2]
    );
}

#[test]
fn sphere_directions_scatter() {
    let dir = tempfile::tempdir().expect("tempdir");
    let a: Vec<[f64; 3]> = (0..500)
        .map(|i| {
            let x = i as f64 * 0.05;
            [x.cos(), x.sin(), 0.3 * (0.1 * x).sin()]
        })
        .collect();
    let b = [[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [f64::NAN, 1.0, 0.0]];
    let fig = Figure::new("sun_dirs", "Sun directions").with_size(1000, 560);
    let sets = [
        DirectionSet {
            name: "data set 1",
            dirs_body: &a,
        },
        DirectionSet {
            name: "data set 2",
            dirs_body: &b,
        },
    ];
    let w = sphere_directions(dir.path(), &fig, &sets).expect("figure");
    check_png(&w.png, 1000, 560);
    let svg = check_svg(&w.svg, "Sun directions");
    assert!(svg.contains("azimuth (deg)") && svg.contains("elevation (deg)"));
    // plotters writes text content on its own line.
    assert!(
        svg.contains("\n-180\n") && svg.contains("\n90\n"),
        "degree tick labels"
    );
    let err = sphere_directions(dir.path(), &fig, &[]).unwrap_err();
    assert!(matches!(err, ReportError::Count { found: 0, .. }), "{err}");
}

#[test]
fn nan_only_input_gives_an_empty_but_valid_figure() {
    let dir = tempfile::tempdir().expect("tempdir");
    let t = time(50);
    let nan = vec![f64::NAN; 50];
    let fig = Figure::new("never_lit", "Never lit").with_size(600, 400);
    let w = series_with_bounds(
        dir.path(),
        &fig,
        "time (min)",
        "residual",
        &[BoundsPanel::new("PD 17", "residual (V)", &t, &nan, &nan)],
    )
    .expect("empty figure");
    check_png(&w.png, 600, 400);
    assert!(check_svg(&w.svg, "Never lit").contains("no finite data"));

    let w = lines(
        dir.path(),
        &fig.with_size(600, 400),
        &LineAxes::new("t (min)", "y"),
        &[],
        &[Series::new("empty", &[], Mark::Line)],
    )
    .expect("empty figure");
    assert!(check_svg(&w.svg, "Never lit").contains("no finite data"));

    let panels = [HistogramPanel {
        label: "none",
        values: &nan,
    }];
    let w = histograms(dir.path(), &fig, "x", 10, BinRange::PerPanel, &panels).expect("empty");
    assert!(check_svg(&w.svg, "Never lit").contains("no finite data"));

    let nan3 = [[f64::NAN; 3]];
    let sets = [DirectionSet {
        name: "none",
        dirs_body: &nan3,
    }];
    let w = sphere_directions(dir.path(), &fig, &sets).expect("empty");
    assert!(check_svg(&w.svg, "Never lit").contains("no finite data"));
    assert_only(dir.path(), &["never_lit.png", "never_lit.svg"]);
}

#[test]
fn structural_errors_are_typed_and_write_nothing() {
    let dir = tempfile::tempdir().expect("tempdir");
    let t = time(10);
    let short = [0.0; 9];
    let ok = [0.0; 10];
    let fig = Figure::new("f", "F");
    let err = series_with_bounds(
        dir.path(),
        &fig,
        "t",
        "v",
        &[BoundsPanel::new("p", "y", &t, &short, &ok)],
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            ReportError::LengthMismatch {
                found: 9,
                expected: 10,
                ..
            }
        ),
        "{err}"
    );
    let err = series_with_bounds(dir.path(), &fig, "t", "v", &[]).unwrap_err();
    assert!(matches!(err, ReportError::Count { .. }), "{err}");
    let err = lines(
        dir.path(),
        &fig,
        &LineAxes::new("t", "y"),
        &t,
        &[Series::new("s", &short, Mark::Dot)],
    )
    .unwrap_err();
    assert!(matches!(err, ReportError::LengthMismatch { .. }), "{err}");
    for stem in ["", "../x", ".hidden", "a b", "a/b"] {
        let err = lines(
            dir.path(),
            &Figure::new(stem, "F"),
            &LineAxes::new("t", "y"),
            &t,
            &[Series::new("s", &ok, Mark::Dot)],
        )
        .unwrap_err();
        assert!(
            matches!(err, ReportError::InvalidStem { .. }),
            "{stem:?}: {err}"
        );
    }
    let err = lines(
        dir.path(),
        &fig.with_size(10, 800),
        &LineAxes::new("t", "y"),
        &t,
        &[Series::new("s", &ok, Mark::Dot)],
    )
    .unwrap_err();
    assert!(matches!(err, ReportError::InvalidSize { .. }), "{err}");
    assert_only(dir.path(), &[]);
}

#[test]
fn failed_writes_leave_no_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let t = time(10);
    let y = [1.0; 10];
    let series = [Series::new("s", &y, Mark::Line)];
    let axes = LineAxes::new("t", "y");
    // Missing output directory: an I/O error naming the file, nothing created.
    let missing = dir.path().join("missing");
    let err = lines(&missing, &Figure::new("f", "F"), &axes, &t, &series).unwrap_err();
    assert!(matches!(err, ReportError::Io { .. }), "{err}");
    assert!(!missing.exists());
    // The PNG's final name is taken by a directory: the rename fails, both temporaries are
    // removed, and the SVG is not written either.
    std::fs::create_dir(dir.path().join("f.png")).expect("mkdir");
    let err = lines(dir.path(), &Figure::new("f", "F"), &axes, &t, &series).unwrap_err();
    assert!(matches!(err, ReportError::Io { .. }), "{err}");
    assert_only(dir.path(), &["f.png"]);
    // Overwriting an existing figure works and leaves no temporary.
    std::fs::remove_dir(dir.path().join("f.png")).expect("rmdir");
    for _ in 0..2 {
        lines(dir.path(), &Figure::new("f", "F"), &axes, &t, &series).expect("figure");
    }
    assert_only(dir.path(), &["f.png", "f.svg"]);
}

#[test]
fn index_html_is_escaped_and_self_contained() {
    let dir = tempfile::tempdir().expect("tempdir");
    let rows = [
        ("scale error <max>", "0.4 % & \"ok\""),
        ("photodiodes", "17"),
    ];
    let figures = [
        ("Residuals <Fig. 4>", "residuals"),
        ("Attitude 1σ", "attitude_sigma"),
    ];
    let path = index_html(dir.path(), "Run <1> & 'co'", &rows, &figures).expect("index");
    assert_eq!(path, dir.path().join("index.html"));
    let html = std::fs::read_to_string(&path).expect("read");
    assert!(html.starts_with("<!DOCTYPE html>"));
    assert!(html.contains("<title>Run &lt;1&gt; &amp; &#39;co&#39;</title>"));
    assert!(html.contains("<th>scale error &lt;max&gt;</th><td>0.4 % &amp; &quot;ok&quot;</td>"));
    assert!(html.contains(
        "<a href=\"residuals.svg\"><img src=\"residuals.png\" alt=\"Residuals &lt;Fig. 4&gt;\">"
    ));
    assert!(html.contains("Attitude 1σ"));
    // No external assets and no scripts.
    for banned in ["http:", "https:", "<script", "<link", "@import"] {
        assert!(!html.contains(banned), "found {banned}");
    }
    // Owned Strings work too; a bad stem is rejected and nothing is written.
    let rows: Vec<(String, String)> = vec![];
    let bad = [("x".to_owned(), "../etc".to_owned())];
    let err = index_html(dir.path(), "t", &rows, &bad).unwrap_err();
    assert!(matches!(err, ReportError::InvalidStem { .. }), "{err}");
    assert_only(dir.path(), &["index.html"]);
}
