//! `pdcal simulate`: a scenario in, a dataset directory out.

use std::path::Path;

use anyhow::{Context, Result};
use pdcal_sim::{Scenario, SimOutput};

/// The scenario named by `--scenario`: a built-in name or a RON file.
pub fn load_scenario(name_or_file: &str) -> Result<Scenario> {
    let path = Path::new(name_or_file);
    if path.extension().is_some_and(|e| e == "ron") {
        let text =
            pdcal_dataset::bounded::read_text_bounded(path, pdcal_dataset::bounded::MAX_RON_BYTES)
                .with_context(|| format!("cannot read {}", pdcal_text::path(path)))?;
        Scenario::from_ron_str(&text).with_context(|| pdcal_text::path(path).to_string())
    } else {
        Scenario::builtin(name_or_file).with_context(|| format!("scenario {name_or_file:?}"))
    }
}

/// Simulates `scenario` with `seed` in memory.
pub fn run(scenario: &Scenario, seed: u64) -> Result<SimOutput> {
    run_downlink(scenario, seed, 0)
}

/// Simulates downlink `downlink` of the spacecraft of `seed` in memory: the seed's hardware,
/// the downlink's own noise, start attitude and gyro bias.
pub fn run_downlink(scenario: &Scenario, seed: u64, downlink: u64) -> Result<SimOutput> {
    pdcal_sim::simulate_downlink(scenario, seed, downlink)
        .with_context(|| format!("simulating {}", scenario.name))
}

/// Simulates and writes the dataset directory (whole or not at all); `out` is checked and
/// locked before the simulation.
pub fn run_to_dir(scenario: &Scenario, seed: u64, out: &Path) -> Result<SimOutput> {
    run_downlink_to_dir(scenario, seed, 0, out)
}

/// [`run_to_dir`] for downlink `downlink` of the seed ([`run_downlink`]).
pub fn run_downlink_to_dir(
    scenario: &Scenario,
    seed: u64,
    downlink: u64,
    out: &Path,
) -> Result<SimOutput> {
    run_downlink_to_dir_forced(scenario, seed, downlink, out, false)
}

/// [`run_downlink_to_dir`]; with `force`, an earlier simulation in `out` is replaced even
/// when its files were changed since (`--force`).
pub fn run_downlink_to_dir_forced(
    scenario: &Scenario,
    seed: u64,
    downlink: u64,
    out: &Path,
    force: bool,
) -> Result<SimOutput> {
    let writer = pdcal_dataset::begin_dataset_as(out, "simulate", force)?;
    let output = run_downlink(scenario, seed, downlink)?;
    writer.write(&output.to_dataset())?;
    Ok(output)
}

/// Figures of a simulated set, after the paper's Figs. 2 and 3: the raw photodiode outputs
/// over time and the true Sun directions in the body frame (sunlit samples), written whole
/// into `staging` (a directory of its own, so the dataset directory stays a pure dataset).
pub fn write_plots(output: &SimOutput, staging: crate::output::OutputDir) -> Result<()> {
    let telemetry = &output.telemetry;
    let title = format!(
        "Raw photodiode outputs, {} (seed {})",
        output.meta.name, output.seed
    );
    let pages = crate::figures::raw_outputs_figure(staging.path(), telemetry, &title)?;
    let sunlit: Vec<[f64; 3]> = output
        .truth
        .sun_body
        .iter()
        .zip(&output.truth.eclipse)
        .filter(|(_, e)| **e > 0.5)
        .map(|(s, _)| [s.x, s.y, s.z])
        .collect();
    let figure = pdcal_report::Figure::new(
        "fig03_sun_directions",
        "True Sun directions in the body frame (sunlit samples)",
    );
    let set = pdcal_report::DirectionSet {
        name: "Sun direction",
        dirs_body: &sunlit,
    };
    pdcal_report::sphere_directions(staging.path(), &figure, &[set])?;
    let mut captions: Vec<(String, String)> = pages
        .into_iter()
        .map(|(stem, which)| (format!("Fig. 2: raw photodiode outputs{which}"), stem))
        .collect();
    captions.push((
        "Fig. 3: true Sun directions, body frame".to_owned(),
        "fig03_sun_directions".to_owned(),
    ));
    let figures: Vec<(&str, &str)> = captions
        .iter()
        .map(|(caption, stem)| (caption.as_str(), stem.as_str()))
        .collect();
    let rows = [
        ("samples", telemetry.len().to_string()),
        ("photodiodes", telemetry.pd_v.len().to_string()),
    ];
    pdcal_report::index_html(staging.path(), &output.meta.name, &rows, &figures)?;
    staging.commit()
}
