//! The provided model components, one per effect id of `cli-contract.md` (the direct Sun is
//! `sun`; `mag-bias` and `gyro-scale` are not photodiode effects and live elsewhere).

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::sensor::{SunView, sun_view};
use pdcal_effects::EffectId;

use crate::term::{
    Component, ComponentId, OutputStage, Parameter, ScaleGain, Sensitivity, Term, parameter_for,
};
use crate::{Photodiode, PhotodiodeError, Scene, ShadowMode};

/// A term of the form `f C g(c)` with `c = n^T s`, `f` the shadow factor: value and partials.
/// With `s(a) = (I - [a x]) s`, `ds/da = [s x]`, so `dc/da = n^T [s x]`, gradient `n x s`
/// (Eq. 20 for `g(c) = c`).
fn cosine_law(pd: &Photodiode, scene: &Scene, view: &SunView, g: f64, dg_dc: f64) -> Sensitivity {
    let k = view.shadow * pd.scale_v * dg_dc;
    Sensitivity {
        value_v: view.shadow * pd.scale_v * g,
        d_attitude: pd.n_body.cross(&scene.sun_body) * k,
        d_scale: view.shadow * g,
        d_normal: scene.sun_body * k,
    }
}

/// Direct sunlight, paper Eq. (15) first term with the Sun's distance made explicit:
/// `f (1 AU / r_sun)^2 C n^T A s|_R`, zero when `n^T s <= 0` or outside the photodiode's field
/// of view; `f` from the [`ShadowMode`], `(1 AU / r_sun)^2` the scene's
/// [`Scene::sun_distance_factor`]. `C` is the output at 1 AU and normal incidence, as the
/// albedo term's `E_a / E_AM0` is relative to the 1-AU flux (Eq. 13): without the factor `C`
/// would absorb the distance, about 7 % apart between January and July. Id `sun`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct DirectSun {
    /// How the eclipse fraction enters.
    pub shadow: ShadowMode,
}

impl Component for DirectSun {
    fn id(&self) -> ComponentId {
        ComponentId::Sun
    }
}

impl Term for DirectSun {
    fn value(&self, pd: &Photodiode, _index: usize, scene: &Scene) -> f64 {
        sun_view(pd, scene, self.shadow).map_or(0.0, |v| v.shadow * pd.scale_v * v.cos)
    }

    /// Eqs. (20), (22) and, through the normal gradient `C A s`, (23)-(24).
    fn partials(&self, pd: &Photodiode, _: usize, scene: &Scene, _: &mut [f64]) -> Sensitivity {
        sun_view(pd, scene, self.shadow)
            .map(|v| cosine_law(pd, scene, &v, v.cos, 1.0))
            .unwrap_or_default()
    }
}

/// Whether the albedo term supplies its attitude and normal partials.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum AlbedoPartials {
    /// Zero attitude and normal partials, as the paper (after Eq. 24). The scale partial
    /// `E_a/E_AM0` is always supplied.
    #[default]
    Neglected,
    /// `d/da = C n x (A v)` (i.e. `C n^T [(A v) x]`) and `d/dn = C A v`, with `v = sum c u`
    /// over the gated cells.
    Included,
}

/// Earth albedo, paper Eq. (15) second term: `C E_a/E_AM0`, the ratio from the scene's
/// [`crate::AlbedoIrradiance`] at `n_gcrf = A^T n` with the photodiode's field of view.
/// Id `albedo`. Not affected by the Sun's shadow (the provider knows which cells are lit).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Albedo {
    /// Attitude/normal partials neglected (default, the paper's choice) or included.
    pub partials: AlbedoPartials,
}

impl Component for Albedo {
    fn id(&self) -> ComponentId {
        EffectId::Albedo.into()
    }
}

impl Term for Albedo {
    fn value(&self, pd: &Photodiode, _index: usize, scene: &Scene) -> f64 {
        scene.albedo.map_or(0.0, |provider| {
            let n_gcrf = scene.attitude.transpose() * pd.n_body;
            pd.scale_v * provider.ratio(&n_gcrf, pd.cos_fov())
        })
    }

