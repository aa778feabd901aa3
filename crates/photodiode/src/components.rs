//! The catalogue's effects as model components: the one place an [`Effect`] value becomes a
//! [`Term`](crate::Term), [`ScaleGain`](crate::ScaleGain) or
//! [`OutputStage`](crate::OutputStage), for the simulator's truth and the diagnosis's model
//! alike.

use pdcal_effects::{Effect, EffectId};

use crate::terms::{
    Albedo, AlbedoGain, AlbedoPartials, DarkOffset, FovRolloff, KellyRolloff, Penumbra, Saturation,
    ScaleDrift, Temperature, TimeOffset,
};
use crate::{MeasurementModel, ParameterRole, PhotodiodeError};

/// How the components of [`add_effect`] are made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EffectModelOptions {
    /// Partials of the albedo terms (`albedo`, `albedo-gain`).
    pub albedo_partials: AlbedoPartials,
    /// Role of the parameters of the effects a filter can estimate (`time-offset`,
    /// `scale-drift`, `albedo-gain`, `temperature`, the Kelly roll-off's `kappa`); the
    /// others are always fixed.
    pub role: ParameterRole,
    /// Whether `time-offset` becomes the first-order term; a simulator samples the scene at
    /// the shifted time instead and leaves it out.
    pub time_offset_term: bool,
}

/// Adds the component of `effect` to `model`; false when the effect is not a photodiode
/// component (`mag-bias`, `gyro-scale`: telemetry corrections; `albedo-map`: a correction
/// of the reflectivity map; `time-offset` without
/// [`EffectModelOptions::time_offset_term`]).
pub fn add_effect(
    model: &mut MeasurementModel,
    effect: &Effect,
    options: EffectModelOptions,
) -> Result<bool, PhotodiodeError> {
    let partials = options.albedo_partials;
    match effect {
        Effect::Albedo { .. } => model.add_term(Albedo { partials })?,
        Effect::FovRolloff {
            start_rad,
            cutoff_rad,
        } => model.add_term(FovRolloff::new(*start_rad, *cutoff_rad)?)?,
        Effect::DarkOffset { volts } => model.add_term(DarkOffset::new(volts))?,
        Effect::KellyRolloff { kappa, exponent } => {
            model.add_term(KellyRolloff::new(*kappa, *exponent)?)?
        }
        Effect::Saturation { volts } => model.add_stage(Saturation::shared(*volts))?,
        Effect::SaturationPerPhotodiode { volts } => {
            model.add_stage(Saturation::per_photodiode(volts))?
        }
        Effect::Penumbra => model.add_term(Penumbra)?,
        Effect::TimeOffset { seconds } if options.time_offset_term => {
            model.add_term(TimeOffset::new(*seconds))?
        }
        Effect::ScaleDrift { fraction_per_hour } => {
            model.add_gain(ScaleDrift::per_photodiode(fraction_per_hour))?
        }
        Effect::AlbedoGain { gain } => model.add_term(AlbedoGain::new(*gain, partials))?,
        Effect::Temperature {
            coefficient_per_k,
            reference_c,
        } => model.add_gain(Temperature::per_photodiode(coefficient_per_k, *reference_c))?,
        // `albedo-map` corrects the reflectivity map the albedo provider is built from.
        Effect::TimeOffset { .. }
        | Effect::MagBias { .. }
        | Effect::GyroScale { .. }
        | Effect::AlbedoMap { .. } => {
            return Ok(false);
        }
    }
    // The effects whose values a filter can carry as states: those `estimated_values_mut`
    // lists.
    let estimated = estimated_values_mut(&mut effect.clone()).len();
    if estimated > 0 {
        set_role(model, effect.id(), options.role, estimated)?;
    }
    Ok(true)
}

/// Sets the role of the first `count` parameters of the component `id` (the ones
/// [`estimated_values_mut`] lists, in order).
fn set_role(
    model: &mut MeasurementModel,
    id: EffectId,
    role: ParameterRole,
    count: usize,
) -> Result<(), PhotodiodeError> {
    let indices: Vec<usize> = model
        .parameters()
        .enumerate()
        .filter(|(_, (c, _))| *c == id.into())
        .map(|(i, _)| i)
        .take(count)
        .collect();
    for i in indices {
        model.parameter_mut(i)?.role = role;
    }
    Ok(())
}

/// The effect's values that a filter estimates, in the order of its component's
/// parameters (and in their units: s, 1/h, 1, 1/K); empty for the others. The Kelly
/// roll-off's `kappa` only: its exponent is fixed at the diagnosis's fit (the two are
/// nearly interchangeable inside the filter's 60-deg gate).
pub fn estimated_values_mut(effect: &mut Effect) -> Vec<&mut f64> {
    match effect {
        Effect::TimeOffset { seconds } => vec![seconds],
        Effect::ScaleDrift { fraction_per_hour } => fraction_per_hour.iter_mut().collect(),
        Effect::AlbedoGain { gain } => vec![gain],
        Effect::KellyRolloff { kappa, .. } => vec![kappa],
        Effect::Temperature {
            coefficient_per_k, ..
        } => coefficient_per_k.iter_mut().collect(),
        _ => Vec::new(),
    }
}
