//! The cell model (paper Eq. 13 as implemented by Basilisk's `albedo` module): precomputed cell
//! geometry, the per-step culled cell loop, and the naive all-cell loop kept as an oracle.

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::{Matrix3, Vector3};
use thiserror::Error;

use crate::map::{MapChoice, MapError, ReflectivityMap};
use crate::view::AlbedoView;

/// Astronomical unit, km (the value Basilisk uses).
pub const AU_KM: f64 = 149_597_870.693;
/// Earth equatorial radius used by Basilisk (`REQ_EARTH`), km.
pub const REQ_EARTH_KM: f64 = 6378.1366;
/// Earth polar radius used by Basilisk (`RP_EARTH`), km.
pub const RP_EARTH_KM: f64 = 6356.7519;

/// How the area of a cell is computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CellAreas {
    /// Basilisk: the cell's latitude edges are mapped to authalic latitude before the spherical
    /// zone formula, on a sphere of the authalic radius. The default.
    #[default]
    Authalic,
    /// Plain spherical zones on the same sphere. Used by the analytic test, where the sphere
    /// integral is exact.
    Spherical,
}

/// Errors from a per-step albedo computation.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum AlbedoError {
    /// An input vector or matrix has a NaN or infinite component.
    #[error("{what} is not finite")]
    NonFinite {
        /// Which input.
        what: &'static str,
    },
    /// The Sun position is (nearly) at the Earth centre.
    #[error("Sun position has zero length")]
    ZeroSun,
    /// `gcrf_to_ecef` is not a rotation (|R^T R - I| too large).
    #[error("gcrf_to_ecef is not orthonormal (max |R^T R - I| = {deviation:e})")]
    NotRotation {
        /// Largest deviation of R^T R from identity.
        deviation: f64,
    },
}

/// Authalic radius of the Basilisk Earth ellipsoid, km (6371.0068): the radius of the sphere
/// with the ellipsoid's area.
pub fn authalic_radius_km() -> f64 {
    let e = eccentricity();
    let t0 = REQ_EARTH_KM * REQ_EARTH_KM * 0.5;
    let t1 = (1.0 - e * e) / 2.0 / e;
    let t2 = ((1.0 + e) / (1.0 - e)).ln();
    (t0 * (1.0 + t1 * t2)).sqrt()
}

fn eccentricity() -> f64 {
    (1.0 - (RP_EARTH_KM / REQ_EARTH_KM).powi(2)).sqrt()
}

/// Authalic latitude beta(phi) of geodetic latitude `phi` (rad), Basilisk's truncated series:
/// beta = phi - t0 sin 2phi + t1 sin 4phi - t2 sin 6phi.
pub fn authalic_latitude(phi: f64) -> f64 {
    let e2 = eccentricity().powi(2);
    let (e4, e6) = (e2 * e2, e2 * e2 * e2);
    let t0 = e2 / 3.0 + 31.0 * e4 / 180.0 + 59.0 * e6 / 560.0;
    let t1 = 17.0 * e4 / 360.0 + 61.0 * e6 / 1260.0;
    let t2 = 383.0 * e6 / 45360.0;
    phi - (t0 * (2.0 * phi).sin() - t1 * (4.0 * phi).sin() + t2 * (6.0 * phi).sin())
}

/// A reflectivity map with its cell geometry precomputed (once per map).
///
/// Cell (i, j) has its centre at geodetic latitude `(i - n_lat/2 + 1/2) dlat` and longitude
/// `(j - n_lon/2 + 1/2) dlon`, on a sphere of radius [`AlbedoModel::radius_km`].
#[derive(Debug, Clone)]
pub struct AlbedoModel {
    n_lat: usize,
    n_lon: usize,
    dlat_rad: f64,
    dlon_rad: f64,
    radius_km: f64,
    lat_rad: Vec<f64>,
    lon_rad: Vec<f64>,
    sin_lat: Vec<f64>,
    cos_lat: Vec<f64>,
    sin_lon: Vec<f64>,
    cos_lon: Vec<f64>,
    /// Per cell: ALB * dA / pi, km^2 (row-major like the map).
    weight_km2: Vec<f64>,
}

impl AlbedoModel {
    /// Precomputes the geometry of `map` with Basilisk's authalic cell areas.
    pub fn new(map: &ReflectivityMap) -> Self {
        Self::with_areas(map, CellAreas::Authalic)
    }

