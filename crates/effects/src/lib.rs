//! The one typed catalogue of the effects pdcal simulates, models and diagnoses.
//!
//! Every effect beyond the direct Sun (paper Eq. 11) is one [`EffectId`] and one value of
//! [`Effect`], with SI units inside (radians, volts, seconds; the magnetic field in nT as
//! everywhere in pdcal). The fixed string ids of `docs/cli-contract.md` (`albedo`,
//! `fov-rolloff`, ...) exist only at the edges: [`EffectId::as_str`] / [`std::str::FromStr`]
//! for the command line and JSON, and the RON spelling of truth.ron and scenarios
//! ([`record`], degrees and %/K as the files have always had them).
//!
//! What the catalogue gives every consumer, so that no crate maps an effect again:
//! - the id, its description and the sensor it acts on ([`EffectId::sensor`]);
//! - the physical checks of its values ([`Effect::check`]), for scenarios and truth.ron;
//! - how two applications of one effect compose ([`Effect::compose`]);
//! - the telemetry corruption the simulator applies and the correction the diagnosis applies
//!   for the sensor effects (`mag-bias`, `gyro-scale`: [`Effect::corrupt_gyro`],
//!   [`Effect::correct_gyro`], [`Effect::corrupt_mag`], [`Effect::correct_mag`]).
//!
//! The photodiode model components come from the same values in `pdcal-photodiode`
//! (`components::add_effect`), the diagnosis candidates (signature, fit, parameter count) in
//! `pdcal-diagnose` (`candidates`), both as one exhaustive `match` over [`EffectId`]: adding
//! an effect is a variant here, and the compiler then names every place that must say what
//! the effect does (see `docs/ARCHITECTURE.md`, "Adding an effect").
//!
//! Why hand-written: a closed list of physical effects with their units is domain data; no
//! crate has it.

use std::fmt;
use std::str::FromStr;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

pub mod record;

/// The sensor an effect acts on (what residual its signature lives in).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Sensor {
    /// The photodiode outputs.
    Photodiode,
    /// The magnetometer.
    Magnetometer,
    /// The gyro.
    Gyro,
}

/// The fixed identifier of one effect (`docs/cli-contract.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum EffectId {
    /// `albedo`: Earth-reflected sunlight reaching the photodiodes (paper Eq. 13).
    Albedo,
    /// `fov-rolloff`: response below the cosine law at high incidence.
    FovRolloff,
    /// `dark-offset`: constant additive output per photodiode.
    DarkOffset,
    /// `saturation`: output clipped at a maximum.
    Saturation,
    /// `penumbra`: partial sunlight entering and leaving Earth's shadow.
    Penumbra,
    /// `time-offset`: photodiode samples time-tagged late or early.
    TimeOffset,
    /// `scale-drift`: scale factors changing linearly during the data set.
    ScaleDrift,
    /// `mag-bias`: constant magnetometer bias.
    MagBias,
    /// `gyro-scale`: gyro scale-factor error.
    GyroScale,
    /// `albedo-gain`: the albedo term scaled (1 as modelled, 0 absent, above 1 a brighter
    /// Earth than the map).
    AlbedoGain,
    /// `temperature`: scale factors depending on the photodiode's temperature.
    Temperature,
    /// `albedo-map`: the reflectivity map corrected by a factor varying with latitude.
    AlbedoMap,
}

impl EffectId {
    /// Every effect, in the contract's order (the original nine, then the later ones).
    pub const ALL: [EffectId; 12] = [
        EffectId::Albedo,
        EffectId::FovRolloff,
        EffectId::DarkOffset,
        EffectId::Saturation,
        EffectId::Penumbra,
        EffectId::TimeOffset,
        EffectId::ScaleDrift,
        EffectId::MagBias,
        EffectId::GyroScale,
        EffectId::AlbedoGain,
        EffectId::Temperature,
        EffectId::AlbedoMap,
    ];

