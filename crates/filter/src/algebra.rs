//! The structured filter's covariance kernels, on column-major storage: the sparse
//! `P H^T` with the pending downdates' share, and the rank-k downdate `P -= W W^T` of the
//! lower triangle followed by the mirror that keeps `P` exactly symmetric.
//!
//! Why hand-written: the workspace forbids `unsafe`; `pulp` dispatches these loops at run
//! time to AVX2+FMA or AVX-512 (4 or 8 `f64` lanes per instruction). faer's (also
//! pulp-based) triangular product is slower for the downdate at the filter's sizes (its
//! general kernels pay per-call overhead when `n` is a few tens) and nalgebra's `gemm`
//! (matrixmultiply) allocates its packing buffers per call.
//!
//! `W` is stored with a leading dimension of at least `n + ROW_BLOCK`, a multiple of the
//! cache line, each column starting on a line (whole-vector loads from row 0 do not
//! straddle two lines), so that a register tile of rows starting anywhere below `n` loads
//! whole vectors of `W` without masks.
//!
//! The kernels are written so that LLVM sees fixed trip counts and whole-vector loads in
//! every inner loop: a `P` column is not padded (it belongs to the public `DMatrix`), so
//! [`weighted_sum`] covers its last rows with one vector ending at row `n` (overlapping the
//! one before it, whose rows it recomputes with the same operations, hence the same bits)
//! instead of a masked load; the downdate loads and stores the last vector of a column
//! with a mask once per tile, outside its inner loop (a bounce buffer there cost a
//! store-forwarding stall per vector). The mirror transposes 4 x 4 blocks in AVX2
//! registers.

use pulp::{Simd, WithSimd};

/// Rows of `W` past `n` at least (and the multiple [`padded`] rounds to).
pub(crate) const ROW_BLOCK: usize = 16;

/// Columns of `P` per register tile.
const COL_BLOCK: usize = 4;

/// `n` rounded up to a multiple of [`ROW_BLOCK`].
pub(crate) fn padded(n: usize) -> usize {
    n.div_ceil(ROW_BLOCK) * ROW_BLOCK
}

/// Doubles per 64-byte cache line.
const LINE: usize = 8;

/// The pending rank-1 downdates `w_l` (columns of `W`, padded leading dimension).
#[derive(Debug)]
pub(crate) struct Pending {
    n: usize,
    ld: usize,
    /// Columns of `W` at `l * ld` from the first cache-line boundary in the buffer (see
    /// [`Pending::w`]), plus one column past the last (so that every column can be read
    /// from any row offset below `ld`, see [`apply_pending`]).
    data: Vec<f64>,
    capacity: usize,
    count: usize,
}

impl Pending {
    /// Room for `capacity` columns of length `n`.
    pub(crate) fn new(n: usize, capacity: usize) -> Self {
        let ld = padded(n + ROW_BLOCK);
        let capacity = capacity.max(1);
        Pending {
            n,
            ld,
            data: vec![0.0; Self::buffer_len(ld, capacity)],
            capacity,
            count: 0,
        }
    }

    fn buffer_len(ld: usize, capacity: usize) -> usize {
        ld * (capacity + 1) + LINE
    }

    /// The columns of `W` (`ld` a multiple of [`LINE`]: each starts on a cache line, so
    /// that whole-vector loads from row 0 do not straddle two).
    fn w(&self) -> &[f64] {
        &self.data[line_offset(&self.data)..]
    }

    /// Length `n` of the columns.
    pub(crate) fn n(&self) -> usize {
        self.n
    }

    /// Leading dimension of the columns.
    pub(crate) fn ld(&self) -> usize {
        self.ld
    }

    /// Number of pending columns.
    pub(crate) fn len(&self) -> usize {
        self.count
    }

    /// Drops the pending columns (after they were applied).
    pub(crate) fn clear(&mut self) {
        self.count = 0;
    }

    /// Makes `count` the pending columns and returns them for the caller to fill: column
    /// `l` at `l * ld`, rows `0..n` (the rows past `n` are padding and may hold anything
    /// finite). Grows the buffer when `count` exceeds the capacity.
    pub(crate) fn columns_mut(&mut self, count: usize) -> &mut [f64] {
        if count > self.capacity {
            self.capacity = count;
            self.data = vec![0.0; Self::buffer_len(self.ld, count)];
        }
        self.count = count;
        let offset = line_offset(&self.data);
        &mut self.data[offset..][..count * self.ld]
    }
}

