//! What is checked before and after the fit (docs/magcal.md, "Screening"): the field's
//! size against the reference (a unit mix-up is refused, not fitted), rows whose current or
//! magnitude no calibration could explain (screened out and listed with their cause), a
//! regressor whose variation rests on a few rows (not tested), and a result no CubeSat's
//! magnetometer could have (refused).

use nalgebra::{Matrix3, Vector3};

use crate::MagCalError;
use crate::fit::Sample;

/// The smallest and largest scale factor of a magnetometer (the singular values of `T`):
/// datasheet sensitivities hold to a few percent and a structure's soft iron changes them
/// by tens of percent, so a factor of two either way is a unit or a model failure.
pub const SCALE_RANGE: (f64, f64) = (0.5, 2.0);

/// The largest hard-iron bias, or current-driven bias at 1 A, a CubeSat magnetometer can
/// read, nT: 1 mT (10 G) is beyond the full range of the magnetometers flown (about
/// 0.1-0.8 mT), so a larger bias is not a reading but a failed fit.
pub const MAX_BIAS_NT: f64 = 1.0e6;

/// How many of a current column's spreads (the width of its central 98 % or 1.4826 times
/// its median absolute deviation, the larger) from its median make a value impossible.
pub const CURRENT_SPREADS: f64 = 10.0;

/// How many robust sigmas of the raw magnitude residual `|m| - |H|` from its median a row
/// must lie before the fit to be screened out (it must also miss by half the field).
pub const MAGNITUDE_SIGMAS: f64 = 10.0;

/// Rows' worth of variation a regressor needs per coefficient (three per regressor), as
/// the fit needs rows per parameter: fewer, and its evidence is a glitch's, not an effect's.
pub const ROWS_PER_COEFFICIENT: f64 = 3.0;

/// A row screened out before the fit, with its cause.
#[derive(Debug, Clone, PartialEq)]
pub struct ScreenedRow {
    /// 0-based telemetry row.
    pub row: usize,
    /// Why (the column and its value against the column's history).
    pub cause: String,
}

/// Refuses samples whose field is not in nT: the median of `|m| / |H|` outside what a
/// scale in [`SCALE_RANGE`] and a bias up to [`MAX_BIAS_NT`] can give.
pub fn check_field_size(samples: &[Sample]) -> Result<(), MagCalError> {
    let mut ratios: Vec<f64> = (samples.iter())
        .map(|s| s.mag_nt.norm() / s.field_nt)
        .filter(|r| r.is_finite())
        .collect();
    let mut fields: Vec<f64> = samples.iter().map(|s| s.field_nt).collect();
    let (Some(ratio), Some(field_nt)) = (median(&mut ratios), median(&mut fields)) else {
        return Ok(());
    };
    let (low, high) = (SCALE_RANGE.0 / 2.5, SCALE_RANGE.1 + MAX_BIAS_NT / field_nt);
    if (low..=high).contains(&ratio) {
        return Ok(());
    }
    Err(MagCalError::FieldSize {
        ratio,
        field_nt,
        likely_unit: likely_unit(ratio),
    })
}

/// The unit whose values read `ratio` times nT's, when one is within a factor of 3.
fn likely_unit(ratio: f64) -> Option<&'static str> {
    const UNITS: [(&str, f64); 6] = [
        ("uT", 1e-3),
        ("mG", 1e-2),
        ("G", 1e-5),
        ("T", 1e-9),
        ("mT", 1e-6),
        ("pT", 1e3),
    ];
    (UNITS.iter())
        .find(|(_, r)| (ratio / r).ln().abs() < 3f64.ln())
        .map(|(name, _)| *name)
}

