//! Physically invalid input (issue 14): every case gets an exact error or warning naming the
//! field; `evaluate` never reports a figure it cannot compute as 0; messages say each cause
//! once and name the file.

use std::fs;
use std::path::Path;
use std::process::Command;
use std::sync::OnceLock;

use nalgebra::Vector3;
use pdcal::calibrate::{RunConfig, albedo_model};
use pdcal_sim::SimOutput;

const PDCAL: &str = env!("CARGO_BIN_EXE_pdcal");

/// The RAX-2-like scenario cut to 27 minutes (3 sunlit minutes at the end).
fn sim() -> &'static SimOutput {
    static SIM: OnceLock<SimOutput> = OnceLock::new();
    SIM.get_or_init(|| {
        let mut scenario = pdcal_sim::Scenario::rax2_like().unwrap();
        scenario.duration_s = 27.0 * 60.0;
        pdcal::simulate::run(&scenario, 21).unwrap()
    })
}

fn check(edit: impl FnOnce(&mut pdcal_dataset::Telemetry)) -> anyhow::Result<Vec<String>> {
    let mut telemetry = sim().telemetry.clone();
    edit(&mut telemetry);
    pdcal::checks::check_telemetry(&telemetry)
}

fn rows() -> usize {
    sim().telemetry.len()
}

#[test]
fn the_simulated_set_passes_without_warnings() {
    assert_eq!(check(|_| {}).unwrap(), Vec::<String>::new());
}

#[test]
fn a_gyro_of_exact_zero_is_an_error_even_through_calibrate() {
    let mut telemetry = sim().telemetry.clone();
    telemetry.gyro_rad_s.map_in_place(|_| Vector3::zeros());
    let err = pdcal::calibrate::run(
        &sim().meta,
        &telemetry,
        &RunConfig::default(),
        &albedo_model().unwrap(),
    )
    .map(|_| ())
    .unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        format!(
            "telemetry.csv (gyro_x_rad_s, gyro_y_rad_s, gyro_z_rad_s): the gyro reads exactly 0 \
             on all {} sampled rows; a dead or disconnected gyro makes the attitude, and so the \
             calibration, meaningless",
            rows()
        )
    );
}

#[test]
fn stuck_sensors_are_errors_and_a_dead_photodiode_a_warning() {
    let err = check(|t| {
        t.gyro_rad_s.map_in_place(|w| Vector3::new(w.x, 0.01, w.z));
    })
    .unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        format!(
            "telemetry.csv (gyro_y_rad_s): stuck at 0.01 on all {} sampled rows; a working gyro's \
             noise never repeats exactly",
            rows()
        )
    );
    let err = check(|t| {
        (t.mag_nt.as_mut().unwrap()).map_in_place(|b| Vector3::new(b.x, b.y, 25000.0));
    })
    .unwrap_err();
    assert!(
        format!("{err:#}").starts_with("telemetry.csv (mag_z_nT): stuck at 25000.0 on all "),
        "{err:#}"
    );
    let err = check(|t| t.pd_v[4].values_mut().for_each(|v| *v = 2.5)).unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        format!(
            "telemetry.csv (pd05_V): stuck at 2.5 V on all {} sampled rows; a photodiode on a \
             rotating spacecraft cannot read one value throughout (leave its cells empty to \
             calibrate the others)",
            rows()
        )
    );
    let warnings = check(|t| t.pd_v[4].values_mut().for_each(|v| *v = 0.0)).unwrap();
    assert_eq!(
        warnings,
        [format!(
            "telemetry.csv (pd05_V): 0 on all {} sampled rows, a dead channel; it is not calibrated",
            rows()
        )]
    );
}

#[test]
fn photodiode_outputs_beyond_any_full_scale() {
    // ADC counts written as volts: the whole column is far above any scale.
    let err = check(|t| {
        for v in t.pd_v[2].values_mut() {
            *v = *v * 1000.0 + 100.0;
        }
    })
    .unwrap_err();
    let text = format!("{err:#}");
    assert!(
        text.starts_with(&format!(
            "telemetry.csv (pd03_V): {0} of {0} samples above 50 V, beyond any photodiode's \
             full scale (first at t_s = 0.0: ",
            rows()
        )) && text.ends_with(" V); are these ADC counts rather than volts?"),
        "{text}"
    );
    // One spike: a warning, the run goes on.
    let warnings = check(|t| t.pd_v[2].set(1000, Some(1e300))).unwrap();
    assert_eq!(
        warnings,
        [format!(
            "telemetry.csv (pd03_V): 1 of {} samples above 50 V, beyond any photodiode's full \
             scale (first at t_s = 1000.0: 1e300 V); they are outliers",
            rows()
        )]
    );
}

