//! The rows of the CSV outputs of `docs/cli-contract.md`: `estimates.csv` (also read back by
//! `evaluate`) and `residuals.csv`, their headers and one row of each.

use anyhow::{Context, Result};
use pdcal_filter::{ResidualRecord, Sensor, StepEstimate};

/// The first columns of `estimates.csv`: time, attitude and its sigmas (written here, read
/// back by `evaluate`).
pub const ESTIMATE_LEADING_COLUMNS: [&str; 8] = [
    "t_s",
    "q_x",
    "q_y",
    "q_z",
    "q_w",
    "att_sigma_x_deg",
    "att_sigma_y_deg",
    "att_sigma_z_deg",
];

/// Column names of `estimates.csv` for `m` photodiodes and the extra parameters.
pub fn estimate_header(m: usize, parameters: &[String]) -> Vec<String> {
    let mut h: Vec<String> = ESTIMATE_LEADING_COLUMNS.map(String::from).to_vec();
    for axis in ["x", "y", "z"] {
        h.push(format!("gyro_bias_{axis}_rad_s"));
    }
    for axis in ["x", "y", "z"] {
        h.push(format!("gyro_bias_sigma_{axis}_rad_s"));
    }
    for i in 1..=m {
        for q in [
            "scale_V",
            "scale_sigma_V",
            "azimuth_deg",
            "azimuth_sigma_deg",
            "elevation_deg",
            "elevation_sigma_deg",
        ] {
            h.push(format!("pd{i:02}_{q}"));
        }
    }
    for p in parameters {
        h.push(p.clone());
        h.push(format!("{p}_sigma"));
    }
    h.push("segment".to_owned());
    h.extend(ATTITUDE_COV_COLUMNS.map(String::from));
    h
}

/// The trailing columns of `estimates.csv`: the attitude covariance off the diagonal.
pub const ATTITUDE_COV_COLUMNS: [&str; 3] =
    ["att_cov_xy_deg2", "att_cov_xz_deg2", "att_cov_yz_deg2"];

/// One `estimates.csv` row.
pub fn estimate_row(e: &StepEstimate) -> Vec<String> {
    let f = |x: f64| format!("{x:?}");
    let c = &e.calibration;
    let mut row = vec![f(e.t_s), f(e.q.x), f(e.q.y), f(e.q.z), f(e.q.w)];
    row.extend(e.attitude_sigma_deg.iter().map(|&x| f(x)));
    row.extend(c.gyro_bias_rad_s.iter().map(|&x| f(x)));
    row.extend(c.gyro_bias_sigma_rad_s.iter().map(|&x| f(x)));
    for p in &c.photodiodes {
        row.extend([f(p.scale_v), f(p.scale_sigma_v), f(p.azimuth_deg)]);
        row.push(p.azimuth_sigma_deg.map(f).unwrap_or_default());
        row.extend([f(p.elevation_deg), f(p.elevation_sigma_deg)]);
    }
    for p in &c.parameters {
        row.extend([f(p.value), f(p.sigma)]);
    }
    row.push(e.segment.to_string());
    row.extend(e.attitude_cov_offdiag_deg2.iter().map(|&x| f(x)));
    row
}

/// `estimates.csv` text: one row per filter step.
pub fn estimates_csv(estimates: &[StepEstimate], m: usize) -> Result<Vec<u8>> {
    let names: Vec<String> = estimates
        .first()
        .map(|e| {
            e.calibration
                .parameters
                .iter()
                .map(|p| p.name.clone())
                .collect()
        })
        .unwrap_or_default();
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(estimate_header(m, &names))?;
    for e in estimates {
        w.write_record(estimate_row(e))?;
    }
    w.into_inner().context("estimates.csv")
}

/// The sensor column of `residuals.csv`: `pd03`, `mag_x`.
pub fn sensor_name(sensor: Sensor) -> String {
    match sensor {
        Sensor::Photodiode(i) => format!("pd{:02}", i + 1),
        Sensor::Magnetometer(axis) => format!("mag_{}", ["x", "y", "z"][axis.min(2)]),
    }
}

/// The columns of `residuals.csv`.
pub const RESIDUAL_COLUMNS: [&str; 6] = [
    "t_s",
    "sensor",
    "measured",
    "residual",
    "bound_3sigma",
    "accepted",
];

/// One `residuals.csv` row.
pub fn residual_row(r: &ResidualRecord) -> [String; 6] {
    [
        format!("{:?}", r.t_s),
        sensor_name(r.sensor),
        format!("{:?}", r.measured),
        format!("{:?}", r.residual),
        format!("{:?}", r.bound_3sigma),
        r.accepted.to_string(),
    ]
}

/// `residuals.csv` text: one row per scalar update.
pub fn residuals_csv(residuals: &[ResidualRecord]) -> Result<Vec<u8>> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(RESIDUAL_COLUMNS)?;
    for r in residuals {
        w.write_record(residual_row(r))?;
    }
    w.into_inner().context("residuals.csv")
}
