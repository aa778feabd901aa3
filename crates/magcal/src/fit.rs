//! The refinement: Levenberg-Marquardt on the magnitude residual weighted by its variance,
//! outlier rows gated, the covariance from the Fisher information, the regressors selected
//! by the evidence rule (docs/magcal.md).

use nalgebra::{DMatrix, DVector, Matrix3, Vector3};

use crate::MagCalError;
use crate::model::{MatrixForm, Params};
use crate::screen::{ScreenedRow, check_field_size, few_rows_reason, not_physical, screen};
use crate::start::{Row, linear_start, sphere_start};

/// One telemetry row for the calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// 0-based telemetry row (kept to name rejected rows).
    pub row: usize,
    /// Seconds since the dataset epoch.
    pub t_s: f64,
    /// The magnetometer's reading, nT, sensor axes.
    pub mag_nt: Vector3<f64>,
    /// The reference field's magnitude at the row (IGRF along the orbit), nT.
    pub field_nt: f64,
    /// Every candidate regressor's value at the row, in the order of the names given to
    /// [`calibrate`] (amperes for the `cur_<name>_A` columns).
    pub u: Vec<f64>,
}

/// Tuning of [`calibrate`].
#[derive(Debug, Clone, PartialEq)]
pub struct MagCalConfig {
    /// The richest matrix form tried (simpler ones when it is not determined).
    pub form: MatrixForm,
    /// A regressor is kept only when its score (nats, BIC subtracted) exceeds this; the
    /// diagnosis's threshold (`pdcal_diagnose::DEFAULT_THRESHOLD`, docs/diagnose.md).
    pub threshold_nats: f64,
    /// Rows whose standardized residual exceeds this many robust sigmas are rejected.
    pub gate_sigmas: f64,
    /// Most Levenberg-Marquardt iterations per fit.
    pub max_iterations: usize,
}

impl Default for MagCalConfig {
    fn default() -> Self {
        MagCalConfig {
            form: MatrixForm::Symmetric,
            threshold_nats: 10.0,
            gate_sigmas: 5.0,
            max_iterations: 100,
        }
    }
}

/// What became of one candidate regressor.
#[derive(Debug, Clone, PartialEq)]
pub struct RegressorDecision {
    /// The regressor's name (the telemetry column).
    pub name: String,
    /// Kept in the final model.
    pub kept: bool,
    /// Its score when kept (final fit) or when dropped, nats; `None` when it was not fitted
    /// (constant or not determined).
    pub score_nats: Option<f64>,
    /// Why it was dropped, or `"significant"`.
    pub reason: String,
}

/// The calibration: the forward model's parameters with their covariance.
#[derive(Debug, Clone, PartialEq)]
pub struct MagCalibration {
    /// The estimated parameters in the inverse form (`P = T^-1`).
    pub params: Params,
    /// `T`, symmetric (docs/magcal.md).
    pub matrix: Matrix3<f64>,
    /// Names of the kept regressors, in the order of `params.coeff_nt`.
    pub regressors: Vec<String>,
    /// Covariance of `[T coefficients (in the form's basis), b, c_1, ..., c_J]`.
    pub covariance: DMatrix<f64>,
    /// Covariance of [`Params::to_vector`] (what the correction's uncertainty needs).
    pub param_covariance: DMatrix<f64>,
    /// The per-axis magnetometer noise the residuals imply, nT.
    pub noise_sigma_nt: f64,
    /// Rows used.
    pub rows_used: usize,
    /// Telemetry rows rejected: screened before the fit or by the gate (increasing).
    pub rejected_rows: Vec<usize>,
    /// The rows screened out before the fit, with their causes (also in `rejected_rows`).
    pub screened: Vec<ScreenedRow>,
    /// RMS of `|m| - |H|` over every row the screening kept, nT.
    pub residual_rms_before_nt: f64,
    /// RMS of `|B| - |H|` over the rows used, nT.
    pub residual_rms_after_nt: f64,
    /// Every candidate regressor and what became of it.
    pub decisions: Vec<RegressorDecision>,
    /// Matrix forms given up because the data did not determine them.
    pub forms_not_determined: Vec<MatrixForm>,
}

