//! Photodiode normals from azimuth and elevation (paper Eq. 16) and their partials.

use nalgebra::Vector3;

/// Table 1 of the paper: the intended (azimuth, elevation) of RAX-2's 17 photodiodes,
/// degrees, in pdNN order. The one copy every test, bench and scenario check uses.
pub const RAX2_TABLE1_AZ_EL_DEG: [(f64, f64); 17] = [
    (17.0, -10.0),
    (0.0, 20.0),
    (-17.0, -10.0),
    (-162.0, -10.0),
    (180.0, 20.0),
    (162.0, -10.0),
    (72.0, 10.0),
    (107.0, 10.0),
    (90.0, -20.0),
    (-107.0, 10.0),
    (-72.0, 10.0),
    (-90.0, -20.0),
    (0.0, 90.0),
    (0.0, 90.0),
    (0.0, 90.0),
    (0.0, -90.0),
    (0.0, -90.0),
];

/// Unit normal of Eq. (16): `n = [cos(el) cos(az), cos(el) sin(az), sin(el)]^T`.
pub fn normal_from_az_el(azimuth_rad: f64, elevation_rad: f64) -> Vector3<f64> {
    let (sa, ca) = azimuth_rad.sin_cos();
    let (se, ce) = elevation_rad.sin_cos();
    Vector3::new(ce * ca, ce * sa, se)
}

/// The difference of two azimuths (or any angles), deg, wrapped into [-180, 180).
pub fn wrap_deg(d: f64) -> f64 {
    (d + 180.0).rem_euclid(360.0) - 180.0
}

/// Azimuth and elevation (radians) of a direction; the inverse of Eq. (16).
/// At the poles (`|el| = 90 deg`) the azimuth is undefined and 0 is returned.
pub fn az_el_from_normal(n: &Vector3<f64>) -> (f64, f64) {
    let horizontal = n.x.hypot(n.y);
    let elevation = n.z.atan2(horizontal);
    let azimuth = if horizontal > 0.0 {
        n.y.atan2(n.x)
    } else {
        0.0
    };
    (azimuth, elevation)
}

/// Partial derivatives of Eq. (16): `(dn/d az, dn/d el)`, the vectors of Eqs. (23) and (24).
///
/// The paper prints the x component of dn/d el as `-sin(el) cos(az)` and the y component as
/// `sin(el) sin(az)`; differentiating Eq. (16) gives `-sin(el) sin(az)` for y. This function
/// returns the derivative itself; a finite-difference test pins it.
pub fn normal_partials(azimuth_rad: f64, elevation_rad: f64) -> (Vector3<f64>, Vector3<f64>) {
    let (sa, ca) = azimuth_rad.sin_cos();
    let (se, ce) = elevation_rad.sin_cos();
    (
        Vector3::new(-ce * sa, ce * ca, 0.0),
        Vector3::new(-se * ca, -se * sa, ce),
    )
}

/// The one direction where [`tangent_basis`] is discontinuous: the cube diagonal
/// `-(1, 1, 1)/sqrt(3)`. A continuous tangent frame on the whole sphere cannot exist
/// (hairy-ball theorem), so the break is put where a box-shaped spacecraft mounts no
/// sensor: 54.7 deg from every face normal, and 35 deg from the nearest intended RAX-2
/// normal (az -162 deg, el -10 deg). The poles of Eq. (16), `n = ±z`, are regular.
pub const TANGENT_BASIS_SINGULAR_DIRECTION: Vector3<f64> =
    Vector3::new(-FRAC_1_SQRT_3, -FRAC_1_SQRT_3, -FRAC_1_SQRT_3);

/// `1/sqrt(3)` (std's constant of that name is not stable yet).
const FRAC_1_SQRT_3: f64 = 0.577_350_269_189_625_8;

/// Within this value of `1 + c·n` (about 1.4e-5 rad of the singular direction) the
/// rotation formula has lost too many digits and the fixed fallback basis is used.
const SINGULAR_GUARD: f64 = 1e-10;

