//! [`MeasurementModel`]: the photodiodes and an ordered, run-time editable list of components.

use nalgebra::Vector3;
use pdcal_attitude::normal_partials;

use crate::term::{Component, ComponentId, OutputStage, Parameter, ScaleGain, Sensitivity, Term};
use crate::terms::{Albedo, AlbedoPartials, DirectSun};
use crate::{Photodiode, PhotodiodeError, Scene};

/// One entry of the model's component list.
pub enum Part {
    /// Additive term.
    Term(Box<dyn Term>),
    /// Factor on the scale factor.
    Gain(Box<dyn ScaleGain>),
    /// Stage applied to the summed output.
    Stage(Box<dyn OutputStage>),
}

impl Part {
    /// The component view (id and parameters).
    pub fn component(&self) -> &dyn Component {
        match self {
            Part::Term(t) => t.as_ref(),
            Part::Gain(g) => g.as_ref(),
            Part::Stage(s) => s.as_ref(),
        }
    }

    fn component_mut(&mut self) -> &mut dyn Component {
        match self {
            Part::Term(t) => t.as_mut(),
            Part::Gain(g) => g.as_mut(),
            Part::Stage(s) => s.as_mut(),
        }
    }
}

impl std::fmt::Debug for Part {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let c = self.component();
        f.debug_struct("Part")
            .field("id", &c.id())
            .field("parameters", &c.parameters())
            .finish()
    }
}

/// The full output of one photodiode and its partial derivatives (the photodiode's row of
/// the filter's H, paper Eqs. 20-24 generalised to every component).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Partials {
    /// Predicted output, V (after the output stages).
    pub value_v: f64,
    /// Gradient w.r.t. the attitude error `a`, V/rad (Eq. 20 is the direct-Sun part).
    pub d_attitude: Vector3<f64>,
    /// Partial w.r.t. the photodiode's scale factor `C` (Eq. 22 is the direct-Sun part).
    pub d_scale: f64,
    /// Gradient w.r.t. the body normal as a free 3-vector, V; map it to azimuth/elevation with
    /// [`Partials::d_az_el`] (Eqs. 23-24) or to a tangent-plane correction by projection.
    pub d_normal: Vector3<f64>,
    /// Partials w.r.t. every model parameter, in [`MeasurementModel::parameters`] order.
    pub d_parameters: Vec<f64>,
}

impl Partials {
    /// Chain rule to the normal's azimuth and elevation (rad), Eqs. (23)-(24):
    /// `dI/daz = d_normal . dn/daz`, `dI/del = d_normal . dn/del`.
    pub fn d_az_el(&self, azimuth_rad: f64, elevation_rad: f64) -> (f64, f64) {
        let (dn_daz, dn_del) = normal_partials(azimuth_rad, elevation_rad);
        (self.d_normal.dot(&dn_daz), self.d_normal.dot(&dn_del))
    }

    fn reset(&mut self, n_params: usize) {
        self.value_v = 0.0;
        self.d_attitude = Vector3::zeros();
        self.d_scale = 0.0;
        self.d_normal = Vector3::zeros();
        self.d_parameters.clear();
        self.d_parameters.resize(n_params, 0.0);
    }
}

/// The concrete type of a part, where the model knows it (added through
/// [`MeasurementModel::add_term`] or the named constructors): [`MeasurementModel::partials_into`]
/// then calls the provided terms directly instead of through the generic loop (same
/// operations in the same order, so the same numbers).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Known {
    Sun(DirectSun),
    Albedo(Albedo),
    Other,
}

impl Known {
    fn of<T: Term + 'static>(term: &T) -> Self {
        let any: &dyn std::any::Any = term;
        if let Some(sun) = any.downcast_ref::<DirectSun>() {
            Known::Sun(*sun)
        } else if let Some(albedo) = any.downcast_ref::<Albedo>() {
            Known::Albedo(*albedo)
        } else {
            Known::Other
        }
    }
}

/// Photodiodes plus an ordered list of components; output of photodiode `i`:
///
/// ```text
/// I_i = S_K( ... S_1( sum_k T_k(C_eff, n_i, scene) ) ),   C_eff = C_i prod_j g_j(t)
/// ```
///
/// with additive terms `T_k` ([`Term`]), gains `g_j` ([`ScaleGain`]) and output stages `S`
/// ([`OutputStage`], applied in list order). Parameters of all components are concatenated in
/// list order; adding or removing a component changes that layout.
#[derive(Debug, Default)]
pub struct MeasurementModel {
    photodiodes: Vec<Photodiode>,
    parts: Vec<Part>,
    /// One entry per part.
    known: Vec<Known>,
}

