//! The calibration the core reads: one [`Photodiode`] per channel.

use crate::Real;
use crate::linalg::{V3, is_finite, norm, scale};

/// Most photodiodes one call takes (the used set is a 64-bit mask).
pub const MAX_PHOTODIODES: usize = 64;

/// One photodiode's calibrated parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct Photodiode<T> {
    /// Scale factor `C_i` of paper Eq. (15), the output at normal incidence at 1 AU, V.
    pub scale_v: T,
    /// Unit normal, body frame (Eq. 16; any length above 0.5 and below 2 is normalised).
    pub normal_body: [T; 3],
    /// Output with no light (dark offset), V; 0 where not calibrated.
    pub dark_v: T,
    /// Half-angle of the field of view, rad: no light reaches the photodiode beyond it.
    /// `pi / 2` (or more) for a bare cosine detector.
    pub fov_half_angle_rad: T,
    /// Output noise, 1-sigma, V.
    pub noise_v: T,
    /// The calibration's 1-sigma of `scale_v`, V (0 if unknown).
    pub scale_sigma_v: T,
    /// The calibration's 1-sigma of the normal's direction, rad (0 if unknown).
    pub normal_sigma_rad: T,
    /// Whether the channel is to be used (a channel the calibration left undetermined or
    /// found dead is exported disabled).
    pub enabled: bool,
}

impl<T: Real> Photodiode<T> {
    /// A cosine photodiode of scale `scale_v` and normal `normal_body`, no dark offset, a
    /// hemispherical field of view, noise `noise_v`, calibration sigmas 0.
    pub fn cosine(scale_v: T, normal_body: [T; 3], noise_v: T) -> Self {
        Photodiode {
            scale_v,
            normal_body,
            dark_v: T::zero(),
            fov_half_angle_rad: T::of(core::f64::consts::FRAC_PI_2),
            noise_v,
            scale_sigma_v: T::zero(),
            normal_sigma_rad: T::zero(),
            enabled: true,
        }
    }

    /// The unit normal and the cosine of the field-of-view edge, when every parameter is
    /// usable: finite, a positive scale, a normal of length in (0.5, 2), a non-negative noise
    /// and sigmas.
    pub(crate) fn checked(&self) -> Option<Checked<T>> {
        let finite = self.scale_v.is_finite()
            && is_finite(self.normal_body)
            && self.dark_v.is_finite()
            && self.noise_v.is_finite()
            && self.scale_sigma_v.is_finite()
            && self.normal_sigma_rad.is_finite()
            && !self.fov_half_angle_rad.is_nan();
        let length = norm(self.normal_body);
        let usable = finite
            && self.enabled
            && self.scale_v > T::zero()
            && length > T::of(0.5)
            && length < T::of(2.0)
            && self.noise_v >= T::zero()
            && self.scale_sigma_v >= T::zero()
            && self.normal_sigma_rad >= T::zero()
            && self.fov_half_angle_rad > T::zero();
        usable.then(|| Checked {
            normal: scale(self.normal_body, length.recip()),
            cos_fov: self
                .fov_half_angle_rad
                .min(T::of(core::f64::consts::FRAC_PI_2))
                .cos()
                .max(T::zero()),
        })
    }
}

/// A photodiode's unit normal and field-of-view cosine, checked.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Checked<T> {
    pub normal: V3<T>,
    pub cos_fov: T,
}

/// The calibration of `count` photodiodes in a buffer of `N` (a flight build sizes `N` to its
/// head; `count <= N` and `count <= MAX_PHOTODIODES` are checked at each call).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration<T, const N: usize> {
    /// How many of `photodiodes` are in use.
    pub count: usize,
    /// The photodiodes, `pdNN` order; those beyond `count` are ignored.
    pub photodiodes: [Photodiode<T>; N],
}

impl<T: Real, const N: usize> Calibration<T, N> {
    /// The photodiodes in use, or `None` when `count` exceeds `N` or [`MAX_PHOTODIODES`].
    pub fn in_use(&self) -> Option<&[Photodiode<T>]> {
        if self.count > MAX_PHOTODIODES {
            return None;
        }
        self.photodiodes.get(..self.count)
    }
}