    /// The fixed string id (`fov-rolloff`, ...).
    pub const fn as_str(self) -> &'static str {
        match self {
            EffectId::Albedo => "albedo",
            EffectId::FovRolloff => "fov-rolloff",
            EffectId::DarkOffset => "dark-offset",
            EffectId::Saturation => "saturation",
            EffectId::Penumbra => "penumbra",
            EffectId::TimeOffset => "time-offset",
            EffectId::ScaleDrift => "scale-drift",
            EffectId::MagBias => "mag-bias",
            EffectId::GyroScale => "gyro-scale",
            EffectId::AlbedoGain => "albedo-gain",
            EffectId::Temperature => "temperature",
            EffectId::AlbedoMap => "albedo-map",
        }
    }

    /// One line for reports and `--help`.
    pub const fn description(self) -> &'static str {
        match self {
            EffectId::Albedo => "Earth-reflected sunlight reaching the photodiodes",
            EffectId::FovRolloff => "response falls below the cosine law at high incidence angles",
            EffectId::DarkOffset => {
                "constant additive output (dark current, ADC offset), per photodiode"
            }
            EffectId::Saturation => "output clipped at a maximum",
            EffectId::Penumbra => "partial sunlight while entering and leaving Earth's shadow",
            EffectId::TimeOffset => {
                "photodiode samples time-tagged late or early relative to gyro and magnetometer"
            }
            EffectId::ScaleDrift => {
                "scale factor changing during the data set (temperature, degradation)"
            }
            EffectId::MagBias => "residual constant magnetometer bias",
            EffectId::GyroScale => "gyro scale-factor error",
            EffectId::AlbedoGain => {
                "the albedo term rescaled: 1 as modelled, 0 absent (a model term the data lack)"
            }
            EffectId::Temperature => "scale factors depending on temperature, per photodiode",
            EffectId::AlbedoMap => {
                "the albedo map's pattern off: the reflectivity scaled by a smooth factor of latitude"
            }
        }
    }

    /// The sensor whose residuals carry the effect.
    pub const fn sensor(self) -> Sensor {
        match self {
            EffectId::MagBias => Sensor::Magnetometer,
            EffectId::GyroScale => Sensor::Gyro,
            _ => Sensor::Photodiode,
        }
    }
}

impl fmt::Display for EffectId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A string that is not an effect id of the catalogue.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnknownEffect(pub String);

impl fmt::Display for UnknownEffect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let known: Vec<&str> = EffectId::ALL.iter().map(|e| e.as_str()).collect();
        write!(
            f,
            "unknown effect {} (known: {})",
            pdcal_text::quote(&self.0),
            known.join(", ")
        )
    }
}

impl std::error::Error for UnknownEffect {}

impl FromStr for EffectId {
    type Err = UnknownEffect;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        EffectId::ALL
            .into_iter()
            .find(|e| e.as_str() == s)
            .ok_or_else(|| UnknownEffect(s.to_owned()))
    }
}

