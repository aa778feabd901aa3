//! Filter tuning ([`FilterConfig`], RON, every field defaulted) and run modes ([`Mode`]).
//!
//! Defaults are chosen to hold on any conforming dataset without per-data-set tuning; the
//! dataset's noise hints (`dataset.ron` `noise`) replace the sensor sigmas when present, and
//! an explicit config value replaces both.

use pdcal_dataset::NoiseHints;
use pdcal_photodiode::AlbedoPartials;
use serde::{Deserialize, Serialize};

use crate::FilterError;
use crate::calibration::Calibration;
use crate::segments::SegmentConfig;

/// Solar irradiance at 1 AU, W/m^2 (the paper's `E_AM0`, footnote 3).
pub const E_AM0_W_M2: f64 = 1367.0;

/// Photodiode noise when neither config nor dataset gives one, V (paper IV.B).
pub const DEFAULT_PHOTODIODE_SIGMA_V: f64 = 0.015;
/// Magnetometer noise when neither config nor dataset gives one, nT (paper IV.B).
pub const DEFAULT_MAG_SIGMA_NT: f64 = 320.0;
/// Gyro white noise per sample when neither config nor dataset gives one, rad/s
/// (0.05 deg/s, ADIS16405 class, rax2-scenario.md).
pub const DEFAULT_GYRO_SIGMA_RAD_S: f64 = 8.726_646_259_971_648e-4;

/// Longest window, tolerance or hold of the configuration, s (one day): the windows after
/// an acquisition (`bias_fit_window_s`, `about_sun_probe_s`, `relinearise_window_s`) are
/// held and run again row by row, and a gap or gyro hold longer than a day would have the
/// attitude propagated across it; a day is far beyond any of their uses.
pub const MAX_WINDOW_S: f64 = 86_400.0;

/// Most `parameter_sigmas` entries: one per parameter of a model of a thousand photodiodes
/// with ten effects each (they are searched per parameter).
pub const MAX_PARAMETER_SIGMAS: usize = 10_000;

/// Longest `parameter_sigmas` name or unit, characters: parameter names are a few tens of
/// characters (`pd03_dark_offset_V`), and a longer one matches nothing.
pub const MAX_PARAMETER_NAME_CHARS: usize = 80;

/// How the filter runs.
#[derive(Debug, Clone, PartialEq)]
pub enum Mode {
    /// Attitude, gyro bias, scale factors and normals (paper Eq. 17); magnetometer updates
    /// when the telemetry has `mag_*` columns, otherwise [`Mode::PhotodiodeOnly`] behaviour.
    Full,
    /// As [`Mode::Full`] without magnetometer updates even when `mag_*` columns exist; the
    /// attitude is initialised from the Sun vector alone.
    PhotodiodeOnly,
    /// The paper's third data set: normals fixed at a previous calibration, only the scale
    /// factors (and attitude, bias) estimated, scales initialised from the prior.
    ScaleOnly {
        /// The previous calibration (`calibration.ron`).
        prior: Calibration,
    },
}

