//! Hostile inputs of issue 22 (items 3-6), each with its exact message: a `--config` prior
//! checked by the dataset's own rules, positions that are no orbit, a jittering stuck
//! magnetometer, too little data to diagnose, non-regular and endless input files, control
//! characters and parser internals in messages, a mount-point `--out`, and the largest
//! photodiode count.

use std::fs;
use std::path::Path;
use std::sync::OnceLock;

use nalgebra::Vector3;
use pdcal_filter::{Calibration, PdCalibration};
use pdcal_sim::SimOutput;

/// The RAX-2-like scenario cut to 27 minutes.
fn sim() -> &'static SimOutput {
    static SIM: OnceLock<SimOutput> = OnceLock::new();
    SIM.get_or_init(|| {
        let mut scenario = pdcal_sim::Scenario::rax2_like().unwrap();
        scenario.duration_s = 27.0 * 60.0;
        pdcal::simulate::run(&scenario, 21).unwrap()
    })
}

fn prior(edit: impl FnOnce(&mut PdCalibration)) -> String {
    let mut pd = PdCalibration {
        scale_v: 3.7,
        scale_sigma_v: 0.01,
        azimuth_deg: 17.0,
        azimuth_sigma_deg: Some(0.2),
        elevation_deg: -10.0,
        elevation_sigma_deg: 0.2,
    };
    edit(&mut pd);
    let cal = Calibration {
        format_version: 1,
        photodiodes: vec![pd],
        gyro_bias_rad_s: [0.0; 3],
        gyro_bias_sigma_rad_s: [1e-4; 3],
        parameters: Vec::new(),
        status: Vec::new(),
    };
    cal.to_ron_string().unwrap()
}

fn load_config_error(text: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("prior.ron");
    fs::write(&path, text).unwrap();
    let err = pdcal::calibrate::load_config(&path)
        .map(|_| ())
        .unwrap_err();
    pdcal::cli::error_text(&err).replace(&path.display().to_string(), "PRIOR")
}

#[test]
fn a_config_prior_obeys_the_dataset_rules() {
    assert_eq!(
        load_config_error(&prior(|p| p.elevation_deg = 1000.0)),
        "PRIOR: calibration: photodiodes[0].elevation_deg = 1000: elevation must be in [-90, 90] deg"
    );
    assert_eq!(
        load_config_error(&prior(|p| p.azimuth_deg = 1e9)),
        "PRIOR: calibration: photodiodes[0].azimuth_deg = 1000000000: azimuth must be in \
         [-360, 360] deg"
    );
    for (value, shown) in [
        (-1.0, "-1"),
        (0.0, "0"),
        (f64::NAN, "NaN"),
        (
            1e300,
            "1000000000000000052504760255204420248704468581108159154915854115111802457988908195786371375080447864043704443832883878176942523235360430575644792184786706982848387200926575803737830233794788090059368953234970799945081119038967640880074652742780142494579258788820056842838115467196834763571392.0",
        ),
    ] {
        assert_eq!(
            load_config_error(&prior(|p| p.scale_v = value)),
            format!(
                "PRIOR: calibration: photodiodes[0].scale_V = {}: a scale factor must be positive \
                 and at most 100 V",
                pdcal_text::number(value)
            ),
            "{shown}"
        );
    }
    // The same rule as dataset.ron's.
    assert_eq!(
        pdcal_dataset::rules::mounting(0.0, 1000.0),
        Err(("elevation_deg", "elevation must be in [-90, 90] deg"))
    );
}

/// A circular orbit of `radius_km` in the rows of the short set.
fn circular(radius_km: f64) -> pdcal_dataset::Telemetry {
    let mut telemetry = sim().telemetry.clone();
    let rate = (pdcal_dataset::rules::MU_EARTH_KM3_S2 / radius_km.powi(3)).sqrt();
    telemetry.r_gcrf_km = Some(
        telemetry
            .t_s
            .iter()
            .map(|t| {
                let a = rate * t;
                Some(Vector3::new(radius_km * a.cos(), radius_km * a.sin(), 0.0))
            })
            .collect(),
    );
    telemetry
}

