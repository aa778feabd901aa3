//! The Sun vector: weighted least squares over the lit photodiodes with the albedo
//! subtracted at each pass.

use crate::Real;
use crate::albedo::{EARTH_RADIUS_KM, ReflectivityGrid, Sight, Surface, albedo_into};
use crate::calibration::{Calibration, Checked, MAX_PHOTODIODES};
use crate::linalg::{M3, Sym3, V3, dot, is_finite, mul, norm, scale};

/// The Earth as the flight software sees it, for the albedo compensation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EarthInput<'a, T> {
    /// Unit vector from the spacecraft toward the Earth's centre, body frame (from the
    /// spacecraft's own attitude and position solution).
    pub earth_body: [T; 3],
    /// Distance of the spacecraft from the Earth's centre, km.
    pub orbit_radius_km: T,
    /// Rotation from the body frame to the Earth-fixed frame (`v_E = M v_B`), needed to place
    /// a reflectivity grid; without it (or without a grid) the Earth is uniform
    /// ([`Options::uniform_reflectivity`]).
    pub ecef_from_body: Option<[[T; 3]; 3]>,
    /// The reflectivity grid, Earth-fixed.
    pub grid: Option<&'a ReflectivityGrid<'a>>,
}

/// Settings of [`estimate_sun`]; [`Options::default`] holds the values the validation used.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct Options<T> {
    /// A photodiode is lit when its output, less the dark offset and the predicted albedo,
    /// exceeds this many of its sigmas. Default 3.
    pub lit_sigmas: T,
    /// Smallest acceptable singular value of the used photodiodes' unit normals stacked
    /// (`sqrt(lambda_min(sum n n^T))`). Default 0.1, as `pdcal_photodiode::sun_vector`.
    pub min_singular_value: T,
    /// Passes of solve-then-recompute-the-albedo. Default 4.
    pub albedo_passes: u32,
    /// The albedo model's own error, as a fraction of the predicted albedo (the grid's
    /// resolution, the month of the map against the day of the pass, clouds). Default 0.3.
    pub albedo_relative_sigma: T,
    /// Reflectivity of a uniform Earth (no grid or no rotation). Default 0.3, the Earth's
    /// mean Bond albedo.
    pub uniform_reflectivity: T,
    /// Without the Earth: the largest albedo irradiance over the Sun's any photodiode could
    /// receive; only outputs above it (in the same units as `n . s`) are used. Default
    /// 0.885, a white Earth filling the view from 400 km altitude, `(R / r)^2`.
    pub albedo_bound: T,
    /// `(1 AU / r_sun)^2` at the sample. Default 1.
    pub sun_distance_factor: T,
    /// Largest departure of the Sun vector's magnitude from 1 accepted (besides 5 of its
    /// sigmas) before the estimate is flagged dim or contradictory. Default 0.25.
    pub magnitude_tolerance: T,
    /// Largest normalised residual sum of squares, as a normal deviate by the
    /// Wilson-Hilferty transform, before the outputs are flagged as contradicting each
    /// other. Default 5.
    pub max_misfit_sigmas: T,
}

impl<T: Real> Default for Options<T> {
    fn default() -> Self {
        Options {
            lit_sigmas: T::of(3.0),
            min_singular_value: T::of(0.1),
            albedo_passes: 4,
            albedo_relative_sigma: T::of(0.3),
            uniform_reflectivity: T::of(0.3),
            albedo_bound: T::of(0.885),
            sun_distance_factor: T::one(),
            magnitude_tolerance: T::of(0.25),
            max_misfit_sigmas: T::of(5.0),
        }
    }
}

impl<T: Real> Options<T> {
    fn usable(&self) -> bool {
        let finite = [
            self.lit_sigmas,
            self.min_singular_value,
            self.albedo_relative_sigma,
            self.uniform_reflectivity,
            self.albedo_bound,
            self.sun_distance_factor,
            self.magnitude_tolerance,
            self.max_misfit_sigmas,
        ]
        .iter()
        .all(|v| v.is_finite() && *v >= T::zero());
        finite && self.sun_distance_factor > T::zero() && self.albedo_passes <= 16
    }
}