    fn partials(&self, pd: &Photodiode, _: usize, scene: &Scene, _: &mut [f64]) -> Sensitivity {
        let Some(provider) = scene.albedo else {
            return Sensitivity::default();
        };
        let n_gcrf = scene.attitude.transpose() * pd.n_body;
        match self.partials {
            AlbedoPartials::Neglected => {
                let ratio = provider.ratio(&n_gcrf, pd.cos_fov());
                Sensitivity {
                    value_v: pd.scale_v * ratio,
                    d_scale: ratio,
                    ..Sensitivity::default()
                }
            }
            AlbedoPartials::Included => {
                let (ratio, v_gcrf) = provider.ratio_and_vector(&n_gcrf, pd.cos_fov());
                // n_gcrf(a) = A^T (I + [a x]) n, so d ratio/da = -(A v)^T [n x]: gradient n x (A v).
                let v_body = scene.attitude * v_gcrf;
                Sensitivity {
                    value_v: pd.scale_v * ratio,
                    d_attitude: pd.n_body.cross(&v_body) * pd.scale_v,
                    d_scale: ratio,
                    d_normal: v_body * pd.scale_v,
                }
            }
        }
    }
}

/// Penumbra correction: `(sun_fraction - hard(sun_fraction)) C n^T A s`, which turns a
/// [`DirectSun`] with [`ShadowMode::Hard`] into one with [`ShadowMode::Penumbra`]. Id
/// `penumbra`. Do not combine with a `DirectSun` already in penumbra mode.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Penumbra;

impl Penumbra {
    fn view(pd: &Photodiode, scene: &Scene) -> Option<SunView> {
        sun_view(pd, scene, ShadowMode::Penumbra).map(|v| SunView {
            shadow: v.shadow
                - ShadowMode::Hard.factor(scene.sun_fraction) * scene.sun_distance_factor,
            ..v
        })
    }
}

impl Component for Penumbra {
    fn id(&self) -> ComponentId {
        EffectId::Penumbra.into()
    }
}

impl Term for Penumbra {
    fn value(&self, pd: &Photodiode, _index: usize, scene: &Scene) -> f64 {
        Self::view(pd, scene).map_or(0.0, |v| v.shadow * pd.scale_v * v.cos)
    }

    fn partials(&self, pd: &Photodiode, _: usize, scene: &Scene, _: &mut [f64]) -> Sensitivity {
        Self::view(pd, scene)
            .map(|v| cosine_law(pd, scene, &v, v.cos, 1.0))
            .unwrap_or_default()
    }
}

/// Roll-off below the cosine law at high incidence: the direct-Sun output is multiplied by
/// a raised-cosine taper `r(theta)` of the incidence angle `theta`:
/// 1 for `theta <= start`, 0 for `theta >= cutoff`, `0.5 (1 + cos(pi u))` with
/// `u = (theta - start)/(cutoff - start)` in between (the law of the data set's truth,
/// `pdcal-dataset` `Effect::FovRolloff`). The term adds the correction `f C c (r - 1)`.
/// Id `fov-rolloff`; parameters `fov_rolloff_start_rad`, `fov_rolloff_cutoff_rad` (shared).
///
/// The taper is C1 (zero slope at both ends); its second derivative jumps at `start` and
/// `cutoff`. If the parameters are set so that `cutoff <= start`, the taper becomes a hard
/// cut at `start` with zero parameter partials.
#[derive(Debug, Clone, PartialEq)]
pub struct FovRolloff {
    params: [Parameter; 2],
    /// Shadow factor applied to the correction; keep equal to the [`DirectSun`]'s mode.
    pub shadow: ShadowMode,
}

/// The taper `r`, `dr/dtheta`, `dr/dstart`, `dr/dcutoff` at `theta`.
fn taper(theta: f64, start: f64, cutoff: f64) -> [f64; 4] {
    let span = cutoff - start;
    if theta <= start {
        [1.0, 0.0, 0.0, 0.0]
    } else if theta >= cutoff || span <= 0.0 {
        [0.0; 4]
    } else {
        let u = (theta - start) / span;
        let dr_du = -0.5 * PI * (PI * u).sin();
        [
            0.5 * (1.0 + (PI * u).cos()),
            dr_du / span,
            dr_du * (theta - cutoff) / (span * span),
            -dr_du * (theta - start) / (span * span),
        ]
    }
}

