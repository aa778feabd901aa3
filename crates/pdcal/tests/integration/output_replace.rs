//! Which directory a command may replace (issue 22, item 2): only one holding an output of
//! the same command (by its manifest's `command`), with nothing the manifest does not list,
//! and every listed file as pdcal wrote it unless `--force`. Each refusal is checked word
//! for word and leaves the directory as it was.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use pdcal::calibrate::RunConfig;

const PDCAL: &str = env!("CARGO_BIN_EXE_pdcal");

fn short_scenario() -> pdcal_sim::Scenario {
    let mut scenario = pdcal_sim::Scenario::rax2_like().unwrap();
    scenario.duration_s = 27.0 * 60.0;
    scenario
}

/// A simulated set and its calibration, made once.
fn calibrated() -> &'static (PathBuf, PathBuf) {
    static DIRS: OnceLock<(tempfile::TempDir, (PathBuf, PathBuf))> = OnceLock::new();
    let (_, dirs) = DIRS.get_or_init(|| {
        let tmp = tempfile::tempdir().unwrap();
        let set = tmp.path().join("set");
        let out = tmp.path().join("cal");
        pdcal::simulate::run_to_dir(&short_scenario(), 11, &set).unwrap();
        pdcal::calibrate::run_dir(&set, &out, &RunConfig::default()).unwrap();
        (tmp, (set, out))
    });
    dirs
}

/// A copy of a directory (flat or one level of subdirectories).
fn copy_dir(from: &Path, to: &Path) {
    fs::create_dir_all(to).unwrap();
    for entry in fs::read_dir(from).unwrap() {
        let path = entry.unwrap().path();
        let target = to.join(path.file_name().unwrap());
        if path.is_dir() {
            copy_dir(&path, &target);
        } else {
            fs::copy(&path, &target).unwrap();
        }
    }
}

fn snapshot(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    for entry in fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            out.extend(snapshot(&path));
        } else {
            out.push((path.clone(), fs::read(&path).unwrap()));
        }
    }
    out.sort();
    out
}

const REFUSE: &str =
    "refusing to write into it (nothing was changed); pass a new or empty directory";

#[test]
fn simulate_does_not_replace_a_hand_made_dataset() {
    let tmp = tempfile::tempdir().unwrap();
    let mine = tmp.path().join("mine");
    fs::create_dir(&mine).unwrap();
    let (set, _) = calibrated();
    // dataset.ron and telemetry.csv as a user wrote them, no manifest.
    for name in ["dataset.ron", "telemetry.csv"] {
        fs::copy(set.join(name), mine.join(name)).unwrap();
    }
    let before = snapshot(&mine);
    let err = pdcal::simulate::run_to_dir(&short_scenario(), 1, &mine).unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        format!(
            "{}: not empty and not a pdcal output (no .pdcal-manifest.json); {REFUSE}",
            mine.display()
        )
    );
    assert_eq!(snapshot(&mine), before);
    // A dataset simulate wrote is replaced by simulate, not by import.
    let sim = tmp.path().join("sim");
    pdcal::simulate::run_to_dir(&short_scenario(), 1, &sim).unwrap();
    pdcal::simulate::run_to_dir(&short_scenario(), 2, &sim).unwrap();
    let err = pdcal::import::run_to_dir(
        &tmp.path().join("no-such-export.csv"),
        &tmp.path().join("no-such-map.ron"),
        &sim,
    )
    .unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        format!(
            "{}: holds the output of `pdcal simulate` (its .pdcal-manifest.json says so), which \
             `pdcal import` does not replace; {REFUSE}",
            sim.display()
        )
    );
}

#[test]
fn diagnose_does_not_replace_a_calibration() {
    let tmp = tempfile::tempdir().unwrap();
    let (set, cal) = calibrated();
    let out = tmp.path().join("cal");
    copy_dir(cal, &out);
    let before = snapshot(&out);
    let err = pdcal::diagnose::run_dir(set, &out, pdcal_diagnose::BaseModel::Paper)
        .map(|_| ())
        .unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        format!(
            "{}: holds the output of `pdcal calibrate` (its .pdcal-manifest.json says so), which \
             `pdcal diagnose` does not replace; {REFUSE}",
            out.display()
        )
    );
    assert_eq!(snapshot(&out), before);
}

