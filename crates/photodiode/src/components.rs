//! The catalogue's effects as model components: the one place an [`Effect`] value becomes a
//! [`Term`](crate::Term), [`ScaleGain`](crate::ScaleGain) or
//! [`OutputStage`](crate::OutputStage), for the simulator's truth and the diagnosis's model
//! alike.

use pdcal_effects::{Effect, EffectId};

use crate::terms::{
    Albedo, AlbedoGain, AlbedoPartials, DarkOffset, FovRolloff, Penumbra, Saturation, ScaleDrift,
    Temperature, TimeOffset,
};
use crate::{MeasurementModel, ParameterRole, PhotodiodeError};

/// How the components of [`add_effect`] are made.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EffectModelOptions {
    /// Partials of the albedo terms (`albedo`, `albedo-gain`).
    pub albedo_partials: AlbedoPartials,
    /// Role of the parameters of the effects a filter can estimate (`time-offset`,
    /// `scale-drift`, `albedo-gain`, `temperature`); the others are always fixed.
    pub role: ParameterRole,
    /// Whether `time-offset` becomes the first-order term; a simulator samples the scene at
    /// the shifted time instead and leaves it out.
    pub time_offset_term: bool,
}

/// Adds the component of `effect` to `model`; false when the effect is not a photodiode
/// component (`mag-bias`, `gyro-scale`: telemetry corrections; `time-offset` without
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
        Effect::Saturation { volts } => model.add_stage(Saturation::shared(*volts))?,
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
        Effect::TimeOffset { .. } | Effect::MagBias { .. } | Effect::GyroScale { .. } => {
            return Ok(false);
        }
    }
    // The effects whose values a filter can carry as states: those `estimated_values_mut`
    // lists.
    if !estimated_values_mut(&mut effect.clone()).is_empty() {
        set_role(model, effect.id(), options.role)?;
    }
    Ok(true)
}

fn set_role(
    model: &mut MeasurementModel,
    id: EffectId,
    role: ParameterRole,
) -> Result<(), PhotodiodeError> {
    let indices: Vec<usize> = model
        .parameters()
        .enumerate()
        .filter(|(_, (c, _))| *c == id.into())
        .map(|(i, _)| i)
        .collect();
    for i in indices {
        model.parameter_mut(i)?.role = role;
    }
    Ok(())
}

/// The effect's values that a filter estimates, in the order of its component's
/// parameters (and in their units: s, 1/h, 1, 1/K); empty for the others.
pub fn estimated_values_mut(effect: &mut Effect) -> Vec<&mut f64> {
    match effect {
        Effect::TimeOffset { seconds } => vec![seconds],
        Effect::ScaleDrift { fraction_per_hour } => fraction_per_hour.iter_mut().collect(),
        Effect::AlbedoGain { gain } => vec![gain],
        Effect::Temperature {
            coefficient_per_k, ..
        } => coefficient_per_k.iter_mut().collect(),
        _ => Vec::new(),
    }
}
