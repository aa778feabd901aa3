//! Shared set-up of the diagnosis tests: simulate a rax2-like scenario with chosen effects,
//! build the references the way the driver does, and diagnose.

#![allow(dead_code)]

use pdcal_albedo::{AlbedoModel, MapChoice};
use pdcal_dataset::Effect;
use pdcal_diagnose::{BaseModel, DiagnoseConfig, DiagnoseInputs, Diagnosis, diagnose};
use pdcal_ephem::Reference;
use pdcal_sim::{Scenario, SimOutput, simulate};

/// Duration of the default tests' data sets, s: 90 min (the data set starts in eclipse and enters the next one at 85 min)
/// and most of the sphere of Sun directions while keeping each filter run short.
pub const SHORT_S: f64 = 5400.0;

/// The rax2-like scenario with exactly these effects and this duration.
pub fn scenario(effects: Vec<Effect>, duration_s: f64) -> Scenario {
    let mut s = Scenario::rax2_like().expect("built-in scenario");
    s.effects = effects;
    s.duration_s = duration_s;
    s
}

/// The paper's albedo (the only effect of a control data set).
pub fn albedo() -> Effect {
    Effect::Albedo {
        map: "toms-mean-1p25x1".into(),
    }
}

/// One reference per telemetry row, from the dataset's TLE.
pub fn references(sim: &SimOutput) -> Vec<Reference> {
    pdcal_filter::step_references(&sim.meta, &sim.telemetry).expect("references")
}

/// The filter's albedo model.
pub fn albedo_model() -> AlbedoModel {
    AlbedoModel::from_choice(&MapChoice::TomsMean1p25x1).expect("TOMS map")
}

/// Simulates and diagnoses; also returns the simulation.
pub fn run(scenario: &Scenario, seed: u64, base: BaseModel) -> (SimOutput, Diagnosis) {
    let sim = simulate(scenario, seed).expect("simulation");
    let refs = references(&sim);
    let albedo = albedo_model();
    let inputs = inputs(&sim, &refs, &albedo);
    let d = diagnose(&inputs, base, &DiagnoseConfig::default()).expect("diagnosis");
    (sim, d)
}

/// The diagnosis inputs of a simulation (never its truth), with the TOMS map.
pub fn inputs<'a>(
    sim: &'a SimOutput,
    references: &'a [Reference],
    albedo: &'a AlbedoModel,
) -> DiagnoseInputs<'a> {
    DiagnoseInputs {
        meta: &sim.meta,
        telemetry: &sim.telemetry,
        references,
        albedo,
        albedo_map: "toms-mean-1p25x1",
    }
}

/// Worst true normal (deg) and scale (%) errors of a calibration over the photodiodes lit
/// at least 5 minutes, from the simulation's truth (the tests' view; the diagnosis never
/// sees it).
pub fn true_errors(sim: &SimOutput, calibration: &pdcal_filter::Calibration) -> (f64, f64) {
    let (_, normal, scale) =
        pdcal_evaluate::photodiode_errors(calibration, &sim.truth, &sim.constants);
    (normal, scale)
}

/// One line per round and the final check, for the test log.
pub fn describe(d: &Diagnosis) -> String {
    let mut s = format!("verdict {}\n", d.verdict());
    for r in &d.rounds {
        s += &format!(
            "  {} score {:.1}: {}\n    pd rms {:.4} -> {:.4} V, inside {:.3} -> {:.3}, |s| std {:.4} -> {:.4}, mag {:.0} -> {:.0} nT, gyro {:.2e} -> {:.2e}, shrink {:.2} ({:.0} nats), rejected {:?}, dropped {:?}\n",
            r.found,
            r.score,
            r.evidence,
            r.gap_before.photodiode_rms_v,
            r.gap_after.photodiode_rms_v,
            r.gap_before.fraction_within_3sigma,
            r.gap_after.fraction_within_3sigma,
            r.gap_before.sun_vector_magnitude_std,
            r.gap_after.sun_vector_magnitude_std,
            r.gap_before.magnetometer_rms_nt,
            r.gap_after.magnetometer_rms_nt,
            r.gap_before.gyro_residual_rms_rad_s,
            r.gap_after.gyro_residual_rms_rad_s,
            r.shrink.fraction_removed,
            r.shrink.nats,
            r.rejected,
            r.dropped.iter().map(|x| x.id).collect::<Vec<_>>(),
        );
        s += &format!("    significance: {}\n", r.significance.text());
        for x in &r.reformed {
            s += &format!(
                "    reformed {}: {:?} -> {:?} (photodiode RSS {:.4} -> {:.4} V^2)\n",
                x.id, x.from, x.to, x.photodiode_rss_v2[0], x.photodiode_rss_v2[1]
            );
        }
    }
    s += "  final check:";
    for c in d.final_candidates.iter().take(11) {
        s += &format!(" {} {:.1} (W {:.1});", c.id, c.score, c.wald);
    }
    s += &format!("\n  final rejected: {:?}", d.final_rejected);
    let m = &d.misfit;
    s += &format!(
        "\n  misfit: explained {} rms ratio {:.3} inside {:.4}; {}; failed {:?}; worst pd {:?}",
        m.explained,
        m.rms_ratio,
        m.fraction_within_3sigma,
        m.concentrated_in,
        m.failed,
        m.photodiodes
            .iter()
            .take(3)
            .map(|p| (
                p.photodiode,
                (100.0 * p.rms_ratio).round() / 100.0,
                (100.0 * p.lag1_autocorrelation).round() / 100.0
            ))
            .collect::<Vec<_>>()
    );
    s
}
