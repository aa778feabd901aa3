//! The output schema: `summary.json`'s content (its types and how it is built from a
//! calibration's [`Outcome`]), and the [`Outcome`] itself, what a calibration produced.

use pdcal_dataset::DatasetMeta;
use pdcal_filter::identifiability::{
    Evidence, Judged, NOT_DETERMINED_SIGMA_RATIO, PdIdentifiability, Status,
};
use pdcal_filter::{
    Calibration, CalibrationRun, GapRules, ModeUsed, PdCalibration, RepairKind, ResidualRecord,
    SegmentReport, Sensor,
};
use serde::Serialize;

use crate::stats::MeanStdSums;
use crate::sunvec::SunVectorMetrics;

pub use pdcal_evaluate::OUTPUT_FORMAT_VERSION;

/// The Sun's distance, AU, at which `C` (`scale_V`) is defined: the model's direct-Sun term
/// carries `(1 AU / r_sun)^2` (`pdcal_photodiode::DirectSun`).
pub const SCALE_REFERENCE_DISTANCE_AU: f64 = 1.0;

/// `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Layout version.
    pub format_version: u32,
    /// Dataset name from dataset.ron.
    pub dataset: String,
    /// Its epoch (the earliest set's, with several): with `dataset`, what `evaluate` checks
    /// it is given the data set the calibration read.
    pub epoch_utc: String,
    /// Mode the filter ran in: `full`, `photodiode-only` or `scale-only` ([`mode_name`]).
    pub mode: &'static str,
    /// Whether magnetometer updates were made.
    pub magnetometer_used: bool,
    /// Which attitude directions the data observe ([`attitude_observed`]).
    pub attitude_observed: &'static str,
    /// The Sun's distance, AU, at which the scale factors are defined (always
    /// [`SCALE_REFERENCE_DISTANCE_AU`]): `scale_V` is the output at that distance and
    /// normal incidence, whatever the Sun's distance on the data set's dates.
    pub scale_reference_distance_au: f64,
    /// Per photodiode, in pdNN order.
    pub photodiodes: Vec<PdSummary>,
    /// Final gyro bias, rad/s, body (the prior's on an axis the data did not determine).
    pub gyro_bias_rad_s: [f64; 3],
    /// How well the data determined each gyro-bias axis.
    pub gyro_bias_status: [Judged; 3],
    /// The gyro bias the filter started from at the first acquisition and where it came
    /// from: `fit` (the batch fit of the first segment's vectors and gyro, with its sigma)
    /// or `prior` (`initial_bias_sigma_deg_s`, with why the fit was not used); null when
    /// no segment was acquired.
    pub initial_bias: Option<pdcal_filter::InitialBias>,
    /// Sun-vector magnitude with initial and calibrated parameters.
    pub sun_vector_magnitude: MagnitudeSummary,
    /// Mean angle between the initial and calibrated Sun directions.
    pub sun_direction_change_deg: MeanOnly,
    /// Photodiode residual statistics.
    pub residuals: ResidualSummary,
    /// Whether the residuals are consistent with the model: the one verdict `calibrate`,
    /// `diagnose` and the Python API share ([`pdcal_filter::consistency`]).
    pub consistency: pdcal_filter::Consistency,
    /// Update counts (accepted, gated, ...) per sensor class.
    pub updates: serde_json::Value,
    /// Samples rejected per sensor (`gyro`, `mag`, `pd01`...): screened against their
    /// neighbours before the filter, or gated by it; counts and the first rows.
    pub rejected_samples: Vec<RejectedSummary>,
    /// Repairs of the filter covariance (it stopped being positive definite).
    pub covariance_repairs: RepairsSummary,
    /// Wall-clock time of the filter run, s.
    pub runtime_s: f64,
    /// Physical-plausibility warnings on the input, one line each (also on stderr).
    pub warnings: Vec<String>,
    /// The rules that split the telemetry into segments (gap threshold, gyro hold, the
    /// gyro's own sample period, magnetometer pairing tolerance; s).
    pub segment_rules: GapRules,
    /// How the attitude was carried between samples (`gyro` or `dynamics`), why
    /// (`config-off`, `config-on`, `no-inertia`, `no-gyro`, `gyro-untested`,
    /// `rate-changes`, `rate-carried`) and, with `dynamics: Auto`, the test of the gyro's
    /// samples against its noise ([`pdcal_filter::propagation`]).
    pub propagation: pdcal_filter::PropagationChoice,
    /// The multi-start ensemble that widened the reported sigmas, when one ran
    /// ([`pdcal_filter::ensemble`]); absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ensemble: Option<pdcal_filter::ensemble::EnsembleReport>,
    /// The factor every reported sigma was multiplied by: the residuals' spread after each
    /// step's correction over the sensor noise, at least 1 ([`pdcal_filter::Dispersion`]);
    /// absent when the configuration turns it off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dispersion: Option<pdcal_filter::DispersionReport>,
    /// The segments: rows between gaps, silent gyros and lost attitudes, how each one's
    /// attitude was acquired, or why it was skipped.
    pub segments: Vec<SegmentReport>,
    /// The data sets calibrated together, in time order, each with its place on the joint
    /// time line and its own photodiode residual statistics.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub datasets: Vec<DatasetSummary>,
    /// With several data sets: whether each set's own estimates agree with the others'
    /// (verdict, threshold, warnings; per set in `datasets[k].repeatability`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub repeatability: Option<crate::repeatability::Repeatability>,
    /// Photodiodes whose data contradict their nominal mounting or polarity: what dataset.ron
    /// says, what the data support, and what the calibration did (`crate::mounting`).
    pub mounting_findings: Vec<pdcal_filter::mounting::MountingFinding>,
    /// Sensors whose axes the data found other than stated, one entry per finding (empty
    /// when none), each applied to the data before calibrating ([`crate::axes`]).
    pub sensor_axes: Vec<crate::axes::SensorAxesEntry>,
    /// What the sensor-axes check tested: each check with its residual count, and by how
    /// much the next hypothesis lost to the stated axes (nats) when they fit best.
    pub sensor_axes_checked: SensorAxesChecked,
    /// The one rotation that carries the nominal normals onto the calibrated ones, fitted
    /// to the photodiodes whose normals the data moved, with its sigma and whether it is a
    /// finding (`pdcal_filter::common_rotation`); null when fewer than 4 were.
    pub normals_rotation: Option<pdcal_filter::CommonRotation>,
    /// Why `normals_rotation` is null: the data did not test whether the photodiodes are
    /// turned together (a head mounted turned would go unseen); null when it is fitted.
    pub normals_rotation_not_fitted: Option<String>,
    /// The calibration as reported (`calibration.ron`): every quantity the data did not
    /// determine at its prior value, the statuses listed.
    #[serde(skip)]
    pub reported: Calibration,
}

