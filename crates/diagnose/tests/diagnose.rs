//! Seeded acceptance tests of the diagnosis on simulated data with effects hidden (on in the
//! truth, absent from the base model). 90-minute rax2-like data sets (the scenario starts in
//! eclipse and enters the next one at 85 min, so dark, penumbra and lit samples are all
//! there). The 20-seed control and the effect-size sweep run with `PDCAL_SLOW=1`.

mod common;

use common::*;
use pdcal_dataset::{Effect, EffectId};
use pdcal_diagnose::{
    BaseModel, DiagnoseConfig, Diagnosis, Gap, ModelSpec, calibrate_and_residuals, gap,
};

/// The sensor an effect shows in.
#[derive(Clone, Copy, Debug)]
enum Sensor {
    Photodiode,
    Magnetometer,
    Gyro,
}

fn rms_of(g: &Gap, sensor: Sensor) -> f64 {
    match sensor {
        Sensor::Photodiode => g.photodiode_rms_v,
        Sensor::Magnetometer => g.magnetometer_rms_nt,
        Sensor::Gyro => g.gyro_residual_rms_rad_s,
    }
}

/// Accuracy bounds of the calibration-filter issue: normal error <= 0.5 deg, scale <= 1 %.
const NORMAL_BOUND_DEG: f64 = 0.5;
const SCALE_BOUND_PERCENT: f64 = 1.0;

/// The gyro's residual floor: the same data calibrated with the true scale error removed
/// (the rate beyond the gyro has no sensor sigma of its own: it is what the smoother
/// spreads between gyro noise and attitude corrections).
fn gyro_floor(sim: &pdcal_sim::SimOutput, truth: [f64; 3]) -> f64 {
    let refs = references(sim);
    let albedo = albedo_model();
    let inputs = inputs(sim, &refs, &albedo);
    let mut spec = ModelSpec::new(BaseModel::Paper);
    spec.added.push(Effect::GyroScale { scale_error: truth });
    let (_, res) =
        calibrate_and_residuals(&inputs, &mut spec, &DiagnoseConfig::default()).expect("oracle");
    gap(&res).gyro_residual_rms_rad_s
}

/// Hides `effect` (alone beyond the base's), diagnoses from `base`, and checks the
/// acceptance list: named first; the affected sensor's RMS at least halfway to its floor;
/// the calibration afterwards inside the filter issue's bounds.
fn hidden_alone(effect: Effect, base: BaseModel, sensor: Sensor) -> Diagnosis {
    let id = effect.id();
    let effects = if matches!(effect, Effect::Albedo { .. }) {
        vec![effect.clone()]
    } else {
        vec![albedo(), effect.clone()]
    };
    let (sim, d) = run(&scenario(effects, SHORT_S), 1, base);
    println!("{id}: {}", describe(&d));
    let first = d.rounds.first().expect("something found");
    assert_eq!(first.found, id, "{}", describe(&d));
    assert!(d.verdict().starts_with(id.as_str()), "{}", d.verdict());
    let before = rms_of(&first.gap_before, sensor);
    let after = rms_of(&first.gap_after, sensor);
    let floor = match (sensor, &effect) {
        (Sensor::Photodiode, _) => first.gap_before.photodiode_noise_v,
        (Sensor::Magnetometer, _) => first.gap_before.magnetometer_noise_nt,
        (Sensor::Gyro, Effect::GyroScale { scale_error }) => gyro_floor(&sim, *scale_error),
        (Sensor::Gyro, _) => 0.0,
    };
    let moved = (before - after) / (before - floor);
    println!(
        "{id}: {sensor:?} RMS {before:.4e} -> {after:.4e}, floor {floor:.4e}: moved {moved:.2}"
    );
    assert!(
        moved >= 0.5,
        "{id}: moved only {moved:.2} of the way to the floor"
    );
    let (normal, scale) = true_errors(&sim, &d.final_run.calibration);
    assert!(
        normal <= NORMAL_BOUND_DEG && scale <= SCALE_BOUND_PERCENT,
        "{id}: calibration afterwards: normal {normal:.3} deg, scale {scale:.3} %"
    );
    d
}