impl FovRolloff {
    /// A roll-off starting at `start_rad` and reaching zero at `cutoff_rad`
    /// (`0 <= start < cutoff <= pi/2`).
    pub fn new(start_rad: f64, cutoff_rad: f64) -> Result<Self, PhotodiodeError> {
        if !(0.0..FRAC_PI_2).contains(&start_rad) {
            return Err(PhotodiodeError::BadValue {
                what: "fov_rolloff_start_rad".into(),
                value: start_rad,
                rule: "0 <= start < pi/2",
            });
        }
        if !(cutoff_rad > start_rad && cutoff_rad <= FRAC_PI_2) {
            return Err(PhotodiodeError::BadValue {
                what: "fov_rolloff_cutoff_rad".into(),
                value: cutoff_rad,
                rule: "start < cutoff <= pi/2",
            });
        }
        Ok(FovRolloff {
            params: [
                Parameter::shared("fov_rolloff_start_rad", "rad", start_rad),
                Parameter::shared("fov_rolloff_cutoff_rad", "rad", cutoff_rad),
            ],
            shadow: ShadowMode::Hard,
        })
    }

    /// As [`FovRolloff::new`] with angles in degrees (I/O edge).
    pub fn from_deg(start_deg: f64, cutoff_deg: f64) -> Result<Self, PhotodiodeError> {
        Self::new(start_deg.to_radians(), cutoff_deg.to_radians())
    }

    /// The multiplicative factor `r` at incidence cosine `cos_incidence`.
    pub fn factor(&self, cos_incidence: f64) -> f64 {
        let theta = cos_incidence.clamp(-1.0, 1.0).acos();
        taper(theta, self.params[0].value, self.params[1].value)[0]
    }
}

impl Component for FovRolloff {
    fn id(&self) -> ComponentId {
        EffectId::FovRolloff.into()
    }
    fn parameters(&self) -> &[Parameter] {
        &self.params
    }
    fn parameters_mut(&mut self) -> &mut [Parameter] {
        &mut self.params
    }
}

impl Term for FovRolloff {
    fn value(&self, pd: &Photodiode, _index: usize, scene: &Scene) -> f64 {
        sun_view(pd, scene, self.shadow).map_or(0.0, |v| {
            v.shadow * pd.scale_v * v.cos * (self.factor(v.cos) - 1.0)
        })
    }

    fn partials(
        &self,
        pd: &Photodiode,
        _: usize,
        scene: &Scene,
        d_params: &mut [f64],
    ) -> Sensitivity {
        let Some(view) = sun_view(pd, scene, self.shadow) else {
            return Sensitivity::default();
        };
        let c = view.cos.min(1.0);
        let theta = c.acos();
        let [r, dr_dtheta, dr_dstart, dr_dcutoff] =
            taper(theta, self.params[0].value, self.params[1].value);
        // dtheta/dc = -1/sin(theta); dr/dtheta is zero near theta = 0, where sin -> 0.
        let dr_dc = if dr_dtheta == 0.0 {
            0.0
        } else {
            -dr_dtheta / theta.sin()
        };
        let g = view.cos * (r - 1.0);
        let dg_dc = (r - 1.0) + view.cos * dr_dc;
        let k = view.shadow * pd.scale_v * view.cos;
        if let [d_start, d_cutoff, ..] = d_params {
            *d_start = k * dr_dstart;
            *d_cutoff = k * dr_dcutoff;
        }
        cosine_law(pd, scene, &view, g, dg_dc)
    }
}

/// Smallest `kappa` the [`KellyRolloff`] evaluates with; a filter step below it is held
/// there (with zero partial), where the roll-off is already a hard cut at grazing incidence.
pub const KELLY_MIN_KAPPA: f64 = 1e-4;

