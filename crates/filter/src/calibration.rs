//! [`Calibration`]: the calibrated parameters (`calibration.ron`), also read back as the prior
//! of [`crate::Mode::ScaleOnly`].

use nalgebra::{Matrix2, Vector3};
use pdcal_attitude::{az_el_from_normal, normal_from_az_el, tangent_basis};
use serde::{Deserialize, Serialize};

use crate::FilterError;

/// Version of the `calibration.ron` layout.
pub const CALIBRATION_FORMAT_VERSION: u32 = 1;

/// One photodiode's scale factor and normal with 1-sigma uncertainties (degrees at this I/O
/// edge). Also the per-step photodiode estimate of [`crate::StepEstimate`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PdCalibration {
    /// Scale factor `C_i` of Eq. (15), V.
    #[serde(rename = "scale_V")]
    pub scale_v: f64,
    /// Its 1-sigma, V.
    #[serde(rename = "scale_sigma_V")]
    pub scale_sigma_v: f64,
    /// Azimuth of Eq. (16), deg.
    pub azimuth_deg: f64,
    /// Its 1-sigma, deg; `None` where the azimuth is undefined: at the pole (elevation
    /// +-90 deg) or when the normal's uncertainty reaches the pole (sigma above 180 deg).
    pub azimuth_sigma_deg: Option<f64>,
    /// Elevation of Eq. (16), deg.
    pub elevation_deg: f64,
    /// Its 1-sigma, deg.
    pub elevation_sigma_deg: f64,
}

impl PdCalibration {
    /// From a scale, a unit body normal and the 2x2 covariance of the normal's tangent-plane
    /// correction in the [`tangent_basis`] of that normal (rad^2).
    pub fn from_normal(
        scale_v: f64,
        scale_sigma_v: f64,
        n_body: &Vector3<f64>,
        tangent_cov: &Matrix2<f64>,
    ) -> Self {
        Self::from_normal_in(
            scale_v,
            scale_sigma_v,
            n_body,
            &tangent_basis(n_body),
            tangent_cov,
        )
    }

    /// [`PdCalibration::from_normal`] with the covariance in the tangent basis `basis` of
    /// the normal (the filter's [`crate::StateLayout::tangent_basis`]).
    pub fn from_normal_in(
        scale_v: f64,
        scale_sigma_v: f64,
        n_body: &Vector3<f64>,
        basis: &(Vector3<f64>, Vector3<f64>),
        tangent_cov: &Matrix2<f64>,
    ) -> Self {
        let (az, el) = az_el_from_normal(n_body);
        let (az_sigma, el_sigma) = az_el_sigmas_in(n_body, basis, tangent_cov);
        PdCalibration {
            scale_v,
            scale_sigma_v,
            azimuth_deg: az.to_degrees(),
            azimuth_sigma_deg: az_sigma.map(f64::to_degrees),
            elevation_deg: el.to_degrees(),
            elevation_sigma_deg: el_sigma.to_degrees(),
        }
    }

    /// The unit body normal of Eq. (16).
    pub fn n_body(&self) -> Vector3<f64> {
        normal_from_az_el(
            self.azimuth_deg.to_radians(),
            self.elevation_deg.to_radians(),
        )
    }
}

/// Azimuth and elevation sigmas (rad) of a normal with tangent covariance `cov`.
///
/// A tangent displacement `dn` moves the elevation by `e_el . dn` and the azimuth by
/// `e_az . dn / cos(el)` (`e_az`, `e_el` the unit east/up directions at `n`), so
/// `Sigma_azel = J Sigma_t J^T` with `J = [e_az.e1/cos(el), e_az.e2/cos(el); e_el.e1, e_el.e2]`.
/// The azimuth sigma is `None` at the pole (where `cos(el)` vanishes) and when it would
/// exceed 180 deg (the uncertainty region contains the pole: any azimuth fits).
pub fn az_el_sigmas(n: &Vector3<f64>, cov: &Matrix2<f64>) -> (Option<f64>, f64) {
    az_el_sigmas_in(n, &tangent_basis(n), cov)
}

/// [`az_el_sigmas`] for a covariance expressed in the tangent basis `(e1, e2)` of `n`
/// (e.g. [`crate::StateLayout::tangent_basis`]).
pub fn az_el_sigmas_in(
    n: &Vector3<f64>,
    (e1, e2): &(Vector3<f64>, Vector3<f64>),
    cov: &Matrix2<f64>,
) -> (Option<f64>, f64) {
    let (az, el) = az_el_from_normal(n);
    let (sa, ca) = az.sin_cos();
    let (se, ce) = el.sin_cos();
    let e_az = Vector3::new(-sa, ca, 0.0);
    let e_el = Vector3::new(-se * ca, -se * sa, ce);
    let j_el = nalgebra::RowVector2::new(e_el.dot(e1), e_el.dot(e2));
    let el_var = (j_el * cov * j_el.transpose())[0];
    let horizontal = n.x.hypot(n.y);
    let az_sigma = (horizontal > 1e-12)
        .then(|| {
            let j_az = nalgebra::RowVector2::new(e_az.dot(e1), e_az.dot(e2)) / horizontal;
            (j_az * cov * j_az.transpose())[0].max(0.0).sqrt()
        })
        .filter(|s| *s <= std::f64::consts::PI);
    (az_sigma, el_var.max(0.0).sqrt())
}

