//! One step's sequential scalar updates (Eqs. 4-7), for [`crate::Algebra::Structured`].
//!
//! The `m` scalar rows `h_l` of a step are all linearised at the prior `x_0, P_0` (built
//! before the first update, so the updates are one tight loop). For `l = 1..m`, skipping
//! the rows the gate rejects:
//!
//! ```text
//! u_l = P_{l-1} h_l = P_0 h_l - W (W[idx_l, :]^T h_l),  s_l = h_l u_l + r_l,
//! nu_l = y_l - h_l(x_0) - h_l dx_{l-1},  dx_l = dx_{l-1} + u_l nu_l / s_l,
//! P_l = P_0 - W W^T with the column w_l = u_l / sqrt(s_l) appended to W.
//! ```
//!
//! `u_l` is one pass of [`algebra::weighted_sum`] over the 6 columns of `P_0` the row
//! touches and the `l - 1` columns of `W`; `P = P_0 - W W^T` is formed once, after the
//! step, by the caller ([`algebra::apply_pending`]).
//!
//! (The Cholesky form of the same recursion, every scalar in the `m x m` space of
//! `H P_0 H^T + R` first and the `n`-vectors after, is slower here: its small-space
//! recursion and the products `H P_0 H^T` cost more than the serial chain it removes;
//! docs/performance.md has the measurement.)

use crate::algebra::{self, Pending, Picked, Run};

/// The step's scalar rows, linearised at the prior.
#[derive(Debug)]
pub(crate) struct Rows {
    /// Row `l`'s non-zeros are `idx/val[start[l]..start[l + 1]]`.
    start: Vec<usize>,
    idx: Vec<usize>,
    val: Vec<f64>,
    /// `y - h(x_0)`.
    innovation: Vec<f64>,
    /// Measurement variance.
    r: Vec<f64>,
    /// A fate settled before the sequence (a row of a vector gated as a whole), else `None`:
    /// the scalar gate decides.
    decided: Vec<Option<bool>>,
}

impl Rows {
    /// Room for `rows` rows with `entries` non-zeros in all.
    pub(crate) fn with_capacity(rows: usize, entries: usize) -> Self {
        let mut start = Vec::with_capacity(rows + 1);
        start.push(0);
        Rows {
            start,
            idx: Vec::with_capacity(entries),
            val: Vec::with_capacity(entries),
            innovation: Vec::with_capacity(rows),
            r: Vec::with_capacity(rows),
            decided: Vec::with_capacity(rows),
        }
    }

    /// No rows.
    pub(crate) fn clear(&mut self) {
        self.start.clear();
        self.start.push(0);
        self.idx.clear();
        self.val.clear();
        self.innovation.clear();
        self.r.clear();
        self.decided.clear();
    }

    /// Number of rows.
    pub(crate) fn len(&self) -> usize {
        self.innovation.len()
    }

    /// Starts a row with innovation `y - h(x_0)` and variance `r`; its non-zeros follow
    /// through [`Rows::entry`].
    pub(crate) fn begin(&mut self, innovation: f64, r: f64) {
        self.innovation.push(innovation);
        self.r.push(r);
        self.decided.push(None);
        self.start.push(self.idx.len());
    }

    /// As [`Rows::begin`] for a row whose acceptance was decided with the other components
    /// of its vector (the magnetometer's Mahalanobis gate): the scalar gate is not applied.
    pub(crate) fn begin_decided(&mut self, innovation: f64, r: f64, accepted: bool) {
        self.begin(innovation, r);
        if let Some(d) = self.decided.last_mut() {
            *d = Some(accepted);
        }
    }

    /// Whether row `l` passes: its settled fate, else `nu^2 <= gate2 s`.
    pub(crate) fn accepts(&self, l: usize, nu: f64, spread: f64, gate2: f64) -> bool {
        self.decided[l].unwrap_or(nu * nu <= gate2 * spread)
    }

    /// Row `l`'s residual after the correction `dx` of the whole step, linearised:
    /// `y - h(x_0) - h_l dx`.
    pub(crate) fn after(&self, l: usize, dx: &[f64]) -> f64 {
        let (idx, val) = self.row(l);
        self.innovation[l] - idx.iter().zip(val).map(|(&k, &v)| v * dx[k]).sum::<f64>()
    }

    /// Appends a non-zero `(state, value)` to the last row.
    pub(crate) fn entry(&mut self, state: usize, value: f64) {
        self.idx.push(state);
        self.val.push(value);
        if let Some(end) = self.start.last_mut() {
            *end = self.idx.len();
        }
    }

