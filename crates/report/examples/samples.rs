//! Writes one sample of every figure kind, with synthetic data shaped like a pdcal run, and an
//! index.html: `cargo run --release -p pdcal-report --example samples [OUT_DIR]`
//! (default /tmp/report-samples). Used to look at the figures.

use std::error::Error;
use std::f64::consts::TAU;
use std::path::PathBuf;
use std::time::Instant;

use pdcal_report::{
    BinRange, BoundsPanel, DirectionSet, Figure, HistogramPanel, LineAxes, Mark, Series, YScale,
    histograms, index_html, lines, mean_std, series_with_bounds, sphere_directions,
};

/// Tiny deterministic normal generator (LCG + Box-Muller): the example needs no rand crate.
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (TAU * v).cos()
    }
}

const N: usize = 7200; // two hours at 1 Hz
const PD: usize = 17;

fn sunlit(t_min: f64) -> bool {
    !(t_min < 12.0 || (70.0..105.0).contains(&t_min))
}

/// Sun direction in the body frame of a tumbling spacecraft.
fn sun_body(t_min: f64) -> [f64; 3] {
    let (a, b) = (0.9 * t_min, 0.23 * t_min + 0.4);
    [b.cos() * a.cos(), b.cos() * a.sin(), b.sin()]
}

fn normals() -> Vec<[f64; 3]> {
    (0..PD)
        .map(|i| {
            let az = (i as f64 * 67.0).to_radians();
            let el = (((i * 37) % 150) as f64 - 75.0).to_radians();
            [el.cos() * az.cos(), el.cos() * az.sin(), el.sin()]
        })
        .collect()
}