/// Rows no calibration could explain: a current beyond [`CURRENT_SPREADS`] of its
/// column's history, or a raw magnitude residual beyond [`MAGNITUDE_SIGMAS`] robust sigmas
/// of the others and half the field (a hard-iron bias shifts every row alike and a current's
/// bias moves rows by hundreds to thousands of nT, not by the Earth's field). Increasing rows.
pub fn screen(samples: &[Sample], names: &[String]) -> Vec<ScreenedRow> {
    let mut out: Vec<ScreenedRow> = Vec::new();
    for (j, name) in names.iter().enumerate() {
        let mut values: Vec<f64> = samples.iter().map(|s| s.u[j]).collect();
        let Some((centre, spread)) = centre_and_spread(&mut values) else {
            continue;
        };
        if spread <= 0.0 {
            continue;
        }
        for s in samples {
            let u = s.u[j];
            if u.is_finite() && (u - centre).abs() > CURRENT_SPREADS * spread {
                out.push(ScreenedRow {
                    row: s.row,
                    cause: format!(
                        "{name} = {u} A, more than {CURRENT_SPREADS} times its spread ({spread:.3} A) from its median {centre:.3} A"
                    ),
                });
            }
        }
    }
    let mut residuals: Vec<f64> = samples
        .iter()
        .map(|s| s.mag_nt.norm() - s.field_nt)
        .collect();
    let mut fields: Vec<f64> = samples.iter().map(|s| s.field_nt).collect();
    if let (Some((centre, sigma)), Some(field_nt)) =
        (robust(&mut residuals.clone()), median(&mut fields))
    {
        let bound = (MAGNITUDE_SIGMAS * sigma).max(0.5 * field_nt);
        for (s, r) in samples.iter().zip(residuals.iter_mut()) {
            if !r.is_finite() || (*r - centre).abs() > bound {
                out.push(ScreenedRow {
                    row: s.row,
                    cause: format!(
                        "|m| = {:.0} nT against the reference {:.0} nT, {:.0} nT from the rows' median residual {centre:.0} nT (beyond {bound:.0} nT)",
                        s.mag_nt.norm(),
                        s.field_nt,
                        *r - centre
                    ),
                });
            }
        }
    }
    out.sort_by_key(|s| s.row);
    out.dedup_by_key(|s| s.row);
    out
}

/// Why regressor `j` is not tested: its variation rests on fewer rows than
/// [`ROWS_PER_COEFFICIENT`] per coefficient. The rows' worth is the effective count
/// `(sum d^2)^2 / sum d^4` of the deviations `d` from the mean: about the rows that differ
/// from the rest (a square wave's high rows, every row of a smooth signal, one for a glitch).
pub fn few_rows_reason(samples: &[Sample], j: usize) -> Option<String> {
    let n = samples.len().max(1) as f64;
    let mean = samples.iter().map(|s| s.u[j]).sum::<f64>() / n;
    let (s2, s4) = samples.iter().fold((0.0, 0.0), |(s2, s4), s| {
        let d2 = (s.u[j] - mean).powi(2);
        (s2 + d2, s4 + d2 * d2)
    });
    let rows = s2 * s2 / s4;
    let needed = 3.0 * ROWS_PER_COEFFICIENT;
    (rows.is_finite() && rows < needed).then(|| {
        format!(
            "its variation rests on {rows:.1} rows' worth of samples, fewer than {needed:.0} (three per coefficient): a few rows cannot tell an effect from a glitch"
        )
    })
}

