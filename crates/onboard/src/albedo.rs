//! Earth albedo on each photodiode (paper Eq. 13, the cell model pdcal's `albedo` crate
//! implements after Basilisk), over a compact reflectivity grid or a uniform Earth.

use crate::Real;
use crate::calibration::Checked;
use crate::linalg::{M3, V3, dot, mul, mul_t, norm, scale, sub};

/// Radius of the spherical Earth the cells lie on, km (the authalic radius, as in
/// `pdcal-albedo`).
pub const EARTH_RADIUS_KM: f64 = 6371.0072;

/// Largest grid dimensions (0.1 deg cells).
const MAX_ROWS: usize = 1800;
const MAX_COLUMNS: usize = 3600;

/// A reflectivity grid, one byte a cell (`reflectivity = byte / 255`), `n_lat` rows from the
/// south pole (row 0 centred at `-90 + dlat/2` deg) by `n_lon` columns from longitude -180
/// deg (column 0 centred at `-180 + dlon/2`), Earth-fixed. Its memory is `n_lat * n_lon`
/// bytes: 648 at 10 deg, 2 592 at 5 deg, 41 472 at 1.25 x 1.25 deg.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(C)]
pub struct ReflectivityGrid<'a> {
    n_lat: usize,
    n_lon: usize,
    cells: &'a [u8],
}

impl<'a> ReflectivityGrid<'a> {
    /// A grid of `n_lat` x `n_lon` cells, or `None` when `cells` does not hold exactly that
    /// many or a dimension is 0 or beyond 0.1 deg cells.
    pub const fn new(n_lat: usize, n_lon: usize, cells: &'a [u8]) -> Option<Self> {
        let Some(n) = n_lat.checked_mul(n_lon) else {
            return None;
        };
        if n_lat == 0 || n_lon == 0 || n_lat > MAX_ROWS || n_lon > MAX_COLUMNS || n != cells.len() {
            return None;
        }
        Some(ReflectivityGrid {
            n_lat,
            n_lon,
            cells,
        })
    }

    /// Rows (latitude bands).
    pub const fn n_lat(&self) -> usize {
        self.n_lat
    }

    /// Columns (longitude bands).
    pub const fn n_lon(&self) -> usize {
        self.n_lon
    }

    /// The cells, row-major.
    pub const fn cells(&self) -> &'a [u8] {
        self.cells
    }

    /// The largest reflectivity of any cell.
    pub fn max_reflectivity<T: Real>(&self) -> T {
        let top = self.cells.iter().copied().max().unwrap_or(0);
        T::of(f64::from(top) / 255.0)
    }

    fn reflectivity<T: Real>(&self, row: usize, column: usize) -> T {
        let k = row
            .checked_mul(self.n_lon)
            .and_then(|k| k.checked_add(column));
        let byte = k.and_then(|k| self.cells.get(k)).copied().unwrap_or(0);
        T::of(f64::from(byte) / 255.0)
    }
}

/// Where the reflectivity comes from.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Surface<'a, T> {
    /// A grid in the Earth-fixed frame.
    Grid(&'a ReflectivityGrid<'a>),
    /// One reflectivity everywhere, integrated on a grid of this many rows and twice as many
    /// columns in a frame of the core's own.
    Uniform(T),
}

/// Rows of the frame a uniform Earth is integrated in (2 deg cells).
const UNIFORM_ROWS: usize = 90;

/// The spacecraft and its surface: the unit vector from the Earth's centre to the
/// spacecraft in the surface's frame, the orbit radius, and the rotation from that frame to
/// the body frame (`v_B = M v_F`).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sight<'a, T> {
    pub up_frame: V3<T>,
    pub radius_km: T,
    pub body_from_frame: M3<T>,
    pub surface: Surface<'a, T>,
}

impl<'a, T: Real> Sight<'a, T> {
    /// A sight of a uniform Earth of reflectivity `value` in a frame whose x axis points at
    /// the spacecraft (so the visible cap sits on the frame's equator, where its cells are
    /// regular): built from the Earth direction `earth_body` alone.
    pub fn uniform(earth_body: V3<T>, radius_km: T, value: T) -> Self {
        let x = scale(earth_body, -T::one());
        let [a, b, c] = x;
        // Any unit vector orthogonal to x.
        let helper = if a.abs() < T::of(0.9) {
            [T::one(), T::zero(), T::zero()]
        } else {
            [T::zero(), T::one(), T::zero()]
        };
        let y = sub(helper, scale(x, dot(x, helper)));
        let y = scale(y, norm(y).recip());
        let [d, e, f] = y;
        let z = [b * f - c * e, c * d - a * f, a * e - b * d];
        let [g, h, k] = z;
        Sight {
            up_frame: [T::one(), T::zero(), T::zero()],
            radius_km,
            body_from_frame: [[a, d, g], [b, e, h], [c, f, k]],
            surface: Surface::Uniform(value),
        }
    }
}