/// A field ten times too strong (uT read as 100 nT units, or a bias): calibrate runs, warns
/// on stderr and lists the warning in summary.json, whose mode is a stable string.
#[test]
fn a_field_magnitude_out_of_range_is_a_warning_on_stderr_and_in_summary() {
    let tmp = tempfile::tempdir().unwrap();
    let (set, out) = (tmp.path().join("set"), tmp.path().join("out"));
    let mut ds = sim().to_dataset();
    (ds.telemetry.mag_nt.as_mut().unwrap()).map_in_place(|b| b * 10.0);
    let samples = ds
        .telemetry
        .mag_nt
        .as_ref()
        .unwrap()
        .iter()
        .flatten()
        .count();
    pdcal_dataset::write_dataset(&set, &ds).unwrap();
    let run = Command::new(PDCAL)
        .args([
            "calibrate".as_ref(),
            set.as_os_str(),
            "--out".as_ref(),
            out.as_os_str(),
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    let warning = format!(
        "telemetry.csv (mag_x_nT, mag_y_nT, mag_z_nT): field magnitude outside 10-70 uT on \
         {samples} of {samples} sampled rows (first at t_s = 0.0: "
    );
    assert!(
        stderr.contains(&format!("pdcal: warning: {warning}")),
        "{stderr}"
    );
    let summary: serde_json::Value =
        serde_json::from_slice(&fs::read(out.join("summary.json")).unwrap()).unwrap();
    let listed = summary["warnings"].as_array().unwrap();
    assert_eq!(listed.len(), 1, "{listed:?}");
    assert!(listed[0].as_str().unwrap().starts_with(&warning));
    assert_eq!(summary["mode"], "full");
    assert_eq!(summary["magnetometer_used"], true);
}

fn evaluation_of(truth_rows: Option<usize>) -> pdcal::evaluate::Evaluation {
    let s = sim();
    let outcome = pdcal::calibrate::run(
        &s.meta,
        &s.telemetry,
        &RunConfig::default(),
        &albedo_model().unwrap(),
    )
    .unwrap();
    let mut truth = s.truth.clone();
    if let Some(n) = truth_rows {
        // Keep the truth rows of the first `n` filter steps only.
        let first = truth
            .t_s
            .iter()
            .position(|t| *t == outcome.run.forward[0].t_s)
            .unwrap();
        let keep = first..first + n;
        truth.t_s = truth.t_s[keep.clone()].to_vec();
        truth.q = truth.q[keep.clone()].to_vec();
        truth.w_body_rad_s = truth.w_body_rad_s[keep.clone()].to_vec();
        truth.gyro_bias_rad_s = truth.gyro_bias_rad_s[keep.clone()].to_vec();
        truth.sun_body = truth.sun_body[keep.clone()].to_vec();
        truth.eclipse = truth.eclipse[keep.clone()].to_vec();
        truth.r_gcrf_km = truth.r_gcrf_km[keep.clone()].to_vec();
        truth.mag_body_nt = truth.mag_body_nt[keep].to_vec();
    }
    pdcal::evaluate::evaluate(
        &outcome.run.forward,
        &outcome.run.calibration,
        &truth,
        &s.constants,
    )
    .unwrap()
}

#[test]
fn evaluate_marks_figures_it_cannot_compute_instead_of_zero() {
    // 3 sunlit minutes: no photodiode is lit for 5, so there is no worst case.
    let e = evaluation_of(None);
    assert!(e.worst_normal_error_deg.is_nan() && e.worst_scale_error_percent.is_nan());
    let json = serde_json::to_value(&e).unwrap();
    assert_eq!(json["worst_normal_error_deg"], serde_json::Value::Null);
    let reasons: Vec<(&str, &str)> = e
        .not_evaluable
        .iter()
        .map(|n| (n.figure, n.reason.as_str()))
        .collect();
    assert_eq!(reasons[0].0, "worst_normal_error_deg");
    assert!(
        reasons[0].1.starts_with(
            "no photodiode was lit (full Sun, within 60 deg) for 5 minutes; the most was pd"
        ),
        "{reasons:?}"
    );
    assert_eq!(reasons[1].0, "worst_scale_error_percent");
    assert_eq!(json["not_evaluable"][0]["figure"], "worst_normal_error_deg");

    // Truth covering 100 rows: every time-series figure is not evaluable.
    let e = evaluation_of(Some(100));
    let expected = format!(
        "truth.csv covers 100 of {} estimate rows (needs 99 %)",
        e.truth_coverage.estimate_rows
    );
    let figures: Vec<&str> = e.not_evaluable.iter().map(|n| n.figure).collect();
    assert_eq!(
        figures,
        [
            "worst_normal_error_deg",
            "worst_scale_error_percent",
            "attitude.mean_deg",
            "attitude.rms_deg",
            "attitude.p99_deg",
            "consistency.attitude_within_3sigma",
            "consistency.converged_within_3sigma_of_final",
        ]
    );
    assert_eq!(e.truth_coverage.matched_rows, 100);
    for n in &e.not_evaluable {
        assert_eq!(n.reason, expected, "{}", n.figure);
    }
    assert!(e.attitude.rms_deg.is_nan() && e.consistency.attitude_within_3sigma.is_nan());
    // Per-photodiode errors come from truth.ron and stay.
    assert!(e.photodiodes.iter().all(|p| p.normal_error_deg.is_finite()));
}

#[test]
fn a_config_of_the_wrong_kind_says_what_was_expected() {
    let tmp = tempfile::tempdir().unwrap();
    let set = tmp.path().join("set");
    pdcal_dataset::write_dataset(&set, &sim().to_dataset()).unwrap();
    let scenario = tmp.path().join("scenario.ron");
    fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/scenarios/rax2-like.ron"),
        &scenario,
    )
    .unwrap();
    for (file, kind) in [
        (set.join("dataset.ron"), "a dataset.ron (dataset metadata)"),
        (scenario, "a scenario (simulate --scenario)"),
        (
            set.join("truth.ron"),
            "a truth.ron (simulated truth constants)",
        ),
        (
            set.join("telemetry.csv"),
            "a CSV table (telemetry.csv or truth.csv)",
        ),
    ] {
        let err = pdcal::calibrate::load_config(&file).unwrap_err();
        assert_eq!(
            format!("{err:#}"),
            format!(
                "{}: this is {kind}, not a --config file; --config expects a filter \
                 configuration (RON with fields such as photodiode_sigma_v, gate_sigmas) or the \
                 calibration.ron of an earlier pdcal calibrate",
                file.display()
            )
        );
    }
}

#[test]
fn estimates_csv_faults_name_the_file_and_a_nan_quaternion_is_not_zero() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("estimates.csv");
    let header = pdcal::files::estimate_header(1, &[]).join(",");
    let row = |q: &str| format!("0.0,{q},0.1,0.1,0.1,0,0,0,0,0,0,3.5,0.1,17,0.5,-10,0.5,0,0,0,0");
    fs::write(&path, format!("{header}\n{}\n", row("NaN,0,0,1"))).unwrap();
    let err = pdcal::evaluate::read_estimates(&path).unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        format!(
            "{}:2 (q_x, q_y, q_z, q_w): [NaN, 0.0, 0.0, 1.0] (not finite) is not a quaternion",
            path.display()
        )
    );
    fs::write(&path, format!("{header}\n{}\n", row("0,0,0,0"))).unwrap();
    let err = pdcal::evaluate::read_estimates(&path).unwrap_err();
    assert!(format!("{err:#}").ends_with("[0.0, 0.0, 0.0, 0.0] (all zero) is not a quaternion"));
    // A ragged row: the csv crate's error, with the file and line.
    fs::write(&path, format!("{header}\n{}\n1,2\n", row("0,0,0,1"))).unwrap();
    let err = pdcal::evaluate::read_estimates(&path).unwrap_err();
    assert!(
        format!("{err:#}").starts_with(&format!("{}:3: ", path.display())),
        "{err:#}"
    );
    // A 1 MB cell is quoted short.
    let big = "7".repeat(1 << 20);
    fs::write(
        &path,
        format!("{header}\n{}\n", row(&format!("{big}x,0,0,1"))),
    )
    .unwrap();
    let err = format!("{:#}", pdcal::evaluate::read_estimates(&path).unwrap_err());
    assert!(err.len() < 300, "{} bytes", err.len());
    assert!(
        err.ends_with("... (1048577 bytes) is not a number"),
        "{err}"
    );
}

