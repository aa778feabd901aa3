//! Offline fixed-interval Rauch-Tung-Striebel smoother over the forward filter's stored
//! posteriors, with the multiplicative attitude and the tangent-plane normals handled as
//! error states.
//!
//! Per step `k` (Crassidis & Junkins, *Optimal Estimation*, 2nd ed., Sec. 5.4.1, in error
//! form):
//!
//! ```text
//! P-(k+1) = Phi P+(k) Phi^T + Q                  (recomputed, not stored)
//! G       = P+(k) Phi^T P-(k+1)^-1
//! d       = x_s(k+1) [-] x-(k+1)                 (attitude: rotation vector of q_s q-^-1;
//!                                                  normals: tangent log map; others: minus)
//! x_s(k)  = x+(k) [+] G d                        (multiplicative attitude, rotated normals)
//! P_s(k)  = P+(k) + G (P_s(k+1) - P-(k+1)) G^T
//! ```
//!
//! `P-(k+1)` and `Phi P+(k)` differ from `P+(k)` only in the 6 attitude/bias rows and
//! columns and the diagonal noise, so they cost `O(36 n)`; the rest is faer's (Cholesky
//! of `P-(k+1)` with `n` right-hand sides, `(P_s - P-) G^T`, and the lower triangle of
//! `G (...)`), about `2.8 n^3` multiply-adds per step.
//!
//! Storage per step: the posterior state, the lower triangle of `P+`, the 6x6 `Phi` and `Qd`,
//! the calibration-state noise and the predicted attitude of the next step (about 13 kB for
//! 57 states; 95 MB for 7200 steps).

use nalgebra::{DMatrix, DVector, Matrix6, Vector3};
use pdcal_attitude::mekf::{apply_error, error_vector};
use pdcal_attitude::{Quat, rotate_normal_in, tangent_basis};

use crate::FilterError;
use crate::calibration::Calibration;
use crate::filter::{Filter, Propagation, RatePropagation, StateView};
use crate::layout::{ATTITUDE, BIAS, CORE, StateLayout};
use crate::output::StepEstimate;
use crate::rate::Motion;

struct Transition {
    phi: Matrix6<f64>,
    qd: Matrix6<f64>,
    /// The albedo gain's `e^(-dt/tau)` (1 without the state).
    albedo_gain_decay: f64,
    q_prior_next: Quat,
    /// With dynamics: the transition of `[a, beta, w, m]` instead of `phi`, `qd`.
    rate: Option<Box<RatePropagation>>,
}

struct Stored {
    index: usize,
    t_s: f64,
    segment: usize,
    q: Quat,
    bias: Vector3<f64>,
    scale: Vec<f64>,
    normal: Vec<Vector3<f64>>,
    extras: Vec<f64>,
    /// The albedo gain (0 without the state).
    albedo_gain: f64,
    /// The body rate and residual dipole, with dynamics.
    w: Option<Motion>,
    /// Whether the row's attitude error is small enough for the recursion's error state
    /// ([`SmootherStore::push_posterior`]).
    linear: bool,
    next: Option<Transition>,
}

/// The forward pass as the smoother needs it.
pub(crate) struct SmootherStore {
    n: usize,
    steps: Vec<Stored>,
    packed: Vec<f64>,
    cal_noise: Vec<f64>,
}

impl SmootherStore {
    pub(crate) fn new(n: usize, capacity: usize) -> Self {
        SmootherStore {
            n,
            steps: Vec::with_capacity(capacity),
            packed: Vec::with_capacity(capacity * n * (n + 1) / 2),
            cal_noise: Vec::with_capacity(capacity * n),
        }
    }

    /// Records the propagation from the last stored step to the current one.
    pub(crate) fn push_transition(
        &mut self,
        prop: &Propagation,
        q_prior: Quat,
        cal_noise: &DVector<f64>,
    ) {
        if let Some(last) = self.steps.last_mut() {
            last.next = Some(Transition {
                phi: prop.phi,
                qd: prop.qd,
                albedo_gain_decay: prop.albedo_gain_decay,
                q_prior_next: q_prior,
                rate: prop.rate.clone(),
            });
            self.cal_noise.extend(cal_noise.iter());
        }
    }