/// Albedo irradiance over the Sun's on each photodiode (`E_i` of paper Eq. 15, by the cell
/// sum of Eq. 13) for the unit Sun direction `sun_body`, into `out` (one per photodiode of
/// `sensors`, `None` entries get 0).
pub(crate) fn albedo_into<T: Real>(
    sight: &Sight<'_, T>,
    sun_body: V3<T>,
    sensors: &[Option<Checked<T>>],
    out: &mut [T],
) {
    out.iter_mut().for_each(|e| *e = T::zero());
    let sun_frame = mul_t(&sight.body_from_frame, sun_body);
    let (n_lat, n_lon) = match sight.surface {
        Surface::Grid(g) => (g.n_lat, g.n_lon),
        Surface::Uniform(_) => (UNIFORM_ROWS, UNIFORM_ROWS.saturating_mul(2)),
    };
    let cap = Cap::new(sight, n_lat, n_lon);
    for row in 0..n_lat {
        let Some(band) = cap.band(row) else { continue };
        let mut longitude = Longitude::new(&cap, band.first);
        for column in band.columns() {
            let rho = match sight.surface {
                Surface::Grid(g) => g.reflectivity(row, column),
                Surface::Uniform(v) => v,
            };
            if rho > T::zero() {
                let r_hat = [
                    band.cos_lat * longitude.cos,
                    band.cos_lat * longitude.sin,
                    band.sin_lat,
                ];
                add_cell(sight, band.area_km2, r_hat, rho, sun_frame, sensors, out);
            }
            longitude.step(&cap);
        }
    }
}

/// One cell's contribution (Basilisk's `f1 f2 dA / (pi d^2)` times the photodiode's cosine).
fn add_cell<T: Real>(
    sight: &Sight<'_, T>,
    area_km2: T,
    r_hat: V3<T>,
    rho: T,
    sun_frame: V3<T>,
    sensors: &[Option<Checked<T>>],
    out: &mut [T],
) {
    // Lit: the Sun above the cell's horizon.
    let f1 = dot(r_hat, sun_frame);
    if !(f1 > T::zero()) {
        return;
    }
    let earth_r = T::of(EARTH_RADIUS_KM);
    let sat = scale(sight.up_frame, sight.radius_km);
    // Seen: the spacecraft above the cell's horizon.
    let rise = dot(r_hat, sat) - earth_r;
    if !(rise > T::zero()) {
        return;
    }
    let to_cell = sub(scale(r_hat, earth_r), sat);
    let d = norm(to_cell);
    if !(d > T::zero()) {
        return;
    }
    let inv_d = d.recip();
    let f2 = rise * inv_d;
    let weight = rho * area_km2 * f1 * f2 * inv_d * inv_d / T::of(core::f64::consts::PI);
    let u_body = mul(&sight.body_from_frame, scale(to_cell, inv_d));
    for (sensor, e) in sensors.iter().zip(out.iter_mut()) {
        let Some(s) = sensor else { continue };
        let c = dot(s.normal, u_body);
        if c > T::zero() && c >= s.cos_fov {
            *e = *e + weight * c;
        }
    }
}

/// The sine and cosine of a column's centre longitude, stepped column by column by the
/// angle-sum rule (a `sin_cos` per cell was half the cost of a fine grid) and recomputed
/// every [`Longitude::EXACT_EVERY`] columns so that rounding cannot build up.
struct Longitude<T> {
    index: i64,
    steps: u32,
    sin: T,
    cos: T,
}

impl<T: Real> Longitude<T> {
    const EXACT_EVERY: u32 = 16;

    fn new(cap: &Cap<T>, index: i64) -> Self {
        let (sin, cos) = cap.centre(index).sin_cos();
        Longitude {
            index,
            steps: 0,
            sin,
            cos,
        }
    }

    fn step(&mut self, cap: &Cap<T>) {
        self.index = self.index.wrapping_add(1);
        self.steps = self.steps.wrapping_add(1);
        if self.steps.is_multiple_of(Self::EXACT_EVERY) {
            (self.sin, self.cos) = cap.centre(self.index).sin_cos();
        } else {
            let (s, c) = (self.sin, self.cos);
            self.sin = s * cap.cos_dlon + c * cap.sin_dlon;
            self.cos = c * cap.cos_dlon - s * cap.sin_dlon;
        }
    }
}

/// The cap of cells the spacecraft sees: its sub-satellite point and angular radius.
struct Cap<T> {
    sin_lat: T,
    cos_lat: T,
    lon: T,
    cos_radius: T,
    dlat: T,
    dlon: T,
    lon0: T,
    sin_dlon: T,
    cos_dlon: T,
    n_lon: usize,
}

