//! The page a user opens first (index.html): the verdict as one short line with its reason,
//! the details under it as a list, captions as captions, and every value that could not be
//! computed said to be not available, with why, never `NaN`.

use pdcal::calibrate::RunConfig;
use pdcal_sim::Scenario;

/// The text of every `<tag ...>...</tag>` in `html`.
fn elements<'a>(html: &'a str, open: &str, close: &str) -> Vec<&'a str> {
    html.split(open)
        .skip(1)
        .map(|rest| {
            let rest = &rest[rest.find('>').map_or(0, |i| i + 1)..];
            &rest[..rest.find(close).unwrap_or(rest.len())]
        })
        .collect()
}

/// Calibrates `dataset` and checks the structure every index.html must have; returns the
/// page and its verdict line.
fn page(dataset: &std::path::Path, out: &std::path::Path) -> (String, String) {
    pdcal::calibrate::run_dirs(
        std::slice::from_ref(&dataset.to_path_buf()),
        out,
        &RunConfig::default(),
    )
    .unwrap();
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    for bad in ["NaN", "inf<", ">inf", "-inf"] {
        assert!(!html.contains(bad), "{bad} in index.html:\n{html}");
    }
    for heading in elements(&html, "<h2", "</h2>") {
        assert!(
            heading.len() <= 40,
            "a heading holding a paragraph: {heading}"
        );
    }
    // Every table has its caption first, every figure its figcaption.
    assert_eq!(
        html.matches("<table>").count(),
        html.matches("<table>\n<caption>").count()
    );
    assert_eq!(
        html.matches("<figure>").count(),
        html.matches("<figcaption>").count()
    );
    let leads = elements(&html, "<p class=\"lead\"", "</p>");
    assert_eq!(leads.len(), 1, "one verdict line: {leads:?}");
    let lead = leads[0].to_owned();
    assert!(
        lead.len() <= 110,
        "verdict line of {} bytes: {lead}",
        lead.len()
    );
    (html, lead)
}

#[test]
fn the_verdict_is_one_short_line_and_nothing_uncomputed_shows_as_nan() {
    let tmp = tempfile::tempdir().unwrap();
    let mut scenario = Scenario::rax2_like().unwrap();
    scenario.duration_s = 2400.0;
    let clean = tmp.path().join("clean");
    pdcal::simulate::run_to_dir(&scenario, 3, &clean).unwrap();
    let (_, lead) = page(&clean, &tmp.path().join("cal-clean"));
    assert!(
        lead.starts_with("consistent: photodiode residuals "),
        "{lead}"
    );

    // The photodiode noise declared ten times too small: inconsistent, and the line says
    // by how much, the reasons listed under it.
    let mut ds = pdcal_dataset::read_dataset(&clean).unwrap();
    let noise = ds.meta.noise.as_mut().unwrap();
    noise.photodiode_v = noise.photodiode_v.map(|v| v / 10.0);
    let wrong = tmp.path().join("wrong");
    pdcal_dataset::write_dataset(&wrong, &ds).unwrap();
    let (html, lead) = page(&wrong, &tmp.path().join("cal-wrong"));
    assert!(
        lead.starts_with("inconsistent: photodiode residuals "),
        "{lead}"
    );
    assert!(lead.contains(" times the noise"), "{lead}");
    let details = elements(&html, "<ul class=\"notes\"", "</ul>").join("");
    assert!(details.contains("<li>photodiode: residuals "), "{details}");

    // A four-photodiode pyramid without a magnetometer: no Sun vector is observable, and
    // the page says so instead of `NaN / NaN`.
    let pyramid = Scenario::from_ron_str(include_str!(
        "../../../../fixtures/scenarios/weak/pyramid-head.ron"
    ))
    .unwrap();
    let with_mag = tmp.path().join("pyramid");
    pdcal::simulate::run_to_dir(&pyramid, 1, &with_mag).unwrap();
    let no_mag = tmp.path().join("pyramid-no-mag");
    std::fs::create_dir(&no_mag).unwrap();
    std::fs::copy(with_mag.join("dataset.ron"), no_mag.join("dataset.ron")).unwrap();
    let csv = std::fs::read_to_string(with_mag.join("telemetry.csv")).unwrap();
    let keep: Vec<bool> = csv
        .lines()
        .next()
        .unwrap()
        .split(',')
        .map(|h| !h.starts_with("mag_"))
        .collect();
    let stripped: String = csv
        .lines()
        .map(|line| {
            let cells: Vec<&str> = line
                .split(',')
                .zip(&keep)
                .filter(|(_, k)| **k)
                .map(|(c, _)| c)
                .collect();
            cells.join(",") + "\n"
        })
        .collect();
    std::fs::write(no_mag.join("telemetry.csv"), stripped).unwrap();
    let (html, _) = page(&no_mag, &tmp.path().join("cal-pyramid"));
    assert!(html.contains("<th>mode</th><td>photodiode-only</td>"));
    assert!(
        html.contains(
            "<th>Sun-vector magnitude, initial (mean / std)</th><td>not available: no row"
        ),
        "{html}"
    );
}
