//! The structured filter's covariance kernels, on column-major storage: the sparse
//! `P H^T` with the pending downdates' share, and the rank-k downdate `P -= W W^T` of the
//! lower triangle followed by the mirror that keeps `P` exactly symmetric.
//!
//! Why hand-written: the workspace forbids `unsafe`; `pulp` dispatches these loops at run
//! time to AVX2+FMA or AVX-512 (4 to 8 times the SSE2 baseline's throughput). faer's (also
//! pulp-based) triangular product does the downdate in about twice the time at n = 57 (its
//! general kernels pay per-call overhead at this size) and nalgebra's `gemm`
//! (matrixmultiply) allocates its packing buffers per call.
//!
//! `W` is stored with a leading dimension of at least `n + ROW_BLOCK` (the pad rows are
//! zero), so that a register tile of rows starting anywhere below `n` loads whole vectors
//! of `W` without masks.
//!
//! The kernels are written so that LLVM sees fixed trip counts and whole-vector loads in
//! every inner loop: a `P` column is not padded (it belongs to the public `DMatrix`), so
//! [`sparse_times`] covers its last rows with one vector ending at row `n` (overlapping the
//! one before it, whose rows it recomputes with the same operations, hence the same bits)
//! instead of a masked load.

use pulp::{Simd, WithSimd};

/// Rows per register tile at most (two AVX-512 vectors): `W`'s pad is at least this.
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
    /// Columns of `W` at `l * ld`, plus one zero column past the last (so that every
    /// column can be read from any row offset below `ld`, see [`apply_pending`]).
    data: Vec<f64>,
    capacity: usize,
    count: usize,
    /// `sum_l W[i, l]^2`, kept as the columns arrive (the filter reads diagonal entries of
    /// the current `P` for the second-order noise terms).
    diag: Vec<f64>,
}

impl Pending {
    /// Room for `capacity` columns of length `n`.
    pub(crate) fn new(n: usize, capacity: usize) -> Self {
        let ld = padded(n + ROW_BLOCK);
        let capacity = capacity.max(1);
        Pending {
            n,
            ld,
            data: vec![0.0; ld * (capacity + 1)],
            capacity,
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

    /// Appends `scale * u` (`u` of length at least `n`).
    pub(crate) fn push(&mut self, u: &[f64], scale: f64) {
        if self.count == self.capacity {
            // More updates in a step than planned: grow (never in the filter's own use).
            self.grow();
        }
        let (n, l) = (self.n, self.count);
        let column = &mut self.data[l * self.ld..][..n];
        for ((w, x), d) in column.iter_mut().zip(&u[..n]).zip(&mut self.diag) {
            *w = scale * x;
            *d += *w * *w;
        }
        self.count += 1;
    }

    /// Doubles the capacity, keeping the pending columns.
    fn grow(&mut self) {
        self.capacity *= 2;
        self.data.resize(self.ld * (self.capacity + 1), 0.0);
    }

    /// Row `i` of `W` over the pending columns, one column per item (a strided walk).
    fn row(&self, i: usize) -> impl Iterator<Item = f64> + '_ {
        self.data[i..i + self.count * self.ld]
            .chunks_exact(self.ld)
            .map(|column| column[0])
    }

    /// `sum_l W[i, l]^2`: the pending share of `P[i, i]`.
    pub(crate) fn diagonal(&self, i: usize) -> f64 {
        self.diag[i]
    }

    /// `c = -W[idx, :]^T val` (one entry per pending column), summed in `idx` order.
    fn minus_w_times(&self, idx: &[usize], val: &[f64], c: &mut Vec<f64>) {
        c.clear();
        c.resize(self.count, 0.0);
        for (&i, &v) in idx.iter().zip(val) {
            for (cl, w) in c.iter_mut().zip(self.row(i)) {
                // (-a) - b = -(a + b) exactly: the same bits as negating the sum.
                *cl -= v * w;
            }
        }
    }
}

/// `u = P[:, idx] val - W (W[idx, :]^T val)`: `P H^T` for a sparse row `H` under the
/// pending downdates. `p` is `n x n` column-major; `u` has length at least `n` (entries
/// past `n` come out zero). `c` is scratch (it ends holding `-W[idx, :]^T val`).
pub(crate) fn sparse_times(
    p: &[f64],
    pending: &Pending,
    idx: &[usize],
    val: &[f64],
    c: &mut Vec<f64>,
    u: &mut [f64],
) {
    pending.minus_w_times(idx, val, c);
    let n = pending.n;
    pulp::Arch::new().dispatch(SparseTimes {
        columns: Columns {
            p,
            n,
            w: &pending.data[..c.len() * pending.ld],
            ld: pending.ld,
            idx,
            val,
            c,
        },
        u: &mut u[..n],
    });
    u[n..].fill(0.0);
}

struct SparseTimes<'a> {
    columns: Columns<'a>,
    u: &'a mut [f64],
}

