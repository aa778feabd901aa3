//! The run's first stage, done once: the configuration validated, the sensor sigmas
//! resolved, the telemetry screened ([`crate::screen`]) and its segment rules measured
//! ([`GapRules`]). The forward pass ([`crate::forward::ForwardPass`]) starts from the
//! [`Prepared`] value; a driver that reads the screened telemetry itself (Sun-vector
//! metrics, figures, checks of the mountings) holds the same value, so nothing is screened
//! or resolved twice.

use std::borrow::Cow;

use pdcal_albedo::AlbedoModel;
use pdcal_dataset::{DatasetMeta, Telemetry};

use crate::config::{FilterConfig, SensorSigmas};
use crate::error::check_len;
use crate::screen::{Rejections, ScreenTolerances, find_outliers, remove_outliers};
use crate::segments::GapRules;
use crate::{FilterError, References};

/// What a run reads: the dataset's metadata and telemetry (never its truth), one reference
/// per telemetry row, and optionally the albedo model.
#[derive(Clone, Copy)]
pub struct RunInputs<'a> {
    /// dataset.ron.
    pub meta: &'a DatasetMeta,
    /// telemetry.csv; for a forward pass, the screened telemetry of its [`Prepared`]
    /// ([`Prepared::inputs`]).
    pub telemetry: &'a Telemetry,
    /// Sun, field, eclipse fraction and frames at every telemetry row.
    pub references: References<'a>,
    /// Albedo model (the paper's Eq. 13); `None` runs without albedo.
    pub albedo: Option<&'a AlbedoModel>,
    /// The first telemetry row of each data set of a joint run after the first (empty for
    /// one set): where [`FilterConfig::gyro_bias_across_sets`] applies.
    pub set_first_rows: &'a [usize],
}

/// A run's settled inputs: the validated configuration, the resolved sensor sigmas, the
/// screened telemetry with the samples the screening rejected, and the gap rules of its
/// segments.
#[derive(Debug, Clone)]
pub struct Prepared<'a> {
    config: FilterConfig,
    sigmas: SensorSigmas,
    telemetry: Cow<'a, Telemetry>,
    screened: Rejections,
    rules: GapRules,
}

impl<'a> Prepared<'a> {
    /// Validates `config`, resolves the sensor sigmas (the config's, else `meta`'s noise
    /// hints), screens `telemetry` (a borrowed one is copied only when a sample is
    /// rejected) and measures the gap rules of the screened telemetry.
    pub fn new(
        meta: &DatasetMeta,
        telemetry: Cow<'a, Telemetry>,
        config: &FilterConfig,
    ) -> Result<Self, FilterError> {
        config.validate()?;
        let m = meta.photodiodes.len();
        check_len("telemetry photodiode columns", m, telemetry.pd_v.len())?;
        let sigmas = config.resolve(meta.noise.as_ref());
        let mut screened = Rejections::new(m);
        let mut telemetry = telemetry;
        let outliers = find_outliers(&telemetry, &ScreenTolerances::new(config, &sigmas));
        if !outliers.is_empty() {
            remove_outliers(telemetry.to_mut(), &outliers);
            for &(channel, k) in &outliers {
                screened.push_screened(channel, k);
            }
        }
        // Magnetometer columns without a sample are no magnetometer: the run is the
        // photodiodes' alone, as without the columns.
        if (telemetry.mag_nt.as_ref()).is_some_and(|m| (0..m.len()).all(|k| m.get(k).is_none())) {
            telemetry.to_mut().mag_nt = None;
        }
        if telemetry.is_empty() {
            return Err(FilterError::NoInitialSample {
                reason: "the telemetry has no rows".to_owned(),
            });
        }
        let rules = GapRules::new(&config.segments, &telemetry);
        Ok(Prepared {
            config: config.clone(),
            sigmas,
            telemetry,
            screened,
            rules,
        })
    }

    /// [`Prepared::new`] of `inputs`' metadata and telemetry (borrowed).
    pub fn of(inputs: &RunInputs<'a>, config: &FilterConfig) -> Result<Self, FilterError> {
        Self::new(inputs.meta, Cow::Borrowed(inputs.telemetry), config)
    }

    /// `inputs` with the screened telemetry in place of theirs: what the forward pass
    /// reads.
    pub fn inputs<'b>(&'b self, inputs: &RunInputs<'b>) -> RunInputs<'b> {
        RunInputs {
            telemetry: self.telemetry(),
            ..*inputs
        }
    }

    /// The validated configuration.
    pub fn config(&self) -> &FilterConfig {
        &self.config
    }

    /// The sensor sigmas the run uses.
    pub fn sigmas(&self) -> SensorSigmas {
        self.sigmas
    }

    /// The screened telemetry: what [`crate::RunInputs::telemetry`] must be.
    pub fn telemetry(&self) -> &Telemetry {
        &self.telemetry
    }

    /// The screened telemetry, for a correction that leaves the row times and the gyro
    /// (the gap rules' inputs) as they are: the driver's mounting corrections swap and
    /// negate photodiode columns.
    pub fn telemetry_mut(&mut self) -> &mut Telemetry {
        self.telemetry.to_mut()
    }

    /// The samples the screening rejected.
    pub fn screened(&self) -> &Rejections {
        &self.screened
    }

    /// The gap rules of the screened telemetry.
    pub fn rules(&self) -> GapRules {
        self.rules
    }
}