impl Serialize for EffectId {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

impl<'de> Deserialize<'de> for EffectId {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

/// One effect with its values, SI units inside. Lists marked "per photodiode" hold one entry
/// per photodiode in `pdNN` order.
///
/// Serialised (RON and JSON) through [`record::EffectRecord`], the files' spelling.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(from = "record::EffectRecord", into = "record::EffectRecord")]
pub enum Effect {
    /// `albedo`: paper Eq. (13) on a named reflectivity map.
    Albedo {
        /// Map identifier as the albedo crate names it (`toms-mean-1p25x1`).
        map: String,
    },
    /// `fov-rolloff`: the cosine law times 1 up to `start_rad`, 0 from `cutoff_rad`, and the
    /// raised-cosine taper `0.5 (1 + cos(pi (theta - start) / (cutoff - start)))` between.
    FovRolloff {
        /// Incidence angle where the roll-off starts, rad.
        start_rad: f64,
        /// Incidence angle where the output reaches zero, rad.
        cutoff_rad: f64,
    },
    /// `fov-rolloff` in the Kelly form of the coarse-sun-sensor models of other simulators
    /// (Basilisk's `kellyFactor`, with the exponent free): the cosine law `c` times
    /// `K(c) = 1 - exp(-c^exponent / kappa)`, `c` the cosine of incidence. Basilisk's form
    /// is `exponent = 2`; `kappa = 0.1` loses 0.7 % at 45 deg, 8 % at 60 and 31 % at 70.
    KellyRolloff {
        /// `kappa > 0`: the larger, the earlier the response falls.
        kappa: f64,
        /// `k > 0`, the power of the cosine in the exponent.
        exponent: f64,
    },
    /// `dark-offset`: a constant added to each output, present in eclipse too.
    DarkOffset {
        /// Offset per photodiode, V.
        volts: Vec<f64>,
    },
    /// `saturation`: `min(output, volts)` after noise (one shared ADC full scale).
    Saturation {
        /// Largest output, V.
        volts: f64,
    },
    /// `saturation` with one clip level per photodiode (each channel's own amplifier or ADC
    /// range, e.g. a fixed fraction of its scale factor): `min(output_i, volts_i)`.
    SaturationPerPhotodiode {
        /// Largest output per photodiode, V.
        volts: Vec<f64>,
    },
    /// `penumbra`: the direct Sun scaled by the illuminated fraction of the solar disc.
    Penumbra,
    /// `time-offset`: a photodiode row tagged `t` was sampled at `t - seconds`.
    TimeOffset {
        /// Tag minus true sampling time, s.
        seconds: f64,
    },
    /// `scale-drift`: `C_i(t) = C_i (1 + fraction_per_hour_i t_s / 3600)`. Per hour, not per
    /// second: the filter estimates it as a state of order 1e-2, which keeps the covariance
    /// well scaled; the unit is in the name.
    ScaleDrift {
        /// Relative scale change per hour, per photodiode.
        fraction_per_hour: Vec<f64>,
    },
    /// `mag-bias`: added to each magnetometer sample, body frame.
    MagBias {
        /// Bias, nT, body x/y/z.
        bias_nt: [f64; 3],
    },
    /// `gyro-scale`: `measured = (1 + e) true + bias + noise` per body axis.
    GyroScale {
        /// Dimensionless error per axis (0.01 is 1 %).
        scale_error: [f64; 3],
    },
    /// `albedo-gain`: the albedo term multiplied by `gain`.
    AlbedoGain {
        /// 1 as modelled, 0 no albedo in the data.
        gain: f64,
    },
    /// `temperature`: `C_i(T) = C_i (1 + k_i (T_i - reference_c))`, `T_i` the photodiode's
    /// temperature column (`temp_*_C`); `C_i` is then the scale factor at `reference_c`.
    Temperature {
        /// `k_i`, relative scale change per kelvin, per photodiode (0.001 is 0.1 %/K).
        coefficient_per_k: Vec<f64>,
        /// Temperature at which the scale factor is `C_i`, degrees Celsius.
        reference_c: f64,
    },
    /// `albedo-map`: every cell's reflectivity times `f(latitude)`, `f` piecewise linear
    /// between `latitude_gains[j]` at the centres `-90 + 180 (j + 1/2) / n` deg of `n` equal
    /// latitude bands (6 gains: -75, -45, -15, 15, 45, 75 deg), constant beyond the outer
    /// centres. All gains 1 is the map as it is; a constant field is `albedo-gain`.
    AlbedoMap {
        /// Factor at each band centre, south to north.
        latitude_gains: Vec<f64>,
    },
}

/// The factor of an `albedo-map` correction with `latitude_gains` at latitude `lat_rad`:
/// linear between the band centres `-90 + 180 (j + 1/2) / n` deg, constant beyond the outer
/// ones, never below 0; 1 without gains.
pub fn albedo_map_factor(latitude_gains: &[f64], lat_rad: f64) -> f64 {
    match latitude_gains {
        [] => 1.0,
        [g] => g.max(0.0),
        gains => {
            let n = gains.len();
            // Position in units of bands, 0 at the first centre.
            let x =
                ((lat_rad.to_degrees() + 90.0) / 180.0 * n as f64 - 0.5).clamp(0.0, (n - 1) as f64);
            let j = (x.floor() as usize).min(n - 2);
            let w = x - j as f64;
            (gains[j] * (1.0 - w) + gains[j + 1] * w).max(0.0)
        }
    }
}

/// The latitude band, of `n` equal bands from the south pole, holding `lat_rad`: the
/// `albedo-map` gain it is fitted to.
pub fn albedo_map_band(n: usize, lat_rad: f64) -> usize {
    let x = (lat_rad.to_degrees() + 90.0) / 180.0 * n as f64;
    (x.max(0.0) as usize).min(n.saturating_sub(1))
}

/// Default reference temperature of the `temperature` effect, degrees Celsius.
pub const REFERENCE_TEMPERATURE_C: f64 = 20.0;

/// The physical range of one fitted value of an effect, in the files' field and unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhysicalRange {
    /// The effect.
    pub id: EffectId,
    /// Its field, the files' spelling without an index (`fraction_per_hour`).
    pub field: &'static str,
    /// Smallest physical value.
    pub min: f64,
    /// Largest physical value.
    pub max: f64,
    /// The range and the hardware behind it, for a message.
    pub why: &'static str,
}

/// The physical range of every fitted value of the catalogue (the roll-offs' shapes are
/// fitted on grids inside their validity, [`Effect::check`]). Wide enough for any
/// spacecraft's hardware and a fit's noise at a bound, so that a value outside is a wrong
/// model or wrong data, never an unusual sensor.
pub const PHYSICAL_RANGES: [PhysicalRange; 10] = [
    PhysicalRange {
        id: EffectId::DarkOffset,
        field: "volts",
        min: -1.0,
        max: 1.0,
        why: "a dark offset is within 1 V in size (a dark current through the load gives \
              millivolts)",
    },
    PhysicalRange {
        id: EffectId::Saturation,
        field: "volts",
        min: 0.0,
        max: 100.0,
        why: "a saturation level is within 0 ..= 100 V (the largest scale factor)",
    },
    PhysicalRange {
        id: EffectId::TimeOffset,
        field: "seconds",
        min: -60.0,
        max: 60.0,
        why: "a time offset is within 60 s in size (a clock or a tagging slip of a sample or \
              two)",
    },
    PhysicalRange {
        id: EffectId::ScaleDrift,
        field: "fraction_per_hour",
        min: -0.1,
        max: 0.1,
        why: "a scale drift is within 10 %/h in size (coverglass darkening is about 1 % a \
              year; beyond 10 %/h a photodiode would lose its output within hours)",
    },
    PhysicalRange {
        id: EffectId::MagBias,
        field: "nT",
        min: -1e5,
        max: 1e5,
        why: "a magnetometer bias is within 1e5 nT in size (twice the geomagnetic field)",
    },
    PhysicalRange {
        id: EffectId::GyroScale,
        field: "scale_error",
        min: -0.2,
        max: 0.2,
        why: "a gyro scale error is within 20 % in size (MEMS gyros: a few percent)",
    },
    PhysicalRange {
        id: EffectId::AlbedoGain,
        field: "gain",
        min: -0.2,
        max: 3.0,
        why: "an albedo gain is within 0 ..= 3 (no reflectivity map is off by more than a \
              factor of 3 over an orbit; down to -0.2 is 0 within a fit's noise)",
    },
    PhysicalRange {
        id: EffectId::AlbedoMap,
        field: "latitude_gains",
        min: -0.2,
        max: 3.0,
        why: "an albedo map's latitude gain is within 0 ..= 3 (down to -0.2 is 0 within a \
              fit's noise)",
    },
    PhysicalRange {
        id: EffectId::Temperature,
        field: "percent_per_K",
        min: -2.0,
        max: 2.0,
        why: "a scale factor's temperature coefficient is within 2 %/K in size (silicon: \
              about 0.1 %/K)",
    },
    PhysicalRange {
        id: EffectId::Temperature,
        field: "reference_C",
        min: -150.0,
        max: 150.0,
        why: "a reference temperature is within -150 ..= 150 C",
    },
];

/// A value of an effect outside its physical range.
#[derive(Debug, Clone, PartialEq)]
pub struct Invalid {
    /// Field path inside the effect, in the files' spelling (`cutoff_deg`, `volts[3]`).
    pub field: String,
    /// The offending value.
    pub value: f64,
    /// The rule it breaks.
    pub rule: String,
}

impl fmt::Display for Invalid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let value = pdcal_text::number(self.value);
        write!(f, "{} = {value}: {}", self.field, self.rule)
    }
}

