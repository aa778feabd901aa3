//! Hostile inputs of issue 47 on the newer surfaces: every count and size of a `--config`
//! bounded and named, a FIFO as import source refused before `--out` is locked, import maps
//! that read one export column twice, names too long for a file, values and paths echoed
//! escaped and cut, and diagnoses outside an effect's physical range.

use std::fs;

/// `load_config`'s message for a `--config` of `text`, its path written `CONFIG`.
fn config_error(text: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("config.ron");
    fs::write(&path, text).unwrap();
    let err = pdcal::calibrate::load_config(&path)
        .map(|_| ())
        .unwrap_err();
    pdcal::cli::error_text(&err).replace(&path.display().to_string(), "CONFIG")
}

#[test]
fn every_count_and_size_of_a_config_is_bounded_and_named() {
    let day = "must be at most 86400 s (one day)";
    let cases = [
        (
            "(segments: (lost_window_updates: 18446744073709551615))".to_owned(),
            "segments.lost_window_updates = 18446744073709551615: must be at least 1 and at \
             most 10000"
                .to_owned(),
        ),
        (
            "(segments: (lost_window_updates: 1000000000000))".to_owned(),
            "segments.lost_window_updates = 1000000000000: must be at least 1 and at most 10000"
                .to_owned(),
        ),
        (
            "(segments: (gap_threshold_s: Some(1e12)))".to_owned(),
            format!("segments.gap_threshold_s = 1000000000000: {day}"),
        ),
        (
            "(segments: (gyro_hold_s: Some(1e12)))".to_owned(),
            format!("segments.gyro_hold_s = 1000000000000: {day}"),
        ),
        (
            "(segments: (pairing_tolerance_s: 1e12))".to_owned(),
            format!("segments.pairing_tolerance_s = 1000000000000: {day}"),
        ),
        (
            "(bias_fit_window_s: 1e12)".to_owned(),
            format!("bias_fit_window_s = 1000000000000: {day}"),
        ),
        (
            "(about_sun_probe_s: 1e12)".to_owned(),
            format!("about_sun_probe_s = 1000000000000: {day}"),
        ),
        (
            "(relinearise_window_s: 1e12)".to_owned(),
            format!("relinearise_window_s = 1000000000000: {day}"),
        ),
        (
            "(ensemble: Runs(18446744073709551615))".to_owned(),
            "ensemble = Runs(18446744073709551615): Runs(n) must be at most 64 (each run is one \
             more forward pass)"
                .to_owned(),
        ),
        (
            format!(
                "(parameter_sigmas: [(name_or_unit: \"{}\", sigma: 1.0)])",
                "x".repeat(81)
            ),
            format!(
                "parameter_sigmas[0].name_or_unit = \"{}\"... (81 bytes): a parameter's name or \
                 unit is at most 80 characters",
                "x".repeat(80)
            ),
        ),
        (
            format!(
                "(parameter_sigmas: [{}])",
                "(name_or_unit: \"V\", sigma: 1.0),".repeat(10_001)
            ),
            "parameter_sigmas = 10001 entries: at most 10000 entries".to_owned(),
        ),
        (
            "(parameter_sigmas: [(name_or_unit: \"V\", sigma: 1.0), (name_or_unit: \"s\", \
             sigma: 1.0, walk_per_sqrt_h: -1.0)])"
                .to_owned(),
            "parameter_sigmas[1].walk_per_sqrt_h = -1: must be non-negative and finite".to_owned(),
        ),
        // The sensor sigmas obey dataset.ron's noise rule, the value cut to 80 characters.
        (
            "(photodiode_sigma_v: Some(1e300))".to_owned(),
            format!(
                "photodiode_sigma_v = {}... (301 bytes): a 1-sigma noise must be positive and \
                 at most 1e2 V",
                &1e300.to_string()[..80]
            ),
        ),
        (
            "(mag_sigma_nt: Some(1e6))".to_owned(),
            "mag_sigma_nt = 1000000: a 1-sigma noise must be positive and at most 1e5 nT"
                .to_owned(),
        ),
        (
            "(gyro_sigma_rad_s: Some(-1.0))".to_owned(),
            "gyro_sigma_rad_s = -1: a 1-sigma noise must be positive".to_owned(),
        ),
        // Extreme values that ran into the arithmetic ("q-method failed: pair 1: non-finite
        // weight", "filter state not finite after row 1439") are refused naming the field.
        (
            "(mag_sigma_nt: Some(1e-300))".to_owned(),
            format!(
                "mag_sigma_nt = {}... (302 bytes): must be at least 1e-6 nT",
                &1e-300.to_string()[..80]
            ),
        ),
        (
            "(initial_bias_sigma_deg_s: 1e300)".to_owned(),
            format!(
                "initial_bias_sigma_deg_s = {}... (301 bytes): must be at most 1e3 deg/s",
                &1e300.to_string()[..80]
            ),
        ),
        (
            "(gyro_bias_walk_rad_s_sqrt_s: 1e300)".to_owned(),
            format!(
                "gyro_bias_walk_rad_s_sqrt_s = {}... (301 bytes): must be at most 1e-1 rad/s \
                 per sqrt(s)",
                &1e300.to_string()[..80]
            ),
        ),
    ];
    for (text, shown) in cases {
        assert_eq!(
            config_error(&text),
            format!("CONFIG: filter config: {shown}"),
            "{}",
            pdcal_text::clip(&text)
        );
    }
    // The bounds themselves are accepted.
    let at_bounds = "(segments: (lost_window_updates: 10000, gap_threshold_s: Some(86400.0)), \
                     relinearise_window_s: 86400.0, ensemble: Runs(64))";
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("config.ron");
    fs::write(&path, at_bounds).unwrap();
    pdcal::calibrate::load_config(&path).unwrap();
}

