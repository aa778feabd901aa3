//! Several series over time (paper Figs. 2, 10, 12, 13).

use std::path::Path;

use plotters::coord::Shift;
use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::axes::LogAxis;
use crate::render::{DrawError, Figure, Plot, Written, check_figure, render};
use crate::style::{self, LegendEntry, Mark, clipped_runs, finite_range, padded, points_inside};
use crate::{MAX_SERIES, ReportError};

/// Charts with at most this many series draw 2 px lines, more get 1 px.
const THICK_LINES_UP_TO: usize = 5;

/// Scale of the y axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum YScale {
    /// Linear.
    Linear,
    /// Base-10 logarithmic; values <= 0 are gaps (useful for a 1-sigma that shrinks by
    /// decades, e.g. the attitude sigma from its initial value).
    Log10,
}

/// One series of [`lines`]: `y[i]` belongs to `t_min[i]`; NaN is a gap.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Series<'a> {
    /// Legend name.
    pub name: &'a str,
    /// Values (unit of the y axis).
    pub y: &'a [f64],
    /// Line, dots or circles.
    pub mark: Mark,
    /// RGB colour; `None` takes the next palette colour (by series index).
    pub colour: Option<[u8; 3]>,
}

impl<'a> Series<'a> {
    /// A series with the palette colour of its index.
    pub fn new(name: &'a str, y: &'a [f64], mark: Mark) -> Self {
        Self {
            name,
            y,
            mark,
            colour: None,
        }
    }

    /// The same series in colour `rgb`.
    pub fn with_colour(self, rgb: [u8; 3]) -> Self {
        Self {
            colour: Some(rgb),
            ..self
        }
    }
}

/// Axis descriptions (with units) and y scaling of [`lines`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineAxes<'a> {
    /// X axis description, e.g. "time (min)".
    pub x_label: &'a str,
    /// Y axis description, e.g. "output (V)".
    pub y_label: &'a str,
    /// Linear or logarithmic y.
    pub y_scale: YScale,
    /// Fixed y range; `None` spans the finite data (+5 %, or x/1.25 .. x*1.25 on a log axis).
    pub y_range: Option<(f64, f64)>,
}

impl<'a> LineAxes<'a> {
    /// Linear axes with an automatic y range.
    pub fn new(x_label: &'a str, y_label: &'a str) -> Self {
        Self {
            x_label,
            y_label,
            y_scale: YScale::Linear,
            y_range: None,
        }
    }

    /// The same axes with y scale `y_scale`.
    pub fn with_y_scale(self, y_scale: YScale) -> Self {
        Self { y_scale, ..self }
    }

    /// The same axes with a fixed y range (parts outside are clipped).
    pub fn with_y_range(self, lo: f64, hi: f64) -> Self {
        Self {
            y_range: Some((lo, hi)),
            ..self
        }
    }
}

/// Write `<stem>.png` and `<stem>.svg`: every series over `t_min` (min) in one chart, each
/// in its own colour, with a legend beside the chart when there is more than one series.
/// Series are drawn in the given order (put circles before dots so both stay visible).
///
/// A figure whose series have no finite sample is drawn empty with "no finite data".
///
/// Errors: invalid stem or size, 0 or more than [`MAX_SERIES`] series, a series whose
/// length differs from `t_min`, an invalid fixed y range (not finite and increasing, or
/// not positive on a log axis), or an I/O / rendering failure.
pub fn lines(
    out_dir: &Path,
    figure: &Figure<'_>,
    axes: &LineAxes<'_>,
    t_min: &[f64],
    series: &[Series<'_>],
) -> Result<Written, ReportError> {
    check_figure(figure)?;
    let stem = figure.stem;
    if series.is_empty() || series.len() > MAX_SERIES {
        return Err(ReportError::Count {
            stem: stem.to_owned(),
            what: "series",
            found: series.len(),
            min: 1,
            max: MAX_SERIES,
        });
    }
    for s in series {
        if s.y.len() != t_min.len() {
            return Err(ReportError::LengthMismatch {
                stem: stem.to_owned(),
                what: format!("series {:?}", s.name),
                found: s.y.len(),
                expected: t_min.len(),
            });
        }
    }
    let log = axes.y_scale == YScale::Log10;
    let usable = |y: f64| y.is_finite() && (!log || y > 0.0);
    let data = finite_range(series.iter().flat_map(|s| {
        s.y.iter()
            .zip(t_min)
            .filter(|(y, t)| usable(**y) && t.is_finite())
            .map(|(y, _)| *y)
    }));
    let y_range = match axes.y_range {
        Some((lo, hi)) if lo.is_finite() && hi.is_finite() && hi > lo && (!log || lo > 0.0) => {
            (lo, hi)
        }
        Some((lo, hi)) => {
            return Err(ReportError::InvalidArgument {
                stem: stem.to_owned(),
                message: format!(
                    "y range {lo}..{hi} must be finite and increasing (and positive on a log axis)"
                ),
            });
        }
        None if log => log_padded(data),
        None => padded(data, 0.05),
    };
    let t_range = padded(finite_range(t_min.iter().copied()), 0.0);
    let plot = LinesPlot {
        title: figure.title,
        axes: *axes,
        t_min,
        series,
        t_range,
        y_range,
        has_data: data.is_some(),
    };
    render(out_dir, figure, &plot)
}

/// `lo/1.25 .. hi*1.25` (a decade when there is one value, 1..10 when there is none).
fn log_padded(data: Option<(f64, f64)>) -> (f64, f64) {
    match data {
        None => (1.0, 10.0),
        Some((lo, hi)) if hi > lo => (lo / 1.25, hi * 1.25),
        Some((v, _)) => (v / 10f64.sqrt(), v * 10f64.sqrt()),
    }
}

struct LinesPlot<'a> {
    title: &'a str,
    axes: LineAxes<'a>,
    t_min: &'a [f64],
    series: &'a [Series<'a>],
    t_range: (f64, f64),
    y_range: (f64, f64),
    has_data: bool,
}

