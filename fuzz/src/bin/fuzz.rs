//! The AFL++ harness: `fuzz TARGET` takes inputs from `afl-fuzz` (or one input on stdin when
//! run alone, to replay a crash) and aborts when the reader panics or a rejection breaks one
//! of the promises of `pdcal_fuzz`. See `fuzz/README.md` for the one command that builds and
//! runs every target.
//!
//! Environment: `PDCAL_FUZZ_SCRATCH` is the directory under which the target's files are
//! written (default: `/dev/shm`, else the system's temporary directory); `PDCAL_FUZZ_QUOTES=1` also counts a
//! message quoting too much of its input as a crash.

use std::path::PathBuf;
use std::process::ExitCode;

use pdcal_fuzz::{Scratch, Target, Verdict, exercise};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let target = match args.as_slice() {
        [name] => Target::from_name(name),
        _ => None,
    };
    let Some(target) = target else {
        let names: Vec<&str> = Target::ALL.iter().map(|t| t.name()).collect();
        eprintln!("usage: fuzz TARGET, one of: {}", names.join(", "));
        return ExitCode::FAILURE;
    };
    let quotes = std::env::var_os("PDCAL_FUZZ_QUOTES").is_some_and(|v| v == "1");
    let parent = std::env::var_os("PDCAL_FUZZ_SCRATCH").map(PathBuf::from);
    // Made before the fork server starts, so that every forked child shares one directory
    // instead of leaving one per child behind.
    let scratch = match Scratch::new(parent.as_deref(), target.name()) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("fuzz: cannot create a scratch directory: {e}");
            return ExitCode::FAILURE;
        }
    };
    afl::fuzz(true, |data: &[u8]| {
        let verdict = exercise(target, data, scratch.path());
        if let Verdict::Rejected { message, problems } = &verdict {
            let broken: Vec<String> = problems
                .iter()
                .filter(|p| quotes || !p.is_long_quote())
                .map(ToString::to_string)
                .collect();
            // A panic is how the harness tells afl-fuzz that this input is a finding.
            assert!(
                broken.is_empty(),
                "{}: {message:?} breaks: {}",
                target.name(),
                broken.join("; ")
            );
        }
    });
    ExitCode::SUCCESS
}
