//! Earth albedo irradiance on photodiodes: paper Eq. (13), Bhanderi's cell model as implemented
//! by Basilisk's `albedo` module, on the TOMS and CERES reflectivity maps.
//!
//! This crate owns:
//! - the reflectivity maps ([`ReflectivityMap`], [`MapChoice`]): the shipped TOMS mean and
//!   CERES 1x1 / 5x5 files embedded with `include_str!` and parsed into one layout;
//! - the cell geometry, precomputed once per map ([`AlbedoModel`]);
//! - the per-step list of lit cells seen by the satellite ([`AlbedoView`], filled without
//!   allocation by [`AlbedoModel::compute_into`]);
//! - the trait photodiode models use ([`AlbedoIrradiance`]) and an O(1)-per-sensor onboard
//!   approximation ([`AlbedoExpansion`]).
//!
//! It has no time or frame code: the caller gives the rotation GCRF -> ECEF.
//!
//! # Conventions
//! - Positions in km, GCRF (inertial) unless the name says `ecef`; `gcrf_to_ecef` is R with
//!   v_ecef = R v_gcrf (Basilisk's `J20002Pfix`).
//! - Results are E_a / E_AM0: the albedo irradiance as a fraction of the solar flux at 1 AU,
//!   the term C E_a / E_AM0 of paper Eq. (15) divided by C. Basilisk's raw ratio (to the flux
//!   at the Earth's distance) is multiplied by (AU/|r_sun|)^2, AU = 149597870.693 km.
//! - Map layout: row = latitude band from the south, column = longitude band from -180 deg
//!   east-positive, value = reflectivity fraction.
//! - Cells lie on a sphere of Basilisk's authalic radius R = 6371.0068 km; cell areas use the
//!   authalic latitude of the band edges (they sum to 4 pi R^2).
//!
//! # Symbols (paper Eq. 13 and Basilisk)
//! | paper / Basilisk | here | unit |
//! |---|---|---|
//! | E_a / E_AM0 | [`AlbedoIrradiance::ratio`] | - |
//! | E_c(phi_g, theta_g) / E_AM0 per cell | `c` in [`AlbedoView::cell`] | - |
//! | r_g (unit) | `u` in [`AlbedoView::cell`], satellite to cell, GCRF | - |
//! | n | `n_gcrf` | - |
//! | ALB | map value | - |
//! | f1 = r_hat . s_hat (s from the cell) | sunlit factor | - |
//! | f2 = r_hat . d_hat (d cell to satellite) | visibility factor | - |
//! | f3 = n . u, gated by f3 >= cos(fov) | sensor cosine | - |
//! | dA | cell area | km^2 |
//! | V_sun, V_sat | cells with f1 > 0, f2 > 0 | - |
//!
//! Per cell c = ALB f1 f2 dA / (pi |d|^2) (AU/|r_sun|)^2, and E_a/E_AM0 = sum c f3 over the
//! gated cells (Eq. 13).
//!
//! # Speed
//! [`AlbedoModel::compute_into`] visits only the latitude rows and the chunks of
//! [`TILE_COLS`] columns that intersect the satellite's visible cap (about 5 % of cells from
//! LEO) and computes their terms four cells at a time with `wide::f64x4` (explicit SIMD with
//! a safe API; it runs on the x86-64 baseline SSE2 and uses AVX when the build enables it),
//! over structure-of-arrays cell buffers. Cells failing Basilisk's tests keep their slot with
//! c = 0 instead of being compacted. The slots form ground tiles of [`TILE_ROWS`] x
//! [`TILE_COLS`] cells whose sums of c u and bounding cones are accumulated in the same pass.
//! [`AlbedoIrradiance::ratios`] then classifies, per sensor, four tiles at a time against
//! the sensor's gate cone without square roots (cos(theta +- r) from the cones' cosines and
//! sines): a tile wholly inside adds n . (sum c u), a tile wholly outside is skipped, and only
//! tiles the gate boundary crosses are summed cell by cell; sensors that see the whole disc or
//! none of it cost O(1), and a sensor with the same normal and field of view as an earlier
//! one reuses its result. Benchmark (17 RAX-2 normals, TOMS, 600 km, 2484 lit cells): see
//! `benches/albedo.rs`.
//! [`AlbedoModel::naive_ratios`] loops over every cell for every sensor, as open simulators
//! do, and is kept for the benchmark and as a test oracle.
//!
//! # Onboard approximation
//! [`AlbedoExpansion`] stores the angular moments of the view to degree 4 (35 numbers per
//! step, equivalent to a degree-4 spherical-harmonic expansion) and evaluates a sensor in O(1)
//! by fitting its gated cosine kernel with a polynomial on the range of n.u the Earth disc
//! spans. It is exact for sensors that see all or none of the disc. Measured against the full
//! model (`tests/integration/approx.rs`, TOMS map, 1000 random LEO geometries x normals), in units of the
//! step's maximum ratio (sum of c, about 0.3 over the sub-solar point): fov 90 deg max 2.4e-3,
//! rms 3.7e-4; fov 60 deg max 1.3e-2, rms 2.4e-3. Building the moments from a 2 x 2.5 deg
//! block-mean map (4x fewer cells) barely changes this (2.8e-3 / 1.5e-2 max). The vector
//! (gated sum of c u) is approximated less well (rms 6e-3, max 5e-2) and is not the exact
//! derivative of the approximate ratio.
//!
//! Why hand-written: no maintained crate implements Bhanderi's/Basilisk's albedo grid model;
//! the moment tensors are a few lines and avoid a spherical-harmonics dependency. The SIMD is
//! `wide` (safe, portable); LLVM's auto-vectorisation of the same loops proved unreliable
//! (runs of at most one tile width, and the compaction of lit cells, defeated it).

mod approx;
mod error;
mod geometry;
mod lanes;
mod map;
mod model;
mod tile;
mod view;

pub use approx::{AlbedoExpansion, DEGREE};
pub use error::AlbedoError;
pub use geometry::{AU_KM, REQ_EARTH_KM, RP_EARTH_KM, authalic_latitude, authalic_radius_km};
pub use map::{DEFAULT_UNIFORM_ALBEDO, MapChoice, MapError, ReflectivityMap};
pub use model::{AlbedoModel, CellAreas};
pub use tile::{TILE_COLS, TILE_ROWS};
pub use view::{AlbedoIrradiance, AlbedoView, LinearAlbedo};
