//! The per-step result of the cell model and the trait photodiode models use.

use nalgebra::{Matrix3, Vector3};

/// Albedo irradiance on a flat sensor, as a fraction of the 1-AU solar flux (E_a / E_AM0 of
/// paper Eqs. 13 and 15).
///
/// The full model ([`AlbedoView`]) and the onboard approximation
/// ([`crate::AlbedoExpansion`]) implement it; the photodiode crate depends only on this trait.
pub trait AlbedoIrradiance {
    /// E_a / E_AM0 on a surface with unit normal `n_gcrf`: the sum of c (n.u) over the cells
    /// with n.u >= `cos_fov` and n.u > 0 (paper Eq. 13).
    fn ratio(&self, n_gcrf: &Vector3<f64>, cos_fov: f64) -> f64;

    /// The ratio and the sum of c u over the same gated cells, which is the gradient of the
    /// ratio with respect to n (the gate held fixed); used for partial derivatives.
    fn ratio_and_vector(&self, n_gcrf: &Vector3<f64>, cos_fov: f64) -> (f64, Vector3<f64>);

    /// Ratios for many sensors: `out[k] = ratio(normals_gcrf[k], cos_fov[k])`. Implementations
    /// may do this in one pass over the cells. Extra entries of the longer slices are ignored.
    fn ratios(&self, normals_gcrf: &[Vector3<f64>], cos_fov: &[f64], out: &mut [f64]) {
        for ((n, &cf), slot) in normals_gcrf.iter().zip(cos_fov).zip(out.iter_mut()) {
            *slot = self.ratio(n, cf);
        }
    }
}

/// The lit cells seen by the satellite at one step: unit directions u from the satellite to
/// each cell and the weights c = ALB f1 f2 dA / (pi |d|^2) (AU/|r_sun|)^2, so that
/// sum c (n.u) is E_a / E_AM0.
///
/// Filled by [`crate::AlbedoModel::compute_into`]; the buffers keep their capacity, so reusing
/// one view across steps does not allocate after the first few steps. Directions are stored
/// in ECEF (normals are rotated instead, once per sensor) and grouped in small ground tiles,
/// each with a bounding cone, so that a sensor's gate is tested per tile and per cell only in
/// the tiles its gate boundary crosses. The accessors return GCRF.
#[derive(Debug, Clone, Default)]
pub struct AlbedoView {
    /// Number of cells in use; the buffers below only grow (their length is the capacity).
    len: usize,
    ux: Vec<f64>,
    uy: Vec<f64>,
    uz: Vec<f64>,
    c: Vec<f64>,
    tiles: Vec<Tile>,
    tile_start: usize,
    /// Sum of c (Basilisk's `albedoAtInstrumentMax` times (AU/|r_sun|)^2).
    total: f64,
    /// Sum of c u (ECEF): a sensor that sees every cell has ratio n . sum_cu.
    sum_cu_ecef: Vector3<f64>,
    nadir_ecef: Vector3<f64>,
    sin_rho: f64,
    gcrf_to_ecef: Matrix3<f64>,
}

/// A run of cells with a cone (axis, angular radius) holding all their directions.
#[derive(Debug, Clone, Copy)]
struct Tile {
    start: usize,
    end: usize,
    axis: Vector3<f64>,
    sin_r: f64,
    cos_r: f64,
    sum_cu: Vector3<f64>,
}

/// Where a sensor's gate cone stands against a cone of directions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Coverage {
    /// No direction can pass the gate.
    None,
    /// Every direction passes the gate.
    All,
    /// The gate boundary may cut the cone: test each cell.
    Partial,
}

/// Margin on n.u for the cone shortcuts, far above rounding, so that a shortcut never
/// changes which cells count.
const MARGIN: f64 = 1e-9;