    /// Loads the map named by `choice` and precomputes its geometry (authalic areas).
    pub fn from_choice(choice: &MapChoice) -> Result<Self, MapError> {
        Ok(Self::new(&choice.load()?))
    }

    /// Precomputes the geometry of `map` with the given cell-area rule.
    pub fn with_areas(map: &ReflectivityMap, areas: CellAreas) -> Self {
        let (n_lat, n_lon) = (map.n_lat(), map.n_lon());
        let dlat_rad = PI / n_lat as f64;
        let dlon_rad = 2.0 * PI / n_lon as f64;
        let radius_km = authalic_radius_km();
        // Basilisk: gdlat = (ilat + 0.5) dlat for ilat = -n/2 .. n/2 (n/2 is an integer
        // division in C++ stored as double; the maps here have even n_lat and n_lon).
        let half_lat = (n_lat / 2) as f64;
        let half_lon = (n_lon / 2) as f64;
        let lat_rad: Vec<f64> = (0..n_lat)
            .map(|i| (i as f64 - half_lat + 0.5) * dlat_rad)
            .collect();
        let lon_rad: Vec<f64> = (0..n_lon)
            .map(|j| (j as f64 - half_lon + 0.5) * dlon_rad)
            .collect();
        let band = |lat: f64| match areas {
            CellAreas::Authalic => authalic_latitude(lat),
            CellAreas::Spherical => lat,
        };
        let mut weight_km2 = Vec::with_capacity(n_lat * n_lon);
        for (i, &lat) in lat_rad.iter().enumerate() {
            let north = band(lat + 0.5 * dlat_rad);
            let south = band(lat - 0.5 * dlat_rad);
            let area_km2 = dlon_rad * (north.sin() - south.sin()).abs() * radius_km * radius_km;
            let row = &map.values()[i * n_lon..(i + 1) * n_lon];
            weight_km2.extend(row.iter().map(|alb| alb * area_km2 / PI));
        }
        Self {
            n_lat,
            n_lon,
            dlat_rad,
            dlon_rad,
            radius_km,
            sin_lat: lat_rad.iter().map(|l| l.sin()).collect(),
            cos_lat: lat_rad.iter().map(|l| l.cos()).collect(),
            sin_lon: lon_rad.iter().map(|l| l.sin()).collect(),
            cos_lon: lon_rad.iter().map(|l| l.cos()).collect(),
            lat_rad,
            lon_rad,
            weight_km2,
        }
    }

    /// Radius of the sphere carrying the cells (Basilisk's authalic radius), km.
    pub fn radius_km(&self) -> f64 {
        self.radius_km
    }

    /// Number of cells.
    pub fn n_cells(&self) -> usize {
        self.n_lat * self.n_lon
    }

    /// Sum of the cell areas, km^2 (4 pi R^2 up to the truncation of the authalic series).
    pub fn total_area_km2(&self, map: &ReflectivityMap) -> f64 {
        self.weight_km2
            .iter()
            .zip(map.values())
            .filter(|(_, alb)| **alb > 0.0)
            .map(|(w, alb)| w * PI / alb)
            .sum()
    }

    /// Cell-centre latitude of row `i` and longitude of column `j`, rad.
    pub fn cell_centre_rad(&self, i: usize, j: usize) -> Option<(f64, f64)> {
        Some((*self.lat_rad.get(i)?, *self.lon_rad.get(j)?))
    }

    fn r_hat_ecef(&self, i: usize, j: usize) -> Vector3<f64> {
        let c = self.cos_lat[i];
        Vector3::new(c * self.cos_lon[j], c * self.sin_lon[j], self.sin_lat[i])
    }

    /// Fills `view` with the lit cells seen by the satellite (paper Eq. 13, Basilisk's model).
    ///
    /// Only the latitude rows and per row the longitude span that intersect the satellite's
    /// visible cap (half-angle acos(R/|r_sat|)) are visited; each visited cell gets Basilisk's
    /// exact tests f2 > 0 (seen) and f1 > 0 (lit). Cells are grouped into tiles of
    /// [`TILE_ROWS`] x [`TILE_COLS`] cells for the sensor pass. No allocation once `view` has
    /// grown to the largest cell count. A satellite at or below the surface sees nothing.
    pub fn compute_into(
        &self,
        view: &mut AlbedoView,
        r_sat_gcrf_km: &Vector3<f64>,
        r_sun_gcrf_km: &Vector3<f64>,
        gcrf_to_ecef: &Matrix3<f64>,
    ) -> Result<(), AlbedoError> {
        self.fill(view, r_sat_gcrf_km, r_sun_gcrf_km, gcrf_to_ecef, true)
    }

