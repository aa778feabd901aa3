//! Command-line parsing and dispatch (raw arguments -> resolved commands).

use std::path::PathBuf;

use anyhow::Result;
use clap::{Parser, Subcommand};

/// On-orbit photodiode calibration. With no command: simulate the RAX-2-like scenario,
/// calibrate it, evaluate against truth and print the report.
#[derive(Debug, Parser)]
#[command(name = "pdcal", version, about)]
pub struct Cli {
    /// The command; none runs the embedded default.
    #[command(subcommand)]
    pub command: Option<Command>,
}

/// The commands of `docs/cli-contract.md`.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Simulate a scenario and write a dataset directory.
    Simulate {
        /// Built-in scenario name (rax2-like, sso-6u) or a scenario RON file.
        #[arg(long, default_value = "rax2-like")]
        scenario: String,
        /// Random seed; the same seed gives byte-identical files.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Which downlink of the seed's spacecraft: the same hardware (scale factors and
        /// mountings) as every downlink of the seed, its own noise, start attitude and gyro
        /// bias, at the scenario's own `epoch_utc`. Several downlinks of one seed, each from
        /// the scenario with a later `epoch_utc` (they must not overlap in time), are data
        /// sets for a joint calibration.
        #[arg(long, default_value_t = 0)]
        downlink: u64,
        /// Output dataset directory.
        #[arg(long)]
        out: PathBuf,
        /// Also write the figures of the simulated set (Figs. 2 and 3) into this directory.
        #[arg(long)]
        plots: Option<PathBuf>,
        /// Replace an earlier output of this command in OUT even where its files were
        /// changed since pdcal wrote them (never files pdcal did not write).
        #[arg(long)]
        force: bool,
    },
    /// Turn a ground-segment CSV export into a dataset directory, as a column map says
    /// (docs/import.md).
    Import {
        /// The export, CSV with a header row.
        source: PathBuf,
        /// The column map (RON): time form, columns and units, mounting, orbit, sentinels.
        #[arg(long, required_unless_present = "print_map_template")]
        map: Option<PathBuf>,
        /// Output dataset directory.
        #[arg(long, required_unless_present = "print_map_template")]
        out: Option<PathBuf>,
        /// Print a column map to start from, made from SOURCE's header (each column with its
        /// first value; time, gyro and magnetometer guessed from their names, every other
        /// column a commented-out photodiode entry), and import nothing.
        #[arg(long, conflicts_with_all = ["map", "out", "force"])]
        print_map_template: bool,
        /// Replace an earlier output of this command in OUT even where its files were
        /// changed since pdcal wrote them (never files pdcal did not write).
        #[arg(long)]
        force: bool,
    },
    /// Calibrate a dataset: summary.json, calibration.ron, estimates.csv, residuals.csv,
    /// figures and index.html in OUT_DIR.
    Calibrate {
        /// Dataset directories (dataset.ron, telemetry.csv): several data sets of one
        /// spacecraft (downlinks weeks apart) are calibrated as one.
        #[arg(required = true, num_args = 1..)]
        datasets: Vec<PathBuf>,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Filter configuration RON, or a previous calibration.ron as the prior of a
        /// scale-factors-only run.
        #[arg(long)]
        config: Option<PathBuf>,
        /// A magcal.ron of `pdcal magcal`: the magnetometer is corrected with it before the
        /// filter, and its uncertainty added to the magnetometer noise.
        #[arg(long)]
        mag_cal: Option<PathBuf>,
        /// With --mag-cal: how the magnetometer's rotation against the body, which the
        /// field magnitude cannot see, is found: `photodiodes` (solved against a
        /// photodiode-only calibration's attitude and removed when consistent) or `off`.
        #[arg(long, value_enum, requires = "mag_cal", default_value_t = crate::calibrate::MagAlign::Photodiodes)]
        mag_align: crate::calibrate::MagAlign,
        /// Replace an earlier output of this command in OUT even where its files were
        /// changed since pdcal wrote them (never files pdcal did not write).
        #[arg(long)]
        force: bool,
    },
    /// Compare a calibration in OUT_DIR with the dataset's truth; writes evaluation.json.
    Evaluate {
        /// Simulated dataset directory (with truth.csv and truth.ron).
        dataset: PathBuf,
        /// The calibrate command's output directory.
        out: PathBuf,
    },
    /// Calibrate the magnetometer without attitude (field magnitude against IGRF-14, hard
    /// and soft iron, current-driven biases): writes magcal.ron, magcal.json, the corrected
    /// dataset OUT/dataset/, figures and index.html.
    Magcal {
        /// Dataset directory (dataset.ron, telemetry.csv with mag_* and optional cur_*_A).
        dataset: PathBuf,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Replace an earlier output of this command in OUT even where its files were
        /// changed since pdcal wrote them (never files pdcal did not write).
        #[arg(long)]
        force: bool,
    },
    /// Find the effects the model is missing, add them, show the gap shrink: writes
    /// diagnosis.json, report.md, figures and index.html in OUT_DIR.
    Diagnose {
        /// Dataset directory (dataset.ron, telemetry.csv; truth.* only for the report).
        dataset: PathBuf,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// The model to start from: cosine (Eq. 11) or paper (Eq. 15, with albedo).
        #[arg(long, default_value = "paper", value_parser = ["cosine", "paper"])]
        base_model: String,
        /// Replace an earlier output of this command in OUT even where its files were
        /// changed since pdcal wrote them (never files pdcal did not write).
        #[arg(long)]
        force: bool,
    },
    /// Export a calibration for the onboard Sun-vector core: pdcal_calibration.h (a const
    /// pdcal_calibration and the reflectivity grid) and onboard.ron (the same values with
    /// their provenance and statuses) in OUT.
    ExportOnboard {
        /// The calibrate command's output directory.
        cal_dir: PathBuf,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Cell size of the reflectivity grid, deg (it must divide 180: 10, 5, 2.5, 1.25...).
        #[arg(long, default_value_t = crate::export_onboard::DEFAULT_GRID_DEG)]
        grid_deg: f64,
        /// The data set the calibration was made from (its noise and fields of view); by
        /// default the one summary.json names (a joint calibration's first set).
        #[arg(long)]
        dataset: Option<PathBuf>,
        /// Replace an earlier output of this command in OUT even where its files were
        /// changed since pdcal wrote them (never files pdcal did not write).
        #[arg(long)]
        force: bool,
    },
    /// Run the onboard Sun-vector core on every telemetry row with a calibration, the Earth
    /// from the calibration's attitude estimates: one CSV row per telemetry row.
    SunVector {
        /// Dataset directory (dataset.ron, telemetry.csv).
        dataset: PathBuf,
        /// The calibrate command's output directory (calibration.ron, summary.json,
        /// estimates.csv).
        #[arg(long)]
        calibration: PathBuf,
        /// Output CSV file.
        #[arg(long)]
        out: PathBuf,
        /// Cell size of the reflectivity grid, deg.
        #[arg(long, default_value_t = crate::export_onboard::DEFAULT_GRID_DEG)]
        grid_deg: f64,
    },
}