/// Whether an estimate is to be used, and if not, why.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Validity {
    /// A Sun direction the outputs agree on.
    Valid = 0,
    /// No photodiode lit: eclipse (or every photodiode covered).
    Eclipse = 1,
    /// One or two photodiodes lit: the direction is not determined.
    TooFewLit = 2,
    /// Three or more lit but their normals nearly coplanar.
    DegenerateGeometry = 3,
    /// The outputs contradict each other (residuals far beyond the noise, or more light
    /// than the full Sun).
    Contradictory = 4,
    /// Less light than the full Sun by more than the tolerance: penumbra, a shadow or a
    /// scale far off. The direction is returned but not to be trusted.
    Dim = 5,
    /// An input is not usable (a count beyond the buffer, a non-finite Earth direction,
    /// options out of range). Nothing is estimated.
    InvalidInput = 6,
}

/// Which albedo model the estimate subtracted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum AlbedoUse {
    /// No Earth given: only outputs above [`Options::albedo_bound`] were used.
    Bound = 0,
    /// A uniform Earth.
    Uniform = 1,
    /// The reflectivity grid.
    Grid = 2,
}

/// The result of [`estimate_sun`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SunEstimate<T> {
    /// Unit Sun direction, body frame (zero when nothing was estimated).
    pub sun_body: [T; 3],
    /// Magnitude of the least-squares Sun vector before normalising (1 for a perfect model
    /// in full Sun).
    pub magnitude: T,
    /// Covariance of the unit direction (rad^2, in the plane normal to it).
    pub covariance: [[T; 3]; 3],
    /// 1-sigma cone: the root of the covariance's trace, rad.
    pub cone_sigma_rad: T,
    /// Bit `i` set when photodiode `i` was used.
    pub used_mask: u64,
    /// How many photodiodes were used.
    pub n_used: u32,
    /// Normalised residual sum of squares of the used photodiodes.
    pub misfit: T,
    /// Whether to use it.
    pub validity: Validity,
    /// Which albedo model was subtracted.
    pub albedo: AlbedoUse,
}

impl<T: Real> SunEstimate<T> {
    fn nothing(validity: Validity, albedo: AlbedoUse) -> Self {
        SunEstimate {
            sun_body: [T::zero(); 3],
            magnitude: T::zero(),
            covariance: [[T::zero(); 3]; 3],
            cone_sigma_rad: T::zero(),
            used_mask: 0,
            n_used: 0,
            misfit: T::zero(),
            validity,
            albedo,
        }
    }
}

/// The Sun direction in the body frame from the photodiode outputs `outputs_v` (one per
/// photodiode of `calibration`, V), with the albedo compensated when `earth` is given.
/// Total: every input gives an estimate or a [`Validity`] saying why not.
pub fn estimate_sun<T: Real, const N: usize>(
    outputs_v: &[T; N],
    calibration: &Calibration<T, N>,
    earth: Option<&EarthInput<'_, T>>,
    options: &Options<T>,
) -> SunEstimate<T> {
    let albedo = match earth {
        None => AlbedoUse::Bound,
        Some(e) if e.grid.is_some() && e.ecef_from_body.is_some() => AlbedoUse::Grid,
        Some(_) => AlbedoUse::Uniform,
    };
    let Some(photodiodes) = calibration.in_use() else {
        return SunEstimate::nothing(Validity::InvalidInput, albedo);
    };
    if !options.usable() {
        return SunEstimate::nothing(Validity::InvalidInput, albedo);
    }
    let sight = match earth {
        None => None,
        Some(e) => match sight(e, options.uniform_reflectivity) {
            Some(s) => Some(s),
            None => return SunEstimate::nothing(Validity::InvalidInput, albedo),
        },
    };
    let mut problem = Problem::new(options);
    for (k, (pd, &out)) in photodiodes.iter().zip(outputs_v).enumerate() {
        problem.set(k, pd, out);
    }
    problem.solve(sight.as_ref(), albedo)
}

