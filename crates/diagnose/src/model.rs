//! The current model of a diagnosis: the base (`cosine` or `paper`) plus the effects found so
//! far with their fitted values, as a [`MeasurementModel`] for the filter and as corrections
//! to the telemetry (for the two effects the filter has no states for).

use std::str::FromStr;

use nalgebra::Vector3;
use pdcal_dataset::{Effect, Telemetry};
use pdcal_filter::{Calibration, FilterConfig};
use pdcal_photodiode::{
    Albedo, DarkOffset, DirectSun, FovRolloff, MeasurementModel, ParameterRole, Penumbra,
    Photodiode, Saturation, ScaleDrift, TimeOffset,
};
use serde::Serialize;

use crate::DiagnoseError;

/// The model a diagnosis starts from (`--base-model`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BaseModel {
    /// Direct Sun only, paper Eq. (11).
    Cosine,
    /// Direct Sun plus albedo, paper Eq. (15).
    Paper,
}

impl BaseModel {
    /// The command-line spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            BaseModel::Cosine => "cosine",
            BaseModel::Paper => "paper",
        }
    }
}

impl FromStr for BaseModel {
    type Err = DiagnoseError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "cosine" => Ok(BaseModel::Cosine),
            "paper" => Ok(BaseModel::Paper),
            other => Err(DiagnoseError::BaseModel(other.to_owned())),
        }
    }
}

/// An effect the diagnosis added, with its fitted (or filter-estimated) values.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "id", rename_all = "kebab-case")]
pub enum AddedEffect {
    /// `albedo`: the paper's Eq. (13) term (no parameters).
    Albedo,
    /// `fov-rolloff`: raised-cosine taper, fixed at the fitted angles (the filter gates at
    /// 60 deg incidence, where the taper's parameters are not observable).
    FovRolloff {
        /// Start of the roll-off, rad.
        start_rad: f64,
        /// Zero output from here, rad.
        cutoff_rad: f64,
    },
    /// `dark-offset`: fixed per-photodiode offsets, V, fitted in umbra.
    DarkOffset {
        /// Offset per photodiode, V.
        volts: Vec<f64>,
    },
    /// `saturation`: fixed shared clip level, V.
    Saturation {
        /// Clip level, V.
        volts: f64,
    },
    /// `penumbra`: the direct Sun scaled by the illuminated fraction (no parameters).
    Penumbra,
    /// `time-offset`: a filter state, initialised at the refit's estimate ([`crate::refit`]).
    TimeOffset {
        /// Tag minus sampling time, s.
        seconds: f64,
    },
    /// `scale-drift`: per-photodiode filter states, initialised at the residual fit.
    ScaleDrift {
        /// Relative drift per hour, per photodiode.
        fraction_per_hour: Vec<f64>,
    },
    /// `mag-bias`: subtracted from the magnetometer telemetry (the filter has no bias state).
    MagBias {
        /// Bias, body frame, nT.
        #[serde(rename = "nT")]
        bias_nt: [f64; 3],
    },
    /// `gyro-scale`: the gyro telemetry divided by `1 + e` per axis (no filter state).
    GyroScale {
        /// Scale-factor error per body axis.
        scale_error: [f64; 3],
    },
}