/// The first index of `data` on a cache-line boundary (0 if the platform says none).
fn line_offset(data: &[f64]) -> usize {
    let offset = data.as_ptr().align_offset(LINE * size_of::<f64>());
    if offset < LINE { offset } else { 0 }
}

/// Columns `idx` of a column-major matrix (leading dimension `ld`), one weight each: the
/// sparse part of a [`weighted_sum`] (`P H^T` for a sparse row `H`).
#[derive(Clone, Copy)]
pub(crate) struct Picked<'a> {
    pub data: &'a [f64],
    pub ld: usize,
    pub idx: &'a [usize],
    pub weight: &'a [f64],
}

/// The first `weight.len()` consecutive columns of a column-major matrix (leading dimension
/// `ld`), one weight each: the dense part of a [`weighted_sum`].
#[derive(Clone, Copy)]
pub(crate) struct Run<'a> {
    pub data: &'a [f64],
    pub ld: usize,
    pub weight: &'a [f64],
}

/// `out[..n] = sum_k picked.weight[k] picked[:, idx[k]] + sum_l run.weight[l] run[:, l]`,
/// each row a chain of fused multiply-adds in that order (the picked columns first);
/// `out[n..]` comes out zero.
pub(crate) fn weighted_sum(n: usize, picked: Picked<'_>, run: Run<'_>, out: &mut [f64]) {
    let (head, pad) = out.split_at_mut(n);
    pulp::Arch::new().dispatch(WeightedSum {
        columns: Columns { n, picked, run },
        u: head,
    });
    pad.fill(0.0);
}

struct WeightedSum<'a> {
    columns: Columns<'a>,
    u: &'a mut [f64],
}