/// The checked surface and geometry of `earth`, when usable: a unit (up to a factor 2)
/// finite Earth direction, an orbit radius above the Earth's, and a rotation (if given)
/// orthonormal to 1e-3.
pub(crate) fn sight<'a, T: Real>(earth: &EarthInput<'a, T>, uniform: T) -> Option<Sight<'a, T>> {
    let length = norm(earth.earth_body);
    let radius = earth.orbit_radius_km;
    let usable = is_finite(earth.earth_body)
        && length > T::of(0.5)
        && length < T::of(2.0)
        && radius.is_finite()
        && radius > T::of(EARTH_RADIUS_KM)
        && uniform.is_finite()
        && uniform >= T::zero()
        && uniform <= T::one();
    if !usable {
        return None;
    }
    let earth_body = scale(earth.earth_body, length.recip());
    match (earth.grid, earth.ecef_from_body) {
        (Some(grid), Some(rotation)) => {
            if !orthonormal(&rotation) {
                return None;
            }
            Some(Sight {
                up_frame: scale(mul(&rotation, earth_body), -T::one()),
                radius_km: radius,
                body_from_frame: transpose(&rotation),
                surface: Surface::Grid(grid),
            })
        }
        _ => Some(Sight::uniform(earth_body, radius, uniform)),
    }
}

fn transpose<T: Real>(m: &M3<T>) -> M3<T> {
    let [[a, b, c], [d, e, f], [g, h, k]] = *m;
    [[a, d, g], [b, e, h], [c, f, k]]
}

fn orthonormal<T: Real>(m: &M3<T>) -> bool {
    let basis = [
        [T::one(), T::zero(), T::zero()],
        [T::zero(), T::one(), T::zero()],
        [T::zero(), T::zero(), T::one()],
    ];
    let tolerance = T::of(1e-3);
    basis.iter().enumerate().all(|(i, ei)| {
        let ci = mul(m, *ei);
        basis.iter().enumerate().all(|(j, ej)| {
            let cj = mul(m, *ej);
            let want = if i == j { T::one() } else { T::zero() };
            is_finite(ci) && (dot(ci, cj) - want).abs() < tolerance
        })
    })
}

/// One photodiode's equation: its output in units of the direct Sun at normal incidence.
#[derive(Debug, Clone, Copy)]
struct Channel<T> {
    sensor: Checked<T>,
    /// `(I - b) / (C F)`.
    y: T,
    /// The output noise in the same units.
    sigma: T,
    /// Relative sigma of the scale factor.
    scale_rel_sigma: T,
    normal_sigma: T,
}

/// The per-call working set: at most [`MAX_PHOTODIODES`] channels on the stack.
struct Problem<'o, T> {
    channels: [Option<Channel<T>>; MAX_PHOTODIODES],
    albedo: [T; MAX_PHOTODIODES],
    options: &'o Options<T>,
}

/// One least-squares solution.
#[derive(Debug, Clone, Copy)]
struct Solution<T> {
    s: V3<T>,
    information: Sym3<T>,
    used: u64,
    n_used: u32,
    misfit: T,
    geometry: T,
}

impl<'o, T: Real> Problem<'o, T> {
    fn new(options: &'o Options<T>) -> Self {
        Problem {
            channels: [None; MAX_PHOTODIODES],
            albedo: [T::zero(); MAX_PHOTODIODES],
            options,
        }
    }

    fn set(&mut self, k: usize, pd: &crate::Photodiode<T>, output_v: T) {
        let Some(slot) = self.channels.get_mut(k) else {
            return;
        };
        *slot = pd
            .checked()
            .filter(|_| output_v.is_finite())
            .and_then(|sensor| {
                let unit = pd.scale_v * self.options.sun_distance_factor;
                let channel = Channel {
                    sensor,
                    y: (output_v - pd.dark_v) / unit,
                    sigma: pd.noise_v / unit,
                    scale_rel_sigma: pd.scale_sigma_v / pd.scale_v,
                    normal_sigma: pd.normal_sigma_rad,
                };
                (channel.y.is_finite() && channel.sigma.is_finite()).then_some(channel)
            });
    }

    fn sensors(&self) -> [Option<Checked<T>>; MAX_PHOTODIODES] {
        self.channels.map(|c| c.map(|c| c.sensor))
    }

    fn solve(&mut self, sight: Option<&Sight<'_, T>>, albedo: AlbedoUse) -> SunEstimate<T> {
        let bound = if sight.is_some() {
            T::zero()
        } else {
            self.options.albedo_bound
        };
        let mut solution = self.least_squares(None, bound);
        if let Some(sight) = sight {
            let sensors = self.sensors();
            let mut previous: Option<V3<T>> = None;
            for _ in 0..self.options.albedo_passes {
                let Ok(current) = solution else { break };
                let direction = scale(current.s, norm(current.s).recip());
                if !is_finite(direction) || previous.is_some_and(|p| settled(p, direction)) {
                    break;
                }
                albedo_into(sight, direction, &sensors, &mut self.albedo);
                solution = self.least_squares(Some(direction), T::zero());
                previous = Some(direction);
            }
        }
        match solution {
            Ok(s) => self.finish(&s, albedo),
            Err(validity) => SunEstimate::nothing(validity, albedo),
        }
    }

