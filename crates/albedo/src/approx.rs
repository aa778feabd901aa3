//! Onboard approximation (the paper's future work, Sec. V): per step, the radiance of the
//! visible lit Earth is reduced to its angular moments up to degree [`DEGREE`] (35 numbers,
//! equivalent to a real spherical-harmonic expansion to the same degree); each photodiode is
//! then evaluated in O(1), independent of the number of cells.
//!
//! For a sensor with normal n the exact ratio is sum_i c_i k(n.u_i) with the gated cosine
//! kernel k(t) = t [t >= g], g = max(cos_fov, 0). All t = n.u_i lie in an interval [a, b] known
//! from the angle between n and nadir and the Earth's angular radius rho. On that interval k is
//! replaced by its least-squares polynomial p of degree [`DEGREE`] (a Legendre projection on
//! [a, b], exact by Gauss quadrature), so the ratio becomes sum_k p_k S_k with the t-moments
//! S_k = sum_i c_i t_i^k, which are contractions of the stored moment tensors with n. When the
//! gate holds for the whole interval the result is exact (n . sum c u); when it fails for the
//! whole interval it is exactly zero. The error therefore comes only from sensors whose gate
//! cuts the Earth disc, and is largest for a field of view narrower than 90 deg (a step in k).
//! Measured errors are in the tests and the crate docs.

use nalgebra::{Matrix3, Vector3};

use crate::view::{AlbedoIrradiance, AlbedoView, cone_range};

/// Degree of the moment expansion (and of the kernel polynomial).
pub const DEGREE: usize = 4;
/// Number of moment tensor entries up to [`DEGREE`]: sum over k of (k+1)(k+2)/2.
const N_MOMENTS: usize = 35;
/// Moments of degree DEGREE-1 or less (used by the vector sums, which need one more power).
const N_LOWER: usize = 20;

/// Exponents (a, b, c) of ux^a uy^b uz^c, degree by degree, and the multinomial
/// k! / (a! b! c!) with which the monomial appears in (n.u)^k.
const TERMS: [(usize, usize, usize, f64); N_MOMENTS] = build_terms();

const fn factorial(n: usize) -> f64 {
    let mut f = 1.0;
    let mut k = 2;
    while k <= n {
        f *= k as f64;
        k += 1;
    }
    f
}

const fn build_terms() -> [(usize, usize, usize, f64); N_MOMENTS] {
    let mut out = [(0, 0, 0, 0.0); N_MOMENTS];
    let mut idx = 0;
    let mut k = 0;
    while k <= DEGREE {
        let mut a = k as isize;
        while a >= 0 {
            let mut b = (k as isize) - a;
            while b >= 0 {
                let c = k as isize - a - b;
                let (a_, b_, c_) = (a as usize, b as usize, c as usize);
                out[idx] = (
                    a_,
                    b_,
                    c_,
                    factorial(k) / (factorial(a_) * factorial(b_) * factorial(c_)),
                );
                idx += 1;
                b -= 1;
            }
            a -= 1;
        }
        k += 1;
    }
    out
}

/// Index in [`TERMS`] of the exponents (a, b, c).
const fn term_index(a: usize, b: usize, c: usize) -> usize {
    let k = a + b + c;
    // Entries before degree k, then the position inside degree k (a descending, b descending).
    let before = k * (k + 1) * (k + 2) / 6;
    let rest = k - a; // b + c
    let within = (k - a) * (k - a + 1) / 2 + (rest - b);
    before + within
}

/// Index of the moment one power of x (axis 0), y (1) or z (2) above term `t`.
const fn raised(t: usize, axis: usize) -> usize {
    let (a, b, c, _) = TERMS[t];
    match axis {
        0 => term_index(a + 1, b, c),
        1 => term_index(a, b + 1, c),
        _ => term_index(a, b, c + 1),
    }
}

/// 4-point Gauss-Legendre nodes and weights on [-1, 1] (exact for degree <= 7).
const GAUSS_X: [f64; 4] = [
    -0.861_136_311_594_052_6,
    -0.339_981_043_584_856_3,
    0.339_981_043_584_856_3,
    0.861_136_311_594_052_6,
];
const GAUSS_W: [f64; 4] = [
    0.347_854_845_137_453_9,
    0.652_145_154_862_546_1,
    0.652_145_154_862_546_1,
    0.347_854_845_137_453_9,
];

