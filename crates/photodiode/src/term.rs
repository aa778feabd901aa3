//! The interfaces of the measurement model: additive [`Term`]s, multiplicative
//! [`ScaleGain`]s on the scale factor, and [`OutputStage`]s applied to the sum.

use std::fmt;

use nalgebra::Vector3;
use pdcal_effects::EffectId;
use serde::{Deserialize, Serialize};

use crate::{Photodiode, Scene};

/// How a filter should treat a parameter. The model itself evaluates both kinds the same way
/// and always supplies the partial derivative; the role is a hint for the filter's state layout.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ParameterRole {
    /// Known value, not a filter state.
    #[default]
    Fixed,
    /// To be estimated as a filter state.
    Estimated,
}

/// One scalar parameter owned by a model component.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Parameter {
    /// Name in the project's grammar, e.g. `pd03_dark_offset_V` or `time_offset_s`.
    pub name: String,
    /// Unit, e.g. `V`, `s`, `rad`, `1/h`.
    pub unit: String,
    /// The zero-based photodiode this parameter belongs to; `None` if shared by all.
    pub photodiode: Option<usize>,
    /// Current value, in `unit`.
    pub value: f64,
    /// Fixed or estimated.
    pub role: ParameterRole,
}

impl Parameter {
    /// A parameter shared by every photodiode.
    pub fn shared(name: &str, unit: &str, value: f64) -> Self {
        Parameter {
            name: name.to_owned(),
            unit: unit.to_owned(),
            photodiode: None,
            value,
            role: ParameterRole::Fixed,
        }
    }

    /// A parameter of photodiode `index` (zero-based), named `pdNN_<base>` (1-based NN).
    pub fn per_photodiode(index: usize, base: &str, unit: &str, value: f64) -> Self {
        Parameter {
            name: format!("pd{:02}_{base}", index + 1),
            photodiode: Some(index),
            ..Self::shared(base, unit, value)
        }
    }

    /// A list with one parameter per photodiode, in photodiode order.
    pub fn per_photodiode_list(base: &str, unit: &str, values: &[f64]) -> Vec<Parameter> {
        values
            .iter()
            .enumerate()
            .map(|(i, &v)| Self::per_photodiode(i, base, unit, v))
            .collect()
    }
}

/// The parameter of `params` that acts on photodiode `index`: a shared one, or the one tagged
/// with this photodiode. Returns its position in `params` and its value.
pub fn parameter_for(params: &[Parameter], index: usize) -> Option<(usize, f64)> {
    params
        .iter()
        .position(|p| p.photodiode.is_none() || p.photodiode == Some(index))
        .map(|k| (k, params[k].value))
}

/// A term's value and its partial derivatives for one photodiode at one sample.
///
/// Gradients are column vectors: the filter's H row block for the attitude error is
/// `d_attitude^T`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sensitivity {
    /// Contribution to the output, V.
    pub value_v: f64,
    /// Gradient w.r.t. the attitude error `a` (true `A = (I - [a x]) A_est`), V/rad.
    pub d_attitude: Vector3<f64>,
    /// Partial w.r.t. the scale factor `C` the term was given, V/V.
    pub d_scale: f64,
    /// Gradient w.r.t. the body normal `n` treated as a free 3-vector, V.
    pub d_normal: Vector3<f64>,
}

impl Sensitivity {
    /// Adds `other` into `self`.
    pub fn accumulate(&mut self, other: &Sensitivity) {
        self.value_v += other.value_v;
        self.d_attitude += other.d_attitude;
        self.d_scale += other.d_scale;
        self.d_normal += other.d_normal;
    }
}

/// Which component a model part is: the direct Sun, or one effect of the catalogue.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ComponentId {
    /// The direct Sun, paper Eqs. (11), (15); spelled `sun`.
    Sun,
    /// An effect of the catalogue.
    Effect(EffectId),
}

impl From<EffectId> for ComponentId {
    fn from(id: EffectId) -> Self {
        ComponentId::Effect(id)
    }
}

impl fmt::Display for ComponentId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ComponentId::Sun => f.write_str("sun"),
            ComponentId::Effect(e) => f.write_str(e.as_str()),
        }
    }
}

/// What every model component has: an effect id and, optionally, parameters.
pub trait Component: Send + Sync {
    /// The component's id: the direct Sun or an effect of the catalogue.
    fn id(&self) -> ComponentId;

    /// The component's parameters, in a fixed order. Default: none.
    fn parameters(&self) -> &[Parameter] {
        &[]
    }

    /// Mutable access to the parameters (values and roles; the model never changes their
    /// number or photodiode tags after adding the component). Default: none.
    fn parameters_mut(&mut self) -> &mut [Parameter] {
        &mut []
    }
}

/// An additive contribution to a photodiode's output (paper Eq. 15 is `sun` + `albedo`).
pub trait Term: Component {
    /// Contribution to the output of photodiode `index` (whose parameters are `pd`), V.
    fn value(&self, pd: &Photodiode, index: usize, scene: &Scene) -> f64;

    /// The contribution and its partials. `d_params` has one entry per
    /// [`Component::parameters`] entry, zeroed by the caller; the term writes the partials
    /// of its contribution w.r.t. its own parameters there.
    fn partials(
        &self,
        pd: &Photodiode,
        index: usize,
        scene: &Scene,
        d_params: &mut [f64],
    ) -> Sensitivity;
}

/// A factor `g` multiplying the scale factor: every term sees `C_eff = C * prod(g)`.
///
/// Gains depend on the sample (time, temperature) and their own parameters, not on the
/// attitude or the normal.
pub trait ScaleGain: Component {
    /// The factor for photodiode `index`.
    fn gain(&self, index: usize, scene: &Scene) -> f64;

    /// The factor and its partials w.r.t. the component's parameters (written to `d_params`,
    /// zeroed by the caller).
    fn gain_partials(&self, index: usize, scene: &Scene, d_params: &mut [f64]) -> f64;
}

/// A non-additive stage applied to the summed output, e.g. clipping (saturation).
pub trait OutputStage: Component {
    /// Stage output for photodiode `index` given the input `input_v`.
    fn apply(&self, index: usize, input_v: f64) -> f64;

    /// Stage output, its derivative w.r.t. the input, and (in `d_params`, zeroed by the
    /// caller) its partials w.r.t. the stage's parameters.
    fn apply_partials(&self, index: usize, input_v: f64, d_params: &mut [f64]) -> (f64, f64);
}