/// Tuning of the calibration filter. Every field has a default (`FilterConfig::default()`);
/// a RON file names only what it changes and unknown fields are an error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FilterConfig {
    /// Photodiode noise 1-sigma, V; `None`: the dataset hint, else 0.015 V.
    pub photodiode_sigma_v: Option<f64>,
    /// Albedo-model uncertainty of one row, W/m^2 (paper IV.B: 50); enters R as
    /// `(C sigma / E_AM0)^2`, less the part the albedo gain state carries
    /// (`albedo_gain_sigma`): the white part of the albedo's error.
    pub albedo_sigma_w_m2: f64,
    /// Stationary sigma of the albedo gain `g` (the albedo seen is `(1 + g)` times the
    /// modelled one), a state correlated over `albedo_gain_time_s`; 0 leaves the albedo's
    /// error white. Default 0.2: the footprint-weighted reflectivity of the two shipped
    /// families of maps (TOMS mean, CERES 2018 annual) differs along a low orbit by 0.21
    /// in log ratio (docs/validation.md, "Another simulator's albedo"), and a map of any
    /// kind differs from the Earth of one day by that day's clouds.
    pub albedo_gain_sigma: f64,
    /// Correlation time of the albedo gain, s. Default 360: the time the footprint takes
    /// to cross a region of one reflectivity (a cloud system, an ocean, an ice sheet, a
    /// few thousand km at a ground speed of about 7 km/s); the map-to-map ratio above
    /// falls to 1/e in 360 s.
    pub albedo_gain_time_s: f64,
    /// Magnetometer noise 1-sigma per axis, nT; `None`: the dataset hint, else 320 nT.
    pub mag_sigma_nt: Option<f64>,
    /// Gyro white noise per sample, rad/s; `None`: the dataset hint, else 0.05 deg/s.
    pub gyro_sigma_rad_s: Option<f64>,
    /// Factor on the gyro angle-random-walk density for what the piecewise-constant rate
    /// model misses between samples (the paper inflated Q for the tumble). Default 1.5.
    pub gyro_noise_inflation: f64,
    /// Extra attitude process noise per step, as a fraction of the measured rate change
    /// between consecutive gyro samples times the step: `(f |w_k - w_k-1| dt)^2` per axis.
    /// Default 0.3: covers rate curvature within a step on fast tumbles. It does not vanish
    /// for a steady rate: gyro noise alone (`E|dw|^2 = 6 sigma^2`) adds 24 % to the attitude
    /// process noise (`(1.5 sigma)^2 dt^2`). That part is kept as tuning: every variant that
    /// removed it (subtracting `sqrt(2)` or `sqrt(6) sigma` from `|dw|`, with or without a
    /// larger `gyro_noise_inflation`) made the rax2-like attitude worse (docs/validation.md).
    pub rate_change_fraction: f64,
    /// Gyro bias random walk, rad/s per sqrt(s). Default 2e-6 (0.01 deg/s over 2 h).
    pub gyro_bias_walk_rad_s_sqrt_s: f64,
    /// Scale-factor random walk (Eq. 19), fraction of C per sqrt(hour). Default 1e-4: 0.27 %
    /// per sqrt(month), about 1 % per sqrt(year), slow degradation of photodiodes under
    /// coverglass. It walks across the time between data sets too, so it sets how much of
    /// an earlier set's calibration a joint run keeps; hardware that degrades faster says
    /// so with a larger value (docs/cli-contract.md, "Several data sets").
    pub scale_walk_fraction_per_sqrt_h: f64,
    /// Normal random walk (Eq. 19), deg per sqrt(hour) per tangent axis. Default 0.001:
    /// 0.03 deg per sqrt(month). Mountings do not move after launch; the walk only keeps
    /// the covariance from collapsing over days of data.
    pub normal_walk_deg_per_sqrt_h: f64,
    /// Initial gyro-bias sigma per axis, deg/s. Default 5: the turn-on bias of MEMS gyros
    /// reaches several deg/s (4 deg/s is seen in flight on small-satellite MEMS gyros).
    pub initial_bias_sigma_deg_s: f64,
    /// What the gyro bias does between the data sets of a joint run. Default
    /// [`BiasAcrossSets::Restart`]: a MEMS gyro's turn-on bias changes from one power-on to
    /// the next by up to its whole spread, far beyond the bias walk, so each set's bias
    /// starts again from the prior (`initial_bias_sigma_deg_s`) and is found in that set.
    pub gyro_bias_across_sets: BiasAcrossSets,
    /// Fit the gyro bias from the data at each acquisition ([`crate::bias_fit`]): the first
    /// `bias_fit_window_s` of the segment's vectors and gyro, the directions the data
    /// determine fused into the filter. Default true.
    pub bias_from_data: bool,
    /// Length of the bias fit's window from the acquisition row, s. Default 120: the Sun
    /// moves through the body frame at the body's rate, and a slow tumble (0.5 deg/s) needs
    /// a minute or two to sweep the Sun line far enough for the bias along it.
    pub bias_fit_window_s: f64,
    /// Initial scale sigma as a fraction of the initial C. Default 0.15 (pre-flight guesses
    /// were off by 4-13 %, and C = max output carries albedo and noise).
    pub initial_scale_sigma_fraction: f64,
    /// Initial normal sigma per tangent axis, deg. Default 10 (hand-mounted wedges, up to
    /// about 9 deg per angle).
    pub initial_normal_sigma_deg: f64,
    /// Direction sigma of the initial photodiode Sun vector (uncalibrated), deg; weights the
    /// q-method and gives the initial attitude covariance. Default 10 (paper: 9-10 deg change
    /// of the Sun direction by the calibration).
    pub initial_sun_sigma_deg: f64,
    /// Floor on the initial attitude sigma per axis, deg. Default 1.
    pub initial_attitude_sigma_floor_deg: f64,
    /// Initial sigma of the rotation about the Sun line when the attitude comes from the Sun
    /// alone (photodiode-only), deg. Default 90.
    pub unobserved_axis_sigma_deg: f64,
    /// Sun alone (no magnetometer) with albedo modelled: after each acquisition the filter
    /// follows this long, s, both the acquired attitude and its half turn about the Sun line,
    /// and keeps the one the data favour ([`crate::sun_line`]). 0 turns the probe off.
    /// Default 1800 (half an orbit's sunlit arc of a low orbit: long enough for the albedo
    /// pattern to move across the photodiodes).
    pub about_sun_probe_s: f64,
    /// Sun alone: after each acquisition the filter runs this long, s, once as it would,
    /// then again from the acquisition with each row linearised about the first run's end
    /// state carried back to it by the gyro ([`crate::ForwardPass`], the window's
    /// iterated smoother). 0 turns it off. Default 120, the bias fit's window
    /// (`bias_fit_window_s`): the rows from which the acquisition's bias and calibration
    /// are first learnt, tens of degrees from the truth for an uncalibrated head.
    pub relinearise_window_s: f64,
    /// Smallest angle between Sun and field for the two-vector initialisation, deg.
    /// Default 20 (the q-method's cross-axis error grows as 1/sin of that angle).
    pub initial_min_sun_field_angle_deg: f64,
    /// A photodiode update is used only when the predicted incidence angle is below this,
    /// deg. Default 60: the conservative end of the paper's 60-70 deg cosine-law field of
    /// view, leaving margin for the initial normal error (up to 10 deg) so that a sensor whose
    /// response rolls off from 60-70 deg is not fitted where the cosine law fails.
    pub fov_half_angle_deg: f64,
    /// Photodiodes are used only when the illuminated fraction is at least this. Default
    /// 0.999 (no eclipse, no penumbra).
    pub min_sun_fraction: f64,
    /// Innovation gate per scalar update, in sigmas: rejected when `nu^2 > g^2 s`. Default 5
    /// (a Gaussian innovation exceeds it with probability 5.7e-7, so gating rejects only
    /// outliers and model failures).
    pub gate_sigmas: f64,
    /// Screening of every sensor's samples against their neighbours in time, before the
    /// filter (`screen`): a sample outside its neighbours' range by more than this many
    /// sensor sigmas (plus the range's own width) is rejected and counted. Default 8: a
    /// Gaussian sample exceeds it with probability about 1e-10, so only outliers go.
    pub outlier_sigmas: f64,
    /// The largest angular acceleration the screening allows between neighbouring gyro
    /// samples beyond the trend of the neighbours themselves, rad/s^2. Default 0.01
    /// (0.6 deg/s^2): a sustained acceleration shows in the neighbours and needs none of it.
    pub max_angular_acceleration_rad_s2: f64,
    /// A photodiode whose maximum output over the data set stays below this many
    /// photodiode sigmas is never lit (covered, broken) and takes no part. Default 10.
    pub min_lit_output_sigmas: f64,
    /// Albedo partials in H. Default `Included`, unlike the paper (which neglects them after
    /// Eq. 24, and the photodiode crate's default): with them neglected, a photodiode that is
    /// often lit while its albedo share is 2-10 % (a canted sensor of the sso-6u scenario,
    /// seed 6) ended 0.73 deg and 3.8 sigma off; with them included, 0.16 deg and 0.5 sigma,
    /// and the RAX-2-like accuracy is unchanged (8 seeds: worst normal 0.11 deg either way).
    /// `Neglected` reproduces the paper.
    pub albedo_partials: AlbedoPartials,
    /// Average consecutive gyro samples over a step (default true: second-order accurate for
    /// a rate that changes during the step); false holds the sample at the step start.
    pub average_gyro: bool,
    /// Add the variance of the measurement functions' second-order terms under the current
    /// covariance to R (default true): keeps the first updates, made with 10-degree normal
    /// and attitude errors, from trusting the linearisation more than it deserves; it
    /// vanishes as the covariance shrinks.
    pub second_order_noise: bool,
    /// Run the RTS smoother after the forward filter (default true).
    pub smoother: bool,
    /// Initial sigma and random walk of estimated model parameters, by unit or name.
    pub parameter_sigmas: Vec<ParameterSigma>,
    /// Gaps, segments and the lost-attitude test ([`crate::segments`]).
    pub segments: SegmentConfig,
    /// Dynamics-aided propagation ([`crate::rate`]): the body rate as a state integrated by
    /// Euler's equations with the dataset's `inertia_kg_m2`, the gyro a measurement of it.
    /// Default `Auto`.
    pub dynamics: Dynamics,
    /// The unknown torque (everything the dynamics do not model: drag, solar pressure, a
    /// dipole that changes faster than its walk), white noise per body axis, N m /
    /// sqrt(s). Default 1e-6: drag and solar pressure on a CubeSat are 1e-8..1e-7 N m. A
    /// larger torque the model misses shows in the residuals' consistency verdict
    /// (docs/validation.md, "Rigid-body dynamics in the filter"). The uncertain inertia is
    /// estimated, not added here ([`FilterConfig::inertia_sigma_fraction`]).
    pub torque_noise_n_m_sqrt_s: f64,
    /// No longer read: `dynamics: Auto` tests the gyro's samples themselves
    /// ([`crate::propagation`]) instead of comparing their spacing with a step. Accepted so
    /// that configuration files written for the spacing rule still load; `pdcal calibrate`
    /// warns when it is set.
    #[serde(
        skip_serializing_if = "Option::is_none",
        deserialize_with = "number_as_set"
    )]
    pub dynamics_gyro_step_s: Option<f64>,
    /// With dynamics and no gyro, the initial body-rate sigma per axis, deg/s (the rate
    /// starts at zero and the vector measurements find it). Default 10 deg/s.
    pub initial_rate_sigma_deg_s: f64,
    /// With dynamics, the prior sigma per body axis of the residual magnetic dipole the
    /// filter estimates (its torque `m x B` in the reference field), A m^2. Default 1: a
    /// CubeSat's residual dipole is 0.01-0.1 A m^2 and a passive magnet's 0.3-1 A m^2.
    pub dipole_sigma_a_m2: f64,
    /// With dynamics, the random walk of the residual dipole (currents that change), A m^2
    /// per sqrt(s). Default 1e-4 (0.008 A m^2 over 2 h).
    pub dipole_walk_a_m2_sqrt_s: f64,
    /// With dynamics, the fractional sigma of each diagonal moment of the dataset's
    /// inertia: the prior of the correction the filter estimates from the motion
    /// ([`crate::rate`], "Uncertain inertia"). Default 0.1 (a CAD inertia's typical
    /// error); `0` trusts the inertia.
    pub inertia_sigma_fraction: f64,
    /// The multi-start ensemble that widens the reported covariances by what the data do
    /// not decide between ([`crate::ensemble`]). Default `Auto`: on when the Sun is the
    /// only vector (no magnetometer used).
    pub ensemble: EnsembleRuns,
    /// Seed of the ensemble's starts (ChaCha8): the same seed, the same numbers.
    pub ensemble_seed: u64,
    /// Scale every reported sigma by the residuals' spread over the sensor noise where it
    /// exceeds one ([`crate::consistency::Dispersion`]). Default true; false reports the
    /// filter's own covariances (widened by the ensemble when one runs).
    pub widen_by_residual_spread: bool,
}

