//! The onboard core as a `no_std` C static library (see Cargo.toml).
#![no_std]

pub use pdcal_onboard::ffi::{pdcal_default_options, pdcal_estimate_sun};

unsafe extern "C" {
    /// Never defined: a call that survives optimisation fails the link.
    fn pdcal_onboard_has_a_panic_path() -> !;
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
    // SAFETY: never linked; the call exists only to fail the link if reachable.
    unsafe { pdcal_onboard_has_a_panic_path() }
}
