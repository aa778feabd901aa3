//! Photodiode temperatures: the scenario's thermal model writes plausible `temp_pdNN_C`
//! columns that follow the sunlight, the `temperature` effect scales the outputs by
//! `1 + k (T - T_ref)` at the true temperature, and without the model nothing changes.

use pdcal_dataset::{Effect, EffectId, photodiode_temperature_column, render_dataset};
use pdcal_sim::{Scenario, ScenarioError, SimOutput, Thermal, simulate};

/// RAX-2-like without albedo (the slow part, and irrelevant here).
fn scenario(duration_s: f64, thermal: Option<Thermal>) -> Scenario {
    let mut s = Scenario::rax2_like().unwrap();
    s.duration_s = duration_s;
    s.effects.retain(|e| e.id() != EffectId::Albedo);
    s.temperature = thermal;
    s
}

fn invalid_field(s: &Scenario) -> (String, String) {
    match s.validate() {
        Err(ScenarioError::Invalid { field, reason }) => (field, reason),
        other => panic!("expected Invalid, got {other:?}"),
    }
}

#[test]
fn columns_are_present_sampled_and_plausible() {
    let s = scenario(600.0, Some(Thermal::default()));
    let out = simulate(&s, 4).unwrap();
    let tm = &out.telemetry;
    let names: Vec<&str> = tm.temperature_c.iter().map(|c| c.name.as_str()).collect();
    let expected: Vec<String> = (1..=17).map(photodiode_temperature_column).collect();
    assert_eq!(names, expected);
    assert_eq!(
        tm.photodiode_temperatures(&out.meta),
        (0..17).map(Some).collect::<Vec<_>>()
    );
    let mut residuals = Vec::new();
    for (i, column) in tm.temperature_c.iter().enumerate() {
        assert_eq!(column.values.len(), tm.len());
        for (k, v) in column.values.iter().enumerate() {
            // Every 10 s on the 1 s grid.
            assert_eq!(v.is_some(), k % 10 == 0, "pd{} row {k}", i + 1);
            if let Some(v) = v {
                assert!((-21.0..=61.0).contains(v), "pd{} row {k}: {v} C", i + 1);
                residuals.push(v - out.temperature_true_c[i][k]);
            }
        }
    }
    // The samples are the truth plus 0.1 C noise (1037 samples: 10 % bounds are > 3 sigma).
    let rms = (residuals.iter().map(|r| r * r).sum::<f64>() / residuals.len() as f64).sqrt();
    assert!((rms - 0.1).abs() < 0.01, "noise rms {rms}");
    // The dataset writer accepts the columns (it re-reads what it renders).
    let files = render_dataset(&out.to_dataset()).unwrap();
    assert!(files[1].1.lines().next().unwrap().ends_with(",temp_pd17_C"));
}

/// Mean over rows of each photodiode's `max(0, n.s) nu`, from the truth files alone.
fn mean_illumination(out: &SimOutput) -> Vec<f64> {
    (out.true_photodiodes.iter())
        .map(|p| {
            let sum: f64 = (out.truth.sun_body.iter())
                .zip(&out.truth.eclipse)
                .map(|(s, nu)| p.n_body.dot(s).max(0.0) * nu)
                .sum();
            sum / out.truth.len() as f64
        })
        .collect()
}

fn correlation(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let cov: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let vx: f64 = x.iter().map(|a| (a - mx).powi(2)).sum();
    let vy: f64 = y.iter().map(|b| (b - my).powi(2)).sum();
    cov / (vx * vy).sqrt()
}