impl Effect {
    /// Its id.
    pub fn id(&self) -> EffectId {
        match self {
            Effect::Albedo { .. } => EffectId::Albedo,
            Effect::FovRolloff { .. } | Effect::KellyRolloff { .. } => EffectId::FovRolloff,
            Effect::DarkOffset { .. } => EffectId::DarkOffset,
            Effect::Saturation { .. } | Effect::SaturationPerPhotodiode { .. } => {
                EffectId::Saturation
            }
            Effect::Penumbra => EffectId::Penumbra,
            Effect::TimeOffset { .. } => EffectId::TimeOffset,
            Effect::ScaleDrift { .. } => EffectId::ScaleDrift,
            Effect::MagBias { .. } => EffectId::MagBias,
            Effect::GyroScale { .. } => EffectId::GyroScale,
            Effect::AlbedoGain { .. } => EffectId::AlbedoGain,
            Effect::Temperature { .. } => EffectId::Temperature,
            Effect::AlbedoMap { .. } => EffectId::AlbedoMap,
        }
    }

    /// The per-photodiode list, if the effect has one: its field name and values.
    pub fn per_photodiode(&self) -> Option<(&'static str, &[f64])> {
        match self {
            Effect::DarkOffset { volts } | Effect::SaturationPerPhotodiode { volts } => {
                Some(("volts", volts))
            }
            Effect::ScaleDrift { fraction_per_hour } => {
                Some(("fraction_per_hour", fraction_per_hour))
            }
            Effect::Temperature {
                coefficient_per_k, ..
            } => Some(("percent_per_K", coefficient_per_k)),
            _ => None,
        }
    }

