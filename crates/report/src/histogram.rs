//! Side-by-side histograms with their mean and standard deviation (paper Figs. 8, 9, 11).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::render::{DrawError, Figure, Plot, Written, check_figure, render};
use crate::style::{self, finite_range, fmt_sig, padded};
use crate::{MAX_HISTOGRAMS, ReportError};

/// Most bins a histogram may have (more than the pixels of a panel is pointless).
pub const MAX_BINS: usize = 1000;

/// Head room above the tallest bar, as a factor on its count, so the printed statistics sit
/// above the bars instead of on them.
const HEADROOM: f64 = 1.35;

/// Axis margin beside the outer bin edges, as a fraction of the bin range.
const X_PAD: f64 = 0.02;

/// One histogram panel; NaN and infinite values are ignored.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HistogramPanel<'a> {
    /// Panel caption, e.g. "initial parameters".
    pub label: &'a str,
    /// The samples (unit of the x axis).
    pub values: &'a [f64],
}

/// Where the bins of [`histograms`] lie.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BinRange {
    /// Finite min..max over all panels: the same bins everywhere, so the panels compare
    /// directly (initial vs calibrated).
    Shared,
    /// Finite min..max of each panel.
    PerPanel,
    /// Fixed `lo..hi`; values outside are not counted (but enter the mean and std).
    Fixed {
        /// Lower edge of the first bin.
        lo: f64,
        /// Upper edge of the last bin.
        hi: f64,
    },
}

/// Mean, sample standard deviation (n - 1 denominator; 0 for one sample) and count of the
/// finite values, `None` when there is none.
pub fn mean_std(values: &[f64]) -> Option<(f64, f64, usize)> {
    let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    let n = finite.len();
    if n == 0 {
        return None;
    }
    let mean = finite.iter().sum::<f64>() / n as f64;
    let ss: f64 = finite.iter().map(|v| (v - mean).powi(2)).sum();
    let std = if n > 1 {
        (ss / (n - 1) as f64).sqrt()
    } else {
        0.0
    };
    Some((mean, std, n))
}

/// Counts of the finite `values` in `bins` equal bins over `lo..hi` (the last bin includes
/// `hi`); values outside are not counted.
pub fn bin_counts(values: &[f64], bins: usize, (lo, hi): (f64, f64)) -> Vec<u64> {
    let mut counts = vec![0u64; bins];
    let width = (hi - lo) / bins as f64;
    if bins == 0 || !width.is_finite() || width <= 0.0 {
        return counts;
    }
    for &v in values {
        if v.is_finite() && v >= lo && v <= hi {
            let k = (((v - lo) / width) as usize).min(bins - 1);
            counts[k] += 1;
        }
    }
    counts
}

