//! Shared helpers for the integration tests: the reference table reader, random normals.
#![allow(dead_code, missing_docs)]

use std::collections::HashMap;

use nalgebra::{Matrix3, Vector3};

/// One row of `fixtures/reference/albedo_reference.csv`, by column name.
pub struct RefRow(pub HashMap<String, String>);

impl RefRow {
    pub fn f(&self, key: &str) -> f64 {
        self.0[key]
            .parse()
            .unwrap_or_else(|_| panic!("column {key}"))
    }
    pub fn v3(&self, prefix: [&str; 3]) -> Vector3<f64> {
        Vector3::new(self.f(prefix[0]), self.f(prefix[1]), self.f(prefix[2]))
    }
    pub fn id(&self) -> usize {
        self.0["id"].parse().unwrap()
    }
    pub fn r_sat_gcrf(&self) -> Vector3<f64> {
        self.v3(["x_sat_gcrf_km", "y_sat_gcrf_km", "z_sat_gcrf_km"])
    }
    pub fn r_sun_gcrf(&self) -> Vector3<f64> {
        self.v3(["x_sun_gcrf_km", "y_sun_gcrf_km", "z_sun_gcrf_km"])
    }
    pub fn n_gcrf(&self) -> Vector3<f64> {
        self.v3(["nx_gcrf", "ny_gcrf", "nz_gcrf"])
    }
    pub fn r_sat_ecef(&self) -> Vector3<f64> {
        self.v3(["x_sat_ecef_km", "y_sat_ecef_km", "z_sat_ecef_km"])
    }
    pub fn r_sun_ecef(&self) -> Vector3<f64> {
        self.v3(["x_sun_ecef_km", "y_sun_ecef_km", "z_sun_ecef_km"])
    }
    pub fn n_ecef(&self) -> Vector3<f64> {
        self.v3(["nx_ecef", "ny_ecef", "nz_ecef"])
    }
    /// GCRF -> ECEF rotation, given row-major as R11..R33.
    pub fn rotation(&self) -> Matrix3<f64> {
        let mut m = Matrix3::zeros();
        for r in 0..3 {
            for c in 0..3 {
                m[(r, c)] = self.f(&format!("R{}{}", r + 1, c + 1));
            }
        }
        m
    }
}

pub fn reference_rows() -> Vec<RefRow> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../fixtures/reference/albedo_reference.csv"
    );
    let mut reader = csv::Reader::from_path(path).expect("reference table");
    let headers = reader.headers().expect("header").clone();
    reader
        .records()
        .map(|rec| {
            let rec = rec.expect("record");
            RefRow(
                headers
                    .iter()
                    .zip(rec.iter())
                    .map(|(h, v)| (h.into(), v.into()))
                    .collect(),
            )
        })
        .collect()
}

/// A uniformly random unit vector (rejection from the cube; norms below 0.1 are rejected
/// too, so that the division stays well conditioned).
pub fn random_unit(rng: &mut rand::rngs::StdRng) -> nalgebra::Vector3<f64> {
    use rand::RngExt;
    loop {
        let v = nalgebra::Vector3::new(
            rng.random::<f64>() * 2.0 - 1.0,
            rng.random::<f64>() * 2.0 - 1.0,
            rng.random::<f64>() * 2.0 - 1.0,
        );
        let n = v.norm();
        if n > 0.1 && n <= 1.0 {
            return v / n;
        }
    }
}
