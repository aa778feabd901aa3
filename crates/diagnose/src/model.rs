//! The current model of a diagnosis: the base (`cosine` or `paper`) plus the effects found so
//! far with their fitted values, as a [`MeasurementModel`] for the filter and as corrections
//! to the telemetry (for the two effects the filter has no states for).

use std::str::FromStr;

use pdcal_albedo::AlbedoModel;
use pdcal_dataset::{Effect, EffectId, Telemetry};
use pdcal_effects::albedo_map_factor;
use pdcal_filter::{Calibration, FilterConfig, ParameterSigma};
use pdcal_photodiode::{
    Albedo, DirectSun, EffectModelOptions, MeasurementModel, ParameterRole, Photodiode, add_effect,
    estimated_values_mut,
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

/// Whether adding `effect` changes what the filter sees. `penumbra` acts only where the Sun
/// is partly hidden, and the filter uses photodiodes only in full Sun.
pub fn changes_filter(effect: &Effect) -> bool {
    effect.id() != EffectId::Penumbra
}

/// The base model plus the effects added so far, in the order they were found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelSpec {
    /// Where the diagnosis started.
    pub base: BaseModel,
    /// Effects found, in order.
    pub added: Vec<Effect>,
}

impl ModelSpec {
    /// The base model with nothing added.
    pub fn new(base: BaseModel) -> Self {
        ModelSpec {
            base,
            added: Vec::new(),
        }
    }

    /// Whether the model holds effect `id` (the paper base holds `albedo`).
    pub fn contains(&self, id: EffectId) -> bool {
        (id == EffectId::Albedo && self.base == BaseModel::Paper)
            || self.added.iter().any(|e| e.id() == id)
    }

    /// The added effect `id`, if any.
    pub fn added(&self, id: EffectId) -> Option<&Effect> {
        self.added.iter().find(|e| e.id() == id)
    }

    /// The model without the added effect `id`.
    pub fn without(&self, id: EffectId) -> ModelSpec {
        ModelSpec {
            base: self.base,
            added: self
                .added
                .iter()
                .filter(|e| e.id() != id)
                .cloned()
                .collect(),
        }
    }

    /// The effect ids of the model beyond the direct Sun: the base's, then the added ones.
    pub fn effect_ids(&self) -> Vec<EffectId> {
        let base = (self.base == BaseModel::Paper).then_some(EffectId::Albedo);
        base.into_iter()
            .chain(self.added.iter().map(Effect::id))
            .collect()
    }

    /// The measurement model for the filter: direct Sun (hard shadow), the base's albedo,
    /// then every photodiode effect added. Fitted constants are `Fixed` parameters; the
    /// effects a filter can estimate (`time-offset`, `scale-drift`, `albedo-gain`,
    /// `temperature`) are `Estimated`, filter states starting at the fit.
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
        let options = EffectModelOptions {
            albedo_partials: config.albedo_partials,
            role: ParameterRole::Estimated,
            time_offset_term: true,
        };
        for effect in &self.added {
            add_effect(&mut model, effect, options)?;
        }
        Ok(model)
    }

    /// The albedo model with the `albedo-map` correction applied, if the model holds one
    /// (else `None`: the map as given).
    pub fn albedo_model(&self, base: &AlbedoModel) -> Option<AlbedoModel> {
        match self.added(EffectId::AlbedoMap) {
            Some(Effect::AlbedoMap { latitude_gains }) => {
                Some(base.with_latitude_factor(|lat| albedo_map_factor(latitude_gains, lat)))
            }
            _ => None,
        }
    }

    /// Initial sigmas of the estimated parameters whose scale is the fitted value's own
    /// rather than their unit's: the Kelly roll-off's `kappa` (0.001 to 10 between data
    /// sets) starts at the fit with half its value as 1 sigma, so that the filter's first
    /// steps keep it positive. Put before the configured sigmas (names win over units).
    pub fn parameter_sigmas(&self) -> Vec<ParameterSigma> {
        self.added
            .iter()
            .filter_map(|e| match e {
                Effect::KellyRolloff { kappa, .. } => Some(ParameterSigma {
                    name_or_unit: "fov_rolloff_kappa".to_owned(),
                    sigma: 0.5 * kappa,
                    walk_per_sqrt_h: 0.0,
                }),
                _ => None,
            })
            .collect()
    }

    /// The telemetry with the added sensor corrections applied (`mag-bias` subtracted,
    /// the gyro divided by `1 + e` per axis).
    pub fn corrected_telemetry(&self, telemetry: &Telemetry) -> Telemetry {
        let mut out = telemetry.clone();
        for effect in &self.added {
            if let Some(mag) = out.mag_nt.as_mut() {
                mag.map_in_place(|m| effect.correct_mag(m));
            }
            out.gyro_rad_s.map_in_place(|w| effect.correct_gyro(w));
        }
        out
    }

    /// Replaces the starting values of the filter-estimated effects by the filter's final
    /// estimates (`calibration.parameters`, by the component's parameter names).
    pub fn adopt_estimates(&mut self, calibration: &Calibration) {
        for effect in &mut self.added {
            let names = parameter_names(effect);
            for (value, name) in estimated_values_mut(effect).into_iter().zip(names) {
                if let Some(p) = calibration.parameters.iter().find(|p| p.name == name) {
                    *value = p.value;
                }
            }
        }
    }
}

/// The names of the parameters of `effect`'s model component, in order.
pub(crate) fn parameter_names(effect: &Effect) -> Vec<String> {
    let n = effect.per_photodiode().map_or(0, |(_, v)| v.len());
    let mut model = MeasurementModel::new(vec![Photodiode::from_az_el_deg(1.0, 0.0, 0.0, 0.0); n]);
    let options = EffectModelOptions {
        time_offset_term: true,
        ..EffectModelOptions::default()
    };
    match add_effect(&mut model, effect, options) {
        Ok(true) => model.parameters().map(|(_, p)| p.name.clone()).collect(),
        _ => Vec::new(),
    }
}