impl MeasurementModel {
    /// A model with these photodiodes and no components.
    pub fn new(photodiodes: Vec<Photodiode>) -> Self {
        MeasurementModel {
            photodiodes,
            parts: Vec::new(),
            known: Vec::new(),
        }
    }

    /// The cosine model: the direct Sun only, hard-edged shadow (`--base-model cosine`).
    pub fn cosine(photodiodes: Vec<Photodiode>) -> Self {
        let mut model = Self::new(photodiodes);
        // A new model has no component: adding the first cannot fail.
        let _ = model.add_term(DirectSun::default());
        model
    }

    /// The paper's model, Eq. (15): direct Sun and albedo, albedo partials neglected
    /// (`--base-model paper`).
    pub fn paper(photodiodes: Vec<Photodiode>) -> Self {
        let mut model = Self::cosine(photodiodes);
        // Ids differ from the direct Sun's: cannot fail.
        let _ = model.add_term(Albedo {
            partials: AlbedoPartials::Neglected,
        });
        model
    }

    /// The photodiodes.
    pub fn photodiodes(&self) -> &[Photodiode] {
        &self.photodiodes
    }

    /// Mutable photodiodes (the filter writes its scale and normal estimates here).
    pub fn photodiodes_mut(&mut self) -> &mut [Photodiode] {
        &mut self.photodiodes
    }

    /// The components in order.
    pub fn parts(&self) -> &[Part] {
        &self.parts
    }

    /// Effect ids of the components in order.
    pub fn ids(&self) -> Vec<ComponentId> {
        self.parts.iter().map(|p| p.component().id()).collect()
    }

    /// Whether a component with this id is present.
    pub fn contains(&self, id: impl Into<ComponentId>) -> bool {
        let id = id.into();
        self.parts.iter().any(|p| p.component().id() == id)
    }

    /// Appends a component; fails on a duplicate id or a parameter tagged with a photodiode
    /// the model does not have.
    pub fn add(&mut self, part: Part) -> Result<(), PhotodiodeError> {
        self.add_known(part, Known::Other)
    }

    fn add_known(&mut self, part: Part, known: Known) -> Result<(), PhotodiodeError> {
        let component = part.component();
        if self.contains(component.id()) {
            return Err(PhotodiodeError::DuplicateComponent {
                id: component.id().to_string(),
            });
        }
        let count = self.photodiodes.len();
        if let Some(index) = component
            .parameters()
            .iter()
            .filter_map(|p| p.photodiode)
            .find(|&i| i >= count)
        {
            return Err(PhotodiodeError::PhotodiodeIndex { index, count });
        }
        self.parts.push(part);
        self.known.push(known);
        Ok(())
    }

    /// Appends an additive term.
    pub fn add_term(&mut self, term: impl Term + 'static) -> Result<(), PhotodiodeError> {
        let known = Known::of(&term);
        self.add_known(Part::Term(Box::new(term)), known)
    }

    /// Appends a scale gain.
    pub fn add_gain(&mut self, gain: impl ScaleGain + 'static) -> Result<(), PhotodiodeError> {
        self.add(Part::Gain(Box::new(gain)))
    }

    /// Appends an output stage.
    pub fn add_stage(&mut self, stage: impl OutputStage + 'static) -> Result<(), PhotodiodeError> {
        self.add(Part::Stage(Box::new(stage)))
    }

    /// Removes and returns the component with this id.
    pub fn remove(&mut self, id: impl Into<ComponentId>) -> Result<Part, PhotodiodeError> {
        let id = id.into();
        let at = self
            .parts
            .iter()
            .position(|p| p.component().id() == id)
            .ok_or_else(|| PhotodiodeError::UnknownComponent { id: id.to_string() })?;
        self.known.remove(at);
        Ok(self.parts.remove(at))
    }

    /// Number of parameters over all components.
    pub fn parameter_count(&self) -> usize {
        self.parts
            .iter()
            .map(|p| p.component().parameters().len())
            .sum()
    }

    /// Every parameter with its component's id, in layout order.
    pub fn parameters(&self) -> impl Iterator<Item = (ComponentId, &Parameter)> {
        self.parts.iter().flat_map(|p| {
            let c = p.component();
            c.parameters().iter().map(move |q| (c.id(), q))
        })
    }