/// How many extra forward passes, each from a start drawn from the calibration's prior,
/// the run makes to widen its covariances ([`crate::ensemble`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum EnsembleRuns {
    /// [`crate::ensemble::AUTO_RUNS`] when the run uses no magnetometer (the Sun the only
    /// vector: the posterior is not one Gaussian), none otherwise.
    #[default]
    Auto,
    /// None: the covariances are the filter's own.
    Off,
    /// This many, whatever the sensors.
    Runs(usize),
}

/// The gyro bias at the first acquisition of a data set after the first, in a joint run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum BiasAcrossSets {
    /// Back to the prior: zero, `initial_bias_sigma_deg_s` per axis, uncorrelated (a gyro
    /// turned on anew between the sets).
    #[default]
    Restart,
    /// The estimate carries over with its random walk grown over the time between the sets
    /// (a gyro that stayed on, or whose turn-on bias repeats).
    Carry,
}

/// Whether the filter integrates the rigid-body dynamics ([`crate::rate`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Dynamics {
    /// On when the dataset gives the inertia and there is no gyro, or its rate changes
    /// between its samples by more than its noise explains ([`crate::propagation`]).
    #[default]
    Auto,
    /// The gyro-driven MEKF whatever the dataset gives.
    Off,
    /// On; an error when the dataset has no inertia.
    On,
}

