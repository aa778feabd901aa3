//! Developer tasks, run as `cargo xtask <task>` (alias in `.cargo/config.toml`).
//!
//! - `sim-calibrate [--seeds N] [--scenario NAME]`: Monte Carlo over seeds of simulate ->
//!   calibrate -> evaluate, in parallel, with a progress bar; prints the accuracy table and
//!   writes it to `out/sim-calibrate/<scenario>/`.
//! - `diagnose-demo`: simulates rax2-like with albedo and dark offsets hidden, diagnoses
//!   it from the `cosine` base, prints the rounds and gaps; outputs in `out/diagnose-demo/`.
//! - `magcal-validate [--seeds N] [--scenario FILE] [--duration-s S] [--every-s S]`: the
//!   magnetometer calibration over seeds against the simulator's truth (docs/magcal.md);
//!   `--export DIR` writes each seed's samples, truth and estimate for `tools/magyc_compare.py`.
//! - `onboard-validate [--seeds N] [--scenario NAME]`: the onboard Sun-vector core against
//!   the truth over seeds, beside the same core without the Earth and `cssWlsEst`
//!   (docs/validation.md, "Onboard Sun vector"); work files in `out/onboard-validate/`.
//! - `bench`: runs the criterion benches that `docs/performance.md` quotes.
//! - `make-import-fixture`: rewrites `fixtures/import/` (export.csv and its maps) from the
//!   simulator, seeded (`xtask::import_fixture`).

mod axes_validate;
mod diagnose_demo;
mod magcal_validate;
mod monte_carlo;
mod onboard_validate;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Debug, Parser)]
#[command(name = "xtask", about = "pdcal developer tasks")]
struct Cli {
    #[command(subcommand)]
    task: Task,
}