/// One photodiode in `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct PdSummary {
    /// 1-based index.
    pub index: usize,
    /// The calibrated scale factor and normal with their sigmas (`scale_V`,
    /// `scale_sigma_V`, `azimuth_deg`, `azimuth_sigma_deg`, `elevation_deg`,
    /// `elevation_sigma_deg` in the JSON, as in calibration.ron).
    #[serde(flatten)]
    pub calibration: PdCalibration,
    /// Whether the photodiode took part (false: never lit).
    pub used: bool,
    /// How well the data determined it: the weakest of its three quantities
    /// (`calibrated`, `weakly-determined`, `not-determined`); a `not-determined` quantity
    /// is reported at its nominal value.
    pub status: Status,
    /// Why, when not `calibrated`.
    #[serde(skip_serializing_if = "String::is_empty")]
    pub status_reason: String,
    /// Per quantity (`scale`, `azimuth`, `elevation`), each with its reason.
    pub determination: PdIdentifiability,
    /// The initial estimates.
    pub initial: PdInitial,
    /// Angle between the calibrated and the nominal (initial) normal, deg.
    pub normal_change_deg: f64,
    /// Calibrated C against the initial C (the maximum output), %.
    pub scale_change_percent: f64,
    /// Sunlit time the calibration used: the time its accepted updates cover, min.
    pub time_used_min: f64,
    /// The part of it with the attitude held (its sigma in the observed directions within
    /// `segments.held_attitude_sigma_deg`), min: under 5 min a quantity is at most
    /// `weakly-determined`, with none at all `not-determined`.
    pub time_held_min: f64,
    /// Why the result deserves a second look, when it does: `never lit`, `lit too little
    /// (N min)`, `change beyond 3 sigma of the prior`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub flag: Option<String>,
}

/// A photodiode whose updates cover less than this is flagged as lit too little to
/// calibrate, min (the evaluation's own "lit at least 5 minutes").
pub const MIN_TIME_USED_MIN: f64 = 5.0;

/// The flag of a photodiode ([`PdSummary::flag`]): never lit, lit too little, or changed by
/// more than 3 sigma of the initial uncertainty (a mounting or a scale factor that far from
/// the prior is more often a data problem than a discovery).
fn photodiode_flag(
    used: bool,
    time_used_min: f64,
    (normal_change_deg, scale_change_v): (f64, f64),
    init: &pdcal_filter::PdCalibration,
) -> Option<String> {
    if !used {
        return Some("never lit".to_owned());
    }
    if time_used_min < MIN_TIME_USED_MIN {
        return Some(format!("lit too little ({time_used_min:.1} min)"));
    }
    let normal_sigma_deg = init
        .elevation_sigma_deg
        .max(init.azimuth_sigma_deg.unwrap_or(0.0));
    let beyond = normal_change_deg > 3.0 * normal_sigma_deg
        || scale_change_v.abs() > 3.0 * init.scale_sigma_v;
    beyond.then(|| "change beyond 3 sigma of the prior".to_owned())
}

/// The flag of a photodiode with a mounting finding: what the data say instead of
/// dataset.ron.
fn mounting_flag(
    index: usize,
    findings: &[pdcal_filter::mounting::MountingFinding],
) -> Option<String> {
    use pdcal_filter::mounting::Action;
    let f = findings.iter().find(|f| f.photodiode == index)?;
    Some(match (f.action, f.polarity_reversed) {
        (Action::Excluded, _) => "nominal mounting contradicted: left out".to_owned(),
        (Action::CalibratedNegated, _) => "polarity reversed: outputs negated".to_owned(),
        (Action::CalibratedFromSupported, reversed) => format!(
            "nominal mounting off by {:.0} deg: calibrated from the data's normal{}",
            f.angle_deg.unwrap_or(f64::NAN),
            if reversed { ", outputs negated" } else { "" }
        ),
    })
}

/// Initial values of one photodiode.
#[derive(Debug, Clone, Serialize)]
#[allow(non_snake_case)]
pub struct PdInitial {
    /// Maximum measured output referred to 1 AU (each sample divided by `(1 AU / r_sun)^2`),
    /// V; for a never-lit or dim photodiode the median of the lit ones' maxima
    /// (`pdcal_filter::init::initial_scales`).
    pub scale_V: f64,
    /// Nominal azimuth, deg.
    pub azimuth_deg: f64,
    /// Nominal elevation, deg.
    pub elevation_deg: f64,
}