    /// Row `l`: its states and values.
    pub(crate) fn row(&self, l: usize) -> (&[usize], &[f64]) {
        let range = self.start[l]..self.start[l + 1];
        (&self.idx[range.clone()], &self.val[range])
    }

    /// Adds `h_l d` to every row's innovation: rows linearised at `x + d` read as rows
    /// about the prior mean `x`.
    pub(crate) fn shift_innovations(&mut self, d: &[f64]) {
        for l in 0..self.innovation.len() {
            let range = self.start[l]..self.start[l + 1];
            let shift: f64 = self.idx[range.clone()]
                .iter()
                .zip(&self.val[range])
                .map(|(&k, &v)| v * d[k])
                .sum();
            self.innovation[l] += shift;
        }
    }

    /// Row `l`'s innovation at the prior and its variance.
    pub(crate) fn innovation_and_variance(&self, l: usize) -> (f64, f64) {
        (self.innovation[l], self.r[l])
    }
}

/// What became of one row.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Outcome {
    /// `nu_l`, with the corrections of the rows before it.
    pub residual: f64,
    /// `s_l = h_l P_{l-1} h_l^T + r_l`.
    pub spread: f64,
    /// Whether the gate let it through.
    pub accepted: bool,
}

/// Work space of [`update`] (grows to the largest step, then allocates nothing).
#[derive(Debug, Default)]
pub(crate) struct Workspace {
    /// `u_l` (padded length).
    u: Vec<f64>,
    /// `-W[idx_l, :]^T h_l`, the weights of `W`'s columns in `u_l`.
    weight: Vec<f64>,
}

/// Applies `rows` to the prior `p` (`n x n`, column-major, `n` that of `pending`): outcomes
/// per row in `outcome`, the state correction added to `dx` (length `n`, zero on entry for
/// a step), and the accepted rows' `w_l` as the columns of `pending`. Gate:
/// `nu^2 <= gate2 s` for rows not decided beforehand ([`Rows::accepts`]).
pub(crate) fn update(
    p: &[f64],
    rows: &Rows,
    gate2: f64,
    pending: &mut Pending,
    work: &mut Workspace,
    dx: &mut [f64],
    outcome: &mut Vec<Outcome>,
) {
    let (m, n, ld) = (rows.len(), pending.n(), pending.ld());
    outcome.clear();
    work.u.resize(ld, 0.0);
    let w = pending.columns_mut(m);
    let mut count = 0;
    for l in 0..m {
        let (idx, val) = rows.row(l);
        let (innovation, r) = rows.innovation_and_variance(l);
        let (done, rest) = w.split_at_mut(count * ld);
        pending_weights(idx, val, done, ld, &mut work.weight);
        let picked = Picked {
            data: p,
            ld: n,
            idx,
            weight: val,
        };
        let run = Run {
            data: done,
            ld,
            weight: &work.weight,
        };
        let u = &mut work.u[..ld];
        algebra::weighted_sum(n, picked, run, u);
        let hph: f64 = idx.iter().zip(val).map(|(&k, v)| v * u[k]).sum();
        let h_dx: f64 = idx.iter().zip(val).map(|(&k, v)| v * dx[k]).sum();
        let spread = hph + r;
        let nu = innovation - h_dx;
        let accepted = rows.accepts(l, nu, spread, gate2);
        outcome.push(Outcome {
            residual: nu,
            spread,
            accepted,
        });
        if !accepted {
            continue;
        }
        let gain = nu / spread;
        for (x, u) in dx.iter_mut().zip(u.iter()) {
            *x += gain * u;
        }
        let inv = 1.0 / spread.sqrt();
        for (x, u) in rest[..ld].iter_mut().zip(u.iter()) {
            *x = u * inv;
        }
        count += 1;
    }
    pending.columns_mut(count);
}

/// `weight = -W[idx, :]^T val` over the columns `done` of `W` (leading dimension `ld`),
/// summed in `idx` order.
fn pending_weights(idx: &[usize], val: &[f64], done: &[f64], ld: usize, weight: &mut Vec<f64>) {
    weight.clear();
    weight.resize(done.len() / ld, 0.0);
    for (&k, &v) in idx.iter().zip(val) {
        for (c, column) in weight.iter_mut().zip(done.chunks_exact(ld)) {
            *c -= v * column[k];
        }
    }
}
