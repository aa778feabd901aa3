//! Scenario configuration: what to simulate, read from RON, checked by [`Scenario::validate`].
//!
//! Angles of mountings, mounting errors and fields of view are in degrees (this is an I/O
//! edge); rates are in rad/s as in telemetry.csv. The `effects` list uses the same RON
//! spelling as truth.ron ([`pdcal_dataset::Effect`]), so a scenario's effects are written
//! back verbatim as what was on.

use std::str::FromStr;

use nalgebra::{Matrix3, Vector3};
use pdcal_albedo::MapChoice;
use pdcal_dataset::{Effect, EffectId, NominalMount};
use pdcal_text::{number, quote};
use serde::{Deserialize, Serialize};

use crate::dynamics::{DEFAULT_MAX_STEP_S, RigidBody};

const RAX2_LIKE: &str = include_str!("../../../fixtures/scenarios/rax2-like.ron");
const SSO_6U: &str = include_str!("../../../fixtures/scenarios/sso-6u.ron");

/// Names of the built-in scenarios; the first is the default.
pub const BUILTIN_NAMES: [&str; 2] = ["rax2-like", "sso-6u"];

/// Largest number of output rows a scenario may ask for (a 1 Hz day is 86 401); guards
/// against a typo such as a duration in milliseconds.
pub const MAX_ROWS: f64 = 5e6;

/// Why a scenario cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScenarioError {
    /// The RON text does not parse into a scenario (unknown or missing field, wrong type).
    #[error("scenario RON {line}:{column}: {message}")]
    Ron {
        /// 1-based line of the error.
        line: usize,
        /// 1-based column of the error.
        column: usize,
        /// ron's message.
        message: String,
    },
    /// A field has a value the simulator cannot use.
    #[error("scenario field `{field}`: {reason}")]
    Invalid {
        /// Path of the field (`photodiodes.noise_V`).
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    /// No built-in scenario of that name.
    #[error("no built-in scenario `{0}` (built-in: rax2-like, sso-6u)")]
    UnknownBuiltin(String),
    /// Serialising the scenario back to RON failed.
    #[error("cannot write scenario RON: {0}")]
    Write(String),
}

fn invalid(field: &str, reason: impl Into<String>) -> ScenarioError {
    ScenarioError::Invalid {
        field: field.to_owned(),
        reason: reason.into(),
    }
}

/// Everything the simulator needs to produce one data set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Data-set name written into dataset.ron.
    pub name: String,
    /// Start epoch, ISO 8601 UTC (`2011-11-04T18:29:45Z`); `t_s` counts from here.
    pub epoch_utc: String,
    /// Length of the data set, s.
    pub duration_s: f64,
    /// The orbit.
    pub orbit: ScenarioOrbit,
    /// Mass properties, initial state and disturbance torques.
    pub spacecraft: Spacecraft,
    /// Photodiode layout, true-parameter distributions and noise.
    pub photodiodes: Photodiodes,
    /// Rate gyro.
    pub gyro: Gyro,
    /// Magnetometer.
    pub magnetometer: Magnetometer,
    /// Effects beyond the base model, each at most once (truth.ron spelling).
    #[serde(default)]
    pub effects: Vec<Effect>,
    /// Photodiode temperatures: a thermal model whose samples become `temp_pdNN_C` columns
    /// and whose true values drive the `temperature` effect. Absent: no temperature columns.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature: Option<Thermal>,
    /// Telemetry current channels, written as `cur_<name>_A` columns; those that drive the
    /// magnetometer add `c_j u_j` to it (`magnetometer.errors`). Absent: no current columns.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub currents: Vec<CurrentChannel>,
}

/// One telemetry current channel (a `cur_<name>_A` column).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CurrentChannel {
    /// The channel's name: `a-z`, `0-9`, `_` (the column is `cur_<name>_A`).
    pub name: String,
    /// What the current follows.
    pub source: CurrentSource,
    /// Whether it drives a magnetometer bias (`c_j` drawn from
    /// `magnetometer.errors.current_bias_nT_per_A`); a channel that does not is a control.
    #[serde(default)]
    pub drives_mag: bool,
}

/// How a channel's current evolves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum CurrentSource {
    /// A body-mounted solar panel: `max_A nu max(0, n . s_body)`, `n` its outward normal,
    /// `s_body` the Sun direction, `nu` the lit fraction of the solar disc.
    Panel {
        /// Outward normal, body frame (normalized when used).
        normal: (f64, f64, f64),
        /// Current facing the full Sun, A (file name `max_A`).
        #[serde(rename = "max_A")]
        max_a: f64,
    },
    /// A torquer driven on and off: `amplitude_A` for the first half of every period, 0 for
    /// the second.
    Square {
        /// Current when on, A (file name `amplitude_A`).
        #[serde(rename = "amplitude_A")]
        amplitude_a: f64,
        /// Period, s.
        period_s: f64,
    },
}

