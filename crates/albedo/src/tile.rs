//! The tiles of the culled cell loop: cells are swept [`TILE_COLS`] columns (a chunk) at a
//! time, four per `f64x4`, and summed per ground tile of [`TILE_ROWS`] x [`TILE_COLS`]
//! cells with the tile's bounding cone ([`TileAcc`]), which the model fills
//! ([`crate::AlbedoModel`]) and the view reduces ([`crate::AlbedoView`]).

use nalgebra::Vector3;
use wide::f64x4;

/// Cells per tile along latitude (see [`AlbedoModel::compute_into`]). 8 x 8 measured best
/// for the benchmark scene among 4..16 x 4..16: smaller tiles cost more per-tile work in both
/// passes, larger ones more cells in the tiles a sensor's gate boundary crosses.
pub const TILE_ROWS: usize = 8;
/// Cells per tile along longitude (a multiple of 4: rows are computed four cells at a time).
pub const TILE_COLS: usize = 8;

/// f64x4 vectors per chunk of [`TILE_COLS`] cells.
pub(crate) const LANES_PER_CHUNK: usize = TILE_COLS / 4;
const _: () = assert!(TILE_COLS.is_multiple_of(4) && TILE_COLS > 0);

/// A set of chunk indices in a row: up to two inclusive intervals (an empty one is (1, 0)).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Chunks(pub(crate) [(i64, i64); 2]);

impl Chunks {
    pub(crate) const EMPTY: Self = Self([(1, 0), (1, 0)]);

    pub(crate) fn all(last: i64) -> Self {
        Self([(0, last), (1, 0)])
    }

    pub(crate) fn contains(&self, q: i64) -> bool {
        self.0.iter().any(|&(a, b)| a <= q && q <= b)
    }

    pub(crate) fn is_empty(&self) -> bool {
        self.0.iter().all(|&(a, b)| a > b)
    }

    /// Position of chunk `q` (which must be in the set) in [`Chunks::iter`] order.
    pub(crate) fn index(&self, q: i64) -> usize {
        let [(a0, b0), (a1, _)] = self.0;
        if q <= b0 {
            (q - a0) as usize
        } else {
            (b0 - a0 + 1).max(0) as usize + (q - a1) as usize
        }
    }

    pub(crate) fn iter(&self) -> impl Iterator<Item = i64> {
        let [(a0, b0), (a1, b1)] = self.0;
        (a0..=b0).chain(a1..=b1)
    }
}

/// Four cells' terms: unit vectors u (satellite to cell, ECEF) and weights c (0 for a cell
/// that fails Basilisk's tests).
pub(crate) struct Cells4 {
    pub(crate) u: [f64x4; 3],
    pub(crate) c: f64x4,
}

/// A tile's sums while its cells are computed, in f64x4 lanes (reduced in
/// [`crate::AlbedoView`]).
#[derive(Debug, Clone)]
pub(crate) struct TileAcc {
    /// Axis of the tile's cone (splat x, y, z).
    axis: [f64x4; 3],
    /// The axis as a vector.
    pub(crate) axis_ecef: Vector3<f64>,
    /// First cell vector of the tile's block, relative to the group.
    pub(crate) start: usize,
    /// Next cell vector to write.
    pub(crate) cursor: usize,
    /// Sum of c u.
    pub(crate) cu: [f64x4; 3],
    /// Smallest axis . u over the tile's cells.
    pub(crate) min_t: f64x4,
}

impl TileAcc {
    pub(crate) fn new(axis: Vector3<f64>, start: usize) -> Self {
        Self {
            axis: [
                f64x4::splat(axis.x),
                f64x4::splat(axis.y),
                f64x4::splat(axis.z),
            ],
            axis_ecef: axis,
            start,
            cursor: start,
            cu: [f64x4::ZERO; 3],
            min_t: f64x4::ONE,
        }
    }

    #[inline(always)]
    pub(crate) fn add(&mut self, cell: &Cells4) {
        let [x, y, z] = cell.u;
        let c = cell.c;
        self.cu[0] = c.mul_add(x, self.cu[0]);
        self.cu[1] = c.mul_add(y, self.cu[1]);
        self.cu[2] = c.mul_add(z, self.cu[2]);
        // All cells bound the cone (cheaper than masking; padding repeats a real cell, and
        // cells failing the tests only widen the cones of tiles on the horizon or the
        // terminator).
        let t = self.axis[0].mul_add(x, self.axis[1].mul_add(y, self.axis[2] * z));
        self.min_t = self.min_t.fast_min(t);
    }
}