const PDCAL: &str = env!("CARGO_BIN_EXE_pdcal");

fn import_fixture(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fixtures/import")
        .join(name)
}

/// `pdcal ARGS`, killed and reported as hung when it has not ended within a minute.
fn run_bounded(args: &[&std::ffi::OsStr]) -> std::process::Output {
    use std::process::{Command, Stdio};
    let mut child = Command::new(PDCAL)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > std::time::Duration::from_secs(60) {
            child.kill().unwrap();
            child.wait().unwrap();
            panic!("pdcal {args:?} still running after 60 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child.wait_with_output().unwrap()
}

#[cfg(unix)]
#[test]
fn a_fifo_as_import_source_is_refused_and_out_left_unlocked() {
    let tmp = tempfile::tempdir().unwrap();
    let fifo = tmp.path().join("export.csv");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        return;
    }
    let out = tmp.path().join("ds");
    let map = import_fixture("map.ron");
    let o = run_bounded(&[
        "import".as_ref(),
        fifo.as_os_str(),
        "--map".as_ref(),
        map.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(!o.status.success());
    assert_eq!(
        String::from_utf8_lossy(&o.stderr),
        format!(
            "pdcal: error: cannot read {}: it is a FIFO (named pipe), not a regular file; pdcal \
             reads only regular files\n",
            fifo.display()
        )
    );
    // Nothing was published and `out` is not left locked: the next import writes it.
    assert!(!out.join("telemetry.csv").exists());
    let export = import_fixture("export.csv");
    let o = run_bounded(&[
        "import".as_ref(),
        export.as_os_str(),
        "--map".as_ref(),
        map.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// Control characters in a path or a header never reach the terminal raw: the `-> OUT`
/// line, an error naming a path, and a location's parentheses escape them.
#[cfg(unix)]
#[test]
fn control_characters_in_paths_and_headers_are_escaped_everywhere() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("ds\u{1b}[31mRED\u{7}");
    let map = import_fixture("map.ron");
    let export = import_fixture("export.csv");
    let o = run_bounded(&[
        "import".as_ref(),
        export.as_os_str(),
        "--map".as_ref(),
        map.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    let shown = format!("{}/ds\\u{{1b}}[31mRED\\u{{7}}", tmp.path().display());
    assert!(stdout.contains(&format!("-> {shown}\n")), "{stdout}");
    // A header with an escape sequence and a bell, in a directory whose name has them.
    let telemetry = out.join("telemetry.csv");
    let text = fs::read_to_string(&telemetry).unwrap();
    fs::write(
        &telemetry,
        text.replacen("mag_x_nT", "mag_\u{1b}[31mRED\u{7}", 1),
    )
    .unwrap();
    let o = run_bounded(&[
        "calibrate".as_ref(),
        out.as_os_str(),
        "--out".as_ref(),
        tmp.path().join("cal").as_os_str(),
    ]);
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !stderr.contains('\u{1b}') && !stderr.contains('\u{7}'),
        "{stderr:?}"
    );
    assert!(
        stderr.starts_with(&format!("pdcal: error: {shown}/telemetry.csv:1:"))
            && stderr.contains("(mag_\\u{1b}[31mRED\\u{7}): "),
        "{stderr}"
    );
}
