//! `pdcal`: simulate, calibrate and evaluate photodiode data sets (see `docs/cli-contract.md`).

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = pdcal::cli::Cli::parse();
    match pdcal::cli::run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            // One line with the whole cause chain, as the CLI contract asks.
            eprintln!("pdcal: error: {}", pdcal::cli::error_text(&error));
            ExitCode::FAILURE
        }
    }
}
