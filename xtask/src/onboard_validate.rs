//! `cargo xtask onboard-validate`: the onboard Sun-vector core against the simulator's
//! truth over seeds (docs/validation.md, "Onboard Sun vector"). Each seed is simulated,
//! calibrated and exported as `pdcal sun-vector` does, then on the sunlit rows (truth
//! illuminated fraction 1) four estimators are compared with the true Sun direction:
//! (a) the core in `f32` with the reflectivity grid, (b) the same core without the Earth
//! (the albedo bound only), (c) Basilisk's `cssWlsEst` (unweighted least squares over the
//! photodiodes above a threshold, rows = normal x scale, normalised) at 0.15 V and 1.2 V,
//! and (d) the `f32` core against the `f64` core.

use std::path::Path;

use anyhow::Result;
use nalgebra::{Matrix3, Vector3};
use pdcal::export_onboard::OnboardCalibration;
use pdcal::onboard_sun::{N, RowEstimate, RowInput, estimate_row, estimate_rows};
use pdcal_onboard::Validity;

/// The thresholds of the `cssWlsEst` rows, V.
const WLS_THRESHOLDS_V: [f64; 2] = [0.15, 1.2];

/// One estimator's errors on the sunlit rows of every seed.
#[derive(Default)]
struct Tally {
    /// Angle to the truth on the rows it called valid, deg.
    errors_deg: Vec<f64>,
    sunlit: usize,
    valid: usize,
}

impl Tally {
    fn push(&mut self, direction: Option<Vector3<f64>>, truth: &Vector3<f64>) {
        self.sunlit += 1;
        if let Some(d) = direction {
            self.valid += 1;
            self.errors_deg.push(d.angle(truth).to_degrees());
        }
    }

    fn row(&self, name: &str) -> String {
        let mut e = self.errors_deg.clone();
        e.sort_by(f64::total_cmp);
        let valid = 100.0 * self.valid as f64 / self.sunlit.max(1) as f64;
        let Some(max) = e.last() else {
            return format!("| {name} | - | - | - | {valid:.1} % |");
        };
        let mean = e.iter().sum::<f64>() / e.len() as f64;
        let p95 = percentile(&e, 0.95);
        format!("| {name} | {mean:.3} | {p95:.3} | {max:.3} | {valid:.1} % |")
    }
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let k = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[k.min(sorted.len() - 1)]
}

/// Why the grid core missed on the sunlit rows: invalid by reason, or more than 1 deg off,
/// with the rows near an umbra edge and without an attitude counted apart.
#[derive(Default)]
struct Misses {
    invalid: std::collections::BTreeMap<&'static str, usize>,
    beyond_1deg: usize,
    beyond_near_edge: usize,
    beyond_no_attitude: usize,
    beyond_few_used: usize,
    invalid_near_edge: usize,
}

/// Seconds from an umbra or penumbra row within which a row counts as near the edge.
const EDGE_S: f64 = 120.0;

struct Totals {
    grid: Tally,
    bound: Tally,
    wls: Vec<Tally>,
    f32_vs_f64_max_deg: f64,
    misses: Misses,
}

/// Runs the seeds and prints the table.
pub fn run(seeds: u64, scenario_name: &str) -> Result<()> {
    let scenario = pdcal::simulate::load_scenario(scenario_name)?;
    let base = Path::new("out/onboard-validate").join(&scenario.name);
    let mut totals = Totals {
        grid: Tally::default(),
        bound: Tally::default(),
        wls: WLS_THRESHOLDS_V.iter().map(|_| Tally::default()).collect(),
        f32_vs_f64_max_deg: 0.0,
        misses: Misses::default(),
    };
    for seed in 1..=seeds {
        let dir = base.join(format!("seed-{seed}"));
        seed_run(&scenario, seed, &dir, &mut totals)?;
        eprintln!("seed {seed}/{seeds} done");
    }
    print_table(&scenario.name, seeds, &totals);
    Ok(())
}

fn seed_run(
    scenario: &pdcal_sim::Scenario,
    seed: u64,
    dir: &Path,
    totals: &mut Totals,
) -> Result<()> {
    let dataset = dir.join("dataset");
    let cal = dir.join("cal");
    let sim = pdcal::simulate::run_downlink_to_dir_forced(scenario, seed, 0, &dataset, true)?;
    pdcal::calibrate::run_dirs_forced(
        std::slice::from_ref(&dataset),
        &cal,
        &pdcal::calibrate::RunConfig::default(),
        true,
    )?;
    let export = pdcal::export_onboard::build(
        &cal,
        Some(&dataset),
        pdcal::export_onboard::DEFAULT_GRID_DEG,
    )?;
    let attitudes = pdcal::onboard_sun::read_attitudes(&cal)?;
    let rows = pdcal::onboard_sun::row_inputs(&sim.meta, &sim.telemetry, &attitudes)?;
    let grid32 = estimate_rows::<f32>(&rows, &export)?;
    let grid64 = estimate_rows::<f64>(&rows, &export)?;
    let cal32 = export.core::<f32, N>()?;
    let truth = &sim.truth;
    let near_edge = near_edge(&truth.t_s, &truth.eclipse);
    for (k, row) in rows.iter().enumerate() {
        if truth.eclipse[k] < 1.0 {
            continue;
        }
        let s_true = truth.sun_body[k].normalize();
        let a = &grid32[k];
        totals.grid.push(valid_direction(a), &s_true);
        tally_miss(&mut totals.misses, a, &s_true, row, near_edge[k]);
        let bound = RowEstimate::from(&estimate_row(row, &cal32, None, false));
        totals.bound.push(valid_direction(&bound), &s_true);
        for (tally, threshold) in totals.wls.iter_mut().zip(WLS_THRESHOLDS_V) {
            tally.push(css_wls_est(row, &export, threshold), &s_true);
        }
        if let (Some(x), Some(y)) = (valid_direction(a), valid_direction(&grid64[k])) {
            totals.f32_vs_f64_max_deg = totals.f32_vs_f64_max_deg.max(x.angle(&y).to_degrees());
        }
    }
    Ok(())
}

