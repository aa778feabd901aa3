//! Outlier screening of the telemetry before the filter runs, and the bounded record of
//! every sample the run rejected (screened here or gated in the filter), per sensor.
//!
//! The innovation gate (`FilterConfig::gate_sigmas`) catches a wild sample only where the
//! filter uses it, and only after it has done harm elsewhere: the initial scales are the
//! maximum output of each photodiode (paper IV.B), the initial attitude comes from one
//! sample, and a gyro sample is integrated into the attitude without any test. So each
//! sensor's samples are first compared with their neighbours in time: a cell is rejected
//! (made empty, as if not sampled, and counted) when it is not finite or lies outside the
//! range of its neighbours by more than a tolerance. A rejected gyro sample between two good
//! ones is bridged by their interpolation ([`remove_outliers`]); otherwise the filter holds
//! the last good rate over it.
//!
//! The test, per scalar column (a vector sensor is rejected when any axis is): take up to
//! two sampled neighbours on each side within [`WINDOW`] rows; each side proposes its
//! nearest sample and, with two, the line through them extrapolated to the sample's time;
//! the cell is rejected when it lies outside the range of these candidates widened by
//! `tol`. The extrapolations admit a genuine sample on a steep slope, at a smooth extremum
//! (both lines overshoot it) and at a kink (a photodiode's output where the eclipse exit
//! ramp meets the cosine's decline: one side's line reaches it). `tol = outlier_sigmas *
//! sigma` (the sensor's noise) plus, for the gyro, the plausible angular acceleration times
//! the largest time to a neighbour, and for the magnetometer and the photodiodes what the
//! rotation the gyro measures turns the signal by between the neighbours and a line does
//! not follow (`turn_allowance`): rows seconds apart on a tumbling spacecraft are not a
//! smooth signal's samples. A sample with fewer than two neighbours within
//! [`NEIGHBOUR_REACH_S`] is not judged.
//! A wild neighbour widens the range, so a burst of wild samples hides each one: a value
//! farther from the column's median than [`ABSURD_FACTOR`] times (the column's robust
//! spread plus `tol`) is rejected whatever its neighbours, as is a non-finite one. Smaller
//! errors are left to the innovation gate.

use pdcal_dataset::Telemetry;

use crate::bounded::Bounded;
use crate::config::{FilterConfig, SensorSigmas};
use crate::filter::Sensor;

/// Rows searched on each side of a sample for its neighbours.
pub const WINDOW: usize = 4;

/// Neighbours farther than this from a sample in time do not judge it, s: the test
/// assumes the signal is smooth between them, which a tumbling spacecraft's body-frame
/// field and Sun outputs are over a few seconds, not over the tens of seconds between
/// flight frames or across a gap (there only the absurd-value test and the filter's
/// innovation gate act).
pub const NEIGHBOUR_REACH_S: f64 = 10.0;

/// A sensor as the rejection record names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Channel {
    /// Rate gyro (all three axes).
    Gyro,
    /// Magnetometer (all three axes).
    Magnetometer,
    /// Photodiode, zero-based index.
    Photodiode(usize),
}

impl Channel {
    /// The name used in telemetry.csv's header: `gyro`, `mag`, `pd03`.
    pub fn name(self) -> String {
        match self {
            Channel::Gyro => "gyro".to_owned(),
            Channel::Magnetometer => "mag".to_owned(),
            Channel::Photodiode(i) => format!("pd{:02}", i + 1),
        }
    }
}

impl From<Sensor> for Channel {
    fn from(sensor: Sensor) -> Self {
        match sensor {
            Sensor::Photodiode(i) => Channel::Photodiode(i),
            Sensor::Magnetometer(_) => Channel::Magnetometer,
        }
    }
}

/// Telemetry rows (increasing), counted, the first
/// [`LISTED_ROWS`](crate::bounded::LISTED_ROWS) listed.
pub type RowList = Bounded<usize>;

/// One sensor's rejected samples.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelRejections {
    /// The sensor.
    pub channel: Channel,
    /// Samples rejected by the screening against their neighbours (never reach the filter).
    pub screened: RowList,
    /// Samples the filter's innovation gate rejected (a magnetometer row counts once).
    pub gated: RowList,
}