/// Where the default run writes (relative to the working directory).
pub const DEFAULT_OUT: &str = "out/rax2-like";

/// Runs one parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        None => crate::default_run::run(std::path::Path::new(DEFAULT_OUT)),
        Some(Command::Simulate {
            scenario,
            seed,
            downlink,
            out,
            plots,
            force,
        }) => {
            let scenario = crate::simulate::load_scenario(&scenario)?;
            let plots = plots
                .map(|dir| crate::output::OutputDir::create_forced(&dir, "simulate --plots", force))
                .transpose()?;
            let output = crate::simulate::run_downlink_to_dir_forced(
                &scenario, seed, downlink, &out, force,
            )?;
            if let Some(dir) = plots {
                crate::simulate::write_plots(&output, dir)?;
            }
            println!(
                "simulated {} (seed {seed}): {} samples, {} photodiodes -> {}",
                scenario.name,
                output.telemetry.len(),
                output.true_photodiodes.len(),
                pdcal_text::path(&out)
            );
            Ok(())
        }
        Some(Command::Import {
            source,
            print_map_template: true,
            ..
        }) => {
            print!("{}", crate::import::map_template(&source)?);
            Ok(())
        }
        Some(Command::Import {
            source,
            map,
            out,
            force,
            print_map_template: false,
        }) => {
            // clap requires both without --print-map-template.
            let (Some(map), Some(out)) = (map, out) else {
                anyhow::bail!("import needs --map and --out (or --print-map-template)");
            };
            let imported = crate::import::run_to_dir_forced(&source, &map, &out, force)?;
            for line in crate::import::report_lines(&imported.report) {
                println!("{line}");
            }
            println!(
                "imported {}: {} samples, {} photodiodes -> {}",
                pdcal_text::path(&source),
                imported.report.rows_kept,
                imported.meta.photodiodes.len(),
                pdcal_text::path(&out)
            );
            Ok(())
        }
        Some(Command::Calibrate {
            datasets,
            out,
            config,
            mag_cal,
            mag_align,
            force,
        }) => {
            let mut config = match config {
                Some(path) => crate::calibrate::load_config(&path)?,
                None => crate::calibrate::RunConfig::default(),
            };
            config.mag_cal = mag_cal.as_deref().map(crate::magcal::load).transpose()?;
            config.mag_cal_file = mag_cal;
            config.mag_align = mag_align;
            let (outcome, summary) =
                crate::calibrate::run_dirs_forced(&datasets, &out, &config, force)?;
            print_warnings(&summary.warnings);
            print!("{}", crate::tables::console_summary(&summary));
            eprintln!(
                "calibrated in {:.2} s -> {}",
                outcome.runtime_s,
                pdcal_text::path(&out)
            );
            Ok(())
        }
        Some(Command::Diagnose {
            dataset,
            out,
            base_model,
            force,
        }) => {
            let base: pdcal_diagnose::BaseModel = base_model.parse()?;
            let outcome = crate::diagnose::run_dir_forced(&dataset, &out, base, force)?;
            print_warnings(&outcome.warnings);
            print!("{}", crate::diagnose::console_summary(&outcome));
            eprintln!("diagnosis -> {}", pdcal_text::path(&out));
            Ok(())
        }
        Some(Command::Magcal {
            dataset,
            out,
            force,
        }) => {
            let outcome = crate::magcal::run_dir_forced(&dataset, &out, force)?;
            print_warnings(&outcome.warnings);
            let cal = &outcome.calibration;
            println!(
                "magnetometer: field-magnitude residual {:.1} nT -> {:.1} nT over {} rows ({} rejected); regressors kept: {}",
                cal.residual_rms_before_nt,
                cal.residual_rms_after_nt,
                cal.rows_used,
                cal.rejected_rows.len(),
                if cal.regressors.is_empty() {
                    "none".to_owned()
                } else {
                    cal.regressors.join(", ")
                }
            );
            eprintln!("magcal -> {}", pdcal_text::path(&out));
            Ok(())
        }
        Some(Command::ExportOnboard {
            cal_dir,
            out,
            grid_deg,
            dataset,
            force,
        }) => {
            let export = crate::export_onboard::run_to_dir(
                &cal_dir,
                dataset.as_deref(),
                grid_deg,
                &out,
                force,
            )?;
            let disabled = export.photodiodes.iter().filter(|p| !p.enabled).count();
            let nominal = export
                .photodiodes
                .iter()
                .flat_map(|p| &p.status)
                .filter(|s| s.nominal && s.parameter != "dark")
                .count();
            println!(
                "exported {} photodiodes ({disabled} disabled, {nominal} parameters at their nominal value), grid {} x {} ({} bytes) -> {}",
                export.photodiodes.len(),
                export.grid.n_lat,
                export.grid.n_lon,
                export.grid.bytes,
                out.display()
            );
            Ok(())
        }
        Some(Command::SunVector {
            dataset,
            calibration,
            out,
            grid_deg,
        }) => {
            let rows = crate::onboard_sun::run_to_file(&dataset, &calibration, grid_deg, &out)?;
            let valid = rows
                .iter()
                .filter(|r| r.validity == pdcal_onboard::Validity::Valid)
                .count();
            println!(
                "sun-vector: {} rows, {valid} valid -> {}",
                rows.len(),
                out.display()
            );
            Ok(())
        }
        Some(Command::Evaluate { dataset, out }) => {
            let evaluation = crate::evaluate::run_dir(&dataset, &out)?;
            println!("{}", serde_json::to_string_pretty(&evaluation)?);
            Ok(())
        }
    }
}

/// Warnings on stderr, one line each, after the run (they are also in the output files).
fn print_warnings(warnings: &[String]) {
    for w in warnings {
        eprintln!("pdcal: warning: {w}");
    }
}

/// The one-line message of an error: its causes joined by `: `, each said once. Library
/// errors that both print their inner error and return it as `source` (`"filter: {0}"`
/// with `#[from]`) would otherwise repeat it in the chain.
pub fn error_text(error: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in error.chain() {
        let cause = cause.to_string();
        if text.contains(&cause) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&cause);
    }
    text
}