    /// The physical range of the effect's fitted values ([`PHYSICAL_RANGES`]): what a
    /// spacecraft's hardware can do, with room for a fit's noise at a bound (an albedo gain
    /// of -0.001 is 0). A value a fit
    /// finds outside it is no explanation of the data (a scale drift of -120 %/h would
    /// take every photodiode's output to zero within the pass) but a sign that the base
    /// model or the data are wrong. Field names and units are the files' ([`record`]).
    pub fn check_physical(&self) -> Result<(), Invalid> {
        let id = self.id();
        let rec = record::EffectRecord::from(self.clone());
        for (field, value) in rec.numbers() {
            let name = field.split('[').next().unwrap_or(&field);
            let range = PHYSICAL_RANGES
                .iter()
                .find(|r| r.id == id && r.field == name);
            if let Some(r) = range
                && !(r.min..=r.max).contains(&value)
            {
                return Err(invalid(&field, value, r.why));
            }
        }
        Ok(())
    }

    /// Checks the values against their physical range for a spacecraft with `n_pd`
    /// photodiodes. Field names are the files' ([`record`]).
    pub fn check(&self, n_pd: usize) -> Result<(), Invalid> {
        let rec = record::EffectRecord::from(self.clone());
        for (field, value) in rec.numbers() {
            if !value.is_finite() {
                return Err(invalid(&field, value, "must be finite"));
            }
        }
        if let Some((field, values)) = self.per_photodiode()
            && values.len() != n_pd
        {
            return Err(invalid(
                field,
                values.len() as f64,
                &format!("needs one value per photodiode ({n_pd})"),
            ));
        }
        self.check_range()
    }