impl MagCalibration {
    /// One sigma of each entry of `T`, nT/nT.
    pub fn matrix_sigma(&self) -> Matrix3<f64> {
        let basis = self.params.form.basis();
        let mut s = Matrix3::zeros();
        for (i, e) in basis.iter().enumerate() {
            let sigma = self.covariance[(i, i)].max(0.0).sqrt();
            for a in 0..3 {
                for b in 0..3 {
                    if e[(a, b)] != 0.0 {
                        s[(a, b)] = sigma * e[(a, b)];
                    }
                }
            }
        }
        s
    }

    /// One sigma of `b`, nT.
    pub fn bias_sigma_nt(&self) -> Vector3<f64> {
        let k = self.params.form.len();
        Vector3::from_fn(|a, _| self.covariance[(k + a, k + a)].max(0.0).sqrt())
    }

    /// One sigma of each `c_j`, nT per unit.
    pub fn coeff_sigma_nt(&self) -> Vec<Vector3<f64>> {
        let k = self.params.form.len() + 3;
        (0..self.regressors.len())
            .map(|j| {
                Vector3::from_fn(|a, _| {
                    let i = k + 3 * j + a;
                    self.covariance[(i, i)].max(0.0).sqrt()
                })
            })
            .collect()
    }

    /// A calibration from its forward form as written in a file: `T` (symmetric, of
    /// `form`), `b`, the kept regressors' `c_j` and the covariance of `[T coefficients, b,
    /// c]`; what [`MagCalibration::correct`] and [`MagCalibration::correction_covariance`]
    /// need. `None` when `T` is singular. The fit's statistics are left empty.
    pub fn from_forward(
        form: MatrixForm,
        matrix: Matrix3<f64>,
        bias_nt: Vector3<f64>,
        regressors: Vec<(String, Vector3<f64>)>,
        covariance: DMatrix<f64>,
    ) -> Option<Self> {
        let p = matrix.try_inverse()?;
        let (names, coeff_nt): (Vec<String>, Vec<Vector3<f64>>) = regressors.into_iter().unzip();
        let params = Params {
            form,
            p: (p + p.transpose()) * 0.5,
            bias_nt,
            coeff_nt,
        };
        if covariance.nrows() != params.len() || covariance.ncols() != params.len() {
            return None;
        }
        let (_, jac) = forward_matrix(&params);
        let inv = jac.try_inverse()?;
        let param_covariance = &inv * &covariance * inv.transpose();
        Some(MagCalibration {
            params,
            matrix,
            regressors: names,
            covariance,
            param_covariance,
            noise_sigma_nt: 0.0,
            rows_used: 0,
            rejected_rows: Vec::new(),
            screened: Vec::new(),
            residual_rms_before_nt: 0.0,
            residual_rms_after_nt: 0.0,
            decisions: Vec::new(),
            forms_not_determined: Vec::new(),
        })
    }

    /// Names of the entries of [`MagCalibration::covariance`], in order (`T11`, ..., `b_x`,
    /// ..., `<regressor>_x`, ...).
    pub fn parameter_names(&self) -> Vec<String> {
        let mut names: Vec<String> = match self.params.form {
            MatrixForm::Symmetric => ["T11", "T22", "T33", "T12", "T13", "T23"]
                .map(String::from)
                .to_vec(),
            MatrixForm::Diagonal => ["T11", "T22", "T33"].map(String::from).to_vec(),
            MatrixForm::Scalar => vec!["T".to_owned()],
        };
        names.extend(["b_x", "b_y", "b_z"].map(String::from));
        for r in &self.regressors {
            names.extend(["x", "y", "z"].map(|a| format!("{r}_{a}")));
        }
        names
    }

    /// The corrected field `P (m - b - sum c_j u_j)`; `u` the kept regressors' values.
    pub fn correct(&self, mag_nt: &Vector3<f64>, u: &[f64]) -> Vector3<f64> {
        self.params.correct(mag_nt, u)
    }

