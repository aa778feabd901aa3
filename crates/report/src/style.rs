//! Shared look: fonts, colours, legend, axis ranges, clipping and number formatting.

use plotters::coord::Shift;
use plotters::coord::ranged1d::ValueFormatter;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::error::DrawError;

/// Font family name the embedded font is registered under; SVG viewers fall back to their own
/// sans-serif font with the same name.
pub(crate) const FAMILY: &str = "sans-serif";
/// Figure title size (px).
pub(crate) const TITLE_PX: f64 = 28.0;
/// Panel caption size (px).
pub(crate) const CAPTION_PX: f64 = 20.0;
/// Axis description size (px).
pub(crate) const AXIS_DESC_PX: f64 = 18.0;
/// Tick label and legend size (px).
pub(crate) const LABEL_PX: f64 = 15.0;
/// Text shown in a panel with nothing to plot.
pub(crate) const NO_DATA: &str = "no finite data";

/// How a series is marked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    /// A line through consecutive finite samples, broken at gaps.
    Line,
    /// A small filled dot per finite sample.
    Dot,
    /// A hollow circle per finite sample (stays visible under dots drawn later).
    Circle,
}

/// 20 colours that stay distinguishable side by side: the first ten are the Tableau 10
/// (blue, orange, green, red, ... so two or three series get the usual contrast), the next
/// ten are darker or more saturated tones chosen to differ from all of them.
const PALETTE: [RGBColor; 20] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(0, 0, 128),
    RGBColor(128, 0, 0),
    RGBColor(0, 128, 128),
    RGBColor(0, 0, 0),
    RGBColor(230, 171, 2),
    RGBColor(197, 27, 125),
    RGBColor(27, 94, 32),
    RGBColor(94, 60, 153),
    RGBColor(251, 154, 153),
    RGBColor(102, 102, 0),
];

/// Colour of the `i`-th series (cycles after 20).
pub(crate) fn palette(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Dot colour of estimates / residuals (the paper's dots).
pub(crate) const DOT_COLOUR: RGBColor = RGBColor(31, 119, 180);
/// Colour of the +-3-sigma bound lines.
pub(crate) const BOUND_COLOUR: RGBColor = RGBColor(214, 39, 40);

pub(crate) fn font(size_px: f64) -> TextStyle<'static> {
    TextStyle::from((FAMILY, size_px).into_font()).color(&BLACK)
}

/// The figure's drawing area below its title, with a margin around the whole figure.
pub(crate) fn titled<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    title: &str,
) -> Result<DrawingArea<DB, Shift>, DrawError> {
    Ok(root.margin(10, 6, 6, 10).titled(title, font(TITLE_PX))?)
}

/// One legend row.
pub(crate) struct LegendEntry {
    pub name: String,
    pub colour: RGBColor,
    pub mark: Mark,
}

const LEGEND_ROW_PX: i32 = 24;
const LEGEND_SAMPLE_PX: i32 = 30;

/// Width (px) a legend with `entries` needs, never more than a third of `total_px`.
pub(crate) fn legend_width<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[LegendEntry],
    total_px: u32,
) -> Result<u32, DrawError> {
    let mut widest = 0;
    for e in entries {
        widest = widest.max(area.estimate_text_size(&e.name, &font(LABEL_PX))?.0);
    }
    Ok((widest + LEGEND_SAMPLE_PX as u32 + 30).clamp(100, total_px / 3))
}

/// Draw the legend in its own strip (beside the plots, so it never covers data), starting
/// `top_px` below the strip's top.
pub(crate) fn draw_legend<DB: DrawingBackend>(
    strip: &DrawingArea<DB, Shift>,
    entries: &[LegendEntry],
    top_px: i32,
) -> Result<(), DrawError> {
    for (row, e) in entries.iter().enumerate() {
        let y = top_px + LEGEND_ROW_PX * row as i32 + LEGEND_ROW_PX / 2;
        let (x0, x1) = (8, 8 + LEGEND_SAMPLE_PX);
        match e.mark {
            Mark::Line => strip.draw(&PathElement::new(
                vec![(x0, y), (x1, y)],
                e.colour.stroke_width(2),
            ))?,
            Mark::Dot => strip.draw(&Circle::new(((x0 + x1) / 2, y), 3, e.colour.filled()))?,
            Mark::Circle => strip.draw(&Circle::new(((x0 + x1) / 2, y), 4, e.colour))?,
        }
        let style = font(LABEL_PX).pos(Pos::new(HPos::Left, VPos::Center));
        strip.draw(&Text::new(e.name.clone(), (x1 + 8, y), style))?;
    }
    Ok(())
}