fn check_error(telemetry: &pdcal_dataset::Telemetry) -> String {
    let err = pdcal::checks::check_telemetry(telemetry).unwrap_err();
    format!("{err:#}")
}

#[test]
fn positions_must_be_an_orbit() {
    assert_eq!(
        pdcal::checks::check_telemetry(&circular(6800.0)).unwrap(),
        Vec::<String>::new()
    );
    assert_eq!(
        check_error(&circular(6000.0)),
        "telemetry.csv (r_x_km, r_y_km, r_z_km), row 0 (t_s = 0.0): the position's radius, \
         6000.0 km, is inside the Earth (radius 6378.137 km): positions must be km from the \
         Earth's centre, GCRF; these positions are not an orbit"
    );
    assert_eq!(
        check_error(&circular(6400.0)),
        "telemetry.csv (r_x_km, r_y_km, r_z_km), row 0 (t_s = 0.0): the position's radius, \
         6400.0 km, is 21.9 km above the Earth's surface, below the 100 km where any orbit \
         ends; these positions are not an orbit"
    );
    // Metres in the _km columns.
    let mut metres = circular(6800.0);
    (metres.r_gcrf_km.as_mut().unwrap()).map_in_place(|r| r * 1000.0);
    assert_eq!(
        check_error(&metres),
        "telemetry.csv (r_x_km, r_y_km, r_z_km), row 0 (t_s = 0.0): the position's radius, \
         6.8000e6 km, is beyond 1e6 km (past the Moon): metres written in the _km columns?; \
         these positions are not an orbit"
    );
    // A jump of 1000 km in one second.
    let mut jump = circular(6800.0);
    jump.r_gcrf_km
        .as_mut()
        .unwrap()
        .set(10, Some(Vector3::new(7800.0, 0.0, 0.0)));
    let message = check_error(&jump);
    assert!(
        message.starts_with(
            "telemetry.csv (r_x_km, r_y_km, r_z_km), row 10 (t_s = 10.0): the spacecraft would \
             move at"
        ) && message.contains("above the escape speed at that radius"),
        "{message}"
    );
}

#[test]
fn a_magnetometer_stuck_with_jitter_is_caught() {
    let mut telemetry = sim().telemetry.clone();
    let mag = telemetry.mag_nt.as_mut().unwrap();
    let n = mag.iter().flatten().count();
    let sampled: Vec<usize> = (0..mag.len()).filter(|&j| mag.get(j).is_some()).collect();
    for (k, &row) in sampled.iter().enumerate() {
        let b = Vector3::new(20_000.0 + 1e-3 * (k % 2) as f64, -5_000.0, 30_000.0);
        mag.set(row, Some(b));
    }
    assert_eq!(
        check_error(&telemetry),
        format!(
            "telemetry.csv (mag_x_nT): varies by only 1.000e-3 nT over all {n} sampled rows, \
             less than 1 nT; an orbiting magnetometer sees the field change by far more (a stuck \
             sensor with a little jitter added)"
        )
    );
}

#[test]
fn diagnose_on_ten_rows_says_too_little_data() {
    let telemetry = sim().telemetry.select_rows(|k| k < 10);
    let err = pdcal::diagnose::run(&sim().meta, &telemetry, pdcal_diagnose::BaseModel::Paper)
        .map(|_| ())
        .unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        "too little data to diagnose: 10 rows; a diagnosis tests each effect's signature \
         against the residuals' own noise and needs at least 100 rows"
    );
}