fn valid_direction(e: &RowEstimate) -> Option<Vector3<f64>> {
    (e.validity == Validity::Valid).then(|| Vector3::from(e.sun_body))
}

fn tally_miss(m: &mut Misses, e: &RowEstimate, truth: &Vector3<f64>, row: &RowInput, edge: bool) {
    match valid_direction(e) {
        None => {
            *m.invalid
                .entry(pdcal::onboard_sun::validity_name(e.validity))
                .or_default() += 1;
            m.invalid_near_edge += usize::from(edge);
        }
        Some(d) if d.angle(truth).to_degrees() > 1.0 => {
            m.beyond_1deg += 1;
            m.beyond_near_edge += usize::from(edge);
            m.beyond_no_attitude += usize::from(row.earth.is_none());
            m.beyond_few_used += usize::from(e.n_used <= 4);
        }
        Some(_) => {}
    }
}

/// Whether each row lies within [`EDGE_S`] of a row not in full Sun.
fn near_edge(t_s: &[f64], lit: &[f64]) -> Vec<bool> {
    let shadow: Vec<f64> = t_s
        .iter()
        .zip(lit)
        .filter(|(_, l)| **l < 1.0)
        .map(|(t, _)| *t)
        .collect();
    t_s.iter()
        .map(|t| {
            let i = shadow.partition_point(|s| s < t);
            let before = i.checked_sub(1).and_then(|j| shadow.get(j));
            let after = shadow.get(i);
            [before, after]
                .into_iter()
                .flatten()
                .any(|s| (s - t).abs() <= EDGE_S)
        })
        .collect()
}

/// Basilisk's `cssWlsEst`: the enabled photodiodes whose output exceeds `threshold_v`,
/// `H` rows their normals times their scale, unweighted least squares (the minimum-norm
/// solution with fewer than 3), normalised; `None` with none above the threshold or a
/// singular `H^T H`.
fn css_wls_est(
    row: &RowInput,
    export: &OnboardCalibration,
    threshold_v: f64,
) -> Option<Vector3<f64>> {
    let mut h: Vec<Vector3<f64>> = Vec::new();
    let mut y: Vec<f64> = Vec::new();
    for (pd, &v) in export.photodiodes.iter().zip(&row.outputs_v) {
        if pd.enabled && v.is_finite() && v > threshold_v {
            h.push(Vector3::from(pd.normal_body) * pd.scale_v);
            y.push(v);
        }
    }
    let s = match h.len() {
        0 => return None,
        1 => h[0] * (y[0] / h[0].norm_squared()),
        2 => {
            let g = nalgebra::Matrix2::new(
                h[0].dot(&h[0]),
                h[0].dot(&h[1]),
                h[1].dot(&h[0]),
                h[1].dot(&h[1]),
            );
            let a = g.try_inverse()? * nalgebra::Vector2::new(y[0], y[1]);
            h[0] * a.x + h[1] * a.y
        }
        _ => {
            let hth: Matrix3<f64> = h.iter().map(|r| r * r.transpose()).sum();
            let hty: Vector3<f64> = h.iter().zip(&y).map(|(r, v)| r * *v).sum();
            hth.try_inverse()? * hty
        }
    };
    (s.norm() > 0.0).then(|| s.normalize())
}

fn print_table(scenario: &str, seeds: u64, t: &Totals) {
    println!(
        "\n### {scenario}, seeds 1..={seeds}: {} sunlit rows\n",
        t.grid.sunlit
    );
    println!("| estimator | mean error (deg) | p95 (deg) | max (deg) | valid |");
    println!("|---|---|---|---|---|");
    println!(
        "{}",
        t.grid.row("core, f32, 5 deg grid (albedo compensated)")
    );
    println!("{}", t.bound.row("core, f32, no Earth (albedo bound)"));
    for (tally, threshold) in t.wls.iter().zip(WLS_THRESHOLDS_V) {
        println!(
            "{}",
            tally.row(&format!("cssWlsEst, threshold {threshold} V"))
        );
    }
    println!(
        "\nf32 against f64 (grid core, rows valid in both): largest angle {:.2e} deg",
        t.f32_vs_f64_max_deg
    );
    let m = &t.misses;
    println!(
        "\nGrid core misses on sunlit rows: invalid {:?} ({} within {EDGE_S} s of the umbra or \
         penumbra); beyond 1 deg: {} ({} near the edge, {} without an attitude estimate, {} \
         with 4 or fewer photodiodes used)",
        m.invalid,
        m.invalid_near_edge,
        m.beyond_1deg,
        m.beyond_near_edge,
        m.beyond_no_attitude,
        m.beyond_few_used
    );
}