#[test]
fn albedo_hidden_from_cosine() {
    hidden_alone(albedo(), BaseModel::Cosine, Sensor::Photodiode);
}

#[test]
fn fov_rolloff_hidden() {
    let d = hidden_alone(
        Effect::FovRolloff {
            start_rad: 60f64.to_radians(),
            cutoff_rad: 85f64.to_radians(),
        },
        BaseModel::Paper,
        Sensor::Photodiode,
    );
    // The law is recovered: start and cutoff within 1 deg (grid step 0.5 deg).
    let Effect::FovRolloff {
        start_rad,
        cutoff_rad,
    } = d.rounds[0].effect
    else {
        panic!("not a roll-off");
    };
    assert!((start_rad.to_degrees() - 60.0).abs() <= 1.0);
    assert!((cutoff_rad.to_degrees() - 85.0).abs() <= 1.0);
}

#[test]
fn dark_offset_hidden() {
    let volts: Vec<f64> = (0..17).map(|i| 0.01 + 0.002 * i as f64).collect();
    let d = hidden_alone(
        Effect::DarkOffset {
            volts: volts.clone(),
        },
        BaseModel::Paper,
        Sensor::Photodiode,
    );
    let Effect::DarkOffset { volts: found } = &d.rounds[0].effect else {
        panic!("not a dark offset");
    };
    // Umbra means over ~1400 samples per photodiode: sigma 0.015/sqrt(1400) = 0.4 mV;
    // 2 mV is 5 sigma.
    for (f, t) in found.iter().zip(&volts) {
        assert!((f - t).abs() < 0.002, "{f} vs {t}");
    }
}

#[test]
fn saturation_hidden() {
    hidden_alone(
        Effect::Saturation { volts: 3.3 },
        BaseModel::Paper,
        Sensor::Photodiode,
    );
}

#[test]
fn penumbra_hidden() {
    hidden_alone(Effect::Penumbra, BaseModel::Paper, Sensor::Photodiode);
}

#[test]
fn time_offset_hidden() {
    hidden_alone(
        Effect::TimeOffset { seconds: 0.3 },
        BaseModel::Paper,
        Sensor::Photodiode,
    );
}

/// A 1-s late tag moves the hard shadow edge by a sample, which the penumbra ramp explains
/// in part (Wald 67 on this seed): the refit of the offset as a filter state must win, and
/// with the shadow evaluated at `t - delta` nothing is left for penumbra afterwards.
#[test]
fn time_offset_of_one_second_is_not_penumbra() {
    let effects = vec![albedo(), Effect::TimeOffset { seconds: 1.0 }];
    let (_, d) = run(&scenario(effects, SHORT_S), 3, BaseModel::Paper);
    println!("time-offset 1 s: {}", describe(&d));
    assert_eq!(d.verdict(), "time-offset", "{}", describe(&d));
    let Effect::TimeOffset { seconds } = d.rounds[0].effect else {
        panic!("not a time offset");
    };
    // The filter's estimate: 0.90 s on this seed; the first-order term `delta C n^T (w x s)`
    // loses about 0.5 (|w| delta)^2 ~ 0.2 % of the signal at 4 deg/s, the rest is noise.
    assert!((seconds - 1.0).abs() < 0.15, "{seconds}");
}

#[test]
fn scale_drift_hidden() {
    let rates: Vec<f64> = (0..17).map(|i| 0.01 + 0.001 * i as f64).collect();
    hidden_alone(
        Effect::ScaleDrift {
            fraction_per_hour: rates,
        },
        BaseModel::Paper,
        Sensor::Photodiode,
    );
}

#[test]
fn mag_bias_hidden() {
    hidden_alone(
        Effect::MagBias {
            bias_nt: [1500.0, -1000.0, 800.0],
        },
        BaseModel::Paper,
        Sensor::Magnetometer,
    );
}

#[test]
fn gyro_scale_hidden() {
    hidden_alone(
        Effect::GyroScale {
            scale_error: [0.01, -0.01, 0.0],
        },
        BaseModel::Paper,
        Sensor::Gyro,
    );
}