impl WithSimd for WeightedSum<'_> {
    type Output = ();

    /// Blocks of up to [`VECTORS`] vectors of rows held in registers while the columns
    /// stream through: independent FMA chains and fixed trip counts. The whole vectors of a
    /// column are split evenly over the blocks; the rows past them are covered by one more
    /// vector ending at row `n` (see the module docs), in the last block when it has room.
    #[inline(always)]
    fn with_simd<S: Simd>(self, simd: S) {
        let WeightedSum { columns, u } = self;
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

/// The operands of [`weighted_sum`].
struct Columns<'a> {
    n: usize,
    picked: Picked<'a>,
    run: Run<'a>,
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

    /// The picked columns (their first `n` rows), each with its weight.
    fn picked_columns(&self) -> impl Iterator<Item = (&[f64], f64)> {
        let Picked {
            data,
            ld,
            idx,
            weight,
        } = self.picked;
        let n = self.n;
        idx.iter()
            .zip(weight)
            .map(move |(&k, &v)| (&data[k * ld..][..n], v))
    }

    /// The run's columns (their first `n` rows), each with its weight.
    fn run_columns(&self) -> impl Iterator<Item = (&[f64], f64)> {
        let n = self.n;
        self.run
            .data
            .chunks(self.run.ld)
            .zip(self.run.weight)
            .map(move |(column, &v)| (&column[..n], v))
    }

    /// `u` over the `B` whole vectors of rows from row `r0` and, with `TAIL`, the vector
    /// ending at row `n`.
    #[inline(always)]
    fn block<S: Simd, const B: usize, const TAIL: bool>(&self, simd: S, r0: usize, u: &mut [f64]) {
        let (n, lanes) = (self.n, S::F64_LANES);
        let zero = simd.splat_f64s(0.0);
        let (mut acc, mut last) = ([zero; B], zero);
        // Two loops, not one chained iterator: each keeps a fixed body.
        for (column, v) in self.picked_columns() {
            axpy_rows::<S, B, TAIL>(simd, &mut acc, &mut last, column, r0, v);
        }
        for (column, v) in self.run_columns() {
            axpy_rows::<S, B, TAIL>(simd, &mut acc, &mut last, column, r0, v);
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
            *out = self
                .picked_columns()
                .chain(self.run_columns())
                .fold(0.0, |acc, (column, v)| column[r].mul_add(v, acc));
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

/// Vectors of rows per block of [`weighted_sum`] (8 independent FMA chains cover the FMA
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

    /// Column blocks of [`COL_BLOCK`]; in each, the vectors of rows from the diagonal down
    /// split evenly into tiles of at most [`TILE_VECTORS`] (so that only the last vector of
    /// a block reaches past row `n`, and no tile is mostly past it).
    #[inline(always)]
    fn with_simd<S: Simd>(self, simd: S) {
        let LowerDowndate { p, pending } = self;
        let (n, lanes) = (pending.n, S::F64_LANES);
        let mut j0 = 0;
        while j0 < n {
            let jb = (n - j0).min(COL_BLOCK);
            let vectors = (n - j0).div_ceil(lanes);
            let tiles = vectors.div_ceil(TILE_VECTORS);
            let mut done = 0;
            for t in 0..tiles {
                let size = (vectors - done).div_ceil(tiles - t);
                let tile = Tile {
                    p: &mut *p,
                    pending,
                    i: j0 + done * lanes,
                    j0,
                    jb,
                };
                tile.dispatch(simd, size);
                done += size;
            }
            j0 += jb;
        }
    }
}

/// Vectors of rows per downdate tile at most: 3 x [`COL_BLOCK`] accumulators, 3 loads and
/// 4 broadcasts per 12 FMAs (AVX2 has the 16 registers that takes). The tile shape hardly
/// matters at AVX-512 (the FMA count does: 2 x 8, 4 x 4 and 3 x 8 tiles measured the same
/// within noise).
const TILE_VECTORS: usize = 3;

/// A register tile of `P`: `B` vectors of rows from `i` (clipped to `n`), columns
/// `j0..j0 + jb`.
struct Tile<'a> {
    p: &'a mut [f64],
    pending: &'a Pending,
    i: usize,
    j0: usize,
    jb: usize,
}

impl Tile<'_> {
    /// [`Tile::downdate`] with the tile's `size` vectors and `jb` columns as constants (so
    /// that its accumulators stay in registers).
    #[inline(always)]
    fn dispatch<S: Simd>(self, simd: S, size: usize) {
        macro_rules! shapes {
            ($(($b:literal, $c:literal))*) => {
                match (size, self.jb) {
                    $(($b, $c) => self.downdate::<S, $b, $c>(simd),)*
                    _ => unreachable!("tiles are 1 to TILE_VECTORS vectors, 1 to COL_BLOCK columns"),
                }
            };
        }
        shapes!((1, 1)(1, 2)(1, 3)(1, 4)(2, 1)(2, 2)(2, 3)(2, 4)(3, 1)(3, 2)(3, 3)(3, 4))
    }

    /// `P[i.., j0..] -= W[i.., :] W[j0.., :]^T` for `B` vectors of rows and `JB` columns:
    /// loads, `k` rank-1 steps in registers, stores. Vectors reaching past row `n` are
    /// loaded and stored partially (masked).
    #[inline(always)]
    fn downdate<S: Simd, const B: usize, const JB: usize>(self, simd: S) {
        let Tile {
            p, pending, i, j0, ..
        } = self;
        let (n, ld, k, lanes) = (pending.n, pending.ld, pending.count, S::F64_LANES);
        let zero = simd.splat_f64s(0.0);
        let mut acc = [[zero; B]; JB];
        for (c, a) in acc.iter_mut().enumerate() {
            let column = &p[(j0 + c) * n..][..n];
            for (b, x) in a.iter_mut().enumerate() {
                let r = i + b * lanes;
                if r + lanes <= n {
                    *x = S::as_simd_f64s(&column[r..r + lanes]).0[0];
                } else if r < n {
                    *x = simd.partial_load_f64s(&column[r..]);
                }
            }
        }
        // Each column of W from row i (B vectors; rows past n, from the pad or the next
        // column, only reach accumulator rows that are never stored) and from row j0 (JB
        // entries).
        let w = pending.w();
        let rows = w[i..i + k * ld].chunks_exact(ld);
        let cols = w[j0..j0 + k * ld].chunks_exact(ld);
        for (w_rows, w_cols) in rows.zip(cols) {
            let w = S::as_simd_f64s(&w_rows[..B * lanes]).0;
            let w_cols: &[f64; JB] = w_cols[..JB].try_into().expect("JB entries");
            for (a, &s) in acc.iter_mut().zip(w_cols) {
                let s = simd.splat_f64s(s);
                for (x, &v) in a.iter_mut().zip(w) {
                    *x = simd.negate_mul_add_f64s(v, s, *x);
                }
            }
        }
        for (c, a) in acc.iter().enumerate() {
            let column = &mut p[(j0 + c) * n..][..n];
            for (b, &x) in a.iter().enumerate() {
                let r = i + b * lanes;
                if r + lanes <= n {
                    S::as_mut_simd_f64s(&mut column[r..r + lanes]).0[0] = x;
                } else if r < n {
                    simd.partial_store_f64s(&mut column[r..], x);
                }
            }
        }
    }
}

