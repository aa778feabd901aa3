//! Ephemeris for pdcal: time, orbit, Sun, magnetic field and eclipse, all in GCRF.
//!
//! This crate owns every *reference* quantity the attitude filter compares its sensors
//! against: where the spacecraft is, where the Sun is, what the geomagnetic field is, and
//! how much of the Sun is visible. It does no file I/O; callers hand it text (TLE lines, ISO
//! times) or samples.
//!
//! | module | what |
//! |---|---|
//! | [`time`] | UTC epochs with leap seconds (`hifitime`), ISO 8601 parsing, `t_s` offsets |
//! | [`frames`] | GCRF ⇄ ITRF and TEME → GCRF rotations (IAU-76/80 chain) |
//! | [`orbit`] | [`OrbitSource`] trait, [`OrbitState`], [`TleOrbit`] (SGP4) |
//! | [`columns`] | [`PositionColumns`]: the dataset's `r_*_km` columns, interpolated |
//! | [`sun`] | [`SunEphemeris`] trait, [`LowPrecisionSun`] |
//! | [`igrf`] | IGRF-14 field synthesis, returned in GCRF |
//! | [`eclipse`] | illuminated fraction of the solar disc (conical shadow, penumbra) |
//! | [`tle`] | TLE checksum arithmetic |
//! | [`reference`] | [`ReferenceModel`]: position, Sun, field, eclipse and Earth rotation at one `t_s` |
//!
//! # Traits
//! - [`OrbitSource`]: `state_gcrf(t) -> Result<OrbitState, OrbitError>` (position km and
//!   velocity km/s in GCRF). Implemented by [`TleOrbit`] and [`PositionColumns`]; a SPICE
//!   kernel or a numerical propagator would be a third implementation.
//! - [`SunEphemeris`]: `sun_gcrf_km(t) -> Vector3` (geocentric, astrometric). Implemented by
//!   [`LowPrecisionSun`]; a JPL ephemeris would plug in here.
//!
//! # Conventions
//! - **One inertial frame: GCRF** (ICRS axes, Earth-centred). Every vector this crate returns
//!   is in GCRF unless its name says otherwise (`_teme`, `_ecef`).
//! - Epochs are `hifitime::Epoch`, labelled in UTC. `t_s` counts elapsed SI seconds, so a span
//!   containing a leap second is one second longer than its UTC labels suggest.
//! - Units in names: `_km`, `_km_s`, `_nt`, `_rad`, `_deg` (degrees only at I/O edges).
//! - A rotation matrix `R` named `a_to_b` maps components: `v_b = R v_a`. `Rk(a)` are frame
//!   rotations (the vector stays, the axes turn by `a`).
//!
//! # Frames: which quantity, which frame, how it reaches GCRF
//! | quantity | native frame | into GCRF |
//! |---|---|---|
//! | position from a TLE | TEME (SGP4 output) | [`frames::teme_to_gcrf`] = Bᵀ Pᵀ Nᵀ R3(GMST82 − GAST); velocity rotated the same way (TEME taken as quasi-inertial) |
//! | position from dataset columns | GCRF (dataset-format) | none; interpolated as given |
//! | Sun (Almanac series) | mean equator and equinox of date | Bᵀ Pᵀ: IAU-76 precession to J2000, then frame bias |
//! | magnetic field (IGRF) | ITRF (Earth-fixed) | [`frames::gcrf_to_itrf`]ᵀ; the GCRF position goes in through the same matrix |
//! | eclipse fraction | frame-free | uses the GCRF satellite and Sun positions |
//!
//! Here B is the IERS 2003 frame bias, P IAU-76 precession (Lieske), N IAU-1980 nutation,
//! GAST = GMST82 + equation of the equinoxes (with the 1994 terms), and
//! `gcrf_to_itrf = R3(GAST) N P B` with polar motion ignored.
//!
//! # Approximations and their measured size
//! Measured against `fixtures/reference` (skyfield's IAU 2006/2000A chain with true UT1,
//! DE421, python-sgp4); the tests under `tests/` hold the numbers.
//! - **UT1 = UTC**: |UT1 − UTC| < 0.9 s rotates the Earth-fixed frame by ≤ 0.004°. On
//!   `igrf_frames.csv` (|UT1 − UTC| ≤ 0.36 s) the GCRF direction of the position and of B is
//!   off by ≤ 0.0015°; fed the true UT1, the rest of the chain is within 9.2e-6° (0.033″).
//! - **Polar motion ignored**: ≤ 0.5″ (0.00014°).
//! - **IAU-76/80 instead of IAU 2006/2000A, nutation truncated to 35 of 106 terms**: dropped
//!   terms ≤ 0.019″ in Δψ (≤ 0.7 m at LEO radius). TEME → GCRF for the RAX-2 TLE: 0.68 m and
//!   0.75 mm/s from skyfield over 2 h (acceptance 50 m).
//! - **SGP4** (the `sgp4` crate, WGS-72, improved mode): Vallado's verification set to
//!   4.2e-6 km and 1.9e-9 km/s; the RAX-2 TLE in TEME to 2.2e-5 m. The crate does not flag
//!   decay, so this crate adds Vallado's code 6 (radius below one Earth radius).
//! - **Sun**: Almanac low-precision series, aberration removed, precessed to J2000: ≤ 0.0068°
//!   in direction and ≤ 0.0070 % in distance from DE421 over 2000-2035.
//! - **Position columns**: cubic Hermite with 5-point Lagrange node velocities: 7e-9 km at
//!   1 s sampling, 3e-7 km at 10 s, on an SGP4 orbit.
//!
//! # Why parts are hand-written
//! - **Precession, nutation, sidereal time**: the Rust crates that offer them did not fit:
//!   `siderust` is AGPL-3.0 (this workspace is MIT/Apache-2.0), `celestial-time` is a 0.1
//!   alpha, `rfa` is LGPL and binds the ERFA C library, and ANISE needs orientation data files
//!   at run time. The IAU-76/80 chain is ~150 lines of published constants, tested against
//!   skyfield.
//! - **Low-precision Sun**: a dozen lines from the Astronomical Almanac; an ephemeris crate
//!   would need a JPL kernel file, which the library may not read.
//! - **ISO 8601 parsing and TAI − UTC**: hifitime 4.3 parses many formats but not strictly
//!   `...Z` UTC with clear errors, folds `23:59:60` onto `23:59:59`, and its TAI → UTC
//!   conversion is one second off in the last 37 s before a leap second; [`time`] works
//!   around all three (use [`time::jd_utc`] and [`time::format_utc`], not hifitime's UTC
//!   getters, on epochs near a leap second).
//! - IGRF and eclipse explain their own choices in their module docs.

pub mod columns;
pub mod eclipse;
pub mod frames;
pub mod igrf;
pub mod orbit;
pub mod reference;
pub mod sun;
pub mod time;
pub mod tle;

pub use columns::PositionColumns;
pub use orbit::{OrbitError, OrbitSource, OrbitState, TemeState, TleLine, TleOrbit};
pub use reference::{Reference, ReferenceError, ReferenceModel};
pub use sun::{LowPrecisionSun, SunEphemeris, sun_distance_factor};
pub use time::TimeError;
