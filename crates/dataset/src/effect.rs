//! The effects a simulated truth contained beyond the base measurement model (truth.ron).

use serde::{Deserialize, Serialize};

/// One effect that was switched on in the truth, with its parameters.
///
/// Variant names are the RON spelling (`Albedo(map: "toms-mean-1p25x1")`); [`Effect::id`]
/// gives the fixed identifier of `cli-contract.md` (`albedo`, `dark-offset`, ...). Lists
/// marked "per photodiode" hold one entry per photodiode in `pdNN` order.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Effect {
    /// `albedo`: Earth-reflected sunlight reaching the photodiodes.
    Albedo {
        /// Albedo map identifier as the albedo crate names it (`toms-mean-1p25x1`).
        map: String,
    },
    /// `fov-rolloff`: response falls below the cosine law at high incidence.
    ///
    /// With incidence angle `theta` (between normal and Sun), the cosine-law output is
    /// multiplied by 1 for `theta <= start_deg`, 0 for `theta >= cutoff_deg`, and by the
    /// raised-cosine taper `0.5 (1 + cos(pi (theta - start_deg) / (cutoff_deg - start_deg)))`
    /// in between. Same for every photodiode.
    FovRolloff {
        /// Incidence angle where the roll-off starts, degrees.
        start_deg: f64,
        /// Incidence angle where the output reaches zero, degrees (> `start_deg`, <= 90).
        cutoff_deg: f64,
    },
    /// `dark-offset`: constant additive output (dark current, ADC offset).
    DarkOffset {
        /// Offset added to each output, V, per photodiode; present in eclipse too.
        volts: Vec<f64>,
    },
    /// `saturation`: outputs clipped at a maximum (one shared ADC full scale).
    Saturation {
        /// Largest output, V; `min(output, volts)` after noise.
        volts: f64,
    },
    /// `penumbra`: partial sunlight while entering and leaving Earth's shadow (truth.csv
    /// `eclipse` takes values between 0 and 1); when off, the shadow is hard-edged.
    Penumbra,
    /// `time-offset`: photodiode samples time-tagged late or early relative to gyro and
    /// magnetometer.
    TimeOffset {
        /// Tag minus true sampling time, s: positive means a photodiode row tagged `t_s` was
        /// sampled at `t_s - seconds`.
        seconds: f64,
    },
    /// `scale-drift`: scale factor changing linearly during the data set.
    ///
    /// `C_i(t) = scale_V_i (1 + fraction_per_hour_i * t_s / 3600)`, with `scale_V_i` of
    /// truth.ron the value at `t_s = 0`.
    ScaleDrift {
        /// Relative scale change per hour, dimensionless per hour, per photodiode.
        fraction_per_hour: Vec<f64>,
    },
    /// `mag-bias`: residual constant magnetometer bias, body frame.
    MagBias {
        /// Bias added to each magnetometer sample, nT, body x/y/z (file name `nT`).
        #[serde(rename = "nT", with = "triple")]
        bias_nt: [f64; 3],
    },
    /// `gyro-scale`: gyro scale-factor error per body axis.
    GyroScale {
        /// Dimensionless error `e` per axis: measured = (1 + e) true + bias + noise
        /// (0.01 is a 1 % error).
        #[serde(with = "triple")]
        scale_error: [f64; 3],
    },
}

/// `[f64; 3]` as a RON list `[x, y, z]` like every other list in truth.ron (serde's default
/// for arrays is a tuple, `(x, y, z)`).
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

impl Effect {
    /// Every effect id of `cli-contract.md` except `none`, in the contract's order.
    pub const IDS: [&'static str; 9] = [
        "albedo",
        "fov-rolloff",
        "dark-offset",
        "saturation",
        "penumbra",
        "time-offset",
        "scale-drift",
        "mag-bias",
        "gyro-scale",
    ];

    /// The fixed effect identifier of `cli-contract.md` (`dark-offset`, ...).
    pub fn id(&self) -> &'static str {
        match self {
            Self::Albedo { .. } => "albedo",
            Self::FovRolloff { .. } => "fov-rolloff",
            Self::DarkOffset { .. } => "dark-offset",
            Self::Saturation { .. } => "saturation",
            Self::Penumbra => "penumbra",
            Self::TimeOffset { .. } => "time-offset",
            Self::ScaleDrift { .. } => "scale-drift",
            Self::MagBias { .. } => "mag-bias",
            Self::GyroScale { .. } => "gyro-scale",
        }
    }

    /// Every number the effect carries, with its field path inside the variant, for the
    /// finiteness check.
    pub(crate) fn numbers(&self) -> Vec<(String, f64)> {
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
            Self::DarkOffset { volts } => indexed("volts", volts),
            Self::Saturation { volts } => vec![("volts".into(), *volts)],
            Self::TimeOffset { seconds } => vec![("seconds".into(), *seconds)],
            Self::ScaleDrift { fraction_per_hour } => {
                indexed("fraction_per_hour", fraction_per_hour)
            }
            Self::MagBias { bias_nt } => indexed("nT", bias_nt),
            Self::GyroScale { scale_error } => indexed("scale_error", scale_error),
        }
    }

    /// The per-photodiode list, if the effect has one: its field name and length.
    pub(crate) fn per_photodiode(&self) -> Option<(&'static str, usize)> {
        match self {
            Self::DarkOffset { volts } => Some(("volts", volts.len())),
            Self::ScaleDrift { fraction_per_hour } => {
                Some(("fraction_per_hour", fraction_per_hour.len()))
            }
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_cover_the_contract_once() {
        let all = [
            Effect::Albedo { map: "m".into() },
            Effect::FovRolloff {
                start_deg: 60.0,
                cutoff_deg: 85.0,
            },
            Effect::DarkOffset { volts: vec![0.01] },
            Effect::Saturation { volts: 3.3 },
            Effect::Penumbra,
            Effect::TimeOffset { seconds: 0.5 },
            Effect::ScaleDrift {
                fraction_per_hour: vec![0.01],
            },
            Effect::MagBias {
                bias_nt: [1.0, 2.0, 3.0],
            },
            Effect::GyroScale {
                scale_error: [0.01, 0.0, -0.01],
            },
        ];
        let ids: Vec<_> = all.iter().map(Effect::id).collect();
        assert_eq!(ids, Effect::IDS);
    }
}
