//! The per-step result of the cell model and the trait photodiode models use.

use nalgebra::{Matrix3, Vector3};
use wide::bytemuck::cast_slice;
use wide::f64x4;

use crate::tile::TileAcc;

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

    /// [`AlbedoIrradiance::ratio_and_vector`] for many sensors, the same way as
    /// [`AlbedoIrradiance::ratios`]. Independent evaluations in one call: an implementation
    /// (or the CPU, overlapping them) need not wait for one to finish before the next.
    fn ratios_and_vectors(
        &self,
        normals_gcrf: &[Vector3<f64>],
        cos_fov: &[f64],
        out: &mut [(f64, Vector3<f64>)],
    ) {
        for ((n, &cf), slot) in normals_gcrf.iter().zip(cos_fov).zip(out.iter_mut()) {
            *slot = self.ratio_and_vector(n, cf);
        }
    }
}

/// One sensor's albedo linearised about a normal `n0_gcrf`: `ratio(n) = ratio0 + v . (n -
/// n0)` with `v` the gradient there ([`AlbedoIrradiance::ratio_and_vector`]), the gate held
/// as it was at `n0` (its `cos_fov` argument is ignored).
///
/// A filter evaluates the albedo once per step at the prior attitude and normals, in one
/// batch, and uses this inside the step's sequential updates, where the attitude moves by
/// the updates' small corrections only. For the Lambertian sum the ratio is linear in `n`
/// while no cell crosses the sensor's gate; cells crossing it change the sum by at most
/// `c |n.u|` each: measured, 5.7e-6 of the full-disc sum for a 1e-3 rad turn and 3.8e-7 for
/// 1e-4 rad (test `linearised_albedo_follows_the_full_model`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LinearAlbedo {
    /// Normal of the linearisation, GCRF.
    pub n0_gcrf: Vector3<f64>,
    /// Ratio at `n0_gcrf`.
    pub ratio0: f64,
    /// Gradient of the ratio with respect to the normal at `n0_gcrf`, GCRF.
    pub vector_gcrf: Vector3<f64>,
}

impl AlbedoIrradiance for LinearAlbedo {
    fn ratio(&self, n_gcrf: &Vector3<f64>, _cos_fov: f64) -> f64 {
        self.ratio0 + self.vector_gcrf.dot(&(n_gcrf - self.n0_gcrf))
    }

    fn ratio_and_vector(&self, n_gcrf: &Vector3<f64>, cos_fov: f64) -> (f64, Vector3<f64>) {
        (self.ratio(n_gcrf, cos_fov), self.vector_gcrf)
    }
}

/// The lit cells seen by the satellite at one step: unit directions u from the satellite to
/// each cell and the weights c = ALB f1 f2 dA / (pi |d|^2) (AU/|r_sun|)^2, so that
/// sum c (n.u) is E_a / E_AM0.
///
/// Filled by [`crate::AlbedoModel::compute_into`]; the buffers keep their capacity, so reusing
/// one view across steps does not allocate after the first few steps. Cells are stored as
/// structure of arrays in f64x4 lanes, in ECEF (normals are rotated instead, once per
/// sensor), and grouped in ground tiles, each with its sum of c u and a bounding cone, so
/// that a sensor's gate is tested per tile and per cell only in the tiles its gate boundary
/// crosses. Visited cells that fail Basilisk's tests (and row padding) keep a slot with
/// c = 0: see [`AlbedoView::n_slots`]. The accessors return GCRF.
#[derive(Debug, Clone, Default)]
pub struct AlbedoView {
    /// Cell slots in use, in f64x4 vectors of 4 slots; the buffers below only grow (their
    /// length is the capacity). Slots of cells that fail Basilisk's tests have c = 0.
    n_vec: usize,
    ux: Vec<f64x4>,
    uy: Vec<f64x4>,
    uz: Vec<f64x4>,
    c: Vec<f64x4>,
    tiles: Tiles,
    /// Scratch: the tile accumulators of the row group being filled.
    accs: Vec<TileAcc>,
    /// Sum of c u (ECEF): a sensor that sees every cell has ratio n . sum_cu.
    sum_cu_ecef: Vector3<f64>,
    nadir_ecef: Vector3<f64>,
    sin_rho: f64,
    gcrf_to_ecef: Matrix3<f64>,
}