/// An error type that prints its inner error and also returns it as `source`, as
/// `#[error("...: {0}")]` with `#[from]` does.
#[derive(Debug)]
struct Wrapping(std::io::Error);

impl std::fmt::Display for Wrapping {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "calibration filter: {}", self.0)
    }
}

impl std::error::Error for Wrapping {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.0)
    }
}

#[test]
fn each_cause_is_said_once() {
    let inner = std::io::Error::other("covariance not positive definite at sample 7");
    let err = anyhow::Error::new(Wrapping(inner)).context("diagnosis");
    assert_eq!(
        format!("{err:#}"),
        "diagnosis: calibration filter: covariance not positive definite at sample 7: covariance \
         not positive definite at sample 7",
        "anyhow's own chain repeats it"
    );
    assert_eq!(
        pdcal::cli::error_text(&err),
        "diagnosis: calibration filter: covariance not positive definite at sample 7"
    );
    // The reference errors of pdcal-ephem say their cause once in a chain.
    let field = pdcal_ephem::ReferenceError::from(pdcal_ephem::igrf::IgrfError::Parse {
        line: 3,
        reason: "bad".into(),
    });
    let err = anyhow::Error::new(field).context("references");
    assert_eq!(
        format!("{err:#}"),
        "references: reference field: SHC coefficient file, line 3: bad"
    );
}