impl WithSimd for SparseTimes<'_> {
    type Output = ();

    /// Blocks of up to [`VECTORS`] vectors of rows held in registers while the `6 + k`
    /// columns stream through: independent FMA chains and fixed trip counts. The whole
    /// vectors of a column are split evenly over the blocks; the rows past them are covered
    /// by one more vector ending at row `n` (see the module docs), in the last block when
    /// it has room.
    #[inline(always)]
    fn with_simd<S: Simd>(self, simd: S) {
        let SparseTimes { columns, u } = self;
        let (n, lanes) = (columns.n, S::F64_LANES);
        if n < lanes {
            columns.scalar(u);
            return;
        }
        let whole = n / lanes;
        let tail = n % lanes != 0;
        let blocks = whole.div_ceil(VECTORS);
        let mut done = 0;
        for b in 0..blocks {
            let size = (whole - done).div_ceil(blocks - b);
            let last = b + 1 == blocks;
            columns.dispatch_block(simd, done * lanes, size, last && tail && size < VECTORS, u);
            done += size;
        }
        if tail && whole == blocks * VECTORS {
            columns.block::<S, 0, true>(simd, 0, u);
        }
    }
}

/// The operands of [`sparse_times`]: `w` holds the pending columns of `W` (column `l` at
/// `l * ld`), `c` their coefficients.
struct Columns<'a> {
    p: &'a [f64],
    n: usize,
    w: &'a [f64],
    ld: usize,
    idx: &'a [usize],
    val: &'a [f64],
    c: &'a [f64],
}

impl Columns<'_> {
    /// [`Columns::block`] with `size` (1 to [`VECTORS`]) and `tail` as constants.
    #[inline(always)]
    fn dispatch_block<S: Simd>(&self, simd: S, r0: usize, size: usize, tail: bool, u: &mut [f64]) {
        macro_rules! sizes {
            ($($b:literal)*) => {
                match (size, tail) {
                    $(($b, false) => self.block::<S, $b, false>(simd, r0, u),
                      ($b, true) => self.block::<S, $b, true>(simd, r0, u),)*
                    _ => unreachable!("block sizes are 1 to VECTORS"),
                }
            };
        }
        sizes!(1 2 3 4 5 6 7 8)
    }

    /// `u` over the `B` whole vectors of rows from row `r0` and, with `TAIL`, the vector
    /// ending at row `n`.
    #[inline(always)]
    fn block<S: Simd, const B: usize, const TAIL: bool>(&self, simd: S, r0: usize, u: &mut [f64]) {
        let (n, lanes) = (self.n, S::F64_LANES);
        let zero = simd.splat_f64s(0.0);
        let (mut acc, mut last) = ([zero; B], zero);
        for (&k, &v) in self.idx.iter().zip(self.val) {
            axpy_rows::<S, B, TAIL>(simd, &mut acc, &mut last, &self.p[k * n..][..n], r0, v);
        }
        for (column, &cl) in self.w.chunks_exact(self.ld).zip(self.c) {
            axpy_rows::<S, B, TAIL>(simd, &mut acc, &mut last, &column[..n], r0, cl);
        }
        let out = S::as_mut_simd_f64s(&mut u[r0..][..B * lanes]).0;
        for (o, a) in out.iter_mut().zip(acc) {
            *o = a;
        }
        if TAIL {
            S::as_mut_simd_f64s(&mut u[n - lanes..n]).0[0] = last;
        }
    }

    /// `u` one row at a time (`n` below one vector), in the same order with fused
    /// multiply-adds: the numbers of the vector path.
    fn scalar(&self, u: &mut [f64]) {
        for (r, out) in u.iter_mut().enumerate() {
            let mut acc = 0.0;
            for (&k, &v) in self.idx.iter().zip(self.val) {
                acc = self.p[k * self.n + r].mul_add(v, acc);
            }
            for (column, &cl) in self.w.chunks_exact(self.ld).zip(self.c) {
                acc = column[r].mul_add(cl, acc);
            }
            *out = acc;
        }
    }
}

