//! The files' spelling of an [`Effect`]: truth.ron, scenario RON and `diagnosis.json`.
//!
//! Variant names are the RON spelling (`Albedo(map: "toms-mean-1p25x1")`,
//! `FovRolloff(start_deg: 60, cutoff_deg: 85)`); units are the ones these files have always
//! had (degrees, volts, nT, per hour, %/K). This is the only place they are converted to and
//! from the catalogue's SI values.

use serde::{Deserialize, Serialize};

use crate::Effect;

/// One effect as written in the files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum EffectRecord {
    /// `albedo`.
    Albedo {
        /// Albedo map identifier.
        map: String,
    },
    /// `fov-rolloff`.
    FovRolloff {
        /// Start of the roll-off, deg.
        start_deg: f64,
        /// Zero output from here, deg (> `start_deg`, <= 90).
        cutoff_deg: f64,
    },
    /// `fov-rolloff`, Kelly form.
    KellyRolloff {
        /// `kappa` of `1 - exp(-c^exponent / kappa)`.
        kappa: f64,
        /// The power of the cosine.
        exponent: f64,
    },
    /// `dark-offset`.
    DarkOffset {
        /// Offset per photodiode, V.
        volts: Vec<f64>,
    },
    /// `saturation`.
    Saturation {
        /// Clip level, V.
        volts: f64,
    },
    /// `saturation`, one level per photodiode.
    SaturationPerPhotodiode {
        /// Clip level per photodiode, V.
        volts: Vec<f64>,
    },
    /// `penumbra`.
    Penumbra,
    /// `time-offset`.
    TimeOffset {
        /// Tag minus true sampling time, s.
        seconds: f64,
    },
    /// `scale-drift`.
    ScaleDrift {
        /// Relative scale change per hour, per photodiode.
        fraction_per_hour: Vec<f64>,
    },
    /// `mag-bias`.
    MagBias {
        /// Bias, nT, body x/y/z.
        #[serde(rename = "nT", with = "triple")]
        bias_nt: [f64; 3],
    },
    /// `gyro-scale`.
    GyroScale {
        /// Dimensionless error per axis.
        #[serde(with = "triple")]
        scale_error: [f64; 3],
    },
    /// `albedo-gain`.
    AlbedoGain {
        /// Factor on the albedo term.
        gain: f64,
    },
    /// `temperature`.
    Temperature {
        /// Scale-factor change per kelvin, %/K, per photodiode.
        #[serde(rename = "percent_per_K")]
        percent_per_k: Vec<f64>,
        /// Reference temperature, degrees Celsius (default 20).
        #[serde(rename = "reference_C", default = "reference_c")]
        reference_c: f64,
    },
    /// `albedo-map`.
    AlbedoMap {
        /// Factor at each latitude knot, south to north, knots evenly from -90 to 90 deg.
        latitude_gains: Vec<f64>,
    },
}

fn reference_c() -> f64 {
    crate::REFERENCE_TEMPERATURE_C
}

impl EffectRecord {
    /// Every number the record carries, with its field path, for the finiteness check.
    pub fn numbers(&self) -> Vec<(String, f64)> {
        let indexed = |name: &str, values: &[f64]| -> Vec<(String, f64)> {
            values
                .iter()
                .enumerate()
                .map(|(i, &v)| (format!("{name}[{i}]"), v))
                .collect()
        };
        match self {
            Self::Albedo { .. } | Self::Penumbra => vec![],
            Self::FovRolloff {
                start_deg,
                cutoff_deg,
            } => vec![
                ("start_deg".into(), *start_deg),
                ("cutoff_deg".into(), *cutoff_deg),
            ],
            Self::KellyRolloff { kappa, exponent } => {
                vec![("kappa".into(), *kappa), ("exponent".into(), *exponent)]
            }
            Self::DarkOffset { volts } | Self::SaturationPerPhotodiode { volts } => {
                indexed("volts", volts)
            }
            Self::Saturation { volts } => vec![("volts".into(), *volts)],
            Self::TimeOffset { seconds } => vec![("seconds".into(), *seconds)],
            Self::ScaleDrift { fraction_per_hour } => {
                indexed("fraction_per_hour", fraction_per_hour)
            }
            Self::MagBias { bias_nt } => indexed("nT", bias_nt),
            Self::GyroScale { scale_error } => indexed("scale_error", scale_error),
            Self::AlbedoGain { gain } => vec![("gain".into(), *gain)],
            Self::AlbedoMap { latitude_gains } => indexed("latitude_gains", latitude_gains),
            Self::Temperature {
                percent_per_k,
                reference_c,
            } => {
                let mut v = indexed("percent_per_K", percent_per_k);
                v.push(("reference_C".into(), *reference_c));
                v
            }
        }
    }
}