    /// Layout index of the parameter `name` of component `id`.
    pub fn parameter_index(&self, id: impl Into<ComponentId>, name: &str) -> Option<usize> {
        let id = id.into();
        self.parameters()
            .position(|(c, p)| c == id && p.name == name)
    }

    /// Mutable access to the parameter at layout index `index`.
    pub fn parameter_mut(&mut self, index: usize) -> Result<&mut Parameter, PhotodiodeError> {
        let count = self.parameter_count();
        let mut rest = index;
        for part in &mut self.parts {
            let params = part.component_mut().parameters_mut();
            if rest < params.len() {
                return Ok(&mut params[rest]);
            }
            rest -= params.len();
        }
        Err(PhotodiodeError::ParameterIndex { index, count })
    }

    /// Sets the value of the parameter at layout index `index`.
    pub fn set_parameter(&mut self, index: usize, value: f64) -> Result<(), PhotodiodeError> {
        self.parameter_mut(index)?.value = value;
        Ok(())
    }

    fn photodiode(&self, index: usize) -> Result<&Photodiode, PhotodiodeError> {
        self.photodiodes
            .get(index)
            .ok_or(PhotodiodeError::PhotodiodeIndex {
                index,
                count: self.photodiodes.len(),
            })
    }

    /// The photodiode with the gains applied to its scale factor, and the total gain.
    fn effective(&self, index: usize, scene: &Scene) -> Result<(Photodiode, f64), PhotodiodeError> {
        let pd = *self.photodiode(index)?;
        let gain: f64 = self
            .parts
            .iter()
            .filter_map(|p| match p {
                Part::Gain(g) => Some(g.gain(index, scene)),
                _ => None,
            })
            .product();
        Ok((
            Photodiode {
                scale_v: pd.scale_v * gain,
                ..pd
            },
            gain,
        ))
    }

    /// Each term's contribution for photodiode `index` (gains applied, stages not), in order.
    /// Their sum is [`MeasurementModel::pre_stage_output`].
    pub fn contributions(
        &self,
        index: usize,
        scene: &Scene,
    ) -> Result<Vec<(ComponentId, f64)>, PhotodiodeError> {
        let (pd, _) = self.effective(index, scene)?;
        Ok(self
            .parts
            .iter()
            .filter_map(|p| match p {
                Part::Term(t) => Some((t.id(), t.value(&pd, index, scene))),
                _ => None,
            })
            .collect())
    }

    /// Sum of the terms before the output stages, V. A simulator adds noise to this and then
    /// calls [`MeasurementModel::apply_stages`], because a real sensor clips after noise.
    pub fn pre_stage_output(&self, index: usize, scene: &Scene) -> Result<f64, PhotodiodeError> {
        let (pd, _) = self.effective(index, scene)?;
        Ok(self
            .parts
            .iter()
            .map(|p| match p {
                Part::Term(t) => t.value(&pd, index, scene),
                _ => 0.0,
            })
            .sum())
    }

    /// The output stages applied in order to `input_v`.
    pub fn apply_stages(&self, index: usize, input_v: f64) -> Result<f64, PhotodiodeError> {
        self.photodiode(index)?;
        Ok(self.parts.iter().fold(input_v, |y, p| match p {
            Part::Stage(s) => s.apply(index, y),
            _ => y,
        }))
    }

    /// Predicted noise-free output of photodiode `index`, V.
    pub fn evaluate(&self, index: usize, scene: &Scene) -> Result<f64, PhotodiodeError> {
        self.apply_stages(index, self.pre_stage_output(index, scene)?)
    }

    /// Predicted outputs of all photodiodes into `out` (one entry per photodiode).
    pub fn evaluate_all(&self, scene: &Scene, out: &mut [f64]) -> Result<(), PhotodiodeError> {
        if out.len() != self.photodiodes.len() {
            return Err(PhotodiodeError::LengthMismatch {
                what: "out",
                expected: self.photodiodes.len(),
                found: out.len(),
            });
        }
        for (i, y) in out.iter_mut().enumerate() {
            *y = self.evaluate(i, scene)?;
        }
        Ok(())
    }

    /// Output and partials of photodiode `index`.
    pub fn partials(&self, index: usize, scene: &Scene) -> Result<Partials, PhotodiodeError> {
        let mut out = Partials::default();
        self.partials_into(index, scene, &mut out)?;
        Ok(out)
    }