/// The per-step moment expansion of the albedo radiance: build once per step with
/// [`AlbedoExpansion::from_view`], evaluate per sensor in O(1) through [`AlbedoIrradiance`].
#[derive(Debug, Clone)]
pub struct AlbedoExpansion {
    /// sum_i c_i ux^a uy^b uz^c for the exponents of [`TERMS`].
    moments: [f64; N_MOMENTS],
    /// Moments and nadir are in ECEF (as the view stores them); normals are rotated in.
    nadir_ecef: Vector3<f64>,
    sin_rho: f64,
    gcrf_to_ecef: Matrix3<f64>,
}

impl Default for AlbedoExpansion {
    fn default() -> Self {
        Self {
            moments: [0.0; N_MOMENTS],
            nadir_ecef: Vector3::z(),
            sin_rho: 0.0,
            gcrf_to_ecef: Matrix3::identity(),
        }
    }
}

impl AlbedoExpansion {
    /// Moments of the cells of `view` (O(cells), 35 products per cell).
    pub fn from_view(view: &AlbedoView) -> Self {
        let mut out = Self::default();
        out.update(view);
        out
    }

    /// Recomputes the moments from `view` in place.
    pub fn update(&mut self, view: &AlbedoView) {
        self.moments = [0.0; N_MOMENTS];
        let ([ux, uy, uz, c], nadir_ecef) = view.cells_ecef();
        self.nadir_ecef = nadir_ecef;
        self.sin_rho = view.sin_rho();
        self.gcrf_to_ecef = view.gcrf_to_ecef();
        for k in 0..c.len() {
            // Slots of cells failing the tests (c = 0) add nothing.
            if c[k] == 0.0 {
                continue;
            }
            let px = powers(ux[k]);
            let py = powers(uy[k]);
            let pz = powers(uz[k]);
            for (m, &(a, b, e, _)) in self.moments.iter_mut().zip(TERMS.iter()) {
                *m += c[k] * px[a] * py[b] * pz[e];
            }
        }
    }

    /// Total weight (sum of c), equal to [`AlbedoView::max_ratio`].
    pub fn max_ratio(&self) -> f64 {
        self.moments[0]
    }

    fn sum_cu(&self) -> Vector3<f64> {
        Vector3::new(self.moments[1], self.moments[2], self.moments[3])
    }

    /// t-moments S_k = sum c (n.u)^k, k = 0..=DEGREE, and vector moments
    /// V_k = sum c (n.u)^k u, k = 0..DEGREE.
    fn t_moments(&self, n: &Vector3<f64>) -> ([f64; DEGREE + 1], [Vector3<f64>; DEGREE]) {
        let (px, py, pz) = (powers(n.x), powers(n.y), powers(n.z));
        let mut s = [0.0; DEGREE + 1];
        let mut v = [Vector3::zeros(); DEGREE];
        for (t, &(a, b, c, multi)) in TERMS.iter().enumerate() {
            let w = multi * px[a] * py[b] * pz[c];
            s[a + b + c] += w * self.moments[t];
            if t < N_LOWER {
                let raised = Vector3::new(
                    self.moments[raised(t, 0)],
                    self.moments[raised(t, 1)],
                    self.moments[raised(t, 2)],
                );
                v[a + b + c] += w * raised;
            }
        }
        (s, v)
    }

    fn evaluate(
        &self,
        n_gcrf: &Vector3<f64>,
        cos_fov: f64,
        with_vector: bool,
    ) -> (f64, Vector3<f64>) {
        let (ratio, vector_ecef) =
            self.evaluate_ecef(&(self.gcrf_to_ecef * n_gcrf), cos_fov, with_vector);
        (
            ratio,
            self.gcrf_to_ecef.tr_mul(&vector_ecef).column(0).into(),
        )
    }

    fn evaluate_ecef(
        &self,
        n: &Vector3<f64>,
        cos_fov: f64,
        with_vector: bool,
    ) -> (f64, Vector3<f64>) {
        if self.moments[0] == 0.0 || n.norm() == 0.0 {
            return (0.0, Vector3::zeros());
        }
        let gate = cos_fov.max(0.0);
        let (lo, hi) = cone_range(n, &self.nadir_ecef, self.sin_rho);
        if hi <= gate {
            return (0.0, Vector3::zeros());
        }
        if lo >= gate {
            return (n.dot(&self.sum_cu()), self.sum_cu());
        }
        let (s, v) = self.t_moments(n);
        let p = fit_on_interval(lo, hi, gate, |t| t, DEGREE);
        let ratio = p.iter().zip(&s).map(|(pk, sk)| pk * sk).sum();
        let vector = if with_vector {
            let q = fit_on_interval(lo, hi, gate, |_| 1.0, DEGREE - 1);
            q.iter().zip(&v).map(|(qk, vk)| *qk * vk).sum()
        } else {
            Vector3::zeros()
        };
        (ratio, vector)
    }
}