    /// Like [`AlbedoModel::compute_into`] but visits every cell of the map (no culling). Kept
    /// as a test oracle for the culling.
    pub fn compute_into_unculled(
        &self,
        view: &mut AlbedoView,
        r_sat_gcrf_km: &Vector3<f64>,
        r_sun_gcrf_km: &Vector3<f64>,
        gcrf_to_ecef: &Matrix3<f64>,
    ) -> Result<(), AlbedoError> {
        self.fill(view, r_sat_gcrf_km, r_sun_gcrf_km, gcrf_to_ecef, false)
    }

    fn fill(
        &self,
        view: &mut AlbedoView,
        r_sat_gcrf_km: &Vector3<f64>,
        r_sun_gcrf_km: &Vector3<f64>,
        gcrf_to_ecef: &Matrix3<f64>,
        cull: bool,
    ) -> Result<(), AlbedoError> {
        let step = Step::new(self, r_sat_gcrf_km, r_sun_gcrf_km, gcrf_to_ecef)?;
        view.begin(*gcrf_to_ecef, step.nadir_ecef, step.sin_rho);
        if cull && step.r_sat_norm <= self.radius_km {
            return Ok(());
        }
        let cap = Cap::new(self, &step, cull);
        let (i_lo, i_hi) = cap.rows;
        let mut group = i_lo - i_lo % TILE_ROWS;
        while group <= i_hi {
            let rows = group.max(i_lo)..(group + TILE_ROWS).min(i_hi + 1);
            let spans: [Option<(i64, i64)>; TILE_ROWS] = std::array::from_fn(|r| {
                if rows.contains(&(group + r)) {
                    cap.span(self, group + r)
                } else {
                    None
                }
            });
            let lo = spans.iter().flatten().map(|s| s.0).min();
            let hi = spans.iter().flatten().map(|s| s.1).max();
            if let (Some(lo), Some(hi)) = (lo, hi) {
                let cells: i64 = spans.iter().flatten().map(|s| s.1 - s.0 + 1).sum();
                view.reserve(cells as usize);
                let cols = TILE_COLS as i64;
                for chunk in lo.div_euclid(cols)..=hi.div_euclid(cols) {
                    for (r, span) in spans.iter().enumerate() {
                        let Some((s_lo, s_hi)) = *span else { continue };
                        let (j_lo, j_hi) =
                            (s_lo.max(chunk * cols), s_hi.min(chunk * cols + cols - 1));
                        if j_lo > j_hi {
                            continue;
                        }
                        // One wrap at most (the span is at most n_lon long): two plain runs.
                        let n_lon = self.n_lon as i64;
                        let start = j_lo.rem_euclid(n_lon) as usize;
                        let len = (j_hi - j_lo + 1) as usize;
                        let first = len.min(self.n_lon - start);
                        self.fill_run(view, &step, group + r, start, start + first);
                        self.fill_run(view, &step, group + r, 0, len - first);
                    }
                    view.end_tile();
                }
            }
            group += TILE_ROWS;
        }
        Ok(())
    }

    /// Pushes the lit, seen cells of row `i`, columns `j_lo..j_hi`: a branch-free pass over
    /// the run (vectorisable: the square root and division dominate), then an in-place
    /// compaction that keeps the cells passing Basilisk's tests.
    #[inline(always)]
    fn fill_run(&self, view: &mut AlbedoView, step: &Step, i: usize, j_lo: usize, j_hi: usize) {
        if j_hi <= j_lo {
            return;
        }
        let (cos_lat, sin_lat) = (self.cos_lat[i], self.sin_lat[i]);
        let row = i * self.n_lon;
        let cos_lon = &self.cos_lon[j_lo..j_hi];
        let sin_lon = &self.sin_lon[j_lo..j_hi];
        let weight = &self.weight_km2[row + j_lo..row + j_hi];
        let (ux, uy, uz, c) = view.run_slots(j_hi - j_lo);
        for k in 0..c.len() {
            let r_hat = Vector3::new(cos_lat * cos_lon[k], cos_lat * sin_lon[k], sin_lat);
            let (u, ck) = self.cell_term_raw(step, &r_hat, weight[k]);
            ux[k] = u.x;
            uy[k] = u.y;
            uz[k] = u.z;
            c[k] = ck;
        }
        view.commit_run(j_hi - j_lo);
    }