/// Classifies the gate {t >= gate} for t = n.u over directions u within the cone (axis,
/// radius r): angle a between n and the axis, t in [cos(a + r), cos(a - r)] (clamped), times
/// |n|.
#[inline(always)]
fn classify(
    n: &Vector3<f64>,
    n_norm: f64,
    axis: &Vector3<f64>,
    sin_r: f64,
    cos_r: f64,
    gate: f64,
) -> Coverage {
    // n.axis / |n| without a division when |n| = 1 (the usual case).
    let dot = n.dot(axis);
    let cos_a = if n_norm == 1.0 { dot } else { dot / n_norm }.clamp(-1.0, 1.0);
    let sin_a = (1.0 - cos_a * cos_a).sqrt();
    let hi = if cos_a >= cos_r {
        1.0
    } else {
        cos_a * cos_r + sin_a * sin_r
    } * n_norm;
    if hi < gate - MARGIN {
        return Coverage::None;
    }
    let lo = if cos_a <= -cos_r {
        -1.0
    } else {
        cos_a * cos_r - sin_a * sin_r
    } * n_norm;
    if lo > gate + MARGIN {
        Coverage::All
    } else {
        Coverage::Partial
    }
}

/// Smallest and largest n.u over the unit vectors u within angle rho (sin rho = `sin_rho`) of
/// `nadir`, times |n|.
pub(crate) fn cone_range(n: &Vector3<f64>, nadir: &Vector3<f64>, sin_rho: f64) -> (f64, f64) {
    let n_norm = n.norm();
    let cos_a = (n.dot(nadir) / n_norm).clamp(-1.0, 1.0);
    let sin_a = (1.0 - cos_a * cos_a).sqrt();
    let cos_r = (1.0 - sin_rho * sin_rho).sqrt();
    let hi = if cos_a >= cos_r {
        1.0
    } else {
        cos_a * cos_r + sin_a * sin_rho
    };
    let lo = if cos_a <= -cos_r {
        -1.0
    } else {
        cos_a * cos_r - sin_a * sin_rho
    };
    (lo * n_norm, hi * n_norm)
}

impl AlbedoView {
    /// An empty view.
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty view with room for `cells` cells (to avoid growing in the first steps).
    pub fn with_capacity(cells: usize) -> Self {
        Self {
            ux: vec![0.0; cells],
            uy: vec![0.0; cells],
            uz: vec![0.0; cells],
            c: vec![0.0; cells],
            tiles: Vec::with_capacity(cells / 8 + 16),
            ..Self::default()
        }
    }

    pub(crate) fn begin(
        &mut self,
        gcrf_to_ecef: Matrix3<f64>,
        nadir_ecef: Vector3<f64>,
        sin_rho: f64,
    ) {
        self.len = 0;
        self.tiles.clear();
        self.tile_start = 0;
        self.total = 0.0;
        self.sum_cu_ecef = Vector3::zeros();
        self.nadir_ecef = nadir_ecef;
        self.sin_rho = sin_rho;
        self.gcrf_to_ecef = gcrf_to_ecef;
    }

    /// Makes room for `cells` more cells (grows only during warm-up).
    pub(crate) fn reserve(&mut self, cells: usize) {
        let need = self.len + cells;
        if self.c.len() < need {
            for buf in [&mut self.ux, &mut self.uy, &mut self.uz, &mut self.c] {
                buf.resize(need, 0.0);
            }
        }
    }

    /// Slots for the next `n` cells (growing the buffers during warm-up only).
    pub(crate) fn run_slots(
        &mut self,
        n: usize,
    ) -> (&mut [f64], &mut [f64], &mut [f64], &mut [f64]) {
        self.reserve(n);
        let r = self.len..self.len + n;
        (
            &mut self.ux[r.clone()],
            &mut self.uy[r.clone()],
            &mut self.uz[r.clone()],
            &mut self.c[r],
        )
    }

