//! The magnetometer's rotation against the body frame after `--mag-cal`
//! (docs/magcal.md, "The rotation against the body"): the field magnitude leaves the
//! rotational part of `T` unseen, so a calibration run's attitude carries the reference
//! field into the body frame and [`pdcal_magcal::align::solve`] finds the rotation between
//! it and the corrected magnetometer; the magnetometer is rotated back and the photodiodes
//! calibrated again.

use anyhow::Result;
use nalgebra::Matrix3;
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

/// The estimate's attitude covariance about the body axes, rad^2.
fn attitude_cov_rad2(e: &StepEstimate) -> Matrix3<f64> {
    let [sx, sy, sz] = e.attitude_sigma_deg.map(|s| s * s);
    let [xy, xz, yz] = e.attitude_cov_offdiag_deg2;
    Matrix3::new(sx, xy, xz, xy, sy, yz, xz, yz, sz) * DEG.powi(2)
}

const DEG: f64 = std::f64::consts::PI / 180.0;

/// One [`AlignSample`] per sunlit row with a magnetometer reading and an attitude estimate:
/// the reading against `A(q) B_ref`, with the magnetometer's noise `mag_sigma_nt` and the
/// estimate's attitude covariance.
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
            let measured_nt = mag.get(e.index)?;
            if !sunlit(reference) {
                return None;
            }
            Some(AlignSample {
                measured_nt,
                predicted_nt: e.q.to_body(&reference.b_gcrf_nt),
                variance_nt2: mag_sigma_nt.powi(2),
                attitude_cov_rad2: attitude_cov_rad2(e),
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
    if let Some(mag) = telemetry.mag_nt.as_mut() {
        mag.map_in_place(|m| misalignment.to_body(&m));
    }
}

/// The rotation found against the photodiodes' own frame, and what it adds to the
/// magnetometer's noise.
#[derive(Debug, Clone)]
pub struct PhotodiodeAlignment {
    /// The rotation (`None` when it could not be solved), removed from the telemetry unless
    /// `refused`.
    pub misalignment: Option<Misalignment>,
    /// Why the rotation was left in (`None`: removed).
    pub refused: Option<String>,
    /// The rotation's uncertainty as noise per magnetometer axis, nT (0 when refused):
    /// `sqrt((2/3) tr(Cov) / 3) |B|_rms`.
    pub sigma_nt: f64,
}

impl PhotodiodeAlignment {
    /// Whether the rotation was removed from the telemetry.
    pub fn applied(&self) -> bool {
        self.refused.is_none()
    }
}

/// `r^T C^-1 r / 3` beyond which the photodiode-only attitude does not describe the
/// corrected magnetometer up to one rotation (a mirror attitude, a lost segment, a sensor
/// that is not rigid): the rotation is then not applied. Three times the noise the
/// covariances give.
const MAX_NORMALIZED_RESIDUAL: f64 = 9.0;

/// The rotation an uncalibrated magnetometer may have against the body before any attitude
/// is used, deg: its mounting and the antisymmetric part of its non-orthogonality, a few
/// degrees. The fit's sigma is judged against it by the calibration's own rule
/// ([`pdcal_filter::identifiability::CALIBRATED_SIGMA_RATIO`]): a rotation whose sigma on
/// some axis exceeds that fraction of it is not determined and not applied.
pub const ROTATION_PRIOR_DEG: f64 = 5.0;

/// Why `m` should not be applied, if it should not.
fn refusal(m: &Misalignment) -> Option<String> {
    let limit_deg = pdcal_filter::identifiability::CALIBRATED_SIGMA_RATIO * ROTATION_PRIOR_DEG;
    let sigma_deg = m.sigma_rad().max().to_degrees();
    if m.normalized_residual > MAX_NORMALIZED_RESIDUAL {
        Some(format!(
            "the residuals are {:.1} times what the noise and the attitude covariance give (beyond {MAX_NORMALIZED_RESIDUAL}): the photodiode-only attitude does not describe the magnetometer up to one rotation",
            m.normalized_residual
        ))
    } else if sigma_deg > limit_deg {
        Some(format!(
            "its sigma ({sigma_deg:.2} deg on the worst axis) exceeds {limit_deg:.1} deg ({} of the {ROTATION_PRIOR_DEG} deg a magnetometer may be turned): the photodiode-only attitude does not determine it",
            pdcal_filter::identifiability::CALIBRATED_SIGMA_RATIO
        ))
    } else {
        None
    }
}

/// The magnetometer's rotation against the body frame as the gyro and the photodiodes
/// define it, without the magnetometer (docs/magcal.md, "Against the photodiodes alone"):
/// `photodiode_only` calibrates the rows with the magnetometer removed (its attitude does not
/// turn with the magnetometer) and returns its estimates (the smoothed ones when there are),
/// against which [`pdcal_magcal::align::solve_gated`] finds the rotation of the corrected
/// magnetometer (noise `mag_sigma_nt` per axis); `telemetry`'s magnetometer is rotated back
/// when the fit is consistent and determined. A photodiode-only run or a fit that fails is a
/// refusal with its reason, not an error: the calibration then goes on with the rotation in.
pub fn against_photodiodes(
    telemetry: &mut Telemetry,
    references: &[Reference],
    mag_sigma_nt: f64,
    photodiode_only: impl FnOnce(&Telemetry) -> Result<Vec<StepEstimate>>,
) -> Result<PhotodiodeAlignment> {
    let mut without_mag = telemetry.clone();
    without_mag.mag_nt = None;
    let solved = photodiode_only(&without_mag).and_then(|estimates| {
        let samples = samples(telemetry, references, &estimates, mag_sigma_nt);
        let misalignment = pdcal_magcal::align::solve_gated(&samples)?;
        let field_ms = samples
            .iter()
            .map(|s| s.predicted_nt.norm_squared())
            .sum::<f64>()
            / samples.len().max(1) as f64;
        Ok((misalignment, field_ms))
    });
    let (misalignment, field_ms) = match solved {
        Ok(found) => found,
        Err(e) => {
            return Ok(PhotodiodeAlignment {
                misalignment: None,
                refused: Some(format!("not solved: {e:#}")),
                sigma_nt: 0.0,
            });
        }
    };
    let refused = refusal(&misalignment);
    let sigma_nt = if refused.is_none() {
        apply(telemetry, &misalignment);
        ((2.0 / 3.0) * misalignment.covariance_rad2.trace() / 3.0 * field_ms).sqrt()
    } else {
        0.0
    };
    Ok(PhotodiodeAlignment {
        misalignment: Some(misalignment),
        refused,
        sigma_nt,
    })
}

/// One line for the user: the rotation with its sigma, the rows, and whether it was removed.
pub fn describe(alignment: &PhotodiodeAlignment) -> String {
    let deg = |v: nalgebra::Vector3<f64>| {
        let v = v.map(f64::to_degrees);
        format!("({:.3}, {:.3}, {:.3})", v.x, v.y, v.z)
    };
    let verdict = match &alignment.refused {
        None => format!(
            "removed; its uncertainty adds {:.0} nT to the magnetometer's noise",
            alignment.sigma_nt
        ),
        Some(why) => format!("NOT removed: {why}"),
    };
    match &alignment.misalignment {
        Some(m) => format!(
            "magnetometer rotation against the photodiode-only attitude: {} deg +- {} deg (rotation vector, sensor from body), {} sunlit rows, {} left out as outliers: {verdict}",
            deg(m.angles_rad),
            deg(m.sigma_rad()),
            m.rows,
            m.rows_rejected
        ),
        None => format!("magnetometer rotation against the photodiode-only attitude: {verdict}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    fn misalignment(sigma_deg: f64, normalized_residual: f64) -> Misalignment {
        Misalignment {
            rotation: Matrix3::identity(),
            angles_rad: Vector3::zeros(),
            covariance_rad2: Matrix3::identity() * (sigma_deg * DEG).powi(2),
            rows: 100,
            residual_rms_nt: 300.0,
            rows_rejected: 0,
            normalized_residual,
        }
    }

    /// Applied when consistent and determined; refused, with the reason, when the residuals
    /// are beyond three times the noise or the sigma beyond 0.2 of the prior (1 deg).
    #[test]
    fn a_rotation_is_refused_when_inconsistent_or_not_determined() {
        assert_eq!(refusal(&misalignment(0.05, 1.2)), None);
        assert_eq!(refusal(&misalignment(0.99, 8.9)), None);
        let inconsistent = refusal(&misalignment(0.05, 9.5)).expect("refused");
        assert!(inconsistent.contains("9.5 times"), "{inconsistent}");
        let undetermined = refusal(&misalignment(1.01, 1.0)).expect("refused");
        assert!(undetermined.contains("1.01 deg"), "{undetermined}");
    }
}