/// Why a calibration is not a magnetometer's: a scale factor of `matrix` outside
/// [`SCALE_RANGE`], or a bias (hard iron, or a current's per ampere) beyond [`MAX_BIAS_NT`].
pub fn not_physical(
    matrix: &Matrix3<f64>,
    bias_nt: &Vector3<f64>,
    coeff_nt: &[(String, Vector3<f64>)],
) -> Option<String> {
    let scales = matrix.singular_values();
    let (lo, hi) = (scales.min(), scales.max());
    if !(lo >= SCALE_RANGE.0 && hi <= SCALE_RANGE.1) {
        return Some(format!(
            "T's scale factors run from {lo:.3} to {hi:.3}, outside the {}-{} of any magnetometer (T is a rotation times a scale near 1)",
            SCALE_RANGE.0, SCALE_RANGE.1
        ));
    }
    // Written so that NaN fails too.
    let within = |nt: f64| (0.0..=MAX_BIAS_NT).contains(&nt);
    if !within(bias_nt.norm()) {
        return Some(format!(
            "the hard-iron bias is {:.0} nT, beyond the {MAX_BIAS_NT:.0} nT (1 mT) any CubeSat magnetometer reads",
            bias_nt.norm()
        ));
    }
    for (name, c) in coeff_nt {
        if !within(c.norm()) {
            return Some(format!(
                "the bias driven by {name} is {:.0} nT per A, beyond the {MAX_BIAS_NT:.0} nT (1 mT) any CubeSat magnetometer reads",
                c.norm()
            ));
        }
    }
    None
}

/// The median and the spread of a current column: the width of its central 98 % or its
/// robust sigma, the larger (a square wave's MAD is 0; a smooth signal's width is its range).
fn centre_and_spread(values: &mut [f64]) -> Option<(f64, f64)> {
    let mut finite: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    let (centre, sigma) = robust(&mut finite.clone())?;
    finite.sort_by(f64::total_cmp);
    let at = |p: f64| finite[((finite.len() - 1) as f64 * p).round() as usize];
    Some((centre, (at(0.99) - at(0.01)).max(sigma)))
}

/// The median and 1.4826 times the median absolute deviation of the finite `values`.
fn robust(values: &mut [f64]) -> Option<(f64, f64)> {
    let mut finite: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    let centre = median(&mut finite)?;
    for x in &mut finite {
        *x = (*x - centre).abs();
    }
    Some((centre, 1.4826 * median(&mut finite)?))
}

fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    Some(if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(row: usize, u: f64) -> Sample {
        Sample {
            row,
            t_s: row as f64,
            mag_nt: Vector3::new(30000.0, 0.0, 0.0),
            field_nt: 30000.0,
            u: vec![u],
        }
    }

    /// A square wave high on 5 % of the rows is neither screened nor too few rows; one
    /// glitch is both.
    #[test]
    fn a_square_wave_is_evidence_and_a_glitch_is_not() {
        let wave: Vec<Sample> = (0..1200)
            .map(|k| sample(k, if k % 20 == 0 { 0.2 } else { 0.0 }))
            .collect();
        assert!(screen(&wave, &["cur_tq_A".into()]).is_empty());
        assert!(few_rows_reason(&wave, 0).is_none());
        let glitch: Vec<Sample> = (0..1200)
            .map(|k| sample(k, if k == 600 { 100.0 } else { 0.0 }))
            .collect();
        assert!(few_rows_reason(&glitch, 0).is_some());
        let mut smooth: Vec<Sample> = (0..1200)
            .map(|k| sample(k, 0.25 + 0.25 * (k as f64 / 100.0).sin()))
            .collect();
        smooth[600].u[0] = 100.0;
        let screened = screen(&smooth, &["cur_px_A".into()]);
        assert_eq!(screened.len(), 1, "{screened:?}");
        assert_eq!(screened[0].row, 600);
    }

    #[test]
    fn units_are_named_and_a_rotation_with_small_scale_errors_is_physical() {
        assert_eq!(likely_unit(1.02e-3), Some("uT"));
        assert_eq!(likely_unit(0.9), None);
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 1.1).into_inner();
        let t = r * Matrix3::from_diagonal(&Vector3::new(1.04, 0.97, 1.01));
        assert!(not_physical(&t, &Vector3::new(4000.0, -3000.0, 2000.0), &[]).is_none());
        let stretched = Matrix3::from_diagonal(&Vector3::new(109.0, 148.0, 26.0));
        assert!(not_physical(&stretched, &Vector3::zeros(), &[]).is_some());
        let far = Vector3::new(4.5e6, 0.0, 0.0);
        assert!(not_physical(&Matrix3::identity(), &far, &[]).is_some());
    }
}