    /// Records the filter's posterior at row `index`; `linear`: whether its attitude
    /// error is small enough for the recursion, which composes rotation vectors and
    /// rotates no covariance. A row that is not, and the row before it, keep the forward
    /// estimate, and the recursion restarts there: with the Sun alone the rotation about
    /// the Sun line can be unknown to a half turn, far outside that range, and the gain
    /// would carry it into the directions across the line the forward pass holds.
    pub(crate) fn push_posterior(
        &mut self,
        index: usize,
        t_s: f64,
        segment: usize,
        filter: &Filter,
        linear: bool,
    ) {
        let (n, p) = (self.n, filter.covariance().as_slice());
        for j in 0..n {
            self.packed.extend_from_slice(&p[j * n + j..(j + 1) * n]);
        }
        self.steps.push(Stored {
            index,
            t_s,
            segment,
            q: filter.q(),
            bias: filter.bias_rad_s(),
            scale: filter.scales_v(),
            normal: filter.normals(),
            extras: filter.extra_values(),
            albedo_gain: filter.albedo_gain().unwrap_or(0.0),
            w: filter.motion(),
            linear,
            next: None,
        });
    }

    /// The stored lower triangle of step `k` into `p` (both triangles).
    fn unpack_into(&self, k: usize, p: &mut DMatrix<f64>) {
        let n = self.n;
        let tri = n * (n + 1) / 2;
        let data = &self.packed[k * tri..(k + 1) * tri];
        let target = p.as_mut_slice();
        let mut at = 0;
        for j in 0..n {
            let len = n - j;
            target[j * n + j..(j + 1) * n].copy_from_slice(&data[at..at + len]);
            at += len;
        }
        p.fill_upper_triangle_with_lower_triangle();
    }

    /// Runs the backward pass; one estimate per stored step.
    pub(crate) fn smooth(
        &self,
        layout: &StateLayout,
        fixed: Option<&Calibration>,
    ) -> Result<Vec<StepEstimate>, FilterError> {
        let mut out = Vec::with_capacity(self.steps.len());
        self.smooth_into(layout, fixed, None, &mut |e| out.push(e))?;
        out.reverse();
        Ok(out)
    }

    /// The backward pass over the stored steps, last first, each smoothed estimate handed
    /// to `emit`. Without `boundary` it starts from the last stored posterior (the end of
    /// the data) and emits it; with `boundary`, the smoothed state of the last stored row
    /// (computed by the pass over the rows after it), it starts there and emits from the
    /// row before. Returns the smoothed state of the first stored row: the boundary of the
    /// segment before (`None` when nothing is stored).
    pub(crate) fn smooth_into(
        &self,
        layout: &StateLayout,
        fixed: Option<&Calibration>,
        boundary: Option<Boundary>,
        emit: &mut dyn FnMut(StepEstimate),
    ) -> Result<Option<Boundary>, FilterError> {
        let Some(last) = self.steps.len().checked_sub(1) else {
            return Ok(boundary);
        };
        let n = self.n;
        let (mut xs, mut ps) = match boundary {
            Some(b) => (b.state, b.p),
            None => {
                let mut ps = DMatrix::zeros(n, n);
                self.unpack_into(last, &mut ps);
                let xs = SmoothedState::from_stored(&self.steps[last]);
                emit(xs.estimate(&self.steps[last], &ps, layout, fixed));
                (xs, ps)
            }
        };
        let mut work = Work::new(n);
        let mut d = DVector::zeros(n);
        let mut delta = DVector::zeros(n);
        for k in (0..last).rev() {
            let stored = &self.steps[k];
            let trans = stored
                .next
                .as_ref()
                .ok_or(FilterError::NotPositiveDefinite {
                    index: stored.index,
                })?;
            self.unpack_into(k, &mut work.pf);
            if !(stored.linear && self.steps[k + 1].linear) {
                xs = SmoothedState::from_stored(stored);
                ps.copy_from(&work.pf);
                emit(xs.estimate(stored, &ps, layout, fixed));
                continue;
            }
            work.predict(
                trans,
                &self.cal_noise[k * n..(k + 1) * n],
                layout.albedo_gain(),
            );
            work.gain_transposed()
                .map_err(|_| FilterError::NotPositiveDefinite {
                    index: stored.index,
                })?;
            xs.difference(&trans.q_prior_next, stored, layout, &mut d);
            // delta = G d with G = gt^T.
            delta.gemv_tr(1.0, &work.gt, &d, 0.0);
            xs = SmoothedState::from_stored(stored).plus(&delta, layout);
            work.smoothed_covariance(&mut ps);
            emit(xs.estimate(stored, &ps, layout, fixed));
        }
        Ok(Some(Boundary { state: xs, p: ps }))
    }

