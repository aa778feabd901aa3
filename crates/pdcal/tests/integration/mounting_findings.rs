//! A wrong nominal mounting or a reversed polarity is a finding, never fatal (issue 22,
//! item 1): the rax2-like set with photodiode 6's nominal normal given off by 180 deg (az
//! -18, el 10 instead of 162, -10: a sign slip in a mounting table) and photodiode 3 wired
//! with reversed polarity (negative outputs in the Sun). The run ends normally, names both
//! photodiodes and what the data say, and every photodiode calibrates to the bounds of the
//! continuous table of docs/validation.md (normal 0.5 deg, scale 1 %) against the
//! simulator's truth.

use std::sync::OnceLock;

use pdcal::calibrate::{RunConfig, albedo_model};
use pdcal_filter::mounting::{Action, check_mountings};
use pdcal_sim::SimOutput;

fn sim() -> &'static SimOutput {
    static SIM: OnceLock<SimOutput> = OnceLock::new();
    SIM.get_or_init(|| {
        let scenario = pdcal_sim::Scenario::rax2_like().unwrap();
        pdcal::simulate::run(&scenario, 1).unwrap()
    })
}

/// The set with pd06's mounting flipped and pd03's outputs negated.
fn broken() -> (pdcal_dataset::DatasetMeta, pdcal_dataset::Telemetry) {
    let mut meta = sim().meta.clone();
    let mut telemetry = sim().telemetry.clone();
    let pd06 = &mut meta.photodiodes[5];
    assert_eq!((pd06.azimuth_deg, pd06.elevation_deg), (162.0, -10.0));
    (pd06.azimuth_deg, pd06.elevation_deg) = (-18.0, 10.0);
    let pd03 = &mut telemetry.pd_v[2];
    for k in 0..pd03.len() {
        if let Some(y) = pd03.get_mut(k) {
            *y = -*y;
        }
    }
    (meta, telemetry)
}

fn findings(
    meta: &pdcal_dataset::DatasetMeta,
    telemetry: &pdcal_dataset::Telemetry,
) -> Vec<pdcal_filter::mounting::MountingFinding> {
    let references = pdcal_filter::step_references(meta, telemetry).unwrap();
    let config = pdcal_filter::FilterConfig::default();
    let sigma = config.resolve(meta.noise.as_ref()).photodiode_v;
    let albedo = pdcal::calibrate::albedo_model().unwrap();
    check_mountings(
        meta,
        telemetry,
        &(&references).into(),
        &config,
        sigma,
        Some(&albedo),
    )
    .unwrap()
}

#[test]
fn a_correct_layout_has_no_finding() {
    assert_eq!(findings(&sim().meta, &sim().telemetry), Vec::new());
}

#[test]
fn a_flipped_mounting_and_a_reversed_polarity_are_findings_and_the_run_ends_normally() {
    let (meta, telemetry) = broken();
    let outcome = pdcal::calibrate::run(
        &meta,
        &telemetry,
        &RunConfig::default(),
        &albedo_model().unwrap(),
    )
    .expect("the run ends normally");

    let found = &outcome.mountings;
    assert_eq!(found.len(), 2, "{found:#?}");
    let (pd03, pd06) = (&found[0], &found[1]);
    assert_eq!(pd03.photodiode, 3);
    assert!(pd03.polarity_reversed);
    assert_eq!(pd03.action, Action::CalibratedNegated);
    assert_eq!(
        pd03.message(),
        format!(
            "pd03: the data contradict dataset.ron: its outputs are negative in the Sun \
             (polarity reversed; {} strong samples); calibrated with its outputs negated",
            pd03.samples
        )
    );
    assert_eq!(pd06.photodiode, 6);
    assert!(!pd06.polarity_reversed);
    assert_eq!(pd06.action, Action::CalibratedFromSupported);
    let (az, el) = (
        pd06.supported_azimuth_deg.unwrap(),
        pd06.supported_elevation_deg.unwrap(),
    );
    // The supported normal is the true one to the regression's accuracy (uncalibrated Sun
    // vectors, albedo left out): far inside the filter's 10-degree prior.
    let supported = pdcal_attitude::normal_from_az_el(az.to_radians(), el.to_radians());
    let true_normal = sim().true_photodiodes[5].n_body;
    assert!(
        supported.angle(&true_normal).to_degrees() < 10.0,
        "{az} {el}"
    );
    assert_eq!(
        pd06.message(),
        format!(
            "pd06: the data contradict dataset.ron: its outputs follow a normal at az {az:.1}, \
             el {el:.1} deg, {:.0} deg from the nominal az -18.0, el 10.0 deg; calibrated from \
             that normal",
            pd06.angle_deg.unwrap()
        )
    );
    // Both findings are warnings of the run too (printed, and in summary.json).
    for f in found {
        assert!(
            outcome.warnings.contains(&f.message()),
            "{:?}",
            outcome.warnings
        );
    }

    // Every photodiode, the two wrong ones included, to the continuous table's bounds.
    let calibration = &outcome.run.calibration;
    for (i, (cal, truth)) in calibration
        .photodiodes
        .iter()
        .zip(&sim().true_photodiodes)
        .enumerate()
    {
        let normal_error = cal.n_body().angle(&truth.n_body).to_degrees();
        let scale_error = 100.0 * (cal.scale_v / truth.scale_v - 1.0).abs();
        assert!(
            normal_error <= 0.5 && scale_error <= 1.0,
            "pd{:02}: normal {normal_error} deg, scale {scale_error} %",
            i + 1
        );
    }
    let summary = pdcal::files::summary(&meta, &outcome);
    assert_eq!(
        summary.photodiodes[2].flag.as_deref(),
        Some("polarity reversed: outputs negated")
    );
    assert_eq!(
        summary.photodiodes[5].flag,
        Some(format!(
            "nominal mounting off by {:.0} deg: calibrated from the data's normal",
            pd06.angle_deg.unwrap()
        ))
    );
    let json = serde_json::to_value(&summary).unwrap();
    assert_eq!(json["mounting_findings"][1]["photodiode"], 6);
    assert_eq!(
        json["mounting_findings"][1]["action"],
        "calibrated-from-supported"
    );
}

/// `diagnose` reads the data as calibrate does: the reversed photodiode negated and the
/// flipped mounting corrected, each said, before any effect is sought; no residual of
/// pd03 or pd06 is left for an effect to explain.
#[test]
fn diagnose_reads_the_data_as_calibrate_does() {
    let (meta, telemetry) = broken();
    let outcome =
        pdcal::diagnose::run(&meta, &telemetry, pdcal_diagnose::BaseModel::Paper).unwrap();
    let said = outcome.warnings.join("\n");
    assert!(
        said.contains("pd03") && said.contains("polarity reversed"),
        "{said}"
    );
    assert!(said.contains("pd06"), "{said}");
    let misfit = &outcome.diagnosis.misfit;
    for pd in [2, 5] {
        let rms = pdcal_diagnose::residuals::rms(
            outcome
                .diagnosis
                .final_residuals
                .pd
                .iter()
                .filter(|p| p.pd == pd && p.direct_v > 0.0)
                .map(|p| p.residual_v),
        );
        assert!(rms < 0.1, "pd{:02}: lit residual RMS {rms} V", pd + 1);
    }
    assert!(
        !misfit.concentrated_in.contains("photodiode 3")
            && !misfit.concentrated_in.contains("photodiode 6"),
        "{}",
        misfit.concentrated_in
    );
}