    /// Weighted least squares over the lit photodiodes, dropping those the solution puts
    /// outside their field of view (no direct light can reach them) and solving again.
    fn least_squares(&self, prior: Option<V3<T>>, bound: T) -> Result<Solution<T>, Validity> {
        let mut excluded = 0u64;
        let mut direction = prior;
        let mut last = Err(Validity::Eclipse);
        for _ in 0..4 {
            let solution = self.solve_once(direction, bound, excluded)?;
            let s_hat = scale(solution.s, norm(solution.s).recip());
            let outside = self.outside_view(s_hat, solution.used);
            last = Ok(solution);
            if outside == 0 || !is_finite(s_hat) {
                break;
            }
            excluded |= outside;
            direction = Some(s_hat);
        }
        last
    }

    /// Photodiodes in `used` whose field of view does not hold `s_hat`.
    fn outside_view(&self, s_hat: V3<T>, used: u64) -> u64 {
        let mut mask = 0u64;
        for (k, channel) in self.channels.iter().enumerate() {
            let Some(c) = channel else { continue };
            let bit = 1u64.checked_shl(k as u32).unwrap_or(0);
            let cos = dot(c.sensor.normal, s_hat);
            if used & bit != 0 && !(cos > T::zero() && cos >= c.sensor.cos_fov) {
                mask |= bit;
            }
        }
        mask
    }

    fn variance(&self, c: &Channel<T>, albedo: T, y_direct: T, cos: Option<T>) -> T {
        let albedo_sigma = self.options.albedo_relative_sigma * albedo;
        let scale_sigma = c.scale_rel_sigma * y_direct;
        let normal = cos.map_or(T::zero(), |cos| {
            let sin2 = (T::one() - cos * cos).max(T::zero());
            c.normal_sigma * c.normal_sigma * sin2
        });
        c.sigma * c.sigma + albedo_sigma * albedo_sigma + scale_sigma * scale_sigma + normal
    }

    fn solve_once(
        &self,
        direction: Option<V3<T>>,
        bound: T,
        excluded: u64,
    ) -> Result<Solution<T>, Validity> {
        let mut information = Sym3::default();
        let mut geometry = Sym3::default();
        let mut rhs = [T::zero(); 3];
        let mut used = 0u64;
        let mut n_used = 0u32;
        let mut any_lit = false;
        for (k, (channel, &albedo)) in self.channels.iter().zip(&self.albedo).enumerate() {
            let Some(c) = channel else { continue };
            let y = c.y - albedo;
            let cos = direction.map(|d| dot(c.sensor.normal, d));
            let variance = self.variance(c, albedo, y, cos);
            let lit = y > self.options.lit_sigmas * variance.sqrt() + bound;
            any_lit |= lit;
            let bit = 1u64.checked_shl(k as u32).unwrap_or(0);
            if !lit || excluded & bit != 0 || !(variance > T::zero()) {
                continue;
            }
            let w = variance.recip();
            information.add_outer(c.sensor.normal, w);
            geometry.add_outer(c.sensor.normal, T::one());
            rhs = [
                rhs[0] + w * y * c.sensor.normal[0],
                rhs[1] + w * y * c.sensor.normal[1],
                rhs[2] + w * y * c.sensor.normal[2],
            ];
            used |= bit;
            n_used = n_used.saturating_add(1);
        }
        if !any_lit {
            return Err(Validity::Eclipse);
        }
        if n_used < 3 {
            return Err(Validity::TooFewLit);
        }
        let floor = self.options.min_singular_value * self.options.min_singular_value;
        let smallest = geometry.min_eigenvalue();
        if !(smallest >= floor) {
            return Err(Validity::DegenerateGeometry);
        }
        let covariance = information.inverse().ok_or(Validity::DegenerateGeometry)?;
        let s = mul(&covariance.full(), rhs);
        let misfit = self.misfit(s, used, direction);
        Ok(Solution {
            s,
            information,
            used,
            n_used,
            misfit,
            geometry: smallest,
        })
    }