impl CurrentChannel {
    /// The current at `t_s` with the body Sun direction `sun_body` and lit fraction `nu`, A.
    pub fn current_a(&self, t_s: f64, sun_body: &nalgebra::Vector3<f64>, nu: f64) -> f64 {
        match self.source {
            CurrentSource::Panel { normal, max_a } => {
                let n = nalgebra::Vector3::new(normal.0, normal.1, normal.2).normalize();
                max_a * nu * n.dot(sun_body).max(0.0)
            }
            CurrentSource::Square {
                amplitude_a,
                period_s,
            } => {
                if (t_s / period_s).fract() < 0.5 {
                    amplitude_a
                } else {
                    0.0
                }
            }
        }
    }

    fn validate(&self, i: usize) -> Result<(), ScenarioError> {
        let field = |f: &str| format!("currents[{i}].{f}");
        if !pdcal_dataset::is_current_name(&self.name) {
            return Err(invalid(
                &field("name"),
                "1 to 64 of a-z, 0-9, _ only (the column is cur_<name>_A)",
            ));
        }
        let (amps, what) = match self.source {
            CurrentSource::Panel { normal, max_a } => {
                let n = nalgebra::Vector3::new(normal.0, normal.1, normal.2);
                if !(n.norm() > 0.0 && n.iter().all(|v| v.is_finite())) {
                    return Err(invalid(
                        &field("source.normal"),
                        "must be a finite non-zero vector",
                    ));
                }
                (max_a, "source.max_A")
            }
            CurrentSource::Square {
                amplitude_a,
                period_s,
            } => {
                if !(period_s.is_finite() && period_s > 0.0) {
                    return Err(invalid(&field("source.period_s"), "must be positive"));
                }
                (amplitude_a, "source.amplitude_A")
            }
        };
        let (low, high) = pdcal_dataset::CURRENT_RANGE_A;
        if !(low..=high).contains(&amps) {
            return Err(invalid(
                &field(what),
                format!("must lie within {low} .. {high} A"),
            ));
        }
        Ok(())
    }
}

/// Magnetometer errors drawn per seed (hardware: the same for every downlink):
/// `m = T B + b + sum_j c_j u_j + noise`, `T = (I + D + S) N` with `D` the scale errors,
/// `S` symmetric soft iron and `N` unit upper triangular (non-orthogonal axes). Each value
/// is a magnitude drawn from its spread with a random sign.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MagErrors {
    /// Hard-iron bias per axis, nT (file name `hard_iron_nT`).
    #[serde(rename = "hard_iron_nT")]
    pub hard_iron_nt: Spread,
    /// Scale-factor error per axis, fraction (`T_aa - 1` before the non-orthogonality).
    pub scale: Spread,
    /// Soft-iron coupling per axis pair, fraction (symmetric off-diagonal of `T`).
    pub soft_iron: Spread,
    /// Non-orthogonality per axis pair, degrees.
    pub nonorthogonality_deg: Spread,
    /// Bias per ampere of a channel with `drives_mag`, per axis, nT/A (file name
    /// `current_bias_nT_per_A`).
    #[serde(rename = "current_bias_nT_per_A")]
    pub current_bias_nt_per_a: Spread,
}

/// A first-order thermal model of each photodiode's mount, driven by sunlight:
/// `dT/dt = (T_eq - T) / tau` with `T_eq = T_cold + (T_hot - T_cold) max(0, n.s) nu`
/// (`n` the true normal, `s` the body Sun direction, `nu` the lit fraction of the solar disc).
/// Albedo and Earth infrared are left out: next to direct sunlight they shift `T_eq` by a few
/// kelvin, less than the spread between spacecraft. Sampled into `temp_pdNN_C` with white noise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Thermal {
    /// Equilibrium in the dark, degrees Celsius (file name `cold_C`).
    #[serde(rename = "cold_C", default = "default_cold_c")]
    pub cold_c: f64,
    /// Equilibrium facing the full Sun, degrees Celsius (file name `hot_C`).
    #[serde(rename = "hot_C", default = "default_hot_c")]
    pub hot_c: f64,
    /// Thermal time constant, s.
    #[serde(default = "default_tau_s")]
    pub tau_s: f64,
    /// Temperature of every photodiode at `t_s = 0`, degrees Celsius (file name
    /// `initial_C`); absent: see [`Thermal::initial_c`].
    #[serde(rename = "initial_C", default, skip_serializing_if = "Option::is_none")]
    pub initial_c: Option<f64>,
    /// Sample period of the temperature columns, s.
    #[serde(default = "default_thermal_period_s")]
    pub sample_period_s: f64,
    /// Sensor noise, 1-sigma, degrees Celsius (file name `noise_C`).
    #[serde(rename = "noise_C", default = "default_thermal_noise_c")]
    pub noise_c: f64,
}