/// The paper's Fig. 10 story on the unmodified rax2-like data (albedo and penumbra on):
/// from the cosine base, albedo is found first and removed: the Sun-vector magnitude's
/// spread drops and no albedo signature is left.
#[test]
fn fig10_albedo_found_and_removed() {
    let mut s = pdcal_sim::Scenario::rax2_like().expect("scenario");
    s.duration_s = SHORT_S;
    let (_, d) = run(&s, 2, BaseModel::Cosine);
    println!("fig10: {}", describe(&d));
    // The scenario holds albedo and penumbra, whose scores from the cosine base are within
    // 1 % of each other: either may come first.
    let round = d
        .rounds
        .iter()
        .find(|r| r.found == EffectId::Albedo)
        .expect("albedo found");
    assert!(d.rounds.iter().position(|r| r.found == EffectId::Albedo) < Some(2));
    assert!(d.final_spec.contains(EffectId::Albedo));
    // Paper: 0.022 after; the model here is the truth's, so it must at least halve.
    assert!(
        round.gap_after.sun_vector_magnitude_std < 0.5 * round.gap_before.sun_vector_magnitude_std
    );
    assert!(
        d.verdict()
            .split('+')
            .all(|id| id == "albedo" || id == "penumbra")
    );
}

/// Two hidden at once from the cosine base: albedo and dark offsets, both found, one
/// round each.
#[test]
fn albedo_and_dark_offset_over_two_rounds() {
    let effects = vec![
        albedo(),
        Effect::DarkOffset {
            volts: vec![0.02; 17],
        },
    ];
    let (_, d) = run(&scenario(effects, SHORT_S), 3, BaseModel::Cosine);
    println!("two: {}", describe(&d));
    let found: Vec<EffectId> = d.rounds.iter().map(|r| r.found).collect();
    assert_eq!(
        found,
        [EffectId::Albedo, EffectId::DarkOffset],
        "{}",
        describe(&d)
    );
    assert_eq!(d.verdict(), "albedo+dark-offset");
}

/// Control: nothing hidden (paper base on albedo-only data): `none` on a few seeds.
#[test]
fn control_is_none() {
    for seed in [11, 12] {
        let (_, d) = run(&scenario(vec![albedo()], SHORT_S), seed, BaseModel::Paper);
        println!("control seed {seed}: {}", describe(&d));
        assert_eq!(d.verdict(), "none", "seed {seed}: {}", describe(&d));
    }
}

fn slow() -> bool {
    std::env::var("PDCAL_SLOW").is_ok_and(|v| v == "1")
}

/// The false-alarm rate over 20 control seeds (acceptance: `none`, which also means no
/// `unexplained`, in all 20).
#[test]
fn control_false_alarm_rate_20_seeds() {
    if !slow() {
        return;
    }
    let mut alarms = Vec::new();
    // PDCAL_CONTROL_SEEDS=106,107 runs only those seeds.
    let seeds: Vec<u64> = std::env::var("PDCAL_CONTROL_SEEDS")
        .ok()
        .map(|v| v.split(',').filter_map(|s| s.trim().parse().ok()).collect())
        .unwrap_or_else(|| (101..=120).collect());
    for seed in seeds {
        let (_, d) = run(&scenario(vec![albedo()], SHORT_S), seed, BaseModel::Paper);
        let best = d
            .final_candidates
            .first()
            .map(|c| format!("{} {:.1}", c.id, c.score))
            .unwrap_or_default();
        println!(
            "control seed {seed}: {} (best remaining {best})",
            d.verdict()
        );
        if d.verdict() != "none" {
            println!("{}", describe(&d));
            alarms.push((seed, d.verdict()));
        }
    }
    println!("false alarms: {} of 20: {alarms:?}", alarms.len());
    assert!(alarms.is_empty(), "{alarms:?}");
}

