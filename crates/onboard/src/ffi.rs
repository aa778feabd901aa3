//! The C ABI (`f32`, for flight computers whose FPU has no double precision): the header is
//! `c/pdcal_onboard.h`, checked against these declarations by `tests/c_abi.rs`, which also
//! compiles and runs `c/replay.c` with the system C compiler.
//!
//! Every function takes possibly-null pointers and checks them; the structures are
//! `#[repr(C)]` and plain data. A null or misaligned pointer, or a count beyond the buffer,
//! gives [`Validity::InvalidInput`].
#![allow(unsafe_code)]

use crate::{
    Calibration, EarthInput, MAX_PHOTODIODES, Options, Photodiode, ReflectivityGrid, SunEstimate,
    Validity, estimate_sun,
};

/// `pdcal_calibration`: `count` photodiodes of `photodiodes`.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct PdcalCalibration {
    /// How many of `photodiodes` are in use (at most [`MAX_PHOTODIODES`]).
    pub count: u32,
    /// The photodiodes.
    pub photodiodes: [Photodiode<f32>; MAX_PHOTODIODES],
}

/// `pdcal_grid`: a reflectivity grid as [`ReflectivityGrid`] describes it.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct PdcalGrid {
    /// Rows.
    pub n_lat: u32,
    /// Columns.
    pub n_lon: u32,
    /// `n_lat * n_lon` bytes, row-major from the south pole and longitude -180 deg.
    pub cells: *const u8,
}

/// `pdcal_earth`: the Earth as [`EarthInput`] describes it.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct PdcalEarth {
    /// Unit vector toward the Earth's centre, body frame.
    pub earth_body: [f32; 3],
    /// Orbit radius, km.
    pub orbit_radius_km: f32,
    /// Non-zero when `ecef_from_body` is given.
    pub has_rotation: u32,
    /// Rotation from the body frame to the Earth-fixed frame, rows.
    pub ecef_from_body: [[f32; 3]; 3],
    /// The reflectivity grid, or null.
    pub grid: *const PdcalGrid,
}

/// `pdcal_sun_estimate`: [`SunEstimate`] with its enums as integers.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PdcalSunEstimate {
    /// Unit Sun direction, body frame.
    pub sun_body: [f32; 3],
    /// Magnitude before normalising.
    pub magnitude: f32,
    /// Covariance of the unit direction, rad^2.
    pub covariance: [[f32; 3]; 3],
    /// 1-sigma cone, rad.
    pub cone_sigma_rad: f32,
    /// Bit `i`: photodiode `i` used.
    pub used_mask: u64,
    /// Photodiodes used.
    pub n_used: u32,
    /// Normalised residual sum of squares.
    pub misfit: f32,
    /// [`Validity`] as its integer.
    pub validity: u32,
    /// [`crate::AlbedoUse`] as its integer.
    pub albedo: u32,
}

impl From<&SunEstimate<f32>> for PdcalSunEstimate {
    fn from(e: &SunEstimate<f32>) -> Self {
        PdcalSunEstimate {
            sun_body: e.sun_body,
            magnitude: e.magnitude,
            covariance: e.covariance,
            cone_sigma_rad: e.cone_sigma_rad,
            used_mask: e.used_mask,
            n_used: e.n_used,
            misfit: e.misfit,
            validity: e.validity as u32,
            albedo: e.albedo as u32,
        }
    }
}

/// A shared reference from a C pointer: `None` when null or misaligned.
///
/// # Safety
/// A non-null, aligned `p` must point to a valid `T` for the call's duration.
unsafe fn deref<'a, T>(p: *const T) -> Option<&'a T> {
    if p.is_null() || !p.is_aligned() {
        return None;
    }
    // SAFETY: non-null and aligned; the caller promises a valid T.
    Some(unsafe { &*p })
}

/// Writes the default options ([`Options::default`]) to `out` (nothing when null).
///
/// # Safety
/// `out` is null or points to writable memory for one `pdcal_options`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pdcal_default_options(out: *mut Options<f32>) {
    if out.is_null() || !out.is_aligned() {
        return;
    }
    // SAFETY: non-null, aligned, writable by the caller's promise.
    unsafe { out.write(Options::default()) };
}