fn default_cold_c() -> f64 {
    -20.0
}

fn default_hot_c() -> f64 {
    60.0
}

fn default_tau_s() -> f64 {
    600.0
}

fn default_thermal_period_s() -> f64 {
    10.0
}

fn default_thermal_noise_c() -> f64 {
    0.1
}

impl Default for Thermal {
    fn default() -> Self {
        Thermal {
            cold_c: default_cold_c(),
            hot_c: default_hot_c(),
            tau_s: default_tau_s(),
            initial_c: None,
            sample_period_s: default_thermal_period_s(),
            noise_c: default_thermal_noise_c(),
        }
    }
}

impl Thermal {
    /// Largest magnitude of `cold_C`, `hot_C`, `initial_C`, degrees Celsius: with the noise
    /// bound below, samples stay inside the dataset reader's plausible range.
    pub const MAX_ABS_C: f64 = 120.0;
    /// Largest `noise_C`, degrees Celsius.
    pub const MAX_NOISE_C: f64 = 2.0;

    /// The temperature at the first sample, degrees Celsius: `initial_C`, or the middle of
    /// the cold and hot equilibria (a tumbling spacecraft's faces average near there).
    pub fn initial_c(&self) -> f64 {
        self.initial_c.unwrap_or(0.5 * (self.cold_c + self.hot_c))
    }

    /// The equilibrium temperature for illumination `lit` (`max(0, n.s) nu`, 0..1), C.
    pub fn equilibrium_c(&self, lit: f64) -> f64 {
        self.cold_c + (self.hot_c - self.cold_c) * lit
    }

    fn validate(&self, duration_s: f64) -> Result<(), ScenarioError> {
        for (field, v) in [
            ("temperature.cold_C", Some(self.cold_c)),
            ("temperature.hot_C", Some(self.hot_c)),
            ("temperature.initial_C", self.initial_c),
        ] {
            if let Some(v) = v
                && !(v.is_finite() && v.abs() <= Self::MAX_ABS_C)
            {
                return Err(invalid(
                    field,
                    format!("{} is not within -{1} .. {1} C", number(v), Self::MAX_ABS_C),
                ));
            }
        }
        if self.hot_c < self.cold_c {
            return Err(invalid(
                "temperature.hot_C",
                format!(
                    "{} is below cold_C = {}",
                    number(self.hot_c),
                    number(self.cold_c)
                ),
            ));
        }
        check_positive("temperature.tau_s", self.tau_s)?;
        check_non_negative("temperature.noise_C", self.noise_c)?;
        if self.noise_c > Self::MAX_NOISE_C {
            return Err(invalid(
                "temperature.noise_C",
                format!(
                    "{} C is above {} C",
                    number(self.noise_c),
                    Self::MAX_NOISE_C
                ),
            ));
        }
        check_period(
            "temperature.sample_period_s",
            self.sample_period_s,
            duration_s,
        )
    }
}

/// The orbit of a scenario.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum ScenarioOrbit {
    /// A two-line element set propagated with SGP4; checksums must hold.
    Tle {
        /// Line 1.
        line1: String,
        /// Line 2.
        line2: String,
    },
}

/// Spacecraft body and its initial motion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spacecraft {
    /// Inertia tensor about the centre of mass, body frame, rows, kg m^2.
    pub inertia_kg_m2: [[f64; 3]; 3],
    /// Angular velocity at the first sample.
    pub initial_rate: InitialRate,
    /// Attitude at the first sample.
    pub initial_attitude: InitialAttitude,
    /// Gravity-gradient torque on.
    #[serde(default)]
    pub gravity_gradient: bool,
    /// Residual magnetic dipole, body frame, A m^2 (file name `dipole_A_m2`).
    #[serde(rename = "dipole_A_m2", default)]
    pub dipole_a_m2: [f64; 3],
    /// Largest RK4 step, s.
    #[serde(default = "default_max_step")]
    pub max_step_s: f64,
}

fn default_max_step() -> f64 {
    DEFAULT_MAX_STEP_S
}

fn default_period() -> f64 {
    1.0
}

/// Initial angular velocity.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum InitialRate {
    /// A given body-frame rate, rad/s.
    Fixed {
        /// Body-frame angular velocity, rad/s.
        rad_s: [f64; 3],
    },
    /// A seeded random direction with this magnitude, rad/s.
    RandomTumble {
        /// Magnitude of the angular velocity, rad/s.
        magnitude_rad_s: f64,
    },
}