#[cfg(unix)]
#[test]
fn non_regular_and_endless_inputs_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let set = tmp.path().join("set");
    fs::create_dir(&set).unwrap();
    // dataset.ron pointing at an endless device.
    std::os::unix::fs::symlink("/dev/zero", set.join("dataset.ron")).unwrap();
    let err = pdcal_dataset::read_meta(&set).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "{}: cannot read: it is a character device, not a regular file; pdcal reads only \
             regular files",
            set.join("dataset.ron").display()
        )
    );
    // telemetry.csv a FIFO: refused, not read forever.
    fs::remove_file(set.join("dataset.ron")).unwrap();
    let made = std::process::Command::new("mkfifo")
        .arg(set.join("telemetry.csv"))
        .status();
    if made.is_ok_and(|s| s.success()) {
        let err = pdcal_dataset::read_telemetry(&set, &sim().meta).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!(
                "{}: cannot read: it is a FIFO (named pipe), not a regular file; pdcal reads \
                 only regular files",
                set.join("telemetry.csv").display()
            )
        );
    }
    // A --config larger than any configuration.
    let big = tmp.path().join("big.ron");
    let file = fs::File::create(&big).unwrap();
    file.set_len(pdcal_dataset::bounded::MAX_RON_BYTES + 1)
        .unwrap();
    let err = pdcal::calibrate::load_config(&big).map(|_| ()).unwrap_err();
    assert_eq!(
        pdcal::cli::error_text(&err),
        format!(
            "cannot read {}: it is larger than 16 MB, more than any file of its kind needs; \
             pdcal reads at most that",
            big.display()
        )
    );
}

#[test]
fn messages_escape_control_characters_and_speak_our_words() {
    assert_eq!(pdcal_text::clip("pd01\u{1b}[2J\0_V"), "pd01\\u{1b}[2J\\0_V");
    // ron's own text for input nested beyond its limit (ron::Error::ExceededRecursionLimit).
    let ron = "Exceeded recursion limit, try increasing `ron::Options::recursion_limit` and using \
               `serde_stacker` to protect against a stack overflow";
    assert_eq!(
        pdcal_text::parser_message(ron),
        "nested too deeply: more brackets inside brackets than any pdcal file has"
    );
}

#[cfg(target_os = "linux")]
#[test]
fn a_mount_point_out_is_refused_before_computing() {
    use std::os::unix::fs::MetadataExt;
    let shm = Path::new("/dev/shm");
    let (Ok(m), Ok(p)) = (fs::metadata(shm), fs::metadata("/dev")) else {
        return;
    };
    if m.dev() == p.dev() {
        return;
    }
    let err = pdcal::output::OutputDir::create(shm, "calibrate")
        .map(|_| ())
        .unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        "/dev/shm: is a mount point; pdcal replaces an output directory by renaming it, which a \
         mount point does not allow; pass a directory inside it (nothing was changed)"
    );
}

#[test]
fn many_photodiodes_are_refused_up_front_and_figures_page() {
    let err = pdcal::calibrate::check_photodiode_count(1000, "set").unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        "set: 1000 photodiodes, more than the 200 pdcal calibrates (the filter's work grows as \
         the cube of the count; docs/performance.md, \"Many photodiodes\"); calibrate a subset \
         of at most 200 (the others' columns left empty or removed) at a time"
    );
    pdcal::calibrate::check_photodiode_count(200, "set").unwrap();
    assert_eq!(pdcal::calibrate::smoother_block_rows(17), 1024);
    let n = 6 + 3 * 100;
    let rows = pdcal::calibrate::smoother_block_rows(100);
    assert!(rows * 8 * (n * (n + 1) / 2) <= pdcal::calibrate::SMOOTHER_BLOCK_BYTES);
    let pages = pdcal::figures::raw_output_pages(41);
    let stems: Vec<(&str, std::ops::Range<usize>)> = pages
        .iter()
        .map(|(s, r, _)| (s.as_str(), r.clone()))
        .collect();
    assert_eq!(
        stems,
        vec![
            ("fig02_raw_outputs", 0..20),
            ("fig02_raw_outputs_p2", 20..40),
            ("fig02_raw_outputs_p3", 40..41)
        ]
    );
    assert_eq!(pdcal::figures::raw_output_pages(40).len(), 1);
}

