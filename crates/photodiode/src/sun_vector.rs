//! The Sun vector measured by the photodiodes: least squares over the illuminated ones.
//!
//! Each illuminated photodiode gives one equation `(I_i - b_i)/(F C_i) = n_i^T s`, with `b_i`
//! a known additive part (albedo, dark offset) or 0 and `F = (1 AU / r_sun)^2` the Sun's
//! distance factor ([`SunVectorOptions::sun_distance_factor`]): `C_i` is the output at 1 AU
//! (paper Eq. 15 with the distance made explicit), so without `F` `|s|` would swing by 3 %
//! over the year. Stacking the `m` equations as `H s = y`
//! (`H` has the unit normals as rows) the estimate is `s = (H^T H)^-1 H^T y`, solved by
//! Cholesky on the 3x3 normal matrix. `s` is not normalised: with a perfect model and
//! calibration `|s| = 1`, so `|s|` is the quality metric of the paper's Figs. 8-10.
//!
//! A photodiode counts as illuminated when `I_i - b_i > threshold` (default three times its
//! `noise_v`, so noise alone rarely lights a dark sensor). The geometry is observable when at
//! least 3 are illuminated and the smallest singular value of `H`, `sqrt(lambda_min(H^T H))`,
//! is at least `min_singular_value` (default 0.1): a relative output error `e` then moves `s`
//! by at most about `e / 0.1`, ten times the per-sensor error; coplanar normals give
//! `sigma_min` = 0 up to rounding.
//!
//! A photodiode whose normal faces away from the estimated Sun (`n_i^T s <= 0`) cannot be
//! lit by the Sun: its output is Earth albedo or another unmodelled light, and keeping its
//! equation drags `s` toward it (on raw outputs in LEO this shrinks `|s|` to 0.3-0.6). With
//! `reject_backfacing` (default on) such photodiodes are dropped and the solution repeated,
//! at most [`MAX_BACKFACING_PASSES`] times.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

use crate::{Photodiode, PhotodiodeError};

/// When a photodiode counts as illuminated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LitThreshold {
    /// Corrected output above this many times the photodiode's `noise_v`.
    NoiseSigmas(f64),
    /// Corrected output above this many volts.
    Volts(f64),
}

impl LitThreshold {
    /// The threshold in volts for a photodiode of noise sigma `noise_v`.
    pub fn volts(&self, noise_v: f64) -> f64 {
        match *self {
            LitThreshold::NoiseSigmas(k) => k * noise_v,
            LitThreshold::Volts(v) => v,
        }
    }
}

/// Options of [`estimate_sun_vector`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SunVectorOptions {
    /// Illumination threshold; default `NoiseSigmas(3.0)`.
    pub threshold: LitThreshold,
    /// Smallest acceptable singular value of the stacked unit normals; default 0.1.
    pub min_singular_value: f64,
    /// Drop photodiodes facing away from the solution and solve again; default true.
    pub reject_backfacing: bool,
    /// `(1 AU / r_sun)^2` at the sample (the direct irradiance relative to 1 AU, where the
    /// scale factors are defined); default 1.
    pub sun_distance_factor: f64,
}

/// Most re-solutions after dropping back-facing photodiodes.
pub const MAX_BACKFACING_PASSES: usize = 3;

impl Default for SunVectorOptions {
    fn default() -> Self {
        SunVectorOptions {
            threshold: LitThreshold::NoiseSigmas(3.0),
            min_singular_value: 0.1,
            reject_backfacing: true,
            sun_distance_factor: 1.0,
        }
    }
}

/// An observable Sun vector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SunVector {
    /// Least-squares Sun vector, body frame, not normalised.
    pub vector_body: Vector3<f64>,
    /// Its unit direction.
    pub direction_body: Vector3<f64>,
    /// Number of illuminated photodiodes used.
    pub used: usize,
    /// Smallest singular value of the stacked normals.
    pub min_singular_value: f64,
}

/// Why the Sun vector is not observable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NotObservableReason {
    /// Fewer than 3 photodiodes illuminated.
    TooFewLit,
    /// The illuminated normals are (nearly) coplanar.
    DegenerateGeometry {
        /// Smallest singular value found.
        min_singular_value: f64,
    },
    /// The solution is zero or not finite.
    NoDirection,
}

/// Result of [`estimate_sun_vector`]: a vector, or an explicit "not observable".
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SunEstimate {
    /// Enough well-spread illuminated photodiodes.
    Observable(SunVector),
    /// No estimate.
    NotObservable {
        /// Number of illuminated photodiodes.
        used: usize,
        /// Why.
        reason: NotObservableReason,
    },
}