/// The visible columns of one row.
struct Band<T> {
    sin_lat: T,
    cos_lat: T,
    area_km2: T,
    first: i64,
    count: usize,
    n_lon: usize,
}

impl<T: Real> Band<T> {
    fn columns(&self) -> impl Iterator<Item = usize> + '_ {
        let n = self.n_lon as i64;
        (0..self.count).map(move |k| {
            let j = self.first.wrapping_add(k as i64);
            j.rem_euclid(n.max(1)) as usize
        })
    }
}

impl<T: Real> Cap<T> {
    fn new(sight: &Sight<'_, T>, n_lat: usize, n_lon: usize) -> Self {
        let [x, y, z] = sight.up_frame;
        let pi = T::of(core::f64::consts::PI);
        let sin_lat = z.max(-T::one()).min(T::one());
        let cos_lat = (x * x + y * y).sqrt();
        let ratio = (T::of(EARTH_RADIUS_KM) / sight.radius_km).min(T::one());
        let dlon = T::of(2.0) * pi / T::of(n_lon as f64);
        Cap {
            sin_lat,
            cos_lat,
            lon: y.atan2(x),
            cos_radius: ratio,
            dlat: pi / T::of(n_lat as f64),
            dlon,
            lon0: -pi,
            sin_dlon: dlon.sin(),
            cos_dlon: dlon.cos(),
            n_lon,
        }
    }

    /// Centre longitude of column `index` (unwrapped: any integer).
    fn centre(&self, index: i64) -> T {
        self.lon0 + (T::of(index as f64) + T::of(0.5)) * self.dlon
    }

    /// Row `row`'s cells whose centres the spacecraft can see, when any.
    fn band(&self, row: usize) -> Option<Band<T>> {
        let half_pi = T::of(core::f64::consts::FRAC_PI_2);
        let lat = -half_pi + (T::of(row as f64) + T::of(0.5)) * self.dlat;
        let (sin_lat, cos_lat) = lat.sin_cos();
        // Angular distance from the sub-satellite point: cos c = sin sin + cos cos cos dlon.
        let best = sin_lat * self.sin_lat + cos_lat * self.cos_lat;
        if best < self.cos_radius {
            return None;
        }
        let denominator = cos_lat * self.cos_lat;
        let half_width = if denominator > T::of(1e-9) {
            let x = (self.cos_radius - sin_lat * self.sin_lat) / denominator;
            if x <= -T::one() {
                T::of(core::f64::consts::PI)
            } else {
                x.min(T::one()).acos()
            }
        } else {
            T::of(core::f64::consts::PI)
        };
        let to_index = |lon: T| ((lon - self.lon0) / self.dlon - T::of(0.5)).to_f64_lossless();
        let lo = libm_floor(to_index(self.lon - half_width));
        let hi = libm_ceil(to_index(self.lon + half_width));
        let span = hi.saturating_sub(lo).saturating_add(1);
        let count = usize::try_from(span).unwrap_or(0).min(self.n_lon);
        let top = lat + self.dlat / T::of(2.0);
        let bottom = lat - self.dlat / T::of(2.0);
        let earth_r = T::of(EARTH_RADIUS_KM);
        Some(Band {
            sin_lat,
            cos_lat,
            area_km2: earth_r * earth_r * self.dlon * (top.sin() - bottom.sin()).abs(),
            first: lo,
            count,
            n_lon: self.n_lon,
        })
    }
}

fn libm_floor(x: f64) -> i64 {
    libm::floor(x) as i64
}

fn libm_ceil(x: f64) -> i64 {
    libm::ceil(x) as i64
}

/// Albedo irradiance over the Sun's on each photodiode of `normals_body` (unit normals,
/// hemispherical field of view) for the unit Sun direction `sun_body` and the Earth `earth`
/// (a uniform Earth of reflectivity `uniform` when it has no grid and rotation): the model
/// [`crate::estimate_sun`] subtracts, for tests and ground tools. All 0 when `earth` is not
/// usable; photodiodes whose normal is not usable get 0; at most
/// [`crate::MAX_PHOTODIODES`] are computed.
pub fn albedo_ratios<T: Real>(
    sun_body: [T; 3],
    earth: &crate::EarthInput<'_, T>,
    uniform: T,
    normals_body: &[[T; 3]],
    out: &mut [T],
) {
    let mut sensors = [None; crate::MAX_PHOTODIODES];
    for (s, n) in sensors.iter_mut().zip(normals_body) {
        *s = crate::Photodiode::cosine(T::one(), *n, T::zero()).checked();
    }
    match crate::sun::sight(earth, uniform) {
        Some(sight) => albedo_into(&sight, sun_body, &sensors, out),
        None => out.iter_mut().for_each(|e| *e = T::zero()),
    }
}
