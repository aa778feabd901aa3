//! `pdcal export-onboard` and `pdcal sun-vector` on a simulated RAX-2-like hour (24 min of
//! umbra, then Sun) with one dead channel: the header compiles with the system C compiler
//! and holds calibration.ron's values (a C program reads them back), the dead channel is
//! exported disabled with its parameters flagged nominal, the onboard core's Sun direction
//! matches the truth on the sunlit rows, and bad input names the file.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use pdcal::export_onboard::OnboardCalibration;

const PDCAL: &str = env!("CARGO_BIN_EXE_pdcal");
/// The dead channel (0-based): it reads 0 V throughout.
const DEAD: usize = 4;

struct Run {
    _tmp: tempfile::TempDir,
    dataset: PathBuf,
    cal: PathBuf,
    root: PathBuf,
}

fn run() -> &'static Run {
    static RUN: OnceLock<Run> = OnceLock::new();
    RUN.get_or_init(|| {
        let tmp = tempfile::tempdir().unwrap();
        let root = tmp.path().to_path_buf();
        let mut scenario = pdcal_sim::Scenario::rax2_like().unwrap();
        scenario.duration_s = 3600.0;
        let clean = root.join("clean");
        pdcal::simulate::run_to_dir(&scenario, 3, &clean).unwrap();
        let mut ds = pdcal_dataset::read_dataset(&clean).unwrap();
        ds.telemetry.pd_v[DEAD].values_mut().for_each(|v| *v = 0.0);
        let dataset = root.join("dataset");
        pdcal_dataset::write_dataset(&dataset, &ds).unwrap();
        let cal = root.join("cal");
        pdcal::calibrate::run_dirs(
            std::slice::from_ref(&dataset),
            &cal,
            &pdcal::calibrate::RunConfig::default(),
        )
        .unwrap();
        Run {
            _tmp: tmp,
            dataset,
            cal,
            root,
        }
    })
}

fn pdcal(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(PDCAL).args(args).output().unwrap()
}