/// Roll-off below the cosine law in the Kelly form of other tools' coarse-sun-sensor models
/// (Basilisk's `kellyFactor`, exponent 2): the direct-Sun output times
/// `K(c) = 1 - exp(-c^k / kappa)`, `c = n^T s` the incidence cosine. The term adds the
/// correction `f C c (K - 1) = -f C c exp(-c^k / kappa)`.
/// Id `fov-rolloff`; parameters `fov_rolloff_kappa` and `fov_rolloff_exponent` (shared,
/// dimensionless). Smooth in `c` on `(0, 1]`, unlike the raised-cosine [`FovRolloff`].
#[derive(Debug, Clone, PartialEq)]
pub struct KellyRolloff {
    params: [Parameter; 2],
    /// Shadow factor applied to the correction; keep equal to the [`DirectSun`]'s mode.
    pub shadow: ShadowMode,
}

impl KellyRolloff {
    /// A Kelly roll-off with `kappa > 0` and `exponent > 0`.
    pub fn new(kappa: f64, exponent: f64) -> Result<Self, PhotodiodeError> {
        if !(kappa > 0.0 && kappa.is_finite()) {
            return Err(PhotodiodeError::BadValue {
                what: "fov_rolloff_kappa".into(),
                value: kappa,
                rule: "kappa > 0",
            });
        }
        if !(exponent > 0.0 && exponent.is_finite()) {
            return Err(PhotodiodeError::BadValue {
                what: "fov_rolloff_exponent".into(),
                value: exponent,
                rule: "exponent > 0",
            });
        }
        Ok(KellyRolloff {
            params: [
                Parameter::shared("fov_rolloff_kappa", "1", kappa),
                Parameter::shared("fov_rolloff_exponent", "1", exponent),
            ],
            shadow: ShadowMode::Hard,
        })
    }

    /// `exp(-c^k / kappa)` and its partials w.r.t. `c`, `kappa`, `k` at `c > 0`.
    fn loss(&self, c: f64) -> [f64; 4] {
        let raw_kappa = self.params[0].value;
        let kappa = raw_kappa.max(KELLY_MIN_KAPPA);
        let k = self.params[1].value;
        let ck = c.powf(k);
        let e = (-ck / kappa).exp();
        let d_kappa = if raw_kappa > KELLY_MIN_KAPPA {
            e * ck / (kappa * kappa)
        } else {
            0.0
        };
        [
            e,
            -e * k * ck / (c * kappa),
            d_kappa,
            -e * ck * c.ln() / kappa,
        ]
    }

    /// The multiplicative factor `K` at incidence cosine `cos_incidence` (0 behind).
    pub fn factor(&self, cos_incidence: f64) -> f64 {
        if cos_incidence <= 0.0 {
            return 0.0;
        }
        1.0 - self.loss(cos_incidence.min(1.0))[0]
    }
}

impl Component for KellyRolloff {
    fn id(&self) -> ComponentId {
        EffectId::FovRolloff.into()
    }
    fn parameters(&self) -> &[Parameter] {
        &self.params
    }
    fn parameters_mut(&mut self) -> &mut [Parameter] {
        &mut self.params
    }
}

impl Term for KellyRolloff {
    fn value(&self, pd: &Photodiode, _index: usize, scene: &Scene) -> f64 {
        sun_view(pd, scene, self.shadow).map_or(0.0, |v| {
            -v.shadow * pd.scale_v * v.cos * self.loss(v.cos.min(1.0))[0]
        })
    }

    /// With `g(c) = -c e`, `e = exp(-c^k/kappa)`: `dg/dc = -e - c de/dc`, and the parameter
    /// partials `-f C c de/dp`.
    fn partials(
        &self,
        pd: &Photodiode,
        _: usize,
        scene: &Scene,
        d_params: &mut [f64],
    ) -> Sensitivity {
        let Some(view) = sun_view(pd, scene, self.shadow) else {
            return Sensitivity::default();
        };
        let c = view.cos.min(1.0);
        let [e, de_dc, de_dkappa, de_dk] = self.loss(c);
        let k = -view.shadow * pd.scale_v * view.cos;
        if let [d_kappa, d_exponent, ..] = d_params {
            *d_kappa = k * de_dkappa;
            *d_exponent = k * de_dk;
        }
        cosine_law(pd, scene, &view, -view.cos * e, -e - view.cos * de_dc)
    }
}

