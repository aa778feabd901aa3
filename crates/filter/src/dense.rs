//! The straightforward dense algebra ([`crate::Algebra::Dense`]): full `Phi P Phi^T + Q`,
//! full H rows, dense gain and the Joseph form. The reference the structured filter is tested
//! against (to 1e-9) and the baseline of the benchmark; it allocates freely.

use nalgebra::{DMatrix, DVector, Matrix6};

use crate::sequential::{Outcome, Rows};

/// `P <- Phi P Phi^T + Q` with the full `n x n` `Phi = diag(phi6, I)` and
/// `Q = diag(qd6, cal_noise[6..])`.
pub fn propagate(
    p: &mut DMatrix<f64>,
    phi6: &Matrix6<f64>,
    qd6: &Matrix6<f64>,
    cal_noise: &DVector<f64>,
) {
    let n = p.nrows();
    let mut phi = DMatrix::identity(n, n);
    phi.view_mut((0, 0), (6, 6)).copy_from(phi6);
    let mut q = DMatrix::from_diagonal(cal_noise);
    q.view_mut((0, 0), (6, 6)).copy_from(qd6);
    *p = &phi * &*p * phi.transpose() + q;
    symmetrize(p);
}

/// The full H row of a sparse one.
fn full_row(n: usize, idx: &[usize], val: &[f64]) -> DVector<f64> {
    let mut h = DVector::zeros(n);
    for (&k, &v) in idx.iter().zip(val) {
        h[k] += v;
    }
    h
}

/// The step's rows one after the other (the textbook sequential filter): innovation with
/// the corrections so far, gate `nu^2 <= gate2 s` for rows not decided beforehand,
/// [`joseph_update`].
pub(crate) fn sequential_update(
    p: &mut DMatrix<f64>,
    rows: &Rows,
    gate2: f64,
    dx: &mut DVector<f64>,
    outcome: &mut Vec<Outcome>,
) {
    outcome.clear();
    for l in 0..rows.len() {
        let (idx, val) = rows.row(l);
        let (innovation, r) = rows.innovation_and_variance(l);
        let h_dx: f64 = idx.iter().zip(val).map(|(&k, v)| v * dx[k]).sum();
        let nu = innovation - h_dx;
        let spread = innovation_variance(p, idx, val, r);
        let accepted = rows.accepts(l, nu, spread, gate2);
        if accepted {
            joseph_update(p, dx, idx, val, nu, r);
        }
        outcome.push(Outcome {
            residual: nu,
            spread,
            accepted,
        });
    }
}

/// `H P H^T + R` with the full row.
pub fn innovation_variance(p: &DMatrix<f64>, idx: &[usize], val: &[f64], r: f64) -> f64 {
    let h = full_row(p.nrows(), idx, val);
    (h.transpose() * p * &h)[0] + r
}

/// Kalman update with the dense gain (Eqs. 4, 6) and the Joseph form
/// `P <- (I - K H) P (I - K H)^T + K R K^T` (Eq. 7 in its stabilised form).
pub fn joseph_update(
    p: &mut DMatrix<f64>,
    dx: &mut DVector<f64>,
    idx: &[usize],
    val: &[f64],
    nu: f64,
    r: f64,
) {
    let n = p.nrows();
    let h = full_row(n, idx, val);
    let pht = &*p * &h;
    let s = h.dot(&pht) + r;
    let k = pht / s;
    *dx += &k * nu;
    let ikh = DMatrix::identity(n, n) - &k * h.transpose();
    *p = &ikh * &*p * ikh.transpose() + &k * k.transpose() * r;
    symmetrize(p);
}

fn symmetrize(p: &mut DMatrix<f64>) {
    let t = p.transpose();
    *p += t;
    *p *= 0.5;
}