/// Tiles, structure of arrays: each a run `start..end` of cell vectors with a cone (axis,
/// angular radius r) holding the directions of its cells, and its sum of c u. Filled as
/// scalars in `staged` (8 per tile) and repacked by [`Tiles::finish`] into f64x4 lanes
/// (tile k in lane k % 4 of vector k / 4; the unused lanes of the last vector are zero).
#[derive(Debug, Clone, Default)]
struct Tiles {
    len: usize,
    start: Vec<u32>,
    end: Vec<u32>,
    staged: Vec<[f64; 8]>,
    ax: Vec<f64x4>,
    ay: Vec<f64x4>,
    az: Vec<f64x4>,
    cos_r: Vec<f64x4>,
    sin_r: Vec<f64x4>,
    sx: Vec<f64x4>,
    sy: Vec<f64x4>,
    sz: Vec<f64x4>,
}

impl Tiles {
    fn lanes(&mut self) -> [&mut Vec<f64x4>; 8] {
        [
            &mut self.ax,
            &mut self.ay,
            &mut self.az,
            &mut self.cos_r,
            &mut self.sin_r,
            &mut self.sx,
            &mut self.sy,
            &mut self.sz,
        ]
    }

    fn clear(&mut self) {
        self.len = 0;
        self.start.clear();
        self.end.clear();
        self.staged.clear();
        for v in self.lanes() {
            v.clear();
        }
    }

    fn push(
        &mut self,
        range: (usize, usize),
        axis: Vector3<f64>,
        cos_r: f64,
        sum_cu: Vector3<f64>,
    ) {
        self.len += 1;
        // Cell vector indices fit in u32: a map has far fewer than 2^32 cells.
        self.start.push(range.0 as u32);
        self.end.push(range.1 as u32);
        let sin_r = (1.0 - cos_r * cos_r).sqrt();
        self.staged.push([
            axis.x, axis.y, axis.z, cos_r, sin_r, sum_cu.x, sum_cu.y, sum_cu.z,
        ]);
    }

    /// Repacks the staged tiles into f64x4 lanes.
    fn finish(&mut self) {
        let staged = std::mem::take(&mut self.staged);
        for group in staged.chunks(4) {
            for (field, v) in self.lanes().into_iter().enumerate() {
                let lanes = std::array::from_fn(|l| group.get(l).map_or(0.0, |t| t[field]));
                v.push(f64x4::new(lanes));
            }
        }
        self.staged = staged;
    }
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

/// Margin on cosines for the cone shortcuts, far above rounding, so that a shortcut never
/// changes which cells count.
const MARGIN: f64 = 1e-9;

/// A sensor's gate {n.u >= cos_fov and n.u > 0} as a cone about its unit normal:
/// n_hat.u >= cos(theta) = max(cos_fov, 0)/|n| (u is a unit vector).
#[derive(Debug, Clone, Copy)]
struct Gate {
    n_hat: Vector3<f64>,
    cos_t: f64,
    sin_t: f64,
    /// The per-cell test as one comparison: n.u >= max(cos_fov, smallest positive f64)
    /// is n.u >= cos_fov and n.u > 0.
    threshold: f64,
}

impl Gate {
    /// `None` when no direction can pass (zero normal, or gate/|n| > 1 + margin).
    fn new(n: &Vector3<f64>, cos_fov: f64) -> Option<Self> {
        let n_norm = n.norm();
        let cos_t = cos_fov.max(0.0) / n_norm;
        if n_norm == 0.0 || cos_t > 1.0 + MARGIN {
            return None;
        }
        // Clamped to 1 (theta = 0) the shortcuts can only get more conservative.
        let cos_t = cos_t.min(1.0);
        Some(Self {
            n_hat: n / n_norm,
            cos_t,
            sin_t: (1.0 - cos_t * cos_t).sqrt(),
            threshold: cos_fov.max(f64::from_bits(1)),
        })
    }

    /// Class of the cone of directions within angle r of `axis`: with a the angle between
    /// n_hat and the axis, every direction passes when a + r <= theta, i.e.
    /// cos a >= cos(theta - r) (needs r <= theta), and none when a - r > theta, i.e.
    /// cos a < cos(theta + r) (needs theta + r < pi). No square root.
    fn classify(&self, axis: &Vector3<f64>, cos_r: f64, sin_r: f64) -> Coverage {
        let cos_a = self.n_hat.dot(axis);
        let (pc, ps) = (self.cos_t * cos_r, self.sin_t * sin_r);
        if cos_r >= self.cos_t && cos_a >= pc + ps + MARGIN {
            Coverage::All
        } else if cos_r > -self.cos_t && cos_a < pc - ps - MARGIN {
            Coverage::None
        } else {
            Coverage::Partial
        }
    }
}

/// Smallest and largest n.u over the unit vectors u within angle rho (sin rho = `sin_rho`) of
/// `nadir`, times |n| (the reference of the expansion's own, faster form).
#[cfg(test)]
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