/// Two unit vectors `(e1, e2)` orthogonal to the unit normal `n` and to each other, with
/// `(e1, e2, n)` right-handed.
///
/// A fixed frame `(u0, v0, c)` with `c = (1, 1, 1)/sqrt(3)` is carried to `n` by the
/// smallest rotation taking `c` to `n` (Rodrigues, `k = c x n`:
/// `R = I + [k x] + [k x]^2 / (1 + c·n)`), then re-orthonormalised against `n`. The
/// result is smooth everywhere except at [`TANGENT_BASIS_SINGULAR_DIRECTION`] `= -c`,
/// where a fixed basis is returned (the limit there depends on the approach
/// direction). Well-defined and smooth at both poles of Eq. (16), unlike the
/// azimuth/elevation partials of Eqs. (23)-(24), which vanish or turn there.
pub fn tangent_basis(n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    let c = -TANGENT_BASIS_SINGULAR_DIRECTION;
    carried_basis(n, &c, &(Vector3::new(1.0, -1.0, 0.0) / 2f64.sqrt()))
}

/// A tangent basis of `n` that is smooth everywhere except at `-reference`: the basis of
/// [`tangent_basis`] at `reference`, carried to `n` by the smallest rotation.
///
/// A filter that estimates a normal near its initial value passes that initial value as
/// `reference`; the break then lies 180 deg from the estimate, wherever the sensor is mounted
/// (the fixed break of [`tangent_basis`] sits on the corner directions `±(1,1,1)/sqrt(3)`
/// that canted sensors of a box-shaped spacecraft may well use).
pub fn tangent_basis_about(
    n: &Vector3<f64>,
    reference: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    TangentFrame::about(reference).basis_at(n)
}

/// The reference frame of [`tangent_basis_about`], computed once for a reference that is
/// used many times (a filter's initial normal): `basis_at(n)` gives the same bits as
/// `tangent_basis_about(n, reference)` without redoing the reference's part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TangentFrame {
    /// The reference made unit.
    reference: Vector3<f64>,
    /// The first vector of [`tangent_basis`] at the reference.
    u0: Vector3<f64>,
}

impl TangentFrame {
    /// The frame about `reference` (any non-zero length).
    pub fn about(reference: &Vector3<f64>) -> Self {
        let reference = reference.normalize();
        let (u0, _) = tangent_basis(&reference);
        TangentFrame { reference, u0 }
    }

    /// The tangent basis `(e1, e2)` of the unit normal `n` (see [`tangent_basis_about`]).
    #[inline]
    pub fn basis_at(&self, n: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        carried_basis(n, &self.reference, &self.u0)
    }
}

/// Carries the frame `(u0, c x u0, c)` to `n` by the smallest rotation taking `c` to `n`
/// (Rodrigues, `k = c x n`: `R = I + [k x] + [k x]^2 / (1 + c·n)`), re-orthonormalised.
#[inline]
fn carried_basis(
    n: &Vector3<f64>,
    c: &Vector3<f64>,
    u0: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    let one_plus_cos = 1.0 + c.dot(n);
    let e1 = if one_plus_cos > SINGULAR_GUARD {
        let k = c.cross(n);
        u0 + k.cross(u0) + k.cross(&k.cross(u0)) / one_plus_cos
    } else {
        // The half-turn about u0 also takes c to -c and keeps u0.
        *u0
    };
    let e1 = (e1 - n * n.dot(&e1)).normalize();
    let e2 = n.cross(&e1);
    (e1, e2)
}

/// Rotates the unit normal `n` by the tangent correction `d1 e1 + d2 e2` (radians,
/// `(e1, e2)` from [`tangent_basis`]): along the great circle through `n` in that
/// direction by the angle `theta = |d1 e1 + d2 e2|`,
/// `n' = cos(theta) n + sin(theta)/theta (d1 e1 + d2 e2)`. Exact for any size, unit
/// output, and `d n'/d d1 = e1`, `d n'/d d2 = e2` at zero.
pub fn rotate_normal(n: &Vector3<f64>, d1: f64, d2: f64) -> Vector3<f64> {
    let (e1, e2) = tangent_basis(n);
    rotate_normal_in(n, (&e1, &e2), d1, d2)
}

/// [`rotate_normal`] in a given tangent basis `(e1, e2)` of `n` (e.g. from
/// [`tangent_basis_about`]).
#[inline]
pub fn rotate_normal_in(
    n: &Vector3<f64>,
    (e1, e2): (&Vector3<f64>, &Vector3<f64>),
    d1: f64,
    d2: f64,
) -> Vector3<f64> {
    let t = e1 * d1 + e2 * d2;
    let theta2 = t.norm_squared();
    // A filter's per-step corrections are small: the series, no libm call.
    let (sinc, cos) = crate::series::sinc_and_cos(theta2).unwrap_or_else(|| {
        let theta = theta2.sqrt();
        (theta.sin() / theta, theta.cos())
    });
    (n * cos + t * sinc).normalize()
}
