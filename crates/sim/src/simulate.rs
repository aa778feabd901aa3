//! The simulation run: dynamics, environment, sensors and effects into the dataset types.

use nalgebra::{Matrix3, Vector3, Vector4};
use pdcal_albedo::{AlbedoError, AlbedoModel, AlbedoView, MapChoice, MapError};
use pdcal_attitude::Quat;
use pdcal_dataset::{
    CurrentColumn, Dataset, DatasetMeta, Effect, EpochUtc, FORMAT_VERSION, Inertia, NoiseHints,
    OrbitSpec, Samples, Telemetry, TemperatureColumn, TrueMagnetometer, TruePd, TruthConstants,
    TruthSeries, Vectors, current_column, photodiode_temperature_column,
};
use pdcal_ephem::igrf::IgrfError;
use pdcal_ephem::{OrbitError, Reference, ReferenceError, ReferenceModel, TimeError, TleOrbit};
use pdcal_photodiode::{
    EffectId, EffectModelOptions, MeasurementModel, Photodiode, PhotodiodeError, Scene, ShadowMode,
    add_effect,
};
use rand::rngs::ChaCha8Rng;
use rayon::prelude::*;

use crate::dynamics::{
    AttitudeState, Disturbances, DynamicsError, RigidBody, TorqueEnvironment, propagate,
};
use crate::random::{self, Seed, Stream};
use crate::scenario::{
    InitialAttitude, InitialRate, Scenario, ScenarioError, ScenarioOrbit, Spread, Thermal,
};