/// Serde's test for statistics that do not exist (NaN): they are left out of the JSON,
/// and the object's `count` and `reason` say why, instead of a bare `null`.
fn undefined(x: &f64) -> bool {
    !x.is_finite()
}

/// Mean and standard deviation; in JSON, `mean` is left out when `count` is 0 and `std`
/// when `count` is below 2, with `reason` saying so.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct MeanStd {
    /// Mean (NaN without samples).
    #[serde(skip_serializing_if = "undefined")]
    pub mean: f64,
    /// Sample standard deviation (NaN with fewer than 2 samples).
    #[serde(skip_serializing_if = "undefined")]
    pub std: f64,
    /// Finite samples counted.
    pub count: usize,
    /// Why `mean` or `std` is absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<&'static str>,
}

/// Sun-vector magnitude, initial and calibrated.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct MagnitudeSummary {
    /// With the initial parameters.
    pub initial: MeanStd,
    /// With the calibrated parameters.
    pub calibrated: MeanStd,
    /// Samples used.
    pub samples: usize,
}

/// A mean only; in JSON, `mean` is left out when `count` is 0, with `reason`.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct MeanOnly {
    /// Mean (NaN without samples).
    #[serde(skip_serializing_if = "undefined")]
    pub mean: f64,
    /// Finite samples counted.
    pub count: usize,
    /// Why `mean` is absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<&'static str>,
}

/// Photodiode residuals; in JSON, the RMS and fraction are left out when `count` is 0,
/// with `reason`.
#[derive(Debug, Clone, Copy, Serialize)]
#[allow(non_snake_case)]
pub struct ResidualSummary {
    /// RMS of the photodiode residuals, V (NaN without residuals).
    #[serde(skip_serializing_if = "undefined")]
    pub photodiode_rms_V: f64,
    /// Fraction of photodiode residuals inside their 3-sigma bound (NaN without residuals).
    #[serde(skip_serializing_if = "undefined")]
    pub fraction_within_3sigma: f64,
    /// Photodiode residuals counted.
    pub count: usize,
    /// Why the statistics are absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<&'static str>,
}

/// One sensor's rejected samples in `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct RejectedSummary {
    /// `gyro`, `mag`, `pd01`, ...
    pub sensor: String,
    /// Samples rejected by the screening against their neighbours.
    pub screened: usize,
    /// Their telemetry rows (zero-based data rows of telemetry.csv), the first 100.
    pub screened_rows: Vec<usize>,
    /// Samples rejected by the filter's innovation gate (a magnetometer row counts once).
    pub gated: usize,
    /// Their rows, the first 100.
    pub gated_rows: Vec<usize>,
}

/// The covariance repairs in `summary.json`.
#[derive(Debug, Clone, Serialize)]
pub struct RepairsSummary {
    /// How many.
    pub count: usize,
    /// The first 100: row, time and what was done.
    pub first: Vec<serde_json::Value>,
}

fn rejected_summary(run: &CalibrationRun) -> Vec<RejectedSummary> {
    run.rejections
        .channels
        .iter()
        .map(|c| RejectedSummary {
            sensor: c.channel.name(),
            screened: c.screened.count,
            screened_rows: c.screened.first.clone(),
            gated: c.gated.count,
            gated_rows: c.gated.first.clone(),
        })
        .collect()
}

fn repairs_summary(run: &CalibrationRun) -> RepairsSummary {
    let first = run
        .covariance_repairs
        .first
        .iter()
        .map(|r| match r.kind {
            RepairKind::NonFinite { states } => serde_json::json!({
                "row": r.index, "t_s": r.t_s, "kind": "non-finite", "states_reset": states,
            }),
            RepairKind::Indefinite { min_eigenvalue } => serde_json::json!({
                "row": r.index, "t_s": r.t_s, "kind": "indefinite",
                "min_eigenvalue": min_eigenvalue,
            }),
        })
        .collect();
    RepairsSummary {
        count: run.covariance_repairs.count,
        first,
    }
}

/// The `reason` of a statistic over `count` samples that needs at least `needed`.
fn too_few(count: usize, needed: usize) -> Option<&'static str> {
    match (count, needed) {
        (0, _) => Some("no samples"),
        (1, 2) => Some("one sample: no standard deviation"),
        _ => None,
    }
}

/// Mean and sample standard deviation of the finite values summed in `sums` (NaN, and a
/// reason, for fewer than 1 and 2 values).
pub fn mean_std(sums: &MeanStdSums) -> MeanStd {
    MeanStd {
        mean: sums.mean(),
        std: sums.std(),
        count: sums.count(),
        reason: too_few(sums.count(), 2),
    }
}

/// RMS and within-3-sigma fraction of the photodiode residuals.
pub fn residual_summary(residuals: &[ResidualRecord]) -> ResidualSummary {
    let pd: Vec<&ResidualRecord> = residuals
        .iter()
        .filter(|r| matches!(r.sensor, Sensor::Photodiode(_)))
        .collect();
    let sum_sq = pd.iter().map(|r| r.residual * r.residual).sum::<f64>();
    let inside = pd
        .iter()
        .filter(|r| r.residual.abs() <= r.bound_3sigma)
        .count();
    ResidualSummary::from_sums(sum_sq, inside, pd.len())
}

impl ResidualSummary {
    /// From the sum of squared photodiode residuals, how many were inside their 3-sigma
    /// bound, and how many there were (NaN statistics and a reason when none).
    pub fn from_sums(sum_sq_v2: f64, inside: usize, count: usize) -> Self {
        let n = count as f64;
        ResidualSummary {
            photodiode_rms_V: (sum_sq_v2 / n).sqrt(),
            fraction_within_3sigma: inside as f64 / n,
            count,
            reason: too_few(count, 1),
        }
    }
}