/// Initial attitude.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum InitialAttitude {
    /// A given quaternion `[x, y, z, w]` (scalar last; normalised on use).
    Fixed {
        /// Quaternion components, scalar last.
        q: [f64; 4],
    },
    /// A seeded attitude uniform on SO(3).
    Random,
}

/// A seeded distribution of a scalar.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Spread {
    /// Always this value.
    Fixed(f64),
    /// Uniform on `[min, max]`.
    Uniform {
        /// Lower bound.
        min: f64,
        /// Upper bound.
        max: f64,
    },
    /// Gaussian.
    Normal {
        /// Mean.
        mean: f64,
        /// Standard deviation (>= 0).
        sigma: f64,
    },
}

impl Spread {
    fn check(&self, field: &str) -> Result<(), ScenarioError> {
        let ok = match *self {
            Spread::Fixed(v) => v.is_finite(),
            Spread::Uniform { min, max } => min.is_finite() && max.is_finite() && min <= max,
            Spread::Normal { mean, sigma } => mean.is_finite() && sigma.is_finite() && sigma >= 0.0,
        };
        if ok {
            Ok(())
        } else {
            Err(invalid(
                field,
                format!("{self:?} is not a valid distribution"),
            ))
        }
    }

    /// The smallest and largest value a draw can take (+-6 sigma for a Gaussian).
    fn range(&self) -> (f64, f64) {
        match *self {
            Spread::Fixed(v) => (v, v),
            Spread::Uniform { min, max } => (min, max),
            Spread::Normal { mean, sigma } => (mean - 6.0 * sigma, mean + 6.0 * sigma),
        }
    }
}

/// The photodiodes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Photodiodes {
    /// Intended mounting, `pdNN` order, degrees (dataset.ron's `photodiodes`).
    pub nominal: Vec<NominalMount>,
    /// The mounting dataset.ron states instead of `nominal`, when the two differ (a head
    /// mounted rotated from its drawing): the true normals are drawn around `nominal`, the
    /// calibration is told `assumed`. Absent: dataset.ron states `nominal`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub assumed: Option<Vec<NominalMount>>,
    /// Hard field-of-view half angle of the true sensor (a recessed mount), degrees: beyond
    /// it neither direct sunlight nor albedo reaches the diode ([`pdcal_photodiode::Photodiode`]'s
    /// FOV gate). Absent: the cosine law holds to 90 deg (then `fov-rolloff` is the way to
    /// model a gradual departure from it). The usable FOV of the *filter* (60-70 deg in the
    /// paper) is a calibration setting, not a property of the truth.
    #[serde(default)]
    pub fov_half_angle_deg: Option<f64>,
    /// Output noise, 1-sigma, V (file name `noise_V`).
    #[serde(rename = "noise_V")]
    pub noise_v: f64,
    /// Distribution of the true scale factors `C`, V (file name `scale_V`).
    #[serde(rename = "scale_V")]
    pub scale_v: Spread,
    /// Distribution of the true-minus-intended azimuth and elevation, each drawn
    /// independently, degrees.
    pub mounting_error_deg: Spread,
    /// Sample period, s.
    #[serde(default = "default_period")]
    pub sample_period_s: f64,
}

/// The rate gyro: `measured = (1 + e) w + bias + noise` (`e` only with `gyro-scale`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gyro {
    /// White noise per sample and axis, 1-sigma, rad/s.
    pub noise_rad_s: f64,
    /// Distribution of each axis of the initial bias, rad/s.
    pub bias_rad_s: Spread,
    /// Bias random walk, rad/s per sqrt(s): after `dt` the bias changes by
    /// `N(0, walk^2 dt)` per axis.
    #[serde(default)]
    pub bias_walk_rad_s_sqrt_s: f64,
    /// Sample period, s.
    #[serde(default = "default_period")]
    pub sample_period_s: f64,
}

/// The magnetometer: `measured = A B_ref + noise` (+ bias with `mag-bias`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Magnetometer {
    /// White noise per sample and axis, 1-sigma, nT (file name `noise_nT`).
    #[serde(rename = "noise_nT")]
    pub noise_nt: f64,
    /// Sample period, s.
    #[serde(default = "default_period")]
    pub sample_period_s: f64,
    /// Hard iron, scale, soft iron, non-orthogonality and current-driven bias. Absent: an
    /// ideal sensor (beyond `mag-bias`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub errors: Option<MagErrors>,
}

/// A mounting's angles: azimuth finite, elevation within [-90, 90] deg.
fn check_mount(m: &NominalMount, at: &str) -> Result<(), ScenarioError> {
    if !(m.azimuth_deg.is_finite() && m.elevation_deg.is_finite() && m.elevation_deg.abs() <= 90.0)
    {
        return Err(invalid(
            at,
            "azimuth must be finite and elevation within [-90, 90] deg",
        ));
    }
    Ok(())
}

