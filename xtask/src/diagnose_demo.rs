//! `cargo xtask diagnose-demo`: the whole diagnosis story on the default scenario.
//!
//! Simulates rax2-like with two effects hidden from the `cosine` base model (albedo, the
//! paper's Fig. 10, and a dark offset per photodiode; the scenario's penumbra is switched
//! off so that exactly these two are hidden), runs `pdcal diagnose` on the written
//! dataset, prints the rounds and gaps against what was hidden, and leaves the dataset and
//! the diagnosis under `out/diagnose-demo/`.

use std::path::Path;
use std::time::Instant;

use anyhow::{Result, ensure};
use pdcal_dataset::{Effect, EffectId};
use pdcal_diagnose::BaseModel;

/// Seed of the demo.
const SEED: u64 = 1;

/// Dark offsets, V: 10-40 mV, different per photodiode (ADC offsets of a few LSB plus
/// dark current), about 1-3 photodiode sigmas.
fn dark_offsets(n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| 0.010 + 0.030 * ((i * 7) % n) as f64 / n as f64)
        .collect()
}

/// Runs the demo into `root`.
pub fn run(root: &Path) -> Result<()> {
    let start = Instant::now();
    let mut scenario = pdcal_sim::Scenario::rax2_like()?;
    let offsets = dark_offsets(scenario.n_photodiodes());
    scenario.effects = vec![
        Effect::Albedo {
            map: "toms-mean-1p25x1".into(),
        },
        Effect::DarkOffset {
            volts: offsets.clone(),
        },
    ];
    let dataset = root.join("dataset");
    let out = root.join("diagnosis");
    pdcal::simulate::run_to_dir(&scenario, SEED, &dataset)?;
    println!(
        "simulated {} (seed {SEED}, {:.0} min) with albedo and dark offsets {:.3}..{:.3} V hidden \
         from the cosine base model -> {}",
        scenario.name,
        scenario.duration_s / 60.0,
        offsets.iter().cloned().fold(f64::INFINITY, f64::min),
        offsets.iter().cloned().fold(f64::NEG_INFINITY, f64::max),
        dataset.display()
    );
    let outcome = pdcal::diagnose::run_dir(&dataset, &out, BaseModel::Cosine)?;
    print!("{}", pdcal::diagnose::console_summary(&outcome));
    let d = &outcome.diagnosis;
    print_true_errors(&dataset, d);
    for effect in &d.final_spec.added {
        if let Effect::DarkOffset { volts } = effect {
            let worst = volts
                .iter()
                .zip(&offsets)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            println!(
                "  dark offsets recovered to within {:.4} V of the truth",
                worst
            );
        }
    }
    println!(
        "outputs: {}/diagnosis.json, report.md, index.html; total {:.1} s",
        out.display(),
        start.elapsed().as_secs_f64()
    );
    let found: Vec<EffectId> = d.rounds.iter().map(|r| r.found).collect();
    ensure!(
        found.contains(&EffectId::Albedo) && found.contains(&EffectId::DarkOffset),
        "the demo expected albedo and dark-offset, found {found:?}"
    );
    Ok(())
}

/// The true calibration errors before and after each round, through `evaluate`'s code,
/// after the diagnosis has decided; a truth of another layout is a warning, never an error.
fn print_true_errors(dataset: &Path, d: &pdcal_diagnose::Diagnosis) {
    let truth = pdcal_dataset::read_meta(dataset)
        .and_then(|meta| pdcal_dataset::read_truth(dataset, &meta));
    let (series, constants) = match truth {
        Ok(Some(t)) => t,
        Ok(None) => return,
        Err(e) => {
            eprintln!("warning: true errors not shown: {e}");
            return;
        }
    };
    if constants.photodiodes.len() != d.final_run.calibration.photodiodes.len() {
        eprintln!("warning: true errors not shown: truth.ron's photodiodes differ in number");
        return;
    }
    let worst = |c: &pdcal_filter::Calibration| {
        let (_, normal, scale) = pdcal::evaluate::photodiode_errors(c, &series, &constants);
        format!("worst normal {normal:.2} deg, worst scale {scale:.2} %")
    };
    for (n, r) in d.rounds.iter().enumerate() {
        println!(
            "  round {} true errors: before {}; after {}",
            n + 1,
            worst(&r.calibration_before),
            worst(&r.calibration_after)
        );
    }
}