/// The stable name of a mode in `summary.json`: `full`, `photodiode-only`, `scale-only`.
pub fn mode_name(mode: ModeUsed) -> &'static str {
    match mode {
        ModeUsed::Full => "full",
        ModeUsed::PhotodiodeOnly => "photodiode-only",
        ModeUsed::ScaleOnly { .. } => "scale-only",
    }
}

/// Builds `summary.json`'s content.
pub fn summary(meta: &DatasetMeta, outcome: &Outcome) -> Summary {
    let run = &outcome.run;
    let evidence = Evidence::of_run(run, outcome.consistency.verdict);
    let determination = pdcal_filter::identifiability::judge_photodiodes(&evidence);
    let mut bias_status = pdcal_filter::identifiability::judge_gyro_bias(&evidence);
    let mut reported = pdcal_filter::identifiability::reported_calibration(
        &run.initial,
        &run.calibration,
        &determination,
        &bias_status,
    );
    if let Some(fit) = unheld_bias_fit(run, &outcome.datasets) {
        floor_bias_sigma(fit, &mut reported, &mut bias_status);
    }
    reported.status = status_lines(&determination, &bias_status);
    let rotation = normals_rotation(run);
    let mounting_warning = mounting_warning(run, &rotation);
    let (normals_rotation, normals_rotation_not_fitted) = match rotation {
        Ok(r) => (Some(r), None),
        Err(why) => (None, Some(why.to_string())),
    };
    let photodiodes = reported
        .photodiodes
        .iter()
        .zip(&run.initial.photodiodes)
        .zip(&run.used_photodiodes)
        .zip(determination)
        .enumerate()
        .map(|(i, (((cal, init), used), determination))| {
            let normal_change_deg = cal.n_body().angle(&init.n_body()).to_degrees();
            let time_used_min = run.photodiode_time_used_s.get(i).copied().unwrap_or(0.0) / 60.0;
            let change = (normal_change_deg, cal.scale_v - init.scale_v);
            PdSummary {
                index: i + 1,
                calibration: *cal,
                used: *used,
                status: determination.status,
                status_reason: status_reason(&determination),
                determination,
                initial: PdInitial {
                    scale_V: init.scale_v,
                    azimuth_deg: init.azimuth_deg,
                    elevation_deg: init.elevation_deg,
                },
                normal_change_deg,
                scale_change_percent: 100.0 * (cal.scale_v - init.scale_v) / init.scale_v,
                time_used_min,
                time_held_min: run.photodiode_time_held_s.get(i).copied().unwrap_or(0.0) / 60.0,
                flag: mounting_flag(i + 1, &outcome.mountings)
                    .or_else(|| photodiode_flag(*used, time_used_min, change, init)),
            }
        })
        .collect();
    let sv = &outcome.sun_vector;
    let initial_bias = first_bias_from(run, 0).cloned();
    Summary {
        format_version: OUTPUT_FORMAT_VERSION,
        dataset: meta.name.clone(),
        epoch_utc: meta.epoch_utc.as_str().to_owned(),
        mode: mode_name(run.mode),
        magnetometer_used: magnetometer_used(run.mode),
        attitude_observed: attitude_observed(run.mode),
        scale_reference_distance_au: SCALE_REFERENCE_DISTANCE_AU,
        photodiodes,
        gyro_bias_rad_s: reported.gyro_bias_rad_s,
        gyro_bias_status: bias_status,
        initial_bias: initial_bias.clone(),
        sun_vector_magnitude: MagnitudeSummary {
            initial: mean_std(&sv.magnitude_initial),
            calibrated: mean_std(&sv.magnitude_calibrated),
            samples: sv.samples,
        },
        sun_direction_change_deg: {
            let m = mean_std(&sv.direction_change_deg);
            MeanOnly {
                mean: m.mean,
                count: m.count,
                reason: too_few(m.count, 1),
            }
        },
        residuals: outcome.residuals,
        consistency: with_notes(
            &outcome.consistency,
            mounting_warning
                .iter()
                .cloned()
                .chain(crate::axes::notes(&outcome.axes)),
        ),
        updates: counts_json(run),
        rejected_samples: rejected_summary(run),
        covariance_repairs: repairs_summary(run),
        runtime_s: outcome.runtime_s,
        warnings: outcome
            .warnings
            .iter()
            .cloned()
            .chain(bias_beyond_prior(&run.initial, &run.calibration))
            .chain(
                first_bias_from(run, last_set_row(&outcome.datasets))
                    .and_then(|b| bias_beyond_fit(b, &run.calibration)),
            )
            .chain(about_sun_line_undecided(&run.segments))
            .chain(attitude_losses(&run.segments))
            .chain(outcome.consistency.unlit_warnings())
            .chain(mounting_warning.clone())
            .collect(),
        segment_rules: run.segment_rules,
        propagation: run.propagation,
        ensemble: run.ensemble.clone(),
        dispersion: run.dispersion,
        segments: run.segments.clone(),
        datasets: outcome.datasets.clone(),
        repeatability: outcome.repeatability.clone(),
        mounting_findings: outcome.mountings.clone(),
        sensor_axes: crate::axes::entries(&outcome.axes),
        sensor_axes_checked: SensorAxesChecked {
            checks: outcome.axes.checks.clone(),
            stated_margin_nats: outcome.axes.stated_margin_nats,
        },
        normals_rotation,
        normals_rotation_not_fitted,
        reported,
    }
}