    fn check_range(&self) -> Result<(), Invalid> {
        match self {
            Effect::FovRolloff {
                start_rad,
                cutoff_rad,
            } => {
                let (start, cutoff) = (start_rad.to_degrees(), cutoff_rad.to_degrees());
                if !(0.0 <= start && start < cutoff && cutoff <= 90.0 + 1e-9) {
                    return Err(invalid(
                        "cutoff_deg",
                        cutoff,
                        "need 0 <= start_deg < cutoff_deg <= 90",
                    ));
                }
            }
            Effect::Saturation { volts } if *volts <= 0.0 => {
                return Err(invalid("volts", *volts, "must be positive"));
            }
            Effect::SaturationPerPhotodiode { volts } => {
                if let Some((i, v)) = volts.iter().enumerate().find(|(_, v)| **v <= 0.0) {
                    return Err(invalid(&format!("volts[{i}]"), *v, "must be positive"));
                }
            }
            Effect::KellyRolloff { kappa, exponent } => {
                if !(*kappa > 0.0 && *kappa <= 100.0) {
                    return Err(invalid("kappa", *kappa, "must be in 0 <.. 100"));
                }
                if !(*exponent > 0.0 && *exponent <= 20.0) {
                    return Err(invalid("exponent", *exponent, "must be in 0 <.. 20"));
                }
            }
            Effect::TimeOffset { seconds } if seconds.abs() > 60.0 => {
                return Err(invalid("seconds", *seconds, "must be at most 60 in size"));
            }
            Effect::GyroScale { scale_error } => {
                if let Some(e) = scale_error.iter().find(|e| e.abs() >= 0.5) {
                    return Err(invalid("scale_error", *e, "must be below 0.5 in size"));
                }
            }
            Effect::AlbedoGain { gain } if !(0.0..=5.0).contains(gain) => {
                return Err(invalid("gain", *gain, "must be in 0 ..= 5"));
            }
            Effect::AlbedoMap { latitude_gains } => {
                if latitude_gains.len() < 2 {
                    return Err(invalid(
                        "latitude_gains",
                        latitude_gains.len() as f64,
                        "needs at least 2 gains (the poles)",
                    ));
                }
                if let Some((i, g)) = latitude_gains
                    .iter()
                    .enumerate()
                    .find(|(_, g)| !(0.0..=5.0).contains(*g))
                {
                    return Err(invalid(
                        &format!("latitude_gains[{i}]"),
                        *g,
                        "must be in 0 ..= 5",
                    ));
                }
            }
            Effect::Temperature {
                coefficient_per_k,
                reference_c,
            } => {
                if let Some(k) = coefficient_per_k.iter().find(|k| k.abs() > 0.05) {
                    return Err(invalid(
                        "percent_per_K",
                        100.0 * k,
                        "must be at most 5 %/K in size",
                    ));
                }
                if !(-150.0..=150.0).contains(reference_c) {
                    return Err(invalid(
                        "reference_C",
                        *reference_c,
                        "must be in -150 ..= 150",
                    ));
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// Folds `increment`, the same effect fitted again on the residuals of a model that
    /// already holds `self`, into `self`: the one effect equal to applying both. False (and
    /// `self` unchanged) for effects without such fitted constants or a different id.
    pub fn compose(&mut self, increment: &Effect) -> bool {
        match (self, increment) {
            (Effect::DarkOffset { volts }, Effect::DarkOffset { volts: more }) => {
                volts.iter_mut().zip(more).for_each(|(v, d)| *v += d);
                true
            }
            (Effect::MagBias { bias_nt }, Effect::MagBias { bias_nt: more }) => {
                bias_nt.iter_mut().zip(more).for_each(|(v, d)| *v += d);
                true
            }
            // Telemetry divided by (1 + e1), then by (1 + e2).
            (Effect::GyroScale { scale_error }, Effect::GyroScale { scale_error: more }) => {
                scale_error
                    .iter_mut()
                    .zip(more)
                    .for_each(|(e, d)| *e = (1.0 + *e) * (1.0 + d) - 1.0);
                true
            }
            // The increment is fitted on the unscaled albedo regressor, so gains add.
            (Effect::AlbedoGain { gain }, Effect::AlbedoGain { gain: more }) => {
                *gain += more - 1.0;
                true
            }
            // Fitted the same way, on the map as corrected: the factors multiply.
            (
                Effect::AlbedoMap { latitude_gains },
                Effect::AlbedoMap {
                    latitude_gains: more,
                },
            ) if latitude_gains.len() == more.len() => {
                latitude_gains
                    .iter_mut()
                    .zip(more)
                    .for_each(|(g, m)| *g = (*g * m).max(0.0));
                true
            }
            _ => false,
        }
    }

    /// The gyro reading this effect makes of the true body rate (simulator side).
    pub fn corrupt_gyro(&self, rate_rad_s: Vector3<f64>) -> Vector3<f64> {
        match self {
            Effect::GyroScale { scale_error } => {
                rate_rad_s.component_mul(&Vector3::from(*scale_error).add_scalar(1.0))
            }
            _ => rate_rad_s,
        }
    }

    /// The gyro reading with this effect removed (the inverse of [`Effect::corrupt_gyro`]).
    pub fn correct_gyro(&self, rate_rad_s: Vector3<f64>) -> Vector3<f64> {
        match self {
            Effect::GyroScale { scale_error } => {
                rate_rad_s.component_div(&Vector3::from(*scale_error).add_scalar(1.0))
            }
            _ => rate_rad_s,
        }
    }

    /// The magnetometer reading this effect makes of the true body field (simulator side).
    pub fn corrupt_mag(&self, field_nt: Vector3<f64>) -> Vector3<f64> {
        match self {
            Effect::MagBias { bias_nt } => field_nt + Vector3::from(*bias_nt),
            _ => field_nt,
        }
    }

    /// The magnetometer reading with this effect removed.
    pub fn correct_mag(&self, field_nt: Vector3<f64>) -> Vector3<f64> {
        match self {
            Effect::MagBias { bias_nt } => field_nt - Vector3::from(*bias_nt),
            _ => field_nt,
        }
    }
}

fn invalid(field: &str, value: f64, rule: &str) -> Invalid {
    Invalid {
        field: field.to_owned(),
        value,
        rule: rule.to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_value_outside_its_physical_range_is_refused_with_the_range() {
        let drift = |f: f64| Effect::ScaleDrift {
            fraction_per_hour: vec![0.01, f],
        };
        assert_eq!(drift(0.1).check_physical(), Ok(()));
        let e = drift(-1.2).check_physical().unwrap_err();
        assert_eq!(e.field, "fraction_per_hour[1]");
        assert!(
            e.to_string()
                .starts_with("fraction_per_hour[1] = -1.2: a scale drift is")
        );
        // Valid in a file, not physical.
        assert_eq!(drift(-1.2).check(2), Ok(()));
        let temperature = Effect::Temperature {
            coefficient_per_k: vec![0.03],
            reference_c: 20.0,
        };
        assert_eq!(
            temperature.check_physical().unwrap_err().field,
            "percent_per_K[0]"
        );
        let bias = Effect::MagBias {
            bias_nt: [0.0, -2e5, 0.0],
        };
        assert_eq!(bias.check_physical().unwrap_err().field, "nT[1]");
        // Every range names a field its effect has.
        for r in PHYSICAL_RANGES {
            assert!(r.min < r.max && r.why.contains(' '), "{r:?}");
        }
    }

    /// One value of every effect, in catalogue order.
    pub(crate) fn one_of_each(n_pd: usize) -> Vec<Effect> {
        vec![
            Effect::Albedo {
                map: "toms-mean-1p25x1".into(),
            },
            Effect::FovRolloff {
                start_rad: 60f64.to_radians(),
                cutoff_rad: 85f64.to_radians(),
            },
            Effect::DarkOffset {
                volts: vec![0.01; n_pd],
            },
            Effect::Saturation { volts: 3.3 },
            Effect::Penumbra,
            Effect::TimeOffset { seconds: 0.5 },
            Effect::ScaleDrift {
                fraction_per_hour: vec![0.01; n_pd],
            },
            Effect::MagBias {
                bias_nt: [100.0, -50.0, 20.0],
            },
            Effect::GyroScale {
                scale_error: [0.01, 0.0, -0.01],
            },
            Effect::AlbedoGain { gain: 0.0 },
            Effect::Temperature {
                coefficient_per_k: vec![0.002; n_pd],
                reference_c: REFERENCE_TEMPERATURE_C,
            },
            Effect::AlbedoMap {
                latitude_gains: vec![1.2, 1.0, 0.9, 1.1, 1.0, 0.8],
            },
        ]
    }

    #[test]
    fn ids_cover_the_catalogue_once_and_parse_back() {
        let ids: Vec<EffectId> = one_of_each(2).iter().map(Effect::id).collect();
        assert_eq!(ids, EffectId::ALL);
        for id in EffectId::ALL {
            assert_eq!(id.as_str().parse::<EffectId>(), Ok(id));
            assert_eq!(id.to_string(), id.as_str());
        }
        let err = "albedo-gains".parse::<EffectId>().unwrap_err();
        assert!(err.to_string().contains("albedo-gain"), "{err}");
    }

    #[test]
    fn every_effect_survives_ron_and_json_in_the_files_spelling() {
        for effect in one_of_each(3) {
            let ron_text = ron::to_string(&effect).unwrap();
            let back: Effect = ron::from_str(&ron_text).unwrap();
            assert_eq!(back.id(), effect.id(), "{ron_text}");
            let json = serde_json::to_string(&effect).unwrap();
            let back_json: Effect = serde_json::from_str(&json).unwrap();
            assert_eq!(back_json.id(), effect.id(), "{json}");
            effect.check(3).unwrap();
        }
        let rolloff: Effect =
            ron::from_str("FovRolloff(start_deg: 60.0, cutoff_deg: 90.0)").unwrap();
        let Effect::FovRolloff { cutoff_rad, .. } = rolloff else {
            panic!("{rolloff:?}");
        };
        assert_eq!(cutoff_rad, std::f64::consts::FRAC_PI_2);
    }

    #[test]
    fn other_forms_keep_their_id_and_survive_the_files() {
        let forms = [
            Effect::KellyRolloff {
                kappa: 0.1,
                exponent: 2.0,
            },
            Effect::SaturationPerPhotodiode {
                volts: vec![3.2, 3.4, 3.6],
            },
        ];
        let ids = [EffectId::FovRolloff, EffectId::Saturation];
        for (effect, id) in forms.into_iter().zip(ids) {
            assert_eq!(effect.id(), id);
            effect.check(3).unwrap();
            let ron_text = ron::to_string(&effect).unwrap();
            assert_eq!(
                ron::from_str::<Effect>(&ron_text).unwrap(),
                effect,
                "{ron_text}"
            );
            let json = serde_json::to_string(&effect).unwrap();
            assert_eq!(serde_json::from_str::<Effect>(&json).unwrap(), effect);
        }
        let kelly: Effect = ron::from_str("KellyRolloff(kappa: 0.3, exponent: 2)").unwrap();
        assert_eq!(
            kelly,
            Effect::KellyRolloff {
                kappa: 0.3,
                exponent: 2.0
            }
        );
        let bad = Effect::SaturationPerPhotodiode {
            volts: vec![3.0, -1.0],
        };
        assert_eq!(bad.check(2).unwrap_err().field, "volts[1]");
        assert_eq!(bad.check(3).unwrap_err().field, "volts");
        let bad = Effect::KellyRolloff {
            kappa: 0.0,
            exponent: 2.0,
        };
        assert_eq!(bad.check(1).unwrap_err().field, "kappa");
    }

    #[test]
    fn albedo_map_factor_is_linear_between_its_knots() {
        // Band centres -75, -45, -15, 15, 45, 75 deg.
        let gains = [1.2, 1.0, 0.9, 1.1, 1.0, 0.8];
        let at = |deg: f64| albedo_map_factor(&gains, deg.to_radians());
        assert!((at(-90.0) - 1.2).abs() < 1e-12);
        assert!((at(-75.0) - 1.2).abs() < 1e-12);
        assert!((at(-60.0) - 1.1).abs() < 1e-12);
        assert!((at(0.0) - 1.0).abs() < 1e-12);
        assert!((at(15.0) - 1.1).abs() < 1e-12);
        assert!((at(60.0) - 0.9).abs() < 1e-12);
        assert!((at(90.0) - 0.8).abs() < 1e-12);
        assert_eq!(albedo_map_factor(&[], 0.3), 1.0);
        assert_eq!(albedo_map_band(6, (-90f64).to_radians()), 0);
        assert_eq!(albedo_map_band(6, 0.01), 3);
        assert_eq!(albedo_map_band(6, (90f64).to_radians()), 5);
        let mut map = Effect::AlbedoMap {
            latitude_gains: vec![1.0, 1.2],
        };
        assert!(map.compose(&Effect::AlbedoMap {
            latitude_gains: vec![0.5, 1.0]
        }));
        assert_eq!(
            map,
            Effect::AlbedoMap {
                latitude_gains: vec![0.5, 1.2]
            }
        );
    }

    #[test]
    fn checks_name_the_field_in_the_files_spelling() {
        let cases = [
            (
                Effect::FovRolloff {
                    start_rad: 1.0,
                    cutoff_rad: 0.5,
                },
                "cutoff_deg",
            ),
            (Effect::DarkOffset { volts: vec![0.1] }, "volts"),
            (Effect::Saturation { volts: -1.0 }, "volts"),
            (
                Effect::MagBias {
                    bias_nt: [f64::NAN, 0.0, 0.0],
                },
                "nT[0]",
            ),
            (Effect::AlbedoGain { gain: -0.5 }, "gain"),
            (
                Effect::Temperature {
                    coefficient_per_k: vec![0.5, 0.0],
                    reference_c: 20.0,
                },
                "percent_per_K",
            ),
        ];
        for (effect, field) in cases {
            let err = effect.check(2).unwrap_err();
            assert_eq!(err.field, field, "{effect:?}: {err}");
        }
    }

    #[test]
    fn sensor_corrections_invert_the_corruptions() {
        let w = Vector3::new(0.1, -0.2, 0.05);
        let b = Vector3::new(20000.0, -3000.0, 15000.0);
        for effect in one_of_each(1) {
            let w2 = effect.correct_gyro(effect.corrupt_gyro(w));
            let b2 = effect.correct_mag(effect.corrupt_mag(b));
            assert!(
                (w2 - w).norm() < 1e-15 && (b2 - b).norm() < 1e-9,
                "{effect:?}"
            );
        }
        let gyro = Effect::GyroScale {
            scale_error: [0.01, 0.0, -0.02],
        };
        assert!((gyro.corrupt_gyro(w) - Vector3::new(0.101, -0.2, 0.049)).norm() < 1e-15);
    }

    #[test]
    fn composing_equals_applying_twice() {
        let w = Vector3::new(0.3, -0.1, 0.2);
        let mut first = Effect::GyroScale {
            scale_error: [0.01, -0.02, 0.0],
        };
        let second = Effect::GyroScale {
            scale_error: [0.005, 0.01, 0.03],
        };
        let twice = second.correct_gyro(first.correct_gyro(w));
        assert!(first.compose(&second));
        assert!((first.correct_gyro(w) - twice).norm() < 1e-15);
        let mut gain = Effect::AlbedoGain { gain: 0.6 };
        assert!(gain.compose(&Effect::AlbedoGain { gain: 0.7 }));
        assert_eq!(
            gain,
            Effect::AlbedoGain {
                gain: 0.6 + (0.7 - 1.0)
            }
        );
        assert!(!Effect::Penumbra.compose(&Effect::Penumbra));
    }
}