/// Why a simulation failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// The scenario is invalid.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The orbit could not be built or propagated.
    #[error("orbit at t = {t_s} s: {source}")]
    Orbit {
        /// Time since the epoch, s.
        t_s: f64,
        /// The ephemeris error.
        source: OrbitError,
    },
    /// The magnetic field model failed (e.g. the epoch is outside IGRF-14).
    #[error("magnetic field at t = {t_s} s: {source}")]
    Field {
        /// Time since the epoch, s.
        t_s: f64,
        /// The IGRF error.
        source: IgrfError,
    },
    /// A time conversion failed.
    #[error("time: {0}")]
    Time(#[from] TimeError),
    /// The albedo map could not be loaded.
    #[error("albedo map: {0}")]
    AlbedoMap(#[from] MapError),
    /// The albedo model failed at a sample.
    #[error("albedo at t = {t_s} s: {source}")]
    Albedo {
        /// Time since the epoch, s.
        t_s: f64,
        /// The albedo error.
        source: AlbedoError,
    },
    /// The photodiode model rejected a parameter or scene.
    #[error("photodiode model: {0}")]
    Photodiode(#[from] PhotodiodeError),
    /// The dynamics set-up failed.
    #[error(transparent)]
    Dynamics(#[from] DynamicsError),
    /// The epoch text cannot be written to dataset.ron.
    #[error("epoch_utc: {0}")]
    Epoch(String),
}

/// The result of [`simulate`]: everything of the dataset plus what tests and plots need.
#[derive(Debug, Clone, PartialEq)]
pub struct SimOutput {
    /// dataset.ron.
    pub meta: DatasetMeta,
    /// telemetry.csv.
    pub telemetry: Telemetry,
    /// truth.csv.
    pub truth: TruthSeries,
    /// truth.ron.
    pub constants: TruthConstants,
    /// Unit vector from the spacecraft to the Sun, GCRF, per truth row.
    pub sun_gcrf: Vec<Vector3<f64>>,
    /// Reference magnetic field, GCRF, nT, per truth row.
    pub mag_gcrf_nt: Vec<Vector3<f64>>,
    /// Photodiode outputs without noise (stages such as saturation applied), V:
    /// `pd_noise_free_v[i][k]` for photodiode `i + 1` at row `k`, `None` when not sampled.
    pub pd_noise_free_v: Vec<Vec<Option<f64>>>,
    /// The true photodiodes as the measurement model holds them (radians inside).
    pub true_photodiodes: Vec<Photodiode>,
    /// True temperature of each photodiode, degrees Celsius: `temperature_true_c[i][k]` for
    /// photodiode `i + 1` at row `k`; empty without the scenario's thermal model.
    pub temperature_true_c: Vec<Vec<f64>>,
    /// The seed of the run.
    pub seed: u64,
    /// Which downlink of the seed's spacecraft ([`simulate_downlink`]); 0 for [`simulate`].
    pub downlink: u64,
}

impl SimOutput {
    /// The data set to write: meta, telemetry and both truth files.
    pub fn to_dataset(&self) -> Dataset {
        Dataset {
            meta: self.meta.clone(),
            telemetry: self.telemetry.clone(),
            truth: Some((self.truth.clone(), self.constants.clone())),
        }
    }

    /// As [`SimOutput::to_dataset`], without copying.
    pub fn into_dataset(self) -> Dataset {
        Dataset {
            meta: self.meta,
            telemetry: self.telemetry,
            truth: Some((self.truth, self.constants)),
        }
    }
}

/// Microseconds per second: sample times are kept as whole microseconds so that the union
/// of several sensors' grids has no near-duplicate rows.
const US_PER_S: f64 = 1e6;

fn to_us(t_s: f64) -> i64 {
    (t_s * US_PER_S).round() as i64
}

fn to_s(t_us: i64) -> f64 {
    t_us as f64 / US_PER_S
}

/// Which sensors sample at each row.
struct Grid {
    rows_us: Vec<i64>,
    periods_us: [i64; 3],
    thermal_us: Option<i64>,
}

const GYRO: usize = 0;
const MAG: usize = 1;
const PD: usize = 2;

impl Grid {
    fn new(scenario: &Scenario) -> Self {
        let duration_us = to_us(scenario.duration_s);
        let periods_us = [
            to_us(scenario.gyro.sample_period_s),
            to_us(scenario.magnetometer.sample_period_s),
            to_us(scenario.photodiodes.sample_period_s),
        ];
        let thermal_us = (scenario.temperature.as_ref()).map(|th| to_us(th.sample_period_s));
        let mut rows_us: Vec<i64> = periods_us
            .iter()
            .chain(&thermal_us)
            .flat_map(|&p| (0..=duration_us / p).map(move |k| k * p))
            .collect();
        rows_us.sort_unstable();
        rows_us.dedup();
        Grid {
            rows_us,
            periods_us,
            thermal_us,
        }
    }

    fn samples(&self, sensor: usize, t_us: i64) -> bool {
        t_us % self.periods_us[sensor] == 0
    }

    fn samples_temperature(&self, t_us: i64) -> bool {
        self.thermal_us.is_some_and(|p| t_us % p == 0)
    }
}

/// The ephemeris of a run: the same [`ReferenceModel`] the filter's driver uses, so truth
/// and filter see identical reference vectors.
struct Ephemeris(ReferenceModel);

impl Ephemeris {
    fn new(scenario: &Scenario) -> Result<Self, SimError> {
        let epoch = pdcal_ephem::time::parse_utc(&scenario.epoch_utc)?;
        let ScenarioOrbit::Tle { line1, line2 } = &scenario.orbit;
        let orbit = TleOrbit::from_lines(line1, line2)
            .map_err(|source| SimError::Orbit { t_s: 0.0, source })?;
        ReferenceModel::new(epoch, Box::new(orbit))
            .map(Ephemeris)
            .map_err(|e| reference_error(0.0, e))
    }

    fn at(&self, t_s: f64) -> Result<Reference, SimError> {
        self.0.at(t_s).map_err(|e| reference_error(t_s, e))
    }
}

fn reference_error(t_s: f64, error: ReferenceError) -> SimError {
    match error {
        ReferenceError::Time(e) => SimError::Time(e),
        ReferenceError::Orbit(source) => SimError::Orbit { t_s, source },
        ReferenceError::Field(source) => SimError::Field { t_s, source },
    }
}

/// True photodiode parameters: scale and az/el (degrees, as truth.ron records them).
fn draw_true_photodiodes(scenario: &Scenario, rng: &mut ChaCha8Rng) -> Vec<TruePd> {
    let pd = &scenario.photodiodes;
    pd.nominal
        .iter()
        .map(|m| {
            let scale_v = random::draw(&pd.scale_v, rng);
            let azimuth_deg = m.azimuth_deg + random::draw(&pd.mounting_error_deg, rng);
            let el = m.elevation_deg + random::draw(&pd.mounting_error_deg, rng);
            // Past a pole, fold back: the normal then lies |error| from the nominal pole with
            // the azimuth kept near its nominal value (azimuth is not wrapped either, so
            // true minus nominal stays the drawn error).
            let elevation_deg = if el > 90.0 {
                180.0 - el
            } else if el < -90.0 {
                -180.0 - el
            } else {
                el
            };
            TruePd {
                scale_v,
                azimuth_deg,
                elevation_deg,
            }
        })
        .collect()
}

/// The truth measurement model: the photodiode crate's terms for the effects that are on,
/// hard-edged direct Sun as the base. `time-offset` is not a term here: the simulator
/// samples the scene at the true (shifted) time instead of the first-order correction.
pub fn truth_model(
    scenario: &Scenario,
    photodiodes: Vec<Photodiode>,
) -> Result<MeasurementModel, SimError> {
    let mut model = MeasurementModel::cosine(photodiodes);
    let options = EffectModelOptions::default();
    for effect in &scenario.effects {
        add_effect(&mut model, effect, options)?;
    }
    Ok(model)
}

/// Initial attitude and rate from the scenario and the `InitialState` stream. Both draws
/// are always made, so fixing one does not change the other.
fn initial_state(scenario: &Scenario, seed: Seed) -> AttitudeState {
    let mut rng = seed.stream(Stream::InitialState);
    let q_random = random::uniform_quaternion(&mut rng);
    let direction = random::unit_vector(&mut rng);
    let q = match scenario.spacecraft.initial_attitude {
        InitialAttitude::Fixed { q } => Vector4::from(q),
        InitialAttitude::Random => q_random,
    };
    let w_body_rad_s = match scenario.spacecraft.initial_rate {
        InitialRate::Fixed { rad_s } => Vector3::from(rad_s),
        InitialRate::RandomTumble { magnitude_rad_s } => direction * magnitude_rad_s,
    };
    AttitudeState {
        // validate() rejects a zero or non-finite fixed quaternion.
        q: Quat::new_normalized(q.x, q.y, q.z, q.w).unwrap_or(Quat::IDENTITY),
        w_body_rad_s,
    }
}

/// Sorted, distinct times at which the state is needed: every row, and every true
/// photodiode sampling time (row tag minus the time offset).
fn event_times(grid: &Grid, pd_offset_us: i64) -> Vec<i64> {
    let mut events = grid.rows_us.clone();
    if pd_offset_us != 0 {
        events.extend(
            grid.rows_us
                .iter()
                .filter(|&&t| grid.samples(PD, t))
                .map(|t| t - pd_offset_us),
        );
        events.sort_unstable();
        events.dedup();
    }
    events
}

/// Attitude and environment at every event time.
fn propagate_events(
    scenario: &Scenario,
    ephemeris: &Ephemeris,
    events_us: &[i64],
    initial: AttitudeState,
) -> Result<(Vec<AttitudeState>, Vec<Reference>), SimError> {
    let body = RigidBody::new(scenario.inertia_kg_m2())?;
    let disturbances = Disturbances {
        gravity_gradient: scenario.spacecraft.gravity_gradient,
        dipole_body_a_m2: scenario.dipole_body_a_m2(),
    };
    let references = events_us
        .par_iter()
        .map(|&t_us| ephemeris.at(to_s(t_us)))
        .collect::<Result<Vec<_>, _>>()?;
    // The initial state holds at t = 0 (always a row); earlier events (a positive
    // time-offset) are reached by integrating backwards, so an offset never changes the
    // motion at the rows.
    let k0 = events_us.binary_search(&0).unwrap_or(0);
    let mut states = vec![initial; events_us.len()];
    let step = |from: usize, to: usize, state: &AttitudeState| {
        let dt_s = to_s(events_us[to] - events_us[from]);
        let torque_env = TorqueEnvironment {
            r_gcrf_km: [references[from].r_gcrf_km, references[to].r_gcrf_km],
            b_gcrf_nt: [references[from].b_gcrf_nt, references[to].b_gcrf_nt],
            dt_s,
        };
        let torque = |t: f64, q: &Quat| torque_env.torque(&body, &disturbances, t, q);
        propagate(&body, state, dt_s, scenario.spacecraft.max_step_s, &torque)
    };
    for k in k0 + 1..events_us.len() {
        states[k] = step(k - 1, k, &states[k - 1])?;
    }
    for k in (0..k0).rev() {
        states[k] = step(k + 1, k, &states[k + 1])?;
    }
    Ok((states, references))
}

/// True temperatures at every event, degrees Celsius, `[j * n_pd + i]` for photodiode `i`
/// at event `j`: `dT/dt = (T_eq - T) / tau` stepped exactly with `T_eq` taken as the mean of
/// the step's end values, from `initial_c` at `t = 0`. Events before `t = 0` (a positive
/// time-offset, seconds at most) keep the initial value rather than integrating backwards.
fn thermal_truth(
    thermal: &Thermal,
    photodiodes: &[Photodiode],
    events_us: &[i64],
    states: &[AttitudeState],
    references: &[Reference],
) -> Vec<f64> {
    let n = photodiodes.len();
    let equilibrium = |j: usize, i: usize| {
        let sun_body = states[j].q.attitude_matrix() * references[j].sun_gcrf_unit;
        let lit = photodiodes[i].n_body.dot(&sun_body).max(0.0) * references[j].sun_fraction;
        thermal.equilibrium_c(lit)
    };
    let mut t_c = vec![thermal.initial_c(); events_us.len() * n];
    let k0 = events_us.binary_search(&0).unwrap_or(0);
    for j in k0 + 1..events_us.len() {
        let decay = (-to_s(events_us[j] - events_us[j - 1]) / thermal.tau_s).exp();
        for i in 0..n {
            let t_eq = 0.5 * (equilibrium(j - 1, i) + equilibrium(j, i));
            t_c[j * n + i] = t_eq + (t_c[(j - 1) * n + i] - t_eq) * decay;
        }
    }
    t_c
}

/// Output buffers, filled row by row.
struct Series {
    telemetry: Telemetry,
    truth: TruthSeries,
    sun_gcrf: Vec<Vector3<f64>>,
    mag_gcrf_nt: Vec<Vector3<f64>>,
    pd_noise_free_v: Vec<Vec<Option<f64>>>,
}

impl Series {
    fn with_capacity(rows: usize, n_pd: usize) -> Self {
        Series {
            telemetry: Telemetry {
                t_s: Vec::with_capacity(rows),
                gyro_rad_s: Vectors::with_capacity(rows),
                mag_nt: Some(Vectors::with_capacity(rows)),
                pd_v: vec![Samples::with_capacity(rows); n_pd],
                r_gcrf_km: None,
                temperature_c: Vec::new(),
                current_a: Vec::new(),
            },
            truth: TruthSeries::default(),
            sun_gcrf: Vec::with_capacity(rows),
            mag_gcrf_nt: Vec::with_capacity(rows),
            pd_noise_free_v: vec![Vec::with_capacity(rows); n_pd],
        }
    }
}

/// The sensors' noise streams, settings and the evolving gyro bias.
struct Sensors {
    gyro_noise: ChaCha8Rng,
    gyro_walk: ChaCha8Rng,
    mag_noise: ChaCha8Rng,
    pd_noise: ChaCha8Rng,
    temperature_noise: ChaCha8Rng,
    gyro_bias_rad_s: Vector3<f64>,
    last_gyro_us: Option<i64>,
    /// The scenario's effects, for the sensor corruptions (`gyro-scale`, `mag-bias`).
    effects: Vec<Effect>,
    gyro_sigma_rad_s: f64,
    walk_rad_s_sqrt_s: f64,
    mag_sigma_nt: f64,
    pd_sigma_v: f64,
}

impl Sensors {
    fn new(scenario: &Scenario, seed: Seed) -> Self {
        let mut bias_rng = seed.stream(Stream::GyroBias);
        let mut bias = || random::draw(&scenario.gyro.bias_rad_s, &mut bias_rng);
        let gyro_bias_rad_s = Vector3::new(bias(), bias(), bias());
        Sensors {
            gyro_noise: seed.stream(Stream::GyroNoise),
            gyro_walk: seed.stream(Stream::GyroWalk),
            mag_noise: seed.stream(Stream::MagNoise),
            pd_noise: seed.stream(Stream::PhotodiodeNoise),
            temperature_noise: seed.stream(Stream::TemperatureNoise),
            gyro_bias_rad_s,
            last_gyro_us: None,
            effects: scenario.effects.clone(),
            gyro_sigma_rad_s: scenario.gyro.noise_rad_s,
            walk_rad_s_sqrt_s: scenario.gyro.bias_walk_rad_s_sqrt_s,
            mag_sigma_nt: scenario.magnetometer.noise_nt,
            pd_sigma_v: scenario.photodiodes.noise_v,
        }
    }

    /// A gyro sample at `t_us`: the bias first walks from the previous gyro sample, then
    /// `(1 + e) w + bias + noise`.
    fn gyro(&mut self, t_us: i64, w_body_rad_s: &Vector3<f64>) -> Vector3<f64> {
        if let Some(last) = self.last_gyro_us {
            let dt_s = to_s(t_us - last);
            self.gyro_bias_rad_s +=
                random::normal3(&mut self.gyro_walk) * (self.walk_rad_s_sqrt_s * dt_s.sqrt());
        }
        self.last_gyro_us = Some(t_us);
        let scaled = (self.effects.iter()).fold(*w_body_rad_s, |w, e| e.corrupt_gyro(w));
        scaled
            + self.gyro_bias_rad_s
            + random::normal3(&mut self.gyro_noise) * self.gyro_sigma_rad_s
    }

    /// A magnetometer sample: `T A B_ref + b + sum_j c_j u_j + bias + noise`, `u` every
    /// current channel's value at the row.
    fn magnetometer(
        &mut self,
        mag_body_nt: &Vector3<f64>,
        errors: &TrueMagErrors,
        u: &[f64],
    ) -> Vector3<f64> {
        let field = errors.apply(mag_body_nt, u);
        let biased = (self.effects.iter()).fold(field, |b, e| e.corrupt_mag(b));
        biased + random::normal3(&mut self.mag_noise) * self.mag_sigma_nt
    }

    /// A temperature sample: the true value plus noise, degrees Celsius.
    fn temperature(&mut self, true_c: f64, sigma_c: f64) -> f64 {
        true_c + sigma_c * random::normal(&mut self.temperature_noise)
    }

    /// Photodiode outputs from noise-free pre-stage values: noise, then the output stages
    /// (a real sensor clips after noise). Returns (measured, noise-free) per photodiode.
    fn photodiodes(
        &mut self,
        model: &MeasurementModel,
        clean_v: &[f64],
    ) -> Result<Vec<(f64, f64)>, SimError> {
        clean_v
            .iter()
            .enumerate()
            .map(|(i, &clean)| {
                let noisy = clean + self.pd_sigma_v * random::normal(&mut self.pd_noise);
                Ok((model.apply_stages(i, noisy)?, model.apply_stages(i, clean)?))
            })
            .collect()
    }
}

/// The magnetometer's drawn errors; the identity without `magnetometer.errors`.
struct TrueMagErrors {
    t: Matrix3<f64>,
    bias_nt: Vector3<f64>,
    /// `c_j` per current channel (zero for a channel that does not drive the sensor).
    coeff_nt: Vec<Vector3<f64>>,
}

impl TrueMagErrors {
    /// Draws the errors of `scenario` from the hardware stream: `T = (I + D + S) N`.
    fn draw(scenario: &Scenario, rng: &mut ChaCha8Rng) -> Self {
        let channels = scenario.currents.len();
        let Some(errors) = &scenario.magnetometer.errors else {
            return TrueMagErrors {
                t: Matrix3::identity(),
                bias_nt: Vector3::zeros(),
                coeff_nt: vec![Vector3::zeros(); channels],
            };
        };
        let signed = |spread, rng: &mut ChaCha8Rng| {
            let magnitude = random::draw(spread, rng);
            if random::draw(&Spread::Uniform { min: 0.0, max: 1.0 }, rng) < 0.5 {
                -magnitude
            } else {
                magnitude
            }
        };
        let mut soft = Matrix3::identity();
        for a in 0..3 {
            soft[(a, a)] += signed(&errors.scale, rng);
        }
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            let v = signed(&errors.soft_iron, rng);
            soft[(a, b)] = v;
            soft[(b, a)] = v;
        }
        let mut nonortho = Matrix3::identity();
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            nonortho[(a, b)] = signed(&errors.nonorthogonality_deg, rng).to_radians().sin();
        }
        let bias_nt = Vector3::from_fn(|_, _| signed(&errors.hard_iron_nt, rng));
        let coeff_nt = (scenario.currents.iter())
            .map(|c| {
                let drawn = Vector3::from_fn(|_, _| signed(&errors.current_bias_nt_per_a, rng));
                if c.drives_mag {
                    drawn
                } else {
                    Vector3::zeros()
                }
            })
            .collect();
        TrueMagErrors {
            t: soft * nonortho,
            bias_nt,
            coeff_nt,
        }
    }

    /// `T B + b + sum_j c_j u_j`.
    fn apply(&self, b_nt: &Vector3<f64>, u: &[f64]) -> Vector3<f64> {
        (self.coeff_nt.iter().zip(u)).fold(self.t * b_nt + self.bias_nt, |m, (c, uj)| m + c * *uj)
    }

    /// truth.ron's record, when the scenario has errors.
    fn record(&self, scenario: &Scenario) -> Option<TrueMagnetometer> {
        scenario.magnetometer.errors.as_ref()?;
        Some(TrueMagnetometer {
            matrix: [0, 1, 2].map(|a| [0, 1, 2].map(|b| self.t[(a, b)])),
            bias_nt: [self.bias_nt.x, self.bias_nt.y, self.bias_nt.z],
            current_bias_nt_per_a: (scenario.currents.iter())
                .zip(&self.coeff_nt)
                .filter(|(c, _)| c.drives_mag)
                .map(|(c, v)| (current_column(&c.name), [v.x, v.y, v.z]))
                .collect(),
        })
    }
}

/// dataset.ron of a scenario: its name, epoch, TLE, nominal layout and noise hints.
fn dataset_meta(scenario: &Scenario, epoch_utc: EpochUtc) -> DatasetMeta {
    let ScenarioOrbit::Tle { line1, line2 } = &scenario.orbit;
    DatasetMeta {
        format_version: FORMAT_VERSION,
        name: scenario.name.clone(),
        epoch_utc,
        orbit: OrbitSpec::Tle {
            line1: line1.clone(),
            line2: line2.clone(),
        },
        photodiodes: scenario
            .photodiodes
            .assumed
            .clone()
            .unwrap_or_else(|| scenario.photodiodes.nominal.clone()),
        noise: Some(NoiseHints {
            gyro_rad_s: Some(scenario.gyro.noise_rad_s),
            mag_nt: Some(scenario.magnetometer.noise_nt),
            photodiode_v: Some(scenario.photodiodes.noise_v),
        }),
        inertia_kg_m2: Some(Inertia::from_matrix(&scenario.inertia_kg_m2())),
    }
}

/// The true photodiodes in the measurement model's form, with the hard field of view: the
/// narrower of the scenario's (`fov_half_angle_deg`, the true sensor's, not in dataset.ron)
/// and the photodiode's own `fov_deg` (declared in dataset.ron).
fn model_photodiodes(scenario: &Scenario, true_pds: &[TruePd]) -> Vec<Photodiode> {
    let scenario_fov_rad = scenario.photodiodes.fov_half_angle_deg.map(f64::to_radians);
    true_pds
        .iter()
        .zip(&scenario.photodiodes.nominal)
        .map(|(p, nominal)| {
            let fov_rad = match (scenario_fov_rad, nominal.fov_half_angle_rad()) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
            Photodiode::from_az_el_deg(
                p.scale_v,
                p.azimuth_deg,
                p.elevation_deg,
                scenario.photodiodes.noise_v,
            )
            .with_fov_half_angle_rad(fov_rad)
        })
        .collect()
}

/// Simulates the scenario with the given seed: the same seed gives identical numbers.
///
/// Rows are the union of the sensors' sample grids (`k * period`, whole microseconds, up
/// to `duration_s`); a sensor's cells are `None` at rows it does not sample. The
/// scenario's initial attitude and rate hold at `t_s = 0`.
pub fn simulate(scenario: &Scenario, seed: u64) -> Result<SimOutput, SimError> {
    simulate_downlink(scenario, seed, 0)
}

/// Simulates downlink `downlink` of the spacecraft of `seed`: the same hardware as every
/// other downlink of the seed, with its own initial attitude and rate, turn-on gyro bias and
/// sensor noise (independent data sets of one spacecraft). Downlink 0 is [`simulate`].
pub fn simulate_downlink(
    scenario: &Scenario,
    seed: u64,
    downlink: u64,
) -> Result<SimOutput, SimError> {
    let streams = Seed { seed, downlink };
    scenario.validate()?;
    let epoch_utc =
        EpochUtc::parse(&scenario.epoch_utc).map_err(|e| SimError::Epoch(e.to_string()))?;
    let ephemeris = Ephemeris::new(scenario)?;
    let grid = Grid::new(scenario);
    let pd_offset_us = match scenario.effect(EffectId::TimeOffset) {
        Some(Effect::TimeOffset { seconds }) => to_us(*seconds),
        _ => 0,
    };
    let events_us = event_times(&grid, pd_offset_us);
    let (states, references) = propagate_events(
        scenario,
        &ephemeris,
        &events_us,
        initial_state(scenario, streams),
    )?;
    let event = |t_us: i64| events_us.binary_search(&t_us).unwrap_or(0);

    let true_pds = draw_true_photodiodes(scenario, &mut streams.stream(Stream::TruePhotodiodes));
    let photodiodes = model_photodiodes(scenario, &true_pds);
    let model = truth_model(scenario, photodiodes.clone())?;
    let albedo = match scenario.effect(EffectId::Albedo) {
        Some(Effect::Albedo { map }) => Some(AlbedoModel::from_choice(&map.parse::<MapChoice>()?)?),
        _ => None,
    };
    // `albedo-map`: the Earth's reflectivity is the map's times a factor of latitude.
    let albedo = match (albedo, scenario.effect(EffectId::AlbedoMap)) {
        (Some(model), Some(Effect::AlbedoMap { latitude_gains })) => Some(
            model.with_latitude_factor(|lat| pdcal_effects::albedo_map_factor(latitude_gains, lat)),
        ),
        (albedo, _) => albedo,
    };
    let shadow = if scenario.effect(EffectId::Penumbra).is_some() {
        ShadowMode::Penumbra
    } else {
        ShadowMode::Hard
    };

    let n_pd = scenario.n_photodiodes();
    let thermal = scenario.temperature.as_ref();
    let true_temperature_c = thermal
        .map(|th| thermal_truth(th, &photodiodes, &events_us, &states, &references))
        .unwrap_or_default();
    let truth_scenes = TruthScenes {
        model: &model,
        albedo: albedo.as_ref(),
        states: &states,
        references: &references,
        temperature_c: &true_temperature_c,
    };
    // Noise-free outputs first, in parallel (albedo dominates the run time); each row is a
    // pure function of the truth, so the result does not depend on the thread count.
    let pd_true_events: Vec<usize> = grid
        .rows_us
        .iter()
        .filter(|&&t| grid.samples(PD, t))
        .map(|&t| event(t - pd_offset_us))
        .collect();
    let clean_rows = pd_true_events
        .par_iter()
        .map_init(AlbedoView::default, |view, &j| {
            truth_scenes.pre_stage_outputs(view, j, to_s(events_us[j]))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut clean_rows = clean_rows.into_iter();

    let mut out = Series::with_capacity(grid.rows_us.len(), n_pd);
    let mut temperature_true_c = Vec::new();
    if thermal.is_some() {
        out.telemetry.temperature_c = (1..=n_pd)
            .map(|i| TemperatureColumn {
                name: photodiode_temperature_column(i),
                values: Vec::with_capacity(grid.rows_us.len()),
            })
            .collect();
        temperature_true_c = vec![Vec::with_capacity(grid.rows_us.len()); n_pd];
    }
    out.telemetry.current_a = (scenario.currents.iter())
        .map(|c| CurrentColumn {
            name: current_column(&c.name),
            values: Vec::with_capacity(grid.rows_us.len()),
        })
        .collect();
    let mag_errors = TrueMagErrors::draw(scenario, &mut streams.stream(Stream::MagHardware));
    let mut currents = vec![0.0; scenario.currents.len()];
    let mut sensors = Sensors::new(scenario, streams);
    for &t_us in &grid.rows_us {
        let k = event(t_us);
        let (state, reference) = (&states[k], &references[k]);
        let a = state.q.attitude_matrix();
        let t_s = to_s(t_us);
        out.telemetry.t_s.push(t_s);
        let gyro = grid
            .samples(GYRO, t_us)
            .then(|| sensors.gyro(t_us, &state.w_body_rad_s));
        out.telemetry.gyro_rad_s.push(gyro);
        let mag_body_nt = a * reference.b_gcrf_nt;
        let sun_body = a * reference.sun_gcrf_unit;
        for ((u, channel), column) in (currents.iter_mut())
            .zip(&scenario.currents)
            .zip(&mut out.telemetry.current_a)
        {
            *u = channel.current_a(t_s, &sun_body, reference.sun_fraction);
            column.values.push(Some(*u));
        }
        let mag = grid
            .samples(MAG, t_us)
            .then(|| sensors.magnetometer(&mag_body_nt, &mag_errors, &currents));
        if let Some(column) = out.telemetry.mag_nt.as_mut() {
            column.push(mag);
        }
        let pd = if grid.samples(PD, t_us) {
            sensors.photodiodes(&model, &clean_rows.next().unwrap_or_default())?
        } else {
            Vec::new()
        };
        for i in 0..n_pd {
            out.telemetry.pd_v[i].push(pd.get(i).map(|p| p.0));
            out.pd_noise_free_v[i].push(pd.get(i).map(|p| p.1));
        }
        if let Some(th) = thermal {
            let sampled = grid.samples_temperature(t_us);
            for (i, (column, truth)) in (out.telemetry.temperature_c.iter_mut())
                .zip(&mut temperature_true_c)
                .enumerate()
            {
                let true_c = true_temperature_c[k * n_pd + i];
                truth.push(true_c);
                column
                    .values
                    .push(sampled.then(|| sensors.temperature(true_c, th.noise_c)));
            }
        }

        let q = state.q;
        out.truth.t_s.push(t_s);
        out.truth.q.push(Vector4::new(q.x, q.y, q.z, q.w));
        out.truth.w_body_rad_s.push(state.w_body_rad_s);
        out.truth.gyro_bias_rad_s.push(sensors.gyro_bias_rad_s);
        out.truth.sun_body.push(sun_body);
        out.truth
            .eclipse
            .push(shadow.factor(reference.sun_fraction));
        out.truth.r_gcrf_km.push(reference.r_gcrf_km);
        out.truth.mag_body_nt.push(mag_body_nt);
        out.sun_gcrf.push(reference.sun_gcrf_unit);
        out.mag_gcrf_nt.push(reference.b_gcrf_nt);
    }

    Ok(SimOutput {
        meta: dataset_meta(scenario, epoch_utc),
        telemetry: out.telemetry,
        truth: out.truth,
        constants: TruthConstants {
            photodiodes: true_pds,
            effects: scenario.effects.clone(),
            magnetometer: mag_errors.record(scenario),
        },
        sun_gcrf: out.sun_gcrf,
        mag_gcrf_nt: out.mag_gcrf_nt,
        pd_noise_free_v: out.pd_noise_free_v,
        true_photodiodes: photodiodes,
        temperature_true_c,
        seed,
        downlink,
    })
}

/// What the noise-free photodiode outputs are computed from.
struct TruthScenes<'a> {
    model: &'a MeasurementModel,
    albedo: Option<&'a AlbedoModel>,
    states: &'a [AttitudeState],
    references: &'a [Reference],
    /// [`thermal_truth`], empty without a thermal model.
    temperature_c: &'a [f64],
}

impl TruthScenes<'_> {
    /// Every photodiode's noise-free output before the output stages at event `j`
    /// (time `t_s`), V; `view` is scratch space for the albedo cells.
    fn pre_stage_outputs(
        &self,
        view: &mut AlbedoView,
        j: usize,
        t_s: f64,
    ) -> Result<Vec<f64>, SimError> {
        let reference = &self.references[j];
        let albedo_view = match self.albedo {
            Some(albedo) => {
                albedo
                    .compute_into(
                        view,
                        &reference.r_gcrf_km,
                        &reference.sun_gcrf_km,
                        &reference.gcrf_to_itrf,
                    )
                    .map_err(|source| SimError::Albedo { t_s, source })?;
                Some(&*view)
            }
            None => None,
        };
        let n = self.model.photodiodes().len();
        let temperature_c = self.temperature_c.get(j * n..(j + 1) * n).unwrap_or(&[]);
        let scene = scene_for(&self.states[j], reference, t_s, albedo_view)?
            .with_temperatures(temperature_c);
        (0..n)
            .map(|i| Ok(self.model.pre_stage_output(i, &scene)?))
            .collect()
    }
}

/// The photodiode scene at one instant: attitude, Sun, eclipse fraction, rate, time, albedo.
fn scene_for<'a>(
    state: &AttitudeState,
    reference: &Reference,
    t_s: f64,
    albedo: Option<&'a AlbedoView>,
) -> Result<Scene<'a>, SimError> {
    let a: Matrix3<f64> = state.q.attitude_matrix();
    let scene = Scene::new(a, &reference.sun_gcrf_unit)?
        .with_sun_fraction(reference.sun_fraction)
        .with_sun_distance_factor(pdcal_ephem::sun_distance_factor(
            &reference.r_gcrf_km,
            &reference.sun_gcrf_km,
        ))
        .with_rate(state.w_body_rad_s)
        .with_time(t_s);
    Ok(match albedo {
        Some(view) => scene.with_albedo(view),
        None => scene,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dataset_ron_carries_the_scenarios_inertia_read_back_whole() {
        let scenario = Scenario::builtin("sso-6u").expect("built-in scenario");
        let epoch = EpochUtc::parse(&scenario.epoch_utc).expect("scenario epoch");
        let meta = dataset_meta(&scenario, epoch);
        let text = ron::to_string(&meta).expect("renders");
        let back = pdcal_dataset::meta_from_str(&text).expect("reads back");
        let j = back.inertia_kg_m2.expect("written").matrix();
        assert_eq!(j, scenario.inertia_kg_m2());
    }
}