/// The largest prior sigma of a used photodiode's normal, deg: the mounting uncertainty
/// the user stated.
fn normals_prior_deg(run: &pdcal_filter::CalibrationRun) -> f64 {
    run.initial
        .photodiodes
        .iter()
        .zip(&run.used_photodiodes)
        .filter(|(_, used)| **used)
        .map(|(p, _)| p.elevation_sigma_deg)
        .fold(0.0, f64::max)
}

/// The warning of what the normals' common turn says of the mounting, judged against the
/// normals' prior sigma (the mounting uncertainty the user stated): a finding
/// ([`pdcal_filter::CommonRotation::warning`]); a determined turn larger than that prior
/// that is no finding (independent mounting errors could share it); or, when the data did
/// not determine the turn, a turn larger than that prior that they would leave unseen
/// (the residuals and the comparison of downlinks cannot see it either: a head turned
/// about the Sun line moves nothing they test). A run whose data check the mounting to
/// within its prior says nothing.
pub fn mounting_warning(
    run: &pdcal_filter::CalibrationRun,
    rotation: &Result<pdcal_filter::CommonRotation, NotFitted>,
) -> Option<String> {
    let prior_deg = normals_prior_deg(run);
    let r = match rotation {
        Ok(r) if r.finding => return r.warning(),
        Ok(r) => r,
        Err(why) => {
            return why
                .unchecked()
                .then(|| format!("the mounting was not checked: {why}"));
        }
    };
    if r.chi_square > r.chi_square_threshold {
        return (r.angle_deg > prior_deg).then(|| {
            format!(
                "the normals are turned together by more than their prior sigma ({prior_deg:.1} \
                 deg): {}: a head mounted turned, independent mounting errors that share a \
                 turn, or an attitude error the normals took up; check the mounting",
                r.describe()
            )
        });
    }
    (r.unseen_turn_deg > prior_deg).then(|| {
        format!(
            "the mounting was not checked: a turn of the head by up to about {:.0} deg, more \
             than the normals' prior sigma ({prior_deg:.1} deg), would go unseen by the \
             normals' common turn, the residuals and the comparison of downlinks ({})",
            r.unseen_turn_deg,
            r.describe()
        )
    })
}

/// `consistency` with `notes` among its notes: what the verdict did not test (a head turned
/// about the Sun line moves nothing the residuals test; sensor axes the data could not
/// check), or found beside it.
fn with_notes(
    consistency: &pdcal_filter::Consistency,
    notes: impl Iterator<Item = String>,
) -> pdcal_filter::Consistency {
    let mut c = consistency.clone();
    c.notes.extend(notes);
    c
}

/// [`mounting_warning`] of `run`'s own common rotation.
pub fn mounting_warning_of(run: &pdcal_filter::CalibrationRun) -> Option<String> {
    mounting_warning(run, &normals_rotation(run))
}

/// The common rotation of the used photodiodes' estimated normals from the nominal
/// mounting, when the data determined it, or why not. Every normal used with the attitude
/// held for some of its time takes part, a `not-determined` one too: the fit weighs each by the joint final covariance, so a
/// normal the data hardly moved counts for little, and the normals' common turn can be
/// determined while no single normal is (with the ensemble's widened covariances,
/// [`pdcal_filter::ensemble`], most normals of an uncalibrated Sun-only head are
/// `not-determined` one by one). A rotation whose sigma about any axis is above
/// [`NOT_DETERMINED_SIGMA_RATIO`] of the normals' prior sigma is the prior's, not the
/// data's, and is not reported, by the rule of [`pdcal_filter::identifiability`]; the
/// reason then says so, with that sigma.
fn normals_rotation(
    run: &pdcal_filter::CalibrationRun,
) -> Result<pdcal_filter::CommonRotation, NotFitted> {
    let prior_deg = normals_prior_deg(run);
    // A normal learnt with the attitude never held has a covariance from updates
    // linearised far from the truth (`identifiability`): it does not take part.
    let fitted: Vec<bool> = run
        .used_photodiodes
        .iter()
        .zip(&run.photodiode_time_held_s)
        .map(|(used, held_s)| *used && *held_s > 0.0)
        .collect();
    let used = run.used_photodiodes.iter().filter(|u| **u).count();
    let held = fitted.iter().filter(|f| **f).count();
    let minimum = pdcal_filter::common_rotation::MIN_PHOTODIODES;
    let r = pdcal_filter::common_rotation::common_rotation(
        &run.initial,
        &run.calibration,
        &run.final_covariance,
        &run.layout,
        &fitted,
    )
    .ok_or(match held < minimum {
        true => NotFitted::TooFewHeld { used, held },
        false => NotFitted::NotPositiveDefinite,
    })?;
    let bound_deg = NOT_DETERMINED_SIGMA_RATIO * prior_deg;
    if r.sigma_body_deg.iter().any(|s| *s > bound_deg) {
        return Err(NotFitted::PriorSigma {
            sigma_body_deg: r.sigma_body_deg,
            bound_deg,
            unseen_turn_deg: r.unseen_turn_deg,
        });
    }
    Ok(r)
}

/// Why the normals' common turn is not reported (`normals_rotation_not_fitted`).
#[derive(Debug, Clone, PartialEq)]
pub enum NotFitted {
    /// Fewer than [`pdcal_filter::common_rotation::MIN_PHOTODIODES`] normals held.
    TooFewHeld {
        /// Photodiodes used.
        used: usize,
        /// Of them, lit with the attitude held.
        held: usize,
    },
    /// The normals' covariance or the fit's normal matrix is not positive definite.
    NotPositiveDefinite,
    /// Its sigma about some axis is the prior's, not the data's.
    PriorSigma {
        /// Its sigma per body axis, deg.
        sigma_body_deg: [f64; 3],
        /// The bound it passed ([`NOT_DETERMINED_SIGMA_RATIO`] of the normals' prior), deg.
        bound_deg: f64,
        /// The turn the data would leave unseen, deg.
        unseen_turn_deg: f64,
    },
}