    /// Whether no step is stored.
    pub(crate) fn is_empty(&self) -> bool {
        self.steps.is_empty()
    }

    /// Forgets every stored step (keeps the allocations).
    pub(crate) fn clear(&mut self) {
        self.steps.clear();
        self.packed.clear();
        self.cal_noise.clear();
    }
}

/// The smoothed state and covariance at the first row of a segment of the backward pass.
pub(crate) struct Boundary {
    state: SmoothedState,
    p: DMatrix<f64>,
}

/// Work matrices of one backward step (allocated once per pass).
struct Work {
    /// `P+(k)`.
    pf: DMatrix<f64>,
    /// `P-(k+1) = Phi P+(k) Phi^T + Q`.
    pp: DMatrix<f64>,
    /// `Phi P+(k)`, then `G^T = P-(k+1)^-1 Phi P+(k)`.
    gt: DMatrix<f64>,
    /// `P_s(k+1) - P-(k+1)`, then `(P_s(k+1) - P-(k+1)) G^T`.
    diff: DMatrix<f64>,
    tmp: DMatrix<f64>,
}

impl Work {
    fn new(n: usize) -> Self {
        Work {
            pf: DMatrix::zeros(n, n),
            pp: DMatrix::zeros(n, n),
            gt: DMatrix::zeros(n, n),
            diff: DMatrix::zeros(n, n),
            tmp: DMatrix::zeros(n, n),
        }
    }

    /// `gt = Phi P+` and `pp = Phi P+ Phi^T + Q` with `Phi = diag(Phi6, I)`, the albedo
    /// gain's (index `gain`) diagonal entry its decay: only the first 6 rows (and columns)
    /// and the gain's differ from `P+` (`O(36 n)` instead of two `n^3` products); `pp`
    /// mirrored from its lower triangle so that it is exactly symmetric.
    fn predict(&mut self, trans: &Transition, cal_noise: &[f64], gain: Option<usize>) {
        let decay = trans.albedo_gain_decay;
        if let Some(rate) = &trans.rate {
            self.gt.copy_from(&self.pf);
            crate::rate::left_multiply(&mut self.gt, &rate.idx, &rate.phi);
            if let Some(g) = gain {
                let mut row = self.gt.row_mut(g);
                row *= decay;
            }
            self.pp.copy_from(&self.gt);
            crate::rate::right_multiply_transpose(&mut self.pp, &rate.idx, &rate.phi);
            if let Some(g) = gain {
                let mut column = self.pp.column_mut(g);
                column *= decay;
            }
            crate::rate::add_noise(&mut self.pp, &rate.idx, &rate.qd, cal_noise);
            self.pp.fill_upper_triangle_with_lower_triangle();
            return;
        }
        let n = self.pf.nrows();
        self.gt.copy_from(&self.pf);
        let top = trans.phi * self.pf.rows(0, CORE);
        self.gt.rows_mut(0, CORE).copy_from(&top);
        if let Some(g) = gain {
            let mut row = self.gt.row_mut(g);
            row *= decay;
        }
        self.pp.copy_from(&self.gt);
        let left = self.gt.columns(0, CORE) * trans.phi.transpose();
        self.pp.columns_mut(0, CORE).copy_from(&left);
        if let Some(g) = gain {
            let mut column = self.pp.column_mut(g);
            column *= decay;
        }
        let mut corner = self.pp.fixed_view_mut::<CORE, CORE>(0, 0);
        corner += trans.qd;
        for (i, q) in cal_noise.iter().enumerate().take(n).skip(CORE) {
            self.pp[(i, i)] += q;
        }
        self.pp.fill_upper_triangle_with_lower_triangle();
    }