    /// Keeps the cells of the last `run_slots(n)` whose weight is >= 0, in order.
    pub(crate) fn commit_run(&mut self, n: usize) {
        let mut w = self.len;
        for k in self.len..self.len + n {
            if self.c[k] >= 0.0 {
                self.ux[w] = self.ux[k];
                self.uy[w] = self.uy[k];
                self.uz[w] = self.uz[k];
                self.c[w] = self.c[k];
                w += 1;
            }
        }
        self.len = w;
    }

    /// Appends a cell; room must have been made with [`AlbedoView::reserve`] (otherwise the
    /// buffers grow here).
    #[inline(always)]
    #[allow(dead_code)]
    pub(crate) fn push(&mut self, u_ecef: Vector3<f64>, c: f64) {
        let k = self.len;
        if k >= self.c.len() {
            self.reserve(1);
        }
        self.ux[k] = u_ecef.x;
        self.uy[k] = u_ecef.y;
        self.uz[k] = u_ecef.z;
        self.c[k] = c;
        self.len = k + 1;
    }

    /// Closes the tile of the cells pushed since the previous call: its bounding cone (axis =
    /// normalised mean direction, radius = largest angle to it) and its sums.
    pub(crate) fn end_tile(&mut self) {
        let (start, end) = (self.tile_start, self.len);
        if end == start {
            return;
        }
        self.tile_start = end;
        let (ux, uy, uz, c) = (
            &self.ux[start..end],
            &self.uy[start..end],
            &self.uz[start..end],
            &self.c[start..end],
        );
        let (mut mean, mut sum_cu, mut sum_c) = ([0.0; 3], [0.0; 3], 0.0);
        for k in 0..c.len() {
            mean[0] += ux[k];
            mean[1] += uy[k];
            mean[2] += uz[k];
            sum_cu[0] += c[k] * ux[k];
            sum_cu[1] += c[k] * uy[k];
            sum_cu[2] += c[k] * uz[k];
            sum_c += c[k];
        }
        let axis = Vector3::from(mean).normalize();
        let mut cos_r = 1.0f64;
        for k in 0..c.len() {
            let t = axis.x * ux[k] + axis.y * uy[k] + axis.z * uz[k];
            cos_r = if t < cos_r { t } else { cos_r };
        }
        let cos_r = cos_r.clamp(-1.0, 1.0);
        let sin_r = (1.0 - cos_r * cos_r).sqrt();
        let sum_cu = Vector3::from(sum_cu);
        self.tiles.push(Tile {
            start,
            end,
            axis,
            sin_r,
            cos_r,
            sum_cu,
        });
        self.total += sum_c;
        self.sum_cu_ecef += sum_cu;
    }

    /// Number of lit cells seen by the satellite.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when no lit cell is in view (night side, or the satellite below the surface).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Allocated room, in cells (for checking that steady-state steps do not grow it).
    pub fn capacity(&self) -> usize {
        self.c.len()
    }

    /// Unit direction from the satellite to cell `k` (GCRF) and its weight c.
    pub fn cell(&self, k: usize) -> Option<(Vector3<f64>, f64)> {
        if k >= self.len {
            return None;
        }
        let u_ecef = Vector3::new(self.ux[k], self.uy[k], self.uz[k]);
        Some((
            self.gcrf_to_ecef.tr_mul(&u_ecef).column(0).into(),
            self.c[k],
        ))
    }

    /// Sum of c over all lit cells in view: the ratio with no cosine and no gate (Basilisk's
    /// `albedoAtInstrumentMax`, scaled by (AU/|r_sun|)^2). An upper bound of every ratio.
    pub fn max_ratio(&self) -> f64 {
        self.total
    }

    /// Sum of c u over all lit cells in view (GCRF).
    pub fn sum_cu(&self) -> Vector3<f64> {
        self.gcrf_to_ecef.tr_mul(&self.sum_cu_ecef).column(0).into()
    }

    /// Unit vector from the satellite to the Earth centre (GCRF).
    pub fn nadir_gcrf(&self) -> Vector3<f64> {
        self.gcrf_to_ecef.tr_mul(&self.nadir_ecef).column(0).into()
    }