/// Every sample a run rejected, per sensor: gyro, magnetometer, then the photodiodes.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Rejections {
    /// One entry per sensor.
    pub channels: Vec<ChannelRejections>,
}

impl Rejections {
    /// Empty lists for a gyro, a magnetometer and `photodiodes` photodiodes.
    pub fn new(photodiodes: usize) -> Self {
        let channels = [Channel::Gyro, Channel::Magnetometer]
            .into_iter()
            .chain((0..photodiodes).map(Channel::Photodiode))
            .map(|channel| ChannelRejections {
                channel,
                screened: RowList::default(),
                gated: RowList::default(),
            })
            .collect();
        Rejections { channels }
    }

    /// The entry of `channel`, if the record has one.
    pub fn get(&self, channel: Channel) -> Option<&ChannelRejections> {
        self.channels.iter().find(|c| c.channel == channel)
    }

    fn get_mut(&mut self, channel: Channel) -> Option<&mut ChannelRejections> {
        self.channels.iter_mut().find(|c| c.channel == channel)
    }

    /// Records a screened sample.
    pub fn push_screened(&mut self, channel: Channel, row: usize) {
        if let Some(c) = self.get_mut(channel) {
            c.screened.push(row);
        }
    }

    /// Records a gated sample.
    pub fn push_gated(&mut self, channel: Channel, row: usize) {
        if let Some(c) = self.get_mut(channel) {
            c.gated.push(row);
        }
    }

    /// Screened samples over all sensors.
    pub fn screened_total(&self) -> usize {
        self.channels.iter().map(|c| c.screened.count).sum()
    }
}

/// The screening's tolerances, resolved from the configuration and the sensor sigmas.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScreenTolerances {
    /// Gyro, rad/s, before the acceleration allowance.
    pub gyro_rad_s: f64,
    /// Plausible angular acceleration, rad/s^2.
    pub angular_acceleration_rad_s2: f64,
    /// Magnetometer, nT.
    pub mag_nt: f64,
    /// Photodiode, V.
    pub photodiode_v: f64,
}

impl ScreenTolerances {
    /// `outlier_sigmas` times each sensor's sigma.
    pub fn new(config: &FilterConfig, sigmas: &SensorSigmas) -> Self {
        let k = config.outlier_sigmas;
        ScreenTolerances {
            gyro_rad_s: k * sigmas.gyro_rad_s,
            angular_acceleration_rad_s2: config.max_angular_acceleration_rad_s2,
            mag_nt: k * sigmas.mag_nt,
            photodiode_v: k * sigmas.photodiode_v,
        }
    }
}

/// The cells of `telemetry` the screening rejects, as `(channel, row)` in channel order
/// (gyro, magnetometer, photodiodes) and increasing rows.
pub fn find_outliers(telemetry: &Telemetry, tol: &ScreenTolerances) -> Vec<(Channel, usize)> {
    let t = &telemetry.t_s;
    let mut out = Vec::new();
    let mut flags = Vec::new();
    flag_vectors(
        t,
        &telemetry.gyro_rad_s,
        |_, dt, _| tol.gyro_rad_s + tol.angular_acceleration_rad_s2 * dt,
        &mut flags,
    );
    out.extend(flags.iter().map(|&k| (Channel::Gyro, k)));
    let rate = |k: usize| measured_rate_rad_s(&telemetry.gyro_rad_s, k);
    if let Some(mag) = &telemetry.mag_nt {
        let field_nt = median_magnitude(mag);
        flag_vectors(
            t,
            mag,
            |k, dt, _| tol.mag_nt + turn_allowance(rate(k), dt, field_nt),
            &mut flags,
        );
        out.extend(flags.iter().map(|&k| (Channel::Magnetometer, k)));
    }
    for (i, column) in telemetry.pd_v.iter().enumerate() {
        // The output's size is the photodiode's near its peak, `C`, not the neighbours':
        // between two neighbours at 40 deg either side of the Sun its output peaks above
        // both.
        let peak_v = high_quantile((0..column.len()).filter_map(|k| column.get(k)));
        flag_scalars(
            t,
            column.len(),
            |k| column.get(k),
            |k, dt, output_v| tol.photodiode_v + turn_allowance(rate(k), dt, output_v.max(peak_v)),
            &mut flags,
        );
        out.extend(flags.iter().map(|&k| (Channel::Photodiode(i), k)));
    }
    out
}