/// `acc += v column[r0..r0 + B lanes]` and, with `TAIL`, `last += v column[n - lanes..n]`
/// (`column` of length `n`).
#[inline(always)]
fn axpy_rows<S: Simd, const B: usize, const TAIL: bool>(
    simd: S,
    acc: &mut [S::f64s; B],
    last: &mut S::f64s,
    column: &[f64],
    r0: usize,
    v: f64,
) {
    let lanes = S::F64_LANES;
    let v = simd.splat_f64s(v);
    let rows = S::as_simd_f64s(&column[r0..][..B * lanes]).0;
    for (a, x) in acc.iter_mut().zip(rows) {
        *a = simd.mul_add_f64s(*x, v, *a);
    }
    if TAIL {
        let x = S::as_simd_f64s(&column[column.len() - lanes..]).0[0];
        *last = simd.mul_add_f64s(x, v, *last);
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

    /// Column blocks of [`COL_BLOCK`]; in each, tiles of two vectors of rows from the
    /// diagonal down. Whole tiles load and store `P` directly; the tiles at the bottom edge
    /// or the last column block go through a buffer.
    #[inline(always)]
    fn with_simd<S: Simd>(self, simd: S) {
        let LowerDowndate { p, pending } = self;
        let (n, ld, k) = (pending.n, pending.ld, pending.count);
        let tile_rows = 2 * S::F64_LANES;
        let mut j0 = 0;
        while j0 < n {
            let jb = (n - j0).min(COL_BLOCK);
            // The 4 entries of W's rows j0.. in each pending column.
            let cols = pending.data[j0..j0 + k * ld].chunks_exact(ld);
            let mut i = j0;
            while i < n {
                // The two vectors of W's rows i.. in each pending column (the extra zero
                // column of `data` keeps the last one whole).
                let rows = pending.data[i..i + k * ld].chunks_exact(ld);
                let tile = Tile {
                    p: &mut *p,
                    n,
                    i,
                    j0,
                };
                if jb == COL_BLOCK && i + tile_rows <= n {
                    tile.whole(simd, rows, cols.clone());
                } else {
                    tile.edge(simd, rows, cols.clone(), jb);
                }
                i += tile_rows;
            }
            j0 += jb;
        }
    }
}

/// A register tile of `P`: rows `i..i + 2 lanes`, columns `j0..j0 + 4` (clipped to `n`
/// at the edges).
struct Tile<'a> {
    p: &'a mut [f64],
    n: usize,
    i: usize,
    j0: usize,
}

