//! Attitude from pairs of (body, reference) unit vectors: Davenport's q-method (the
//! paper's initialiser, Sec. IV) and TRIAD.
//!
//! Both solve `v_body ≈ A v_ref` for the attitude matrix `A` of the crate's
//! convention; inputs need not be unit vectors (they are normalised here).
//! Sources: Markley & Crassidis 2014, Ch. 5 (TRIAD; Wahba's problem and Davenport's
//! q-method); Shuster & Oh, "Three-axis attitude
//! determination from vector observations", JGCD 4(1), 1981 (QUEST and TRIAD
//! covariances, used by the tests).

use nalgebra::{Matrix3, Matrix4, SymmetricEigen, Vector3};

use crate::{AttitudeError, Quat};

/// Smallest `|u_i x u_j|` (sine of the angle between unit vectors) counted as
/// non-parallel: about 0.2 arcsec. Below it the rotation about the common direction is
/// determined by noise, not by the geometry.
pub const PARALLEL_TOLERANCE: f64 = 1e-6;

/// Smallest gap between K's two largest eigenvalues, relative to the sum of weights,
/// for the q-method solution to count as unique.
pub const EIGEN_GAP_TOLERANCE: f64 = 1e-12;

/// One observation: the same physical direction in body and reference frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VectorPair {
    /// Direction measured in the body frame (any non-zero length).
    pub body: Vector3<f64>,
    /// The same direction in the reference (inertial, GCRF) frame (any non-zero length).
    pub reference: Vector3<f64>,
    /// Weight in Wahba's loss, e.g. `1/sigma^2` (positive; TRIAD ignores it).
    pub weight: f64,
}

impl VectorPair {
    /// A pair with the given weight.
    pub fn new(body: Vector3<f64>, reference: Vector3<f64>, weight: f64) -> Self {
        VectorPair {
            body,
            reference,
            weight,
        }
    }
}

/// Davenport's q-method: the quaternion maximising Wahba's gain `q^T K q`
/// (Davenport 1968; Markley & Crassidis Ch. 5, scalar last):
///
/// ```text
/// B = sum w_i b_i r_i^T,   z = sum w_i b_i x r_i,
/// K = [ B + B^T - tr(B) I   z     ]
///     [ z^T                 tr(B) ]
/// ```
///
/// the eigenvector of K's largest eigenvalue. Needs two non-parallel pairs.
pub fn q_method(pairs: &[VectorPair]) -> Result<Quat, AttitudeError> {
    let units = validated_units(pairs)?;
    let mut b = Matrix3::zeros();
    let mut z = Vector3::zeros();
    let mut total_weight = 0.0;
    for pair in &units {
        b += pair.body * pair.reference.transpose() * pair.weight;
        z += pair.body.cross(&pair.reference) * pair.weight;
        total_weight += pair.weight;
    }
    let trace = b.trace();
    let mut k = Matrix4::zeros();
    k.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(b + b.transpose() - Matrix3::identity() * trace));
    k.fixed_view_mut::<3, 1>(0, 3).copy_from(&z);
    k.fixed_view_mut::<1, 3>(3, 0).copy_from(&z.transpose());
    k[(3, 3)] = trace;

    let eigen = SymmetricEigen::new(k);
    let mut order: Vec<usize> = (0..4).collect();
    order.sort_by(|&i, &j| eigen.eigenvalues[j].total_cmp(&eigen.eigenvalues[i]));
    let gap = (eigen.eigenvalues[order[0]] - eigen.eigenvalues[order[1]]) / total_weight;
    if gap.is_nan() || gap <= EIGEN_GAP_TOLERANCE {
        return Err(AttitudeError::Degenerate { gap });
    }
    let v = eigen.eigenvectors.column(order[0]);
    Quat::new_normalized(v[0], v[1], v[2], v[3])
        .map(|q| q.canonical())
        .ok_or(AttitudeError::Degenerate { gap })
}

/// TRIAD (Black 1964; Markley & Crassidis Ch. 5): the attitude that maps
/// `primary.reference` exactly onto `primary.body` and puts the second pair in the
/// same plane. The primary pair should be the more accurate one; weights are ignored.
///
/// ```text
/// t1 = u1,  t2 = u1 x u2 / |u1 x u2|,  t3 = t1 x t2   (in each frame)
/// A = [t1_B t2_B t3_B] [t1_R t2_R t3_R]^T
/// ```
pub fn triad(primary: &VectorPair, secondary: &VectorPair) -> Result<Quat, AttitudeError> {
    let units = validated_units(&[*primary, *secondary])?;
    let (b1, r1) = (units[0].body, units[0].reference);
    let (b2, r2) = (units[1].body, units[1].reference);
    let frame = |u1: Vector3<f64>, u2: Vector3<f64>| {
        let t2 = u1.cross(&u2).normalize();
        Matrix3::from_columns(&[u1, t2, u1.cross(&t2)])
    };
    let a = frame(b1, b2) * frame(r1, r2).transpose();
    Ok(Quat::from_attitude_matrix(&a).canonical())
}

/// Checks every pair and returns them with unit vectors; errors name the pair.
fn validated_units(pairs: &[VectorPair]) -> Result<Vec<VectorPair>, AttitudeError> {
    if pairs.len() < 2 {
        return Err(AttitudeError::TooFewPairs { count: pairs.len() });
    }
    let mut units = Vec::with_capacity(pairs.len());
    for (index, pair) in pairs.iter().enumerate() {
        let body = unit(&pair.body, index, "body vector")?;
        let reference = unit(&pair.reference, index, "reference vector")?;
        if !pair.weight.is_finite() {
            return Err(AttitudeError::NonFinite {
                index,
                what: "weight",
            });
        }
        if pair.weight <= 0.0 {
            return Err(AttitudeError::NonPositiveWeight {
                index,
                weight: pair.weight,
            });
        }
        units.push(VectorPair::new(body, reference, pair.weight));
    }
    require_non_parallel(units.iter().map(|u| u.body), "body")?;
    require_non_parallel(units.iter().map(|u| u.reference), "reference")?;
    Ok(units)
}

fn unit(v: &Vector3<f64>, index: usize, what: &'static str) -> Result<Vector3<f64>, AttitudeError> {
    if !v.iter().all(|c| c.is_finite()) {
        return Err(AttitudeError::NonFinite { index, what });
    }
    let norm = v.norm();
    if norm == 0.0 {
        return Err(AttitudeError::ZeroVector { index, what });
    }
    Ok(v / norm)
}

/// Errors unless some vector is at least [`PARALLEL_TOLERANCE`] (in the sine of the
/// angle) away from the first one; if none is, all are parallel to each other.
fn require_non_parallel(
    units: impl Iterator<Item = Vector3<f64>>,
    frame: &'static str,
) -> Result<(), AttitudeError> {
    let mut units = units;
    let Some(first) = units.next() else {
        return Ok(());
    };
    let max_sin = units.map(|u| first.cross(&u).norm()).fold(0.0, f64::max);
    if max_sin < PARALLEL_TOLERANCE {
        return Err(AttitudeError::Parallel { frame, max_sin });
    }
    Ok(())
}