    fn misfit(&self, s: V3<T>, used: u64, direction: Option<V3<T>>) -> T {
        let mut sum = T::zero();
        for (k, (channel, &albedo)) in self.channels.iter().zip(&self.albedo).enumerate() {
            let Some(c) = channel else { continue };
            let bit = 1u64.checked_shl(k as u32).unwrap_or(0);
            if used & bit == 0 {
                continue;
            }
            let y = c.y - albedo;
            let cos = direction.map(|d| dot(c.sensor.normal, d));
            let r = y - dot(c.sensor.normal, s);
            sum = sum + r * r / self.variance(c, albedo, y, cos);
        }
        sum
    }

    fn finish(&self, solution: &Solution<T>, albedo: AlbedoUse) -> SunEstimate<T> {
        let magnitude = norm(solution.s);
        let s_hat = scale(solution.s, magnitude.recip());
        let Some(covariance) = solution.information.inverse() else {
            return SunEstimate::nothing(Validity::DegenerateGeometry, albedo);
        };
        let unit_cov = project(&covariance.full(), s_hat, magnitude);
        let [[xx, _, _], [_, yy, _], [_, _, zz]] = unit_cov;
        let magnitude_sigma = dot(s_hat, mul(&covariance.full(), s_hat))
            .max(T::zero())
            .sqrt();
        let validity = self.judge(solution, magnitude, magnitude_sigma);
        SunEstimate {
            sun_body: s_hat,
            magnitude,
            covariance: unit_cov,
            cone_sigma_rad: (xx + yy + zz).max(T::zero()).sqrt(),
            used_mask: solution.used,
            n_used: solution.n_used,
            misfit: solution.misfit,
            validity,
            albedo,
        }
    }

    fn judge(&self, solution: &Solution<T>, magnitude: T, magnitude_sigma: T) -> Validity {
        if !is_finite(solution.s) || !(magnitude > T::zero()) || !(solution.geometry > T::zero()) {
            return Validity::DegenerateGeometry;
        }
        let dof = solution.n_used.saturating_sub(3);
        if dof > 0 && wilson_hilferty(solution.misfit, dof) > self.options.max_misfit_sigmas {
            return Validity::Contradictory;
        }
        let allowed = self
            .options
            .magnitude_tolerance
            .max(T::of(5.0) * magnitude_sigma);
        if magnitude > T::one() + allowed {
            Validity::Contradictory
        } else if magnitude < T::one() - allowed {
            Validity::Dim
        } else {
            Validity::Valid
        }
    }
}

/// Whether two unit directions agree to 2e-6 rad (0.0001 deg): another albedo pass would
/// move the estimate by less than that again.
fn settled<T: Real>(a: V3<T>, b: V3<T>) -> bool {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    dot(d, d) < T::of(4e-12)
}

/// `(I - s s^T) P (I - s s^T) / m^2`: the covariance of the normalised vector.
fn project<T: Real>(p: &M3<T>, s: V3<T>, m: T) -> M3<T> {
    let columns = [
        [T::one(), T::zero(), T::zero()],
        [T::zero(), T::one(), T::zero()],
        [T::zero(), T::zero(), T::one()],
    ];
    let reject = |v: V3<T>| {
        let k = dot(v, s);
        [v[0] - k * s[0], v[1] - k * s[1], v[2] - k * s[2]]
    };
    let inv_m2 = (m * m).recip();
    // Q = (I - ss^T); Q P Q: columns of P Q are P (Q e_j); then Q applied to each.
    let pq: [V3<T>; 3] = columns.map(|e| reject(mul(p, reject(e))));
    // pq[j] is column j of Q P Q (symmetric), so it is also row j.
    pq.map(|row| scale(row, inv_m2))
}

/// The normal deviate of a chi-square value `x` with `dof` degrees of freedom
/// (Wilson-Hilferty's cube-root transform).
fn wilson_hilferty<T: Real>(x: T, dof: u32) -> T {
    let k = T::of(f64::from(dof));
    let a = T::of(2.0) / (T::of(9.0) * k);
    ((x / k).max(T::zero()).cbrt() - (T::one() - a)) / a.sqrt()
}