    /// Covariance of the corrected field from the parameters' uncertainty alone, nT^2.
    pub fn correction_covariance(&self, mag_nt: &Vector3<f64>, u: &[f64]) -> Matrix3<f64> {
        let j = correction_jacobian(&self.params, mag_nt, u);
        let c = &j * &self.param_covariance * j.transpose();
        Matrix3::from_fn(|a, b| c[(a, b)])
    }
}

/// `d B / d theta` (3 x parameters), `B = P (m - b - sum c_j u_j)`.
fn correction_jacobian(params: &Params, mag_nt: &Vector3<f64>, u: &[f64]) -> DMatrix<f64> {
    let v = params.debiased(mag_nt, u);
    let mut j = DMatrix::zeros(3, params.len());
    for (i, e) in params.form.basis().iter().enumerate() {
        j.column_mut(i).copy_from(&(e * v));
    }
    let k = params.form.len();
    for a in 0..3 {
        for b in 0..3 {
            j[(a, k + b)] = -params.p[(a, b)];
            for (jj, uj) in u.iter().enumerate().take(params.coeff_nt.len()) {
                j[(a, k + 3 + 3 * jj + b)] = -uj * params.p[(a, b)];
            }
        }
    }
    j
}

/// Calibrates the magnetometer from `samples`, testing the regressors `names` (one value
/// per name in each sample's `u`): the field's size checked against the reference, the
/// rows no calibration could explain screened out ([`crate::screen`]), the fit, and its
/// result refused when it is no magnetometer's.
pub fn calibrate(
    samples: &[Sample],
    names: &[String],
    config: &MagCalConfig,
) -> Result<MagCalibration, MagCalError> {
    for s in samples {
        if s.u.len() != names.len() {
            return Err(MagCalError::RegressorCount {
                row: s.row,
                expected: names.len(),
                found: s.u.len(),
            });
        }
    }
    check_field_size(samples)?;
    let screened = screen(samples, names);
    let kept: Vec<Sample> = (samples.iter())
        .filter(|s| screened.binary_search_by_key(&s.row, |r| r.row).is_err())
        .cloned()
        .collect();
    let mut cal = calibrate_screened(&kept, names, config)?;
    let coeffs: Vec<(String, Vector3<f64>)> = (cal.regressors.iter().cloned())
        .zip(cal.params.coeff_nt.iter().copied())
        .collect();
    if let Some(why) = not_physical(&cal.matrix, &cal.params.bias_nt, &coeffs) {
        return Err(MagCalError::NotPhysical(why));
    }
    cal.rejected_rows.extend(screened.iter().map(|r| r.row));
    cal.rejected_rows.sort_unstable();
    cal.screened = screened;
    Ok(cal)
}

/// [`calibrate`] on the screened samples.
fn calibrate_screened(
    samples: &[Sample],
    names: &[String],
    config: &MagCalConfig,
) -> Result<MagCalibration, MagCalError> {
    let mut decisions = Vec::new();
    let mut active: Vec<usize> = Vec::new();
    for (j, name) in names.iter().enumerate() {
        match constant_reason(samples, j).or_else(|| few_rows_reason(samples, j)) {
            Some(reason) => decisions.push(RegressorDecision {
                name: name.clone(),
                kept: false,
                score_nats: None,
                reason,
            }),
            None => active.push(j),
        }
    }
    let mut form = config.form;
    let mut forms_not_determined = Vec::new();
    loop {
        let fit = match fit_with(samples, &active, form, config) {
            Ok(fit) => fit,
            Err(Undetermined::Regressor(slot)) => {
                let j = active.remove(slot);
                decisions.push(RegressorDecision {
                    name: names[j].clone(),
                    kept: false,
                    score_nats: None,
                    reason: "not determined (collinear with the bias or another regressor)".into(),
                });
                continue;
            }
            Err(Undetermined::Matrix) => {
                forms_not_determined.push(form);
                form = form
                    .simpler()
                    .ok_or_else(|| MagCalError::NotDetermined("the scale factor".into()))?;
                continue;
            }
            Err(Undetermined::Error(e)) => return Err(e),
        };
        let scores = regressor_scores(&fit);
        let weakest = scores
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .map(|(slot, s)| (slot, *s));
        if let Some((slot, score)) = weakest.filter(|(_, s)| *s <= config.threshold_nats) {
            let j = active.remove(slot);
            decisions.push(RegressorDecision {
                name: names[j].clone(),
                kept: false,
                score_nats: Some(score),
                reason: format!(
                    "score {score:.1} nats not above the threshold {:.0}",
                    config.threshold_nats
                ),
            });
            continue;
        }
        for (slot, &j) in active.iter().enumerate() {
            decisions.push(RegressorDecision {
                name: names[j].clone(),
                kept: true,
                score_nats: Some(scores[slot]),
                reason: "significant".into(),
            });
        }
        decisions.sort_by_key(|d| names.iter().position(|n| *n == d.name));
        let before = rms(samples.iter().map(|s| s.mag_nt.norm() - s.field_nt));
        return Ok(MagCalibration {
            regressors: active.iter().map(|&j| names[j].clone()).collect(),
            residual_rms_before_nt: before,
            decisions,
            forms_not_determined,
            ..fit
        });
    }
}