/// Initial sigma and random walk of estimated model parameters whose `name` (exact) or
/// `unit` matches; the first match wins, names before units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterSigma {
    /// Parameter name (`pd03_dark_offset_V`) or unit (`V`).
    pub name_or_unit: String,
    /// Initial 1-sigma, in the parameter's unit.
    pub sigma: f64,
    /// Random walk, unit per sqrt(hour).
    #[serde(default)]
    pub walk_per_sqrt_h: f64,
}

impl Default for FilterConfig {
    fn default() -> Self {
        FilterConfig {
            photodiode_sigma_v: None,
            albedo_sigma_w_m2: 50.0,
            albedo_gain_sigma: 0.2,
            albedo_gain_time_s: 360.0,
            mag_sigma_nt: None,
            gyro_sigma_rad_s: None,
            gyro_noise_inflation: 1.5,
            rate_change_fraction: 0.3,
            gyro_bias_walk_rad_s_sqrt_s: 2e-6,
            scale_walk_fraction_per_sqrt_h: 1e-4,
            normal_walk_deg_per_sqrt_h: 0.001,
            initial_bias_sigma_deg_s: 5.0,
            gyro_bias_across_sets: BiasAcrossSets::Restart,
            bias_from_data: true,
            bias_fit_window_s: 120.0,
            initial_scale_sigma_fraction: 0.15,
            initial_normal_sigma_deg: 10.0,
            initial_sun_sigma_deg: 10.0,
            initial_attitude_sigma_floor_deg: 1.0,
            unobserved_axis_sigma_deg: 90.0,
            about_sun_probe_s: 1800.0,
            relinearise_window_s: 120.0,
            initial_min_sun_field_angle_deg: 20.0,
            fov_half_angle_deg: 60.0,
            min_sun_fraction: 0.999,
            gate_sigmas: 5.0,
            outlier_sigmas: 8.0,
            max_angular_acceleration_rad_s2: 0.01,
            min_lit_output_sigmas: 10.0,
            albedo_partials: AlbedoPartials::Included,
            average_gyro: true,
            second_order_noise: true,
            smoother: true,
            parameter_sigmas: default_parameter_sigmas(),
            segments: SegmentConfig::default(),
            dynamics: Dynamics::Auto,
            torque_noise_n_m_sqrt_s: 1e-6,
            dynamics_gyro_step_s: None,
            initial_rate_sigma_deg_s: 10.0,
            dipole_sigma_a_m2: 1.0,
            dipole_walk_a_m2_sqrt_s: 1e-4,
            inertia_sigma_fraction: 0.1,
            ensemble: EnsembleRuns::Auto,
            ensemble_seed: 1,
            widen_by_residual_spread: true,
        }
    }
}