    /// An empty view with room for `cells` cell slots (to avoid growing in the first steps).
    pub fn with_capacity(cells: usize) -> Self {
        let n = cells.div_ceil(4);
        Self {
            ux: vec![f64x4::ZERO; n],
            uy: vec![f64x4::ZERO; n],
            uz: vec![f64x4::ZERO; n],
            c: vec![f64x4::ZERO; n],
            ..Self::default()
        }
    }

    /// Starts a step.
    pub(crate) fn begin(
        &mut self,
        gcrf_to_ecef: Matrix3<f64>,
        nadir_ecef: Vector3<f64>,
        sin_rho: f64,
    ) {
        self.n_vec = 0;
        self.tiles.clear();
        self.sum_cu_ecef = Vector3::zeros();
        self.nadir_ecef = nadir_ecef;
        self.sin_rho = sin_rho;
        self.gcrf_to_ecef = gcrf_to_ecef;
    }

    /// Ends a step.
    pub(crate) fn finish(&mut self) {
        self.tiles.finish();
    }

    /// The (cleared) tile accumulators of the next row group, to be filled in tile order.
    pub(crate) fn group_accs(&mut self) -> &mut Vec<TileAcc> {
        self.accs.clear();
        &mut self.accs
    }

    /// The next `n` cell vectors (ux, uy, uz, c), growing the buffers during warm-up only,
    /// and the group's tile accumulators; [`AlbedoView::end_group`] takes them.
    #[inline(always)]
    pub(crate) fn group_slots(&mut self, n: usize) -> ([&mut [f64x4]; 4], &mut [TileAcc]) {
        let r = self.n_vec..self.n_vec + n;
        if self.c.len() < r.end {
            for buf in [&mut self.ux, &mut self.uy, &mut self.uz, &mut self.c] {
                buf.resize(r.end, f64x4::ZERO);
            }
        }
        (
            [
                &mut self.ux[r.clone()],
                &mut self.uy[r.clone()],
                &mut self.uz[r.clone()],
                &mut self.c[r],
            ],
            &mut self.accs,
        )
    }

    /// Takes the group's `n` cell vectors and closes its tiles: sums and cones (axis,
    /// smallest axis . u) from the accumulators. A tile with no weight (night, or no cell
    /// passing the tests) gets no tile entry; its slots stay, with c = 0.
    pub(crate) fn end_group(&mut self, n: usize) {
        let base = self.n_vec;
        self.n_vec += n;
        for acc in &self.accs {
            let sum_cu = Vector3::new(
                acc.cu[0].reduce_add(),
                acc.cu[1].reduce_add(),
                acc.cu[2].reduce_add(),
            );
            // All c = 0 exactly when the sum is zero (c >= 0 and the u of a tile are within
            // 90 deg of each other).
            if acc.cursor == acc.start || sum_cu == Vector3::zeros() || sum_cu.x.is_nan() {
                continue;
            }
            let cos_r = acc.min_t.to_array().into_iter().fold(1.0f64, f64::min);
            self.tiles.push(
                (base + acc.start, base + acc.cursor),
                acc.axis_ecef,
                cos_r.clamp(-1.0, 1.0),
                sum_cu,
            );
            self.sum_cu_ecef += sum_cu;
        }
    }

    /// Number of lit cells seen by the satellite with a nonzero weight c (cells of zero
    /// reflectivity are not counted). O(cells): counted on demand, not per step.
    pub fn len(&self) -> usize {
        cast_slice::<f64x4, f64>(&self.c[..self.n_vec])
            .iter()
            .filter(|&&c| c > 0.0)
            .count()
    }

    /// True when no lit cell is in view (night side, or the satellite below the surface).
    pub fn is_empty(&self) -> bool {
        // Tiles are kept only when they hold a cell with c > 0.
        self.tiles.len == 0
    }

    /// Number of stored cell slots: the lit cells seen, plus cells of the same ground tiles
    /// that fail Basilisk's tests (or pad a row), stored with weight c = 0: keeping them is
    /// cheaper than compacting, and they add nothing to any sum.
    pub fn n_slots(&self) -> usize {
        self.n_vec * 4
    }

