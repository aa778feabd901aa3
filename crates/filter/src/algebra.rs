//! The structured filter's covariance kernels, on column-major storage: the sparse
//! `P H^T` with the pending downdates' share, and the rank-k downdate `P -= W W^T` of the
//! lower triangle followed by the mirror that keeps `P` exactly symmetric.
//!
//! Why hand-written: the workspace compiles for the x86-64 baseline (SSE2, no FMA) and
//! forbids `unsafe`; `pulp` dispatches these loops at run time to AVX2+FMA or AVX-512, 4 to
//! 8 times the baseline's throughput. faer's (also pulp-based) triangular product does the
//! downdate in about twice the time at n = 57 (its general kernels pay per-call overhead
//! at this size) and nalgebra's `gemm` (matrixmultiply) allocates its packing buffers per
//! call.
//!
//! `W` is stored with a leading dimension padded to a multiple of [`ROW_BLOCK`] (the pad
//! rows are zero), so that the inner loops load whole vectors without masks.

use pulp::{Simd, WithSimd};

/// Rows per register tile (two AVX-512 vectors, four AVX2 vectors' worth of two): `W`'s
/// leading dimension is a multiple of this.
pub(crate) const ROW_BLOCK: usize = 16;

/// Columns of `P` per register tile.
const COL_BLOCK: usize = 4;

/// `n` rounded up to a multiple of [`ROW_BLOCK`].
pub(crate) fn padded(n: usize) -> usize {
    n.div_ceil(ROW_BLOCK) * ROW_BLOCK
}

/// The pending rank-1 downdates `w_l` (columns of `W`, padded leading dimension).
#[derive(Debug, Clone)]
pub(crate) struct Pending {
    n: usize,
    ld: usize,
    data: Vec<f64>,
    count: usize,
    /// `sum_l W[i, l]^2`, kept as the columns arrive (the filter reads diagonal entries of
    /// the current `P` for the second-order noise terms).
    diag: Vec<f64>,
}

impl Pending {
    /// Room for `capacity` columns of length `n`.
    pub(crate) fn new(n: usize, capacity: usize) -> Self {
        let ld = padded(n);
        Pending {
            n,
            ld,
            data: vec![0.0; ld * capacity],
            count: 0,
            diag: vec![0.0; n],
        }
    }

    /// Number of pending columns.
    pub(crate) fn len(&self) -> usize {
        self.count
    }

    /// Drops the pending columns (after they were applied).
    pub(crate) fn clear(&mut self) {
        self.count = 0;
        self.diag.fill(0.0);
    }

    fn column(&self, l: usize) -> &[f64] {
        &self.data[l * self.ld..(l + 1) * self.ld]
    }

    /// Appends `scale * u` (`u` of length at least `n`).
    pub(crate) fn push(&mut self, u: &[f64], scale: f64) {
        let (n, at) = (self.n, self.count * self.ld);
        if at + self.ld > self.data.len() {
            // More updates in a step than planned: grow (never in the filter's own use).
            self.data.resize(at + self.ld, 0.0);
        }
        for ((w, x), d) in self.data[at..at + n]
            .iter_mut()
            .zip(&u[..n])
            .zip(&mut self.diag)
        {
            *w = scale * x;
            *d += *w * *w;
        }
        self.count += 1;
    }

    /// `sum_l W[i, l]^2`: the pending share of `P[i, i]`.
    pub(crate) fn diagonal(&self, i: usize) -> f64 {
        self.diag[i]
    }
}

/// `u = P[:, idx] val - W (W[idx, :]^T val)`: `P H^T` for a sparse row `H` under the
/// pending downdates. `p` is `n x n` column-major; `u` has length at least the padded `n`
/// (its pad entries come out zero). `c` is scratch of length at least `pending.len()`.
pub(crate) fn sparse_times(
    p: &[f64],
    pending: &Pending,
    idx: &[usize],
    val: &[f64],
    c: &mut Vec<f64>,
    u: &mut [f64],
) {
    c.clear();
    c.extend((0..pending.len()).map(|l| {
        let w = pending.column(l);
        -idx.iter().zip(val).map(|(&i, v)| v * w[i]).sum::<f64>()
    }));
    pulp::Arch::new().dispatch(SparseTimes {
        p,
        pending,
        idx,
        val,
        c,
        u,
    });
}

struct SparseTimes<'a> {
    p: &'a [f64],
    pending: &'a Pending,
    idx: &'a [usize],
    val: &'a [f64],
    c: &'a [f64],
    u: &'a mut [f64],
}