    /// Like [`Self::cell_term_at`] without branches: c < 0 marks a cell that is not lit or
    /// not seen (it is then dropped by the view).
    #[inline(always)]
    fn cell_term_raw(
        &self,
        step: &Step,
        r_hat: &Vector3<f64>,
        weight_km2: f64,
    ) -> (Vector3<f64>, f64) {
        let radius = self.radius_km;
        let rd = r_hat.dot(&step.r_sat_ecef) - radius;
        let a_sun = r_hat.dot(&step.r_sun_ecef);
        let re = a_sun - radius;
        let d = step.r_sat_ecef - r_hat * radius;
        let inv_d = 1.0 / d.norm_squared().sqrt();
        let inv_e = step.inv_sun_distance(radius, a_sun);
        let c = weight_km2 * (re * inv_e) * (rd * inv_d) * inv_d * inv_d * step.au_sq;
        let keep = rd > 0.0 && re > 0.0;
        (-d * inv_d, if keep { c } else { -1.0 })
    }

    #[inline(always)]
    fn cell_term(&self, step: &Step, i: usize, j: usize) -> Option<(Vector3<f64>, f64)> {
        self.cell_term_at(
            step,
            &self.r_hat_ecef(i, j),
            self.weight_km2[i * self.n_lon + j],
        )
    }

    /// Basilisk's per-cell terms: `Some((u, c))` for a lit cell seen by the satellite, with
    /// u the unit vector from the satellite to the cell (ECEF) and
    /// c = ALB f1 f2 dA / (pi |d|^2) (AU/|r_sun|)^2.
    #[inline(always)]
    fn cell_term_at(
        &self,
        step: &Step,
        r_hat: &Vector3<f64>,
        weight_km2: f64,
    ) -> Option<(Vector3<f64>, f64)> {
        let radius = self.radius_km;
        // f2 > 0: r_hat . (r_sat - R r_hat) > 0, the cell centre is above the satellite's
        // horizon.
        let rd = r_hat.dot(&step.r_sat_ecef) - radius;
        if rd <= 0.0 {
            return None;
        }
        // f1 > 0 with the Sun vector from the cell itself (not from the Earth centre): lit.
        let a_sun = r_hat.dot(&step.r_sun_ecef);
        let re = a_sun - radius;
        if re <= 0.0 {
            return None;
        }
        let d = step.r_sat_ecef - r_hat * radius;
        let d2 = d.norm_squared();
        let inv_d = 1.0 / d2.sqrt();
        let inv_e = step.inv_sun_distance(radius, a_sun);
        let f1 = re * inv_e;
        let f2 = rd * inv_d;
        let c = weight_km2 * f1 * f2 * inv_d * inv_d * step.au_sq;
        Some((-d * inv_d, c))
    }

    /// Naive evaluation as open simulators do it: for each sensor, loop over every cell of the
    /// map and accumulate c (n.u) over the lit, seen, gated cells. Returns E_a/E_AM0 and the
    /// gated sum of c u per sensor in `out`. For benchmarks and as an oracle.
    pub fn naive_ratios(
        &self,
        r_sat_gcrf_km: &Vector3<f64>,
        r_sun_gcrf_km: &Vector3<f64>,
        gcrf_to_ecef: &Matrix3<f64>,
        normals_gcrf: &[Vector3<f64>],
        cos_fov: &[f64],
        out: &mut [(f64, Vector3<f64>)],
    ) -> Result<(), AlbedoError> {
        let step = Step::new(self, r_sat_gcrf_km, r_sun_gcrf_km, gcrf_to_ecef)?;
        for ((n_gcrf, &cf), slot) in normals_gcrf.iter().zip(cos_fov).zip(out.iter_mut()) {
            let mut sum = 0.0;
            let mut vec = Vector3::zeros();
            for i in 0..self.n_lat {
                for j in 0..self.n_lon {
                    if let Some((u_ecef, c)) = self.cell_term(&step, i, j) {
                        let u_gcrf = gcrf_to_ecef.tr_mul(&u_ecef).column(0).into_owned();
                        // Basilisk: f3 = n.(-d_hat), gated by f3 >= cos(fov).
                        let f3 = n_gcrf.dot(&u_gcrf);
                        if f3 >= cf && f3 > 0.0 {
                            sum += c * f3;
                            vec += c * u_gcrf;
                        }
                    }
                }
            }
            *slot = (sum, vec);
        }
        Ok(())
    }
}