/// Why regressor `j` cannot be fitted at all, if so.
fn constant_reason(samples: &[Sample], j: usize) -> Option<String> {
    let values = samples.iter().map(|s| s.u[j]);
    if values.clone().any(|v| !v.is_finite()) {
        return Some("has values that are not numbers".into());
    }
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    (hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater))
        .then(|| "constant (indistinguishable from the hard-iron bias)".into())
}

/// Each active regressor's score: `W/2 - 3 ln(N)/2`, `W = c^T Sigma_c^-1 c`.
fn regressor_scores(fit: &MagCalibration) -> Vec<f64> {
    let k = fit.params.form.len() + 3;
    let penalty = 1.5 * (fit.rows_used.max(2) as f64).ln();
    fit.params
        .coeff_nt
        .iter()
        .enumerate()
        .map(|(j, c)| {
            let block = fit
                .covariance
                .view((k + 3 * j, k + 3 * j), (3, 3))
                .into_owned();
            let wald = block
                .cholesky()
                .map(|ch| c.dot(&ch.solve(&DVector::from_column_slice(c.as_slice()))))
                .unwrap_or(0.0);
            0.5 * wald - penalty
        })
        .collect()
}

/// Why a fit could not be made.
enum Undetermined {
    /// The regressor in this slot of the active list is not determined.
    Regressor(usize),
    /// The matrix form is not determined.
    Matrix,
    /// Any other failure.
    Error(MagCalError),
}