    /// Allocated room, in cell slots (for checking that steady-state steps do not grow it).
    pub fn capacity(&self) -> usize {
        self.c.len() * 4
    }

    /// Unit direction from the satellite to the cell in slot `k < n_slots()` (GCRF) and its
    /// weight c (0 for a slot whose cell is not lit, not seen, or padding).
    pub fn cell(&self, k: usize) -> Option<(Vector3<f64>, f64)> {
        if k >= self.n_slots() {
            return None;
        }
        let lane = |v: &[f64x4]| cast_slice::<f64x4, f64>(v)[k];
        let u_ecef = Vector3::new(lane(&self.ux), lane(&self.uy), lane(&self.uz));
        Some((
            self.gcrf_to_ecef.tr_mul(&u_ecef).column(0).into(),
            lane(&self.c),
        ))
    }

    /// Sum of c over all lit cells in view: the ratio with no cosine and no gate (Basilisk's
    /// `albedoAtInstrumentMax`, scaled by (AU/|r_sun|)^2). An upper bound of every ratio.
    ///
    /// O(cells): summed on demand, not per step.
    pub fn max_ratio(&self) -> f64 {
        self.c[..self.n_vec]
            .iter()
            .fold(f64x4::ZERO, |acc, &c| acc + c)
            .reduce_add()
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

    /// The cell slots in ECEF as slices (ux, uy, uz, c), and the nadir (ECEF).
    pub(crate) fn cells_ecef(&self) -> ([&[f64]; 4], Vector3<f64>) {
        let n = self.n_vec;
        fn f(v: &[f64x4]) -> &[f64] {
            cast_slice(v)
        }
        (
            [
                f(&self.ux[..n]),
                f(&self.uy[..n]),
                f(&self.uz[..n]),
                f(&self.c[..n]),
            ],
            self.nadir_ecef,
        )
    }

    /// Number of tiles (ground patches of a few cells) in the view.
    pub fn n_tiles(&self) -> usize {
        self.tiles.len
    }

    /// The sensor's gate and its class against the whole view (the Earth disc cone).
    fn coverage(&self, n_ecef: &Vector3<f64>, cos_fov: f64) -> Option<(Gate, Coverage)> {
        if self.tiles.len == 0 {
            return None;
        }
        let gate = Gate::new(n_ecef, cos_fov)?;
        let cos_rho = (1.0 - self.sin_rho * self.sin_rho).sqrt();
        let class = gate.classify(&self.nadir_ecef, cos_rho, self.sin_rho);
        Some((gate, class))
    }

    /// Gated sums of c t (t = n.u) and, when `VEC`, of c u, for an ECEF normal whose gate
    /// cuts the view: a pass over the tiles four at a time (inside the gate: the tile's
    /// sums; outside: nothing; crossed: its cells four at a time).
    #[inline(always)]
    fn tiles_sum<const VEC: bool>(&self, n: &Vector3<f64>, gate: &Gate) -> (f64, Vector3<f64>) {
        let v = f64x4::splat;
        let t = &self.tiles;
        let (gx, gy, gz) = (v(gate.n_hat.x), v(gate.n_hat.y), v(gate.n_hat.z));
        let (nx, ny, nz) = (v(n.x), v(n.y), v(n.z));
        let (cos_t, sin_t, neg_cos_t) = (v(gate.cos_t), v(gate.sin_t), v(-gate.cos_t));
        let margin = v(MARGIN);
        let threshold = v(gate.threshold);
        let mut sum = f64x4::ZERO;
        let mut sums = [f64x4::ZERO; 2];
        let mut vec = [f64x4::ZERO; 3];
        let fields =
            t.ax.iter()
                .zip(&t.ay)
                .zip(&t.az)
                .zip(&t.cos_r)
                .zip(&t.sin_r);
        let sums_cu = t.sx.iter().zip(&t.sy).zip(&t.sz);
        for (q, (((((&ax, &ay), &az), &cos_r), &sin_r), ((&sx, &sy), &sz))) in
            fields.zip(sums_cu).enumerate()
        {
            let cos_a = gx.mul_add(ax, gy.mul_add(ay, gz * az));
            let (pc, ps) = (cos_t * cos_r, sin_t * sin_r);
            // See `Gate::classify`.
            let all = cos_r.simd_ge(cos_t) & (cos_a - margin).simd_ge(pc + ps);
            let none = cos_r.simd_gt(neg_cos_t) & (cos_a + margin).simd_lt(pc - ps);
            sum += all & nx.mul_add(sx, ny.mul_add(sy, nz * sz));
            if VEC {
                vec[0] += all & sx;
                vec[1] += all & sy;
                vec[2] += all & sz;
            }
            let mut crossed = (all | none).to_bitmask() ^ 0b1111;
            while crossed != 0 {
                let k = q * 4 + crossed.trailing_zeros() as usize;
                crossed &= crossed - 1;
                if k >= t.len {
                    break;
                }
                let cells = t.start[k] as usize..t.end[k] as usize;
                let (xs, ys) = (&self.ux[cells.clone()], &self.uy[cells.clone()]);
                let (zs, cs) = (&self.uz[cells.clone()], &self.c[cells]);
                let n = cs.len().min(xs.len()).min(ys.len()).min(zs.len());
                // Gated c t of cell vector m and its mask-weighted c.
                let term = |m: usize| {
                    let tm = nx.mul_add(xs[m], ny.mul_add(ys[m], nz * zs[m]));
                    (tm, tm.simd_ge(threshold) & cs[m])
                };
                // Two vectors a step into two accumulators: halves the add latency chain.
                let mut m = 0;
                while m + 2 <= n {
                    let ((t0, c0), (t1, c1)) = (term(m), term(m + 1));
                    sums[0] = c0.mul_add(t0, sums[0]);
                    sums[1] = c1.mul_add(t1, sums[1]);
                    if VEC {
                        vec[0] = c0.mul_add(xs[m], c1.mul_add(xs[m + 1], vec[0]));
                        vec[1] = c0.mul_add(ys[m], c1.mul_add(ys[m + 1], vec[1]));
                        vec[2] = c0.mul_add(zs[m], c1.mul_add(zs[m + 1], vec[2]));
                    }
                    m += 2;
                }
                if m < n {
                    let (t0, c0) = term(m);
                    sums[0] = c0.mul_add(t0, sums[0]);
                    if VEC {
                        vec[0] = c0.mul_add(xs[m], vec[0]);
                        vec[1] = c0.mul_add(ys[m], vec[1]);
                        vec[2] = c0.mul_add(zs[m], vec[2]);
                    }
                }
            }
        }
        let sum = sum + sums[0] + sums[1];
        let vec = Vector3::new(
            vec[0].reduce_add(),
            vec[1].reduce_add(),
            vec[2].reduce_add(),
        );
        (sum.reduce_add(), vec)
    }

    /// The ratio and gated sum of c u for an ECEF normal.
    #[inline(always)]
    fn gated_ecef<const VEC: bool>(&self, n: &Vector3<f64>, cos_fov: f64) -> (f64, Vector3<f64>) {
        match self.coverage(n, cos_fov) {
            Some((gate, Coverage::Partial)) => self.tiles_sum::<VEC>(n, &gate),
            Some((_, Coverage::All)) => (n.dot(&self.sum_cu_ecef), self.sum_cu_ecef),
            _ => (0.0, Vector3::zeros()),
        }
    }
}

impl AlbedoIrradiance for AlbedoView {
    fn ratio(&self, n_gcrf: &Vector3<f64>, cos_fov: f64) -> f64 {
        self.gated_ecef::<false>(&(self.gcrf_to_ecef * n_gcrf), cos_fov)
            .0
    }

    fn ratio_and_vector(&self, n_gcrf: &Vector3<f64>, cos_fov: f64) -> (f64, Vector3<f64>) {
        let (sum, vec_ecef) = self.gated_ecef::<true>(&(self.gcrf_to_ecef * n_gcrf), cos_fov);
        (sum, self.gcrf_to_ecef.tr_mul(&vec_ecef).column(0).into())
    }

    /// All sensors: each costs O(1) when its gate takes all or none of the Earth disc, else
    /// one pass over the tiles plus the cells of the tiles its gate boundary crosses. A
    /// sensor identical to an earlier one (same normal and gate, as redundant photodiodes on
    /// one face) reuses its result.
    fn ratios(&self, normals_gcrf: &[Vector3<f64>], cos_fov: &[f64], out: &mut [f64]) {
        let n_out = normals_gcrf.len().min(cos_fov.len()).min(out.len());
        for k in 0..n_out {
            let twin =
                (0..k).find(|&m| normals_gcrf[m] == normals_gcrf[k] && cos_fov[m] == cos_fov[k]);
            out[k] = match twin {
                Some(m) => out[m],
                None => self.ratio(&normals_gcrf[k], cos_fov[k]),
            };
        }
    }
}