impl Scenario {
    /// Parses a scenario from RON text and validates it.
    pub fn from_ron_str(text: &str) -> Result<Self, ScenarioError> {
        let scenario: Scenario = ron_options()
            .from_str(text)
            .map_err(|e| ScenarioError::Ron {
                line: e.span.start.line,
                column: e.span.start.col,
                message: pdcal_text::parser_message(&e.code.to_string()),
            })?;
        scenario.validate()?;
        Ok(scenario)
    }

    /// A built-in scenario by name (see [`BUILTIN_NAMES`]); `rax2-like` is the default.
    pub fn builtin(name: &str) -> Result<Self, ScenarioError> {
        match name {
            "rax2-like" => Self::from_ron_str(RAX2_LIKE),
            "sso-6u" => Self::from_ron_str(SSO_6U),
            other => Err(ScenarioError::UnknownBuiltin(other.to_owned())),
        }
    }

    /// The default scenario, `rax2-like`.
    pub fn rax2_like() -> Result<Self, ScenarioError> {
        Self::builtin("rax2-like")
    }

    /// Pretty RON text of the scenario (parses back to an equal scenario).
    pub fn to_ron_string(&self) -> Result<String, ScenarioError> {
        let config = ron::ser::PrettyConfig::new().depth_limit(3);
        ron_options()
            .to_string_pretty(self, config)
            .map_err(|e| ScenarioError::Write(e.to_string()))
    }

    /// Number of photodiodes.
    pub fn n_photodiodes(&self) -> usize {
        self.photodiodes.nominal.len()
    }

    /// The inertia tensor as a matrix, kg m^2.
    pub fn inertia_kg_m2(&self) -> Matrix3<f64> {
        let j = &self.spacecraft.inertia_kg_m2;
        Matrix3::from_fn(|r, c| j[r][c])
    }

    /// The residual dipole, body frame, A m^2.
    pub fn dipole_body_a_m2(&self) -> Vector3<f64> {
        Vector3::from(self.spacecraft.dipole_a_m2)
    }

    /// The effect with this id, if it is on.
    pub fn effect(&self, id: EffectId) -> Option<&Effect> {
        self.effects.iter().find(|e| e.id() == id)
    }

    /// Checks every field for values the simulator cannot use; the message names the field.
    pub fn validate(&self) -> Result<(), ScenarioError> {
        if self.name.trim().is_empty() {
            return Err(invalid("name", "must not be empty"));
        }
        pdcal_ephem::time::parse_utc(&self.epoch_utc)
            .map_err(|e| invalid("epoch_utc", e.to_string()))?;
        let ScenarioOrbit::Tle { line1, line2 } = &self.orbit;
        pdcal_ephem::TleOrbit::from_lines(line1, line2)
            .map_err(|e| invalid("orbit", e.to_string()))?;
        check_positive("duration_s", self.duration_s)?;
        self.validate_spacecraft()?;
        self.validate_sensors()?;
        self.validate_effects()
    }

    fn validate_spacecraft(&self) -> Result<(), ScenarioError> {
        let sc = &self.spacecraft;
        RigidBody::new(self.inertia_kg_m2())
            .map_err(|e| invalid("spacecraft.inertia_kg_m2", e.to_string()))?;
        check_positive("spacecraft.max_step_s", sc.max_step_s)?;
        if !sc.dipole_a_m2.iter().all(|v| v.is_finite()) {
            return Err(invalid("spacecraft.dipole_A_m2", "must be finite"));
        }
        match sc.initial_rate {
            InitialRate::Fixed { rad_s } if !rad_s.iter().all(|v| v.is_finite()) => {
                return Err(invalid("spacecraft.initial_rate", "must be finite"));
            }
            InitialRate::RandomTumble { magnitude_rad_s } => {
                check_non_negative("spacecraft.initial_rate.magnitude_rad_s", magnitude_rad_s)?;
            }
            InitialRate::Fixed { .. } => {}
        }
        if let InitialAttitude::Fixed { q } = sc.initial_attitude
            && pdcal_attitude::Quat::new_normalized(q[0], q[1], q[2], q[3]).is_none()
        {
            return Err(invalid(
                "spacecraft.initial_attitude.q",
                "must be finite and non-zero",
            ));
        }
        Ok(())
    }