impl NotFitted {
    /// Whether the data left the mounting unchecked (not a fault of the covariance), and
    /// there were normals enough to check it with.
    fn unchecked(&self) -> bool {
        match self {
            NotFitted::TooFewHeld { used, .. } => {
                *used >= pdcal_filter::common_rotation::MIN_PHOTODIODES
            }
            NotFitted::NotPositiveDefinite => false,
            NotFitted::PriorSigma { .. } => true,
        }
    }
}

impl std::fmt::Display for NotFitted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let minimum = pdcal_filter::common_rotation::MIN_PHOTODIODES;
        match self {
            NotFitted::TooFewHeld { used, held } => write!(
                f,
                "{used} photodiodes used, {held} of them with the attitude held, fewer than the \
                 {minimum} a common turn of the normals is fitted to: a head mounted turned is \
                 not tested"
            ),
            NotFitted::NotPositiveDefinite => write!(
                f,
                "the normals' covariance is not positive definite: a head mounted turned is not \
                 tested"
            ),
            NotFitted::PriorSigma {
                sigma_body_deg: s,
                bound_deg,
                unseen_turn_deg,
            } => write!(
                f,
                "the normals' common turn has a sigma of {:.1}, {:.1}, {:.1} deg about body x, \
                 y, z, above {bound_deg:.1} deg ({NOT_DETERMINED_SIGMA_RATIO} of the normals' \
                 prior): the prior's, not the data's; a head mounted turned by up to about \
                 {unseen_turn_deg:.0} deg would go unseen",
                s[0], s[1], s[2]
            ),
        }
    }
}

/// A warning when the attitude was lost (a segment ended because its sigma in the observed
/// directions outgrew the bound, or its innovations went wrong): how often, and the first
/// reason. Each loss restarts the attitude from the data; a run that loses it often is one
/// whose model and data disagree, or whose data hold the attitude only briefly.
fn attitude_losses(segments: &[pdcal_filter::SegmentReport]) -> Option<String> {
    let mut lost = segments.iter().filter_map(|s| s.lost.as_deref());
    let first = lost.next()?;
    let count = 1 + lost.count();
    Some(format!(
        "the attitude was lost {count} time(s) in {} segments (first: {first}); each loss \
         restarts the attitude from the data, and states learnt across losses rest on the \
         stretches between them: a run that loses it often has a model and data that \
         disagree, or data that hold the attitude only briefly (the segment table lists \
         each)",
        segments.len()
    ))
}

/// A warning naming the Sun-only segments whose attitude the data did not tell from its
/// half turn about the Sun line ([`pdcal_filter::sun_line`]): their attitude estimates
/// may be the mirrored one, whatever their sigmas say.
fn about_sun_line_undecided(segments: &[pdcal_filter::SegmentReport]) -> Option<String> {
    let undecided: Vec<String> = segments
        .iter()
        .enumerate()
        .filter_map(|(i, s)| {
            let a = s.about_sun_line.as_ref()?;
            (!a.decided).then(|| format!("{i} (-2 ln odds {:.1})", a.neg2_ln_likelihood_ratio))
        })
        .collect();
    (!undecided.is_empty()).then(|| {
        format!(
            "segments {}: the photodiodes alone did not tell the attitude about the Sun line \
             from its half turn (odds below those of a 3-sigma event); their attitude \
             estimates may be the mirrored one, whatever the sigmas say",
            undecided.join(", ")
        )
    })
}

/// A warning per gyro-bias axis whose estimate lies beyond 3 sigma of its prior: the prior
/// (`initial_bias_sigma_deg_s`) was too narrow for this gyro, and the attitude and every
/// number that leaned on it were held by a wrong model while the bias converged.
fn bias_beyond_prior(initial: &Calibration, calibration: &Calibration) -> Vec<String> {
    (0..3)
        .filter_map(|k| {
            let prior = initial.gyro_bias_sigma_rad_s[k];
            let change = calibration.gyro_bias_rad_s[k] - initial.gyro_bias_rad_s[k];
            (prior > 0.0 && change.abs() > 3.0 * prior).then(|| {
                format!(
                    "gyro bias {} = {:.3} deg/s is {:.1} sigma of its prior ({:.3} deg/s): \
                     set a wider initial_bias_sigma_deg_s in --config for this gyro",
                    ["x", "y", "z"][k],
                    calibration.gyro_bias_rad_s[k].to_degrees(),
                    change.abs() / prior,
                    prior.to_degrees()
                )
            })
        })
        .collect()
}

/// The first row of the last data set: the one the final estimate belongs to. An earlier
/// set's bias is another turn-on of the gyro (the bias restarts with each set,
/// [`pdcal_filter::BiasAcrossSets`]), and even carried across sets it is weeks of walk away;
/// its fit says nothing of whether the final estimate's set was fitted well.
fn last_set_row(datasets: &[DatasetSummary]) -> usize {
    datasets.last().map_or(0, |d| d.span.first_row)
}

/// The bias at the first acquisition from `first_row` on.
fn first_bias_from(
    run: &pdcal_filter::CalibrationRun,
    first_row: usize,
) -> Option<&pdcal_filter::InitialBias> {
    run.segments
        .iter()
        .filter(|s| s.first_row >= first_row)
        .find_map(|s| s.initial_bias.as_ref())
}