    /// sin of the Earth's angular radius rho seen from the satellite: every u is within rho
    /// of nadir.
    pub fn sin_rho(&self) -> f64 {
        self.sin_rho
    }

    /// The GCRF -> ECEF rotation given to the last `compute_into`.
    pub fn gcrf_to_ecef(&self) -> Matrix3<f64> {
        self.gcrf_to_ecef
    }

    /// The cells in ECEF as slices (ux, uy, uz, c), and the nadir (ECEF).
    pub(crate) fn cells_ecef(&self) -> ([&[f64]; 4], Vector3<f64>) {
        let n = self.len;
        (
            [&self.ux[..n], &self.uy[..n], &self.uz[..n], &self.c[..n]],
            self.nadir_ecef,
        )
    }

    /// Number of tiles (ground patches of a few cells) in the view.
    pub fn n_tiles(&self) -> usize {
        self.tiles.len()
    }

    /// Gate class of the whole view for an ECEF normal.
    fn coverage(&self, n_ecef: &Vector3<f64>, n_norm: f64, gate: f64) -> Coverage {
        if self.len == 0 || n_norm == 0.0 {
            return Coverage::None;
        }
        let cos_rho = (1.0 - self.sin_rho * self.sin_rho).sqrt();
        classify(
            n_ecef,
            n_norm,
            &self.nadir_ecef,
            self.sin_rho,
            cos_rho,
            gate,
        )
    }

    /// Sum of c t over cells lo..hi with t = n.u gated; four lanes so the loop vectorises.
    #[inline(always)]
    fn gated_sum(&self, n: &Vector3<f64>, cos_fov: f64, lo: usize, hi: usize) -> f64 {
        let (ux, uy, uz, c) = (
            &self.ux[lo..hi],
            &self.uy[lo..hi],
            &self.uz[lo..hi],
            &self.c[lo..hi],
        );
        let mut acc = [0.0f64; 4];
        let mut k = 0;
        while k + 4 <= c.len() {
            for lane in 0..4 {
                let t = n.x * ux[k + lane] + n.y * uy[k + lane] + n.z * uz[k + lane];
                let gated = t >= cos_fov && t > 0.0;
                acc[lane] += if gated { c[k + lane] * t } else { 0.0 };
            }
            k += 4;
        }
        for m in k..c.len() {
            let t = n.x * ux[m] + n.y * uy[m] + n.z * uz[m];
            if t >= cos_fov && t > 0.0 {
                acc[0] += c[m] * t;
            }
        }
        (acc[0] + acc[1]) + (acc[2] + acc[3])
    }

    /// Gated sums of c t and c u over cells lo..hi.
    fn gated_sum_vec(
        &self,
        n: &Vector3<f64>,
        cos_fov: f64,
        lo: usize,
        hi: usize,
    ) -> (f64, Vector3<f64>) {
        let mut sum = 0.0;
        let mut vec = Vector3::zeros();
        for k in lo..hi {
            let u = Vector3::new(self.ux[k], self.uy[k], self.uz[k]);
            let t = n.dot(&u);
            if t >= cos_fov && t > 0.0 {
                sum += self.c[k] * t;
                vec += self.c[k] * u;
            }
        }
        (sum, vec)
    }

    /// The ratio for an ECEF normal: tiles entirely inside the gate by their sums, tiles
    /// entirely outside skipped, the others cell by cell.
    fn ratio_ecef(&self, n: &Vector3<f64>, cos_fov: f64) -> f64 {
        let n_norm = n.norm();
        let gate = cos_fov.max(0.0);
        match self.coverage(n, n_norm, gate) {
            Coverage::None => 0.0,
            Coverage::All => n.dot(&self.sum_cu_ecef),
            Coverage::Partial => {
                let mut sum = 0.0;
                for tile in &self.tiles {
                    match classify(n, n_norm, &tile.axis, tile.sin_r, tile.cos_r, gate) {
                        Coverage::None => {}
                        Coverage::All => sum += n.dot(&tile.sum_cu),
                        Coverage::Partial => {
                            sum += self.gated_sum(n, cos_fov, tile.start, tile.end)
                        }
                    }
                }
                sum
            }
        }
    }
}