fn default_parameter_sigmas() -> Vec<ParameterSigma> {
    let entry = |unit: &str, sigma: f64| ParameterSigma {
        name_or_unit: unit.to_owned(),
        sigma,
        walk_per_sqrt_h: 0.0,
    };
    // Volts: dark offsets of tens of mV; seconds: time tags off by a fraction of a sample;
    // radians: roll-off angles; 1/h: scale drift of a few percent per hour; 1/K: scale
    // factors changing by up to a percent per kelvin; dimensionless: the albedo gain, whose
    // plausible range (0 to about 2) is one sigma wide.
    vec![
        entry("V", 0.1),
        entry("s", 0.5),
        entry("rad", 0.2),
        entry("1/h", 0.05),
        entry("1/K", 0.01),
        entry("1", 1.0),
    ]
}

impl FilterConfig {
    /// Parses RON text (unknown fields are errors) and validates.
    pub fn from_ron_str(text: &str) -> Result<Self, FilterError> {
        let config: FilterConfig =
            ron::from_str(text).map_err(|e| FilterError::ron_parse("filter config", &e))?;
        config.validate()?;
        Ok(config)
    }

    /// Pretty RON text.
    pub fn to_ron_string(&self) -> Result<String, FilterError> {
        ron::ser::to_string_pretty(self, ron::ser::PrettyConfig::default()).map_err(|e| {
            FilterError::Ron {
                what: "filter config",
                message: e.to_string(),
            }
        })
    }