impl SunEstimate {
    /// The unit Sun direction, body frame, when observable.
    pub fn direction_body(&self) -> Option<Vector3<f64>> {
        match self {
            SunEstimate::Observable(s) => Some(s.direction_body),
            SunEstimate::NotObservable { .. } => None,
        }
    }
}

/// Least-squares Sun vector from photodiode outputs `outputs_v` (one per photodiode), after
/// subtracting `known_v` (albedo, offsets; one per photodiode) when given.
pub fn estimate_sun_vector(
    photodiodes: &[Photodiode],
    outputs_v: &[f64],
    known_v: Option<&[f64]>,
    options: &SunVectorOptions,
) -> Result<SunEstimate, PhotodiodeError> {
    check_len("outputs_v", photodiodes.len(), outputs_v.len())?;
    if let Some(known) = known_v {
        check_len("known_v", photodiodes.len(), known.len())?;
    }
    let factor = options.sun_distance_factor;
    if !(factor > 0.0 && factor.is_finite()) {
        return Err(PhotodiodeError::BadValue {
            what: "sun_distance_factor".into(),
            value: factor,
            rule: "the Sun's distance factor must be positive and finite",
        });
    }
    let mut lit = Vec::with_capacity(photodiodes.len());
    for (i, (pd, &output)) in photodiodes.iter().zip(outputs_v).enumerate() {
        if !(pd.scale_v > 0.0 && pd.scale_v.is_finite()) {
            return Err(PhotodiodeError::BadValue {
                what: format!("photodiode {} scale_v", i + 1),
                value: pd.scale_v,
                rule: "scale factor must be positive and finite",
            });
        }
        let direct = output - known_v.map_or(0.0, |k| k[i]);
        let threshold = options.threshold.volts(pd.noise_v);
        lit.push((direct > threshold).then_some(direct / (factor * pd.scale_v)));
    }
    let mut estimate = solve(photodiodes, &lit, options);
    for _ in 0..MAX_BACKFACING_PASSES {
        let SunEstimate::Observable(s) = &estimate else {
            break;
        };
        if !options.reject_backfacing {
            break;
        }
        let mut dropped = false;
        for (pd, y) in photodiodes.iter().zip(lit.iter_mut()) {
            if y.is_some() && pd.n_body.dot(&s.direction_body) <= 0.0 {
                *y = None;
                dropped = true;
            }
        }
        if !dropped {
            break;
        }
        estimate = solve(photodiodes, &lit, options);
    }
    Ok(estimate)
}

/// Least squares over the photodiodes with `Some(relative output)`.
fn solve(
    photodiodes: &[Photodiode],
    lit: &[Option<f64>],
    options: &SunVectorOptions,
) -> SunEstimate {
    let mut normal_matrix = Matrix3::zeros();
    let mut rhs = Vector3::zeros();
    let mut used = 0;
    for (pd, y) in photodiodes.iter().zip(lit) {
        if let Some(y) = y {
            normal_matrix += pd.n_body * pd.n_body.transpose();
            rhs += pd.n_body * *y;
            used += 1;
        }
    }
    if used < 3 {
        return SunEstimate::NotObservable {
            used,
            reason: NotObservableReason::TooFewLit,
        };
    }
    let min_singular_value = SymmetricEigen::new(normal_matrix)
        .eigenvalues
        .min()
        .max(0.0)
        .sqrt();
    if min_singular_value < options.min_singular_value {
        return SunEstimate::NotObservable {
            used,
            reason: NotObservableReason::DegenerateGeometry { min_singular_value },
        };
    }
    let solution = normal_matrix.cholesky().map(|c| c.solve(&rhs));
    let Some((vector_body, direction_body)) = solution
        .filter(|s| s.iter().all(|x| x.is_finite()))
        .and_then(|s| s.try_normalize(0.0).map(|d| (s, d)))
    else {
        return SunEstimate::NotObservable {
            used,
            reason: NotObservableReason::NoDirection,
        };
    };
    SunEstimate::Observable(SunVector {
        vector_body,
        direction_body,
        used,
        min_singular_value,
    })
}

fn check_len(what: &'static str, expected: usize, found: usize) -> Result<(), PhotodiodeError> {
    if expected == found {
        Ok(())
    } else {
        Err(PhotodiodeError::LengthMismatch {
            what,
            expected,
            found,
        })
    }
}
