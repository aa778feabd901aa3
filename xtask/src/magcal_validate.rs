//! The magnetometer calibration over seeds against the simulator's truth (docs/magcal.md,
//! docs/validation.md): every estimated parameter against its truth in sigmas, the
//! field-magnitude residual against what the noise alone gives, the regressors kept, missed
//! and falsely kept.

use std::fmt::Write;

use std::path::Path;

use anyhow::{Context, Result, bail};
use nalgebra::{Matrix3, Vector3};
use pdcal_magcal::MatrixForm;
use rayon::prelude::*;

/// One seed's comparison.
struct SeedCheck {
    seed: u64,
    rows: usize,
    rejected: usize,
    before_nt: f64,
    after_nt: f64,
    noise_only_nt: f64,
    z: Vec<f64>,
    kept: Vec<String>,
    missed: Vec<String>,
    false_kept: Vec<String>,
    form: MatrixForm,
}

/// Runs seeds `1..=n` of `scenario_name` and prints the table.
pub fn run(
    n: u64,
    scenario_name: &str,
    duration_s: Option<f64>,
    every_s: Option<f64>,
    export: Option<&Path>,
) -> Result<()> {
    let mut scenario = pdcal::simulate::load_scenario(scenario_name)?;
    if let Some(d) = duration_s {
        scenario.duration_s = d;
    }
    if let Some(dir) = export {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let checks: Vec<SeedCheck> = (1..=n)
        .into_par_iter()
        .map(|seed| {
            check_seed(&scenario, seed, every_s, export).with_context(|| format!("seed {seed}"))
        })
        .collect::<Result<_>>()?;
    print!(
        "{}",
        table(
            &scenario.name,
            duration_s.unwrap_or(scenario.duration_s),
            every_s,
            &checks
        )
    );
    Ok(())
}

fn check_seed(
    scenario: &pdcal_sim::Scenario,
    seed: u64,
    every_s: Option<f64>,
    export: Option<&Path>,
) -> Result<SeedCheck> {
    let sim = pdcal::simulate::run_downlink(scenario, seed, 0)?;
    let Some(truth) = sim.constants.magnetometer.clone() else {
        bail!("the scenario has no magnetometer errors (magnetometer.errors)");
    };
    let t_s = &sim.telemetry.t_s;
    let telemetry = match every_s {
        Some(e) => sim.telemetry.select_rows(|k| {
            let x = t_s[k] / e;
            (x - x.round()).abs() < 1e-9
        }),
        None => sim.telemetry.clone(),
    };
    let outcome = pdcal::magcal::run(&sim.meta, &telemetry)?;
    let cal = &outcome.calibration;
    let t = Matrix3::from_fn(|a, b| truth.matrix[a][b]);
    let (s, _) = pdcal_magcal::align::polar(&t).context("singular truth")?;
    if let Some(dir) = export {
        let sigma = scenario.magnetometer.noise_nt;
        write_export(dir, seed, &outcome, &truth, &s, sigma)?;
    }
    let mut z = Vec::new();
    let ts = cal.matrix_sigma();
    let entries: &[(usize, usize)] = match cal.params.form {
        MatrixForm::Symmetric => &[(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)],
        MatrixForm::Diagonal | MatrixForm::Scalar => &[(0, 0), (1, 1), (2, 2)],
    };
    for &(a, b) in entries {
        z.push((cal.matrix[(a, b)] - s[(a, b)]) / ts[(a, b)]);
    }
    let bs = cal.bias_sigma_nt();
    z.extend((0..3).map(|a| (cal.params.bias_nt[a] - truth.bias_nt[a]) / bs[a]));
    let true_c = |name: &str| {
        (truth.current_bias_nt_per_a.iter())
            .find(|(n, _)| n == name)
            .map(|(_, c)| Vector3::from(*c))
    };
    let mut false_kept = Vec::new();
    for ((name, c), sigma) in cal
        .regressors
        .iter()
        .zip(&cal.params.coeff_nt)
        .zip(cal.coeff_sigma_nt())
    {
        let truth_c = true_c(name).unwrap_or_else(|| {
            false_kept.push(name.clone());
            Vector3::zeros()
        });
        z.extend((0..3).map(|a| (c[a] - truth_c[a]) / sigma[a]));
    }
    let missed = (truth.current_bias_nt_per_a.iter())
        .filter(|(n, _)| !cal.regressors.contains(n))
        .map(|(n, _)| n.clone())
        .collect();
    // The magnitude residual of the noise alone: sigma * sqrt(mean g^T P P g), P = S^-1 and
    // g the corrected true field's direction.
    let p = s.try_inverse().context("singular truth")?;
    let sigma = scenario.magnetometer.noise_nt;
    let mean_var = (sim.truth.mag_body_nt.iter())
        .map(|b| (p * (p * t * b).normalize()).norm_squared())
        .sum::<f64>()
        / sim.truth.mag_body_nt.len().max(1) as f64;
    Ok(SeedCheck {
        seed,
        rows: cal.rows_used,
        rejected: cal.rejected_rows.len(),
        before_nt: cal.residual_rms_before_nt,
        after_nt: cal.residual_rms_after_nt,
        noise_only_nt: sigma * mean_var.sqrt(),
        z,
        kept: cal.regressors.clone(),
        missed,
        false_kept,
        form: cal.params.form,
    })
}

/// For a check outside pdcal (`tools/magyc_compare.py`): `seed-N.csv`, the samples the fit
/// used (raw magnetometer, the IGRF-14 magnitude along the orbit, every current column),
/// and `seed-N.json`, the truth (`T`, its symmetric form, `b`, `c_j`), pdcal's estimate and
/// the noise.
fn write_export(
    dir: &Path,
    seed: u64,
    outcome: &pdcal::magcal::MagCalOutcome,
    truth: &pdcal_dataset::TrueMagnetometer,
    symmetric: &Matrix3<f64>,
    noise_nt: f64,
) -> Result<()> {
    let mut csv = String::from("row,t_s,mag_x_nT,mag_y_nT,mag_z_nT,field_nT");
    for name in &outcome.names {
        let _ = write!(csv, ",{name}");
    }
    csv.push('\n');
    for sample in &outcome.samples {
        let m = sample.mag_nt;
        let _ = write!(
            csv,
            "{},{},{},{},{},{}",
            sample.row, sample.t_s, m.x, m.y, m.z, sample.field_nt
        );
        for u in &sample.u {
            let _ = write!(csv, ",{u}");
        }
        csv.push('\n');
    }
    let cal = &outcome.calibration;
    let rows = |m: &Matrix3<f64>| [0, 1, 2].map(|a| [0, 1, 2].map(|b| m[(a, b)]));
    let estimate_c: serde_json::Map<String, serde_json::Value> = (cal.regressors.iter())
        .zip(&cal.params.coeff_nt)
        .map(|(n, c)| (n.clone(), serde_json::json!([c.x, c.y, c.z])))
        .collect();
    let json = serde_json::json!({
        "seed": seed,
        "noise_nT": noise_nt,
        "truth": {
            "matrix": truth.matrix,
            "symmetric_matrix": rows(symmetric),
            "bias_nT": truth.bias_nt,
            "current_bias_nT_per_A": truth.current_bias_nt_per_a.iter().cloned().collect::<std::collections::BTreeMap<_, _>>(),
        },
        "pdcal": {
            "form": format!("{:?}", cal.params.form),
            "matrix": rows(&cal.matrix),
            "bias_nT": [cal.params.bias_nt.x, cal.params.bias_nt.y, cal.params.bias_nt.z],
            "current_bias_nT_per_A": estimate_c,
            "rejected_rows": cal.rejected_rows,
        },
    });
    let write = |name: String, text: String| {
        let path = dir.join(name);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))
    };
    write(format!("seed-{seed}.csv"), csv)?;
    write(
        format!("seed-{seed}.json"),
        serde_json::to_string_pretty(&json)?,
    )
}

