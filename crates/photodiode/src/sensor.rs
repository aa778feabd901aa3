//! One photodiode ([`Photodiode`]) and everything at one sample that is not a photodiode
//! parameter ([`Scene`]).

use nalgebra::{Matrix3, Vector3};
use pdcal_attitude::{az_el_from_normal, normal_from_az_el};
use serde::{Deserialize, Serialize};

use crate::{AlbedoIrradiance, PhotodiodeError};

/// One photodiode: the per-sensor parameters of paper Eq. (15).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Photodiode {
    /// Scale factor `C_i` of Eq. (15), V: the output under direct, normal-incidence sunlight.
    pub scale_v: f64,
    /// Unit normal `n_i`, body frame (Eq. 16 when built from azimuth and elevation).
    pub n_body: Vector3<f64>,
    /// 1-sigma output noise, V.
    pub noise_v: f64,
    /// Field-of-view half angle, rad. `None`: the cosine law holds over the whole hemisphere
    /// (output zero only when `n^T s <= 0`). `Some(fov)`: the direct Sun also counts as zero
    /// when the incidence angle exceeds `fov`, and albedo cells outside the cone are not seen.
    pub fov_half_angle_rad: Option<f64>,
}

impl Photodiode {
    /// A photodiode with the normal of Eq. (16) from azimuth and elevation in radians.
    pub fn from_az_el_rad(
        scale_v: f64,
        azimuth_rad: f64,
        elevation_rad: f64,
        noise_v: f64,
    ) -> Self {
        Photodiode {
            scale_v,
            n_body: normal_from_az_el(azimuth_rad, elevation_rad),
            noise_v,
            fov_half_angle_rad: None,
        }
    }

    /// As [`Photodiode::from_az_el_rad`], azimuth and elevation in degrees (I/O edge).
    pub fn from_az_el_deg(
        scale_v: f64,
        azimuth_deg: f64,
        elevation_deg: f64,
        noise_v: f64,
    ) -> Self {
        Self::from_az_el_rad(
            scale_v,
            azimuth_deg.to_radians(),
            elevation_deg.to_radians(),
            noise_v,
        )
    }

    /// A photodiode with a given body normal, normalised here.
    pub fn new(scale_v: f64, n_body: Vector3<f64>, noise_v: f64) -> Result<Self, PhotodiodeError> {
        let n_body = unit(&n_body, "n_body")?;
        Ok(Photodiode {
            scale_v,
            n_body,
            noise_v,
            fov_half_angle_rad: None,
        })
    }

    /// The same photodiode with a field-of-view half angle (rad), or none.
    pub fn with_fov_half_angle_rad(mut self, fov_half_angle_rad: Option<f64>) -> Self {
        self.fov_half_angle_rad = fov_half_angle_rad;
        self
    }

    /// Azimuth and elevation of the normal, rad (inverse of Eq. 16).
    pub fn az_el_rad(&self) -> (f64, f64) {
        az_el_from_normal(&self.n_body)
    }

    /// Cosine of the field-of-view half angle; 0 (the hemisphere) without one.
    pub fn cos_fov(&self) -> f64 {
        self.fov_half_angle_rad.map_or(0.0, f64::cos)
    }

    /// Whether a direction at incidence cosine `cos_incidence` is seen by the cosine law:
    /// `cos > 0` and, with a field of view, `cos >= cos(fov)`.
    pub fn accepts(&self, cos_incidence: f64) -> bool {
        cos_incidence > 0.0 && cos_incidence >= self.cos_fov()
    }
}

/// How the illuminated fraction of the Sun ([`Scene::sun_fraction`]) enters the direct-Sun
/// output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum ShadowMode {
    /// Hard-edged shadow: factor 1 when `sun_fraction > 0.5`, else 0 (the paper's model).
    #[default]
    Hard,
    /// Penumbra: factor `sun_fraction` (clamped to 0..1).
    Penumbra,
}

impl ShadowMode {
    /// The factor multiplying the direct-Sun output.
    pub fn factor(self, sun_fraction: f64) -> f64 {
        match self {
            ShadowMode::Hard => {
                if sun_fraction > 0.5 {
                    1.0
                } else {
                    0.0
                }
            }
            ShadowMode::Penumbra => sun_fraction.clamp(0.0, 1.0),
        }
    }
}