/// A TLE years from its data (a Unix time column read as GPS time puts the data ten years
/// on) is said; one within the year is not.
#[test]
fn a_tle_years_from_the_data_is_said() {
    let mut meta = sim().meta.clone();
    let telemetry = &sim().telemetry;
    assert_eq!(
        pdcal::checks::orbit_age(&meta, telemetry, "dataset.ron"),
        None
    );
    for (epoch, said) in [
        ("2012-03-01T00:00:00Z", false),
        ("2021-11-10T18:29:45Z", true),
    ] {
        meta.epoch_utc = pdcal_dataset::EpochUtc::parse(epoch).unwrap();
        let warning = pdcal::checks::orbit_age(&meta, telemetry, "dataset.ron");
        assert_eq!(warning.is_some(), said, "{epoch}: {warning:?}");
        if let Some(w) = warning {
            assert!(
                w.starts_with("dataset.ron: the TLE's epoch") && w.contains("3659 days"),
                "{w}"
            );
        }
    }
    // Data spanning three years from the TLE's epoch: the row quoted is the far one.
    let meta = sim().meta.clone();
    let mut telemetry = telemetry.clone();
    *telemetry.t_s.last_mut().unwrap() = 3.0 * 365.0 * 86_400.0;
    let w = pdcal::checks::orbit_age(&meta, &telemetry, "dataset.ron").unwrap();
    assert!(
        w.contains("days from the data (last row 2014-11-03T"),
        "{w}"
    );
}

/// A run that fails keeps the input's warnings: with a TLE from 1957, the failure says the
/// TLE is decades from the data, not only what the filter then met.
#[test]
fn a_failed_run_keeps_the_tle_age_warning() {
    let tmp = tempfile::tempdir().unwrap();
    let scenario = pdcal_sim::Scenario::from_ron_str(include_str!(
        "../../../../fixtures/scenarios/weak/pyramid-head.ron"
    ))
    .unwrap();
    let dir = tmp.path().join("ds");
    pdcal::simulate::run_to_dir(&scenario, 1, &dir).unwrap();
    let text = fs::read_to_string(dir.join("dataset.ron")).unwrap();
    let at = text.find("line1: \"").unwrap() + "line1: \"".len();
    let line1 = &text[at..at + 69];
    // Epoch year 11 -> 57, and the checksum of columns 1-68 again.
    let mut moved = format!("{}57{}", &line1[..18], &line1[20..68]);
    let sum: u32 = moved
        .chars()
        .map(|c| c.to_digit(10).unwrap_or(u32::from(c == '-')))
        .sum();
    moved.push(char::from_digit(sum % 10, 10).unwrap());
    fs::write(dir.join("dataset.ron"), text.replace(line1, &moved)).unwrap();
    let Err(err) = pdcal::calibrate::run_dir(&dir, &tmp.path().join("out"), &RunConfig::default())
    else {
        panic!("a TLE from 1957 calibrated");
    };
    let text = pdcal::cli::error_text(&err);
    assert!(
        text.contains("the input's warnings, which may say why: ")
            && text.contains("the TLE's epoch 1957-11-04T"),
        "{text}"
    );
}

/// `--mag-align` acts on a `--mag-cal` file only: given without one, it is refused before
/// anything is read, instead of silently doing nothing.
#[test]
fn mag_align_without_mag_cal_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let o = Command::new(PDCAL)
        .args([
            "calibrate",
            "no-such-dataset",
            "--mag-align",
            "off",
            "--out",
        ])
        .arg(tmp.path().join("out"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--mag-cal <MAG_CAL>"), "{stderr}");
    assert!(!tmp.path().join("out").exists());
}
