//! Axis types whose ticks plotters does not choose well.

use std::ops::Range;

use plotters::coord::ranged1d::{
    KeyPointHint, KeyPointWeight, NoDefaultFormatting, ValueFormatter,
};
use plotters::prelude::*;

use crate::style::tick_label;

/// A linear axis in degrees whose ticks are the multiples of `step` (45 or 30 deg read better
/// on a sphere than plotters' 1-2-5 steps), labelled without decimals.
pub(crate) struct DegreeAxis {
    lo: f64,
    hi: f64,
    step: f64,
}

impl DegreeAxis {
    pub(crate) fn new(lo: f64, hi: f64, step: f64) -> Self {
        Self { lo, hi, step }
    }
}

impl Ranged for DegreeAxis {
    type FormatOption = NoDefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let frac = (value - self.lo) / (self.hi - self.lo);
        limit.0 + (f64::from(limit.1 - limit.0) * frac).round() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        let first = (self.lo / self.step).ceil() as i64;
        let last = (self.hi / self.step).floor() as i64;
        let all: Vec<f64> = (first..=last).map(|k| k as f64 * self.step).collect();
        // Thin out (every 2nd, 3rd, ...) when the hint allows fewer points.
        let max = hint.max_num_points().max(1);
        let every = all.len().div_ceil(max).max(1);
        all.into_iter().step_by(every).collect()
    }

    fn range(&self) -> Range<f64> {
        self.lo..self.hi
    }
}

impl ValueFormatter<f64> for DegreeAxis {
    fn format(value: &f64) -> String {
        format!("{value:.0}")
    }
}

/// A base-10 logarithmic axis over `lo..hi` (both > 0). plotters' own log axis labels only
/// powers of ten, so a range inside one decade (a converged 1-sigma, 0.15-0.5 deg) gets no
/// label at all; this one labels 1-2-5 or 1..9 multiples of the decades, or plain 1-2-5 steps
/// when the range is narrower still.
pub(crate) struct LogAxis {
    lo: f64,
    hi: f64,
}

impl LogAxis {
    /// `lo..hi` with `0 < lo < hi` (the caller checks).
    pub(crate) fn new(lo: f64, hi: f64) -> Self {
        Self { lo, hi }
    }

    /// `m * 10^k` for every mantissa in `mantissas` and every decade, inside the range.
    fn decade_multiples(&self, mantissas: &[f64]) -> Vec<f64> {
        let (k0, k1) = (
            self.lo.log10().floor() as i32,
            self.hi.log10().ceil() as i32,
        );
        let mut out = Vec::new();
        for k in k0..=k1 {
            for m in mantissas {
                let v = m * 10f64.powi(k);
                if v >= self.lo * (1.0 - 1e-12) && v <= self.hi * (1.0 + 1e-12) {
                    out.push(v);
                }
            }
        }
        out
    }

    /// Bold (labelled) ticks: the coarsest decade set with at least 3 ticks that fits `max`.
    fn labelled(&self, max: usize) -> Vec<f64> {
        const SETS: [&[f64]; 3] = [
            &[1.0],
            &[1.0, 2.0, 5.0],
            &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0],
        ];
        let mut best = Vec::new();
        for set in SETS {
            let ticks = self.decade_multiples(set);
            if ticks.len() > max {
                break;
            }
            best = ticks;
            if best.len() >= 3 {
                return best;
            }
        }
        if best.len() >= 3 {
            best
        } else {
            linear_ticks(self.lo, self.hi, max.clamp(3, 6))
        }
    }
}

/// Multiples of a 1-2-5 step inside `lo..hi`, about `target` of them.
fn linear_ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    let raw = (hi - lo) / target as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * mag);
    let first = (lo / step).ceil() as i64;
    let last = (hi / step).floor() as i64;
    (first..=last).map(|k| k as f64 * step).collect()
}

impl Ranged for LogAxis {
    type FormatOption = NoDefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        let (l0, l1) = (self.lo.log10(), self.hi.log10());
        let frac = (value.log10() - l0) / (l1 - l0);
        limit.0 + (f64::from(limit.1 - limit.0) * frac).round() as i32
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        let max = hint.max_num_points().max(1);
        let bold = self.labelled(hint.bold_points().max(1));
        if matches!(hint.weight(), KeyPointWeight::Bold) {
            return bold;
        }
        // Light grid: every 1..9 multiple when there is room, as on log paper.
        let minor = self.decade_multiples(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
        if minor.len() <= max && minor.len() >= bold.len() {
            minor
        } else {
            bold
        }
    }

    fn range(&self) -> Range<f64> {
        self.lo..self.hi
    }
}

impl ValueFormatter<f64> for LogAxis {
    fn format(value: &f64) -> String {
        tick_label(value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degree_ticks_are_multiples_of_the_step() {
        let axis = DegreeAxis::new(-180.0, 180.0, 45.0);
        assert_eq!(axis.key_points(20usize).len(), 9);
        assert_eq!(
            axis.key_points(5usize),
            vec![-180.0, -90.0, 0.0, 90.0, 180.0]
        );
    }

    fn close(a: &[f64], b: &[f64]) -> bool {
        a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-12)
    }

    #[test]
    fn log_ticks_label_every_range() {
        // Two decades: powers of ten give only 2 labels, so 1-2-5 multiples.
        let t = LogAxis::new(0.2, 25.0).labelled(10);
        assert!(close(&t, &[0.2, 0.5, 1.0, 2.0, 5.0, 10.0, 20.0]), "{t:?}");
        // Inside one decade: 1..9 multiples.
        let t = LogAxis::new(0.12, 0.6).labelled(10);
        assert!(close(&t, &[0.2, 0.3, 0.4, 0.5, 0.6]), "{t:?}");
        // Narrower than any decade set: linear 1-2-5 steps.
        let t = LogAxis::new(0.31, 0.36).labelled(10);
        assert!(close(&t, &[0.31, 0.32, 0.33, 0.34, 0.35, 0.36]), "{t:?}");
        // Many decades: powers of ten only.
        let t = LogAxis::new(1e-3, 1e3).labelled(10);
        assert_eq!(t.len(), 7, "{t:?}");
    }
}
