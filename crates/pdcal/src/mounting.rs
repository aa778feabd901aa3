//! The mounting and polarity check before a calibration (`pdcal_filter::mounting`): a
//! photodiode whose data contradict its nominal normal or sign is a finding, reported in
//! the warnings and `summary.json` `mounting_findings`, and calibrated from what the data
//! support.

use std::borrow::Cow;

use anyhow::{Context, Result};
use pdcal_dataset::{DatasetMeta, Telemetry};
use pdcal_filter::mounting::{MountingFinding, check_mountings};
use pdcal_filter::{FilterConfig, References};

pub use pdcal_filter::mounting::apply;

/// The findings on `meta` and `telemetry` with the filter's photodiode noise.
pub fn check(
    meta: &DatasetMeta,
    telemetry: &Telemetry,
    references: References<'_>,
    config: &FilterConfig,
    albedo: &pdcal_albedo::AlbedoModel,
) -> Result<Vec<MountingFinding>> {
    let sigmas = config.resolve(meta.noise.as_ref());
    check_mountings(
        meta,
        telemetry,
        &references,
        config,
        sigmas.photodiode_v,
        Some(albedo),
    )
    .context("mounting check")
}

/// `meta` and `telemetry` with `findings` applied ([`apply`]): borrowed as they are when
/// there are none, copied and corrected otherwise.
pub fn corrected<'a>(
    findings: &[MountingFinding],
    meta: &'a DatasetMeta,
    telemetry: &'a Telemetry,
) -> (Cow<'a, DatasetMeta>, Cow<'a, Telemetry>) {
    if findings.is_empty() {
        return (Cow::Borrowed(meta), Cow::Borrowed(telemetry));
    }
    let (mut meta, mut telemetry) = (meta.clone(), telemetry.clone());
    apply(findings, &mut meta, &mut telemetry);
    (Cow::Owned(meta), Cow::Owned(telemetry))
}