#[test]
fn temperature_follows_illumination() {
    let thermal = Thermal {
        noise_c: 0.0,
        ..Thermal::default()
    };
    let out = simulate(&scenario(8400.0, Some(thermal)), 2).unwrap();
    let truth = &out.truth;

    // Photodiodes that see more Sun run hotter: over 14 time constants the initial value is
    // forgotten and the mean temperature is close to the mean equilibrium.
    let lit = mean_illumination(&out);
    let mean_t: Vec<f64> = (out.temperature_true_c.iter())
        .map(|t| t.iter().sum::<f64>() / t.len() as f64)
        .collect();
    let r = correlation(&lit, &mean_t);
    assert!(r > 0.95, "illumination vs temperature correlation {r}");

    // Every photodiode cools through an umbra entered from sunlight, and warms after it.
    let dark = |k: usize| truth.eclipse[k] == 0.0;
    let first = (1..truth.len())
        .find(|&k| dark(k) && !dark(k - 1))
        .expect("the run enters the umbra");
    let last = (first..truth.len())
        .take_while(|&k| dark(k))
        .last()
        .unwrap_or(first);
    assert!(
        last - first > 1200 && last + 900 < truth.len(),
        "an umbra of > 20 min and 15 min of sunlight after it: rows {first}..{last}"
    );
    for (i, t) in out.temperature_true_c.iter().enumerate() {
        assert!(
            t[last] < t[first] - 5.0,
            "pd{} cools: {} -> {}",
            i + 1,
            t[first],
            t[last]
        );
        assert!(
            t[last] < -15.0,
            "pd{} near T_cold at umbra exit: {}",
            i + 1,
            t[last]
        );
        assert!(
            t[last + 900] > t[last] + 5.0,
            "pd{} warms after the umbra",
            i + 1
        );
    }
}