/// Constant additive output per photodiode (dark current, ADC offset), present in eclipse too.
/// Id `dark-offset`; parameters `pdNN_dark_offset_V`.
#[derive(Debug, Clone, PartialEq)]
pub struct DarkOffset {
    params: Vec<Parameter>,
}

impl DarkOffset {
    /// Offsets in V, one per photodiode in order.
    pub fn new(offsets_v: &[f64]) -> Self {
        DarkOffset {
            params: Parameter::per_photodiode_list("dark_offset_V", "V", offsets_v),
        }
    }
}

impl Component for DarkOffset {
    fn id(&self) -> ComponentId {
        EffectId::DarkOffset.into()
    }
    fn parameters(&self) -> &[Parameter] {
        &self.params
    }
    fn parameters_mut(&mut self) -> &mut [Parameter] {
        &mut self.params
    }
}

impl Term for DarkOffset {
    fn value(&self, _pd: &Photodiode, index: usize, _scene: &Scene) -> f64 {
        parameter_for(&self.params, index).map_or(0.0, |(_, v)| v)
    }

    fn partials(
        &self,
        _: &Photodiode,
        index: usize,
        _: &Scene,
        d_params: &mut [f64],
    ) -> Sensitivity {
        let Some((k, value_v)) = parameter_for(&self.params, index) else {
            return Sensitivity::default();
        };
        if let Some(d) = d_params.get_mut(k) {
            *d = 1.0;
        }
        Sensitivity {
            value_v,
            ..Sensitivity::default()
        }
    }
}

/// Photodiode samples time-tagged late by `delta` seconds (a row tagged `t` was sampled at
/// `t - delta`): the Sun is seen at `s_body(t - delta) ~= s_body + delta (w x s_body)` (first
/// order, from `dA/dt = -[w x] A`). The term adds `f C delta n^T (w x s)` where the direct Sun
/// is lit (gate on the untagged `s`; albedo not shifted). Id `time-offset`; parameter
/// `time_offset_s` (shared: one clock).
#[derive(Debug, Clone, PartialEq)]
pub struct TimeOffset {
    params: [Parameter; 1],
    /// Shadow factor applied to the correction; keep equal to the [`DirectSun`]'s mode.
    pub shadow: ShadowMode,
}

impl TimeOffset {
    /// Tag minus true sampling time, s.
    pub fn new(offset_s: f64) -> Self {
        TimeOffset {
            params: [Parameter::shared("time_offset_s", "s", offset_s)],
            shadow: ShadowMode::Hard,
        }
    }
}

impl Component for TimeOffset {
    fn id(&self) -> ComponentId {
        EffectId::TimeOffset.into()
    }
    fn parameters(&self) -> &[Parameter] {
        &self.params
    }
    fn parameters_mut(&mut self) -> &mut [Parameter] {
        &mut self.params
    }
}

impl Term for TimeOffset {
    fn value(&self, pd: &Photodiode, _index: usize, scene: &Scene) -> f64 {
        let w_cross_s = scene.rate_body_rad_s.cross(&scene.sun_body);
        sun_view(pd, scene, self.shadow).map_or(0.0, |v| {
            v.shadow * pd.scale_v * self.params[0].value * pd.n_body.dot(&w_cross_s)
        })
    }

    fn partials(
        &self,
        pd: &Photodiode,
        _: usize,
        scene: &Scene,
        d_params: &mut [f64],
    ) -> Sensitivity {
        let Some(view) = sun_view(pd, scene, self.shadow) else {
            return Sensitivity::default();
        };
        let delta = self.params[0].value;
        let w = scene.rate_body_rad_s;
        let w_cross_s: Vector3<f64> = w.cross(&scene.sun_body);
        let unit_value = view.shadow * pd.scale_v * pd.n_body.dot(&w_cross_s);
        if let Some(d) = d_params.first_mut() {
            *d = unit_value;
        }
        let k = view.shadow * pd.scale_v * delta;
        Sensitivity {
            value_v: delta * unit_value,
            // d/da of n^T [w x] s(a) with ds/da = [s x]: gradient [s x][w x] n = s x (w x n).
            d_attitude: scene.sun_body.cross(&w.cross(&pd.n_body)) * k,
            d_scale: view.shadow * delta * pd.n_body.dot(&w_cross_s),
            d_normal: w_cross_s * k,
        }
    }
}