    /// `gt <- P-^-1 gt`, i.e. `G^T` (Cholesky of `P-`, faer).
    fn gain_transposed(&mut self) -> Result<(), faer::linalg::cholesky::llt::factor::LltError> {
        use faer::linalg::solvers::Solve;
        let n = self.pp.nrows();
        let pp = faer::MatRef::from_column_major_slice(self.pp.as_slice(), n, n);
        let llt = pp.llt(faer::Side::Lower)?;
        let gt = faer::MatMut::from_column_major_slice_mut(self.gt.as_mut_slice(), n, n);
        llt.solve_in_place(gt);
        Ok(())
    }

    /// `ps <- P+ + G (ps - P-) G^T` (lower triangle by faer's triangular product, mirrored).
    fn smoothed_covariance(&mut self, ps: &mut DMatrix<f64>) {
        use faer::linalg::matmul::triangular::{BlockStructure, matmul};
        let n = ps.nrows();
        self.diff.copy_from(ps);
        self.diff -= &self.pp;
        fn view(m: &DMatrix<f64>) -> faer::MatRef<'_, f64> {
            faer::MatRef::from_column_major_slice(m.as_slice(), m.nrows(), m.ncols())
        }
        let gt = view(&self.gt);
        faer::linalg::matmul::matmul(
            faer::MatMut::from_column_major_slice_mut(self.tmp.as_mut_slice(), n, n),
            faer::Accum::Replace,
            view(&self.diff),
            gt,
            1.0,
            faer::Par::Seq,
        );
        ps.copy_from(&self.pf);
        matmul(
            faer::MatMut::from_column_major_slice_mut(ps.as_mut_slice(), n, n),
            BlockStructure::TriangularLower,
            faer::Accum::Add,
            gt.transpose(),
            BlockStructure::Rectangular,
            view(&self.tmp),
            BlockStructure::Rectangular,
            1.0,
            faer::Par::Seq,
        );
        ps.fill_upper_triangle_with_lower_triangle();
    }
}

struct SmoothedState {
    q: Quat,
    bias: Vector3<f64>,
    scale: Vec<f64>,
    normal: Vec<Vector3<f64>>,
    extras: Vec<f64>,
    albedo_gain: f64,
    w: Option<Motion>,
}

impl SmoothedState {
    fn from_stored(s: &Stored) -> Self {
        SmoothedState {
            q: s.q,
            bias: s.bias,
            scale: s.scale.clone(),
            normal: s.normal.clone(),
            extras: s.extras.clone(),
            albedo_gain: s.albedo_gain,
            w: s.w,
        }
    }

