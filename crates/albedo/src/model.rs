//! The cell model (paper Eq. 13 as implemented by Basilisk's `albedo` module): precomputed cell
//! geometry, the per-step culled cell loop, and the naive all-cell loop kept as an oracle.

use std::f64::consts::{FRAC_PI_2, PI};

use nalgebra::{Matrix3, Vector3};
use wide::f64x4;

use crate::error::AlbedoError;
use crate::geometry::{AU_KM, authalic_latitude, authalic_radius_km};
use crate::map::{MapChoice, MapError, ReflectivityMap};
use crate::tile::{Cells4, Chunks, LANES_PER_CHUNK, TILE_COLS, TILE_ROWS, TileAcc};
use crate::view::AlbedoView;

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
    /// Columns per row rounded up to a multiple of [`TILE_COLS`] (the fast loop's rows).
    n_pad: usize,
    /// cos and sin of the column longitudes, padded (the padding repeats the last column).
    cos_lon4: Vec<f64x4>,
    sin_lon4: Vec<f64x4>,
    /// Weights in padded rows; -1 marks padding (never kept).
    weight4: Vec<f64x4>,
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
        // Rows padded to whole chunks: padding repeats the last column's longitude (so tile
        // cones do not grow) with weight -1 (never kept).
        let n_pad = n_lon.div_ceil(TILE_COLS) * TILE_COLS;
        let padded = |f: &dyn Fn(usize) -> f64| -> Vec<f64x4> {
            let cols: Vec<f64> = (0..n_pad).map(f).collect();
            cols.chunks_exact(4)
                .map(|q| f64x4::new([q[0], q[1], q[2], q[3]]))
                .collect()
        };
        let cos_lon4 = padded(&|j| lon_rad[j.min(n_lon - 1)].cos());
        let sin_lon4 = padded(&|j| lon_rad[j.min(n_lon - 1)].sin());
        let weight4 = (0..n_lat)
            .flat_map(|i| {
                padded(&|j| {
                    weight_km2
                        .get(i * n_lon + j)
                        .filter(|_| j < n_lon)
                        .copied()
                        .unwrap_or(-1.0)
                })
            })
            .collect();
        Self {
            n_pad,
            cos_lon4,
            sin_lon4,
            weight4,
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

    /// The same model with every cell's reflectivity multiplied by `factor(latitude_rad)`
    /// of its row (negative factors count as 0): a map corrected in latitude, as the
    /// diagnosis's `albedo-map` effect fits it. Padding stays padding.
    pub fn with_latitude_factor(&self, factor: impl Fn(f64) -> f64) -> AlbedoModel {
        let mut out = self.clone();
        let per_row = self.n_pad / 4;
        for (i, &lat) in self.lat_rad.iter().enumerate() {
            let f = factor(lat).max(0.0);
            for w in &mut out.weight_km2[i * self.n_lon..(i + 1) * self.n_lon] {
                *w *= f;
            }
            for v in &mut out.weight4[i * per_row..(i + 1) * per_row] {
                let lanes = v.to_array().map(|w| if w < 0.0 { w } else { w * f });
                *v = f64x4::new(lanes);
            }
        }
        out
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
    /// Only the latitude rows and per row the chunks of [`TILE_COLS`] columns that intersect
    /// the satellite's visible cap (half-angle acos(R/|r_sat|)) are visited; each visited
    /// cell gets Basilisk's exact tests f2 > 0 (seen) and f1 > 0 (lit), four cells at a time
    /// (f64x4, branch-free: a cell failing them keeps its slot with c = 0). Cells are grouped
    /// into tiles of [`TILE_ROWS`] x [`TILE_COLS`] cells, each with its sum of c u and a
    /// bounding cone, for the sensor pass. No allocation once `view` has grown to the largest
    /// cell count. A satellite at or below the surface sees nothing.
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
            // Rows without padding skip the padding test (monomorphised).
            if self.n_pad == self.n_lon {
                self.fill_group::<false>(view, &step, &cap, group);
            } else {
                self.fill_group::<true>(view, &step, &cap, group);
            }
            group += TILE_ROWS;
        }
        view.finish();
        Ok(())
    }

    /// The tiles of rows `group..group + TILE_ROWS` (those in the cap): one tile per chunk of
    /// [`TILE_COLS`] columns that any row's span reaches. Each row is swept once over its
    /// chunks, writing each chunk's cells into its tile's block of slots.
    fn fill_group<const PADDED: bool>(
        &self,
        view: &mut AlbedoView,
        step: &Step,
        cap: &Cap,
        group: usize,
    ) {
        let mut chunks = [Chunks::EMPTY; TILE_ROWS];
        let mut union: Option<(i64, i64)> = None;
        for (row_chunks, span) in chunks.iter_mut().zip(cap.spans(self, group)) {
            if let Some(span) = span {
                *row_chunks = self.chunks(span);
                // Every span contains the sub-satellite column, so their union is one
                // interval.
                union = Some(union.map_or(span, |u| (u.0.min(span.0), u.1.max(span.1))));
            }
        }
        let Some(union) = union else { return };
        let tiles = self.chunks(union);
        // Tile blocks in chunk order, each as long as the rows reaching its chunk.
        let accs = view.group_accs();
        let mut n_vec = 0;
        for q in tiles.iter() {
            let rows = chunks.iter().filter(|c| c.contains(q)).count();
            accs.push(TileAcc::new(self.tile_axis(step, group, q), n_vec));
            n_vec += rows * LANES_PER_CHUNK;
        }
        let (mut slots, accs) = view.group_slots(n_vec);
        for (r, row_chunks) in chunks.iter().enumerate() {
            if row_chunks.is_empty() {
                continue;
            }
            let row = RowConsts::new(self, step, group + r);
            let base = (group + r) * self.n_pad / 4;
            for q in row_chunks.iter() {
                let acc = &mut accs[tiles.index(q)];
                let out = acc.cursor..acc.cursor + LANES_PER_CHUNK;
                acc.cursor = out.end;
                let v0 = q as usize * LANES_PER_CHUNK;
                let cols = v0..v0 + LANES_PER_CHUNK;
                let (cos_lon, sin_lon) = (&self.cos_lon4[cols.clone()], &self.sin_lon4[cols]);
                let weight = &self.weight4[base + v0..base + v0 + LANES_PER_CHUNK];
                let [xs, ys, zs, cs] = &mut slots;
                let (xs, ys) = (&mut xs[out.clone()], &mut ys[out.clone()]);
                let (zs, cs) = (&mut zs[out.clone()], &mut cs[out]);
                for k in 0..LANES_PER_CHUNK {
                    let cell = row.cell::<PADDED>(cos_lon[k], sin_lon[k], weight[k]);
                    acc.add(&cell);
                    (xs[k], ys[k], zs[k], cs[k]) = (cell.u[0], cell.u[1], cell.u[2], cell.c);
                }
            }
        }
        view.end_group(n_vec);
    }

    /// The chunks of [`TILE_COLS`] columns (indices into the padded row) holding the columns
    /// of the unwrapped span `lo..=hi`.
    fn chunks(&self, (lo, hi): (i64, i64)) -> Chunks {
        let n = self.n_lon as i64;
        let cols = TILE_COLS as i64;
        let last = (self.n_pad / TILE_COLS) as i64 - 1;
        if hi - lo + 1 >= n {
            return Chunks::all(last);
        }
        let (lo_m, hi_m) = (lo.rem_euclid(n), hi.rem_euclid(n));
        let (a, b) = (lo_m / cols, hi_m / cols);
        if lo_m <= hi_m {
            Chunks([(a, b), (1, 0)])
        } else if b + 1 >= a {
            // The two ends of a wrapped span share a chunk: the whole row.
            Chunks::all(last)
        } else {
            Chunks([(0, b), (a, last)])
        }
    }

    /// Unit vector from the satellite to the cell nearest the centre of the tile of rows
    /// `group..group + TILE_ROWS` and chunk `q`: the axis of the tile's cone (any axis works;
    /// the radius is measured from it).
    fn tile_axis(&self, step: &Step, group: usize, q: i64) -> Vector3<f64> {
        let i = (group + TILE_ROWS / 2).min(self.n_lat - 1);
        let j = (q as usize * TILE_COLS + TILE_COLS / 2).min(self.n_lon - 1);
        let d = self.r_hat_ecef(i, j) * self.radius_km - step.r_sat_ecef;
        let norm = d.norm();
        if norm > 0.0 {
            d / norm
        } else {
            step.nadir_ecef
        }
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

/// Per-row constants of the cell loop (splat in f64x4): with
/// r_hat = (cos_lat cos_lon, cos_lat sin_lon, sin_lat), every dot product with r_hat is
/// a cos_lon + b sin_lon + c.
struct RowConsts {
    /// rd = r_hat . r_sat - R = sat[0] cos_lon + sat[1] sin_lon + sat[2].
    sat: [f64x4; 3],
    /// re = r_hat . r_sun - R = sun[0] cos_lon + sun[1] sin_lon + sun[2].
    sun: [f64x4; 3],
    /// |d|^2 = d2_0 + d2_1 rd, d = r_sat - R r_hat.
    d2_0: f64x4,
    d2_1: f64x4,
    /// Floor of |d|^2 (keeps u finite for a satellite on a cell centre, whose c is 0).
    tiny: f64x4,
    /// u = (R r_hat - r_sat) / |d|: R cos_lat, -r_sat.x, -r_sat.y, R sin_lat - r_sat.z.
    rcl: f64x4,
    nsat: [f64x4; 2],
    uz_num: f64x4,
    /// The Sun is far: re kc/|r_sun - R r_hat| = re (b0 + re (b1 + re (b2 + re b3))), the
    /// series of [`Step::inv_sun_distance`] in eps = e_0 + e_1 re expanded in powers of re;
    /// else kc/sqrt(e_0 + e_1 re).
    sun_series: bool,
    e_0: f64x4,
    e_1: f64x4,
    b: [f64x4; 4],
    /// (AU/|r_sun|)^2, times 1/S with the series.
    kc: f64x4,
}

impl RowConsts {
    fn new(model: &AlbedoModel, step: &Step, i: usize) -> Self {
        let (cl, sl) = (model.cos_lat[i], model.sin_lat[i]);
        let (s, p) = (&step.r_sat_ecef, &step.r_sun_ecef);
        let radius = model.radius_km;
        let r2 = radius * radius;
        let v = f64x4::splat;
        let (e_0, e_1, kc) = if step.sun_series {
            // eps = (R^2 - 2 R r_hat.r_sun) / S^2 with r_hat.r_sun = re + R.
            (
                -r2 * step.inv_s2,
                -2.0 * radius * step.inv_s2,
                step.au_sq * step.inv_s,
            )
        } else {
            (step.r_sun_norm2 - r2, -2.0 * radius, step.au_sq)
        };
        Self {
            sat: [v(cl * s.x), v(cl * s.y), v(sl * s.z - radius)],
            sun: [v(cl * p.x), v(cl * p.y), v(sl * p.z - radius)],
            d2_0: v(step.r_sat_norm * step.r_sat_norm - r2),
            d2_1: v(-2.0 * radius),
            tiny: v(f64::MIN_POSITIVE),
            rcl: v(radius * cl),
            nsat: [v(-s.x), v(-s.y)],
            uz_num: v(radius * sl - s.z),
            sun_series: step.sun_series,
            e_0: v(e_0),
            e_1: v(e_1),
            b: sun_series_in_re(e_0, e_1, kc).map(v),
            kc: v(kc),
        }
    }

    /// Basilisk's terms of four cells of the row at longitudes (cos, sin) with weights
    /// ALB dA / pi: c = ALB f1 f2 dA / (pi |d|^2) (AU/|r_sun|)^2, and c = 0 for a cell that
    /// is not lit or not seen (f1 <= 0 or f2 <= 0) or pads the row (weight < 0).
    #[inline(always)]
    fn cell<const PADDED: bool>(&self, cl: f64x4, sl: f64x4, w: f64x4) -> Cells4 {
        let zero = f64x4::ZERO;
        // f2 and f1 numerators: r_hat . r_sat - R and r_hat . r_sun - R.
        let rd = self.sat[0].mul_add(cl, self.sat[1].mul_add(sl, self.sat[2]));
        let re = self.sun[0].mul_add(cl, self.sun[1].mul_add(sl, self.sun[2]));
        let d2 = self.d2_1.mul_add(rd, self.d2_0);
        let inv_d = f64x4::ONE / d2.fast_max(self.tiny).sqrt();
        // re kc / |r_sun - R r_hat|.
        let f1 = if self.sun_series {
            let [b0, b1, b2, b3] = self.b;
            re * re.mul_add(re.mul_add(re.mul_add(b3, b2), b1), b0)
        } else {
            re * self.kc / self.e_1.mul_add(re, self.e_0).sqrt()
        };
        // rd > 0 and re > 0 (both finite: the inputs are checked).
        let lit_seen = rd.fast_min(re).simd_gt(zero);
        let keep = if PADDED {
            lit_seen & w.simd_ge(zero)
        } else {
            lit_seen
        };
        let c = (w * f1) * rd * (inv_d * inv_d * inv_d);
        Cells4 {
            u: [
                self.rcl.mul_add(cl, self.nsat[0]) * inv_d,
                self.rcl.mul_add(sl, self.nsat[1]) * inv_d,
                self.uz_num * inv_d,
            ],
            c: keep & c,
        }
    }
}

/// Coefficients b of kc (1 - eps/2 + 3/8 eps^2 - 5/16 eps^3) = b0 + b1 re + b2 re^2 +
/// b3 re^3 for eps = e0 + e1 re (all terms of one sign for a lit cell: no cancellation).
fn sun_series_in_re(e0: f64, e1: f64, kc: f64) -> [f64; 4] {
    [
        kc * (1.0 - e0 * (0.5 - e0 * (0.375 - 0.3125 * e0))),
        kc * e1 * (-0.5 + e0 * (0.75 - 0.9375 * e0)),
        kc * e1 * e1 * (0.375 - 0.9375 * e0),
        kc * e1 * e1 * e1 * -0.3125,
    ]
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
    /// The spans of rows `group..group + TILE_ROWS` (`None` outside `rows`), with the
    /// arc cosines taken four rows at a time.
    fn spans(&self, model: &AlbedoModel, group: usize) -> [Option<(i64, i64)>; TILE_ROWS] {
        // k > 1: no cell (rows outside the cap's rows get 2).
        let mut k = [2.0f64; SPAN_LANES];
        for (r, k) in k.iter_mut().enumerate().take(TILE_ROWS) {
            let i = group + r;
            if (self.rows.0..=self.rows.1).contains(&i) {
                *k = self.span_k(model, i);
            }
        }
        let mut half = [0.0f64; SPAN_LANES];
        for (h, k) in half.chunks_exact_mut(4).zip(k.chunks_exact(4)) {
            let k = f64x4::new([k[0], k[1], k[2], k[3]]);
            h.copy_from_slice(&k.fast_clamp(-f64x4::ONE, f64x4::ONE).acos().to_array());
        }
        std::array::from_fn(|r| self.span_from(model, k[r], half[r]))
    }

    /// cos of the largest longitude offset of a centre in the cap, in row `i` (> 1: none;
    /// <= -1: all).
    fn span_k(&self, model: &AlbedoModel, i: usize) -> f64 {
        if !self.cull {
            return -1.0;
        }
        // Centre at angular distance <= cap from the sub-satellite point: cos(dlon) >= k.
        let den = model.cos_lat[i] * self.cos_s;
        if den > 1e-12 {
            (self.cos_cap - model.sin_lat[i] * self.sin_s) / den
        } else {
            -1.0
        }
    }

    /// The span from `k` (see [`Cap::span_k`]) and `half` = acos(k) (the cap's margin
    /// covers the rounding of the arc cosine).
    fn span_from(&self, model: &AlbedoModel, k: f64, half: f64) -> Option<(i64, i64)> {
        let n_lon = model.n_lon as i64;
        let full = || {
            let j_s = ((self.lon_s + PI) / model.dlon_rad).floor() as i64;
            Some((j_s - n_lon / 2, j_s - n_lon / 2 + n_lon - 1))
        };
        if k > 1.0 {
            return None;
        }
        if k <= -1.0 {
            return full();
        }
        let lo = ((self.lon_s - half + PI) / model.dlon_rad - 0.5).floor() as i64;
        let hi = ((self.lon_s + half + PI) / model.dlon_rad - 0.5).ceil() as i64;
        if hi - lo + 1 >= n_lon {
            full()
        } else {
            Some((lo, hi))
        }
    }
}

/// Rows per batch of arc cosines in [`Cap::spans`]: [`TILE_ROWS`] rounded up to 4.
const SPAN_LANES: usize = TILE_ROWS.div_ceil(4) * 4;

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