    /// Checks every field's range: each number finite and in its physical range, each
    /// count, window and name below its bound (a count sets an allocation or a loop), with
    /// the field named.
    pub fn validate(&self) -> Result<(), FilterError> {
        self.check_sensor_sigmas()?;
        self.check_positive()?;
        self.check_non_negative()?;
        let windows = [
            ("bias_fit_window_s", self.bias_fit_window_s),
            ("about_sun_probe_s", self.about_sun_probe_s),
            ("relinearise_window_s", self.relinearise_window_s),
        ];
        for (field, value) in windows {
            if value > MAX_WINDOW_S {
                return Err(bad(field, value, WINDOW_RULE));
            }
        }
        let angles = [
            ("fov_half_angle_deg", self.fov_half_angle_deg),
            (
                "initial_min_sun_field_angle_deg",
                self.initial_min_sun_field_angle_deg,
            ),
        ];
        for (field, value) in angles {
            if !(value > 0.0 && value < 90.0) {
                return Err(bad(field, value, "must be in (0, 90) deg"));
            }
        }
        if !(self.min_sun_fraction > 0.0 && self.min_sun_fraction <= 1.0) {
            return Err(bad(
                "min_sun_fraction",
                self.min_sun_fraction,
                "must be in (0, 1]",
            ));
        }
        self.check_ranges()?;
        self.segments.validate()?;
        self.check_parameter_sigmas()?;
        if let EnsembleRuns::Runs(n) = self.ensemble
            && n > crate::ensemble::MAX_RUNS
        {
            return Err(FilterError::ConfigValue {
                field: "ensemble".into(),
                value: format!("Runs({n})"),
                rule: "Runs(n) must be at most 64 (each run is one more forward pass)".into(),
            });
        }
        Ok(())
    }

    /// The sensor sigmas by the rule dataset.ron's noise hints obey
    /// ([`pdcal_dataset::rules::noise`]): a config cannot pass what the dataset may not.
    fn check_sensor_sigmas(&self) -> Result<(), FilterError> {
        let sigmas = [
            (
                "photodiode_sigma_v",
                "photodiode_V",
                self.photodiode_sigma_v,
            ),
            ("mag_sigma_nt", "mag_nT", self.mag_sigma_nt),
            ("gyro_sigma_rad_s", "gyro_rad_s", self.gyro_sigma_rad_s),
        ];
        for (field, name, value) in sigmas {
            let Some(value) = value else { continue };
            if let Err(rule) = pdcal_dataset::rules::noise(name, value) {
                return Err(FilterError::ConfigValue {
                    field: field.into(),
                    value: pdcal_text::number(value),
                    rule,
                });
            }
        }
        Ok(())
    }

