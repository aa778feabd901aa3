//! Finite-difference checks of the residual's gradient.

use nalgebra::{DVector, Matrix3, Vector3};
use pdcal_magcal::{MatrixForm, Params};

fn params(form: MatrixForm) -> Params {
    let p = match form {
        MatrixForm::Symmetric => {
            Matrix3::new(1.03, 0.02, -0.01, 0.02, 0.97, 0.015, -0.01, 0.015, 1.01)
        }
        MatrixForm::Diagonal => Matrix3::from_diagonal(&Vector3::new(1.03, 0.97, 1.01)),
        MatrixForm::Scalar => Matrix3::identity() * 1.02,
    };
    Params {
        form,
        p,
        bias_nt: Vector3::new(3000.0, -2500.0, 4100.0),
        coeff_nt: vec![
            Vector3::new(400.0, -300.0, 650.0),
            Vector3::new(-250.0, 700.0, 220.0),
        ],
    }
}

#[test]
fn row_gradient_matches_central_differences() {
    let m = Vector3::new(21000.0, -13000.0, 30500.0);
    let u = [0.31, 0.12];
    for form in [
        MatrixForm::Symmetric,
        MatrixForm::Diagonal,
        MatrixForm::Scalar,
    ] {
        let base = params(form);
        let x = base.to_vector();
        let fit = base.row(&m, &u, 40000.0);
        for i in 0..x.len() {
            // Steps relative to each parameter's size: 1e-6 of P, 1e-3 nT of the biases.
            let h = if i < form.len() { 1e-6 } else { 1e-3 };
            let mut dx = DVector::zeros(x.len());
            dx[i] = h;
            let plus = Params::from_vector(form, &(&x + &dx))
                .row(&m, &u, 40000.0)
                .r_nt;
            let minus = Params::from_vector(form, &(&x - &dx))
                .row(&m, &u, 40000.0)
                .r_nt;
            let numeric = (plus - minus) / (2.0 * h);
            assert!(
                (numeric - fit.grad[i]).abs() <= 1e-6 * numeric.abs().max(1.0),
                "{form:?} param {i}: analytic {} numeric {numeric}",
                fit.grad[i]
            );
        }
    }
}

#[test]
fn vector_round_trip_and_variance() {
    let base = params(MatrixForm::Symmetric);
    let back = Params::from_vector(MatrixForm::Symmetric, &base.to_vector());
    assert!((back.p - base.p).abs().max() < 1e-15);
    assert_eq!(back.bias_nt, base.bias_nt);
    assert_eq!(back.coeff_nt, base.coeff_nt);
    // The variance factor is g^T P P g for the corrected direction g.
    let m = Vector3::new(21000.0, -13000.0, 30500.0);
    let fit = base.row(&m, &[0.3, 0.1], 40000.0);
    let g = base.correct(&m, &[0.3, 0.1]).normalize();
    assert!((fit.var_rel - (base.p * g).norm_squared()).abs() < 1e-14);
}