#[test]
fn the_printed_summary_stays_short_for_many_segments() {
    let rows: Vec<Vec<String>> = (0..1000).map(|i| vec![i.to_string()]).collect();
    let table = pdcal_report::Table::new("Segments", &["segment", "rows"], rows);
    let short = pdcal::tables::shortened(table, pdcal::tables::CONSOLE_SEGMENTS);
    assert_eq!(short.rows.len(), 21);
    assert_eq!(
        short.rows[10],
        vec!["...", "980 segments more (summary.json segments)"]
    );
    assert_eq!(short.rows[20], vec!["999"]);
}

#[test]
fn a_joint_set_that_cannot_run_in_the_joint_mode_is_an_error_naming_it() {
    let first = (
        std::path::PathBuf::from("set1"),
        sim().meta.clone(),
        sim().telemetry.clone(),
    );
    let mut meta = sim().meta.clone();
    meta.epoch_utc = pdcal_dataset::EpochUtc::parse("2011-11-05T18:29:45Z").unwrap();
    let mut telemetry = sim().telemetry.clone();
    telemetry.mag_nt = None;
    let second = (std::path::PathBuf::from("set2"), meta.clone(), telemetry);
    let err = pdcal::joint::join(vec![first.clone(), second])
        .map(|_| ())
        .unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        "set2: has no magnetometer columns (mag_x_nT, mag_y_nT, mag_z_nT), but set1 has: a joint \
         calibration runs in one mode, and this set cannot run in the full mode the others \
         need; calibrate it alone (photodiode-only), or the others without it"
    );
    // Another object's TLE.
    let pdcal_dataset::OrbitSpec::Tle { line1, line2 } = &sim().meta.orbit else {
        panic!("the scenario flies a TLE");
    };
    let other = pdcal_dataset::OrbitSpec::Tle {
        line1: line1.replacen("37853", "25544", 1),
        line2: line2.replacen("37853", "25544", 1),
    };
    let mut meta_other = meta.clone();
    meta_other.orbit = other;
    let third = (
        std::path::PathBuf::from("set3"),
        meta_other,
        sim().telemetry.clone(),
    );
    let err = pdcal::joint::join(vec![first.clone(), third])
        .map(|_| ())
        .unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        "set3: its TLE is of object \"25544\", but set1's is of object \"37853\": data sets \
         of one calibration must be one spacecraft's (another spacecraft's TLE?)"
    );
    // Two years apart.
    let mut meta_late = sim().meta.clone();
    meta_late.epoch_utc = pdcal_dataset::EpochUtc::parse("2013-11-04T18:29:45Z").unwrap();
    let late = (
        std::path::PathBuf::from("set4"),
        meta_late,
        sim().telemetry.clone(),
    );
    let err = pdcal::joint::join(vec![first, late])
        .map(|_| ())
        .unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        "set4: its epoch is 731 days after set1's, more than the 366 days one joint calibration \
         spans; calibrate the sets separately and compare the results"
    );
}

#[test]
fn a_gyro_in_deg_s_declared_as_rad_s_gets_a_hint() {
    let mut telemetry = sim().telemetry.clone();
    (telemetry.gyro_rad_s).map_in_place(|w| w * (180.0 / std::f64::consts::PI));
    let warnings = pdcal::checks::check_telemetry(&telemetry).unwrap();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].starts_with(
            "telemetry.csv (gyro_x_rad_s, gyro_y_rad_s, gyro_z_rad_s): the gyro says the body \
             turns "
        ) && warnings[0].ends_with("are the rates in deg/s rather than rad/s (a factor of 57.3)?"),
        "{}",
        warnings[0]
    );
}