#[test]
fn temperature_effect_scales_outputs_by_one_plus_k_delta_t() {
    let thermal = Thermal {
        noise_c: 0.0,
        sample_period_s: 1.0,
        ..Thermal::default()
    };
    let plain = scenario(3000.0, Some(thermal));
    let mut heated = plain.clone();
    heated.effects.push(Effect::Temperature {
        coefficient_per_k: vec![0.005; 17],
        reference_c: 20.0,
    });
    let (a, b) = (simulate(&heated, 9).unwrap(), simulate(&plain, 9).unwrap());
    assert_eq!(a.telemetry.temperature_c, b.telemetry.temperature_c);
    let (mut checked, mut t_min, mut t_max) = (0, f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..17 {
        for k in 0..a.telemetry.len() {
            let (Some(ya), Some(yb)) = (a.pd_noise_free_v[i][k], b.pd_noise_free_v[i][k]) else {
                continue;
            };
            // The column is the true temperature (no noise, sampled every row).
            let t = a.telemetry.temperature_c[i].values[k].unwrap();
            assert_eq!(t, a.temperature_true_c[i][k]);
            let factor = 1.0 + 0.005 * (t - 20.0);
            assert!(
                (ya - factor * yb).abs() <= 1e-12 * yb.abs().max(1e-3),
                "pd{} row {k}: {ya} vs {factor} * {yb}",
                i + 1
            );
            if yb > 0.1 {
                checked += 1;
                t_min = t_min.min(t);
                t_max = t_max.max(t);
            }
        }
    }
    // Enough lit samples over a wide enough temperature range that the factor is not ~1.
    assert!(checked > 1000, "{checked} lit samples");
    assert!(t_max - t_min > 10.0, "temperatures {t_min} .. {t_max}");
}

#[test]
fn without_the_thermal_model_nothing_else_changes() {
    let without = scenario(300.0, None);
    let with = scenario(300.0, Some(Thermal::default()));
    let (a, b) = (simulate(&without, 5).unwrap(), simulate(&with, 5).unwrap());
    assert!(a.telemetry.temperature_c.is_empty());
    assert!(a.temperature_true_c.is_empty());
    assert_eq!(b.telemetry.temperature_c.len(), 17);
    // Same rows, same sensor samples and truth, bit for bit (the temperature noise has its
    // own random stream).
    let mut b_tm = b.telemetry.clone();
    b_tm.temperature_c.clear();
    let bits = |o: &pdcal_dataset::Telemetry| format!("{:?}", render_like(o));
    assert_eq!(bits(&a.telemetry), bits(&b_tm));
    assert_eq!(a.truth, b.truth);
    assert_eq!(a.constants, b.constants);
    // The built-in scenarios are written back without the field.
    let text = Scenario::rax2_like().unwrap().to_ron_string().unwrap();
    assert!(!text.contains("temperature"), "{text}");
}

/// Every float of a telemetry as bits (`PartialEq` would equate -0.0 and 0.0).
fn render_like(tm: &pdcal_dataset::Telemetry) -> Vec<Option<u64>> {
    let mut out: Vec<Option<u64>> = tm.t_s.iter().map(|t| Some(t.to_bits())).collect();
    for v in tm.gyro_rad_s.iter().chain(tm.mag_nt.iter().flatten()) {
        out.extend(v.map_or(vec![None], |v| {
            v.iter().map(|x| Some(x.to_bits())).collect()
        }));
    }
    for pd in &tm.pd_v {
        out.extend(pd.iter().map(|v| v.map(f64::to_bits)));
    }
    out
}

#[test]
fn scenario_ron_spelling_and_defaults() {
    let base = Scenario::rax2_like().unwrap().to_ron_string().unwrap();
    let with = |field: &str| {
        let text = base.replacen("    effects: [", &format!("    {field}\n    effects: ["), 1);
        Scenario::from_ron_str(&text)
    };
    let s = with("temperature: Thermal(),").unwrap();
    assert_eq!(s.temperature, Some(Thermal::default()));
    let s = with("temperature: Some(Thermal(tau_s: 300.0, hot_C: 80.0)),").unwrap();
    let th = s.temperature.unwrap();
    assert_eq!((th.tau_s, th.hot_c, th.cold_c), (300.0, 80.0, -20.0));
    assert!(matches!(
        with("temperature: Thermal(tau: 300.0),"),
        Err(ScenarioError::Ron { .. })
    ));
}

#[test]
fn effects_without_what_they_act_on_are_scenario_errors() {
    let mut s = scenario(60.0, None);
    s.effects.push(Effect::Temperature {
        coefficient_per_k: vec![0.005; 17],
        reference_c: 20.0,
    });
    let (field, reason) = invalid_field(&s);
    assert_eq!(field, "effects[1] (temperature)");
    assert!(reason.contains("`temperature: Thermal()`"), "{reason}");
    s.temperature = Some(Thermal::default());
    assert_eq!(s.validate(), Ok(()));

    let mut s = scenario(60.0, None);
    s.effects.push(Effect::AlbedoGain { gain: 0.5 });
    let (field, reason) = invalid_field(&s);
    assert_eq!(field, "effects[1] (albedo-gain)");
    assert!(reason.contains("`albedo`"), "{reason}");
    let mut s = Scenario::rax2_like().unwrap();
    s.effects.push(Effect::AlbedoGain { gain: 0.5 });
    assert_eq!(s.validate(), Ok(()));
}

#[test]
fn thermal_parameters_are_checked() {
    type Change = fn(&mut Thermal);
    let cases: [(&str, Change); 6] = [
        ("temperature.tau_s", |t| t.tau_s = 0.0),
        ("temperature.hot_C", |t| t.hot_c = -30.0),
        ("temperature.cold_C", |t| t.cold_c = -200.0),
        ("temperature.initial_C", |t| t.initial_c = Some(f64::NAN)),
        ("temperature.noise_C", |t| t.noise_c = 5.0),
        ("temperature.sample_period_s", |t| t.sample_period_s = 0.0),
    ];
    for (want, change) in cases {
        let mut thermal = Thermal::default();
        change(&mut thermal);
        let (field, _) = invalid_field(&scenario(60.0, Some(thermal)));
        assert_eq!(field, want);
    }
}