/// The Sun vector from `n_outputs` photodiode outputs (V) and the calibration (see
/// [`estimate_sun`]); `earth` and `options` may be null (no albedo compensation; the
/// default options). Writes the estimate to `out` (when not null) and returns its validity.
///
/// # Safety
/// Each non-null pointer points to valid memory of its type (`outputs_v` to `n_outputs`
/// floats, a grid's `cells` to `n_lat * n_lon` bytes) for the call's duration.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pdcal_estimate_sun(
    outputs_v: *const f32,
    n_outputs: u32,
    calibration: *const PdcalCalibration,
    earth: *const PdcalEarth,
    options: *const Options<f32>,
    out: *mut PdcalSunEstimate,
) -> u32 {
    // SAFETY: forwarded from this function's contract.
    let estimate = unsafe { estimate_from_c(outputs_v, n_outputs, calibration, earth, options) };
    if !out.is_null() && out.is_aligned() {
        // SAFETY: non-null, aligned, writable by the caller's promise.
        unsafe { out.write(PdcalSunEstimate::from(&estimate)) };
    }
    estimate.validity as u32
}

/// # Safety
/// As [`pdcal_estimate_sun`].
unsafe fn estimate_from_c(
    outputs_v: *const f32,
    n_outputs: u32,
    calibration: *const PdcalCalibration,
    earth: *const PdcalEarth,
    options: *const Options<f32>,
) -> SunEstimate<f32> {
    let invalid = || estimate_invalid();
    // SAFETY: from the caller's contract.
    let Some(cal) = (unsafe { deref(calibration) }) else {
        return invalid();
    };
    let count = cal.count as usize;
    if outputs_v.is_null() || !outputs_v.is_aligned() || (n_outputs as usize) < count {
        return invalid();
    }
    // SAFETY: `outputs_v` holds `n_outputs >= count` floats by the caller's contract.
    let given = unsafe { core::slice::from_raw_parts(outputs_v, count) };
    let mut outputs = [0.0f32; MAX_PHOTODIODES];
    outputs.iter_mut().zip(given).for_each(|(o, g)| *o = *g);
    let calibration = Calibration {
        count,
        photodiodes: cal.photodiodes,
    };
    // SAFETY: from the caller's contract.
    let options = unsafe { deref(options) }.copied().unwrap_or_default();
    // SAFETY: from the caller's contract.
    let Some(earth) = (unsafe { deref(earth) }) else {
        return estimate_sun(&outputs, &calibration, None, &options);
    };
    // SAFETY: from the caller's contract.
    let grid = match unsafe { grid_from_c(earth.grid) } {
        Ok(grid) => grid,
        Err(()) => return invalid(),
    };
    let input = EarthInput {
        earth_body: earth.earth_body,
        orbit_radius_km: earth.orbit_radius_km,
        ecef_from_body: (earth.has_rotation != 0).then_some(earth.ecef_from_body),
        grid: grid.as_ref(),
    };
    estimate_sun(&outputs, &calibration, Some(&input), &options)
}

fn estimate_invalid() -> SunEstimate<f32> {
    let nothing = Calibration {
        count: MAX_PHOTODIODES.saturating_add(1),
        photodiodes: [Photodiode::cosine(1.0, [0.0, 0.0, 1.0], 0.0); MAX_PHOTODIODES],
    };
    let estimate = estimate_sun(&[0.0; MAX_PHOTODIODES], &nothing, None, &Options::default());
    debug_assert_eq!(estimate.validity, Validity::InvalidInput);
    estimate
}

/// The grid behind a C pointer: `Ok(None)` for null, `Err` when its dimensions do not hold.
///
/// # Safety
/// A non-null `grid` points to a valid `pdcal_grid` whose `cells` holds `n_lat * n_lon` bytes.
unsafe fn grid_from_c<'a>(grid: *const PdcalGrid) -> Result<Option<ReflectivityGrid<'a>>, ()> {
    // SAFETY: from the caller's contract.
    let Some(g) = (unsafe { deref(grid) }) else {
        return if grid.is_null() { Ok(None) } else { Err(()) };
    };
    let (n_lat, n_lon) = (g.n_lat as usize, g.n_lon as usize);
    let n = n_lat.checked_mul(n_lon).ok_or(())?;
    if g.cells.is_null() || n == 0 {
        return Err(());
    }
    // SAFETY: `cells` holds `n_lat * n_lon` bytes by the caller's contract.
    let cells = unsafe { core::slice::from_raw_parts(g.cells, n) };
    ReflectivityGrid::new(n_lat, n_lon, cells)
        .map(Some)
        .ok_or(())
}
