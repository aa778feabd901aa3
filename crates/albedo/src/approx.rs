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
use wide::f64x4;

use crate::lanes::{Lane, dot3, mat_vec};
#[cfg(test)]
use crate::view::cone_range;
use crate::view::{AlbedoIrradiance, AlbedoView};

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

/// [`raised`] for every term of degree below [`DEGREE`] and each axis.
const RAISED: [[usize; 3]; N_LOWER] = build_raised();

const fn build_raised() -> [[usize; 3]; N_LOWER] {
    let mut out = [[0; 3]; N_LOWER];
    let mut t = 0;
    while t < N_LOWER {
        out[t] = [raised(t, 0), raised(t, 1), raised(t, 2)];
        t += 1;
    }
    out
}

/// First term of each degree in [`TERMS`] (and one past the last).
const DEGREE_START: [usize; DEGREE + 2] = [0, 1, 4, 10, 20, 35];

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
    /// `moments` times the multinomials of [`TERMS`] (the per-sensor contraction then needs
    /// only the monomials of n).
    scaled: [f64; N_MOMENTS],
    /// For the terms of degree below [`DEGREE`]: the multinomial times the moments one power
    /// of x, y, z higher (the vector sums).
    scaled_raised: [[f64; 3]; N_LOWER],
    /// Moments and nadir are in ECEF (as the view stores them); normals are rotated in.
    nadir_ecef: Vector3<f64>,
    sin_rho: f64,
    /// `sqrt(1 - sin_rho^2)`, as [`cone_range`] computes it.
    cos_rho: f64,
    gcrf_to_ecef: Matrix3<f64>,
}