/// Cells per tile along latitude and longitude (see [`AlbedoModel::compute_into`]).
pub const TILE_ROWS: usize = 4;
/// Cells per tile along longitude.
pub const TILE_COLS: usize = 8;

/// Per-step quantities shared by all cells.
struct Step {
    r_sat_ecef: Vector3<f64>,
    r_sun_ecef: Vector3<f64>,
    r_sat_norm: f64,
    r_sun_norm2: f64,
    inv_s: f64,
    inv_s2: f64,
    /// The Sun is far enough (> 1e8 km) for the series of 1/|r_sun - r_cell|.
    sun_series: bool,
    nadir_ecef: Vector3<f64>,
    /// sin of the Earth's angular radius seen from the satellite (R/|r_sat|, at most 1).
    sin_rho: f64,
    /// (AU/|r_sun|)^2: scales the flux at the Earth's distance to the 1-AU flux.
    au_sq: f64,
}

impl Step {
    /// 1/|r_sun - R r_hat| from a_sun = r_hat . r_sun. At the Sun's distance it is
    /// (1/S) (1 + eps)^(-1/2) with eps = (R^2 - 2 R a_sun)/S^2, |eps| < 1e-4, so the series to
    /// eps^3 is exact to rounding (next term 35/128 eps^4 < 3e-17); closer "suns" take the
    /// square root.
    #[inline(always)]
    fn inv_sun_distance(&self, radius: f64, a_sun: f64) -> f64 {
        if self.sun_series {
            let eps = (radius * radius - 2.0 * radius * a_sun) * self.inv_s2;
            self.inv_s * (1.0 - eps * (0.5 - eps * (0.375 - eps * 0.3125)))
        } else {
            let e2 = self.r_sun_norm2 - 2.0 * radius * a_sun + radius * radius;
            1.0 / e2.sqrt()
        }
    }

    fn new(
        model: &AlbedoModel,
        r_sat_gcrf_km: &Vector3<f64>,
        r_sun_gcrf_km: &Vector3<f64>,
        gcrf_to_ecef: &Matrix3<f64>,
    ) -> Result<Self, AlbedoError> {
        if !r_sat_gcrf_km.iter().all(|v| v.is_finite()) {
            return Err(AlbedoError::NonFinite {
                what: "r_sat_gcrf_km",
            });
        }
        if !r_sun_gcrf_km.iter().all(|v| v.is_finite()) {
            return Err(AlbedoError::NonFinite {
                what: "r_sun_gcrf_km",
            });
        }
        if !gcrf_to_ecef.iter().all(|v| v.is_finite()) {
            return Err(AlbedoError::NonFinite {
                what: "gcrf_to_ecef",
            });
        }
        let deviation = (gcrf_to_ecef.transpose() * gcrf_to_ecef - Matrix3::identity()).amax();
        // 1e-9 admits rotations built from rounded file values (10-15 digits) while rejecting
        // anything that is not a rotation.
        if deviation > 1e-9 {
            return Err(AlbedoError::NotRotation { deviation });
        }
        let r_sun_norm = r_sun_gcrf_km.norm();
        if r_sun_norm <= model.radius_km {
            return Err(AlbedoError::ZeroSun);
        }
        let r_sat_ecef = gcrf_to_ecef * r_sat_gcrf_km;
        let r_sat_norm = r_sat_ecef.norm();
        let nadir_ecef = if r_sat_norm > 0.0 {
            -r_sat_ecef / r_sat_norm
        } else {
            Vector3::z()
        };
        Ok(Self {
            r_sat_ecef,
            r_sun_ecef: gcrf_to_ecef * r_sun_gcrf_km,
            r_sat_norm,
            r_sun_norm2: r_sun_norm * r_sun_norm,
            inv_s: 1.0 / r_sun_norm,
            inv_s2: 1.0 / (r_sun_norm * r_sun_norm),
            sun_series: r_sun_norm > 1e8,
            nadir_ecef,
            sin_rho: (model.radius_km / r_sat_norm).min(1.0),
            au_sq: (AU_KM / r_sun_norm).powi(2),
        })
    }
}