/// What a line through samples `dt` apart misses of a signal of size `amplitude` that the
/// body's rotation at `rate_rad_s` turns: a component of a vector turning at `w` curves by
/// up to `w^2` times its size (a photodiode's `C cos(theta)` by `w^2` times its output), and
/// the line's error over `dt` is half that times `dt^2`. At 1 Hz and a few deg/s it is a
/// fraction of the noise; between rows 10 s apart on a tumbling spacecraft it is the
/// signal itself, which the neighbours then no longer judge.
fn turn_allowance(rate_rad_s: f64, dt_s: f64, amplitude: f64) -> f64 {
    0.5 * (rate_rad_s * dt_s).powi(2) * amplitude.abs()
}

/// The gyro's rate magnitude at row `k`, or at the nearest sampled row within [`WINDOW`];
/// 0 without one (the neighbours then judge as for a body at rest).
fn measured_rate_rad_s(gyro: &pdcal_dataset::Vectors, k: usize) -> f64 {
    (0..=WINDOW)
        .flat_map(|d| [k.checked_sub(d), Some(k + d)])
        .flatten()
        .find_map(|j| gyro.get(j).filter(|w| w.iter().all(|x| x.is_finite())))
        .map_or(0.0, |w| w.norm())
}

/// The 99th percentile of the magnitudes of `values`' finite members (a column's size near
/// its peak, robust to a few wild samples); 0 for none.
fn high_quantile(values: impl Iterator<Item = f64>) -> f64 {
    let mut sizes: Vec<f64> = values.map(f64::abs).filter(|x| x.is_finite()).collect();
    order_statistic(&mut sizes, 99, 100).unwrap_or(0.0)
}

/// The median magnitude of a vector column's finite samples (the field a magnetometer
/// sees, robust to its wild samples); 0 for an empty column.
fn median_magnitude(column: &pdcal_dataset::Vectors) -> f64 {
    let mut norms: Vec<f64> = (0..column.len())
        .filter_map(|k| column.get(k))
        .map(|v| v.norm())
        .filter(|n| n.is_finite())
        .collect();
    order_statistic(&mut norms, 1, 2).unwrap_or(0.0)
}

/// The value at rank `len * per / of` (at most the last) of `values` in increasing order,
/// reordering them; `None` for none.
fn order_statistic(values: &mut [f64], per: usize, of: usize) -> Option<f64> {
    let at = (values.len() * per / of).min(values.len().checked_sub(1)?);
    Some(*values.select_nth_unstable_by(at, f64::total_cmp).1)
}

/// Empties the cells `outliers` names (from [`find_outliers`]), except a gyro sample
/// between two good ones, which becomes their linear interpolation in time: the rate is
/// smooth, so the bridge is as good as a sample, where holding the last sample would be
/// off by a step's rate change.
pub fn remove_outliers(telemetry: &mut Telemetry, outliers: &[(Channel, usize)]) {
    let gyro_rows: Vec<usize> = outliers
        .iter()
        .filter(|(c, _)| *c == Channel::Gyro)
        .map(|&(_, k)| k)
        .collect();
    let good = |j: usize| gyro_rows.binary_search(&j).is_err();
    for &(channel, k) in outliers {
        match channel {
            Channel::Gyro => {
                let (t, gyro) = (&telemetry.t_s, &telemetry.gyro_rad_s);
                let bridge = match (k.checked_sub(1), gyro.get(k + 1)) {
                    (Some(before), Some(b)) if good(before) && good(k + 1) => {
                        gyro.get(before).map(|a| {
                            let f = (t[k] - t[before]) / (t[k + 1] - t[before]);
                            a + (b - a) * f
                        })
                    }
                    _ => None,
                };
                telemetry.gyro_rad_s.set(k, bridge);
            }
            Channel::Magnetometer => {
                if let Some(mag) = telemetry.mag_nt.as_mut() {
                    mag.set(k, None);
                }
            }
            Channel::Photodiode(i) => {
                if let Some(column) = telemetry.pd_v.get_mut(i) {
                    column.set(k, None);
                }
            }
        }
    }
}

