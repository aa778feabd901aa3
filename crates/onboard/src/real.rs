//! The floating-point type of the core: `f32` or `f64`.

use num_traits::Float;

/// A float the core computes in: [`Float`] (through libm in `no_std`) and a conversion from
/// the `f64` constants of the model.
pub trait Real: Float + Default + core::fmt::Debug {
    /// `x` rounded to this type.
    fn of(x: f64) -> Self;
    /// This value as `f64`.
    fn to_f64_lossless(self) -> f64;
}

impl Real for f32 {
    fn of(x: f64) -> f32 {
        x as f32
    }
    fn to_f64_lossless(self) -> f64 {
        f64::from(self)
    }
}

impl Real for f64 {
    fn of(x: f64) -> f64 {
        x
    }
    fn to_f64_lossless(self) -> f64 {
        self
    }
}