impl AddedEffect {
    /// The effect id of `cli-contract.md`.
    pub fn id(&self) -> &'static str {
        match self {
            AddedEffect::Albedo => "albedo",
            AddedEffect::FovRolloff { .. } => "fov-rolloff",
            AddedEffect::DarkOffset { .. } => "dark-offset",
            AddedEffect::Saturation { .. } => "saturation",
            AddedEffect::Penumbra => "penumbra",
            AddedEffect::TimeOffset { .. } => "time-offset",
            AddedEffect::ScaleDrift { .. } => "scale-drift",
            AddedEffect::MagBias { .. } => "mag-bias",
            AddedEffect::GyroScale { .. } => "gyro-scale",
        }
    }

    /// Folds a second fit of the same effect, made on the residuals of a model that already
    /// holds `self`, into `self`; true when the effect has such fitted constants
    /// (`dark-offset`, `mag-bias`, `gyro-scale`). The filter's attitude absorbs part of a
    /// magnetometer bias or gyro scale error, so their first fit is short of the truth and
    /// a few alternations converge.
    pub fn refine(&mut self, increment: &AddedEffect) -> bool {
        match (self, increment) {
            (AddedEffect::DarkOffset { volts }, AddedEffect::DarkOffset { volts: more }) => {
                volts.iter_mut().zip(more).for_each(|(v, d)| *v += d);
                true
            }
            (AddedEffect::MagBias { bias_nt }, AddedEffect::MagBias { bias_nt: more }) => {
                bias_nt.iter_mut().zip(more).for_each(|(v, d)| *v += d);
                true
            }
            (
                AddedEffect::GyroScale { scale_error },
                AddedEffect::GyroScale { scale_error: more },
            ) => {
                // Telemetry divided by (1 + e1), then by (1 + e2).
                scale_error
                    .iter_mut()
                    .zip(more)
                    .for_each(|(e, d)| *e = (1.0 + *e) * (1.0 + d) - 1.0);
                true
            }
            _ => false,
        }
    }

    /// Whether adding this effect changes what the filter sees. `penumbra` acts only where
    /// the Sun is partly hidden, and the filter uses photodiodes only in full Sun.
    pub fn changes_filter(&self) -> bool {
        !matches!(self, AddedEffect::Penumbra)
    }

    /// The same effect as the truth's `Effect` record (for comparing with truth.ron).
    pub fn to_effect(&self) -> Effect {
        match self {
            AddedEffect::Albedo => Effect::Albedo {
                map: "toms-mean-1p25x1".into(),
            },
            AddedEffect::FovRolloff {
                start_rad,
                cutoff_rad,
            } => Effect::FovRolloff {
                start_deg: start_rad.to_degrees(),
                cutoff_deg: cutoff_rad.to_degrees(),
            },
            AddedEffect::DarkOffset { volts } => Effect::DarkOffset {
                volts: volts.clone(),
            },
            AddedEffect::Saturation { volts } => Effect::Saturation { volts: *volts },
            AddedEffect::Penumbra => Effect::Penumbra,
            AddedEffect::TimeOffset { seconds } => Effect::TimeOffset { seconds: *seconds },
            AddedEffect::ScaleDrift { fraction_per_hour } => Effect::ScaleDrift {
                fraction_per_hour: fraction_per_hour.clone(),
            },
            AddedEffect::MagBias { bias_nt } => Effect::MagBias { bias_nt: *bias_nt },
            AddedEffect::GyroScale { scale_error } => Effect::GyroScale {
                scale_error: *scale_error,
            },
        }
    }
}

/// The base model plus the effects added so far, in the order they were found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelSpec {
    /// Where the diagnosis started.
    pub base: BaseModel,
    /// Effects found, in order.
    pub added: Vec<AddedEffect>,
}

impl ModelSpec {
    /// The base model with nothing added.
    pub fn new(base: BaseModel) -> Self {
        ModelSpec {
            base,
            added: Vec::new(),
        }
    }

    /// Whether the model explains effect `id` (the paper base holds `albedo`).
    pub fn contains(&self, id: &str) -> bool {
        (id == "albedo" && self.base == BaseModel::Paper) || self.added.iter().any(|e| e.id() == id)
    }

    /// The effect ids of the model beyond the direct Sun: the base's, then the added ones.
    pub fn effect_ids(&self) -> Vec<String> {
        let base = (self.base == BaseModel::Paper).then(|| "albedo".to_owned());
        base.into_iter()
            .chain(self.added.iter().map(|e| e.id().to_owned()))
            .collect()
    }