    /// The values beyond which the filter's arithmetic breaks down (a weight of 1e600, a
    /// covariance of 1e600) long before any sensor or spacecraft is reached: each within a
    /// range that holds every real one by decades, the field named. The sensor sigmas' floors
    /// are far below any sensor's quantisation; the sigmas' and walks' ceilings far above a
    /// tumbling CubeSat's worst.
    fn check_ranges(&self) -> Result<(), FilterError> {
        let ranges = [
            (
                "photodiode_sigma_v",
                self.photodiode_sigma_v,
                1e-9,
                f64::INFINITY,
                "V",
            ),
            ("mag_sigma_nt", self.mag_sigma_nt, 1e-6, f64::INFINITY, "nT"),
            (
                "gyro_sigma_rad_s",
                self.gyro_sigma_rad_s,
                1e-12,
                f64::INFINITY,
                "rad/s",
            ),
            (
                "initial_bias_sigma_deg_s",
                Some(self.initial_bias_sigma_deg_s),
                0.0,
                1000.0,
                "deg/s",
            ),
            (
                "initial_rate_sigma_deg_s",
                Some(self.initial_rate_sigma_deg_s),
                0.0,
                1000.0,
                "deg/s",
            ),
            (
                "gyro_bias_walk_rad_s_sqrt_s",
                Some(self.gyro_bias_walk_rad_s_sqrt_s),
                0.0,
                0.1,
                "rad/s per sqrt(s)",
            ),
            (
                "initial_normal_sigma_deg",
                Some(self.initial_normal_sigma_deg),
                0.0,
                180.0,
                "deg",
            ),
            (
                "initial_sun_sigma_deg",
                Some(self.initial_sun_sigma_deg),
                0.0,
                180.0,
                "deg",
            ),
            (
                "initial_attitude_sigma_floor_deg",
                Some(self.initial_attitude_sigma_floor_deg),
                0.0,
                180.0,
                "deg",
            ),
            (
                "unobserved_axis_sigma_deg",
                Some(self.unobserved_axis_sigma_deg),
                0.0,
                180.0,
                "deg",
            ),
            (
                "normal_walk_deg_per_sqrt_h",
                Some(self.normal_walk_deg_per_sqrt_h),
                0.0,
                180.0,
                "deg per sqrt(h)",
            ),
            (
                "scale_walk_fraction_per_sqrt_h",
                Some(self.scale_walk_fraction_per_sqrt_h),
                0.0,
                10.0,
                "per sqrt(h)",
            ),
            (
                "initial_scale_sigma_fraction",
                Some(self.initial_scale_sigma_fraction),
                0.0,
                10.0,
                "of the scale",
            ),
            (
                "albedo_sigma_w_m2",
                Some(self.albedo_sigma_w_m2),
                0.0,
                1.0e4,
                "W/m^2",
            ),
            (
                "albedo_gain_sigma",
                Some(self.albedo_gain_sigma),
                0.0,
                100.0,
                "",
            ),
        ];
        for (field, value, low, high, unit) in ranges {
            let Some(value) = value else { continue };
            if value < low || value > high {
                let rule = if high.is_finite() {
                    format!("must be at most {high:e} {unit}")
                } else {
                    format!("must be at least {low:e} {unit}")
                };
                return Err(FilterError::ConfigValue {
                    field: field.into(),
                    value: pdcal_text::number(value),
                    rule: rule.trim_end().to_owned(),
                });
            }
        }
        Ok(())
    }

    fn check_positive(&self) -> Result<(), FilterError> {
        let positive = [
            ("gyro_noise_inflation", self.gyro_noise_inflation),
            ("initial_bias_sigma_deg_s", self.initial_bias_sigma_deg_s),
            ("bias_fit_window_s", self.bias_fit_window_s),
            (
                "initial_scale_sigma_fraction",
                self.initial_scale_sigma_fraction,
            ),
            ("initial_normal_sigma_deg", self.initial_normal_sigma_deg),
            ("initial_sun_sigma_deg", self.initial_sun_sigma_deg),
            (
                "initial_attitude_sigma_floor_deg",
                self.initial_attitude_sigma_floor_deg,
            ),
            ("unobserved_axis_sigma_deg", self.unobserved_axis_sigma_deg),
            ("gate_sigmas", self.gate_sigmas),
            ("outlier_sigmas", self.outlier_sigmas),
            (
                "max_angular_acceleration_rad_s2",
                self.max_angular_acceleration_rad_s2,
            ),
            ("torque_noise_n_m_sqrt_s", self.torque_noise_n_m_sqrt_s),
            ("initial_rate_sigma_deg_s", self.initial_rate_sigma_deg_s),
            ("dipole_sigma_a_m2", self.dipole_sigma_a_m2),
            ("albedo_gain_time_s", self.albedo_gain_time_s),
        ];
        for (field, value) in positive {
            if !(value > 0.0 && value.is_finite()) {
                return Err(bad(field, value, "must be positive and finite"));
            }
        }
        Ok(())
    }

    fn check_non_negative(&self) -> Result<(), FilterError> {
        let non_negative = [
            ("albedo_sigma_w_m2", self.albedo_sigma_w_m2),
            ("albedo_gain_sigma", self.albedo_gain_sigma),
            ("dipole_walk_a_m2_sqrt_s", self.dipole_walk_a_m2_sqrt_s),
            ("inertia_sigma_fraction", self.inertia_sigma_fraction),
            ("rate_change_fraction", self.rate_change_fraction),
            (
                "gyro_bias_walk_rad_s_sqrt_s",
                self.gyro_bias_walk_rad_s_sqrt_s,
            ),
            (
                "scale_walk_fraction_per_sqrt_h",
                self.scale_walk_fraction_per_sqrt_h,
            ),
            (
                "normal_walk_deg_per_sqrt_h",
                self.normal_walk_deg_per_sqrt_h,
            ),
            ("min_lit_output_sigmas", self.min_lit_output_sigmas),
            ("about_sun_probe_s", self.about_sun_probe_s),
            ("relinearise_window_s", self.relinearise_window_s),
        ];
        for (field, value) in non_negative {
            if !(value >= 0.0 && value.is_finite()) {
                return Err(bad(field, value, "must be non-negative and finite"));
            }
        }
        Ok(())
    }

