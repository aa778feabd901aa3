//! Shared test helpers: seeded random states, a simple albedo provider, and central finite
//! differences with error statistics.
#![allow(dead_code)]

use nalgebra::{Matrix3, Rotation3, Vector3};
use pdcal_attitude::Quat;
use pdcal_photodiode::{AlbedoIrradiance, Photodiode, Scene, Sensitivity};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;

/// Central-difference step. Truncation error ~ h^2 |f'''|/6 ~ 1e-10 for outputs of a few V
/// with unit-scale curvature; rounding error ~ eps |f| / h ~ 2e-16 * 8 / 1e-5 ~ 2e-10. Both are
/// far below the 1e-6 relative tolerance for derivatives >= TINY.
pub const H: f64 = 1e-5;
/// Relative tolerance of the acceptance criterion.
pub const REL_TOL: f64 = 1e-6;
/// Below this magnitude (V per unit) a derivative counts as "tiny": it is then checked in
/// absolute terms against ABS_TOL instead (1e-6 relative of TINY).
pub const TINY: f64 = 1e-3;
/// Absolute tolerance for tiny derivatives, 5x the rounding error estimate above.
pub const ABS_TOL: f64 = 1e-9;
/// Distance in cosine from a gate (n^T s = 0, FOV edge, albedo cell gate) that a state must
/// keep: FD perturbations move cosines by <= ~2 H, so a 0.02 margin keeps both sides of the
/// central difference on the same side of every kink.
pub const KINK_MARGIN: f64 = 0.02;
/// Number of accepted random states per partial (acceptance asks for >= 100).
pub const STATES: usize = 120;

pub fn rng(seed: u64) -> StdRng {
    StdRng::seed_from_u64(seed)
}

pub fn random_unit(rng: &mut StdRng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(
            rng.sample::<f64, _>(StandardNormal),
            rng.sample::<f64, _>(StandardNormal),
            rng.sample::<f64, _>(StandardNormal),
        );
        if let Some(u) = v.try_normalize(1e-6) {
            return u;
        }
    }
}

pub fn random_attitude(rng: &mut StdRng) -> Matrix3<f64> {
    let q = Quat::new_normalized(
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
        rng.sample(StandardNormal),
    )
    .expect("non-zero random quaternion");
    q.attitude_matrix()
}

/// Albedo stand-in: a handful of weighted directions `u_j` (GCRF) with weights `c_j`; the
/// ratio is `sum c_j n.u_j` over `n.u_j >= cos_fov` and `n.u_j > 0`, as the trait specifies.
#[derive(Debug, Clone)]
pub struct Directions(pub Vec<(f64, Vector3<f64>)>);

impl Directions {
    pub fn random(rng: &mut StdRng, count: usize) -> Self {
        Directions(
            (0..count)
                .map(|_| (rng.random_range(0.005..0.05), random_unit(rng)))
                .collect(),
        )
    }

    fn gated(&self, n: &Vector3<f64>, cos_fov: f64) -> impl Iterator<Item = &(f64, Vector3<f64>)> {
        self.0.iter().filter(move |(_, u)| {
            let d = n.dot(u);
            d > 0.0 && d >= cos_fov
        })
    }

    /// Whether every direction is at least `margin` (in cosine) away from both gates.
    pub fn away_from_gates(&self, n_gcrf: &Vector3<f64>, cos_fov: f64, margin: f64) -> bool {
        self.0.iter().all(|(_, u)| {
            let d = n_gcrf.dot(u);
            d.abs() > margin && (d - cos_fov).abs() > margin
        })
    }
}

impl AlbedoIrradiance for Directions {
    fn ratio(&self, n_gcrf: &Vector3<f64>, cos_fov: f64) -> f64 {
        self.gated(n_gcrf, cos_fov)
            .map(|(c, u)| c * n_gcrf.dot(u))
            .sum()
    }

    fn ratio_and_vector(&self, n_gcrf: &Vector3<f64>, cos_fov: f64) -> (f64, Vector3<f64>) {
        self.gated(n_gcrf, cos_fov)
            .fold((0.0, Vector3::zeros()), |(r, v), (c, u)| {
                (r + c * n_gcrf.dot(u), v + u * *c)
            })
    }
}

/// One random sample: a photodiode and a scene, with the Sun in GCRF kept for perturbations.
#[derive(Debug, Clone)]
pub struct State {
    pub pd: Photodiode,
    pub attitude: Matrix3<f64>,
    pub sun_gcrf: Vector3<f64>,
    pub sun_fraction: f64,
    /// `(1 AU / r_sun)^2`, drawn over the year's range.
    pub sun_distance_factor: f64,
    pub rate_body_rad_s: Vector3<f64>,
    pub t_s: f64,
    pub albedo: Directions,
}

