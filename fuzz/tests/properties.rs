//! The property-test twin of every fuzz target: seeded mutations of the seed files
//! (`pdcal_fuzz::mutate`) through the same readers and checks as the AFL++ harness, a few
//! thousand cases per target inside `cargo test`.
//!
//! `PDCAL_PROPTEST_CASES` changes the number of cases per target and `PDCAL_PROPTEST_SEED`
//! the seed (a failure report names both, and writes the failing inputs to a directory it
//! names, ready for `fuzz TARGET < FILE`).

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;

use pdcal_fuzz::mutate::{Mutation, Rng, mutate};
use pdcal_fuzz::{Problem, Scratch, Target, Verdict, exercise};

const DEFAULT_CASES: usize = 2500;
const DEFAULT_SEED: u64 = 0x7064_6361_6c14;

fn env_number(name: &str) -> Option<u64> {
    std::env::var(name).ok().and_then(|v| v.trim().parse().ok())
}

/// Which promises a run holds the readers to.
#[derive(Clone, Copy, PartialEq)]
enum Promises {
    /// No panic; the file named; a line and column where line-based.
    Placement,
    /// At most `pdcal_fuzz::QUOTE_LIMIT` input characters repeated in a message.
    Quoting,
}

struct Failure {
    case: usize,
    mutations: Vec<Mutation>,
    what: String,
    file: PathBuf,
}

struct Tally {
    accepted: usize,
    rejected: usize,
    failures: Vec<Failure>,
}

fn run(target: Target, promises: Promises) -> Tally {
    let cases = env_number("PDCAL_PROPTEST_CASES").map_or(DEFAULT_CASES, |n| n as usize);
    let seed = env_number("PDCAL_PROPTEST_SEED").unwrap_or(DEFAULT_SEED);
    let tag = format!("prop-{}-{}", target.name(), promises as u8);
    let scratch = Scratch::new(None, &tag).expect("scratch directory");
    let failed_dir = std::env::temp_dir().join(format!("pdcal-proptest-failures-{seed}"));
    let seeds = target.seeds();
    // One stream per target, so adding a target does not change another's cases.
    let salt = target
        .name()
        .bytes()
        .fold(0u64, |h, b| h.rotate_left(5) ^ u64::from(b));
    let mut rng = Rng::new(seed ^ salt);
    let mut tally = Tally {
        accepted: 0,
        rejected: 0,
        failures: Vec::new(),
    };
    for case in 0..cases {
        let base = *rng.pick(&seeds);
        let (input, mutations) = mutate(target, base, &mut rng);
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            exercise(target, &input, scratch.path())
        }));
        let what = match outcome {
            Err(panic) => {
                let text = panic
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_owned()))
                    .unwrap_or_default();
                Some(format!("panicked: {text}"))
            }
            Ok(Verdict::Accepted) => {
                tally.accepted += 1;
                None
            }
            Ok(Verdict::Rejected { message, problems }) => {
                tally.rejected += 1;
                let broken: Vec<String> = problems
                    .iter()
                    .filter(|p| p.is_long_quote() == (promises == Promises::Quoting))
                    .map(Problem::to_string)
                    .collect();
                (!broken.is_empty()).then(|| {
                    let shown: String = message.chars().take(300).collect();
                    format!("{}: {shown:?}", broken.join("; "))
                })
            }
        };
        if let Some(what) = what {
            let file = failed_dir.join(format!("{}-{case}", target.name()));
            let _ = std::fs::create_dir_all(&failed_dir);
            let _ = std::fs::write(&file, &input);
            tally.failures.push(Failure {
                case,
                mutations,
                what,
                file,
            });
        }
    }
    tally
}