/// An estimated model parameter (e.g. a dark offset added by the diagnosis workflow).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterEstimate {
    /// Parameter name (`pd03_dark_offset_V`).
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Estimate.
    pub value: f64,
    /// 1-sigma.
    pub sigma: f64,
}

/// The calibrated parameters the driver writes as `calibration.ron`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    /// [`CALIBRATION_FORMAT_VERSION`].
    pub format_version: u32,
    /// Per photodiode, `pdNN` order.
    pub photodiodes: Vec<PdCalibration>,
    /// Gyro bias, rad/s, body x/y/z.
    pub gyro_bias_rad_s: [f64; 3],
    /// Its 1-sigma, rad/s.
    pub gyro_bias_sigma_rad_s: [f64; 3],
    /// Estimated model parameters, if any.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub parameters: Vec<ParameterEstimate>,
    /// The quantities the data did not determine or determined weakly, one line each
    /// (`pd03 scale_V: not-determined (why)`): a `not-determined` one holds its prior value
    /// (`crate::identifiability`). Empty when every quantity is calibrated.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub status: Vec<String>,
}

impl Calibration {
    /// Multiplies every sigma (gyro bias, scales, normals, parameters) by `factor`
    /// ([`crate::consistency::Dispersion`]).
    pub fn scale_sigmas(&mut self, factor: f64) {
        self.gyro_bias_sigma_rad_s
            .iter_mut()
            .for_each(|s| *s *= factor);
        for pd in &mut self.photodiodes {
            pd.scale_sigma_v *= factor;
            pd.azimuth_sigma_deg = pd.azimuth_sigma_deg.map(|s| s * factor);
            pd.elevation_sigma_deg *= factor;
        }
        self.parameters.iter_mut().for_each(|p| p.sigma *= factor);
    }

    /// Parses `calibration.ron` text and checks every photodiode by the dataset's own rules
    /// for a mounting and a scale factor ([`pdcal_dataset::rules`]).
    pub fn from_ron_str(text: &str) -> Result<Self, FilterError> {
        let cal: Calibration =
            ron::from_str(text).map_err(|e| FilterError::ron_parse("calibration", &e))?;
        if cal.format_version != CALIBRATION_FORMAT_VERSION {
            return Err(FilterError::Config {
                field: "format_version",
                value: f64::from(cal.format_version),
                rule: "calibration format version must be 1",
            });
        }
        for (i, pd) in cal.photodiodes.iter().enumerate() {
            check_photodiode(i, pd)?;
        }
        Ok(cal)
    }

    /// Pretty RON text.
    pub fn to_ron_string(&self) -> Result<String, FilterError> {
        ron::ser::to_string_pretty(self, ron::ser::PrettyConfig::default()).map_err(|e| {
            FilterError::Ron {
                what: "calibration",
                message: e.to_string(),
            }
        })
    }
}

/// Photodiode `i` of a calibration by the rules every file's mounting and scale factor
/// obey ([`pdcal_dataset::rules`]); the error names `photodiodes[i].field` and the value.
fn check_photodiode(i: usize, pd: &PdCalibration) -> Result<(), FilterError> {
    use pdcal_dataset::rules;
    let bad = |field: &str, value: f64, rule: String| FilterError::Invalid {
        field: format!("photodiodes[{i}].{field}"),
        value: pdcal_text::number(value),
        rule,
    };
    if let Err((field, rule)) = rules::mounting(pd.azimuth_deg, pd.elevation_deg) {
        let value = match field {
            "azimuth_deg" => pd.azimuth_deg,
            _ => pd.elevation_deg,
        };
        return Err(bad(field, value, rule.to_owned()));
    }
    rules::scale_factor(pd.scale_v).map_err(|rule| bad("scale_V", pd.scale_v, rule.to_owned()))?;
    let sigmas = [
        ("scale_sigma_V", pd.scale_sigma_v, rules::MAX_SCALE_V),
        ("elevation_sigma_deg", pd.elevation_sigma_deg, 180.0),
        (
            "azimuth_sigma_deg",
            pd.azimuth_sigma_deg.unwrap_or(0.0),
            360.0,
        ),
    ];
    for (field, value, max) in sigmas {
        rules::sigma(value, max).map_err(|rule| bad(field, value, rule))?;
    }
    Ok(())
}