/// [1, x, x^2, ..., x^DEGREE].
fn powers(x: f64) -> [f64; DEGREE + 1] {
    let mut p = [1.0; DEGREE + 1];
    for k in 1..=DEGREE {
        p[k] = p[k - 1] * x;
    }
    p
}

/// Legendre polynomials P_0..P_DEGREE at s.
fn legendre(s: f64) -> [f64; DEGREE + 1] {
    let mut p = [0.0; DEGREE + 1];
    p[0] = 1.0;
    p[1] = s;
    for j in 1..DEGREE {
        p[j + 1] = ((2 * j + 1) as f64 * s * p[j] - j as f64 * p[j - 1]) / (j + 1) as f64;
    }
    p
}

/// Monomial coefficients of P_j(s), j <= 4, by ascending power of s.
const LEGENDRE_MONO: [[f64; DEGREE + 1]; DEGREE + 1] = [
    [1.0, 0.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0, 0.0],
    [-0.5, 0.0, 1.5, 0.0, 0.0],
    [0.0, -1.5, 0.0, 2.5, 0.0],
    [0.375, 0.0, -3.75, 0.0, 4.375],
];

/// Least-squares polynomial of degree `deg` in t for f(t) [t >= gate] on [lo, hi]
/// (lo < gate < hi), returned by ascending power of t. f must be a polynomial of degree <= 1
/// so that the 4-point Gauss rule is exact.
fn fit_on_interval(
    lo: f64,
    hi: f64,
    gate: f64,
    f: impl Fn(f64) -> f64,
    deg: usize,
) -> [f64; DEGREE + 1] {
    // s = alpha + beta t maps [lo, hi] to [-1, 1].
    let beta = 2.0 / (hi - lo);
    let alpha = -(hi + lo) / (hi - lo);
    let s_gate = alpha + beta * gate;
    // Legendre coefficients: (2j+1)/2 * integral over [s_gate, 1] of f P_j ds.
    let half = 0.5 * (1.0 - s_gate);
    let mut coef = [0.0; DEGREE + 1];
    for (x, w) in GAUSS_X.iter().zip(GAUSS_W) {
        let s = s_gate + half * (x + 1.0);
        let t = (s - alpha) / beta;
        let pj = legendre(s);
        for j in 0..=deg {
            coef[j] += w * half * f(t) * pj[j];
        }
    }
    for (j, cj) in coef.iter_mut().enumerate() {
        *cj *= (2 * j + 1) as f64 / 2.0;
    }
    // Series in s -> monomials in s -> monomials in t via s^m = sum C(m,k) alpha^(m-k) beta^k t^k.
    let mut in_s = [0.0; DEGREE + 1];
    for j in 0..=deg {
        for m in 0..=j {
            in_s[m] += coef[j] * LEGENDRE_MONO[j][m];
        }
    }
    let mut in_t = [0.0; DEGREE + 1];
    for (m, &sm) in in_s.iter().enumerate() {
        let mut binom = 1.0;
        for (k, tk) in in_t.iter_mut().enumerate().take(m + 1) {
            *tk += sm * binom * alpha.powi((m - k) as i32) * beta.powi(k as i32);
            binom = binom * (m - k) as f64 / (k + 1) as f64;
        }
    }
    in_t
}

impl AlbedoIrradiance for AlbedoExpansion {
    fn ratio(&self, n_gcrf: &Vector3<f64>, cos_fov: f64) -> f64 {
        self.evaluate(n_gcrf, cos_fov, false).0
    }

    fn ratio_and_vector(&self, n_gcrf: &Vector3<f64>, cos_fov: f64) -> (f64, Vector3<f64>) {
        self.evaluate(n_gcrf, cos_fov, true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn term_table_is_consistent() {
        for (t, &(a, b, c, _)) in TERMS.iter().enumerate() {
            assert_eq!(term_index(a, b, c), t);
        }
        // Multinomials of degree k sum to 3^k.
        let mut sums = [0.0; DEGREE + 1];
        for &(a, b, c, m) in &TERMS {
            sums[a + b + c] += m;
        }
        for (k, s) in sums.iter().enumerate() {
            assert_eq!(*s, 3f64.powi(k as i32));
        }
    }

    #[test]
    fn fit_reproduces_polynomials() {
        // With the gate at the interval start the kernel is t itself: exact fit.
        let p = fit_on_interval(0.2, 0.9, 0.2, |t| t, DEGREE);
        for t in [0.2f64, 0.5, 0.9] {
            let val: f64 = p
                .iter()
                .enumerate()
                .map(|(k, pk)| pk * t.powi(k as i32))
                .sum();
            assert!((val - t).abs() < 1e-12);
        }
    }
}