impl AlbedoIrradiance for AlbedoView {
    fn ratio(&self, n_gcrf: &Vector3<f64>, cos_fov: f64) -> f64 {
        self.ratio_ecef(&(self.gcrf_to_ecef * n_gcrf), cos_fov)
    }

    fn ratio_and_vector(&self, n_gcrf: &Vector3<f64>, cos_fov: f64) -> (f64, Vector3<f64>) {
        let n = self.gcrf_to_ecef * n_gcrf;
        let n_norm = n.norm();
        let gate = cos_fov.max(0.0);
        let (sum, vec_ecef) = match self.coverage(&n, n_norm, gate) {
            Coverage::None => (0.0, Vector3::zeros()),
            Coverage::All => (n.dot(&self.sum_cu_ecef), self.sum_cu_ecef),
            Coverage::Partial => {
                let mut sum = 0.0;
                let mut vec = Vector3::zeros();
                for tile in &self.tiles {
                    match classify(&n, n_norm, &tile.axis, tile.sin_r, tile.cos_r, gate) {
                        Coverage::None => {}
                        Coverage::All => {
                            sum += n.dot(&tile.sum_cu);
                            vec += tile.sum_cu;
                        }
                        Coverage::Partial => {
                            let (s, v) = self.gated_sum_vec(&n, cos_fov, tile.start, tile.end);
                            sum += s;
                            vec += v;
                        }
                    }
                }
                (sum, vec)
            }
        };
        (sum, self.gcrf_to_ecef.tr_mul(&vec_ecef).column(0).into())
    }

    /// All sensors in one pass over the tiles: each tile (a few cells, in L1) is classified
    /// against every sensor's gate and swept cell by cell only for the sensors whose gate
    /// boundary crosses it.
    fn ratios(&self, normals_gcrf: &[Vector3<f64>], cos_fov: &[f64], out: &mut [f64]) {
        const MAX_BATCH: usize = 32;
        let n_out = normals_gcrf.len().min(cos_fov.len()).min(out.len());
        for batch in (0..n_out).step_by(MAX_BATCH) {
            let end = (batch + MAX_BATCH).min(n_out);
            let mut n_ecef = [Vector3::zeros(); MAX_BATCH];
            let mut n_norm = [0.0; MAX_BATCH];
            let mut partial = [false; MAX_BATCH];
            let mut any_partial = false;
            for k in batch..end {
                let b = k - batch;
                n_ecef[b] = self.gcrf_to_ecef * normals_gcrf[k];
                n_norm[b] = n_ecef[b].norm();
                out[k] = match self.coverage(&n_ecef[b], n_norm[b], cos_fov[k].max(0.0)) {
                    Coverage::None => 0.0,
                    Coverage::All => n_ecef[b].dot(&self.sum_cu_ecef),
                    Coverage::Partial => {
                        partial[b] = true;
                        any_partial = true;
                        0.0
                    }
                };
            }
            if !any_partial {
                continue;
            }
            for tile in &self.tiles {
                for k in batch..end {
                    let b = k - batch;
                    if !partial[b] {
                        continue;
                    }
                    let n = &n_ecef[b];
                    let gate = cos_fov[k].max(0.0);
                    match classify(n, n_norm[b], &tile.axis, tile.sin_r, tile.cos_r, gate) {
                        Coverage::None => {}
                        Coverage::All => out[k] += n.dot(&tile.sum_cu),
                        Coverage::Partial => {
                            out[k] += self.gated_sum(n, cos_fov[k], tile.start, tile.end)
                        }
                    }
                }
            }
        }
    }
}