    /// Each entry's sigma and walk in range, its name short enough to be a parameter's,
    /// and no more entries than [`MAX_PARAMETER_SIGMAS`].
    fn check_parameter_sigmas(&self) -> Result<(), FilterError> {
        let n = self.parameter_sigmas.len();
        if n > MAX_PARAMETER_SIGMAS {
            return Err(FilterError::ConfigValue {
                field: "parameter_sigmas".into(),
                value: format!("{n} entries"),
                rule: format!("at most {MAX_PARAMETER_SIGMAS} entries"),
            });
        }
        for (i, p) in self.parameter_sigmas.iter().enumerate() {
            let entry = |field: &str, value: String, rule: &str| FilterError::ConfigValue {
                field: format!("parameter_sigmas[{i}].{field}"),
                value,
                rule: rule.into(),
            };
            if p.name_or_unit.chars().count() > MAX_PARAMETER_NAME_CHARS {
                return Err(entry(
                    "name_or_unit",
                    pdcal_text::quote(&p.name_or_unit),
                    "a parameter's name or unit is at most 80 characters",
                ));
            }
            if !(p.sigma > 0.0 && p.sigma.is_finite()) {
                let value = pdcal_text::number(p.sigma);
                return Err(entry("sigma", value, "must be positive and finite"));
            }
            if !(p.walk_per_sqrt_h >= 0.0 && p.walk_per_sqrt_h.is_finite()) {
                let value = pdcal_text::number(p.walk_per_sqrt_h);
                return Err(entry(
                    "walk_per_sqrt_h",
                    value,
                    "must be non-negative and finite",
                ));
            }
        }
        Ok(())
    }

    /// The sensor sigmas: config value, else dataset hint, else the default.
    pub fn resolve(&self, hints: Option<&NoiseHints>) -> SensorSigmas {
        let hints = hints.copied().unwrap_or_default();
        SensorSigmas {
            photodiode_v: self
                .photodiode_sigma_v
                .or(hints.photodiode_v)
                .unwrap_or(DEFAULT_PHOTODIODE_SIGMA_V),
            mag_nt: self
                .mag_sigma_nt
                .or(hints.mag_nt)
                .unwrap_or(DEFAULT_MAG_SIGMA_NT),
            gyro_rad_s: self
                .gyro_sigma_rad_s
                .or(hints.gyro_rad_s)
                .unwrap_or(DEFAULT_GYRO_SIGMA_RAD_S),
        }
    }

    /// Initial sigma and random walk (per sqrt(s)) of an estimated parameter.
    pub fn parameter_sigma(&self, name: &str, unit: &str) -> (f64, f64) {
        let found = self
            .parameter_sigmas
            .iter()
            .find(|p| p.name_or_unit == name)
            .or_else(|| {
                self.parameter_sigmas
                    .iter()
                    .find(|p| p.name_or_unit == unit)
            });
        // An unknown unit gets a unit sigma: wide, and the user can name it.
        found.map_or((1.0, 0.0), |p| (p.sigma, p.walk_per_sqrt_h / 60.0))
    }
}

/// The rule of the windows, tolerances and holds ([`MAX_WINDOW_S`]).
pub(crate) const WINDOW_RULE: &str = "must be at most 86400 s (one day)";

fn bad(field: &'static str, value: f64, rule: &'static str) -> FilterError {
    FilterError::Config { field, value, rule }
}

/// Sensor noise sigmas after config, hints and defaults.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorSigmas {
    /// Photodiode, V.
    pub photodiode_v: f64,
    /// Magnetometer per axis, nT.
    pub mag_nt: f64,
    /// Gyro white noise per sample, rad/s.
    pub gyro_rad_s: f64,
}

/// A number field that is only there or not: written as the number, as before it became
/// optional.
fn number_as_set<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    <f64 as Deserialize>::deserialize(d).map(Some)
}
