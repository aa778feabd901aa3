//! Everything the sensors are compared against at one sample time, from one place.
//!
//! The simulator (to make truth) and the filter (to predict measurements) both need, at each
//! `t_s`, the spacecraft position, the Sun, the geomagnetic field, the illuminated fraction
//! of the Sun and the Earth-fixed rotation (for the albedo grid). [`ReferenceModel`] is the
//! one implementation of that bundle, so both sides use identical reference vectors.

use hifitime::Epoch;
use nalgebra::{Matrix3, Vector3};

use crate::igrf::{Igrf, IgrfError};
use crate::sun::{LowPrecisionSun, SunEphemeris};
use crate::time::{self, TimeError};
use crate::{OrbitError, OrbitSource, eclipse, frames};

/// Failure to build a reference sample.
///
/// The inner error's text is part of the message, so it is not also a `source` (an
/// `anyhow` chain would print it twice); hence the hand-written `From`s.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReferenceError {
    /// The sample time could not be formed from the epoch and `t_s`.
    #[error("reference time: {0}")]
    Time(TimeError),
    /// The orbit source could not give a position.
    #[error("reference orbit: {0}")]
    Orbit(OrbitError),
    /// The field model could not be evaluated (outside 1900-2030, bad position).
    #[error("reference field: {0}")]
    Field(IgrfError),
}

impl From<TimeError> for ReferenceError {
    fn from(e: TimeError) -> Self {
        Self::Time(e)
    }
}

impl From<OrbitError> for ReferenceError {
    fn from(e: OrbitError) -> Self {
        Self::Orbit(e)
    }
}

impl From<IgrfError> for ReferenceError {
    fn from(e: IgrfError) -> Self {
        Self::Field(e)
    }
}

/// Reference quantities at one sample, all inertial vectors in GCRF: the one per-sample
/// reference of the workspace (the simulator's truth, the filter's predictions, the
/// diagnosis's residual bands and the driver's stored rows all read this type).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reference {
    /// Spacecraft position, km.
    pub r_gcrf_km: Vector3<f64>,
    /// Geocentric Sun position, km.
    pub sun_gcrf_km: Vector3<f64>,
    /// Unit vector from the spacecraft to the Sun, parallax of the orbit included (`s|_R`
    /// of the paper's Eq. 14).
    pub sun_gcrf_unit: Vector3<f64>,
    /// IGRF-14 field at the spacecraft, nT.
    pub b_gcrf_nt: Vector3<f64>,
    /// Illuminated fraction of the solar disc, 0 (umbra) to 1 (full Sun).
    pub sun_fraction: f64,
    /// Rotation GCRF -> ITRF (`v_itrf = R v_gcrf`), for Earth-fixed grids.
    pub gcrf_to_itrf: Matrix3<f64>,
}

impl Reference {
    /// `(1 AU / r_sun)^2`, `r_sun` the spacecraft-to-Sun distance
    /// ([`crate::sun_distance_factor`]).
    pub fn sun_distance_factor(&self) -> f64 {
        crate::sun_distance_factor(&self.r_gcrf_km, &self.sun_gcrf_km)
    }
}

/// Orbit, Sun, field and eclipse models bundled for per-sample evaluation.
pub struct ReferenceModel {
    epoch: Epoch,
    orbit: Box<dyn OrbitSource + Send + Sync>,
    sun: Box<dyn SunEphemeris + Send + Sync>,
    field: Igrf,
}

impl ReferenceModel {
    /// The default bundle: the given orbit, the Almanac Sun and IGRF-14.
    pub fn new(
        epoch: Epoch,
        orbit: Box<dyn OrbitSource + Send + Sync>,
    ) -> Result<Self, ReferenceError> {
        Ok(Self {
            epoch,
            orbit,
            sun: Box::new(LowPrecisionSun),
            field: Igrf::igrf14()?,
        })
    }

    /// Replaces the Sun ephemeris (e.g. with a JPL-based source).
    pub fn with_sun(mut self, sun: Box<dyn SunEphemeris + Send + Sync>) -> Self {
        self.sun = sun;
        self
    }

    /// The epoch `t_s` counts from.
    pub fn epoch(&self) -> Epoch {
        self.epoch
    }

    /// All reference quantities at `t_s` seconds after the epoch.
    pub fn at(&self, t_s: f64) -> Result<Reference, ReferenceError> {
        let epoch = time::offset(self.epoch, t_s)?;
        let state = self.orbit.state_gcrf(epoch)?;
        let sun_gcrf_km = self.sun.sun_gcrf_km(epoch);
        let gcrf_to_itrf = frames::gcrf_to_itrf(epoch);
        let r = state.r_gcrf_km;
        let b_itrf = self.field.field_ecef_nt(&(gcrf_to_itrf * r), epoch)?;
        Ok(Reference {
            r_gcrf_km: r,
            sun_gcrf_km,
            sun_gcrf_unit: (sun_gcrf_km - r).normalize(),
            b_gcrf_nt: gcrf_to_itrf.transpose() * b_itrf,
            sun_fraction: eclipse::illuminated_fraction(&r, &sun_gcrf_km),
            gcrf_to_itrf,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TleOrbit;

    const L1: &str = "1 37853U 11061D   11308.77065972  .00000000  00000-0  20000-4 0  9997";
    const L2: &str = "2 37853 101.7000  50.0000 0300509 130.0000 230.0000 14.86144463  1000";

    fn model() -> ReferenceModel {
        let epoch = time::parse_utc("2011-11-04T18:29:45Z").expect("valid epoch");
        let orbit = TleOrbit::from_lines(L1, L2).expect("valid TLE");
        ReferenceModel::new(epoch, Box::new(orbit)).expect("IGRF parses")
    }

    /// The bundle must agree with the individual models it wraps; the field is checked
    /// against the GCRF path of the IGRF module, which has its own reference test.
    #[test]
    fn bundle_matches_the_individual_models() {
        let m = model();
        let r = m.at(1800.0).expect("in range");
        let epoch = time::offset(m.epoch(), 1800.0).expect("in range");
        let field = Igrf::igrf14().expect("parses");
        let b = field.field_gcrf_nt(&r.r_gcrf_km, epoch).expect("in range");
        assert!((b - r.b_gcrf_nt).norm() < 1e-9 * b.norm());
        assert!((r.sun_gcrf_unit.norm() - 1.0).abs() < 1e-15);
        assert!((0.0..=1.0).contains(&r.sun_fraction));
        // Orthonormal rotation.
        let rt_r = r.gcrf_to_itrf.transpose() * r.gcrf_to_itrf;
        assert!((rt_r - Matrix3::identity()).norm() < 1e-14);
    }

    /// A full 97-minute orbit of the RAX-2-like TLE is both sunlit and eclipsed
    /// (small beta angle, rax2-scenario.md): about 60 of 97 minutes in sunlight.
    #[test]
    fn rax2_orbit_has_the_papers_sunlit_share() {
        let m = model();
        let lit = (0..97 * 60)
            .step_by(10)
            .filter(|&t| m.at(t as f64).expect("in range").sun_fraction > 0.5)
            .count();
        let lit_min = lit as f64 * 10.0 / 60.0;
        assert!(
            (55.0..=68.0).contains(&lit_min),
            "sunlit {lit_min} min of 97"
        );
    }
}