impl State {
    pub fn random(rng: &mut StdRng) -> Self {
        let fov = rng
            .random_bool(0.5)
            .then(|| rng.random_range(50f64..85.0).to_radians());
        let pd = Photodiode::from_az_el_rad(
            rng.random_range(3.3..4.0),
            rng.random_range(-3.1..3.1),
            rng.random_range(-1.4..1.4),
            0.015,
        )
        .with_fov_half_angle_rad(fov);
        State {
            pd,
            attitude: random_attitude(rng),
            sun_gcrf: random_unit(rng),
            sun_fraction: rng.random_range(0.0..1.0),
            sun_distance_factor: rng.random_range(0.96..1.04),
            rate_body_rad_s: random_unit(rng) * rng.random_range(0.01..0.1),
            t_s: rng.random_range(0.0..7200.0),
            albedo: Directions::random(rng, 8),
        }
    }

    pub fn scene(&self) -> Scene<'_> {
        Scene::new(self.attitude, &self.sun_gcrf)
            .expect("unit sun")
            .with_sun_fraction(self.sun_fraction)
            .with_sun_distance_factor(self.sun_distance_factor)
            .with_rate(self.rate_body_rad_s)
            .with_time(self.t_s)
            .with_albedo(&self.albedo)
    }

    pub fn cos_sun(&self) -> f64 {
        self.pd.n_body.dot(&(self.attitude * self.sun_gcrf))
    }

    /// Away from the direct-Sun gates (n^T s = 0 and the FOV edge) and the albedo cell gates.
    pub fn away_from_kinks(&self) -> bool {
        let c = self.cos_sun();
        let cos_fov = self.pd.cos_fov();
        let n_gcrf = self.attitude.transpose() * self.pd.n_body;
        c.abs() > KINK_MARGIN
            && (c - cos_fov).abs() > KINK_MARGIN
            && self.albedo.away_from_gates(&n_gcrf, cos_fov, KINK_MARGIN)
    }

    /// The same state with the multiplicative attitude error `a`: `A(a) = exp(-[a x]) A`.
    pub fn with_attitude_error(&self, a: &Vector3<f64>) -> State {
        let rotation = Rotation3::new(-a);
        State {
            attitude: rotation.matrix() * self.attitude,
            ..self.clone()
        }
    }
}

/// Largest relative error seen over non-tiny derivatives, and counts.
#[derive(Debug, Default)]
pub struct Stats {
    pub max_rel: f64,
    pub max_abs_tiny: f64,
    pub checked: usize,
    pub tiny: usize,
}

impl Stats {
    pub fn check(&mut self, what: &str, analytic: f64, numeric: f64) {
        let err = (analytic - numeric).abs();
        if analytic.abs() >= TINY {
            let rel = err / analytic.abs();
            self.max_rel = self.max_rel.max(rel);
            self.checked += 1;
            assert!(
                rel < REL_TOL,
                "{what}: analytic {analytic:e}, FD {numeric:e}, rel {rel:e}"
            );
        } else {
            self.max_abs_tiny = self.max_abs_tiny.max(err);
            self.tiny += 1;
            assert!(
                err < ABS_TOL,
                "{what}: tiny analytic {analytic:e}, FD {numeric:e}, abs {err:e}"
            );
        }
    }

    pub fn report(&self, label: &str) {
        eprintln!(
            "{label}: {} non-tiny partials, max rel err {:.2e}; {} tiny, max abs err {:.2e}",
            self.checked, self.max_rel, self.tiny, self.max_abs_tiny
        );
    }
}

/// Central difference of `f` along a scalar perturbation.
pub fn central(f: impl Fn(f64) -> f64, h: f64) -> f64 {
    (f(h) - f(-h)) / (2.0 * h)
}

/// Checks a term-like sensitivity against finite differences of `value` in the attitude
/// error, the scale factor and the normal (as a free 3-vector).
pub fn check_sensitivity(
    state: &State,
    sens: &Sensitivity,
    value: &dyn Fn(&State) -> f64,
    stats: &mut Stats,
    label: &str,
) {
    let v0 = value(state);
    assert!(
        (sens.value_v - v0).abs() <= 1e-14 * v0.abs().max(1.0),
        "{label}: partials value {} vs value {v0}",
        sens.value_v
    );
    for k in 0..3 {
        let e = Vector3::ith(k, 1.0);
        let fd = central(|h| value(&state.with_attitude_error(&(e * h))), H);
        stats.check(&format!("{label} d/da[{k}]"), sens.d_attitude[k], fd);
        let fd = central(
            |h| {
                let mut s = state.clone();
                s.pd.n_body += e * h;
                value(&s)
            },
            H,
        );
        stats.check(&format!("{label} d/dn[{k}]"), sens.d_normal[k], fd);
    }
    let fd = central(
        |h| {
            let mut s = state.clone();
            s.pd.scale_v += h;
            value(&s)
        },
        H,
    );
    stats.check(&format!("{label} d/dC"), sens.d_scale, fd);
}

/// Draws random states until `count` satisfy `accept`, calling `body` on each.
pub fn for_states(
    seed: u64,
    count: usize,
    accept: impl Fn(&State) -> bool,
    mut body: impl FnMut(&State),
) {
    let mut rng = rng(seed);
    let mut accepted = 0;
    let mut tries = 0;
    while accepted < count {
        tries += 1;
        assert!(tries < 200 * count, "too few acceptable random states");
        let state = State::random(&mut rng);
        if accept(&state) {
            body(&state);
            accepted += 1;
        }
    }
}