    fn validate_sensors(&self) -> Result<(), ScenarioError> {
        let pd = &self.photodiodes;
        let n = pd.nominal.len();
        if n == 0 || n > 999 {
            return Err(invalid(
                "photodiodes.nominal",
                format!("needs 1 to 999 entries, has {n}"),
            ));
        }
        if let Some(assumed) = &pd.assumed {
            if assumed.len() != n {
                return Err(invalid(
                    "photodiodes.assumed",
                    format!("has {} entries, nominal has {n}", assumed.len()),
                ));
            }
            for (i, m) in assumed.iter().enumerate() {
                check_mount(m, &format!("photodiodes.assumed[{i}]"))?;
            }
        }
        for (i, m) in pd.nominal.iter().enumerate() {
            check_mount(m, &format!("photodiodes.nominal[{i}]"))?;
            if let Some(panel) = &m.panel
                && !pdcal_dataset::is_panel_name(panel)
            {
                return Err(invalid(
                    &format!("photodiodes.nominal[{i}].panel"),
                    format!(
                        "{} is not a panel name (a-z, 0-9, _; not pd and a digit)",
                        quote(panel)
                    ),
                ));
            }
            if let Some(fov) = m.fov_deg
                && !(fov > 0.0 && fov <= 90.0)
            {
                return Err(invalid(
                    &format!("photodiodes.nominal[{i}].fov_deg"),
                    format!("{fov} is not in (0, 90]"),
                ));
            }
        }
        if let Some(fov) = pd.fov_half_angle_deg
            && !(fov > 0.0 && fov <= 90.0)
        {
            return Err(invalid(
                "photodiodes.fov_half_angle_deg",
                format!("{} is not in (0, 90]", number(fov)),
            ));
        }
        check_non_negative("photodiodes.noise_V", pd.noise_v)?;
        pd.scale_v.check("photodiodes.scale_V")?;
        if pd.scale_v.range().0 <= 0.0 {
            return Err(invalid(
                "photodiodes.scale_V",
                "scale factors must stay positive",
            ));
        }
        pd.mounting_error_deg
            .check("photodiodes.mounting_error_deg")?;
        let (lo, hi) = pd.mounting_error_deg.range();
        if lo.abs().max(hi.abs()) > 45.0 {
            return Err(invalid(
                "photodiodes.mounting_error_deg",
                "errors beyond 45 deg are not mounting errors",
            ));
        }
        check_non_negative("gyro.noise_rad_s", self.gyro.noise_rad_s)?;
        self.gyro.bias_rad_s.check("gyro.bias_rad_s")?;
        check_non_negative(
            "gyro.bias_walk_rad_s_sqrt_s",
            self.gyro.bias_walk_rad_s_sqrt_s,
        )?;
        check_non_negative("magnetometer.noise_nT", self.magnetometer.noise_nt)?;
        for (field, period) in [
            ("photodiodes.sample_period_s", pd.sample_period_s),
            ("gyro.sample_period_s", self.gyro.sample_period_s),
            (
                "magnetometer.sample_period_s",
                self.magnetometer.sample_period_s,
            ),
        ] {
            check_period(field, period, self.duration_s)?;
        }
        if let Some(thermal) = &self.temperature {
            thermal.validate(self.duration_s)?;
        }
        if let Some(errors) = &self.magnetometer.errors {
            errors
                .hard_iron_nt
                .check("magnetometer.errors.hard_iron_nT")?;
            errors.scale.check("magnetometer.errors.scale")?;
            errors.soft_iron.check("magnetometer.errors.soft_iron")?;
            (errors.nonorthogonality_deg).check("magnetometer.errors.nonorthogonality_deg")?;
            (errors.current_bias_nt_per_a).check("magnetometer.errors.current_bias_nT_per_A")?;
        }
        for (i, channel) in self.currents.iter().enumerate() {
            channel.validate(i)?;
            if self.currents[..i].iter().any(|c| c.name == channel.name) {
                return Err(invalid(
                    &format!("currents[{i}].name"),
                    "a second channel of this name",
                ));
            }
        }
        Ok(())
    }

    fn validate_effects(&self) -> Result<(), ScenarioError> {
        let n = self.n_photodiodes();
        for (i, effect) in self.effects.iter().enumerate() {
            let field = format!("effects[{i}] ({})", effect.id());
            if self.effects[..i].iter().any(|e| e.id() == effect.id()) {
                return Err(invalid(&field, "effect listed twice"));
            }
            effect
                .check(n)
                .map_err(|bad| invalid(&field, bad.to_string()))?;
            if let Effect::Albedo { map } = effect {
                MapChoice::from_str(map).map_err(|e| invalid(&field, e.to_string()))?;
            }
            // Without these the effect would be written to truth.ron as "on" while changing
            // nothing in the data.
            if matches!(effect.id(), EffectId::AlbedoGain | EffectId::AlbedoMap)
                && self.effect(EffectId::Albedo).is_none()
            {
                return Err(invalid(
                    &field,
                    "scales the albedo term, so the scenario's effects need `albedo` as well",
                ));
            }
            if effect.id() == EffectId::Temperature && self.temperature.is_none() {
                return Err(invalid(
                    &field,
                    "needs photodiode temperatures: add the scenario field \
                     `temperature: Thermal()`",
                ));
            }
        }
        Ok(())
    }
}