/// The bias fit at the last data set's first acquisition, when the attitude was never held
/// since the bias last started from its prior: every update after the fit was then
/// linearised at an attitude less certain than the held bound (as a photodiode lit only
/// then, `pdcal_filter::identifiability`), and narrowed the bias by information that is not
/// the data's.
fn unheld_bias_fit<'a>(
    run: &'a pdcal_filter::CalibrationRun,
    datasets: &[DatasetSummary],
) -> Option<&'a pdcal_filter::InitialBias> {
    (run.bias_time_held_s <= 0.0)
        .then(|| first_bias_from(run, last_set_row(datasets)))
        .flatten()
        .filter(|b| b.source == pdcal_filter::BiasSource::Fit)
}

/// The reported gyro-bias sigma no narrower than `fit`'s on any axis still reported as an
/// estimate, with the reason added to its status.
fn floor_bias_sigma(
    fit: &pdcal_filter::InitialBias,
    reported: &mut Calibration,
    status: &mut [pdcal_filter::identifiability::Judged; 3],
) {
    for (k, judged) in status.iter_mut().enumerate() {
        let fit_sigma = fit.sigma_deg_s[k].to_radians();
        if judged.status == pdcal_filter::identifiability::Status::NotDetermined
            || reported.gyro_bias_sigma_rad_s[k] >= fit_sigma
        {
            continue;
        }
        reported.gyro_bias_sigma_rad_s[k] = fit_sigma;
        judged.reason = format!(
            "{}; reported with the sigma of its fit at acquisition, {:.3} deg/s: with the \
             attitude never held, no later update narrowed it by the data",
            judged.reason, fit.sigma_deg_s[k]
        );
    }
}

/// A warning when the last data set's first acquisition took its bias from the fit and the
/// final estimate lies beyond 3 sigma of it on some axis: the fit, which held that
/// acquisition's first minutes' attitude, was off (a Sun vector worse than its sigma, a
/// rate the gyro did not measure).
fn bias_beyond_fit(
    initial: &pdcal_filter::InitialBias,
    calibration: &Calibration,
) -> Option<String> {
    if initial.source != pdcal_filter::BiasSource::Fit {
        return None;
    }
    let sigmas: Vec<f64> = (0..3)
        .map(|k| {
            let change = calibration.gyro_bias_rad_s[k].to_degrees() - initial.bias_deg_s[k];
            change.abs() / initial.sigma_deg_s[k]
        })
        .collect();
    let worst = sigmas.iter().copied().fold(0.0, f64::max);
    (worst > 3.0).then(|| {
        format!(
            "gyro bias: the final estimate lies {worst:.1} sigma from the fit at the first \
             acquisition of its data set ({:.3}, {:.3}, {:.3} deg/s): that segment's attitude \
             leaned on a wrong bias",
            initial.bias_deg_s[0], initial.bias_deg_s[1], initial.bias_deg_s[2]
        )
    })
}

/// The photodiode's status reason: each quantity that is not `calibrated`, with its own.
fn status_reason(d: &PdIdentifiability) -> String {
    [
        ("scale", &d.scale),
        ("azimuth", &d.azimuth),
        ("elevation", &d.elevation),
    ]
    .iter()
    .filter(|(_, j)| j.status != Status::Calibrated)
    .map(|(name, j)| format!("{name} {}: {}", j.status.as_str(), j.reason))
    .collect::<Vec<_>>()
    .join("; ")
}

/// `calibration.ron`'s `status` lines: every quantity that is not `calibrated`.
fn status_lines(photodiodes: &[PdIdentifiability], bias: &[Judged; 3]) -> Vec<String> {
    let mut lines = Vec::new();
    for (i, d) in photodiodes.iter().enumerate() {
        for (name, j) in [
            ("scale_V", &d.scale),
            ("azimuth_deg", &d.azimuth),
            ("elevation_deg", &d.elevation),
        ] {
            if j.status != Status::Calibrated {
                lines.push(format!(
                    "pd{:02} {name}: {} ({})",
                    i + 1,
                    j.status.as_str(),
                    j.reason
                ));
            }
        }
    }
    for (axis, j) in ["x", "y", "z"].iter().zip(bias) {
        if j.status != Status::Calibrated {
            lines.push(format!(
                "gyro_bias_{axis}: {} ({})",
                j.status.as_str(),
                j.reason
            ));
        }
    }
    lines
}

fn counts_json(run: &CalibrationRun) -> serde_json::Value {
    let class = |c: &pdcal_filter::SensorCounts| {
        serde_json::json!({
            "accepted": c.accepted, "gated": c.gated, "not_sampled": c.not_sampled,
            "shadowed": c.shadowed, "outside_fov": c.outside_fov, "unused_sensor": c.unused_sensor,
            "contradicted": c.contradicted,
        })
    };
    serde_json::json!({
        "photodiode": class(&run.counts.photodiode),
        "magnetometer": class(&run.counts.magnetometer),
    })
}

/// `summary.json` `sensor_axes_checked`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SensorAxesChecked {
    /// The checks that had enough data.
    pub checks: Vec<pdcal_axes::CheckCount>,
    /// The next hypothesis's loss to the stated axes, nats (null when a hypothesis fit
    /// better than the stated axes).
    pub stated_margin_nats: Option<f64>,
}

