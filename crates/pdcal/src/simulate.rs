//! `pdcal simulate`: a scenario in, a dataset directory out.

use std::path::Path;

use anyhow::{Context, Result};
use pdcal_sim::{Scenario, SimOutput};

/// The scenario named by `--scenario`: a built-in name or a RON file.
pub fn load_scenario(name_or_file: &str) -> Result<Scenario> {
    let path = Path::new(name_or_file);
    if path.extension().is_some_and(|e| e == "ron") {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        Scenario::from_ron_str(&text).with_context(|| format!("{}", path.display()))
    } else {
        Scenario::builtin(name_or_file).with_context(|| format!("scenario {name_or_file:?}"))
    }
}

/// Simulates `scenario` with `seed` in memory.
pub fn run(scenario: &Scenario, seed: u64) -> Result<SimOutput> {
    pdcal_sim::simulate(scenario, seed).with_context(|| format!("simulating {}", scenario.name))
}

/// Simulates and writes the dataset directory (whole or not at all).
pub fn run_to_dir(scenario: &Scenario, seed: u64, out: &Path) -> Result<SimOutput> {
    let output = run(scenario, seed)?;
    pdcal_dataset::write_dataset(out, &output.to_dataset())?;
    Ok(output)
}