impl Default for AlbedoExpansion {
    fn default() -> Self {
        Self {
            moments: [0.0; N_MOMENTS],
            scaled: [0.0; N_MOMENTS],
            scaled_raised: [[0.0; 3]; N_LOWER],
            nadir_ecef: Vector3::z(),
            sin_rho: 0.0,
            cos_rho: 1.0,
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
        self.cos_rho = (1.0 - self.sin_rho * self.sin_rho).sqrt();
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
        for (t, &(_, _, _, multi)) in TERMS.iter().enumerate() {
            self.scaled[t] = multi * self.moments[t];
            if t < N_LOWER {
                for (axis, slot) in self.scaled_raised[t].iter_mut().enumerate() {
                    *slot = multi * self.moments[RAISED[t][axis]];
                }
            }
        }
    }

    /// Total weight (sum of c), equal to [`AlbedoView::max_ratio`].
    pub fn max_ratio(&self) -> f64 {
        self.moments[0]
    }

    /// t-moments S_k = sum c (n.u)^k, k = 0..=DEGREE, and (with `with_vector`) vector
    /// moments V_k = sum c (n.u)^k u, k = 0..DEGREE: the moment tensors contracted with the
    /// monomials of n, degree by degree.
    fn t_moments<T: Lane>(
        &self,
        n: &[T; 3],
        with_vector: bool,
    ) -> ([T; DEGREE + 1], [[T; 3]; DEGREE]) {
        let (px, py, pz) = (powers(n[0]), powers(n[1]), powers(n[2]));
        let mono: [T; N_MOMENTS] = std::array::from_fn(|t| {
            let (a, b, c, _) = TERMS[t];
            px[a] * py[b] * pz[c]
        });
        let zero = T::splat(0.0);
        let s = std::array::from_fn(|k| {
            let range = DEGREE_START[k]..DEGREE_START[k + 1];
            mono[range.clone()]
                .iter()
                .zip(&self.scaled[range])
                .fold(zero, |acc, (m, w)| acc + *m * T::splat(*w))
        });
        let mut v = [[zero; 3]; DEGREE];
        if with_vector {
            for (k, vk) in v.iter_mut().enumerate() {
                let range = DEGREE_START[k]..DEGREE_START[k + 1];
                for (m, w) in mono[range.clone()].iter().zip(&self.scaled_raised[range]) {
                    for (s, w) in vk.iter_mut().zip(w) {
                        *s = *s + *m * T::splat(*w);
                    }
                }
            }
        }
        (s, v)
    }

    /// Rows of the GCRF to ECEF rotation.
    fn rotation_rows(&self) -> [[f64; 3]; 3] {
        let m = &self.gcrf_to_ecef;
        std::array::from_fn(|r| [m[(r, 0)], m[(r, 1)], m[(r, 2)]])
    }

    /// Rows of the ECEF to GCRF rotation (the transpose).
    fn inverse_rows(&self) -> [[f64; 3]; 3] {
        let m = &self.gcrf_to_ecef;
        std::array::from_fn(|r| [m[(0, r)], m[(1, r)], m[(2, r)]])
    }

    /// [`cone_range`] with the norm of `n` and `cos_rho` already known (two square roots
    /// fewer), per lane.
    fn cone_range<T: Lane>(&self, n: &[T; 3], n_norm: T) -> (T, T) {
        let (sin_rho, cos_r) = (T::splat(self.sin_rho), T::splat(self.cos_rho));
        let nadir = [self.nadir_ecef.x, self.nadir_ecef.y, self.nadir_ecef.z].map(T::splat);
        let cos_a = (dot3(n, &nadir) / n_norm).clamp_unit();
        let sin_a = (T::splat(1.0) - cos_a * cos_a).sqrt();
        let hi = T::ge_select(cos_a, cos_r, T::splat(1.0), cos_a * cos_r + sin_a * sin_rho);
        let lo = T::ge_select(
            -cos_r,
            cos_a,
            T::splat(-1.0),
            cos_a * cos_r - sin_a * sin_rho,
        );
        (lo * n_norm, hi * n_norm)
    }

    /// Ratio and vector (ECEF) where the gate cuts the interval `[lo, hi]` of `t = n.u`:
    /// the kernel's polynomial against the t-moments.
    fn partial<T: Lane>(
        &self,
        n: &[T; 3],
        lo: T,
        hi: T,
        gate: T,
        with_vector: bool,
    ) -> (T, [T; 3]) {
        let (s, v) = self.t_moments(n, with_vector);
        let (p, q) = fit_on_interval(lo, hi, gate);
        let zero = T::splat(0.0);
        let ratio = p.iter().zip(&s).fold(zero, |acc, (pk, sk)| acc + *pk * *sk);
        let mut vector = [zero; 3];
        if with_vector {
            for (qk, vk) in q.iter().zip(&v) {
                for (out, x) in vector.iter_mut().zip(vk) {
                    *out = *out + *qk * *x;
                }
            }
        }
        (ratio, vector)
    }

    fn evaluate(
        &self,
        n_gcrf: &Vector3<f64>,
        cos_fov: f64,
        with_vector: bool,
    ) -> (f64, Vector3<f64>) {
        let n = mat_vec(&self.rotation_rows(), &[n_gcrf.x, n_gcrf.y, n_gcrf.z]);
        let n_norm = dot3(&n, &n).sqrt();
        if self.moments[0] == 0.0 || n_norm == 0.0 {
            return (0.0, Vector3::zeros());
        }
        let gate = cos_fov.max(0.0);
        let (lo, hi) = self.cone_range(&n, n_norm);
        let (ratio, vector_ecef) = if hi <= gate {
            return (0.0, Vector3::zeros());
        } else if lo >= gate {
            (dot3(&n, &self.sum_cu()), self.sum_cu())
        } else {
            self.partial(&n, lo, hi, gate, with_vector)
        };
        (
            ratio,
            Vector3::from(mat_vec(&self.inverse_rows(), &vector_ecef)),
        )
    }

    /// [`AlbedoIrradiance::ratios_and_vectors`] for four normals at once (one lane each):
    /// every lane takes the partial-cone path, then each keeps the branch
    /// [`AlbedoExpansion::evaluate`] would have taken.
    fn evaluate4(&self, n_gcrf: &[[f64; 4]; 3], cos_fov: f64x4) -> (f64x4, [f64x4; 3]) {
        let zero = f64x4::splat(0.0);
        let n = mat_vec(&self.rotation_rows(), &n_gcrf.map(f64x4::new));
        let n_norm = dot3(&n, &n).sqrt();
        let gate = cos_fov.max(zero);
        let (lo, hi) = self.cone_range(&n, n_norm);
        let (ratio, vector) = self.partial(&n, lo, hi, gate, true);
        let full = self.sum_cu();
        let full_ratio = dot3(&n, &full);
        // lo >= gate: the whole cone in view; hi <= gate (or a zero normal): nothing.
        let inside = |full: f64x4, part: f64x4| {
            let value = f64x4::ge_select(lo, gate, full, part);
            let seen = n_norm.simd_gt(zero) & hi.simd_gt(gate);
            seen.bitselect(value, zero)
        };
        let ratio = inside(full_ratio, ratio);
        let vector_ecef: [f64x4; 3] = std::array::from_fn(|a| inside(full[a], vector[a]));
        (ratio, mat_vec(&self.inverse_rows(), &vector_ecef))
    }

    /// `[S_1, S_2, S_3]` at degree one: the sum of c u (ECEF), per lane.
    fn sum_cu<T: Lane>(&self) -> [T; 3] {
        [self.moments[1], self.moments[2], self.moments[3]].map(T::splat)
    }
}

/// [1, x, x^2, ..., x^DEGREE].
fn powers<T: Lane>(x: T) -> [T; DEGREE + 1] {
    let mut p = [T::splat(1.0); DEGREE + 1];
    for k in 1..=DEGREE {
        p[k] = p[k - 1] * x;
    }
    p
}

/// Legendre polynomials P_0..P_DEGREE at s, by Bonnet's recursion with the divisions by
/// `j + 1` done as products with [`RECIPROCALS`] (a division's latency is several
/// multiplications': the recursion is on the evaluation's critical path).
fn legendre<T: Lane>(s: T) -> [T; DEGREE + 1] {
    let mut p = [T::splat(0.0); DEGREE + 1];
    p[0] = T::splat(1.0);
    p[1] = s;
    for j in 1..DEGREE {
        p[j + 1] = (T::splat((2 * j + 1) as f64) * s * p[j] - T::splat(j as f64) * p[j - 1])
            * T::splat(RECIPROCALS[j + 1]);
    }
    p
}

/// `1 / k`, k = 0..=DEGREE (entry 0 unused).
const RECIPROCALS: [f64; DEGREE + 1] = [0.0, 1.0, 0.5, 1.0 / 3.0, 0.25];

/// Legendre polynomials P_0..P_DEGREE at s, dividing (the first form).
#[cfg(test)]
fn legendre_dividing(s: f64) -> [f64; DEGREE + 1] {
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

/// Least-squares polynomials on [lo, hi] (lo < gate < hi), by ascending power of t: of
/// degree [`DEGREE`] for the gated kernel t [t >= gate], and of degree `DEGREE - 1` for the
/// gate [t >= gate] alone (the vector sums). The integrands are polynomials of degree
/// <= 2 DEGREE - 1 on [gate, hi], so the 4-point Gauss rule is exact.
fn fit_on_interval<T: Lane>(lo: T, hi: T, gate: T) -> ([T; DEGREE + 1], [T; DEGREE]) {
    let (zero, one, half_c) = (T::splat(0.0), T::splat(1.0), T::splat(0.5));
    // s = alpha + beta t maps [lo, hi] to [-1, 1]; t = (s - alpha) half_width.
    let inv_width = one / (hi - lo);
    let beta = T::splat(2.0) * inv_width;
    let alpha = -(hi + lo) * inv_width;
    let half_width = half_c * (hi - lo);
    let s_gate = alpha + beta * gate;
    // Legendre coefficients: (2j+1)/2 * integral over [s_gate, 1] of f P_j ds.
    let half = half_c * (one - s_gate);
    let mut coef_t = [zero; DEGREE + 1];
    let mut coef_1 = [zero; DEGREE + 1];
    for (x, w) in GAUSS_X.iter().zip(GAUSS_W) {
        let s = s_gate + half * (T::splat(*x) + one);
        let t = (s - alpha) * half_width;
        let pj = legendre(s);
        let wh = T::splat(w) * half;
        for j in 0..=DEGREE {
            coef_1[j] = coef_1[j] + wh * pj[j];
            coef_t[j] = coef_t[j] + wh * t * pj[j];
        }
    }
    for j in 0..=DEGREE {
        let norm = T::splat((2 * j + 1) as f64 / 2.0);
        coef_t[j] = coef_t[j] * norm;
        coef_1[j] = coef_1[j] * norm;
    }
    // alpha^m and beta^m, m = 0..=DEGREE.
    let (pa, pb) = (powers(alpha), powers(beta));
    let to_t = |coef: &[T], deg: usize| {
        // Series in s -> monomials in s -> monomials in t via
        // s^m = sum C(m,k) alpha^(m-k) beta^k t^k.
        let mut in_s = [zero; DEGREE + 1];
        for j in 0..=deg {
            for m in 0..=j {
                in_s[m] = in_s[m] + coef[j] * T::splat(LEGENDRE_MONO[j][m]);
            }
        }
        let mut in_t = [zero; DEGREE + 1];
        for (m, &sm) in in_s.iter().enumerate().take(deg + 1) {
            for (k, tk) in in_t.iter_mut().enumerate().take(m + 1) {
                *tk = *tk + sm * T::splat(BINOMIAL[m][k]) * pa[m - k] * pb[k];
            }
        }
        in_t
    };
    let p = to_t(&coef_t, DEGREE);
    let q = to_t(&coef_1, DEGREE - 1);
    (p, std::array::from_fn(|k| q[k]))
}

/// Binomial coefficients C(m, k), m, k <= [`DEGREE`].
const BINOMIAL: [[f64; DEGREE + 1]; DEGREE + 1] = [
    [1.0, 0.0, 0.0, 0.0, 0.0],
    [1.0, 1.0, 0.0, 0.0, 0.0],
    [1.0, 2.0, 1.0, 0.0, 0.0],
    [1.0, 3.0, 3.0, 1.0, 0.0],
    [1.0, 4.0, 6.0, 4.0, 1.0],
];

impl AlbedoIrradiance for AlbedoExpansion {
    fn ratio(&self, n_gcrf: &Vector3<f64>, cos_fov: f64) -> f64 {
        self.evaluate(n_gcrf, cos_fov, false).0
    }

    fn ratio_and_vector(&self, n_gcrf: &Vector3<f64>, cos_fov: f64) -> (f64, Vector3<f64>) {
        self.evaluate(n_gcrf, cos_fov, true)
    }

    /// Four normals per pass ([`AlbedoExpansion::evaluate4`]); the last pass repeats its
    /// final normal in the unused lanes.
    fn ratios_and_vectors(
        &self,
        normals_gcrf: &[Vector3<f64>],
        cos_fov: &[f64],
        out: &mut [(f64, Vector3<f64>)],
    ) {
        let count = normals_gcrf.len().min(cos_fov.len()).min(out.len());
        if self.moments[0] == 0.0 {
            out[..count].fill((0.0, Vector3::zeros()));
            return;
        }
        for start in (0..count).step_by(4) {
            let lane = |l: usize| (start + l).min(count - 1);
            let n: [[f64; 4]; 3] =
                std::array::from_fn(|a| std::array::from_fn(|l| normals_gcrf[lane(l)][a]));
            let gate = f64x4::new(std::array::from_fn(|l| cos_fov[lane(l)]));
            let (ratio, vector) = self.evaluate4(&n, gate);
            let (ratio, vector) = (ratio.to_array(), vector.map(|v| v.to_array()));
            for (l, slot) in out[start..count.min(start + 4)].iter_mut().enumerate() {
                *slot = (
                    ratio[l],
                    Vector3::new(vector[0][l], vector[1][l], vector[2][l]),
                );
            }
        }
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
        // With the gate at the interval start the kernels are t and 1 themselves: exact fit.
        let (p, q) = fit_on_interval(0.2, 0.9, 0.2);
        for t in [0.2f64, 0.5, 0.9] {
            let poly = |c: &[f64]| -> f64 {
                c.iter()
                    .enumerate()
                    .map(|(k, ck)| ck * t.powi(k as i32))
                    .sum()
            };
            assert!((poly(&p) - t).abs() < 1e-12);
            assert!((poly(&q) - 1.0).abs() < 1e-12);
        }
    }

    /// The evaluation as first written (runtime `raised`, multinomials applied per sensor,
    /// one fit per kernel, `powi` powers): the reference for the faster form.
    mod reference {
        use super::super::*;

        pub fn t_moments(
            e: &AlbedoExpansion,
            n: &Vector3<f64>,
        ) -> ([f64; DEGREE + 1], [Vector3<f64>; DEGREE]) {
            let (px, py, pz) = (powers(n.x), powers(n.y), powers(n.z));
            let mut s = [0.0; DEGREE + 1];
            let mut v = [Vector3::zeros(); DEGREE];
            for (t, &(a, b, c, multi)) in TERMS.iter().enumerate() {
                let w = multi * px[a] * py[b] * pz[c];
                s[a + b + c] += w * e.moments[t];
                if t < N_LOWER {
                    let raised = Vector3::new(
                        e.moments[raised(t, 0)],
                        e.moments[raised(t, 1)],
                        e.moments[raised(t, 2)],
                    );
                    v[a + b + c] += w * raised;
                }
            }
            (s, v)
        }

        pub fn fit(
            lo: f64,
            hi: f64,
            gate: f64,
            f: impl Fn(f64) -> f64,
            deg: usize,
        ) -> [f64; DEGREE + 1] {
            let beta = 2.0 / (hi - lo);
            let alpha = -(hi + lo) / (hi - lo);
            let s_gate = alpha + beta * gate;
            let half = 0.5 * (1.0 - s_gate);
            let mut coef = [0.0; DEGREE + 1];
            for (x, w) in GAUSS_X.iter().zip(GAUSS_W) {
                let s = s_gate + half * (x + 1.0);
                let t = (s - alpha) / beta;
                let pj = legendre_dividing(s);
                for j in 0..=deg {
                    coef[j] += w * half * f(t) * pj[j];
                }
            }
            for (j, cj) in coef.iter_mut().enumerate() {
                *cj *= (2 * j + 1) as f64 / 2.0;
            }
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
    }

    #[test]
    fn fast_evaluation_matches_the_first_form() {
        // Synthetic moments of 200 cells in a cap around nadir (z), weights ~1e-4 as the
        // TOMS view's; normals over the sphere, gates 0 and cos 60 deg.
        let mut e = AlbedoExpansion::default();
        let mut moments = [0.0; N_MOMENTS];
        for i in 0..200 {
            let (th, ph) = (0.6 * (i as f64 / 200.0).sqrt(), 2.399_963 * i as f64);
            let u = Vector3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
            let c = 1e-4 * (1.0 + 0.5 * (3.0 * ph).sin());
            let (px, py, pz) = (powers(u.x), powers(u.y), powers(u.z));
            for (m, &(a, b, d, _)) in moments.iter_mut().zip(TERMS.iter()) {
                *m += c * px[a] * py[b] * pz[d];
            }
        }
        e.moments = moments;
        for (t, &(_, _, _, multi)) in TERMS.iter().enumerate() {
            e.scaled[t] = multi * moments[t];
            if t < N_LOWER {
                for axis in 0..3 {
                    e.scaled_raised[t][axis] = multi * moments[RAISED[t][axis]];
                }
            }
        }
        e.sin_rho = 0.6f64.sin();
        e.cos_rho = (1.0 - e.sin_rho * e.sin_rho).sqrt();
        let mut worst: f64 = 0.0;
        for i in 0..500 {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / 500.0;
            let r = (1.0 - z * z).sqrt();
            let n = Vector3::new(r * (2.4 * i as f64).cos(), r * (2.4 * i as f64).sin(), z);
            let (lo, hi) = cone_range(&n, &e.nadir_ecef, e.sin_rho);
            // The cached form is the same operations up to the dot product's grouping.
            let fast = e.cone_range(&[n.x, n.y, n.z], n.norm());
            assert!((fast.0 - lo).abs() < 1e-15 && (fast.1 - hi).abs() < 1e-15);
            for gate in [0.0, 0.5] {
                if lo >= gate || hi <= gate {
                    continue;
                }
                let (s, v) = e.t_moments(&[n.x, n.y, n.z], true);
                let v = v.map(Vector3::from);
                let (s0, v0) = reference::t_moments(&e, &n);
                let (p, q) = fit_on_interval(lo, hi, gate);
                let p0 = reference::fit(lo, hi, gate, |t| t, DEGREE);
                let q0 = reference::fit(lo, hi, gate, |_| 1.0, DEGREE - 1);
                let ratio: f64 = p.iter().zip(&s).map(|(a, b)| a * b).sum();
                let ratio0: f64 = p0.iter().zip(&s0).map(|(a, b)| a * b).sum();
                let vector: Vector3<f64> = q.iter().zip(&v).map(|(a, b)| b * *a).sum();
                let vector0: Vector3<f64> = q0.iter().zip(&v0).map(|(a, b)| *a * b).sum();
                // Relative to the full-disc sums (the scale of every result).
                worst = worst.max((ratio - ratio0).abs() / e.moments[0]);
                worst = worst.max((vector - vector0).norm() / e.moments[0]);
            }
        }
        // Same sums in another order and grouping: rounding only, a few hundred ulps of the
        // full-disc sum at most (the fit's monomial coefficients reach ~1e3 and cancel).
        eprintln!("fast vs first form: worst {worst:e} of the full-disc sum");
        assert!(worst < 1e-12, "worst {worst:e}");
    }
}