/// One fit with the regressors `active` (indices into each sample's `u`): start, then
/// refinement and gating until the rejected rows stop changing.
fn fit_with(
    samples: &[Sample],
    active: &[usize],
    form: MatrixForm,
    config: &MagCalConfig,
) -> Result<MagCalibration, Undetermined> {
    let u: Vec<Vec<f64>> = samples
        .iter()
        .map(|s| active.iter().map(|&j| s.u[j]).collect())
        .collect();
    let n_params = form.len() + 3 + 3 * active.len();
    let needed = 3 * n_params;
    if samples.len() < needed {
        return Err(Undetermined::Error(MagCalError::TooFewRows {
            rows: samples.len(),
            parameters: n_params,
            needed,
        }));
    }
    let start_rows: Vec<Row<'_>> = samples
        .iter()
        .zip(&u)
        .map(|(s, u)| Row {
            mag_nt: s.mag_nt,
            field_nt: s.field_nt,
            u,
        })
        .collect();
    let all = vec![true; samples.len()];
    // Both starts are refined and the one of lower cost kept: the magnitude's cost has
    // local minima, and which start lands in the global one depends on the data.
    let mut params = [
        linear_start(&start_rows, form, active.len()),
        sphere_start(&start_rows, form, active.len()),
    ]
    .into_iter()
    .flatten()
    .map(|p| refine(samples, &u, &all, p, config.max_iterations))
    .min_by(|a, b| profiled(samples, &u, a).total_cmp(&profiled(samples, &u, b)))
    .unwrap_or_else(|| {
        let mut p = Params::identity(form, active.len());
        p.bias_nt = samples.iter().map(|s| s.mag_nt).sum::<Vector3<f64>>() / samples.len() as f64;
        p
    });
    let mut keep = all.clone();
    for _ in 0..8 {
        params = refine(samples, &u, &keep, params, config.max_iterations);
        let next = gate(samples, &u, &params, config.gate_sigmas);
        if next == keep {
            break;
        }
        keep = next;
    }
    let used = keep.iter().filter(|k| **k).count();
    if used < needed {
        return Err(Undetermined::Error(MagCalError::TooFewRows {
            rows: used,
            parameters: n_params,
            needed,
        }));
    }
    let (fisher, weighted_ss) = normal_equations(samples, &u, &keep, &params).0;
    let inverse = inverse_or_culprit(&fisher, form.len())?;
    let sigma2 = weighted_ss / (used - n_params) as f64;
    let param_covariance = inverse * sigma2;
    let (matrix, jac) = forward_matrix(&params);
    let covariance = &jac * &param_covariance * jac.transpose();
    let after = rms(samples
        .iter()
        .zip(&u)
        .zip(&keep)
        .filter(|(_, k)| **k)
        .map(|((s, u), _)| params.row(&s.mag_nt, u, s.field_nt).r_nt));
    Ok(MagCalibration {
        params,
        matrix,
        regressors: Vec::new(),
        covariance,
        param_covariance,
        noise_sigma_nt: sigma2.sqrt(),
        rows_used: used,
        rejected_rows: samples
            .iter()
            .zip(&keep)
            .filter(|(_, k)| !**k)
            .map(|(s, _)| s.row)
            .collect(),
        screened: Vec::new(),
        residual_rms_before_nt: 0.0,
        residual_rms_after_nt: after,
        decisions: Vec::new(),
        forms_not_determined: Vec::new(),
    })
}

/// `T = P^-1` and the Jacobian from `[p, b, c]` to `[t, b, c]` (`dT = -T dP T`).
fn forward_matrix(params: &Params) -> (Matrix3<f64>, DMatrix<f64>) {
    let t = params.p.try_inverse().unwrap_or_else(Matrix3::identity);
    let n = params.len();
    let k = params.form.len();
    let mut jac = DMatrix::identity(n, n);
    for (i, e) in params.form.basis().iter().enumerate() {
        let dt = -(t * e * t);
        for (r, v) in params.form.coefficients(&dt).into_iter().enumerate() {
            jac[(r, i)] = v;
        }
    }
    for r in 0..k {
        for c in k..n {
            jac[(r, c)] = 0.0;
        }
    }
    (t, jac)
}

/// `(sum g g^T / v, sum r^2 / v)` over the kept rows, and `sum g r / v`.
fn normal_equations(
    samples: &[Sample],
    u: &[Vec<f64>],
    keep: &[bool],
    params: &Params,
) -> ((DMatrix<f64>, f64), DVector<f64>) {
    let n = params.len();
    let mut a = DMatrix::zeros(n, n);
    let mut g = DVector::zeros(n);
    let mut ss = 0.0;
    for ((s, u), _) in samples.iter().zip(u).zip(keep).filter(|(_, k)| **k) {
        let row = params.row(&s.mag_nt, u, s.field_nt);
        let w = 1.0 / row.var_rel;
        a.syger(w, &row.grad, &row.grad, 1.0);
        g.axpy(w * row.r_nt, &row.grad, 1.0);
        ss += w * row.r_nt * row.r_nt;
    }
    a.fill_upper_triangle_with_lower_triangle();
    ((a, ss), g)
}

/// The weighted cost `sum r^2 / v` over the kept rows.
fn cost(samples: &[Sample], u: &[Vec<f64>], keep: &[bool], params: &Params) -> f64 {
    samples
        .iter()
        .zip(u)
        .zip(keep)
        .filter(|(_, k)| **k)
        .map(|((s, u), _)| {
            let row = params.row(&s.mag_nt, u, s.field_nt);
            row.r_nt * row.r_nt / row.var_rel
        })
        .sum()
}

