//! Fault injection on output directories (issue 14): user files survive, a run killed at
//! any instant leaves the complete old or the complete new output, and what killed runs
//! leave beside the output is cleaned by the next run.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use pdcal::calibrate::RunConfig;
use pdcal::output::{MANIFEST, Manifest};
use rand::{RngExt, SeedableRng};

const PDCAL: &str = env!("CARGO_BIN_EXE_pdcal");

/// The RAX-2-like scenario cut to 27 minutes: the first 3 sunlit minutes give the filter
/// something to do, and one run stays well under a second.
fn short_dataset() -> &'static Path {
    static DIR: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    let (_, path) = DIR.get_or_init(|| {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("set");
        let mut scenario = pdcal_sim::Scenario::rax2_like().unwrap();
        scenario.duration_s = 27.0 * 60.0;
        pdcal::simulate::run_to_dir(&scenario, 11, &path).unwrap();
        (tmp, path)
    });
    path
}

/// Every file under `dir` with its bytes, relative paths, sorted.
fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<(String, Vec<u8>)>) {
        for entry in fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(root, &path, out);
            } else {
                let rel = path.strip_prefix(root).unwrap().display().to_string();
                out.push((rel, fs::read(&path).unwrap()));
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out.sort();
    out
}

/// Names in `parent` that pdcal puts beside an output `name` (staging, moved aside, lock).
fn siblings(parent: &Path, name: &str) -> Vec<String> {
    let prefix = format!(".{name}.pdcal-");
    let mut v: Vec<String> = fs::read_dir(parent)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(&prefix))
        .collect();
    v.sort();
    v
}

/// The manifest of a complete output: it parses, every listed file has its size and
/// checksum, and the directory holds nothing else.
fn complete_output(dir: &Path) -> Result<Manifest, String> {
    let manifest = Manifest::read(dir)
        .map_err(|e| format!("{e:#}"))?
        .ok_or_else(|| format!("{} has no manifest", dir.display()))?;
    manifest.verify(dir).map_err(|e| format!("{e:#}"))?;
    let mut listed: Vec<String> = manifest.files.iter().map(|f| f.name.clone()).collect();
    listed.push(MANIFEST.to_owned());
    listed.sort();
    let present: Vec<String> = snapshot(dir).into_iter().map(|(n, _)| n).collect();
    if present != listed {
        return Err(format!(
            "{} holds {present:?}, lists {listed:?}",
            dir.display()
        ));
    }
    Ok(manifest)
}

/// A process that is certainly gone: spawned, finished and reaped.
fn dead_pid() -> u32 {
    let mut child = Command::new("true").spawn().unwrap();
    let pid = child.id();
    child.wait().unwrap();
    pid
}

fn calibrate_child(out: &Path, pause_ms: Option<u64>) -> Child {
    let mut cmd = Command::new(PDCAL);
    cmd.arg("calibrate")
        .arg(short_dataset())
        .arg("--out")
        .arg(out)
        .stdout(Stdio::null())
        .stderr(Stdio::null());
    if let Some(ms) = pause_ms {
        cmd.env("PDCAL_TEST_PAUSE_BEFORE_PUBLISH_MS", ms.to_string());
    }
    cmd.spawn().unwrap()
}

fn calibrate_from(dataset: &Path, out: &Path) -> anyhow::Result<()> {
    pdcal::calibrate::run_dir(dataset, out, &RunConfig::default()).map(|_| ())
}

fn calibrate(out: &Path) -> anyhow::Result<()> {
    calibrate_from(short_dataset(), out)
}

#[test]
fn a_directory_pdcal_did_not_write_is_refused_untouched_before_any_computation() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("thesis");
    fs::create_dir_all(out.join("chapter1")).unwrap();
    fs::write(out.join("notes.txt"), "mine").unwrap();
    fs::write(out.join("thesis.tex"), "\\documentclass{article}").unwrap();
    fs::write(out.join("photo.jpg"), [0xff, 0xd8, 0xff]).unwrap();
    fs::write(out.join("chapter1/intro.tex"), "intro").unwrap();
    // A pdcal-looking name does not make it pdcal's.
    fs::write(out.join("summary.json"), "{}").unwrap();
    let before = snapshot(&out);
    // The dataset does not exist: the refusal must come first, before reading it.
    let err = calibrate_from(&tmp.path().join("no-such-set"), &out).unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        format!(
            "{}: not empty and not a pdcal output (no .pdcal-manifest.json); refusing to write \
             into it (nothing was changed); pass a new or empty directory",
            out.display()
        )
    );
    assert_eq!(snapshot(&out), before, "every user file is untouched");
    assert_eq!(siblings(tmp.path(), "thesis"), Vec::<String>::new());
}

