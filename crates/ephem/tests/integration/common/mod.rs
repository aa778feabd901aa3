//! Reading the reference tables of `fixtures/reference` (shared by the ephem tests).

#![allow(dead_code)]

use serde::Deserialize;
use serde::de::DeserializeOwned;

/// Every row of `fixtures/reference/<name>`; panics with the table's name on a bad row (the
/// fixtures are part of the repository: a failure here is a broken checkout).
pub fn reference_rows<T: DeserializeOwned>(name: &str) -> Vec<T> {
    let path = format!(
        "{}/../../fixtures/reference/{name}",
        env!("CARGO_MANIFEST_DIR")
    );
    let mut reader = csv::Reader::from_path(&path).unwrap_or_else(|e| panic!("{name} opens: {e}"));
    reader
        .deserialize()
        .collect::<Result<Vec<T>, _>>()
        .unwrap_or_else(|e| panic!("{name} parses: {e}"))
}

/// One row of `igrf_frames.csv` (skyfield, IAU 2006/2000A, true UT1, polar motion ignored):
/// a position and the IGRF field in ITRF and GCRF.
#[derive(Debug, Deserialize)]
pub struct FramesRow {
    pub id: u32,
    pub utc: String,
    pub x_ecef_km: f64,
    pub y_ecef_km: f64,
    pub z_ecef_km: f64,
    #[serde(rename = "Bx_ecef_nT")]
    pub bx_ecef_nt: f64,
    #[serde(rename = "By_ecef_nT")]
    pub by_ecef_nt: f64,
    #[serde(rename = "Bz_ecef_nT")]
    pub bz_ecef_nt: f64,
    pub x_gcrf_km: f64,
    pub y_gcrf_km: f64,
    pub z_gcrf_km: f64,
    #[serde(rename = "Bx_gcrf_nT")]
    pub bx_gcrf_nt: f64,
    #[serde(rename = "By_gcrf_nT")]
    pub by_gcrf_nt: f64,
    #[serde(rename = "Bz_gcrf_nT")]
    pub bz_gcrf_nt: f64,
    pub ut1_minus_utc_s: f64,
}