/// Rows of a 3-axis column rejected on any axis, into `flags` (increasing).
fn flag_vectors(
    t: &[f64],
    column: &pdcal_dataset::Vectors,
    tol: impl Fn(usize, f64, f64) -> f64 + Copy,
    flags: &mut Vec<usize>,
) {
    let mut axis_flags = Vec::new();
    let mut rows = std::collections::BTreeSet::new();
    for axis in 0..3 {
        flag_scalars(
            t,
            column.len(),
            |k| column.get(k).map(|v| v[axis]),
            tol,
            &mut axis_flags,
        );
        rows.extend(axis_flags.iter().copied());
    }
    flags.clear();
    flags.extend(rows);
}

/// Rows of one scalar column (`value(k)`, `len` rows) rejected by the tests of the module
/// docs, into `flags` (increasing). `tol(k, dt, size)` is the tolerance at row `k` for
/// neighbours up to `dt` seconds away whose values reach `size` in magnitude.
fn flag_scalars(
    t: &[f64],
    len: usize,
    value: impl Fn(usize) -> Option<f64>,
    tol: impl Fn(usize, f64, f64) -> f64,
    flags: &mut Vec<usize>,
) {
    flags.clear();
    let len = len.min(t.len());
    let absurd = absurd_bound(len, &value, tol(0, 0.0, 0.0));
    for k in 0..len {
        let Some(v) = value(k) else { continue };
        if !v.is_finite() || absurd.is_some_and(|(centre, bound)| (v - centre).abs() > bound) {
            flags.push(k);
            continue;
        }
        // Between its two adjacent samples (within the tolerance for them): inside the
        // candidates' range below too, so accepted without gathering more.
        if let (Some(a), Some(b)) = (
            k.checked_sub(1).and_then(&value),
            (k + 1 < len).then(|| value(k + 1)).flatten(),
        ) {
            let near = tol(
                k,
                (t[k] - t[k - 1]).max(t[k + 1] - t[k]),
                a.abs().max(b.abs()),
            );
            if v >= a.min(b) - near && v <= a.max(b) + near {
                continue;
            }
        }
        let near = |j: &usize| (t[*j] - t[k]).abs() <= NEIGHBOUR_REACH_S;
        let before = Side::gather((k.saturating_sub(WINDOW)..k).rev().filter(near), &value, t);
        let after = Side::gather((k + 1..len.min(k + 1 + WINDOW)).filter(near), &value, t);
        if before.count + after.count < 2 {
            continue;
        }
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for x in before.candidates(t[k]).chain(after.candidates(t[k])) {
            lo = lo.min(x);
            hi = hi.max(x);
        }
        let reach_s = before.reach_s(t[k]).max(after.reach_s(t[k]));
        let size = before.size().max(after.size());
        let allowance = tol(k, reach_s, size);
        if v < lo - allowance || v > hi + allowance {
            flags.push(k);
        }
    }
}

/// `(centre, bound)`: a value farther than `bound` from the column's median is absurd
/// whatever its neighbours (a burst of wild samples hides each one from the neighbour
/// test). `bound = ABSURD_FACTOR (1.4826 MAD + tol)`; `None` for an empty column.
fn absurd_bound(len: usize, value: &impl Fn(usize) -> Option<f64>, tol: f64) -> Option<(f64, f64)> {
    let mut values: Vec<f64> = (0..len)
        .filter_map(value)
        .filter(|x| x.is_finite())
        .collect();
    let median = order_statistic(&mut values, 1, 2)?;
    for x in &mut values {
        *x = (*x - median).abs();
    }
    let mad = order_statistic(&mut values, 1, 2)?;
    Some((median, ABSURD_FACTOR * (1.4826 * mad + tol)))
}

/// How many robust spreads (plus tolerances) from the column's median make a value absurd.
pub const ABSURD_FACTOR: f64 = 100.0;

/// Up to two sampled neighbours on one side of a sample (nearest first), with their times.
#[derive(Default)]
struct Side {
    values: [f64; 2],
    times: [f64; 2],
    count: usize,
}