    /// As [`MeasurementModel::partials`], reusing `out`'s buffer (no allocation once sized).
    pub fn partials_into(
        &self,
        index: usize,
        scene: &Scene,
        out: &mut Partials,
    ) -> Result<(), PhotodiodeError> {
        if self.known.iter().all(|k| *k != Known::Other) {
            return self.known_partials_into(index, scene, out);
        }
        self.generic_partials_into(index, scene, out)
    }

    /// [`MeasurementModel::partials_into`] when every part is a provided term the model
    /// knows ([`DirectSun`], [`Albedo`]: no gains, stages or parameters): the terms called
    /// directly, summed in list order as the generic loop does (the gain is the empty
    /// product 1, an exact factor), so the numbers are the same bits.
    fn known_partials_into(
        &self,
        index: usize,
        scene: &Scene,
        out: &mut Partials,
    ) -> Result<(), PhotodiodeError> {
        let pd = self.photodiode(index)?;
        let mut sum = Sensitivity::default();
        for known in &self.known {
            let term = match known {
                Known::Sun(sun) => sun.partials(pd, index, scene, &mut []),
                Known::Albedo(albedo) => albedo.partials(pd, index, scene, &mut []),
                Known::Other => Sensitivity::default(),
            };
            sum.accumulate(&term);
        }
        out.value_v = sum.value_v;
        out.d_attitude = sum.d_attitude;
        out.d_scale = sum.d_scale;
        out.d_normal = sum.d_normal;
        out.d_parameters.clear();
        Ok(())
    }

    /// The generic form of [`MeasurementModel::partials_into`]: every part through its
    /// trait object.
    fn generic_partials_into(
        &self,
        index: usize,
        scene: &Scene,
        out: &mut Partials,
    ) -> Result<(), PhotodiodeError> {
        let (pd, gain) = self.effective(index, scene)?;
        let scale_v = self.photodiode(index)?.scale_v;
        out.reset(self.parameter_count());
        let mut sum = Sensitivity::default();
        let mut offset = 0;
        for part in &self.parts {
            let len = part.component().parameters().len();
            let slice = &mut out.d_parameters[offset..offset + len];
            match part {
                Part::Term(t) => sum.accumulate(&t.partials(&pd, index, scene, slice)),
                Part::Gain(g) => {
                    // d(prod g)/dp = (prod g / g_j) dg_j/dp; recompute the other factors
                    // instead of dividing, so that a zero factor is harmless.
                    let others: f64 = self
                        .parts
                        .iter()
                        .filter(|q| !std::ptr::eq(*q, part))
                        .filter_map(|q| match q {
                            Part::Gain(h) => Some(h.gain(index, scene)),
                            _ => None,
                        })
                        .product();
                    g.gain_partials(index, scene, slice);
                    slice.iter_mut().for_each(|d| *d *= others);
                }
                Part::Stage(_) => {}
            }
            offset += len;
        }
        // Terms gave d/dC_eff; C_eff = C * gain.
        let mut offset = 0;
        for part in &self.parts {
            let len = part.component().parameters().len();
            if let Part::Gain(_) = part {
                out.d_parameters[offset..offset + len]
                    .iter_mut()
                    .for_each(|d| *d *= sum.d_scale * scale_v);
            }
            offset += len;
        }
        out.value_v = sum.value_v;
        out.d_attitude = sum.d_attitude;
        out.d_scale = sum.d_scale * gain;
        out.d_normal = sum.d_normal;
        self.chain_stages(index, out);
        Ok(())
    }

    /// [`MeasurementModel::partials_into`] always through the generic loop over trait
    /// objects: the reference the direct path of the provided terms is tested against.
    pub fn partials_into_generic(
        &self,
        index: usize,
        scene: &Scene,
        out: &mut Partials,
    ) -> Result<(), PhotodiodeError> {
        self.generic_partials_into(index, scene, out)
    }

    /// Applies the output stages to `out` in order: each stage multiplies every partial so far
    /// by its input derivative and writes its own parameter partials.
    fn chain_stages(&self, index: usize, out: &mut Partials) {
        let mut offset = 0;
        for part in &self.parts {
            let len = part.component().parameters().len();
            if let Part::Stage(stage) = part {
                let (before, rest) = out.d_parameters.split_at_mut(offset);
                let (own, after) = rest.split_at_mut(len);
                let (y, dy) = stage.apply_partials(index, out.value_v, own);
                out.value_v = y;
                out.d_attitude *= dy;
                out.d_scale *= dy;
                out.d_normal *= dy;
                before
                    .iter_mut()
                    .chain(after.iter_mut())
                    .for_each(|d| *d *= dy);
            }
            offset += len;
        }
    }
}