#[derive(Debug, Subcommand)]
enum Task {
    /// Monte Carlo over seeds: simulate, calibrate, evaluate; the accuracy table.
    SimCalibrate {
        /// Number of seeds (1..=N).
        #[arg(long, default_value_t = 20)]
        seeds: u64,
        /// Built-in scenario name or RON file.
        #[arg(long, default_value = "rax2-like")]
        scenario: String,
        /// Run the filter without the magnetometer (photodiode-only mode).
        #[arg(long)]
        photodiode_only: bool,
        /// Filter configuration RON (as `pdcal calibrate --config`).
        #[arg(long)]
        config: Option<std::path::PathBuf>,
        /// Keep only passes of the telemetry: `passes:ON/PERIOD` (seconds), at a phase
        /// drawn from each seed.
        #[arg(long)]
        cut: Option<monte_carlo::Cut>,
        /// Calibrate this many data sets of the same spacecraft (the same seed), a month
        /// apart, jointly; the table compares with the best set calibrated alone.
        #[arg(long, default_value_t = 1)]
        sets: usize,
        /// Calibrate each seed's magnetometer from its own data first (`pdcal magcal`) and
        /// calibrate the photodiodes with it applied (`--mag-cal`).
        #[arg(long)]
        magcal: bool,
        /// With `--magcal`: passes of the magnetometer's rotation against the calibrated
        /// attitude, each followed by a calibration again (docs/magcal.md).
        #[arg(long, default_value_t = 0)]
        mag_align_passes: usize,
        /// With `--magcal`: leave the magnetometer's rotation against the body as the
        /// magnitude fit gives it (by default it is solved against a photodiode-only
        /// calibration's attitude and removed, docs/magcal.md).
        #[arg(long)]
        no_mag_align: bool,
        /// A seed that ends with an error is listed under the table (with the error)
        /// instead of stopping the run: for weak-data scenarios whose filter may fail.
        #[arg(long)]
        keep_going: bool,
    },
    /// The sensor-axes check on simulated data: every wrong signed permutation of the
    /// gyro, the magnetometer and the photodiode table, and false findings on clean data.
    AxesValidate {
        /// Built-in scenario name or RON file.
        #[arg(long, default_value = "rax2-like")]
        scenario: String,
        /// Clean seeds (1..=N), each full, photodiode-only and cut into passes.
        #[arg(long, default_value_t = 30)]
        clean_seeds: u64,
        /// Seeds (1..=N) with each of the 141 wrong permutations.
        #[arg(long, default_value_t = 3)]
        permuted_seeds: u64,
    },
    /// Magnetometer calibration over seeds against the simulator's truth (docs/magcal.md):
    /// parameters within 3 sigma, residual against the noise, regressors kept and missed.
    MagcalValidate {
        /// Number of seeds (1..=N).
        #[arg(long, default_value_t = 20)]
        seeds: u64,
        /// Scenario RON file (with magnetometer errors and currents).
        #[arg(long, default_value = "fixtures/scenarios/magcal/rax2-like-magcal.ron")]
        scenario: String,
        /// Override the scenario's duration, s.
        #[arg(long)]
        duration_s: Option<f64>,
        /// Keep one row every this many seconds (sparse data).
        #[arg(long)]
        every_s: Option<f64>,
        /// Also write each seed's samples, truth and estimate to this directory
        /// (`seed-N.csv`, `seed-N.json`) for `tools/magyc_compare.py`.
        #[arg(long)]
        export: Option<std::path::PathBuf>,
    },
    /// The onboard Sun-vector core against the truth over seeds: simulate, calibrate,
    /// `pdcal sun-vector`, beside the core without the Earth and `cssWlsEst`.
    OnboardValidate {
        /// Number of seeds (1..=N).
        #[arg(long, default_value_t = 20)]
        seeds: u64,
        /// Built-in scenario name or RON file.
        #[arg(long, default_value = "rax2-like")]
        scenario: String,
    },
    /// Simulate rax2-like with albedo and dark offsets hidden, diagnose from `cosine`.
    DiagnoseDemo,
    /// Run the criterion benches quoted in docs/performance.md.
    Bench,
    /// Rewrite fixtures/import/ (export.csv, map.ron, map-positions.ron) from the simulator.
    MakeImportFixture,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.task {
        Task::SimCalibrate {
            seeds,
            scenario,
            photodiode_only,
            config,
            cut,
            sets,
            magcal,
            mag_align_passes,
            no_mag_align,
            keep_going,
        } => monte_carlo::run(
            seeds,
            &scenario,
            photodiode_only,
            config.as_deref(),
            (cut, sets),
            (magcal, mag_align_passes, no_mag_align),
            keep_going,
        ),
        Task::MagcalValidate {
            seeds,
            scenario,
            duration_s,
            every_s,
            export,
        } => magcal_validate::run(seeds, &scenario, duration_s, every_s, export.as_deref()),
        Task::AxesValidate {
            scenario,
            clean_seeds,
            permuted_seeds,
        } => axes_validate::run(&scenario, clean_seeds, permuted_seeds),
        Task::OnboardValidate { seeds, scenario } => onboard_validate::run(seeds, &scenario),
        Task::DiagnoseDemo => diagnose_demo::run(std::path::Path::new("out/diagnose-demo")),
        Task::Bench => bench(),
        Task::MakeImportFixture => make_import_fixture(),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn bench() -> anyhow::Result<()> {
    let benches = [
        ("pdcal-albedo", "albedo"),
        ("pdcal-sim", "simulate"),
        ("pdcal-filter", "ekf"),
    ];
    for (package, bench) in benches {
        let status = std::process::Command::new(env!("CARGO"))
            .args(["bench", "-p", package, "--bench", bench])
            .status()?;
        anyhow::ensure!(
            status.success(),
            "cargo bench -p {package} --bench {bench} failed"
        );
    }
    Ok(())
}

fn make_import_fixture() -> anyhow::Result<()> {
    // The workspace root, so the task writes the same place from any working directory.
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/import");
    let fixture = xtask::import_fixture::write(&dir)?;
    println!(
        "wrote {} ({} bytes export, {} data rows of {} simulated)",
        dir.display(),
        fixture.export_csv.len(),
        fixture.export_csv.lines().count() - 1,
        fixture.sim.telemetry.len()
    );
    Ok(())
}