impl WithSimd for SparseTimes<'_> {
    type Output = ();

    /// Blocks of up to [`VECTORS`] vectors of rows held in registers while the `6 + k`
    /// columns stream through: independent FMA chains instead of one per row chunk.
    #[inline(always)]
    fn with_simd<S: Simd>(self, simd: S) {
        let SparseTimes {
            p,
            pending,
            idx,
            val,
            c,
            u,
        } = self;
        let (n, ld) = (pending.n, pending.ld);
        let lanes = S::F64_LANES;
        let mut r0 = 0;
        while r0 < ld {
            let count = ((ld - r0) / lanes).min(VECTORS);
            let mut acc = [simd.splat_f64s(0.0); VECTORS];
            for (&k, &v) in idx.iter().zip(val) {
                let column = &p[k * n..(k + 1) * n];
                let v = simd.splat_f64s(v);
                for (b, a) in acc.iter_mut().enumerate().take(count) {
                    let start = (r0 + b * lanes).min(n);
                    let x = load(simd, &column[start..(start + lanes).min(n)]);
                    *a = simd.mul_add_f64s(x, v, *a);
                }
            }
            for (l, &cl) in c.iter().enumerate() {
                let w = &pending.column(l)[r0..r0 + count * lanes];
                let (w, _) = S::as_simd_f64s(w);
                let cl = simd.splat_f64s(cl);
                for (a, x) in acc.iter_mut().zip(w) {
                    *a = simd.mul_add_f64s(*x, cl, *a);
                }
            }
            let (out, _) = S::as_mut_simd_f64s(&mut u[r0..r0 + count * lanes]);
            for (o, a) in out.iter_mut().zip(acc) {
                *o = a;
            }
            r0 += count * lanes;
        }
    }
}

/// Vectors of rows per block of [`sparse_times`] (8 independent FMA chains cover the FMA
/// latency on two ports).
const VECTORS: usize = 8;

/// `P -= W W^T` on the lower triangle (and some entries above it in the diagonal tiles),
/// then the upper triangle mirrored from the lower: `P` exactly symmetric. Clears
/// `pending`.
pub(crate) fn apply_pending(p: &mut [f64], pending: &mut Pending) {
    if pending.len() == 0 {
        return;
    }
    pulp::Arch::new().dispatch(LowerDowndate {
        p: &mut *p,
        pending,
    });
    mirror_lower(p, pending.n);
    pending.clear();
}

struct LowerDowndate<'a> {
    p: &'a mut [f64],
    pending: &'a Pending,
}

impl WithSimd for LowerDowndate<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: Simd>(self, simd: S) {
        let LowerDowndate { p, pending } = self;
        let n = pending.n;
        // Two vectors of rows per tile when they fit in ROW_BLOCK (AVX-512: 2 x 8).
        let lanes = S::F64_LANES;
        let mut j0 = 0;
        while j0 < n {
            let jb = (n - j0).min(COL_BLOCK);
            let mut i = j0 - j0 % (2 * lanes);
            while i < n {
                tile(simd, p, pending, i, j0, jb);
                i += 2 * lanes;
            }
            j0 += jb;
        }
    }
}

/// One register tile: rows `i..i + 2 lanes` (clipped to `n`) of columns `j0..j0 + jb`.
#[inline(always)]
fn tile<S: Simd>(simd: S, p: &mut [f64], pending: &Pending, i: usize, j0: usize, jb: usize) {
    let (n, ld) = (pending.n, pending.ld);
    let lanes = S::F64_LANES;
    let mid = (i + lanes).min(n);
    let end = (i + 2 * lanes).min(n);
    let zero = simd.splat_f64s(0.0);
    let mut a = [zero; COL_BLOCK];
    let mut b = [zero; COL_BLOCK];
    // Fixed trip counts (COL_BLOCK) so that the tile stays in registers.
    for c in 0..COL_BLOCK {
        if c < jb {
            let column = &p[(j0 + c) * n..(j0 + c + 1) * n];
            a[c] = load(simd, &column[i..mid]);
            b[c] = load(simd, &column[mid..end]);
        }
    }
    for l in 0..pending.count {
        let w = &pending.data[l * ld..(l + 1) * ld];
        let (rows, _) = S::as_simd_f64s(&w[i..i + 2 * lanes]);
        let (wa, wb) = (rows[0], rows[1]);
        for c in 0..COL_BLOCK {
            // Columns past n read the zero pad: harmless, never stored.
            let s = simd.splat_f64s(w[j0 + c]);
            a[c] = simd.negate_mul_add_f64s(wa, s, a[c]);
            b[c] = simd.negate_mul_add_f64s(wb, s, b[c]);
        }
    }
    for c in 0..COL_BLOCK {
        if c < jb {
            let column = &mut p[(j0 + c) * n..(j0 + c + 1) * n];
            store(simd, &mut column[i..mid], a[c]);
            store(simd, &mut column[mid..end], b[c]);
        }
    }
}