impl Side {
    /// The first two finite values of rows `rows`.
    fn gather(
        rows: impl Iterator<Item = usize>,
        value: &impl Fn(usize) -> Option<f64>,
        t: &[f64],
    ) -> Self {
        let mut side = Side::default();
        for j in rows {
            if side.count == 2 {
                break;
            }
            if let Some(x) = value(j).filter(|x| x.is_finite()) {
                side.values[side.count] = x;
                side.times[side.count] = t[j];
                side.count += 1;
            }
        }
        side
    }

    /// What this side says the value at `t_s` may be: its nearest sample and, with two, the
    /// line through both extrapolated to `t_s`.
    fn candidates(&self, t_s: f64) -> impl Iterator<Item = f64> {
        let nearest = (self.count >= 1).then_some(self.values[0]);
        let line = (self.count == 2).then(|| {
            let [a, b] = self.values;
            let [ta, tb] = self.times;
            a + (a - b) * (t_s - ta) / (ta - tb)
        });
        nearest.into_iter().chain(line)
    }

    /// The largest magnitude of this side's samples.
    fn size(&self) -> f64 {
        self.values[..self.count]
            .iter()
            .fold(0.0, |m, x| m.max(x.abs()))
    }

    /// The largest time from `t_s` to a sample of this side.
    fn reach_s(&self, t_s: f64) -> f64 {
        self.times[..self.count]
            .iter()
            .fold(0.0, |m, t| m.max((t - t_s).abs()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flagged(values: &[Option<f64>], tol: f64) -> Vec<usize> {
        let t: Vec<f64> = (0..values.len()).map(|k| k as f64).collect();
        let mut flags = Vec::new();
        flag_scalars(&t, values.len(), |k| values[k], |_, _, _| tol, &mut flags);
        flags
    }

    /// A photodiode leaving eclipse while the Sun moves away from its normal (simulated
    /// rax2-like, seed 2, pd14, rows 1428-1445): the peak at the kink is genuine.
    const KINK_V: [f64; 18] = [
        -0.0191, 0.0802, 0.3613, 0.7305, 1.1504, 1.6284, 2.0222, 2.3846, 2.6946, 2.8687, 2.8107,
        2.7004, 2.6076, 2.5006, 2.3642, 2.2497, 2.0658, 1.9677,
    ];

    #[test]
    fn a_kink_and_slopes_are_not_outliers() {
        let values: Vec<Option<f64>> = KINK_V.iter().map(|&v| Some(v)).collect();
        assert_eq!(flagged(&values, 0.12), Vec::<usize>::new());
    }

    #[test]
    fn a_spike_of_any_size_is_flagged_at_its_row() {
        for spike in [1e300, 1e6, 1.0] {
            let mut values: Vec<Option<f64>> = KINK_V.iter().map(|&v| Some(v)).collect();
            let v = values[12].unwrap();
            values[12] = Some(v + spike);
            assert_eq!(flagged(&values, 0.12), vec![12], "spike {spike}");
        }
    }

    #[test]
    fn a_burst_of_absurd_values_is_flagged_whole() {
        let mut values: Vec<Option<f64>> = KINK_V.iter().map(|&v| Some(v)).collect();
        values[5..8].fill(Some(1e300));
        values[9] = Some(f64::NAN);
        assert_eq!(flagged(&values, 0.12), vec![5, 6, 7, 9]);
    }

    /// A field of 40 uT seen from a body turning at 4 deg/s about an axis across it, with
    /// 320 nT noise: at 1 Hz a 20-sigma spike is flagged and nothing else; sampled every
    /// 10 s (40 deg between rows) the field is no line between neighbours, and no sample
    /// is flagged where, judged as a smooth signal, most of them were.
    fn tumbling_field(step_s: f64, rows: usize, spike: Option<usize>) -> Telemetry {
        let rate = 4f64.to_radians();
        let mut noise = 0.0f64;
        let mut tel = Telemetry {
            t_s: (0..rows).map(|k| k as f64 * step_s).collect(),
            gyro_rad_s: (0..rows)
                .map(|_| Some(nalgebra::Vector3::new(0.0, 0.0, rate)))
                .collect(),
            mag_nt: Some(
                (0..rows)
                    .map(|k| {
                        // A deterministic stand-in for noise: a slow pseudo-random walk.
                        noise = (noise * 1.7 + 0.61).sin();
                        let a = rate * k as f64 * step_s;
                        Some(nalgebra::Vector3::new(
                            40_000.0 * a.cos() + 320.0 * noise,
                            -40_000.0 * a.sin() - 320.0 * noise,
                            5_000.0,
                        ))
                    })
                    .collect(),
            ),
            ..Telemetry::default()
        };
        if let (Some(k), Some(mag)) = (spike, tel.mag_nt.as_mut()) {
            let mut b = mag.get(k).unwrap();
            b.x += 20.0 * 320.0;
            mag.set(k, Some(b));
        }
        tel
    }

    /// A photodiode of `C` = 1 V on a body turning at 4 deg/s, its output `C max(cos, 0)`:
    /// every 10 s its peaks fall between samples 40 deg from the Sun, above both.
    fn tumbling_photodiode(step_s: f64, rows: usize, spike: Option<usize>) -> Telemetry {
        let rate = 4f64.to_radians();
        let output = |k: usize| (rate * k as f64 * step_s + 0.3).cos().max(0.0);
        let mut pd = pdcal_dataset::Samples::from_iter((0..rows).map(|k| Some(output(k))));
        if let Some(k) = spike {
            pd.set(k, Some(output(k) + 0.2));
        }
        Telemetry {
            t_s: (0..rows).map(|k| k as f64 * step_s).collect(),
            gyro_rad_s: (0..rows)
                .map(|_| Some(nalgebra::Vector3::new(0.0, 0.0, rate)))
                .collect(),
            pd_v: vec![pd],
            ..Telemetry::default()
        }
    }

    #[test]
    fn a_photodiode_peak_between_sparse_rows_is_not_an_outlier() {
        let tol = ScreenTolerances {
            gyro_rad_s: 0.007,
            angular_acceleration_rad_s2: 0.01,
            mag_nt: 2560.0,
            photodiode_v: 0.04,
        };
        let dense = find_outliers(&tumbling_photodiode(1.0, 400, Some(30)), &tol);
        assert_eq!(dense, vec![(Channel::Photodiode(0), 30)]);
        let sparse = find_outliers(&tumbling_photodiode(10.0, 200, None), &tol);
        assert_eq!(sparse, vec![]);
    }

    #[test]
    fn a_field_turned_between_sparse_rows_is_not_an_outlier() {
        let tol = ScreenTolerances {
            gyro_rad_s: 0.007,
            angular_acceleration_rad_s2: 0.01,
            mag_nt: 8.0 * 320.0,
            photodiode_v: 0.04,
        };
        let dense = find_outliers(&tumbling_field(1.0, 200, Some(100)), &tol);
        assert_eq!(dense, vec![(Channel::Magnetometer, 100)]);
        let sparse = find_outliers(&tumbling_field(10.0, 200, None), &tol);
        assert_eq!(sparse, vec![]);
    }

    #[test]
    fn a_gyro_outlier_between_good_samples_is_interpolated() {
        let mut tel = Telemetry {
            t_s: (0..8).map(f64::from).collect(),
            gyro_rad_s: (0..8)
                .map(|k| Some(nalgebra::Vector3::new(0.01 * f64::from(k), 0.02, -0.03)))
                .collect(),
            ..Telemetry::default()
        };
        tel.gyro_rad_s
            .set(4, Some(nalgebra::Vector3::new(1e300, 0.02, -0.03)));
        tel.gyro_rad_s
            .set(7, Some(nalgebra::Vector3::new(0.07, 5.0, -0.03)));
        let tol = ScreenTolerances {
            gyro_rad_s: 0.007,
            angular_acceleration_rad_s2: 0.01,
            mag_nt: 1.0,
            photodiode_v: 1.0,
        };
        let outliers = find_outliers(&tel, &tol);
        assert_eq!(outliers, vec![(Channel::Gyro, 4), (Channel::Gyro, 7)]);
        remove_outliers(&mut tel, &outliers);
        let bridged = tel.gyro_rad_s.get(4).unwrap();
        assert!((bridged - nalgebra::Vector3::new(0.04, 0.02, -0.03)).norm() < 1e-15);
        // The last row has no later neighbour: emptied, the filter holds the rate.
        assert_eq!(tel.gyro_rad_s.get(7), None);
    }
}