/// Grid, ticks and axis descriptions in the crate's style (faint grid so data dominates).
pub(crate) fn draw_mesh<DB, X, Y>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
    x_desc: Option<&str>,
    y_desc: &str,
) -> Result<(), DrawError>
where
    DB: DrawingBackend,
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    let mut mesh = chart.configure_mesh();
    mesh.y_desc(y_desc)
        .label_style(font(LABEL_PX))
        .axis_desc_style(font(AXIS_DESC_PX))
        .bold_line_style(RGBColor(200, 200, 200))
        .light_line_style(RGBColor(238, 238, 238))
        .x_labels(10)
        .y_labels(8)
        .x_label_formatter(&tick_label)
        .y_label_formatter(&tick_label);
    if let Some(x) = x_desc {
        mesh.x_desc(x);
    }
    mesh.draw()?;
    Ok(())
}

/// Write "no finite data" in the middle of a plotting area.
pub(crate) fn draw_no_data<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
) -> Result<(), DrawError> {
    let (w, h) = area.dim_in_pixel();
    let style = font(CAPTION_PX).pos(Pos::new(HPos::Center, VPos::Center));
    area.draw(&Text::new(NO_DATA, (w as i32 / 2, h as i32 / 2), style))?;
    Ok(())
}

/// Smallest and largest finite value, `None` if there is none.
pub(crate) fn finite_range(values: impl IntoIterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .into_iter()
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

/// Union of two optional ranges.
pub(crate) fn union(a: Option<(f64, f64)>, b: Option<(f64, f64)>) -> Option<(f64, f64)> {
    match (a, b) {
        (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
        (a, None) => a,
        (None, b) => b,
    }
}

/// An axis range around `range` with `frac` of its width added on each side; a single value
/// gets +-10 % of itself (or +-1 around zero); no data gives 0..1.
pub(crate) fn padded(range: Option<(f64, f64)>, frac: f64) -> (f64, f64) {
    match range {
        None => (0.0, 1.0),
        Some((lo, hi)) if hi > lo => {
            let pad = (hi - lo) * frac;
            (lo - pad, hi + pad)
        }
        Some((v, _)) => {
            let half = if v == 0.0 { 1.0 } else { v.abs() * 0.1 };
            (v - half, v + half)
        }
    }
}

/// The `q` quantile (0..1, nearest rank) of the finite values, `None` if there is none.
pub(crate) fn quantile(values: impl IntoIterator<Item = f64>, q: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let idx = ((v.len() - 1) as f64 * q).round() as usize;
    v.get(idx.min(v.len() - 1)).copied()
}

/// Clip the segment `a`-`b` to the box (Liang-Barsky); `None` if it lies outside.
fn clip_segment(
    a: (f64, f64),
    b: (f64, f64),
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
) -> Option<((f64, f64), (f64, f64))> {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
    for (p, q) in [
        (-dx, a.0 - x0),
        (dx, x1 - a.0),
        (-dy, a.1 - y0),
        (dy, y1 - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    (t0 <= t1).then_some({
        (
            (a.0 + t0 * dx, a.1 + t0 * dy),
            (a.0 + t1 * dx, a.1 + t1 * dy),
        )
    })
}

/// Polylines through the finite `(x, y)` samples inside the box: broken at non-finite samples
/// (gaps: not sampled, not updated) and clipped where they leave the box. plotters itself only
/// clamps points to the plotting area, which would draw out-of-range parts along its border.
pub(crate) fn clipped_runs(
    x: &[f64],
    y: &[f64],
    x_range: (f64, f64),
    y_range: (f64, f64),
) -> Vec<Vec<(f64, f64)>> {
    let mut runs = Vec::new();
    let mut run: Vec<(f64, f64)> = Vec::new();
    let mut prev: Option<(f64, f64)> = None;
    for (&xi, &yi) in x.iter().zip(y) {
        let p = (xi.is_finite() && yi.is_finite()).then_some((xi, yi));
        if let (Some(a), Some(b)) = (prev, p) {
            match clip_segment(a, b, x_range, y_range) {
                Some((ca, cb)) => {
                    if run.last() != Some(&ca) {
                        flush(&mut runs, &mut run);
                        run.push(ca);
                    }
                    run.push(cb);
                }
                None => flush(&mut runs, &mut run),
            }
        } else {
            flush(&mut runs, &mut run);
        }
        prev = p;
    }
    flush(&mut runs, &mut run);
    runs
}

fn flush(runs: &mut Vec<Vec<(f64, f64)>>, run: &mut Vec<(f64, f64)>) {
    if run.len() >= 2 {
        runs.push(std::mem::take(run));
    } else {
        run.clear();
    }
}

/// The finite `(x, y)` samples inside the box (for dots).
pub(crate) fn points_inside(
    x: &[f64],
    y: &[f64],
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
) -> Vec<(f64, f64)> {
    x.iter()
        .zip(y)
        .filter(|(xi, yi)| (x0..=x1).contains(*xi) && (y0..=y1).contains(*yi))
        .map(|(&xi, &yi)| (xi, yi))
        .collect()
}

/// A tick label without trailing zeros ("20", "0.5", "1e-5"): plotters' default prints
/// "20.0", and its log axis prints Rust's Debug form.
pub(crate) fn tick_label(x: &f64) -> String {
    // plotters accumulates its linear tick values, so the tick at zero can arrive as
    // 2e-17; no pdcal axis has genuine ticks this small.
    let x = if x.abs() < 1e-15 { 0.0 } else { *x };
    if x == 0.0 || !x.is_finite() {
        return if x == 0.0 {
            "0".to_owned()
        } else {
            format!("{x}")
        };
    }
    if !(1e-4..1e6).contains(&x.abs()) {
        // Shortest form that round-trips the tick value, e.g. "1e-5", "2.5e6".
        return format!("{x:e}");
    }
    let fixed = format!("{x:.6}");
    let trimmed = fixed.trim_end_matches('0').trim_end_matches('.');
    if trimmed == "-0" {
        "0".to_owned()
    } else {
        trimmed.to_owned()
    }
}

/// `x` with `sig` significant digits, plain notation between 1e-4 and 1e6.
pub(crate) fn fmt_sig(x: f64, sig: i32) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".to_owned();
    }
    let mag = x.abs().log10().floor() as i32;
    if !(-4..6).contains(&mag) {
        return format!("{:.*e}", (sig - 1).max(0) as usize, x);
    }
    let decimals = (sig - 1 - mag).clamp(0, 12) as usize;
    format!("{x:.decimals$}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_break_at_nan_and_clip_at_the_box() {
        let x = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        let y = [0.0, 0.5, f64::NAN, 0.5, 2.0, 0.5];
        let runs = clipped_runs(&x, &y, (0.0, 5.0), (0.0, 1.0));
        // Run 1: samples 0-1. Run 2: 3 -> exit at y = 1 (x = 3 + 1/3). Run 3: re-entry at
        // y = 1 (x = 4 + 2/3) -> 5. Exact in binary up to rounding of the thirds.
        assert_eq!(runs.len(), 3);
        assert_eq!(runs[0], vec![(0.0, 0.0), (1.0, 0.5)]);
        assert!((runs[1][1].0 - (3.0 + 1.0 / 3.0)).abs() < 1e-12 && runs[1][1].1 == 1.0);
        assert!((runs[2][0].0 - (4.0 + 2.0 / 3.0)).abs() < 1e-12 && runs[2][0].1 == 1.0);
        assert_eq!(runs[2][1], (5.0, 0.5));
    }

    #[test]
    fn ranges_and_formatting() {
        assert_eq!(
            finite_range([f64::NAN, 2.0, -1.0, f64::INFINITY]),
            Some((-1.0, 2.0))
        );
        assert_eq!(finite_range([f64::NAN]), None);
        assert_eq!(padded(None, 0.05), (0.0, 1.0));
        assert_eq!(padded(Some((0.0, 0.0)), 0.05), (-1.0, 1.0));
        assert_eq!(fmt_sig(0.99312, 4), "0.9931");
        assert_eq!(fmt_sig(9.1, 4), "9.100");
        assert_eq!(fmt_sig(1234.0, 4), "1234");
        assert_eq!(fmt_sig(2.5e-7, 3), "2.50e-7");
        assert_eq!(tick_label(&20.0), "20");
        assert_eq!(
            tick_label(&2.3125783e-17),
            "0",
            "accumulated tick noise at zero"
        );
        assert_eq!(tick_label(&0.30000000000000004), "0.3");
        assert_eq!(tick_label(&-0.5), "-0.5");
        assert_eq!(tick_label(&1e-5), "1e-5");
        assert_eq!(quantile([3.0, 1.0, f64::NAN, 2.0], 0.5), Some(2.0));
    }
}