fn table(name: &str, duration_s: f64, every_s: Option<f64>, checks: &[SeedCheck]) -> String {
    let mut s = String::new();
    let sampling = every_s.map_or("every row".to_owned(), |e| format!("one row every {e} s"));
    let _ = writeln!(
        s,
        "### {name}, {duration_s} s, {sampling}, seeds 1..={}\n",
        checks.len()
    );
    let _ = writeln!(
        s,
        "| seed | rows used (rejected) | form | RMS before, nT | RMS after, nT | noise alone, nT | after / noise | within 3 sigma | kept | missed | false |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
    for c in checks {
        let within = c.z.iter().filter(|z| z.abs() <= 3.0).count();
        let _ = writeln!(
            s,
            "| {} | {} ({}) | {:?} | {:.0} | {:.1} | {:.1} | {:.3} | {}/{} | {} | {} | {} |",
            c.seed,
            c.rows,
            c.rejected,
            c.form,
            c.before_nt,
            c.after_nt,
            c.noise_only_nt,
            c.after_nt / c.noise_only_nt,
            within,
            c.z.len(),
            list(&c.kept),
            list(&c.missed),
            list(&c.false_kept),
        );
    }
    let total: usize = checks.iter().map(|c| c.z.len()).sum();
    let within: usize = checks
        .iter()
        .map(|c| c.z.iter().filter(|z| z.abs() <= 3.0).count())
        .sum();
    let z_rms = (checks
        .iter()
        .flat_map(|c| c.z.iter())
        .map(|z| z * z)
        .sum::<f64>()
        / total.max(1) as f64)
        .sqrt();
    let worst_ratio = checks
        .iter()
        .map(|c| (c.after_nt / c.noise_only_nt - 1.0).abs())
        .fold(0.0, f64::max);
    let missed: usize = checks.iter().map(|c| c.missed.len()).sum();
    let false_kept: usize = checks.iter().map(|c| c.false_kept.len()).sum();
    let _ = writeln!(
        s,
        "\nParameters within 3 sigma: {within}/{total} ({:.1} %), normalized-error RMS {z_rms:.2}; residual RMS within {:.1} % of the noise alone (worst seed); true regressors missed: {missed}; false regressors kept: {false_kept}.",
        100.0 * within as f64 / total.max(1) as f64,
        100.0 * worst_ratio
    );
    s
}

fn list(names: &[String]) -> String {
    if names.is_empty() {
        "-".to_owned()
    } else {
        names
            .iter()
            .map(|n| n.trim_start_matches("cur_").trim_end_matches("_A"))
            .collect::<Vec<_>>()
            .join(" ")
    }
}
