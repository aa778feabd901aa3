//! One sensor or four: the expansion's evaluation ([`crate::AlbedoExpansion`]) is written
//! once over [`Lane`] and runs on `f64` (one normal) or `f64x4` (four normals in one pass,
//! the batch of [`crate::AlbedoIrradiance::ratios_and_vectors`]). The same operations in the
//! same order on each lane: the batch gives the single evaluation's bits.

use std::ops::{Add, Div, Mul, Neg, Sub};

use wide::f64x4;

/// The arithmetic the evaluation needs.
pub(crate) trait Lane:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// Every lane `x`.
    fn splat(x: f64) -> Self;
    /// IEEE square root per lane.
    fn sqrt(self) -> Self;
    /// Clamped to [-1, 1] (finite input).
    fn clamp_unit(self) -> Self;
    /// Per lane: `then` where `a >= b`, else `otherwise`.
    fn ge_select(a: Self, b: Self, then: Self, otherwise: Self) -> Self;
}

impl Lane for f64 {
    fn splat(x: f64) -> Self {
        x
    }
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    fn clamp_unit(self) -> Self {
        self.clamp(-1.0, 1.0)
    }
    fn ge_select(a: Self, b: Self, then: Self, otherwise: Self) -> Self {
        if a >= b { then } else { otherwise }
    }
}

impl Lane for f64x4 {
    fn splat(x: f64) -> Self {
        f64x4::splat(x)
    }
    fn sqrt(self) -> Self {
        f64x4::sqrt(self)
    }
    fn clamp_unit(self) -> Self {
        self.max(f64x4::splat(-1.0)).min(f64x4::ONE)
    }
    fn ge_select(a: Self, b: Self, then: Self, otherwise: Self) -> Self {
        a.simd_ge(b).bitselect(then, otherwise)
    }
}

/// `a . b`, left to right.
pub(crate) fn dot3<T: Lane>(a: &[T; 3], b: &[T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `m v` for a 3x3 matrix given by rows, each row left to right.
pub(crate) fn mat_vec<T: Lane>(rows: &[[f64; 3]; 3], v: &[T; 3]) -> [T; 3] {
    std::array::from_fn(|r| dot3(&rows[r].map(T::splat), v))
}
