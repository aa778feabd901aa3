//! Quantity over time with its +-3-sigma bounds, several panels stacked (paper Figs. 4-7).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::render::{DrawError, Figure, Plot, Written, check_figure, render};
use crate::style::{
    self, BOUND_COLOUR, DOT_COLOUR, LegendEntry, Mark, clipped_runs, finite_range, padded,
    points_inside, quantile, union,
};
use crate::{MAX_PANELS, ReportError};

/// Bound half-width in sigmas, as in the paper's figures.
pub const N_SIGMA: f64 = 3.0;

/// Quantiles of the lower / upper bound used for the automatic y range: the bounds start wide
/// (initial covariance) and shrink; taking the 2nd / 98th percentile keeps the converged part
/// readable while the first moments run off the panel (clipped), as in the paper's figures.
/// Every finite dot is always inside the automatic range.
const BOUND_QUANTILES: (f64, f64) = (0.02, 0.98);

/// One panel: dots of `value` and the lines `center +- 3 sigma`, over time in minutes.
///
/// NaN in any slice is a gap: a NaN `value` is not drawn (not sampled, not updated), a NaN
/// (or negative) `sigma` or NaN `center` breaks the bound lines there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundsPanel<'a> {
    /// Panel caption, e.g. "photodiode 1".
    pub label: &'a str,
    /// Y axis description with its unit, e.g. "scale factor C (V)".
    pub y_label: &'a str,
    /// Sample times (min).
    pub t_min: &'a [f64],
    /// The dots: residual, estimate or estimation error (unit of `y_label`).
    pub value: &'a [f64],
    /// Centre of the bounds; `None` centres them on zero (residuals, estimation errors). For
    /// estimates give the estimate at every time, also where `value` is NaN because the state
    /// was not updated (the paper's Figs. 5-7 draw the bounds over the whole data set).
    pub center: Option<&'a [f64]>,
    /// 1-sigma of the quantity (unit of `y_label`); the lines are at `center +- 3 sigma`.
    pub sigma: &'a [f64],
    /// Fixed y range; `None` chooses one from the data (see [`series_with_bounds`]).
    pub y_range: Option<(f64, f64)>,
}

impl<'a> BoundsPanel<'a> {
    /// A panel with bounds around zero and an automatic y range.
    pub fn new(
        label: &'a str,
        y_label: &'a str,
        t_min: &'a [f64],
        value: &'a [f64],
        sigma: &'a [f64],
    ) -> Self {
        Self {
            label,
            y_label,
            t_min,
            value,
            center: None,
            sigma,
            y_range: None,
        }
    }

    /// The same panel with the bounds around `center`.
    pub fn around(self, center: &'a [f64]) -> Self {
        Self {
            center: Some(center),
            ..self
        }
    }

    /// The same panel with a fixed y range.
    pub fn with_y_range(self, lo: f64, hi: f64) -> Self {
        Self {
            y_range: Some((lo, hi)),
            ..self
        }
    }
}

/// Write `<stem>.png` and `<stem>.svg`: one panel per entry of `panels`, stacked top to bottom
/// on a shared time axis (min), each with dots of the value and +-3-sigma bound lines, and a
/// legend (`value_name` for the dots, "±3σ bound" for the lines) beside the panels.
///
/// The automatic y range holds every finite dot and the bounds between their 2nd and 98th
/// percentiles; lines leaving the range are clipped. A panel without any finite sample shows
/// "no finite data" (an empty-but-valid panel, not an error).
///
/// Errors: invalid stem or size, 0 or more than [`MAX_PANELS`] panels, a slice whose length
/// differs from its panel's `t_min`, a fixed y range that is not finite and increasing, or an
/// I/O / rendering failure.
pub fn series_with_bounds(
    out_dir: &Path,
    figure: &Figure<'_>,
    x_label: &str,
    value_name: &str,
    panels: &[BoundsPanel<'_>],
) -> Result<Written, ReportError> {
    check_figure(figure)?;
    let stem = figure.stem;
    if panels.is_empty() || panels.len() > MAX_PANELS {
        return Err(ReportError::Count {
            stem: stem.to_owned(),
            what: "panels",
            found: panels.len(),
            min: 1,
            max: MAX_PANELS,
        });
    }
    let prepared = panels
        .iter()
        .map(|p| prepare(stem, p))
        .collect::<Result<Vec<_>, _>>()?;
    let t_range = padded(
        finite_range(panels.iter().flat_map(|p| p.t_min.iter().copied())),
        0.0,
    );
    let plot = BoundsPlot {
        title: figure.title,
        x_label,
        value_name,
        t_range,
        panels: prepared,
    };
    render(out_dir, figure, &plot)
}

struct PreparedPanel<'a> {
    panel: BoundsPanel<'a>,
    upper: Vec<f64>,
    lower: Vec<f64>,
    y_range: (f64, f64),
    has_data: bool,
}

