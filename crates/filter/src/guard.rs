//! The covariance guard: detects a covariance that stopped being a covariance (non-finite
//! entries, a non-positive variance, an indefinite matrix) and repairs it, so that one bad
//! step is reported with its row instead of ending the run thousands of rows later (the
//! smoother's Cholesky was the first to notice before).
//!
//! Repairs: the rows and columns of states with a non-finite entry are reset to their
//! initial variance, uncorrelated (their information is lost, the rest kept); then an
//! indefinite matrix is re-symmetrised and its eigenvalues floored at [`EIGEN_FLOOR`] times
//! the largest (the nearest positive definite matrix in the Frobenius norm, up to the
//! floor). What cannot be repaired is an error naming the row.

use nalgebra::{DMatrix, SymmetricEigen};

/// Smallest eigenvalue after a repair, relative to the largest.
pub const EIGEN_FLOOR: f64 = 1e-12;

/// What the guard found and did at one row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RepairKind {
    /// `states` states had non-finite covariance entries: reset to their initial variance.
    NonFinite {
        /// How many states were reset.
        states: usize,
    },
    /// The matrix was not positive definite: re-symmetrised, eigenvalues floored.
    Indefinite {
        /// Its smallest eigenvalue before the repair.
        min_eigenvalue: f64,
    },
}

/// One repair, at a telemetry row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CovarianceRepair {
    /// Telemetry row.
    pub index: usize,
    /// Its time, s.
    pub t_s: f64,
    /// What was wrong and done.
    pub kind: RepairKind,
}

/// The repairs of a run: the count and the first [`crate::bounded::LISTED_ROWS`].
pub type RepairLog = crate::bounded::Bounded<CovarianceRepair>;

/// Whether every diagonal entry is finite and positive (`O(n)`: the per-step test).
pub(crate) fn diagonal_ok(p: &DMatrix<f64>) -> bool {
    (0..p.nrows()).all(|i| {
        let d = p[(i, i)];
        d.is_finite() && d > 0.0
    })
}

/// Whether `p` is finite, symmetric and has a Cholesky factor (`O(n^3)`).
pub(crate) fn positive_definite(p: &DMatrix<f64>) -> bool {
    p.iter().all(|x| x.is_finite())
        && p == &p.transpose()
        && nalgebra::Cholesky::new(p.clone()).is_some()
}

/// Repairs `p` in place; `initial_variance[i]` is state `i`'s variance at the start. The
/// repair made, if any; `Err(())` if the result is still not positive definite.
pub(crate) fn repair(
    p: &mut DMatrix<f64>,
    initial_variance: &[f64],
) -> Result<Option<RepairKind>, ()> {
    let n = p.nrows();
    let bad: Vec<usize> = (0..n)
        .filter(|&j| p.column(j).iter().any(|x| !x.is_finite()))
        .collect();
    let mut kind = None;
    if !bad.is_empty() {
        for &j in &bad {
            p.column_mut(j).fill(0.0);
            p.row_mut(j).fill(0.0);
            p[(j, j)] = initial_variance.get(j).copied().unwrap_or(1.0);
        }
        kind = Some(RepairKind::NonFinite { states: bad.len() });
    }
    if positive_definite(p) {
        return Ok(kind);
    }
    let symmetric = 0.5 * (&*p + p.transpose());
    let eigen = SymmetricEigen::new(symmetric);
    let min_eigenvalue = eigen.eigenvalues.min();
    let largest = eigen.eigenvalues.amax();
    if !(largest.is_finite() && largest > 0.0) {
        return Err(());
    }
    let floor = EIGEN_FLOOR * largest;
    let values = eigen.eigenvalues.map(|l| l.max(floor));
    let vectors = &eigen.eigenvectors;
    let rebuilt = vectors * DMatrix::from_diagonal(&values) * vectors.transpose();
    p.copy_from(&(0.5 * (&rebuilt + rebuilt.transpose())));
    if !positive_definite(p) {
        return Err(());
    }
    Ok(kind.or(Some(RepairKind::Indefinite { min_eigenvalue })))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spd(n: usize) -> DMatrix<f64> {
        let a = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 3) % 11) as f64 / 11.0 - 0.4);
        &a * a.transpose() + DMatrix::identity(n, n) * 0.1
    }

    #[test]
    fn a_positive_definite_matrix_is_left_alone() {
        let mut p = spd(9);
        let before = p.clone();
        assert_eq!(repair(&mut p, &[1.0; 9]), Ok(None));
        assert_eq!(p, before);
    }

    #[test]
    fn an_indefinite_matrix_is_floored_and_reported() {
        let mut p = spd(9);
        p[(4, 4)] = -2.0;
        assert!(!diagonal_ok(&p));
        let kind = repair(&mut p, &[1.0; 9]).unwrap();
        match kind {
            Some(RepairKind::Indefinite { min_eigenvalue }) => assert!(min_eigenvalue < 0.0),
            other => panic!("{other:?}"),
        }
        assert!(positive_definite(&p));
        assert!(diagonal_ok(&p));
    }

    #[test]
    fn an_indefinite_matrix_with_a_positive_diagonal_is_repaired() {
        let mut p = DMatrix::identity(4, 4);
        p[(0, 1)] = 2.0;
        p[(1, 0)] = 2.0;
        assert!(diagonal_ok(&p) && !positive_definite(&p));
        assert!(matches!(
            repair(&mut p, &[1.0; 4]),
            Ok(Some(RepairKind::Indefinite { .. }))
        ));
        assert!(positive_definite(&p));
    }

    #[test]
    fn non_finite_states_are_reset_to_their_initial_variance() {
        let mut p = spd(6);
        p[(2, 5)] = f64::NAN;
        p[(5, 2)] = f64::NAN;
        let initial = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
        let kind = repair(&mut p, &initial).unwrap();
        assert_eq!(kind, Some(RepairKind::NonFinite { states: 2 }));
        assert_eq!(p[(2, 2)], 3.0);
        assert_eq!(p[(5, 5)], 6.0);
        assert_eq!(p[(2, 0)], 0.0);
        assert!(positive_definite(&p));
    }

    #[test]
    fn an_infinite_diagonal_everywhere_cannot_be_hidden() {
        let mut p = DMatrix::from_element(3, 3, f64::INFINITY);
        // Every state reset: the result is the initial covariance, positive definite.
        assert_eq!(
            repair(&mut p, &[1.0, 1.0, 1.0]),
            Ok(Some(RepairKind::NonFinite { states: 3 }))
        );
        assert_eq!(p, DMatrix::identity(3, 3));
        // A non-positive initial variance cannot make a covariance: an error.
        let mut p = DMatrix::from_element(2, 2, f64::NAN);
        assert_eq!(repair(&mut p, &[0.0, 0.0]), Err(()));
    }
}