impl LinesPlot<'_> {
    fn colour(&self, i: usize) -> RGBColor {
        match self.series[i].colour {
            Some([r, g, b]) => RGBColor(r, g, b),
            None => style::palette(i),
        }
    }

    fn draw_chart<DB, Y>(
        &self,
        chart: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordf64, Y>>,
    ) -> Result<(), DrawError>
    where
        DB: DrawingBackend,
        Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
    {
        style::draw_mesh(chart, Some(self.axes.x_label), self.axes.y_label)?;
        if !self.has_data {
            return style::draw_no_data(&chart.plotting_area().strip_coord_spec());
        }
        let log = self.axes.y_scale == YScale::Log10;
        // Thick lines read better, but 17 overlapping ones would hide each other.
        let width = if self.series.len() <= THICK_LINES_UP_TO {
            2
        } else {
            1
        };
        for (i, s) in self.series.iter().enumerate() {
            let colour = self.colour(i);
            // Non-positive values are gaps on a log axis.
            let y: Vec<f64> = if log {
                s.y.iter()
                    .map(|&v| if v > 0.0 { v } else { f64::NAN })
                    .collect()
            } else {
                s.y.to_vec()
            };
            match s.mark {
                Mark::Line => {
                    for run in clipped_runs(self.t_min, &y, self.t_range, self.y_range) {
                        chart.draw_series(std::iter::once(PathElement::new(
                            run,
                            colour.stroke_width(width),
                        )))?;
                    }
                }
                Mark::Dot => {
                    let pts = points_inside(self.t_min, &y, self.t_range, self.y_range);
                    chart
                        .draw_series(pts.into_iter().map(|p| Circle::new(p, 2, colour.filled())))?;
                }
                Mark::Circle => {
                    let pts = points_inside(self.t_min, &y, self.t_range, self.y_range);
                    chart.draw_series(pts.into_iter().map(|p| Circle::new(p, 4, colour)))?;
                }
            }
        }
        Ok(())
    }
}

impl Plot for LinesPlot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), DrawError> {
        let body = style::titled(root, self.title)?;
        let area = if self.series.len() > 1 {
            let legend: Vec<LegendEntry> = self
                .series
                .iter()
                .enumerate()
                .map(|(i, s)| LegendEntry {
                    name: s.name.to_owned(),
                    colour: self.colour(i),
                    mark: s.mark,
                })
                .collect();
            let (w, _) = body.dim_in_pixel();
            let legend_w = style::legend_width(&body, &legend, w)?;
            let (area, strip) = body.split_horizontally(w - legend_w);
            style::draw_legend(&strip, &legend, 10)?;
            area
        } else {
            body
        };
        let (t0, t1) = self.t_range;
        let (y0, y1) = self.y_range;
        let mut builder = ChartBuilder::on(&area);
        builder
            .margin(10)
            .x_label_area_size(55)
            .y_label_area_size(90);
        match self.axes.y_scale {
            YScale::Linear => self.draw_chart(&mut builder.build_cartesian_2d(t0..t1, y0..y1)?),
            YScale::Log10 => {
                self.draw_chart(&mut builder.build_cartesian_2d(t0..t1, LogAxis::new(y0, y1))?)
            }
        }
    }
}