/// The negative log-likelihood with the noise variance profiled out, up to a constant:
/// `n ln(sum r^2 / v / n) + sum ln v` over every row (comparable between fits whose `P`, and
/// so whose variances `v`, differ).
fn profiled(samples: &[Sample], u: &[Vec<f64>], params: &Params) -> f64 {
    let (mut weighted, mut log_v) = (0.0, 0.0);
    for (s, u) in samples.iter().zip(u) {
        let row = params.row(&s.mag_nt, u, s.field_nt);
        weighted += row.r_nt * row.r_nt / row.var_rel;
        log_v += row.var_rel.ln();
    }
    let n = samples.len().max(1) as f64;
    n * (weighted / n).ln() + log_v
}

/// Levenberg-Marquardt with Marquardt's diagonal scaling; the weights are re-evaluated at
/// every point (iteratively reweighted).
fn refine(
    samples: &[Sample],
    u: &[Vec<f64>],
    keep: &[bool],
    mut params: Params,
    max_iterations: usize,
) -> Params {
    let form = params.form;
    let mut lambda = 1e-3;
    let mut current = cost(samples, u, keep, &params);
    for _ in 0..max_iterations {
        let ((a, _), g) = normal_equations(samples, u, keep, &params);
        let x = params.to_vector();
        let mut improved = false;
        while lambda < 1e12 {
            let mut damped = a.clone();
            for i in 0..damped.nrows() {
                damped[(i, i)] += lambda * a[(i, i)].max(f64::MIN_POSITIVE);
            }
            let Some(step) = damped.cholesky().map(|c| c.solve(&(-&g))) else {
                lambda *= 10.0;
                continue;
            };
            let trial = Params::from_vector(form, &(&x + &step));
            let next = cost(samples, u, keep, &trial);
            if next < current {
                let gain = current - next;
                params = trial;
                current = next;
                lambda = (lambda / 10.0).max(1e-12);
                improved = gain > 1e-10 * current.max(1.0);
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    params
}

/// Rows kept by the gate: standardized residual within `sigmas` robust sigmas (the median
/// absolute deviation, so the outliers themselves do not widen the gate).
fn gate(samples: &[Sample], u: &[Vec<f64>], params: &Params, sigmas: f64) -> Vec<bool> {
    let z: Vec<f64> = samples
        .iter()
        .zip(u)
        .map(|(s, u)| {
            let row = params.row(&s.mag_nt, u, s.field_nt);
            row.r_nt / row.var_rel.sqrt()
        })
        .collect();
    let mut sorted = z.clone();
    let centre = median(&mut sorted);
    let mut dev: Vec<f64> = z.iter().map(|v| (v - centre).abs()).collect();
    let scale = 1.4826 * median(&mut dev);
    if scale.is_nan() || scale <= 0.0 {
        return vec![true; samples.len()];
    }
    z.iter()
        .map(|v| (v - centre).abs() <= sigmas * scale)
        .collect()
}

fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    if n == 0 { 0.0 } else { (sum / n as f64).sqrt() }
}

/// `A^-1`, or which parameter the data leave undetermined: the largest component of the
/// eigenvector of the smallest eigenvalue of `A` scaled to a unit diagonal.
fn inverse_or_culprit(
    a: &DMatrix<f64>,
    matrix_params: usize,
) -> Result<DMatrix<f64>, Undetermined> {
    let n = a.nrows();
    let d: Vec<f64> = (0..n).map(|i| a[(i, i)].max(0.0).sqrt()).collect();
    let scaled = DMatrix::from_fn(n, n, |i, j| {
        if d[i] > 0.0 && d[j] > 0.0 {
            a[(i, j)] / (d[i] * d[j])
        } else {
            0.0
        }
    });
    let eig = scaled.clone().symmetric_eigen();
    let (min_i, min_v) = eig
        .eigenvalues
        .iter()
        .enumerate()
        .min_by(|x, y| x.1.total_cmp(y.1))
        .map(|(i, v)| (i, *v))
        .unwrap_or((0, 0.0));
    if min_v > 1e-10
        && d.iter().all(|v| *v > 0.0)
        && let Some(inv) = scaled.cholesky().map(|c| c.inverse())
    {
        return Ok(DMatrix::from_fn(n, n, |i, j| inv[(i, j)] / (d[i] * d[j])));
    }
    let culprit = (0..n)
        .max_by(|&x, &y| {
            eig.eigenvectors[(x, min_i)]
                .abs()
                .total_cmp(&eig.eigenvectors[(y, min_i)].abs())
        })
        .unwrap_or(0);
    if culprit >= matrix_params + 3 {
        Err(Undetermined::Regressor((culprit - matrix_params - 3) / 3))
    } else {
        Err(Undetermined::Matrix)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> Params {
        Params {
            form: MatrixForm::Symmetric,
            p: Matrix3::new(1.03, 0.02, -0.01, 0.02, 0.97, 0.015, -0.01, 0.015, 1.01),
            bias_nt: Vector3::new(3000.0, -2500.0, 4100.0),
            coeff_nt: vec![Vector3::new(400.0, -300.0, 650.0)],
        }
    }

    /// `dB/dtheta` of the correction against central differences.
    #[test]
    fn correction_jacobian_matches_central_differences() {
        let base = params();
        let m = Vector3::new(21000.0, -13000.0, 30500.0);
        let u = [0.37];
        let j = correction_jacobian(&base, &m, &u);
        let x = base.to_vector();
        for i in 0..x.len() {
            let h = if i < 6 { 1e-6 } else { 1e-3 };
            let mut dx = DVector::zeros(x.len());
            dx[i] = h;
            let plus = Params::from_vector(base.form, &(&x + &dx)).correct(&m, &u);
            let minus = Params::from_vector(base.form, &(&x - &dx)).correct(&m, &u);
            let numeric = (plus - minus) / (2.0 * h);
            for a in 0..3 {
                assert!(
                    (numeric[a] - j[(a, i)]).abs() <= 1e-6 * numeric[a].abs().max(1.0),
                    "param {i} axis {a}: {} vs {}",
                    j[(a, i)],
                    numeric[a]
                );
            }
        }
    }

    /// The Jacobian from `P`'s coefficients to `T = P^-1`'s against central differences.
    /// A calibration rebuilt from its forward form has the same correction and the same
    /// covariance of the corrected field.
    #[test]
    fn forward_form_round_trip() {
        let params = params();
        let n = params.len();
        let a = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 3) % 5) as f64 * 0.1);
        let param_covariance = &a * a.transpose() + DMatrix::identity(n, n);
        let (matrix, jac) = forward_matrix(&params);
        let covariance = &jac * &param_covariance * jac.transpose();
        let back = MagCalibration::from_forward(
            MatrixForm::Symmetric,
            matrix,
            params.bias_nt,
            vec![("cur_px_A".into(), params.coeff_nt[0])],
            covariance,
        )
        .expect("invertible");
        assert!((back.params.p - params.p).abs().max() < 1e-12);
        assert!((&back.param_covariance - &param_covariance).abs().max() < 1e-8);
        assert_eq!(back.parameter_names().len(), n);
    }

    #[test]
    fn forward_matrix_jacobian_matches_central_differences() {
        let base = params();
        let (t, jac) = forward_matrix(&base);
        assert!((t * base.p - Matrix3::identity()).abs().max() < 1e-14);
        let x = base.to_vector();
        let coeffs = |x: &DVector<f64>| {
            let p = Params::from_vector(base.form, x);
            let t = p.p.try_inverse().expect("invertible");
            base.form.coefficients(&t)
        };
        for i in 0..6 {
            let h = 1e-6;
            let mut dx = DVector::zeros(x.len());
            dx[i] = h;
            let plus = coeffs(&(&x + &dx));
            let minus = coeffs(&(&x - &dx));
            for r in 0..6 {
                let numeric = (plus[r] - minus[r]) / (2.0 * h);
                assert!((numeric - jac[(r, i)]).abs() < 1e-7, "{r},{i}");
            }
        }
    }
}