impl Tile<'_> {
    /// A tile wholly inside `P`.
    #[inline(always)]
    fn whole<'w, S: Simd>(
        self,
        simd: S,
        rows: impl Iterator<Item = &'w [f64]>,
        cols: impl Iterator<Item = &'w [f64]>,
    ) {
        let Tile { p, n, i, j0 } = self;
        let lanes = S::F64_LANES;
        let zero = simd.splat_f64s(0.0);
        let (mut a, mut b) = ([zero; COL_BLOCK], [zero; COL_BLOCK]);
        for c in 0..COL_BLOCK {
            let column = S::as_simd_f64s(&p[(j0 + c) * n + i..][..2 * lanes]).0;
            (a[c], b[c]) = (column[0], column[1]);
        }
        downdate_tile(simd, rows, cols, &mut a, &mut b);
        for c in 0..COL_BLOCK {
            let column = S::as_mut_simd_f64s(&mut p[(j0 + c) * n + i..][..2 * lanes]).0;
            (column[0], column[1]) = (a[c], b[c]);
        }
    }

    /// A tile at the bottom edge or in the last column block (`jb` columns), through a
    /// buffer.
    #[inline(always)]
    fn edge<'w, S: Simd>(
        self,
        simd: S,
        rows: impl Iterator<Item = &'w [f64]>,
        cols: impl Iterator<Item = &'w [f64]>,
        jb: usize,
    ) {
        let Tile { p, n, i, j0 } = self;
        let lanes = S::F64_LANES;
        let end = (i + 2 * lanes).min(n);
        let zero = simd.splat_f64s(0.0);
        let (mut a, mut b) = ([zero; COL_BLOCK], [zero; COL_BLOCK]);
        let mut buffer = [0.0; 2 * ROW_BLOCK];
        for c in 0..jb {
            buffer[..end - i].copy_from_slice(&p[(j0 + c) * n + i..(j0 + c) * n + end]);
            let v = S::as_simd_f64s(&buffer[..2 * lanes]).0;
            (a[c], b[c]) = (v[0], v[1]);
        }
        downdate_tile(simd, rows, cols, &mut a, &mut b);
        for c in 0..jb {
            let v = S::as_mut_simd_f64s(&mut buffer[..2 * lanes]).0;
            (v[0], v[1]) = (a[c], b[c]);
            p[(j0 + c) * n + i..(j0 + c) * n + end].copy_from_slice(&buffer[..end - i]);
        }
    }
}

/// `[a b] -= w[i..i + 2 lanes] w[j0..j0 + 4]^T` summed over the pending columns, with
/// `rows` yielding each column from row `i` and `cols` from row `j0`.
#[inline(always)]
fn downdate_tile<'w, S: Simd>(
    simd: S,
    rows: impl Iterator<Item = &'w [f64]>,
    cols: impl Iterator<Item = &'w [f64]>,
    a: &mut [S::f64s; COL_BLOCK],
    b: &mut [S::f64s; COL_BLOCK],
) {
    let lanes = S::F64_LANES;
    for (w_rows, w_cols) in rows.zip(cols) {
        let v = S::as_simd_f64s(&w_rows[..2 * lanes]).0;
        let (wa, wb) = (v[0], v[1]);
        // Columns past n read the zero pad: harmless, never stored.
        let w_cols = &w_cols[..COL_BLOCK];
        for c in 0..COL_BLOCK {
            let s = simd.splat_f64s(w_cols[c]);
            a[c] = simd.negate_mul_add_f64s(wa, s, a[c]);
            b[c] = simd.negate_mul_add_f64s(wb, s, b[c]);
        }
    }
}

/// Copies the strict lower triangle of the `n x n` column-major `p` onto the upper, four
/// columns at a time: rows `j..j + 4` of each earlier column (contiguous) go to row `i` of
/// columns `j..j + 4`.
fn mirror_lower(p: &mut [f64], n: usize) {
    let mut j = 0;
    while j + 4 <= n {
        let (left, right) = p.split_at_mut(j * n);
        let (c0, right) = right.split_at_mut(n);
        let (c1, right) = right.split_at_mut(n);
        let (c2, c3) = right.split_at_mut(n);
        let targets = c0[..j]
            .iter_mut()
            .zip(&mut c1[..j])
            .zip(&mut c2[..j])
            .zip(&mut c3[..j]);
        for (source, (((d0, d1), d2), d3)) in left.chunks_exact(n).zip(targets) {
            let s = &source[j..j + 4];
            (*d0, *d1, *d2, *d3) = (s[0], s[1], s[2], s[3]);
        }
        // The strict upper part of the 4 x 4 diagonal block.
        for c in 1..4 {
            for r in 0..c {
                p[(j + c) * n + j + r] = p[(j + r) * n + j + c];
            }
        }
        j += 4;
    }
    for c in j..n {
        for r in 0..c {
            p[c * n + r] = p[r * n + c];
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