    /// `self [-] prior(k+1)`, where the prior's calibration equals the posterior at `k`.
    fn difference(
        &self,
        q_prior: &Quat,
        prev: &Stored,
        layout: &StateLayout,
        d: &mut DVector<f64>,
    ) {
        d.fill(0.0);
        if let (Some(k), Some(w), Some(rate)) = (
            layout.rate(),
            self.w,
            prev.next.as_ref().and_then(|t| t.rate.as_ref()),
        ) {
            d.fixed_rows_mut::<3>(k)
                .copy_from(&(w.w_body_rad_s - rate.w_prior_body_rad_s));
        }
        if let (Some(k), Some(c), Some(w), Some(prev_w)) =
            (layout.dipole(), layout.moment_fraction(), self.w, prev.w)
        {
            d.fixed_rows_mut::<3>(k)
                .copy_from(&(w.dipole_body_a_m2 - prev_w.dipole_body_a_m2));
            d.fixed_rows_mut::<3>(c)
                .copy_from(&(w.moment_fraction - prev_w.moment_fraction));
        }
        let a = error_vector(&self.q, q_prior);
        d.fixed_rows_mut::<3>(ATTITUDE).copy_from(&a);
        d.fixed_rows_mut::<3>(BIAS)
            .copy_from(&(self.bias - prev.bias));
        for i in 0..layout.photodiodes() {
            d[layout.scale(i)] = self.scale[i] - prev.scale[i];
            if let Some(k) = layout.normal(i) {
                let basis = layout.tangent_basis(i, &prev.normal[i]);
                let (d1, d2) = tangent_log_in(&prev.normal[i], &self.normal[i], &basis);
                d[k] = d1;
                d[k + 1] = d2;
            }
        }
        for (e, (s, p)) in layout
            .extras()
            .iter()
            .zip(self.extras.iter().zip(&prev.extras))
        {
            d[e.state] = s - p;
        }
        if let (Some(g), Some(t)) = (layout.albedo_gain(), prev.next.as_ref()) {
            d[g] = self.albedo_gain - t.albedo_gain_decay * prev.albedo_gain;
        }
    }

    fn plus(mut self, delta: &DVector<f64>, layout: &StateLayout) -> Self {
        let a = Vector3::new(delta[ATTITUDE], delta[ATTITUDE + 1], delta[ATTITUDE + 2]);
        self.q = apply_error(&self.q, &a);
        self.bias += Vector3::new(delta[BIAS], delta[BIAS + 1], delta[BIAS + 2]);
        for i in 0..layout.photodiodes() {
            self.scale[i] += delta[layout.scale(i)];
            if let Some(k) = layout.normal(i) {
                let (e1, e2) = layout.tangent_basis(i, &self.normal[i]);
                self.normal[i] =
                    rotate_normal_in(&self.normal[i], (&e1, &e2), delta[k], delta[k + 1]);
            }
        }
        for (e, v) in layout.extras().iter().zip(self.extras.iter_mut()) {
            *v += delta[e.state];
        }
        if let Some(g) = layout.albedo_gain() {
            self.albedo_gain += delta[g];
        }
        if let (Some(k), Some(w)) = (layout.rate(), self.w.as_mut()) {
            w.w_body_rad_s += Vector3::new(delta[k], delta[k + 1], delta[k + 2]);
            w.dipole_body_a_m2 += Vector3::new(delta[k + 3], delta[k + 4], delta[k + 5]);
            w.moment_fraction += Vector3::new(delta[k + 6], delta[k + 7], delta[k + 8]);
        }
        self
    }

    fn estimate(
        &self,
        at: &Stored,
        p: &DMatrix<f64>,
        layout: &StateLayout,
        fixed: Option<&Calibration>,
    ) -> StepEstimate {
        let view = StateView {
            bias: self.bias,
            scale: self.scale.as_slice().into(),
            normal: self.normal.as_slice().into(),
            extras: self.extras.clone(),
            p,
        };
        crate::output::step_estimate(at.index, at.t_s, at.segment, self.q, &view, layout, fixed)
    }
}

/// The tangent correction `(d1, d2)` with `rotate_normal(from, d1, d2) == to`: the inverse
/// of [`rotate_normal`] (log map on the sphere), in [`tangent_basis`]`(from)`.
pub fn tangent_log(from: &Vector3<f64>, to: &Vector3<f64>) -> (f64, f64) {
    tangent_log_in(from, to, &tangent_basis(from))
}

/// [`tangent_log`] in a given tangent basis `(e1, e2)` of `from` (e.g. the filter's
/// [`StateLayout::tangent_basis`]).
pub fn tangent_log_in(
    from: &Vector3<f64>,
    to: &Vector3<f64>,
    (e1, e2): &(Vector3<f64>, Vector3<f64>),
) -> (f64, f64) {
    let c = from.dot(to);
    let t = to - from * c;
    let sin = t.norm();
    if sin == 0.0 {
        return (0.0, 0.0);
    }
    let v = t * (sin.atan2(c) / sin);
    (v.dot(e1), v.dot(e2))
}
