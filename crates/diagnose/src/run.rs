//! One calibration of the diagnosis: what it reads ([`DiagnoseInputs`]), its tuning
//! ([`DiagnoseConfig`]), and the filter run with the model a [`ModelSpec`] describes, with or
//! without the residuals over every sample. The rounds ([`crate::diagnose`]) and the refit
//! scores ([`crate::refit`]) both run it.

use std::borrow::Cow;

use pdcal_albedo::AlbedoModel;
use pdcal_dataset::{DatasetMeta, EffectId, Telemetry};
use pdcal_ephem::Reference;
use pdcal_filter::{
    Algebra, CalibrationRun, FilterConfig, Mode, Prepared, RunInputs, calibrate_with_model,
};
use pdcal_photodiode::Photodiode;

use crate::DiagnoseError;
use crate::model::ModelSpec;
use crate::residuals::{ResidualInputs, Residuals, residuals};

/// What a diagnosis reads: the dataset's metadata and telemetry (never its truth), the
/// references, and the albedo model.
#[derive(Clone, Copy)]
pub struct DiagnoseInputs<'a> {
    /// dataset.ron.
    pub meta: &'a DatasetMeta,
    /// telemetry.csv.
    pub telemetry: &'a Telemetry,
    /// One reference per telemetry row.
    pub references: &'a [Reference],
    /// The albedo model (the filter's, and the albedo candidates' regressor).
    pub albedo: &'a AlbedoModel,
    /// Its reflectivity map's id (`toms-mean-1p25x1`), for the `albedo` effect it adds.
    pub albedo_map: &'a str,
}

/// Tuning of the diagnosis.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseConfig {
    /// The calibration filter's tuning.
    pub filter: FilterConfig,
    /// Most rounds (effects added or changed). Default 4.
    pub max_rounds: usize,
    /// A candidate is tried only when its score (nats, BIC already subtracted) exceeds
    /// this. Default [`DEFAULT_THRESHOLD`].
    pub threshold: f64,
    /// HAC window, telemetry rows. Default [`DEFAULT_MAX_LAG`].
    pub max_lag_rows: usize,
    /// Least fraction of the excess mean square (mean square minus noise variance) over the
    /// samples a photodiode candidate targets that its refit must remove. Default
    /// [`DEFAULT_MIN_SHRINK`].
    pub min_shrink: f64,
    /// Most significant candidates tried per round before the round gives up. Default 3.
    pub max_tries: usize,
}

/// Score threshold above the BIC, nats (see docs/diagnose.md: set from control seeds).
pub const DEFAULT_THRESHOLD: f64 = 10.0;
/// Bartlett window of the HAC covariance, rows (1 min at 1 Hz: longer than the correlation
/// time of the smoother's attitude error on the built-in scenarios).
pub const DEFAULT_MAX_LAG: usize = 60;
/// Default [`DiagnoseConfig::min_shrink`]: a named effect removes at least a quarter of the
/// misfit it targets (docs/diagnose.md gives the values seen for true and spurious effects).
pub const DEFAULT_MIN_SHRINK: f64 = 0.25;

impl Default for DiagnoseConfig {
    fn default() -> Self {
        DiagnoseConfig {
            filter: FilterConfig::default(),
            max_rounds: 4,
            threshold: DEFAULT_THRESHOLD,
            max_lag_rows: DEFAULT_MAX_LAG,
            min_shrink: DEFAULT_MIN_SHRINK,
            max_tries: 3,
        }
    }
}

pub(crate) fn residual_inputs<'a>(
    inputs: &'a DiagnoseInputs<'a>,
    telemetry: &'a Telemetry,
    config: &'a DiagnoseConfig,
) -> ResidualInputs<'a> {
    ResidualInputs {
        meta: inputs.meta,
        telemetry,
        references: inputs.references,
        albedo: inputs.albedo,
        albedo_map: inputs.albedo_map,
        config: &config.filter,
    }
}

/// Calibrates with the model `spec` describes, forward filter only (no smoother), and
/// adopts the filter's estimates of its estimated effects: what a refit score needs.
pub(crate) fn forward_run(
    inputs: &DiagnoseInputs<'_>,
    spec: &mut ModelSpec,
    config: &DiagnoseConfig,
) -> Result<CalibrationRun, DiagnoseError> {
    let filter = FilterConfig {
        smoother: false,
        ..config.filter.clone()
    };
    let telemetry = spec.corrected_telemetry(inputs.telemetry);
    let run = filter_run(inputs, spec, &filter, &telemetry)?;
    spec.adopt_estimates(&run.calibration);
    Ok(run)
}

/// Calibrates with the model `spec` describes (its sensor corrections applied to the
/// telemetry), adopts the filter's estimates of its estimated effects, and computes the
/// residuals over every sample.
pub fn calibrate_and_residuals(
    inputs: &DiagnoseInputs<'_>,
    spec: &mut ModelSpec,
    config: &DiagnoseConfig,
) -> Result<(CalibrationRun, Residuals), DiagnoseError> {
    let telemetry = spec.corrected_telemetry(inputs.telemetry);
    let screened = screened(inputs, &telemetry, config)?;
    let run = filter_run(inputs, spec, &config.filter, screened.telemetry())?;
    spec.adopt_estimates(&run.calibration);
    let corrected = spec.albedo_model(inputs.albedo);
    let inputs = &DiagnoseInputs {
        albedo: corrected.as_ref().unwrap_or(inputs.albedo),
        ..*inputs
    };
    let res = residuals(
        &residual_inputs(inputs, screened.telemetry(), config),
        spec,
        &run,
    )?;
    Ok((run, res))
}

/// `telemetry` screened as the filter screens it: the residuals read the telemetry the
/// filter read, and a wild sample the screening removed (a gyro reading of 1e300 deg/s) is
/// no residual of the model.
pub(crate) fn screened<'a>(
    inputs: &DiagnoseInputs<'_>,
    telemetry: &'a Telemetry,
    config: &DiagnoseConfig,
) -> Result<Prepared<'a>, DiagnoseError> {
    Ok(Prepared::new(
        inputs.meta,
        Cow::Borrowed(telemetry),
        &config.filter,
    )?)
}

/// One calibration with the model `spec` describes on `telemetry` (already corrected).
fn filter_run(
    inputs: &DiagnoseInputs<'_>,
    spec: &ModelSpec,
    filter: &FilterConfig,
    telemetry: &Telemetry,
) -> Result<CalibrationRun, DiagnoseError> {
    let nominal: Vec<Photodiode> = pdcal_filter::nominal_photodiodes(inputs.meta);
    let model = spec.measurement_model(nominal, filter)?;
    let mut filter = filter.clone();
    filter
        .parameter_sigmas
        .splice(0..0, spec.parameter_sigmas());
    let filter = &filter;
    // Without albedo in the model, the filter's start (photodiode Sun vector) must not
    // remove it either.
    let corrected = spec.albedo_model(inputs.albedo);
    let albedo = spec
        .contains(EffectId::Albedo)
        .then_some(corrected.as_ref().unwrap_or(inputs.albedo));
    let prepared = Prepared::new(inputs.meta, Cow::Borrowed(telemetry), filter)?;
    let run_inputs = RunInputs {
        meta: inputs.meta,
        telemetry: prepared.telemetry(),
        references: inputs.references.into(),
        albedo,
        set_first_rows: &[],
    };
    Ok(calibrate_with_model(
        &run_inputs,
        &prepared,
        &Mode::Full,
        model,
        Algebra::Structured,
    )?)
}