fn main() -> Result<(), Box<dyn Error>> {
    let out = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or("/tmp/report-samples".into()),
    );
    std::fs::create_dir_all(&out)?;
    let mut rng = Noise(7);
    let t: Vec<f64> = (0..N).map(|i| i as f64 / 60.0).collect();
    let ns = normals();

    // Fig. 2: raw outputs of 17 photodiodes.
    let raw: Vec<Vec<f64>> = ns
        .iter()
        .enumerate()
        .map(|(k, n)| {
            let c = 3.4 + 0.05 * k as f64;
            t.iter()
                .map(|&tm| {
                    let s = sun_body(tm);
                    let cos = n[0] * s[0] + n[1] * s[1] + n[2] * s[2];
                    let sun = if sunlit(tm) { c * cos.max(0.0) } else { 0.0 };
                    sun + 0.02 * rng.normal()
                })
                .collect()
        })
        .collect();
    let names: Vec<String> = (1..=PD).map(|k| format!("photodiode {k}")).collect();
    let series: Vec<Series<'_>> = raw
        .iter()
        .zip(&names)
        .map(|(y, name)| Series::new(name, y, Mark::Line))
        .collect();
    let start = Instant::now();
    lines(
        &out,
        &Figure::new("raw_outputs", "Raw photodiode outputs"),
        &LineAxes::new("time (min)", "output (V)"),
        &t,
        &series,
    )?;
    println!(
        "raw_outputs (17 x 7200 lines): {:.0} ms",
        start.elapsed().as_secs_f64() * 1e3
    );

    // Fig. 4: residuals of photodiodes 1-3 with 3-sigma bounds (NaN when not used).
    let mut residual = Vec::new();
    let mut res_sigma = Vec::new();
    for out_k in raw.iter().take(3) {
        let sig: Vec<f64> = t
            .iter()
            .map(|&tm| 0.03 + 0.4 * (-(tm - 12.0).max(0.0) / 4.0).exp())
            .collect();
        let r: Vec<f64> = t
            .iter()
            .zip(&sig)
            .enumerate()
            .map(|(i, (&tm, s))| {
                let lit = sunlit(tm) && out_k[i] > 0.2;
                if lit { s * rng.normal() } else { f64::NAN }
            })
            .collect();
        residual.push(r);
        res_sigma.push(sig);
    }
    let labels = ["photodiode 1", "photodiode 2", "photodiode 3"];
    let panels: Vec<BoundsPanel<'_>> = (0..3)
        .map(|k| BoundsPanel::new(labels[k], "residual (V)", &t, &residual[k], &res_sigma[k]))
        .collect();
    let start = Instant::now();
    series_with_bounds(
        &out,
        &Figure::new("residuals", "Photodiode residuals and ±3σ bounds").with_size(1200, 1000),
        "time (min)",
        "residual",
        &panels,
    )?;
    println!("residuals: {:.0} ms", start.elapsed().as_secs_f64() * 1e3);

    // Fig. 5: scale-factor estimates with 3-sigma bounds around them.
    let mut est = Vec::new();
    let mut centre = Vec::new();
    let mut sig = Vec::new();
    for (k, out_k) in raw.iter().enumerate().take(3) {
        let truth = 3.7 + 0.1 * k as f64;
        let mut e = 3.4;
        let mut s = 0.3_f64;
        let (mut ev, mut cv, mut sv) = (vec![], vec![], vec![]);
        for (i, &tm) in t.iter().enumerate() {
            let updated = sunlit(tm) && out_k[i] > 0.2;
            if updated {
                s = (s * 0.995).max(0.01);
                e += 0.02 * (truth - e) + 0.2 * s * rng.normal() * 0.1;
            }
            ev.push(if updated { e } else { f64::NAN });
            cv.push(e);
            sv.push(s);
        }
        est.push(ev);
        centre.push(cv);
        sig.push(sv);
    }
    let panels: Vec<BoundsPanel<'_>> = (0..3)
        .map(|k| {
            BoundsPanel::new(labels[k], "scale factor C (V)", &t, &est[k], &sig[k])
                .around(&centre[k])
        })
        .collect();
    series_with_bounds(
        &out,
        &Figure::new("scale_factors", "Scale factor estimates and ±3σ bounds")
            .with_size(1200, 1000),
        "time (min)",
        "estimate",
        &panels,
    )?;

    // Figs. 8-9: magnitude histograms, initial vs calibrated.
    let initial: Vec<f64> = (0..3000).map(|_| 0.925 + 0.029 * rng.normal()).collect();
    let calibrated: Vec<f64> = (0..3000).map(|_| 0.993 + 0.022 * rng.normal()).collect();
    histograms(
        &out,
        &Figure::new("magnitude_hist", "Measured sun-vector magnitude").with_size(1200, 600),
        "magnitude (-)",
        40,
        BinRange::Shared,
        &[
            HistogramPanel {
                label: "initial parameters",
                values: &initial,
            },
            HistogramPanel {
                label: "calibrated parameters",
                values: &calibrated,
            },
        ],
    )?;
    // Fig. 11: direction change, one panel.
    let change: Vec<f64> = (0..3000)
        .map(|_| (9.1 + 3.0 * rng.normal()).abs())
        .collect();
    histograms(
        &out,
        &Figure::new(
            "direction_change_hist",
            "Sun-direction change, initial vs calibrated",
        )
        .with_size(900, 600),
        "angle (deg)",
        30,
        BinRange::PerPanel,
        &[HistogramPanel {
            label: "data set 1",
            values: &change,
        }],
    )?;

    // Fig. 10: magnitude over time with and without albedo compensation.
    let compensated: Vec<f64> = t
        .iter()
        .map(|&tm| {
            if sunlit(tm) {
                0.993 + 0.02 * rng.normal()
            } else {
                f64::NAN
            }
        })
        .collect();
    let raw_mag: Vec<f64> = t
        .iter()
        .zip(&compensated)
        .map(|(&tm, m)| m + 0.08 * (1.0 + (tm / 9.0).sin()))
        .collect();
    lines(
        &out,
        &Figure::new(
            "magnitude_time",
            "Sun-vector magnitude with and without albedo compensation",
        ),
        &LineAxes::new("time (min)", "magnitude (-)"),
        &t,
        &[
            Series::new("uncompensated", &raw_mag, Mark::Circle).with_colour([214, 39, 40]),
            Series::new("albedo-compensated", &compensated, Mark::Dot).with_colour([31, 119, 180]),
        ],
    )?;

    // Fig. 12: attitude 1-sigma per axis, log scale.
    let att: Vec<Vec<f64>> = (0..3)
        .map(|ax| {
            t.iter()
                .map(|&tm| {
                    let base = 20.0 * (-tm / 3.0).exp() + 0.3 + 0.1 * ax as f64;
                    if sunlit(tm) {
                        base
                    } else {
                        base + 0.05 * (tm - 70.0).max(0.0) * (ax + 1) as f64
                    }
                })
                .collect()
        })
        .collect();
    lines(
        &out,
        &Figure::new("attitude_sigma", "Attitude 1σ"),
        &LineAxes::new("time (min)", "1σ (deg)").with_y_scale(YScale::Log10),
        &t,
        &[
            Series::new("x", &att[0], Mark::Line),
            Series::new("y", &att[1], Mark::Line),
            Series::new("z", &att[2], Mark::Line),
        ],
    )?;

    // Fig. 13: a converged run (less than a decade on the log axis).
    let att13: Vec<Vec<f64>> = (0..3)
        .map(|ax| {
            t.iter()
                .map(|&tm| {
                    let base = 0.15 + 0.1 * ax as f64;
                    if sunlit(tm) {
                        base
                    } else {
                        base + 0.004 * (tm - 70.0).max(0.0)
                    }
                })
                .collect()
        })
        .collect();
    lines(
        &out,
        &Figure::new(
            "attitude_sigma_converged",
            "Attitude 1σ, scale factors only",
        ),
        &LineAxes::new("time (min)", "1σ (deg)").with_y_scale(YScale::Log10),
        &t,
        &[
            Series::new("x", &att13[0], Mark::Line),
            Series::new("y", &att13[1], Mark::Line),
            Series::new("z", &att13[2], Mark::Line),
        ],
    )?;

    // Fig. 3: sun directions in the body frame, two data sets.
    let d1: Vec<[f64; 3]> = t
        .iter()
        .filter(|&&tm| sunlit(tm))
        .map(|&tm| sun_body(tm))
        .collect();
    let d2: Vec<[f64; 3]> = t
        .iter()
        .filter(|&&tm| sunlit(tm))
        .map(|&tm| sun_body(0.7 * tm + 40.0))
        .collect();
    sphere_directions(
        &out,
        &Figure::new(
            "sun_directions",
            "Measured sun directions in the body frame",
        )
        .with_size(1200, 700),
        &[
            DirectionSet {
                name: "data set 1",
                dirs_body: &d1,
            },
            DirectionSet {
                name: "data set 2",
                dirs_body: &d2,
            },
        ],
    )?;

    // Empty-but-valid: all NaN.
    let nan = vec![f64::NAN; 100];
    let t100: Vec<f64> = (0..100).map(f64::from).collect();
    series_with_bounds(
        &out,
        &Figure::new("all_nan", "A photodiode that was never lit"),
        "time (min)",
        "residual",
        &[BoundsPanel::new(
            "photodiode 17",
            "residual (V)",
            &t100,
            &nan,
            &nan,
        )],
    )?;

    let (m0, s0, _) = mean_std(&initial).unwrap_or_default();
    let (m1, s1, _) = mean_std(&calibrated).unwrap_or_default();
    let rows = vec![
        (
            "magnitude mean, initial -> calibrated".to_owned(),
            format!("{m0:.3} -> {m1:.3}"),
        ),
        (
            "magnitude std, initial -> calibrated".to_owned(),
            format!("{s0:.3} -> {s1:.3}"),
        ),
        ("photodiodes".to_owned(), "17 <all lit>".to_owned()),
    ];
    let figs = [
        ("Raw photodiode outputs (Fig. 2)", "raw_outputs"),
        (
            "Sun directions in the body frame (Fig. 3)",
            "sun_directions",
        ),
        ("Residuals with ±3σ bounds (Fig. 4)", "residuals"),
        ("Scale factors with ±3σ bounds (Fig. 5)", "scale_factors"),
        ("Magnitude histograms (Figs. 8-9)", "magnitude_hist"),
        ("Magnitude over time (Fig. 10)", "magnitude_time"),
        ("Direction change (Fig. 11)", "direction_change_hist"),
        ("Attitude 1σ (Fig. 12)", "attitude_sigma"),
        (
            "Attitude 1σ, converged (Fig. 13)",
            "attitude_sigma_converged",
        ),
        ("All-NaN panel", "all_nan"),
    ];
    let page = index_html(&out, "pdcal report samples", &rows, &figs)?;
    println!("wrote {}", page.display());
    Ok(())
}