fn prepare<'a>(stem: &str, p: &BoundsPanel<'a>) -> Result<PreparedPanel<'a>, ReportError> {
    let n = p.t_min.len();
    let check = |what: &str, len: usize| {
        if len == n {
            Ok(())
        } else {
            Err(ReportError::LengthMismatch {
                stem: stem.to_owned(),
                what: format!("panel {:?} {what}", p.label),
                found: len,
                expected: n,
            })
        }
    };
    check("value", p.value.len())?;
    check("sigma", p.sigma.len())?;
    if let Some(c) = p.center {
        check("center", c.len())?;
    }
    let center = |i: usize| p.center.map_or(0.0, |c| c[i]);
    let half = |i: usize| {
        let s = p.sigma[i];
        if s >= 0.0 { N_SIGMA * s } else { f64::NAN }
    };
    let upper: Vec<f64> = (0..n).map(|i| center(i) + half(i)).collect();
    let lower: Vec<f64> = (0..n).map(|i| center(i) - half(i)).collect();
    let with_time = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .zip(p.t_min)
            .filter(|(_, t)| t.is_finite())
            .map(|(&v, _)| v)
            .collect()
    };
    let dots = finite_range(with_time(p.value));
    let bounds = match (
        quantile(with_time(&lower), BOUND_QUANTILES.0),
        quantile(with_time(&upper), BOUND_QUANTILES.1),
    ) {
        (Some(lo), Some(hi)) => Some((lo.min(hi), hi.max(lo))),
        _ => None,
    };
    let data = union(dots, bounds);
    let y_range = match p.y_range {
        Some((lo, hi)) if lo.is_finite() && hi.is_finite() && hi > lo => (lo, hi),
        Some((lo, hi)) => {
            return Err(ReportError::InvalidArgument {
                stem: stem.to_owned(),
                message: format!(
                    "panel {:?}: y range {lo}..{hi} must be finite and increasing",
                    p.label
                ),
            });
        }
        None => padded(data, 0.05),
    };
    Ok(PreparedPanel {
        panel: *p,
        upper,
        lower,
        y_range,
        has_data: data.is_some(),
    })
}

struct BoundsPlot<'a> {
    title: &'a str,
    x_label: &'a str,
    value_name: &'a str,
    t_range: (f64, f64),
    panels: Vec<PreparedPanel<'a>>,
}

impl Plot for BoundsPlot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), DrawError> {
        let body = style::titled(root, self.title)?;
        let legend = [
            LegendEntry {
                name: self.value_name.to_owned(),
                colour: DOT_COLOUR,
                mark: Mark::Dot,
            },
            LegendEntry {
                name: format!("±{N_SIGMA}σ bound"),
                colour: BOUND_COLOUR,
                mark: Mark::Line,
            },
        ];
        let (w, _) = body.dim_in_pixel();
        let legend_w = style::legend_width(&body, &legend, w)?;
        let (plots, strip) = body.split_horizontally(w - legend_w);
        style::draw_legend(&strip, &legend, 40)?;
        let rows = plots.split_evenly((self.panels.len(), 1));
        let last = self.panels.len() - 1;
        for (i, (area, panel)) in rows.iter().zip(&self.panels).enumerate() {
            let x_desc = (i == last).then_some(self.x_label);
            self.draw_panel(area, panel, x_desc)?;
        }
        Ok(())
    }
}

impl BoundsPlot<'_> {
    fn draw_panel<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        p: &PreparedPanel<'_>,
        x_desc: Option<&str>,
    ) -> Result<(), DrawError> {
        let (t0, t1) = self.t_range;
        let (y0, y1) = p.y_range;
        let mut chart = ChartBuilder::on(area)
            .caption(p.panel.label, style::font(style::CAPTION_PX))
            .margin(8)
            .x_label_area_size(if x_desc.is_some() { 55 } else { 30 })
            .y_label_area_size(90)
            .build_cartesian_2d(t0..t1, y0..y1)?;
        style::draw_mesh(&mut chart, x_desc, p.panel.y_label)?;
        if !p.has_data {
            return style::draw_no_data(&chart.plotting_area().strip_coord_spec());
        }
        let t = p.panel.t_min;
        for line in [&p.upper, &p.lower] {
            for run in clipped_runs(t, line, self.t_range, p.y_range) {
                chart.draw_series(std::iter::once(PathElement::new(
                    run,
                    BOUND_COLOUR.stroke_width(2),
                )))?;
            }
        }
        let dots = points_inside(t, p.panel.value, self.t_range, p.y_range);
        chart.draw_series(
            dots.into_iter()
                .map(|xy| Circle::new(xy, 2, DOT_COLOUR.filled())),
        )?;
        Ok(())
    }
}
