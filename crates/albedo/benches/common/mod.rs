//! The scene of the `albedo_17pd` benchmark, shared with `examples/profile.rs` (which
//! includes this file by path): 17 RAX-2 normals under a fixed attitude, 600 km, 30 deg from
//! the sub-solar point, and the TOMS mean map.

#![allow(dead_code)]

use nalgebra::{Matrix3, Rotation3, Vector3};
use pdcal_albedo::{AU_KM, ReflectivityMap, authalic_radius_km};

/// RAX-2 photodiode azimuth/elevation, deg (docs/rax2-scenario.md).
const AZ_EL_DEG: [(f64, f64); 17] = pdcal_attitude::RAX2_TABLE1_AZ_EL_DEG;

/// Satellite and Sun in GCRF, km; GCRF to ITRF; normals in GCRF; cosine of each FOV edge.
pub struct Scene {
    pub r_sat: Vector3<f64>,
    pub r_sun: Vector3<f64>,
    pub rot: Matrix3<f64>,
    pub normals: Vec<Vector3<f64>>,
    pub cos_fov: Vec<f64>,
}

/// The benchmark scene.
pub fn scene() -> Scene {
    let sun = Vector3::new(0.2, -0.9, 0.38).normalize();
    // Satellite 30 deg from the sub-solar point, 600 km altitude.
    let axis = sun.cross(&Vector3::z()).normalize();
    let sat = Rotation3::new(axis * 30f64.to_radians()) * sun;
    // Body to GCRF: an arbitrary attitude; n_gcrf = A^T n_body.
    let body_to_gcrf = Rotation3::new(Vector3::new(0.3, -0.5, 0.8).normalize() * 1.2);
    let normals = AZ_EL_DEG
        .iter()
        .map(|&(az, el): &(f64, f64)| {
            let (az, el) = (az.to_radians(), el.to_radians());
            body_to_gcrf * Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
        })
        .collect();
    Scene {
        r_sat: sat * (authalic_radius_km() + 600.0),
        r_sun: sun * AU_KM,
        // An Earth rotation angle of 40 deg about z (the crate takes any rotation).
        rot: Rotation3::from_axis_angle(&Vector3::z_axis(), 40f64.to_radians()).into_inner(),
        normals,
        cos_fov: vec![70f64.to_radians().cos(); 17],
    }
}

/// The TOMS mean reflectivity map shipped in `fixtures/albedo`.
pub fn toms_map() -> ReflectivityMap {
    ReflectivityMap::parse_toms_dat(
        "toms",
        include_str!("../../../../fixtures/albedo/earthReflectivityMean_1p25x1.dat"),
    )
    .expect("shipped map")
}