/// Write `<stem>.png` and `<stem>.svg`: one histogram per panel (1 to [`MAX_HISTOGRAMS`]),
/// side by side, each with `bins` bins, a "count" y axis, and its mean, standard deviation and
/// sample count printed in the upper right corner.
///
/// A panel without finite values is drawn empty with "no finite data".
///
/// Errors: invalid stem or size, a panel count outside 1..=[`MAX_HISTOGRAMS`], `bins` outside
/// 1..=[`MAX_BINS`], a fixed range that is not finite and increasing, or an I/O / rendering
/// failure.
pub fn histograms(
    out_dir: &Path,
    figure: &Figure<'_>,
    x_label: &str,
    bins: usize,
    range: BinRange,
    panels: &[HistogramPanel<'_>],
) -> Result<Written, ReportError> {
    check_figure(figure)?;
    let stem = figure.stem;
    if panels.is_empty() || panels.len() > MAX_HISTOGRAMS {
        return Err(ReportError::Count {
            stem: stem.to_owned(),
            what: "histogram panels",
            found: panels.len(),
            min: 1,
            max: MAX_HISTOGRAMS,
        });
    }
    let invalid = |message: String| ReportError::InvalidArgument {
        stem: stem.to_owned(),
        message,
    };
    if !(1..=MAX_BINS).contains(&bins) {
        return Err(invalid(format!(
            "bin count {bins} is outside 1..={MAX_BINS}"
        )));
    }
    let shared = finite_range(panels.iter().flat_map(|p| p.values.iter().copied()));
    let mut prepared = Vec::with_capacity(panels.len());
    for p in panels {
        let edges = match range {
            BinRange::Shared => padded(shared, 0.0),
            BinRange::PerPanel => padded(finite_range(p.values.iter().copied()), 0.0),
            BinRange::Fixed { lo, hi } if lo.is_finite() && hi.is_finite() && hi > lo => (lo, hi),
            BinRange::Fixed { lo, hi } => {
                return Err(invalid(format!(
                    "bin range {lo}..{hi} must be finite and increasing"
                )));
            }
        };
        prepared.push(Prepared {
            label: p.label,
            edges,
            counts: bin_counts(p.values, bins, edges),
            stats: mean_std(p.values),
        });
    }
    let plot = HistogramPlot {
        title: figure.title,
        x_label,
        panels: prepared,
    };
    render(out_dir, figure, &plot)
}

struct Prepared<'a> {
    label: &'a str,
    edges: (f64, f64),
    counts: Vec<u64>,
    stats: Option<(f64, f64, usize)>,
}

struct HistogramPlot<'a> {
    title: &'a str,
    x_label: &'a str,
    panels: Vec<Prepared<'a>>,
}

impl Plot for HistogramPlot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), DrawError> {
        let body = style::titled(root, self.title)?;
        let columns = body.split_evenly((1, self.panels.len()));
        for (i, (area, p)) in columns.iter().zip(&self.panels).enumerate() {
            self.draw_panel(area, p, style::palette(i))?;
        }
        Ok(())
    }
}

impl HistogramPlot<'_> {
    fn draw_panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        p: &Prepared<'_>,
        colour: RGBColor,
    ) -> Result<(), DrawError> {
        let (lo, hi) = p.edges;
        let top = p.counts.iter().copied().max().unwrap_or(0).max(1) as f64 * HEADROOM;
        let mut chart = ChartBuilder::on(area)
            .caption(p.label, style::font(style::CAPTION_PX))
            .margin(10)
            .x_label_area_size(55)
            .y_label_area_size(75)
            // The axis is a little wider than the bins so the outer bars do not touch the frame.
            .build_cartesian_2d(lo - X_PAD * (hi - lo)..hi + X_PAD * (hi - lo), 0.0..top)?;
        style::draw_mesh(&mut chart, Some(self.x_label), "count")?;
        let plotting = chart.plotting_area().strip_coord_spec();
        let Some((mean, std, n)) = p.stats else {
            return style::draw_no_data(&plotting);
        };
        let width = (hi - lo) / p.counts.len() as f64;
        let bars = p.counts.iter().enumerate().filter(|(_, c)| **c > 0);
        chart.draw_series(bars.clone().map(|(k, &c)| {
            let x0 = lo + width * k as f64;
            Rectangle::new(
                [(x0, 0.0), (x0 + width, c as f64)],
                colour.mix(0.75).filled(),
            )
        }))?;
        chart.draw_series(bars.map(|(k, &c)| {
            let x0 = lo + width * k as f64;
            Rectangle::new([(x0, 0.0), (x0 + width, c as f64)], colour.stroke_width(1))
        }))?;
        let lines = [
            format!("mean = {}", fmt_sig(mean, 4)),
            format!("std = {}", fmt_sig(std, 3)),
            format!("n = {n}"),
        ];
        let (w, _) = plotting.dim_in_pixel();
        let style = style::font(style::LABEL_PX + 1.0).pos(Pos::new(HPos::Right, VPos::Top));
        for (row, text) in lines.into_iter().enumerate() {
            plotting.draw(&Text::new(
                text,
                (w as i32 - 10, 8 + 22 * row as i32),
                style.clone(),
            ))?;
        }
        Ok(())
    }
}