/// Scale factor drifting linearly: `C(t) = C (1 + k t_s/3600)`, a [`ScaleGain`], so every
/// term (direct Sun, albedo, corrections) sees the drifted scale. Id `scale-drift`;
/// parameters `pdNN_scale_drift_per_h` or shared `scale_drift_per_h`, unit 1/h.
#[derive(Debug, Clone, PartialEq)]
pub struct ScaleDrift {
    params: Vec<Parameter>,
}

impl ScaleDrift {
    /// One relative drift rate per photodiode, 1/h (0.01 is 1 % per hour).
    pub fn per_photodiode(fraction_per_hour: &[f64]) -> Self {
        ScaleDrift {
            params: Parameter::per_photodiode_list("scale_drift_per_h", "1/h", fraction_per_hour),
        }
    }

    /// One drift rate shared by all photodiodes, 1/h.
    pub fn shared(fraction_per_hour: f64) -> Self {
        ScaleDrift {
            params: vec![Parameter::shared(
                "scale_drift_per_h",
                "1/h",
                fraction_per_hour,
            )],
        }
    }
}

impl Component for ScaleDrift {
    fn id(&self) -> ComponentId {
        EffectId::ScaleDrift.into()
    }
    fn parameters(&self) -> &[Parameter] {
        &self.params
    }
    fn parameters_mut(&mut self) -> &mut [Parameter] {
        &mut self.params
    }
}

impl ScaleGain for ScaleDrift {
    fn gain(&self, index: usize, scene: &Scene) -> f64 {
        parameter_for(&self.params, index).map_or(1.0, |(_, k)| 1.0 + k * scene.t_s / 3600.0)
    }

    fn gain_partials(&self, index: usize, scene: &Scene, d_params: &mut [f64]) -> f64 {
        let Some((at, k)) = parameter_for(&self.params, index) else {
            return 1.0;
        };
        if let Some(d) = d_params.get_mut(at) {
            *d = scene.t_s / 3600.0;
        }
        1.0 + k * scene.t_s / 3600.0
    }
}

/// Output clipped at a maximum: `min(y, max_V)`, an [`OutputStage`]. Id `saturation`;
/// parameter `saturation_V` (shared ADC full scale) or `pdNN_saturation_V`.
///
/// Derivative w.r.t. the input: 1 below the clip, 0 at or above it; w.r.t. `max_V`: the
/// opposite. A clipped sample therefore tells the filter nothing about attitude, scale or
/// normal, only about `max_V`; and since the real sensor clips after noise, a sample near the
/// clip is a censored observation the Gaussian update does not describe. Filters should skip
/// samples within a few sigma of `max_V` unless `max_V` is a state.
#[derive(Debug, Clone, PartialEq)]
pub struct Saturation {
    params: Vec<Parameter>,
}

impl Saturation {
    /// One clip level for all photodiodes, V.
    pub fn shared(max_v: f64) -> Self {
        Saturation {
            params: vec![Parameter::shared("saturation_V", "V", max_v)],
        }
    }

    /// One clip level per photodiode, V.
    pub fn per_photodiode(max_v: &[f64]) -> Self {
        Saturation {
            params: Parameter::per_photodiode_list("saturation_V", "V", max_v),
        }
    }
}

impl Component for Saturation {
    fn id(&self) -> ComponentId {
        EffectId::Saturation.into()
    }
    fn parameters(&self) -> &[Parameter] {
        &self.params
    }
    fn parameters_mut(&mut self) -> &mut [Parameter] {
        &mut self.params
    }
}

impl OutputStage for Saturation {
    fn apply(&self, index: usize, input_v: f64) -> f64 {
        parameter_for(&self.params, index).map_or(input_v, |(_, max)| input_v.min(max))
    }

    fn apply_partials(&self, index: usize, input_v: f64, d_params: &mut [f64]) -> (f64, f64) {
        match parameter_for(&self.params, index) {
            Some((_, max)) if input_v < max => (input_v, 1.0),
            Some((at, max)) => {
                if let Some(d) = d_params.get_mut(at) {
                    *d = 1.0;
                }
                (max, 0.0)
            }
            None => (input_v, 1.0),
        }
    }
}