fn assert_holds(target: Target, promises: Promises) {
    let tally = run(target, promises);
    let total = tally.accepted + tally.rejected + tally.failures.len();
    // The mutations must reach the error paths, and some must leave a readable file, or the
    // run proves little.
    assert!(
        tally.rejected * 2 > total,
        "{}: only {} of {total} cases rejected",
        target.name(),
        tally.rejected
    );
    let report: Vec<String> = tally
        .failures
        .iter()
        .take(8)
        .map(|f| {
            format!(
                "case {} {:?}: {} (input: {})",
                f.case,
                f.mutations,
                f.what,
                f.file.display()
            )
        })
        .collect();
    assert!(
        tally.failures.is_empty(),
        "{}: {} of {total} cases fail (seed {}):\n{}",
        target.name(),
        tally.failures.len(),
        env_number("PDCAL_PROPTEST_SEED").unwrap_or(DEFAULT_SEED),
        report.join("\n")
    );
}

#[test]
fn seeds_are_accepted() {
    for target in Target::ALL {
        let scratch = Scratch::new(None, &format!("seeds-{}", target.name())).unwrap();
        for (i, seed) in target.seeds().into_iter().enumerate() {
            let verdict = exercise(target, seed, scratch.path());
            assert!(
                matches!(verdict, Verdict::Accepted),
                "{} seed {i}: {verdict:?}",
                target.name()
            );
        }
    }
}

#[test]
fn hostile_inputs_are_refused_keeping_the_promises() {
    for target in Target::ALL {
        let scratch = Scratch::new(None, &format!("hostile-{}", target.name())).unwrap();
        for (i, input) in target.hostile().into_iter().enumerate() {
            let verdict = exercise(target, input, scratch.path());
            assert!(
                matches!(&verdict, Verdict::Rejected { problems, .. } if problems.is_empty()),
                "{} hostile input {i}: {verdict:?}",
                target.name()
            );
        }
    }
}

#[test]
fn dataset_pair_never_panics_and_places_errors() {
    assert_holds(Target::DatasetPair, Promises::Placement);
}

#[test]
fn dataset_ron_never_panics_and_places_errors() {
    assert_holds(Target::DatasetRon, Promises::Placement);
}

#[test]
fn telemetry_csv_never_panics_and_places_errors() {
    assert_holds(Target::TelemetryCsv, Promises::Placement);
}

#[test]
fn truth_csv_never_panics_and_places_errors() {
    assert_holds(Target::TruthCsv, Promises::Placement);
}

#[test]
fn scenario_ron_never_panics_and_places_errors() {
    assert_holds(Target::ScenarioRon, Promises::Placement);
}

#[test]
fn config_ron_never_panics_and_places_errors() {
    assert_holds(Target::ConfigRon, Promises::Placement);
}

#[test]
fn import_map_never_panics_and_places_errors() {
    assert_holds(Target::ImportMap, Promises::Placement);
}

#[test]
fn joint_sets_never_panic_and_place_errors() {
    assert_holds(Target::JointSets, Promises::Placement);
}

// Quoting: one test per target, so that a failure names its reader.
#[test]
fn dataset_pair_errors_quote_at_most_the_limit() {
    assert_holds(Target::DatasetPair, Promises::Quoting);
}

#[test]
fn dataset_ron_errors_quote_at_most_the_limit() {
    assert_holds(Target::DatasetRon, Promises::Quoting);
}

#[test]
fn telemetry_csv_errors_quote_at_most_the_limit() {
    assert_holds(Target::TelemetryCsv, Promises::Quoting);
}

#[test]
fn truth_csv_errors_quote_at_most_the_limit() {
    assert_holds(Target::TruthCsv, Promises::Quoting);
}

#[test]
fn import_map_errors_quote_at_most_the_limit() {
    assert_holds(Target::ImportMap, Promises::Quoting);
}

#[test]
fn joint_sets_errors_quote_at_most_the_limit() {
    assert_holds(Target::JointSets, Promises::Quoting);
}

#[test]
fn scenario_ron_errors_quote_at_most_the_limit() {
    assert_holds(Target::ScenarioRon, Promises::Quoting);
}

#[test]
fn magcal_ron_never_panics_and_places_errors() {
    assert_holds(Target::MagcalRon, Promises::Placement);
}

#[test]
fn magcal_ron_errors_quote_at_most_the_limit() {
    assert_holds(Target::MagcalRon, Promises::Quoting);
}

#[test]
fn config_ron_errors_quote_at_most_the_limit() {
    assert_holds(Target::ConfigRon, Promises::Quoting);
}