/// A vector from `s` (at most one vector long; zeros past its end). A short slice goes
/// through a stack buffer: pulp's masked loads call through a function-pointer table.
#[inline(always)]
fn load<S: Simd>(simd: S, s: &[f64]) -> S::f64s {
    if s.len() == S::F64_LANES {
        S::as_simd_f64s(s).0[0]
    } else {
        let mut buffer = [0.0; 8];
        buffer[..s.len()].copy_from_slice(s);
        let _ = simd;
        S::as_simd_f64s(&buffer[..S::F64_LANES]).0[0]
    }
}

/// Stores the first `s.len()` lanes of `v` (at most one vector).
#[inline(always)]
fn store<S: Simd>(simd: S, s: &mut [f64], v: S::f64s) {
    let _ = simd;
    if s.len() == S::F64_LANES {
        S::as_mut_simd_f64s(s).0[0] = v;
    } else {
        let mut buffer = [0.0; 8];
        S::as_mut_simd_f64s(&mut buffer[..S::F64_LANES]).0[0] = v;
        let len = s.len();
        s.copy_from_slice(&buffer[..len]);
    }
}

/// Copies the strict lower triangle of the `n x n` column-major `p` onto the upper.
fn mirror_lower(p: &mut [f64], n: usize) {
    for j in 1..n {
        for i in 0..j {
            p[j * n + i] = p[i * n + j];
        }
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{DMatrix, DVector};

    use super::*;

    fn pending_from(w: &DMatrix<f64>) -> Pending {
        let mut pending = Pending::new(w.nrows(), 1);
        for l in 0..w.ncols() {
            pending.push(w.column(l).as_slice(), 1.0);
        }
        pending
    }

    #[test]
    fn downdate_matches_the_textbook_product() {
        // Sizes around the tile edges: 1, 4, 16, 17 and the 17-photodiode 57.
        for (n, k) in [(1, 1), (4, 3), (16, 5), (17, 2), (57, 20)] {
            let p0 = DMatrix::from_fn(n, n, |i, j| {
                ((i * 7 + j * 7) % 11) as f64 + 30.0 * f64::from(u8::from(i == j))
            });
            let w = DMatrix::from_fn(n, k, |i, j| ((i * 5 + j * 3) % 13) as f64 * 0.1);
            let mut p = p0.clone();
            let mut pending = pending_from(&w);
            apply_pending(p.as_mut_slice(), &mut pending);
            let expected = &p0 - &w * w.transpose();
            // Same products, summation order up to the kernel: rounding only (entries ~30).
            assert!((&p - expected).abs().max() < 1e-12, "n {n} k {k}");
            assert_eq!(p, p.transpose(), "n {n}: exactly symmetric");
            assert_eq!(pending.len(), 0);
        }
    }

    #[test]
    fn sparse_times_matches_the_textbook_product() {
        for n in [3, 17, 57] {
            let p = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 7) % 11) as f64);
            let w = DMatrix::from_fn(n, 5, |i, j| ((i * 5 + j * 3) % 13) as f64 * 0.1);
            let (idx, val) = ([0usize, 2, n - 1], [0.5, -1.0, 2.0]);
            let mut h = DVector::zeros(n);
            for (&i, &v) in idx.iter().zip(&val) {
                h[i] += v;
            }
            let pending = pending_from(&w);
            let mut u = vec![f64::NAN; padded(n)];
            sparse_times(p.as_slice(), &pending, &idx, &val, &mut Vec::new(), &mut u);
            let expected = (&p - &w * w.transpose()) * h;
            for i in 0..n {
                // Rounding only (entries ~10).
                assert!((u[i] - expected[i]).abs() < 1e-12, "n {n} row {i}");
            }
            assert!(u[n..].iter().all(|&x| x == 0.0), "pad rows zero");
        }
    }
}
