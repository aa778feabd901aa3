//! The Sun direction the photodiodes give with their stated table, attitude-free.

use nalgebra::Vector3;
use pdcal_onboard::{Calibration, EARTH_RADIUS_KM, MAX_PHOTODIODES, Options, Photodiode, Validity};

/// Fraction of a white Earth filling the view taken as the largest albedo a photodiode
/// receives (a bright cloudy Earth): only outputs above it count as lit by the Sun.
const ALBEDO_FRACTION: f64 = 0.5;

/// Per row, the Sun direction (unit, the table's frame) from the photodiode outputs
/// `outputs_v[i][k]` (photodiode `i`, row `k`) with unit normals `normals`, each
/// photodiode's scale taken as its 99th-percentile output, through the onboard core without
/// the Earth (only outputs above the largest albedo the orbit radius allows count). `None`
/// where the outputs do not give a valid direction, or beyond the core's 64 photodiodes.
pub fn photodiode_sun(
    outputs_v: &[Vec<Option<f64>>],
    normals: &[Vector3<f64>],
    noise_v: f64,
    orbit_radius_km: &[f64],
) -> Vec<Option<Vector3<f64>>> {
    let rows = orbit_radius_km.len();
    if normals.len() > MAX_PHOTODIODES || normals.len() != outputs_v.len() {
        return vec![None; rows];
    }
    let mut photodiodes = [Photodiode::cosine(1.0, [0.0, 0.0, 1.0], noise_v); MAX_PHOTODIODES];
    for ((pd, n), out) in photodiodes.iter_mut().zip(normals).zip(outputs_v) {
        *pd = Photodiode::cosine(high_output(out).unwrap_or(0.0), [n.x, n.y, n.z], noise_v);
    }
    let calibration = Calibration {
        count: normals.len(),
        photodiodes,
    };
    (0..rows)
        .map(|k| {
            let mut y = [0.0; MAX_PHOTODIODES];
            for (slot, out) in y.iter_mut().zip(outputs_v) {
                *slot = out.get(k).copied().flatten().unwrap_or(f64::NAN);
            }
            let ratio = EARTH_RADIUS_KM / orbit_radius_km[k];
            let options = Options {
                albedo_bound: ALBEDO_FRACTION * ratio * ratio,
                ..Options::default()
            };
            let e = pdcal_onboard::estimate_sun(&y, &calibration, None, &options);
            (e.validity == Validity::Valid).then(|| Vector3::from(e.sun_body))
        })
        .collect()
}

/// The 99th-percentile output, when any.
fn high_output(outputs: &[Option<f64>]) -> Option<f64> {
    let mut v: Vec<f64> = outputs
        .iter()
        .flatten()
        .copied()
        .filter(|x| x.is_finite())
        .collect();
    if v.is_empty() {
        return None;
    }
    let k = (v.len() * 99 / 100).min(v.len() - 1);
    let (_, q, _) = v.select_nth_unstable_by(k, f64::total_cmp);
    Some(*q)
}
