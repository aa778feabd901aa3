//! The floating-point type of the core: `f32` or `f64`.
//!
//! The functions beyond the four operations come from the `libm` crate, whichever the
//! build: the flight library and a ground tool then compute the same bits (std's `sin` is the
//! platform's C library's).

use core::fmt::Debug;
use core::ops::{Add, Div, Mul, Neg, Sub};

/// A float the core computes in.
pub trait Real:
    Copy
    + Default
    + Debug
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// `x` rounded to this type.
    fn of(x: f64) -> Self;
    /// This value as `f64`.
    fn to_f64_lossless(self) -> f64;
    /// 0.
    fn zero() -> Self {
        Self::of(0.0)
    }
    /// 1.
    fn one() -> Self {
        Self::of(1.0)
    }
    /// Neither infinite nor NaN.
    fn is_finite(self) -> bool;
    /// Not a number.
    fn is_nan(self) -> bool;
    /// `1 / self`.
    fn recip(self) -> Self {
        Self::one() / self
    }
    /// The larger; a NaN operand gives the other.
    fn max(self, other: Self) -> Self {
        if self >= other || other.is_nan() {
            self
        } else {
            other
        }
    }
    /// The smaller; a NaN operand gives the other.
    fn min(self, other: Self) -> Self {
        if self <= other || other.is_nan() {
            self
        } else {
            other
        }
    }
    /// `|self|`.
    fn abs(self) -> Self {
        if self < Self::zero() { -self } else { self }
    }
    /// Square root (NaN below 0).
    fn sqrt(self) -> Self;
    /// Cube root.
    fn cbrt(self) -> Self;
    /// Sine.
    fn sin(self) -> Self;
    /// Cosine.
    fn cos(self) -> Self;
    /// `(sin, cos)`.
    fn sin_cos(self) -> (Self, Self) {
        (self.sin(), self.cos())
    }
    /// Arc cosine (NaN outside [-1, 1]).
    fn acos(self) -> Self;
    /// `atan2(self, x)`.
    fn atan2(self, x: Self) -> Self;
}

impl Real for f32 {
    fn of(x: f64) -> f32 {
        x as f32
    }
    fn to_f64_lossless(self) -> f64 {
        f64::from(self)
    }
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
    fn is_nan(self) -> bool {
        f32::is_nan(self)
    }
    fn sqrt(self) -> f32 {
        libm::sqrtf(self)
    }
    fn cbrt(self) -> f32 {
        libm::cbrtf(self)
    }
    fn sin(self) -> f32 {
        libm::sinf(self)
    }
    fn cos(self) -> f32 {
        libm::cosf(self)
    }
    fn acos(self) -> f32 {
        libm::acosf(self)
    }
    fn atan2(self, x: f32) -> f32 {
        libm::atan2f(self, x)
    }
}

impl Real for f64 {
    fn of(x: f64) -> f64 {
        x
    }
    fn to_f64_lossless(self) -> f64 {
        self
    }
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
    fn is_nan(self) -> bool {
        f64::is_nan(self)
    }
    fn sqrt(self) -> f64 {
        libm::sqrt(self)
    }
    fn cbrt(self) -> f64 {
        libm::cbrt(self)
    }
    fn sin(self) -> f64 {
        libm::sin(self)
    }
    fn cos(self) -> f64 {
        libm::cos(self)
    }
    fn acos(self) -> f64 {
        libm::acos(self)
    }
    fn atan2(self, x: f64) -> f64 {
        libm::atan2(self, x)
    }
}
