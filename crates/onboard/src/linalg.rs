//! 3-vectors and symmetric 3x3 matrices, without indexing (so without a panic path).

use crate::Real;

/// A 3-vector.
pub type V3<T> = [T; 3];
/// A 3x3 matrix, rows.
pub type M3<T> = [[T; 3]; 3];

pub fn dot<T: Real>([a, b, c]: V3<T>, [x, y, z]: V3<T>) -> T {
    a * x + b * y + c * z
}

pub fn scale<T: Real>([a, b, c]: V3<T>, k: T) -> V3<T> {
    [a * k, b * k, c * k]
}

pub fn sub<T: Real>([a, b, c]: V3<T>, [x, y, z]: V3<T>) -> V3<T> {
    [a - x, b - y, c - z]
}

pub fn norm<T: Real>(v: V3<T>) -> T {
    dot(v, v).sqrt()
}

pub fn is_finite<T: Real>([a, b, c]: V3<T>) -> bool {
    a.is_finite() && b.is_finite() && c.is_finite()
}

/// `m v`.
pub fn mul<T: Real>([r0, r1, r2]: &M3<T>, v: V3<T>) -> V3<T> {
    [dot(*r0, v), dot(*r1, v), dot(*r2, v)]
}

/// `m^T v`.
pub fn mul_t<T: Real>([r0, r1, r2]: &M3<T>, [a, b, c]: V3<T>) -> V3<T> {
    let [x0, y0, z0] = *r0;
    let [x1, y1, z1] = *r1;
    let [x2, y2, z2] = *r2;
    [
        x0 * a + x1 * b + x2 * c,
        y0 * a + y1 * b + y2 * c,
        z0 * a + z1 * b + z2 * c,
    ]
}

/// A symmetric 3x3 matrix: `[xx, yy, zz, xy, xz, yz]`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Sym3<T>(pub [T; 6]);

impl<T: Real> Sym3<T> {
    /// Adds `w v v^T`.
    pub fn add_outer(&mut self, [x, y, z]: V3<T>, w: T) {
        let [xx, yy, zz, xy, xz, yz] = &mut self.0;
        *xx = *xx + w * x * x;
        *yy = *yy + w * y * y;
        *zz = *zz + w * z * z;
        *xy = *xy + w * x * y;
        *xz = *xz + w * x * z;
        *yz = *yz + w * y * z;
    }

    pub fn full(&self) -> M3<T> {
        let [xx, yy, zz, xy, xz, yz] = self.0;
        [[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]
    }

    /// The inverse, when the matrix is positive definite (its determinant above a tiny
    /// fraction of the cube of its trace).
    pub fn inverse(&self) -> Option<Sym3<T>> {
        let [a, d, f, b, c, e] = self.0;
        // [[a b c] [b d e] [c e f]]
        let c00 = d * f - e * e;
        let c01 = c * e - b * f;
        let c02 = b * e - c * d;
        let det = a * c00 + b * c01 + c * c02;
        let trace = a + d + f;
        let floor = T::of(1e-12) * trace * trace * trace;
        if !(det > floor) || !det.is_finite() {
            return None;
        }
        let c11 = a * f - c * c;
        let c12 = b * c - a * e;
        let c22 = a * d - b * b;
        let k = det.recip();
        Some(Sym3([c00 * k, c11 * k, c22 * k, c01 * k, c02 * k, c12 * k]))
    }

    /// The smallest eigenvalue (trigonometric solution of the characteristic cubic).
    pub fn min_eigenvalue(&self) -> T {
        let [a, d, f, b, c, e] = self.0;
        let p1 = b * b + c * c + e * e;
        let q = (a + d + f) / T::of(3.0);
        if p1 <= T::zero() {
            return a.min(d).min(f);
        }
        let p2 = (a - q) * (a - q) + (d - q) * (d - q) + (f - q) * (f - q) + T::of(2.0) * p1;
        let p = (p2 / T::of(6.0)).sqrt();
        if !(p > T::zero()) {
            return q;
        }
        let k = p.recip();
        let (ba, bd, bf) = ((a - q) * k, (d - q) * k, (f - q) * k);
        let (bb, bc, be) = (b * k, c * k, e * k);
        let det_b = ba * (bd * bf - be * be) - bb * (bb * bf - be * bc) + bc * (bb * be - bd * bc);
        let r = (det_b / T::of(2.0)).max(-T::one()).min(T::one());
        let phi = r.acos() / T::of(3.0);
        q + T::of(2.0) * p * (phi + T::of(2.0 * core::f64::consts::PI / 3.0)).cos()
    }
}