/// Everything at one sample that is not a photodiode parameter.
///
/// `sun_body` must equal `attitude * s_R`; [`Scene::new`] computes it so. Terms read
/// `sun_body` for the direct Sun and `attitude` to express normals in GCRF for the albedo.
#[derive(Clone, Copy)]
pub struct Scene<'a> {
    /// Attitude matrix `A` of Eq. (14), GCRF -> body (`v_B = A v_I`).
    pub attitude: Matrix3<f64>,
    /// Unit Sun direction, body frame: `A s|_R`.
    pub sun_body: Vector3<f64>,
    /// Illuminated fraction of the solar disc, 0 (umbra) .. 1 (full Sun), from an eclipse model.
    pub sun_fraction: f64,
    /// `(1 AU / r_sun)^2`, `r_sun` the spacecraft-to-Sun distance: the direct solar
    /// irradiance relative to its value at 1 AU, at which the scale factors `C` are defined.
    /// 1 in [`Scene::new`]; between about 0.967 (aphelion) and 1.034 (perihelion).
    pub sun_distance_factor: f64,
    /// Body angular rate relative to GCRF, body frame, rad/s (for `time-offset`).
    pub rate_body_rad_s: Vector3<f64>,
    /// Time since the data set epoch, s (for `scale-drift`).
    pub t_s: f64,
    /// Albedo irradiance provider for this sample (GCRF); `None` means no albedo reaches the
    /// sensors at this sample (the `albedo` term then contributes zero).
    pub albedo: Option<&'a dyn AlbedoIrradiance>,
    /// Temperature of each photodiode, degrees Celsius, in photodiode order (for
    /// `temperature`); empty when the telemetry has none, NaN for a photodiode without one.
    pub temperature_c: &'a [f64],
}

impl std::fmt::Debug for Scene<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("attitude", &self.attitude)
            .field("sun_body", &self.sun_body)
            .field("sun_fraction", &self.sun_fraction)
            .field("sun_distance_factor", &self.sun_distance_factor)
            .field("rate_body_rad_s", &self.rate_body_rad_s)
            .field("t_s", &self.t_s)
            .field("albedo", &self.albedo.is_some())
            .field("temperature_c", &self.temperature_c)
            .finish()
    }
}

impl<'a> Scene<'a> {
    /// A fully sunlit, non-rotating scene at `t_s = 0` without albedo; `sun_gcrf` is
    /// normalised and rotated into the body frame.
    pub fn new(attitude: Matrix3<f64>, sun_gcrf: &Vector3<f64>) -> Result<Self, PhotodiodeError> {
        let sun_gcrf = unit(sun_gcrf, "sun_gcrf")?;
        Ok(Scene {
            attitude,
            sun_body: attitude * sun_gcrf,
            sun_fraction: 1.0,
            sun_distance_factor: 1.0,
            rate_body_rad_s: Vector3::zeros(),
            t_s: 0.0,
            albedo: None,
            temperature_c: &[],
        })
    }

    /// The same scene with an illuminated Sun fraction (0..1).
    pub fn with_sun_fraction(mut self, sun_fraction: f64) -> Self {
        self.sun_fraction = sun_fraction;
        self
    }

    /// The same scene with the Sun's distance factor `(1 AU / r_sun)^2`.
    pub fn with_sun_distance_factor(mut self, sun_distance_factor: f64) -> Self {
        self.sun_distance_factor = sun_distance_factor;
        self
    }

    /// The same scene with a body rate, rad/s.
    pub fn with_rate(mut self, rate_body_rad_s: Vector3<f64>) -> Self {
        self.rate_body_rad_s = rate_body_rad_s;
        self
    }

    /// The same scene at time `t_s`, s.
    pub fn with_time(mut self, t_s: f64) -> Self {
        self.t_s = t_s;
        self
    }

    /// The same scene with per-photodiode temperatures, degrees Celsius.
    pub fn with_temperatures(mut self, temperature_c: &'a [f64]) -> Self {
        self.temperature_c = temperature_c;
        self
    }

    /// The same scene with an albedo provider.
    pub fn with_albedo(mut self, albedo: &'a dyn AlbedoIrradiance) -> Self {
        self.albedo = Some(albedo);
        self
    }
}

/// Incidence cosine and irradiance factor of the direct Sun on one photodiode, or `None` when
/// the cosine law gives zero (Sun behind the sensor, or outside its field of view).
pub(crate) struct SunView {
    /// `n^T A s|_R` (the normal is not re-normalised, so partials w.r.t. `n` stay exact).
    pub cos: f64,
    /// [`ShadowMode::factor`] of the scene's Sun fraction times
    /// [`Scene::sun_distance_factor`]: what multiplies `C n^T A s|_R`, so every term built on
    /// the direct Sun (and its partials, where it enters only as a scale) sees the same
    /// irradiance.
    pub shadow: f64,
}

pub(crate) fn sun_view(pd: &Photodiode, scene: &Scene, shadow: ShadowMode) -> Option<SunView> {
    let cos = pd.n_body.dot(&scene.sun_body);
    pd.accepts(cos).then(|| SunView {
        cos,
        shadow: shadow.factor(scene.sun_fraction) * scene.sun_distance_factor,
    })
}

fn unit(v: &Vector3<f64>, what: &'static str) -> Result<Vector3<f64>, PhotodiodeError> {
    v.iter()
        .all(|c| c.is_finite())
        .then(|| v.try_normalize(0.0))
        .flatten()
        .ok_or(PhotodiodeError::BadDirection {
            what,
            x: v.x,
            y: v.y,
            z: v.z,
        })
}