impl From<EffectRecord> for Effect {
    fn from(r: EffectRecord) -> Self {
        match r {
            EffectRecord::Albedo { map } => Effect::Albedo { map },
            EffectRecord::FovRolloff {
                start_deg,
                cutoff_deg,
            } => Effect::FovRolloff {
                start_rad: start_deg.to_radians(),
                cutoff_rad: cutoff_deg.to_radians(),
            },
            EffectRecord::KellyRolloff { kappa, exponent } => {
                Effect::KellyRolloff { kappa, exponent }
            }
            EffectRecord::DarkOffset { volts } => Effect::DarkOffset { volts },
            EffectRecord::SaturationPerPhotodiode { volts } => {
                Effect::SaturationPerPhotodiode { volts }
            }
            EffectRecord::Saturation { volts } => Effect::Saturation { volts },
            EffectRecord::Penumbra => Effect::Penumbra,
            EffectRecord::TimeOffset { seconds } => Effect::TimeOffset { seconds },
            EffectRecord::ScaleDrift { fraction_per_hour } => {
                Effect::ScaleDrift { fraction_per_hour }
            }
            EffectRecord::MagBias { bias_nt } => Effect::MagBias { bias_nt },
            EffectRecord::GyroScale { scale_error } => Effect::GyroScale { scale_error },
            EffectRecord::AlbedoGain { gain } => Effect::AlbedoGain { gain },
            EffectRecord::AlbedoMap { latitude_gains } => Effect::AlbedoMap { latitude_gains },
            EffectRecord::Temperature {
                percent_per_k,
                reference_c,
            } => Effect::Temperature {
                coefficient_per_k: percent_per_k.iter().map(|p| p / 100.0).collect(),
                reference_c,
            },
        }
    }
}

impl From<Effect> for EffectRecord {
    fn from(e: Effect) -> Self {
        match e {
            Effect::Albedo { map } => EffectRecord::Albedo { map },
            Effect::FovRolloff {
                start_rad,
                cutoff_rad,
            } => EffectRecord::FovRolloff {
                start_deg: start_rad.to_degrees(),
                cutoff_deg: cutoff_rad.to_degrees(),
            },
            Effect::KellyRolloff { kappa, exponent } => {
                EffectRecord::KellyRolloff { kappa, exponent }
            }
            Effect::DarkOffset { volts } => EffectRecord::DarkOffset { volts },
            Effect::SaturationPerPhotodiode { volts } => {
                EffectRecord::SaturationPerPhotodiode { volts }
            }
            Effect::Saturation { volts } => EffectRecord::Saturation { volts },
            Effect::Penumbra => EffectRecord::Penumbra,
            Effect::TimeOffset { seconds } => EffectRecord::TimeOffset { seconds },
            Effect::ScaleDrift { fraction_per_hour } => {
                EffectRecord::ScaleDrift { fraction_per_hour }
            }
            Effect::MagBias { bias_nt } => EffectRecord::MagBias { bias_nt },
            Effect::GyroScale { scale_error } => EffectRecord::GyroScale { scale_error },
            Effect::AlbedoGain { gain } => EffectRecord::AlbedoGain { gain },
            Effect::AlbedoMap { latitude_gains } => EffectRecord::AlbedoMap { latitude_gains },
            Effect::Temperature {
                coefficient_per_k,
                reference_c,
            } => EffectRecord::Temperature {
                percent_per_k: coefficient_per_k.iter().map(|k| 100.0 * k).collect(),
                reference_c,
            },
        }
    }
}

/// `[f64; 3]` as a list `[x, y, z]` like every other list in the files (serde's default for
/// arrays is a RON tuple, `(x, y, z)`).
mod triple {
    use serde::{Deserialize, Deserializer, Serializer, de::Error};

    pub fn serialize<S: Serializer>(v: &[f64; 3], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(v)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
        let v = Vec::<f64>::deserialize(d)?;
        <[f64; 3]>::try_from(v.as_slice())
            .map_err(|_| D::Error::invalid_length(v.len(), &"3 numbers, x y z"))
    }
}