/// The rows and per-row longitude spans of the satellite's visible cap.
struct Cap {
    rows: (usize, usize),
    cull: bool,
    cos_cap: f64,
    sin_s: f64,
    cos_s: f64,
    lon_s: f64,
}

impl Cap {
    fn new(model: &AlbedoModel, step: &Step, cull: bool) -> Self {
        let r = step.r_sat_ecef;
        let lat_s = (r.z / step.r_sat_norm.max(f64::MIN_POSITIVE))
            .clamp(-1.0, 1.0)
            .asin();
        let lon_s = r.y.atan2(r.x);
        let (sin_s, cos_s) = lat_s.sin_cos();
        if !cull {
            return Self {
                rows: (0, model.n_lat - 1),
                cull,
                cos_cap: -1.0,
                sin_s,
                cos_s,
                lon_s,
            };
        }
        // Small angular margin so that rounding in the cap bounds never drops a cell that the
        // exact per-cell test accepts; extra cells are rejected by that test.
        const MARGIN_RAD: f64 = 1e-9;
        let cap = (model.radius_km / step.r_sat_norm).acos() + MARGIN_RAD;
        let to_index = |lat: f64| (lat + FRAC_PI_2) / model.dlat_rad - 0.5;
        let i_lo = to_index(lat_s - cap).floor().max(0.0) as usize;
        let i_hi = (to_index(lat_s + cap).ceil().max(0.0) as usize).min(model.n_lat - 1);
        Self {
            rows: (i_lo, i_hi),
            cull,
            cos_cap: cap.cos(),
            sin_s,
            cos_s,
            lon_s,
        }
    }

    /// Unwrapped longitude index range [lo, hi] (at most n_lon long, indices taken modulo
    /// n_lon) of the cells of row `i` whose centres may be in the cap; `None` if none.
    fn span(&self, model: &AlbedoModel, i: usize) -> Option<(i64, i64)> {
        let n_lon = model.n_lon as i64;
        let full = || {
            let j_s = ((self.lon_s + PI) / model.dlon_rad).floor() as i64;
            Some((j_s - n_lon / 2, j_s - n_lon / 2 + n_lon - 1))
        };
        if !self.cull {
            return full();
        }
        // Centre at angular distance <= cap from the sub-satellite point: cos(dlon) >= k.
        let den = model.cos_lat[i] * self.cos_s;
        let k = if den > 1e-12 {
            (self.cos_cap - model.sin_lat[i] * self.sin_s) / den
        } else {
            -1.0
        };
        if k > 1.0 {
            return None;
        }
        if k <= -1.0 {
            return full();
        }
        let half = k.acos();
        let lo = ((self.lon_s - half + PI) / model.dlon_rad - 0.5).floor() as i64;
        let hi = ((self.lon_s + half + PI) / model.dlon_rad - 0.5).ceil() as i64;
        if hi - lo + 1 >= n_lon {
            full()
        } else {
            Some((lo, hi))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn authalic_radius_is_basilisk_value() {
        // Reference README: R = 6371.0068 km.
        assert!((authalic_radius_km() - 6371.0068).abs() < 5e-5);
    }

    #[test]
    fn cell_areas_sum_to_sphere_area() {
        let map = ReflectivityMap::uniform(180, 288, 0.5).unwrap();
        let r = authalic_radius_km();
        let sphere = 4.0 * PI * r * r;
        for areas in [CellAreas::Authalic, CellAreas::Spherical] {
            let model = AlbedoModel::with_areas(&map, areas);
            let total = model.total_area_km2(&map);
            // The authalic series is exact at the poles and the equator up to its O(e^8)
            // truncation (~1e-11), so the zones tile the sphere to rounding.
            assert!(
                (total / sphere - 1.0).abs() < 1e-10,
                "{areas:?}: {total} vs {sphere}"
            );
        }
    }
}
