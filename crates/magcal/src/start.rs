//! The starting point: a closed-form, linear solution of the squared magnitude equation, in
//! the spirit of Alonso & Shuster's TWOSTEP and its complete linear form (the paper's
//! references [17]-[18]), grown by the current-driven biases.
//!
//! With `E = P^T P`, `c_k = b + sum_j c_j u_jk` and `|H_k|^2 = (m_k - c_k)^T E (m_k - c_k)`:
//!
//! `|H_k|^2 = m^T E m - 2 m^T (E b) - 2 sum_j u_j m^T (E c_j) + kappa + sum_j lambda_j u_j
//!            + sum_{j<=l} mu_jl u_j u_l`
//!
//! is linear in `E`, `beta = E b`, `gamma_j = E c_j` and the nuisance terms `kappa`,
//! `lambda`, `mu` (which absorb `b^T E b`, the noise's `tr(E) sigma^2` and the cross terms;
//! treating them as free is what keeps the problem linear). Each row is weighted by
//! `1/|H|^2`, the squared equation's noise variance growing with the field. Then
//! `P = E^(1/2)`, `b = E^-1 beta`, `c_j = E^-1 gamma_j`. The refinement
//! ([`crate::fit`]) starts from here.

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use crate::model::{MatrixForm, Params};

/// One row's data for the start: measurement, reference magnitude, active regressors.
pub(crate) struct Row<'a> {
    pub(crate) mag_nt: Vector3<f64>,
    pub(crate) field_nt: f64,
    pub(crate) u: &'a [f64],
}

/// The linear solution projected on `form`; `None` when `E` is not positive definite (the
/// rows do not determine it), in which case the caller starts from the identity.
pub(crate) fn linear_start(
    rows: &[Row<'_>],
    form: MatrixForm,
    regressors: usize,
) -> Option<Params> {
    let n_terms = 6 + 3 + 3 * regressors + 1 + regressors + regressors * (regressors + 1) / 2;
    if rows.len() < 2 * n_terms {
        return None;
    }
    // Work in units of the RMS reference field, so the columns are of order one.
    let scale =
        (rows.iter().map(|r| r.field_nt * r.field_nt).sum::<f64>() / rows.len() as f64).sqrt();
    if scale.is_nan() || scale <= 0.0 {
        return None;
    }
    let mut a = DMatrix::<f64>::zeros(n_terms, n_terms);
    let mut rhs = DVector::<f64>::zeros(n_terms);
    let mut x = DVector::<f64>::zeros(n_terms);
    for row in rows {
        let m = row.mag_nt / scale;
        let h2 = (row.field_nt / scale).powi(2);
        terms(&m, row.u, &mut x);
        let w = 1.0 / h2.max(1e-6);
        a.syger(w, &x, &x, 1.0);
        rhs.axpy(w * h2, &x, 1.0);
    }
    let solution = solve_scaled(&a, &rhs)?;
    let e = Matrix3::new(
        solution[0],
        solution[3],
        solution[4],
        solution[3],
        solution[1],
        solution[5],
        solution[4],
        solution[5],
        solution[2],
    );
    let eig = e.symmetric_eigen();
    if eig.eigenvalues.iter().any(|v| v.is_nan() || *v <= 0.0) {
        return None;
    }
    let sqrt = Matrix3::from_diagonal(&eig.eigenvalues.map(f64::sqrt));
    let p = eig.eigenvectors * sqrt * eig.eigenvectors.transpose();
    let e_inv = e.try_inverse()?;
    let vec3 = |i: usize| Vector3::new(solution[i], solution[i + 1], solution[i + 2]);
    let bias_nt = e_inv * vec3(6) * scale;
    let coeff_nt = (0..regressors)
        .map(|j| e_inv * vec3(9 + 3 * j) * scale)
        .collect();
    let projected = form
        .basis()
        .iter()
        .zip(form.coefficients(&p))
        .fold(Matrix3::zeros(), |acc, (b, v)| acc + b * v);
    Some(Params {
        form,
        p: projected,
        bias_nt,
        coeff_nt,
    })
}

/// A second start for data the linear solution misjudges (few rows, a field that varies
/// little against a large hard iron): the centre of the sphere that best fits the readings,
/// `|m|^2 = 2 m^T b + k`, and one scale factor `mean |H| / mean |m - b|`, no current bias.
pub(crate) fn sphere_start(
    rows: &[Row<'_>],
    form: MatrixForm,
    regressors: usize,
) -> Option<Params> {
    if rows.len() < 8 {
        return None;
    }
    let scale = rows.iter().map(|r| r.mag_nt.norm()).sum::<f64>() / rows.len() as f64;
    if scale.is_nan() || scale <= 0.0 {
        return None;
    }
    let mut a = DMatrix::<f64>::zeros(4, 4);
    let mut rhs = DVector::<f64>::zeros(4);
    for row in rows {
        let m = row.mag_nt / scale;
        let x = DVector::from_vec(vec![2.0 * m.x, 2.0 * m.y, 2.0 * m.z, 1.0]);
        a.syger(1.0, &x, &x, 1.0);
        rhs.axpy(m.norm_squared(), &x, 1.0);
    }
    let solution = solve_scaled(&a, &rhs)?;
    let bias_nt = Vector3::new(solution[0], solution[1], solution[2]) * scale;
    let n = rows.len() as f64;
    let radius = rows
        .iter()
        .map(|r| (r.mag_nt - bias_nt).norm())
        .sum::<f64>()
        / n;
    let field = rows.iter().map(|r| r.field_nt).sum::<f64>() / n;
    if radius.is_nan() || radius <= 0.0 {
        return None;
    }
    let mut params = Params::identity(form, regressors);
    params.p = Matrix3::identity() * (field / radius);
    params.bias_nt = bias_nt;
    Some(params)
}

/// The row's terms in the order `E11 E22 E33 E12 E13 E23, beta, gamma_j, kappa, lambda_j,
/// mu_jl`.
fn terms(m: &Vector3<f64>, u: &[f64], x: &mut DVector<f64>) {
    x[0] = m.x * m.x;
    x[1] = m.y * m.y;
    x[2] = m.z * m.z;
    x[3] = 2.0 * m.x * m.y;
    x[4] = 2.0 * m.x * m.z;
    x[5] = 2.0 * m.y * m.z;
    let mut i = 6;
    for a in 0..3 {
        x[i + a] = -2.0 * m[a];
    }
    i += 3;
    for uj in u {
        for a in 0..3 {
            x[i + a] = -2.0 * uj * m[a];
        }
        i += 3;
    }
    x[i] = 1.0;
    i += 1;
    for uj in u {
        x[i] = *uj;
        i += 1;
    }
    for j in 0..u.len() {
        for l in j..u.len() {
            x[i] = u[j] * u[l];
            i += 1;
        }
    }
}

/// Solves the normal equations after scaling them to a unit diagonal; `None` when singular.
fn solve_scaled(a: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<DVector<f64>> {
    let n = a.nrows();
    let mut full = a.clone();
    full.fill_upper_triangle_with_lower_triangle();
    let d: Vec<f64> = (0..n)
        .map(|i| {
            let v = full[(i, i)];
            if v > 0.0 { 1.0 / v.sqrt() } else { 0.0 }
        })
        .collect();
    if d.contains(&0.0) {
        return None;
    }
    let scaled = DMatrix::from_fn(n, n, |i, j| full[(i, j)] * d[i] * d[j]);
    let b = DVector::from_fn(n, |i, _| rhs[i] * d[i]);
    let y = scaled.cholesky()?.solve(&b);
    Some(DVector::from_fn(n, |i, _| y[i] * d[i]))
}