/// The smallest size of each effect found reliably (named first in 3 of 3 seeds), from a
/// halving sweep; prints the table recorded in docs/diagnose.md.
#[test]
fn effect_size_sweep() {
    if !slow() {
        return;
    }
    type Make = fn(f64) -> Effect;
    let sweeps: [(&str, Make, &[f64]); 8] = [
        (
            "dark-offset (V)",
            |v| Effect::DarkOffset { volts: vec![v; 17] },
            &[0.004, 0.002, 0.001, 0.0005],
        ),
        (
            "saturation (V below the largest output)",
            |v| Effect::Saturation { volts: 3.9 - v },
            &[0.2, 0.1, 0.05, 0.02],
        ),
        (
            "fov-rolloff (start deg, cutoff 89)",
            |v| Effect::FovRolloff {
                start_rad: v.to_radians(),
                cutoff_rad: 89f64.to_radians(),
            },
            &[75.0, 80.0, 84.0, 87.0],
        ),
        (
            "time-offset (s)",
            |v| Effect::TimeOffset { seconds: v },
            &[0.4, 0.3, 0.2, 0.1],
        ),
        (
            "scale-drift (1/h)",
            |v| Effect::ScaleDrift {
                fraction_per_hour: vec![v; 17],
            },
            &[0.004, 0.002, 0.001, 0.0005],
        ),
        (
            "mag-bias (nT per axis)",
            |v| Effect::MagBias {
                bias_nt: [v, -v, v],
            },
            &[400.0, 200.0, 100.0, 50.0],
        ),
        (
            "gyro-scale (x, y)",
            |v| Effect::GyroScale {
                scale_error: [v, -v, 0.0],
            },
            &[0.02, 0.01, 0.006, 0.004, 0.002],
        ),
        ("penumbra (on/off)", |_| Effect::Penumbra, &[1.0]),
    ];
    // PDCAL_SWEEP=<part of a name> restricts the sweep to the matching effects.
    let only = std::env::var("PDCAL_SWEEP").unwrap_or_default();
    for (name, make, sizes) in sweeps.into_iter().filter(|s| s.0.contains(&only)) {
        let mut smallest = None;
        for &size in sizes {
            let effect = make(size);
            let id = effect.id();
            let hits = (1..=3)
                .filter(|&seed| {
                    let (_, d) = run(
                        &scenario(vec![albedo(), effect.clone()], SHORT_S),
                        seed,
                        BaseModel::Paper,
                    );
                    let hit = d.rounds.first().is_some_and(|r| r.found == id);
                    if !hit {
                        println!("missed, seed {seed}: {}", describe(&d));
                    }
                    hit
                })
                .count();
            println!("sweep {name}: size {size}: {hits}/3");
            if hits == 3 {
                smallest = Some(size);
            } else {
                break;
            }
        }
        println!("SWEEP {name}: smallest found in 3/3 seeds: {smallest:?}");
    }
}

/// A refit outside its effect's physical range is not named: every photodiode losing 15 %
/// of its output per hour is no scale drift any hardware has (it would be dark within
/// seven hours), so the diagnosis says that the model or the data are wrong instead.
#[test]
fn a_refit_outside_the_physical_range_is_not_named() {
    let drift = Effect::ScaleDrift {
        fraction_per_hour: vec![-0.15; 17],
    };
    let (_, d) = run(
        &scenario(vec![albedo(), drift], SHORT_S),
        1,
        BaseModel::Paper,
    );
    println!("{}", describe(&d));
    assert!(
        d.rounds.iter().all(|r| r.found != EffectId::ScaleDrift),
        "{}",
        describe(&d)
    );
    assert!(!d.verdict().contains("scale-drift"), "{}", d.verdict());
    let rejected = (d.rounds.iter().flat_map(|r| &r.rejected))
        .chain(&d.final_rejected)
        .find(|r| r.id == EffectId::ScaleDrift)
        .expect("scale-drift tried and rejected");
    assert!(
        rejected.reason.starts_with(
            "its refit is outside the effect's physical range (fraction_per_hour[0] = -0.1"
        ) && rejected.reason.ends_with(
            "a scale drift is within 10 %/h in size (coverglass darkening is about 1 % a year; \
             beyond 10 %/h a photodiode would lose its output within hours)): not an \
             explanation, a sign that the base model or the data are wrong"
        ),
        "{}",
        rejected.reason
    );
}