#[test]
fn a_user_file_added_to_an_output_stops_its_replacement() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    calibrate(&out).unwrap();
    fs::write(out.join("notes.txt"), "mine").unwrap();
    let before = snapshot(&out);
    let err = calibrate(&out).unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        format!(
            "{}: holds \"notes.txt\", which pdcal did not write (it is not in \
             .pdcal-manifest.json); refusing to write into it (nothing was changed); pass a new \
             or empty directory",
            out.display()
        )
    );
    assert_eq!(snapshot(&out), before);
    // Without it, the output is pdcal's again and is replaced.
    fs::remove_file(out.join("notes.txt")).unwrap();
    calibrate(&out).unwrap();
    complete_output(&out).unwrap();
}

#[test]
fn diagnose_and_simulate_check_out_before_computing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("mine");
    fs::create_dir(&out).unwrap();
    fs::write(out.join("notes.txt"), "mine").unwrap();
    let start = Instant::now();
    let err = pdcal::diagnose::run_dir(
        &tmp.path().join("no-such-set"),
        &out,
        pdcal_diagnose::BaseModel::Paper,
    )
    .map(|_| ())
    .unwrap_err();
    assert!(
        format!("{err:#}").starts_with(&format!(
            "{}: not empty and not a pdcal output",
            out.display()
        )),
        "{err:#}"
    );
    // simulate: the full 2-hour scenario would take seconds; the refusal is immediate.
    let scenario = pdcal_sim::Scenario::rax2_like().unwrap();
    let err = pdcal::simulate::run_to_dir(&scenario, 1, &out).unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        format!(
            "{}: not empty and not a pdcal output (no .pdcal-manifest.json); refusing to write \
             into it (nothing was changed); pass a new or empty directory",
            out.display()
        )
    );
    assert!(
        start.elapsed() < Duration::from_secs(2),
        "{:?}",
        start.elapsed()
    );
    assert_eq!(fs::read_to_string(out.join("notes.txt")).unwrap(), "mine");
}

#[test]
fn a_symlinked_out_is_followed_and_stays_a_symlink() {
    let tmp = tempfile::tempdir().unwrap();
    let real = tmp.path().join("real");
    let link = tmp.path().join("link");
    fs::create_dir(&real).unwrap();
    std::os::unix::fs::symlink(&real, &link).unwrap();
    calibrate(&link).unwrap();
    calibrate(&link).unwrap();
    assert!(
        fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(complete_output(&real).unwrap().command, "calibrate");
    // A link to nothing is refused with what it points to.
    let dangling = tmp.path().join("dangling");
    std::os::unix::fs::symlink(tmp.path().join("gone"), &dangling).unwrap();
    let err = calibrate(&dangling).unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        format!(
            "{}: is a symlink to {}, which does not exist; create that directory or pass another \
             path",
            dangling.display(),
            tmp.path().join("gone").display()
        )
    );
}

#[test]
fn a_second_run_on_a_locked_out_names_the_holder_and_a_dead_holder_is_taken_over() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    calibrate(&out).unwrap();
    let before = snapshot(&out);
    let mut holder = Command::new("sleep").arg("30").spawn().unwrap();
    let lock = tmp.path().join(".out.pdcal-lock");
    fs::write(&lock, holder.id().to_string()).unwrap();
    let err = calibrate(&out).unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        format!(
            "{}: is being written by another pdcal run (process {}, lock file {}); wait for it to \
             finish or choose another directory",
            out.display(),
            holder.id(),
            lock.display()
        )
    );
    assert_eq!(snapshot(&out), before, "the holder's output is untouched");
    assert!(lock.exists(), "a live holder's lock stays");
    holder.kill().unwrap();
    holder.wait().unwrap();
    calibrate(&out).unwrap();
    assert!(!lock.exists(), "the lock is released after publishing");
    complete_output(&out).unwrap();
}

#[test]
fn what_dead_runs_leave_is_cleaned_and_live_runs_are_left_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    calibrate(&out).unwrap();
    let dead = dead_pid();
    let mut live = Command::new("sleep").arg("30").spawn().unwrap();
    let dead_staging = tmp.path().join(format!(".out.pdcal-staging-{dead}"));
    let live_staging = tmp.path().join(format!(".out.pdcal-staging-{}", live.id()));
    for dir in [&dead_staging, &live_staging] {
        fs::create_dir(dir).unwrap();
        fs::write(dir.join("estimates.csv"), "t_s\n1.0\n").unwrap();
    }
    calibrate(&out).unwrap();
    assert!(
        !dead_staging.exists(),
        "a dead run's staging directory is removed"
    );
    assert!(
        live_staging.exists(),
        "a live run's staging directory is kept"
    );
    live.kill().unwrap();
    live.wait().unwrap();
    fs::remove_dir_all(&live_staging).unwrap();

    // A kill between the two renames of the fallback swap leaves OUT missing and the old
    // output aside: the next run puts it back before deciding anything.
    let aside = tmp.path().join(format!(".out.pdcal-old-{}", dead_pid()));
    fs::rename(&out, &aside).unwrap();
    let old = complete_output(&aside).unwrap();
    let err = calibrate_from(&tmp.path().join("no-such-set"), &out).unwrap_err();
    assert!(format!("{err:#}").contains("no-such-set"), "{err:#}");
    assert_eq!(
        complete_output(&out).unwrap(),
        old,
        "the old output is back"
    );
    assert_eq!(siblings(tmp.path(), "out"), Vec::<String>::new());
}