/// The albedo term rescaled: adds `(g - 1) C E_a/E_AM0`, so that with an [`Albedo`] term the
/// model's albedo is `g C E_a/E_AM0` (paper Eq. 15's second term times `g`): `g = 1` as
/// modelled, `g = 0` no albedo. Id `albedo-gain`; parameter `albedo_gain` (shared,
/// dimensionless). A separate term rather than a parameter of [`Albedo`], so that the
/// paper's model keeps its parameter-free direct path.
#[derive(Debug, Clone, PartialEq)]
pub struct AlbedoGain {
    albedo: Albedo,
    params: [Parameter; 1],
}

impl AlbedoGain {
    /// A gain `gain` on an albedo term with these partials.
    pub fn new(gain: f64, partials: AlbedoPartials) -> Self {
        AlbedoGain {
            albedo: Albedo { partials },
            params: [Parameter::shared("albedo_gain", "1", gain)],
        }
    }
}

impl Component for AlbedoGain {
    fn id(&self) -> ComponentId {
        EffectId::AlbedoGain.into()
    }
    fn parameters(&self) -> &[Parameter] {
        &self.params
    }
    fn parameters_mut(&mut self) -> &mut [Parameter] {
        &mut self.params
    }
}

impl Term for AlbedoGain {
    fn value(&self, pd: &Photodiode, index: usize, scene: &Scene) -> f64 {
        (self.params[0].value - 1.0) * self.albedo.value(pd, index, scene)
    }

    fn partials(
        &self,
        pd: &Photodiode,
        index: usize,
        scene: &Scene,
        d_params: &mut [f64],
    ) -> Sensitivity {
        let unit = self.albedo.partials(pd, index, scene, &mut []);
        if let Some(d) = d_params.first_mut() {
            *d = unit.value_v;
        }
        let k = self.params[0].value - 1.0;
        Sensitivity {
            value_v: k * unit.value_v,
            d_attitude: unit.d_attitude * k,
            d_scale: k * unit.d_scale,
            d_normal: unit.d_normal * k,
        }
    }
}

/// Scale factors depending on temperature: `C_i(T) = C_i (1 + k_i (T_i - T_ref))`, a
/// [`ScaleGain`], with `T_i` the scene's temperature of photodiode `i`. Id `temperature`;
/// parameters `pdNN_temperature_per_K`, unit 1/K. Where the scene has no temperature for the
/// photodiode the gain is 1 (the scale factor at `T_ref`).
#[derive(Debug, Clone, PartialEq)]
pub struct Temperature {
    params: Vec<Parameter>,
    reference_c: f64,
}

impl Temperature {
    /// One coefficient per photodiode, 1/K, about `reference_c` (degrees Celsius).
    pub fn per_photodiode(coefficient_per_k: &[f64], reference_c: f64) -> Self {
        Temperature {
            params: Parameter::per_photodiode_list("temperature_per_K", "1/K", coefficient_per_k),
            reference_c,
        }
    }

    fn excess_k(&self, index: usize, scene: &Scene) -> f64 {
        scene
            .temperature_c
            .get(index)
            .filter(|t| t.is_finite())
            .map_or(0.0, |t| t - self.reference_c)
    }
}

impl Component for Temperature {
    fn id(&self) -> ComponentId {
        EffectId::Temperature.into()
    }
    fn parameters(&self) -> &[Parameter] {
        &self.params
    }
    fn parameters_mut(&mut self) -> &mut [Parameter] {
        &mut self.params
    }
}

impl ScaleGain for Temperature {
    fn gain(&self, index: usize, scene: &Scene) -> f64 {
        parameter_for(&self.params, index)
            .map_or(1.0, |(_, k)| 1.0 + k * self.excess_k(index, scene))
    }

    fn gain_partials(&self, index: usize, scene: &Scene, d_params: &mut [f64]) -> f64 {
        let Some((at, k)) = parameter_for(&self.params, index) else {
            return 1.0;
        };
        let dt = self.excess_k(index, scene);
        if let Some(d) = d_params.get_mut(at) {
            *d = dt;
        }
        1.0 + k * dt
    }
}
