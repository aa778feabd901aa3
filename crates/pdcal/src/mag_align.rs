//! The magnetometer's rotation against the body frame after `--mag-cal`
//! (docs/magcal.md, "The rotation against the body"): the field magnitude leaves the
//! rotational part of `T` unseen, so a calibration run's attitude carries the reference
//! field into the body frame and [`pdcal_magcal::align::solve`] finds the rotation between
//! it and the corrected magnetometer; the magnetometer is rotated back and the photodiodes
//! calibrated again.

use anyhow::Result;
use pdcal_dataset::Telemetry;
use pdcal_ephem::Reference;
use pdcal_filter::StepEstimate;
use pdcal_magcal::{AlignSample, Misalignment};

/// The rows whose attitude the photodiodes help determine: the Sun's whole disc in view.
/// In eclipse the attitude comes from the magnetometer and the gyro alone and follows the
/// magnetometer's own rotation, which would pull the estimate toward none.
fn sunlit(reference: &Reference) -> bool {
    reference.sun_fraction >= 1.0
}

/// One [`AlignSample`] per sunlit row with a magnetometer reading and an attitude estimate:
/// the reading against `A(q) B_ref`, with the variance of the magnetometer's noise
/// `mag_sigma_nt` and of the attitude's error across the field (the estimate's mean
/// variance about two axes times `|B|^2`, per axis).
pub fn samples(
    telemetry: &Telemetry,
    references: &[Reference],
    estimates: &[StepEstimate],
    mag_sigma_nt: f64,
) -> Vec<AlignSample> {
    let Some(mag) = telemetry.mag_nt.as_ref() else {
        return Vec::new();
    };
    estimates
        .iter()
        .filter_map(|e| {
            let reference = references.get(e.index)?;
            let measured_nt = (*mag.get(e.index)?)?;
            if !sunlit(reference) {
                return None;
            }
            let predicted_nt = e.q.to_body(&reference.b_gcrf_nt);
            let attitude_var_rad2 = e
                .attitude_sigma_deg
                .iter()
                .map(|s| s.to_radians().powi(2))
                .sum::<f64>()
                / 3.0;
            Some(AlignSample {
                measured_nt,
                predicted_nt,
                variance_nt2: mag_sigma_nt.powi(2)
                    + (2.0 / 3.0) * attitude_var_rad2 * predicted_nt.norm_squared(),
            })
        })
        .collect()
}

/// The misalignment of the run whose estimates are given (the smoothed ones when there are).
pub fn estimate(
    telemetry: &Telemetry,
    references: &[Reference],
    estimates: &[StepEstimate],
    mag_sigma_nt: f64,
) -> Result<Misalignment> {
    let samples = samples(telemetry, references, estimates, mag_sigma_nt);
    Ok(pdcal_magcal::align::solve(&samples)?)
}

/// Rotates every magnetometer reading into the body frame, `Q^T m`.
pub fn apply(telemetry: &mut Telemetry, misalignment: &Misalignment) {
    for m in telemetry.mag_nt.iter_mut().flatten().flatten() {
        *m = misalignment.to_body(m);
    }
}