    /// The measurement model for the filter: direct Sun (hard shadow), the base's albedo,
    /// then every photodiode effect added. Fitted constants are `Fixed` parameters;
    /// `time-offset` and `scale-drift` are `Estimated` (filter states starting at the fit).
    pub fn measurement_model(
        &self,
        photodiodes: Vec<Photodiode>,
        config: &FilterConfig,
    ) -> Result<MeasurementModel, DiagnoseError> {
        let mut model = MeasurementModel::new(photodiodes);
        model.add_term(DirectSun::default())?;
        if self.base == BaseModel::Paper {
            model.add_term(Albedo {
                partials: config.albedo_partials,
            })?;
        }
        for effect in &self.added {
            match effect {
                AddedEffect::Albedo => model.add_term(Albedo {
                    partials: config.albedo_partials,
                })?,
                AddedEffect::FovRolloff {
                    start_rad,
                    cutoff_rad,
                } => model.add_term(FovRolloff::new(*start_rad, *cutoff_rad)?)?,
                AddedEffect::DarkOffset { volts } => model.add_term(DarkOffset::new(volts))?,
                AddedEffect::Saturation { volts } => model.add_stage(Saturation::shared(*volts))?,
                AddedEffect::Penumbra => model.add_term(Penumbra)?,
                AddedEffect::TimeOffset { seconds } => {
                    model.add_term(TimeOffset::new(*seconds))?;
                    estimate_parameters(&mut model, "time-offset")?;
                }
                AddedEffect::ScaleDrift { fraction_per_hour } => {
                    model.add_gain(ScaleDrift::per_photodiode(fraction_per_hour))?;
                    estimate_parameters(&mut model, "scale-drift")?;
                }
                AddedEffect::MagBias { .. } | AddedEffect::GyroScale { .. } => {}
            }
        }
        Ok(model)
    }

    /// The telemetry with the added sensor corrections applied: the magnetometer bias
    /// subtracted, the gyro divided by `1 + e` per axis (the simulator's
    /// `measured = (1 + e) w + bias + noise`).
    pub fn corrected_telemetry(&self, telemetry: &Telemetry) -> Telemetry {
        let mut out = telemetry.clone();
        for effect in &self.added {
            match effect {
                AddedEffect::MagBias { bias_nt } => {
                    let b = Vector3::from(*bias_nt);
                    if let Some(mag) = out.mag_nt.as_mut() {
                        mag.iter_mut().flatten().for_each(|m| *m -= b);
                    }
                }
                AddedEffect::GyroScale { scale_error } => {
                    let f = Vector3::from(*scale_error).map(|e| 1.0 / (1.0 + e));
                    out.gyro_rad_s
                        .iter_mut()
                        .flatten()
                        .for_each(|w| *w = w.component_mul(&f));
                }
                _ => {}
            }
        }
        out
    }

    /// Replaces the starting values of the filter-estimated effects by the filter's final
    /// estimates (`calibration.parameters`, by name).
    pub fn adopt_estimates(&mut self, calibration: &Calibration) {
        let value = |name: &str| {
            calibration
                .parameters
                .iter()
                .find(|p| p.name == name)
                .map(|p| p.value)
        };
        for effect in &mut self.added {
            match effect {
                AddedEffect::TimeOffset { seconds } => {
                    if let Some(v) = value("time_offset_s") {
                        *seconds = v;
                    }
                }
                AddedEffect::ScaleDrift { fraction_per_hour } => {
                    for (i, k) in fraction_per_hour.iter_mut().enumerate() {
                        if let Some(v) = value(&format!("pd{:02}_scale_drift_per_h", i + 1)) {
                            *k = v;
                        }
                    }
                }
                _ => {}
            }
        }
    }
}

/// Marks every parameter of component `id` as a filter state.
fn estimate_parameters(model: &mut MeasurementModel, id: &str) -> Result<(), DiagnoseError> {
    let indices: Vec<usize> = model
        .parameters()
        .enumerate()
        .filter(|(_, (c, _))| *c == id)
        .map(|(k, _)| k)
        .collect();
    for k in indices {
        model.parameter_mut(k)?.role = ParameterRole::Estimated;
    }
    Ok(())
}
