//! The measurement model and its inverse, the correction:
//!
//! `m_k = T B_k + b + sum_j c_j u_jk + noise`,   `B_k = P (m_k - b - sum_j c_j u_jk)`,
//!
//! with `P = T^-1` in the symmetric convention (docs/magcal.md): `T` symmetric positive
//! definite, the rotation the field magnitude cannot see left out. `P` is a linear
//! combination of fixed symmetric basis matrices ([`MatrixForm`]), so the residual is
//! linear in each of its coefficients.

use nalgebra::{DVector, Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// Which matrices `T` (and `P = T^-1`) may be.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MatrixForm {
    /// Any symmetric positive definite matrix: scale factors, soft iron and the
    /// non-orthogonality's symmetric part (6 parameters).
    Symmetric,
    /// A scale factor per axis (3 parameters).
    Diagonal,
    /// One scale factor for all axes (1 parameter).
    Scalar,
}

impl MatrixForm {
    /// The symmetric basis matrices `E_i` with `P = sum_i p_i E_i`.
    pub fn basis(self) -> Vec<Matrix3<f64>> {
        let unit = |a: usize, b: usize| {
            let mut e = Matrix3::zeros();
            e[(a, b)] = 1.0;
            e[(b, a)] = 1.0;
            e
        };
        match self {
            MatrixForm::Symmetric => vec![
                unit(0, 0),
                unit(1, 1),
                unit(2, 2),
                unit(0, 1),
                unit(0, 2),
                unit(1, 2),
            ],
            MatrixForm::Diagonal => vec![unit(0, 0), unit(1, 1), unit(2, 2)],
            MatrixForm::Scalar => vec![Matrix3::identity()],
        }
    }

    /// The coefficients of `P` in [`MatrixForm::basis`] that are closest to `p` (the
    /// basis is orthogonal, so this is a projection).
    pub fn coefficients(self, p: &Matrix3<f64>) -> Vec<f64> {
        self.basis()
            .iter()
            .map(|e| e.component_mul(p).sum() / e.component_mul(e).sum())
            .collect()
    }

    /// Number of matrix parameters.
    pub fn len(self) -> usize {
        match self {
            MatrixForm::Symmetric => 6,
            MatrixForm::Diagonal => 3,
            MatrixForm::Scalar => 1,
        }
    }

    /// Never empty: every form has a scale factor.
    pub fn is_empty(self) -> bool {
        false
    }

    /// The simpler form to fall back to when this one is not determined.
    pub fn simpler(self) -> Option<MatrixForm> {
        match self {
            MatrixForm::Symmetric => Some(MatrixForm::Diagonal),
            MatrixForm::Diagonal => Some(MatrixForm::Scalar),
            MatrixForm::Scalar => None,
        }
    }
}

/// The model's parameters in the inverse form used for estimation.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    /// The form of `P`.
    pub form: MatrixForm,
    /// `P = T^-1`, symmetric, dimensionless.
    pub p: Matrix3<f64>,
    /// Hard-iron bias `b`, nT (sensor frame).
    pub bias_nt: Vector3<f64>,
    /// Current-driven bias `c_j` per active regressor, nT per unit of the regressor.
    pub coeff_nt: Vec<Vector3<f64>>,
}

/// One row's magnitude residual, its relative variance and its gradient.
#[derive(Debug, Clone, PartialEq)]
pub struct RowFit {
    /// `|P v| - |H|`, nT, `v = m - b - sum c_j u_j`.
    pub r_nt: f64,
    /// `g^T P P g`, `g` the corrected field's direction: the residual's variance in units
    /// of the magnetometer's per-axis noise variance (to first order).
    pub var_rel: f64,
    /// `d r / d theta` in the order of [`Params::to_vector`].
    pub grad: DVector<f64>,
}

impl Params {
    /// No correction: `P = I`, no biases.
    pub fn identity(form: MatrixForm, regressors: usize) -> Self {
        Params {
            form,
            p: Matrix3::identity(),
            bias_nt: Vector3::zeros(),
            coeff_nt: vec![Vector3::zeros(); regressors],
        }
    }

    /// Number of estimated parameters.
    pub fn len(&self) -> usize {
        self.form.len() + 3 + 3 * self.coeff_nt.len()
    }

    /// Never empty: the bias is always estimated.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// `[p_i (basis coefficients), b, c_1, ..., c_J]`.
    pub fn to_vector(&self) -> DVector<f64> {
        let mut x = self.form.coefficients(&self.p);
        x.extend(self.bias_nt.iter());
        for c in &self.coeff_nt {
            x.extend(c.iter());
        }
        DVector::from_vec(x)
    }

    /// The inverse of [`Params::to_vector`].
    pub fn from_vector(form: MatrixForm, x: &DVector<f64>) -> Self {
        let k = form.len();
        let p = form
            .basis()
            .iter()
            .zip(x.iter())
            .fold(Matrix3::zeros(), |acc, (e, v)| acc + e * *v);
        let coeff_nt = (k + 3..x.len())
            .step_by(3)
            .map(|i| Vector3::new(x[i], x[i + 1], x[i + 2]))
            .collect();
        Params {
            form,
            p,
            bias_nt: Vector3::new(x[k], x[k + 1], x[k + 2]),
            coeff_nt,
        }
    }

    /// The sensor-frame field with the biases removed: `m - b - sum c_j u_j`.
    pub fn debiased(&self, mag_nt: &Vector3<f64>, u: &[f64]) -> Vector3<f64> {
        self.coeff_nt
            .iter()
            .zip(u)
            .fold(mag_nt - self.bias_nt, |acc, (c, uj)| acc - c * *uj)
    }

    /// The corrected field `P (m - b - sum c_j u_j)`, nT.
    pub fn correct(&self, mag_nt: &Vector3<f64>, u: &[f64]) -> Vector3<f64> {
        self.p * self.debiased(mag_nt, u)
    }

    /// The residual of one row against the reference magnitude `field_nt`, with its
    /// gradient. `u` holds the active regressors' values.
    pub fn row(&self, mag_nt: &Vector3<f64>, u: &[f64], field_nt: f64) -> RowFit {
        let v = self.debiased(mag_nt, u);
        let y = self.p * v;
        let norm = y.norm();
        let g = if norm > 0.0 { y / norm } else { Vector3::x() };
        let pg = self.p * g;
        let mut grad = DVector::zeros(self.len());
        for (i, e) in self.form.basis().iter().enumerate() {
            grad[i] = g.dot(&(e * v));
        }
        let k = self.form.len();
        for a in 0..3 {
            grad[k + a] = -pg[a];
        }
        for (j, uj) in u.iter().enumerate().take(self.coeff_nt.len()) {
            for a in 0..3 {
                grad[k + 3 + 3 * j + a] = -uj * pg[a];
            }
        }
        RowFit {
            r_nt: norm - field_nt,
            var_rel: pg.norm_squared(),
            grad,
        }
    }
}