#[test]
fn evaluate_writes_only_into_a_pdcal_output_and_lists_what_it_adds() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    calibrate(&out).unwrap();
    pdcal::evaluate::run_dir(short_dataset(), &out).unwrap();
    let manifest = complete_output(&out).unwrap();
    assert!(manifest.files.iter().any(|f| f.name == "evaluation.json"));
    // A copy of the outputs without the manifest is not pdcal's to write into.
    let copy = tmp.path().join("copy");
    fs::create_dir(&copy).unwrap();
    for name in ["calibration.ron", "estimates.csv"] {
        fs::copy(out.join(name), copy.join(name)).unwrap();
    }
    let err = pdcal::evaluate::run_dir(short_dataset(), &copy).unwrap_err();
    assert_eq!(
        format!("{err:#}"),
        format!(
            "{}: not a pdcal output (no .pdcal-manifest.json); run pdcal calibrate into it first",
            copy.display()
        )
    );
    assert!(!copy.join("evaluation.json").exists());
}

#[test]
fn a_full_disk_names_the_file() {
    let err = pdcal::output::write_file(Path::new("/dev/full"), b"summary").unwrap_err();
    assert_eq!(
        pdcal::cli::error_text(&err),
        "cannot write /dev/full: No space left on device (os error 28)"
    );
}

/// A `pdcal calibrate` child replacing an earlier output, SIGKILLed at 200 seeded random
/// instants: after every kill OUT is a complete output (the previous one or the new one),
/// and after one more run nothing is left beside it.
#[test]
fn killed_at_200_random_instants_out_is_always_complete_old_or_new() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    // The longest of three complete runs: the other tests of this binary load the machine
    // while the kills run, and a run slower than the shortest must still be able to finish
    // before its kill in some of them.
    let full_run = (0..3)
        .map(|_| {
            let start = Instant::now();
            assert!(calibrate_child(&out, None).wait().unwrap().success());
            start.elapsed()
        })
        .max()
        .unwrap();
    let mut previous = complete_output(&out).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(14);
    let (mut kept_old, mut got_new, mut finished, mut left_siblings) = (0, 0, 0, 0);
    // Kills that left a complete output under a staging name: inside the publication
    // (before the swap: the new output; after it: the old one, not yet removed).
    let mut in_publication = 0;
    for k in 0..200 {
        // Four runs in five are killed at an instant uniform over 1.3 runs. The fifth
        // pauses 500 ms between its finished staging directory and the swap (a test-only
        // hook) and is killed at a random instant from just after its computation, so that
        // kills also land in the publication, which lasts only a few milliseconds otherwise.
        let (pause_ms, delay) = if k % 5 == 4 {
            let after = full_run.mul_f64(1.15) + Duration::from_millis(rng.random_range(0..300));
            (Some(500), after)
        } else {
            (None, full_run.mul_f64(rng.random_range(0.0..1.3)))
        };
        let mut child = calibrate_child(&out, pause_ms);
        std::thread::sleep(delay);
        let _ = child.kill();
        let status = child.wait().unwrap();
        let now = complete_output(&out)
            .unwrap_or_else(|e| panic!("kill {k} after {delay:?}: incomplete output: {e}"));
        if status.success() {
            finished += 1;
        } else if now == previous {
            kept_old += 1;
        } else {
            got_new += 1;
        }
        let left = siblings(tmp.path(), "out");
        if !left.is_empty() {
            left_siblings += 1;
        }
        if left
            .iter()
            .filter(|n| n.starts_with(".out.pdcal-staging-"))
            .any(|n| complete_output(&tmp.path().join(n)).is_ok())
        {
            in_publication += 1;
        }
        previous = now;
    }
    eprintln!(
        "200 kills (full run {full_run:?}): old output kept {kept_old}, new output complete \
         {got_new}, run finished before the kill {finished}; staging or lock left {left_siblings} \
         times, {in_publication} of them a complete output (killed inside the publication)"
    );
    assert!(
        kept_old > 0 && got_new + finished > 0,
        "kills must land on both sides"
    );
    assert!(
        left_siblings > 0,
        "some kills must leave staging or lock behind"
    );
    assert!(calibrate_child(&out, None).wait().unwrap().success());
    complete_output(&out).unwrap();
    assert_eq!(siblings(tmp.path(), "out"), Vec::<String>::new());
}