/// Copies the strict lower triangle of the `n x n` column-major `p` onto the upper: in
/// 4 x 4 blocks transposed in AVX2 registers where the CPU has them, else one entry at a
/// time.
fn mirror_lower(p: &mut [f64], n: usize) {
    #[cfg(target_arch = "x86_64")]
    if let Some(simd) = pulp::x86::V3::try_new() {
        pulp::Simd::vectorize(simd, Mirror { p, n });
        return;
    }
    mirror_from(p, n, 0);
}

/// The strict upper triangle of columns `from..n` copied from the lower.
fn mirror_from(p: &mut [f64], n: usize, from: usize) {
    for c in from..n {
        for r in 0..c {
            p[c * n + r] = p[r * n + c];
        }
    }
}

struct Mirror<'a> {
    p: &'a mut [f64],
    n: usize,
}

impl WithSimd for Mirror<'_> {
    type Output = ();

    /// For 4 lanes (AVX2): the strictly lower 4 x 4 blocks loaded as 4 column vectors,
    /// transposed by the 4-field deinterleave and stored as 4 column vectors of the block
    /// above the diagonal; the diagonal blocks and the last `n % 4` columns entry by entry.
    #[inline(always)]
    fn with_simd<S: Simd>(self, simd: S) {
        let Mirror { p, n } = self;
        if S::F64_LANES != 4 {
            mirror_from(p, n, 0);
            return;
        }
        let whole = n / 4 * 4;
        for i in (0..whole).step_by(4) {
            // Columns i..i + 4 of the upper part from rows i..i + 4 of the earlier columns.
            let (left, right) = p.split_at_mut(i * n);
            let targets = &mut right[..4 * n];
            for (j, sources) in (0..i).step_by(4).zip(left.chunks_exact(4 * n)) {
                let x: [S::f64s; 4] =
                    core::array::from_fn(|c| S::as_simd_f64s(&sources[c * n + i..][..4]).0[0]);
                let t = simd.deinterleave_shfl_f64s(x);
                for (r, t) in t.into_iter().enumerate() {
                    S::as_mut_simd_f64s(&mut targets[r * n + j..][..4]).0[0] = t;
                }
            }
            // The strict upper part of the 4 x 4 diagonal block.
            for c in 1..4 {
                for r in 0..c {
                    p[(i + c) * n + i + r] = p[(i + r) * n + i + c];
                }
            }
        }
        mirror_from(p, n, whole);
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::{DMatrix, DVector};

    use super::*;

    fn pending_from(w: &DMatrix<f64>) -> Pending {
        let (n, k) = w.shape();
        let mut pending = Pending::new(n, 1);
        let ld = pending.ld();
        let columns = pending.columns_mut(k);
        for l in 0..k {
            columns[l * ld..][..n].copy_from_slice(w.column(l).as_slice());
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

    /// `P0` (diagonally dominant, not symmetric above the diagonal: the kernels read only
    /// the lower triangle) and `W` (`n x k`) with entries of order 1.
    fn operands(n: usize, k: usize) -> (DMatrix<f64>, DMatrix<f64>) {
        let p0 = DMatrix::from_fn(n, n, |i, j| {
            ((i * 7 + j * 3) % 11) as f64 + 30.0 * f64::from(u8::from(i == j))
        });
        let w = DMatrix::from_fn(n, k, |i, j| ((i * 5 + j * 3) % 13) as f64 * 0.1 - 0.6);
        (p0, w)
    }

    #[test]
    fn downdate_matches_the_textbook_product_at_every_size() {
        // Every n to 70 covers each tile size (1 to 3 vectors), the masked last vectors at
        // every n mod 8 (AVX-512) and 4 (AVX2), and the mirror's whole and partial blocks.
        for n in 1..=70 {
            for k in [1, 2, 20] {
                let (p0, w) = operands(n, k);
                let mut p = p0.clone();
                let mut pending = pending_from(&w);
                apply_pending(p.as_mut_slice(), &mut pending);
                let lower = (&p0 - &w * w.transpose()).lower_triangle();
                let expected =
                    &lower + lower.transpose() - DMatrix::from_diagonal(&lower.diagonal());
                // Same products, summation order up to the kernel: rounding only (entries
                // ~30, k up to 20 products of order 1).
                assert!((&p - expected).abs().max() < 1e-12, "n {n} k {k}");
                assert_eq!(p, p.transpose(), "n {n} k {k}: exactly symmetric");
            }
        }
    }

    /// The lower triangle of `P0 - W W^T` with each entry `P0 - w_0 w_0 - w_1 w_1 - ...`
    /// rounded once per pending column (fused multiply-add, in push order).
    fn fused_lower(p0: &DMatrix<f64>, w: &DMatrix<f64>) -> DMatrix<f64> {
        DMatrix::from_fn(p0.nrows(), p0.ncols(), |i, j| {
            let fused = |acc: f64, l: usize| (-w[(i, l)]).mul_add(w[(j, l)], acc);
            if i >= j {
                (0..w.ncols()).fold(p0[(i, j)], fused)
            } else {
                0.0
            }
        })
    }

    #[test]
    fn downdate_keeps_the_fma_order_of_each_entry() {
        // Whatever the tile an entry falls in, on the dispatched SIMD and on AVX2 (the path
        // callgrind runs): the same bits as the scalar fold.
        for n in 1..=70 {
            let (p0, w) = operands(n, 20);
            let expected = fused_lower(&p0, &w);
            let mut p = p0.clone();
            pulp::Arch::new().dispatch(LowerDowndate {
                p: p.as_mut_slice(),
                pending: &pending_from(&w),
            });
            assert_eq!(p.lower_triangle(), expected, "n {n}, dispatched");
            #[cfg(target_arch = "x86_64")]
            if let Some(simd) = pulp::x86::V3::try_new() {
                let mut p = p0.clone();
                let op = LowerDowndate {
                    p: p.as_mut_slice(),
                    pending: &pending_from(&w),
                };
                pulp::Simd::vectorize(simd, op);
                assert_eq!(p.lower_triangle(), expected, "n {n}, AVX2");
            }
        }
    }

    #[test]
    fn weighted_sum_matches_the_textbook_product() {
        // Every n to 70: one or two blocks, with and without the tail vector, and the
        // scalar path below one vector.
        for n in 1..=70 {
            let p = DMatrix::from_fn(n, n, |i, j| ((i * 7 + j * 7) % 11) as f64);
            let w = DMatrix::from_fn(n, 5, |i, j| ((i * 5 + j * 3) % 13) as f64 * 0.1);
            let (idx, val) = ([0usize, n / 2, n - 1], [0.5, -1.0, 2.0]);
            let c = [0.3, -0.7, 1.1, 0.0, 2.5];
            let mut h = DVector::zeros(n);
            for (&i, &v) in idx.iter().zip(&val) {
                h[i] += v;
            }
            let pending = pending_from(&w);
            let picked = Picked {
                data: p.as_slice(),
                ld: n,
                idx: &idx,
                weight: &val,
            };
            let run = Run {
                data: &pending.w()[..5 * pending.ld()],
                ld: pending.ld(),
                weight: &c,
            };
            let mut u = vec![f64::NAN; padded(n)];
            weighted_sum(n, picked, run, &mut u);
            let expected = &p * h + &w * DVector::from_column_slice(&c);
            for i in 0..n {
                // Rounding only (entries ~10).
                assert!((u[i] - expected[i]).abs() < 1e-12, "n {n} row {i}");
            }
            assert!(u[n..].iter().all(|&x| x == 0.0), "pad rows zero");
        }
    }
}