/// `implicit_some` lets optional fields be written bare (`fov_half_angle_deg: 70.0`).
fn ron_options() -> ron::Options {
    ron::Options::default().with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
}

fn check_period(field: &str, period: f64, duration_s: f64) -> Result<(), ScenarioError> {
    // Times are kept in whole microseconds.
    if !(period >= 1e-6 && period.is_finite()) {
        return Err(invalid(
            field,
            format!("{} s is not a period of at least 1 us", number(period)),
        ));
    }
    let samples = duration_s / period;
    if samples > MAX_ROWS {
        // Neither field alone is wrong: both are named.
        return Err(invalid(
            "duration_s",
            format!(
                "{} s sampled every {} s ({field}) is {samples:.3e} samples, more than \
                 {MAX_ROWS}: a shorter duration_s or a longer {field}",
                number(duration_s),
                number(period)
            ),
        ));
    }
    Ok(())
}

fn check_positive(field: &str, v: f64) -> Result<(), ScenarioError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(invalid(
            field,
            format!("{} must be finite and positive", number(v)),
        ))
    }
}

fn check_non_negative(field: &str, v: f64) -> Result<(), ScenarioError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(invalid(
            field,
            format!("{} must be finite and non-negative", number(v)),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtins_parse_validate_and_round_trip() {
        for name in BUILTIN_NAMES {
            let s = Scenario::builtin(name).unwrap();
            assert_eq!(s.name, name);
            let text = s.to_ron_string().unwrap();
            assert_eq!(
                Scenario::from_ron_str(&text).unwrap(),
                s,
                "{name} round trip"
            );
        }
    }

    #[test]
    fn builtin_tles_carry_valid_checksums() {
        for name in BUILTIN_NAMES {
            let ScenarioOrbit::Tle { line1, line2 } = Scenario::builtin(name).unwrap().orbit;
            assert!(pdcal_ephem::tle::checksum_ok(&line1), "{name} line 1");
            assert!(pdcal_ephem::tle::checksum_ok(&line2), "{name} line 2");
        }
    }

    #[test]
    fn rax2_like_carries_the_scenario_document_numbers() {
        let s = Scenario::rax2_like().unwrap();
        assert_eq!(s.n_photodiodes(), 17);
        assert_eq!(s.duration_s, 7200.0);
        assert_eq!(s.epoch_utc, "2011-11-04T18:29:45Z");
        assert_eq!(s.photodiodes.noise_v, 0.015);
        assert_eq!(s.magnetometer.noise_nt, 320.0);
        assert_eq!(
            s.photodiodes.scale_v,
            Spread::Uniform { min: 3.5, max: 3.9 }
        );
        let table1 = pdcal_attitude::RAX2_TABLE1_AZ_EL_DEG;
        for (m, (az, el)) in s.photodiodes.nominal.iter().zip(table1) {
            assert_eq!((m.azimuth_deg, m.elevation_deg), (az, el));
        }
        let diag = Vector3::new(0.0314, 0.0314, 0.0050);
        assert_eq!(s.inertia_kg_m2(), Matrix3::from_diagonal(&diag));
    }

    #[test]
    fn sso_6u_differs_from_rax2() {
        let s = Scenario::builtin("sso-6u").unwrap();
        assert_eq!(s.n_photodiodes(), 10);
        assert_ne!(
            s.inertia_kg_m2(),
            Scenario::rax2_like().unwrap().inertia_kg_m2()
        );
    }

    #[test]
    fn unknown_builtin_is_an_error() {
        assert_eq!(
            Scenario::builtin("nope"),
            Err(ScenarioError::UnknownBuiltin("nope".into()))
        );
    }

    #[test]
    fn unknown_field_is_a_ron_error_with_position() {
        let text = RAX2_LIKE.replacen("duration_s:", "duration_seconds:", 1);
        match Scenario::from_ron_str(&text) {
            Err(ScenarioError::Ron { line, message, .. }) => {
                assert!(line > 1);
                assert!(message.contains("duration_seconds"), "{message}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn missing_field_and_wrong_type_are_ron_errors() {
        let missing = RAX2_LIKE.replacen("noise_nT:", "// noise_nT:", 1);
        assert!(matches!(
            Scenario::from_ron_str(&missing),
            Err(ScenarioError::Ron { .. })
        ));
        let wrong = RAX2_LIKE.replacen("duration_s: 7200.0", "duration_s: \"long\"", 1);
        assert!(matches!(
            Scenario::from_ron_str(&wrong),
            Err(ScenarioError::Ron { .. })
        ));
        assert!(matches!(
            Scenario::from_ron_str(""),
            Err(ScenarioError::Ron { .. })
        ));
    }

    fn field_of(result: Result<(), ScenarioError>) -> String {
        match result {
            Err(ScenarioError::Invalid { field, .. }) => field,
            other => panic!("expected Invalid, got {other:?}"),
        }
    }

    #[test]
    fn validate_names_the_bad_field() {
        let base = Scenario::rax2_like().unwrap();
        let mut s = base.clone();
        s.duration_s = f64::NAN;
        assert_eq!(field_of(s.validate()), "duration_s");
        let mut s = base.clone();
        s.photodiodes.noise_v = -1.0;
        assert_eq!(field_of(s.validate()), "photodiodes.noise_V");
        let mut s = base.clone();
        s.spacecraft.inertia_kg_m2[2][2] = 0.1;
        assert_eq!(field_of(s.validate()), "spacecraft.inertia_kg_m2");
        let mut s = base.clone();
        s.photodiodes.scale_v = Spread::Uniform { min: 3.9, max: 3.5 };
        assert_eq!(field_of(s.validate()), "photodiodes.scale_V");
        let mut s = base.clone();
        s.gyro.sample_period_s = 0.0;
        assert_eq!(field_of(s.validate()), "gyro.sample_period_s");
        let mut s = base.clone();
        s.epoch_utc = "yesterday".into();
        assert_eq!(field_of(s.validate()), "epoch_utc");
        // Too many samples: the duration, with the period it was sampled at.
        let mut s = base.clone();
        s.duration_s = 1e12;
        let e = s.validate().unwrap_err().to_string();
        assert_eq!(field_of(s.validate()), "duration_s");
        assert!(
            e.contains("1000000000000 s sampled every 1 s (photodiodes.sample_period_s)"),
            "{e}"
        );
    }

    #[test]
    fn an_assumed_mounting_is_what_dataset_ron_states() {
        let text = include_str!("../../../fixtures/scenarios/weak/pyramid-head-rotated.ron");
        let s = Scenario::from_ron_str(text).unwrap();
        let assumed = s.photodiodes.assumed.clone().unwrap();
        for (a, n) in assumed.iter().zip(&s.photodiodes.nominal) {
            // The head turned 15 deg about its boresight (+z): azimuths 15 deg on.
            let turn = (a.azimuth_deg - n.azimuth_deg).rem_euclid(360.0);
            assert!((turn - 15.0).abs() < 1e-9, "{a:?} {n:?}");
            assert_eq!(a.elevation_deg, n.elevation_deg);
        }
        let out = crate::simulate(&s, 1).unwrap();
        assert_eq!(out.meta.photodiodes, assumed);
        let mut short = s.clone();
        short.photodiodes.assumed.as_mut().unwrap().pop();
        assert_eq!(field_of(short.validate()), "photodiodes.assumed");
        let mut bad = s;
        bad.photodiodes.assumed.as_mut().unwrap()[2].elevation_deg = 91.0;
        assert_eq!(field_of(bad.validate()), "photodiodes.assumed[2]");
    }

    #[test]
    fn bad_tle_checksum_is_rejected() {
        let mut s = Scenario::rax2_like().unwrap();
        let ScenarioOrbit::Tle { line1, line2 } = s.orbit.clone();
        s.orbit = ScenarioOrbit::Tle {
            line1: line1.replacen("37853U", "37854U", 1),
            line2,
        };
        assert_eq!(field_of(s.validate()), "orbit");
    }

    #[test]
    fn effect_parameters_are_checked() {
        let base = Scenario::rax2_like().unwrap();
        let cases = [
            Effect::DarkOffset {
                volts: vec![0.01; 3],
            },
            Effect::ScaleDrift {
                fraction_per_hour: vec![0.0; 18],
            },
            Effect::FovRolloff {
                start_rad: 80f64.to_radians(),
                cutoff_rad: 70f64.to_radians(),
            },
            Effect::Saturation { volts: 0.0 },
            Effect::Albedo {
                map: "no-such-map".into(),
            },
            Effect::GyroScale {
                scale_error: [f64::NAN, 0.0, 0.0],
            },
        ];
        for effect in cases {
            let mut s = base.clone();
            s.effects = vec![effect.clone()];
            assert!(
                field_of(s.validate()).starts_with("effects[0]"),
                "{effect:?}"
            );
        }
        let mut s = base.clone();
        s.effects = vec![Effect::Penumbra, Effect::Penumbra];
        assert!(field_of(s.validate()).starts_with("effects[1]"));
    }
}