#[test]
fn an_edited_file_is_replaced_only_with_force() {
    let tmp = tempfile::tempdir().unwrap();
    let (set, cal) = calibrated();
    let out = tmp.path().join("cal");
    copy_dir(cal, &out);
    let edited = fs::read_to_string(out.join("calibration.ron")).unwrap() + "// my notes\n";
    fs::write(out.join("calibration.ron"), &edited).unwrap();
    let before = snapshot(&out);
    let run = |force: bool| {
        let mut cmd = Command::new(PDCAL);
        cmd.arg("calibrate").arg(set).arg("--out").arg(&out);
        if force {
            cmd.arg("--force");
        }
        cmd.output().unwrap()
    };
    let refused = run(false);
    assert!(!refused.status.success());
    assert_eq!(
        String::from_utf8_lossy(&refused.stderr),
        format!(
            "pdcal: error: {}: \"calibration.ron\" was changed after pdcal wrote it (its size or \
             checksum differs from .pdcal-manifest.json), so it may be your edit; refusing to \
             replace it (nothing was changed): copy it elsewhere, or pass --force to replace it \
             anyway\n",
            out.display()
        )
    );
    assert_eq!(snapshot(&out), before);
    let forced = run(true);
    assert!(
        forced.status.success(),
        "{}",
        String::from_utf8_lossy(&forced.stderr)
    );
    let manifest = pdcal::output::Manifest::read(&out).unwrap().unwrap();
    manifest.verify(&out).unwrap();
    assert_ne!(
        fs::read_to_string(out.join("calibration.ron")).unwrap(),
        edited
    );
}

#[test]
fn nothing_the_manifest_does_not_list_is_removed_even_with_force() {
    let tmp = tempfile::tempdir().unwrap();
    let (set, cal) = calibrated();
    let out = tmp.path().join("cal");
    copy_dir(cal, &out);
    // A directory named like an output file, holding the user's files.
    fs::remove_file(out.join("estimates.csv")).unwrap();
    fs::create_dir(out.join("estimates.csv")).unwrap();
    fs::write(out.join("estimates.csv/thesis.tex"), "mine").unwrap();
    let before = snapshot(&out);
    for force in [false, true] {
        let err = pdcal::calibrate::run_dirs_forced(
            std::slice::from_ref(set),
            &out,
            &RunConfig::default(),
            force,
        )
        .map(|_| ())
        .unwrap_err();
        assert_eq!(
            format!("{err:#}"),
            format!(
                "{}: holds a directory \"estimates.csv\", which pdcal did not write (it is not \
                 in .pdcal-manifest.json); {REFUSE}",
                out.display()
            )
        );
        assert_eq!(snapshot(&out), before);
    }
    // A file inside a directory pdcal wrote (figures/...) is refused the same way.
    let out2 = tmp.path().join("cal2");
    copy_dir(cal, &out2);
    let sub = fs::read_dir(&out2)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.is_dir());
    if let Some(sub) = sub {
        fs::write(sub.join("mine.txt"), "mine").unwrap();
        let name = sub.file_name().unwrap().to_string_lossy().into_owned();
        let err = pdcal::calibrate::run_dir(set, &out2, &RunConfig::default())
            .map(|_| ())
            .unwrap_err();
        assert_eq!(
            format!("{err:#}"),
            format!(
                "{}: holds \"{name}/mine.txt\", which pdcal did not write (it is not in \
                 .pdcal-manifest.json); {REFUSE}",
                out2.display()
            )
        );
    }
}

/// `--out .` is refused for what it is, a path with no name of its own, not as a mount
/// point; a 240-byte name, which the file system allows, is written and replaced (its
/// staging and lock files beside it take a shortened name).
#[test]
fn out_dot_is_named_for_what_it_is_and_a_long_legal_name_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let simulate = |cwd: &Path, out: &str| {
        Command::new(PDCAL)
            .current_dir(cwd)
            .args(["simulate", "--scenario", "sso-6u", "--out", out])
            .output()
            .unwrap()
    };
    let o = simulate(tmp.path(), ".");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains(".: names no directory of its own") && !stderr.contains("mount point"),
        "{stderr}"
    );
    let long = "d".repeat(240);
    for _ in 0..2 {
        let o = simulate(tmp.path(), &long);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(tmp.path().join(&long).join("dataset.ron").is_file());
    }
    // Nothing left beside it.
    let names: Vec<String> = fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, [long]);
}