fn export(out: &Path) -> OnboardCalibration {
    let r = run();
    let o = pdcal(&[
        "export-onboard".as_ref(),
        r.cal.as_os_str(),
        "--dataset".as_ref(),
        r.dataset.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    pdcal::export_onboard::load(&out.join("onboard.ron")).unwrap()
}

/// Compiles `main.c` including the header in `dir` and runs it: one line per photodiode.
fn compile_and_run(dir: &Path) -> String {
    let source = dir.join("main.c");
    std::fs::write(
        &source,
        r#"#include <stdio.h>
#include "pdcal_calibration.h"
int main(void) {
    const pdcal_calibration *c = &pdcal_calibration_default;
    unsigned i;
    printf("%u %u %u %u %zu\n", c->count, pdcal_grid_default.n_lat, pdcal_grid_default.n_lon,
           (unsigned)pdcal_grid_default.cells[0], sizeof(pdcal_calibration));
    for (i = 0; i < c->count; i++) {
        const pdcal_photodiode *p = &c->photodiodes[i];
        printf("%.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %d\n", p->scale_v,
               p->normal_body[0], p->normal_body[1], p->normal_body[2], p->dark_v,
               p->fov_half_angle_rad, p->noise_v, p->scale_sigma_v, p->normal_sigma_rad,
               0.0, p->enabled ? 1 : 0);
    }
    return 0;
}
"#,
    )
    .unwrap();
    // On its own (its constants unused there), then in a program that reads them.
    let object = dir.join("header.o");
    let cc = Command::new("cc")
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror"])
        .args(["-Wno-unused-const-variable", "-c", "-x", "c"])
        .arg(dir.join("pdcal_calibration.h"))
        .arg("-o")
        .arg(&object)
        .output()
        .unwrap();
    assert!(
        cc.status.success(),
        "{}",
        String::from_utf8_lossy(&cc.stderr)
    );
    let exe = dir.join("main");
    let cc = Command::new("cc")
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(dir)
        .arg(&source)
        .arg("-o")
        .arg(&exe)
        .output()
        .unwrap();
    assert!(
        cc.status.success(),
        "{}",
        String::from_utf8_lossy(&cc.stderr)
    );
    let out = Command::new(&exe).output().unwrap();
    assert!(out.status.success());
    String::from_utf8(out.stdout).unwrap()
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-6 * a.abs().max(b.abs()).max(1e-3)
}

#[test]
fn the_header_compiles_and_holds_calibration_ron_values() {
    let r = run();
    let out = r.root.join("export-a");
    let export = export(&out);
    let printed = compile_and_run(&out);
    let mut lines = printed.lines();
    let head: Vec<usize> = lines
        .next()
        .unwrap()
        .split(' ')
        .map(|x| x.parse().unwrap())
        .collect();
    assert_eq!(head[0], 17);
    assert_eq!((head[1], head[2]), (36, 72), "5 deg cells by default");
    assert_eq!(head[3], usize::from(export.grid.cells[0]));
    assert_eq!(
        head[4],
        std::mem::size_of::<pdcal_onboard::ffi::PdcalCalibration>(),
        "the header's struct has the Rust layout"
    );

    let text = std::fs::read_to_string(r.cal.join("calibration.ron")).unwrap();
    let cal = pdcal_filter::Calibration::from_ron_str(&text).unwrap();
    let meta = pdcal_dataset::read_meta(&r.dataset).unwrap();
    let noise = meta.noise.and_then(|n| n.photodiode_v).unwrap();
    let mut compared = 0;
    for (i, (line, pd)) in lines.zip(&cal.photodiodes).enumerate() {
        let v: Vec<f64> = line.split(' ').map(|x| x.parse().unwrap()).collect();
        let status = &export.photodiodes[i].status;
        let calibrated = |name: &str| {
            status
                .iter()
                .any(|s| s.parameter == name && s.status == "calibrated")
        };
        if calibrated("scale") {
            assert!(close(v[0], pd.scale_v), "pd{:02} scale {v:?} {pd:?}", i + 1);
            compared += 1;
        }
        if calibrated("azimuth") && calibrated("elevation") {
            let n = pd.n_body();
            for k in 0..3 {
                assert!(
                    (v[1 + k] - n[k]).abs() < 1e-6,
                    "pd{:02} normal {v:?}",
                    i + 1
                );
            }
            compared += 1;
        }
        assert_eq!(v[4], 0.0, "no dark offset estimated");
        assert!(close(v[5], std::f64::consts::FRAC_PI_2), "hemisphere");
        assert!(close(v[6], noise), "the data set's noise");
        assert_eq!(v[10] == 1.0, i != DEAD, "pd{:02} enabled", i + 1);
    }
    assert!(compared >= 30, "only {compared} values were calibrated");
}

#[test]
fn a_dead_channel_is_disabled_and_its_parameters_flagged_nominal() {
    let r = run();
    let out = r.root.join("export-b");
    let export = export(&out);
    let dead = &export.photodiodes[DEAD];
    assert!(!dead.enabled);
    assert!(dead.disabled_reason.is_some());
    let flagged: Vec<&str> = dead
        .status
        .iter()
        .filter(|s| s.nominal && s.status != "calibrated" && s.parameter != "dark")
        .map(|s| s.parameter.as_str())
        .collect();
    assert!(!flagged.is_empty(), "{dead:?}");
    // Exported at the nominal value summary.json gives.
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(r.cal.join("summary.json")).unwrap())
            .unwrap();
    let initial = &summary["photodiodes"][DEAD]["initial"];
    if flagged.contains(&"scale") {
        assert_eq!(dead.scale_v, initial["scale_V"].as_f64().unwrap());
    }
    let header = std::fs::read_to_string(out.join("pdcal_calibration.h")).unwrap();
    let comment = header.lines().find(|l| l.contains("/* pd05 ")).unwrap();
    assert!(comment.contains("DISABLED"), "{comment}");
    assert!(comment.contains("NOMINAL"), "{comment}");
    for p in flagged {
        assert!(comment.contains(p), "{comment}");
    }
}

/// The true Sun direction in the body frame: the true attitude times the Sun direction in
/// GCRF from the ephemeris.
fn true_sun_body(r: &Run) -> (Vec<nalgebra::Vector3<f64>>, Vec<f64>) {
    let ds = pdcal_dataset::read_dataset(&r.dataset).unwrap();
    let (truth, _) = ds.truth.unwrap();
    let model = pdcal_filter::references::reference_model(&ds.meta, &ds.telemetry).unwrap();
    let sun = truth
        .t_s
        .iter()
        .zip(&truth.q)
        .map(|(&t, q)| {
            let q = pdcal_attitude::Quat::new_normalized(q[0], q[1], q[2], q[3]).unwrap();
            q.attitude_matrix() * model.at(t).unwrap().sun_gcrf_unit
        })
        .collect();
    (sun, truth.eclipse)
}

#[test]
fn sun_vector_matches_the_truth_on_sunlit_rows() {
    let r = run();
    let out = r.root.join("sun.csv");
    let o = pdcal(&[
        "sun-vector".as_ref(),
        r.dataset.as_os_str(),
        "--calibration".as_ref(),
        r.cal.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (sun, lit) = true_sun_body(r);
    let mut reader = csv::Reader::from_path(&out).unwrap();
    let header = reader.headers().unwrap().clone();
    assert_eq!(
        header.iter().take(7).collect::<Vec<_>>(),
        [
            "t_s",
            "sun_x",
            "sun_y",
            "sun_z",
            "sigma_deg",
            "used",
            "valid"
        ]
    );
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let (mut sunlit, mut within, mut valid, mut rows) = (0, 0, 0, 0);
    for (k, record) in reader.records().enumerate() {
        let record = record.unwrap();
        rows += 1;
        if record[col("attitude")] == *"none" {
            assert_eq!(&record[col("albedo")], "bound", "row {k}");
        }
        if lit[k] < 1.0 {
            continue;
        }
        sunlit += 1;
        valid += usize::from(&record[col("valid")] == "1");
        if record[col("sun_x")].is_empty() {
            continue;
        }
        let s = nalgebra::Vector3::new(
            record[col("sun_x")].parse::<f64>().unwrap(),
            record[col("sun_y")].parse::<f64>().unwrap(),
            record[col("sun_z")].parse::<f64>().unwrap(),
        );
        within += usize::from(s.angle(&sun[k]).to_degrees() <= 1.0);
    }
    assert_eq!(rows, sun.len(), "one row per telemetry row");
    assert!(sunlit > 1000, "{sunlit} sunlit rows");
    let within = within as f64 / sunlit as f64;
    let valid = valid as f64 / sunlit as f64;
    assert!(within >= 0.9, "within 1 deg on {within:.3} of sunlit rows");
    assert!(valid >= 0.9, "valid on {valid:.3} of sunlit rows");
}

fn stderr_of(args: &[&std::ffi::OsStr]) -> String {
    let o = pdcal(args);
    assert!(!o.status.success());
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn bad_input_names_the_file() {
    let r = run();
    // No calibration there.
    let empty = r.root.join("no-calibration");
    std::fs::create_dir_all(&empty).unwrap();
    let err = stderr_of(&[
        "sun-vector".as_ref(),
        r.dataset.as_os_str(),
        "--calibration".as_ref(),
        empty.as_os_str(),
        "--out".as_ref(),
        r.root.join("x.csv").as_os_str(),
    ]);
    assert!(
        err.contains(&format!(
            "cannot read {}",
            empty.join("calibration.ron").display()
        )),
        "{err}"
    );
    assert!(!r.root.join("x.csv").exists());

    // A data set of 16 photodiodes against a calibration of 17.
    let mut ds = pdcal_dataset::read_dataset(&r.dataset).unwrap();
    ds.meta.photodiodes.pop();
    ds.telemetry.pd_v.pop();
    ds.truth = None;
    let fewer = r.root.join("fewer");
    pdcal_dataset::write_dataset(&fewer, &ds).unwrap();
    let err = stderr_of(&[
        "export-onboard".as_ref(),
        r.cal.as_os_str(),
        "--dataset".as_ref(),
        fewer.as_os_str(),
        "--out".as_ref(),
        r.root.join("export-c").as_os_str(),
    ]);
    let expected = format!(
        "{}: 16 photodiodes, but the calibration {} has 17",
        fewer.join("dataset.ron").display(),
        r.cal.join("calibration.ron").display()
    );
    assert!(err.contains(&expected), "{err}");
    assert!(!r.root.join("export-c").exists());
}