/// Everything a calibration produces, in memory.
pub struct Outcome {
    /// The filter run (forward, smoother, residuals, calibration).
    pub run: CalibrationRun,
    /// Sun-vector magnitude and direction metrics (Figs. 8-11).
    pub sun_vector: SunVectorMetrics,
    /// Photodiode residual statistics over every row.
    pub residuals: ResidualSummary,
    /// Whether the residuals are consistent with the model ([`pdcal_filter::consistency`]).
    pub consistency: pdcal_filter::Consistency,
    /// Wall-clock time of the filter run, s.
    pub runtime_s: f64,
    /// Physical-plausibility warnings on the input ([`crate::checks`]), one line each.
    pub warnings: Vec<String>,
    /// The data sets of a joint calibration with their own residual statistics (empty for
    /// one data set).
    pub datasets: Vec<DatasetSummary>,
    /// Photodiodes whose data contradict their nominal mounting or polarity, and what the
    /// calibration did about each ([`crate::mounting`]).
    pub mountings: Vec<pdcal_filter::mounting::MountingFinding>,
    /// With several data sets, whether their own estimates agree
    /// ([`crate::repeatability`]).
    pub repeatability: Option<crate::repeatability::Repeatability>,
    /// The sensor-axes check before the filter ([`crate::axes`]).
    pub axes: pdcal_axes::AxesCheck,
}

/// One data set of a calibration and the statistics of its own photodiode residuals
/// (`summary.json` `datasets`).
#[derive(Debug, Clone, Serialize)]
pub struct DatasetSummary {
    /// Where it sits among the sets.
    #[serde(flatten)]
    pub span: crate::joint::SetSpan,
    /// Its photodiode residuals.
    pub residuals: ResidualSummary,
    /// The consistency verdict of its own residuals.
    pub consistency: pdcal_filter::Consistency,
    /// Its own estimate of every parameter against the other sets'
    /// ([`crate::repeatability`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub repeatability: Option<crate::repeatability::SetRepeatability>,
}

/// Whether the run made magnetometer updates.
fn magnetometer_used(mode: ModeUsed) -> bool {
    matches!(
        mode,
        ModeUsed::Full
            | ModeUsed::ScaleOnly {
                with_magnetometer: true
            }
    )
}

/// Which attitude directions the data observe: `all` with the magnetometer; `across-sun-line`
/// with the Sun as the only vector, where the rotation about the Sun line is informed by the
/// albedo alone (the attitude is judged lost, gated and held on the two axes across the
/// line, never on that rotation; its sigma grows as the gyro lets it).
fn attitude_observed(mode: ModeUsed) -> &'static str {
    if magnetometer_used(mode) {
        "all"
    } else {
        "across-sun-line"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_final_bias_beyond_three_sigmas_of_the_fit_is_a_warning() {
        let fit = |source| pdcal_filter::InitialBias {
            source,
            bias_deg_s: [1.0, -2.0, 0.5],
            sigma_deg_s: [0.1, 0.2, 0.1],
            directions: 3,
            vectors: 24,
            span_s: 120.0,
            reason: None,
        };
        let final_at = |deg: [f64; 3]| Calibration {
            format_version: 1,
            photodiodes: Vec::new(),
            gyro_bias_rad_s: deg.map(f64::to_radians),
            gyro_bias_sigma_rad_s: [1e-4; 3],
            parameters: Vec::new(),
            status: Vec::new(),
        };
        let fitted = fit(pdcal_filter::BiasSource::Fit);
        assert_eq!(bias_beyond_fit(&fitted, &final_at([1.25, -1.5, 0.6])), None);
        let w = bias_beyond_fit(&fitted, &final_at([1.0, -2.0, 0.9])).unwrap();
        assert!(
            w.starts_with("gyro bias: the final estimate lies 4.0 sigma"),
            "{w}"
        );
        // The prior is judged by the prior's own warning, not this one.
        let prior = fit(pdcal_filter::BiasSource::Prior);
        assert_eq!(bias_beyond_fit(&prior, &final_at([9.0, 9.0, 9.0])), None);
    }

    #[test]
    fn a_bias_beyond_three_prior_sigmas_is_a_warning() {
        let cal = |bias: [f64; 3], sigma: f64| Calibration {
            format_version: 1,
            photodiodes: Vec::new(),
            gyro_bias_rad_s: bias,
            gyro_bias_sigma_rad_s: [sigma; 3],
            parameters: Vec::new(),
            status: Vec::new(),
        };
        let prior = cal([0.0; 3], 0.5f64.to_radians());
        let within = cal([0.01, -0.02, 0.025], 1e-4);
        assert!(bias_beyond_prior(&prior, &within).is_empty());
        let beyond = cal([0.07, 0.0, -0.03], 1e-4);
        let w = bias_beyond_prior(&prior, &beyond);
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(
            w[0].starts_with("gyro bias x = 4.011 deg/s is 8.0 sigma"),
            "{}",
            w[0]
        );
        assert!(w[1].starts_with("gyro bias z"), "{}", w[1]);
    }

    #[test]
    fn flags_say_never_lit_too_little_and_implausible_change() {
        let init = pdcal_filter::PdCalibration {
            scale_v: 3.7,
            scale_sigma_v: 0.5,
            azimuth_deg: 0.0,
            azimuth_sigma_deg: Some(10.0),
            elevation_deg: 0.0,
            elevation_sigma_deg: 10.0,
        };
        let flag = |used, minutes, change| photodiode_flag(used, minutes, change, &init);
        assert_eq!(flag(false, 0.0, (0.0, 0.0)).as_deref(), Some("never lit"));
        assert_eq!(
            flag(true, 2.04, (1.0, 0.1)).as_deref(),
            Some("lit too little (2.0 min)")
        );
        assert_eq!(flag(true, 20.0, (9.0, -0.2)), None);
        let beyond = Some("change beyond 3 sigma of the prior");
        assert_eq!(flag(true, 20.0, (31.0, 0.0)).as_deref(), beyond);
        assert_eq!(flag(true, 20.0, (1.0, -1.6)).as_deref(), beyond);
    }
}
