//! The figures of a calibration, after the paper's Figs. 2-12, and index.html.

use std::path::Path;

use anyhow::Result;
use pdcal_dataset::Telemetry;
use pdcal_filter::{Sensor, StepEstimate};
use pdcal_report::{
    BinRange, BoundsPanel, DirectionSet, Figure, HistogramPanel, LineAxes, Mark, Series, YScale,
    histograms, lines, series_with_bounds, sphere_directions,
};

use crate::schema::{Outcome, Summary};
use crate::stream::stride_for;
use crate::sunvec::SunVectorPoint;

/// A written figure: caption and file stem.
pub type FigureEntry = (String, String);

/// Photodiodes shown in the per-photodiode figures (the paper shows 1-3).
const SHOWN: usize = 3;

/// Every `stride`-th element: a long series cut to at most
/// [`crate::stream::FIGURE_POINTS`] points for a figure.
fn every<T: Clone>(values: &[T], stride: usize) -> Vec<T> {
    values.iter().step_by(stride.max(1)).cloned().collect()
}

fn minutes(t_s: &[f64]) -> Vec<f64> {
    t_s.iter().map(|t| t / 60.0).collect()
}

/// The points of a time series with a break (a NaN point) inserted wherever a new segment
/// starts: figures draw a gap as a gap, not as a line across it.
struct Broken {
    /// Times, min.
    t_min: Vec<f64>,
    /// Index into the original series; `None` at a break.
    at: Vec<Option<usize>>,
}

impl Broken {
    /// Breaks before every point `i` where `starts(i)` holds.
    fn new(t_s: &[f64], starts: impl Fn(usize) -> bool) -> Self {
        let mut broken = Broken {
            t_min: Vec::with_capacity(t_s.len()),
            at: Vec::with_capacity(t_s.len()),
        };
        for (i, &t) in t_s.iter().enumerate() {
            if i > 0 && starts(i) {
                broken.t_min.push(0.5 * (t_s[i - 1] + t) / 60.0);
                broken.at.push(None);
            }
            broken.t_min.push(t / 60.0);
            broken.at.push(Some(i));
        }
        broken
    }

    /// Breaks between the estimates of different segments.
    fn segments(estimates: &[StepEstimate]) -> Self {
        let t: Vec<f64> = estimates.iter().map(|e| e.t_s).collect();
        Broken::new(&t, |i| estimates[i].segment != estimates[i - 1].segment)
    }

    /// Breaks where consecutive times are further apart than the gap rule (ten median
    /// spacings, at least the floor), for series that carry no segment.
    fn time_gaps(t_s: &[f64]) -> Self {
        let spacing = pdcal_filter::median_spacing(t_s.iter().copied()).unwrap_or(1.0);
        let gap_s = (pdcal_filter::segments::GAP_SPACINGS * spacing)
            .max(pdcal_filter::segments::GAP_FLOOR_S);
        Broken::new(t_s, |i| t_s[i] - t_s[i - 1] > gap_s)
    }

    /// `value(i)` at every point, NaN at the breaks.
    fn pick(&self, value: impl Fn(usize) -> f64) -> Vec<f64> {
        self.at.iter().map(|i| i.map_or(f64::NAN, &value)).collect()
    }
}

/// Writes Figs. 2-12 into `dir`; returns what was written.
pub fn calibration_figures(
    dir: &Path,
    telemetry: &Telemetry,
    outcome: &Outcome,
) -> Result<Vec<FigureEntry>> {
    let mut out = Vec::new();
    raw_outputs(dir, telemetry, &mut out)?;
    sun_directions(dir, outcome, &mut out)?;
    residuals(dir, outcome, &mut out)?;
    estimates(dir, &outcome.run.forward, &mut out)?;
    magnitudes(dir, outcome, &mut out)?;
    attitude_sigma(dir, &outcome.run.forward, &mut out)?;
    Ok(out)
}

fn push(out: &mut Vec<FigureEntry>, caption: &str, stem: &str) {
    out.push((caption.to_owned(), stem.to_owned()));
}

fn raw_outputs(dir: &Path, telemetry: &Telemetry, out: &mut Vec<FigureEntry>) -> Result<()> {
    for (stem, which) in raw_outputs_figure(dir, telemetry, "Raw photodiode outputs")? {
        push(
            out,
            &format!("Fig. 2: raw photodiode outputs{which}"),
            &stem,
        );
    }
    Ok(())
}

/// Photodiodes per page of Fig. 2 when they are more than [`pdcal_report::MAX_SERIES`]:
/// few enough that each line's colour and legend entry can still be told apart.
pub const RAW_OUTPUTS_PER_PAGE: usize = 20;

/// The pages of Fig. 2 for `m` photodiodes: one figure `fig02_raw_outputs` for up to
/// [`pdcal_report::MAX_SERIES`], else pages of [`RAW_OUTPUTS_PER_PAGE`], the first keeping
/// that stem and the others `fig02_raw_outputs_pN`; each with its photodiode range and the
/// caption's suffix naming it.
pub fn raw_output_pages(m: usize) -> Vec<(String, std::ops::Range<usize>, String)> {
    if m <= pdcal_report::MAX_SERIES {
        return vec![("fig02_raw_outputs".to_owned(), 0..m, String::new())];
    }
    (0..m.div_ceil(RAW_OUTPUTS_PER_PAGE))
        .map(|page| {
            let range = page * RAW_OUTPUTS_PER_PAGE..((page + 1) * RAW_OUTPUTS_PER_PAGE).min(m);
            let stem = match page {
                0 => "fig02_raw_outputs".to_owned(),
                _ => format!("fig02_raw_outputs_p{}", page + 1),
            };
            let which = format!(", pd{:02}-pd{:02}", range.start + 1, range.end);
            (stem, range, which)
        })
        .collect()
}

/// Fig. 2: every photodiode's raw output over time (`fig02_raw_outputs` in `dir`, in pages
/// for many photodiodes, [`raw_output_pages`]); empty cells are gaps. Returns each page's
/// stem and the caption suffix naming its photodiodes.
pub fn raw_outputs_figure(
    dir: &Path,
    telemetry: &Telemetry,
    title: &str,
) -> Result<Vec<(String, String)>> {
    let stride = stride_for(telemetry.len());
    let broken = Broken::time_gaps(&every(&telemetry.t_s, stride));
    let t = &broken.t_min;
    let mut pages = Vec::new();
    for (stem, range, which) in raw_output_pages(telemetry.pd_v.len()) {
        let columns: Vec<Vec<f64>> = telemetry.pd_v[range.clone()]
            .iter()
            .map(|c| broken.pick(|i| c.get(i * stride).unwrap_or(f64::NAN)))
            .collect();
        let names: Vec<String> = range.map(|i| format!("pd{:02}", i + 1)).collect();
        let series: Vec<Series> = columns
            .iter()
            .zip(&names)
            .map(|(c, n)| Series::new(n, c, Mark::Line))
            .collect();
        let page_title = format!("{title}{which}");
        let figure = Figure::new(&stem, &page_title);
        lines(
            dir,
            &figure,
            &LineAxes::new("time (min)", "output (V)"),
            t,
            &series,
        )?;
        pages.push((stem, which));
    }
    Ok(pages)
}

fn sun_directions(dir: &Path, outcome: &Outcome, out: &mut Vec<FigureEntry>) -> Result<()> {
    let points = &outcome.sun_vector.points;
    let all: Vec<[f64; 3]> = points.iter().map(|p| p.direction_initial_body).collect();
    let dirs = &every(&all, stride_for(all.len()));
    let figure = Figure::new(
        "fig03_sun_directions",
        "Measured Sun directions in the body frame (initial parameters)",
    );
    sphere_directions(
        dir,
        &figure,
        &[DirectionSet {
            name: "Sun direction",
            dirs_body: dirs,
        }],
    )?;
    push(
        out,
        "Fig. 3: measured Sun directions, body frame",
        "fig03_sun_directions",
    );
    Ok(())
}

/// Residuals of photodiodes 1-3 on the rows of the run's forward estimates (every row, or
/// every few rows of a long streamed run; NaN where not updated).
fn residuals(dir: &Path, outcome: &Outcome, out: &mut Vec<FigureEntry>) -> Result<()> {
    let run = &outcome.run;
    let figure = Figure::new("fig04_residuals", "Photodiode residuals and 3-sigma bounds");
    residuals_figure(dir, &figure, run, (0..usize::MAX, 0.0))?;
    push(
        out,
        "Fig. 4: residuals with 3-sigma bounds",
        "fig04_residuals",
    );
    // A joint calibration: each set's own, on its own time from its epoch.
    for (n, set) in outcome.datasets.iter().enumerate() {
        let span = &set.span;
        let stem = format!("fig04_residuals_set{}", n + 1);
        let title = format!("Photodiode residuals and 3-sigma bounds: {}", span.name);
        let rows = span.first_row..span.first_row + span.rows;
        residuals_figure(dir, &Figure::new(&stem, &title), run, (rows, span.offset_s))?;
        push(
            out,
            &format!("Fig. 4, data set {} ({}): residuals", n + 1, span.name),
            &stem,
        );
    }
    Ok(())
}

/// Residuals of photodiodes 1-3 with their bounds, of the estimate rows `rows`, time from
/// `offset_s` (a joint calibration's set epoch).
fn residuals_figure(
    dir: &Path,
    figure: &Figure,
    run: &pdcal_filter::CalibrationRun,
    (rows, offset_s): (std::ops::Range<usize>, f64),
) -> Result<()> {
    let forward: Vec<StepEstimate> = run
        .forward
        .iter()
        .filter(|e| rows.contains(&e.index))
        .map(|e| StepEstimate {
            t_s: e.t_s - offset_s,
            ..e.clone()
        })
        .collect();
    let broken = Broken::segments(&forward);
    let t = &broken.t_min;
    // The plotted point of each estimate (breaks between segments stay NaN).
    let mut point = vec![0; forward.len()];
    for (p, at) in broken.at.iter().enumerate() {
        if let Some(k) = at {
            point[*k] = p;
        }
    }
    let index: Vec<usize> = forward.iter().map(|e| e.index).collect();
    let n = t.len();
    let shown = SHOWN.min(run.calibration.photodiodes.len());
    let mut value = vec![vec![f64::NAN; n]; shown];
    let mut sigma = vec![vec![f64::NAN; n]; shown];
    for r in &run.residuals {
        if let Sensor::Photodiode(i) = r.sensor
            && i < shown
            && let Ok(k) = index.binary_search(&r.index)
        {
            value[i][point[k]] = r.residual;
            sigma[i][point[k]] = r.bound_3sigma / 3.0;
        }
    }
    let labels: Vec<String> = (1..=shown).map(|i| format!("photodiode {i}")).collect();
    let panels: Vec<BoundsPanel> = (0..shown)
        .map(|i| BoundsPanel::new(&labels[i], "residual (V)", t, &value[i], &sigma[i]))
        .collect();
    series_with_bounds(dir, figure, "time (min)", "residual", &panels)?;
    Ok(())
}

/// Scale, azimuth and elevation estimates of photodiodes 1-3 with 3-sigma bounds (Figs. 5-7).
fn estimates(dir: &Path, forward: &[StepEstimate], out: &mut Vec<FigureEntry>) -> Result<()> {
    let broken = Broken::segments(forward);
    let t = &broken.t_min;
    let shown = SHOWN.min(
        forward
            .first()
            .map_or(0, |e| e.calibration.photodiodes.len()),
    );
    type Pick = fn(&pdcal_filter::PdCalibration) -> (f64, f64);
    let quantities: [(&str, &str, &str, &str, Pick); 3] = [
        (
            "fig05_scale",
            "Scale factor estimates",
            "C (V)",
            "Fig. 5: scale factors with 3-sigma bounds",
            |p| (p.scale_v, p.scale_sigma_v),
        ),
        (
            "fig06_azimuth",
            "Azimuth estimates",
            "azimuth (deg)",
            "Fig. 6: azimuths with 3-sigma bounds",
            |p| (p.azimuth_deg, p.azimuth_sigma_deg.unwrap_or(f64::NAN)),
        ),
        (
            "fig07_elevation",
            "Elevation estimates",
            "elevation (deg)",
            "Fig. 7: elevations with 3-sigma bounds",
            |p| (p.elevation_deg, p.elevation_sigma_deg),
        ),
    ];
    for (stem, title, y_label, caption, pick) in quantities {
        let series: Vec<(Vec<f64>, Vec<f64>)> = (0..shown)
            .map(|i| {
                let at = |k: usize| pick(&forward[k].calibration.photodiodes[i]);
                (broken.pick(|k| at(k).0), broken.pick(|k| at(k).1))
            })
            .collect();
        let labels: Vec<String> = (1..=shown).map(|i| format!("photodiode {i}")).collect();
        let panels: Vec<BoundsPanel> = series
            .iter()
            .zip(&labels)
            .map(|((v, s), l)| BoundsPanel::new(l, y_label, t, v, s).around(v))
            .collect();
        series_with_bounds(
            dir,
            &Figure::new(stem, title),
            "time (min)",
            "estimate",
            &panels,
        )?;
        push(out, caption, stem);
    }
    Ok(())
}

fn magnitudes(dir: &Path, outcome: &Outcome, out: &mut Vec<FigureEntry>) -> Result<()> {
    let points = &outcome.sun_vector.points;
    let column = |f: fn(&SunVectorPoint) -> f64| -> Vec<f64> { points.iter().map(f).collect() };
    let (initial, calibrated) = (
        column(|p| p.magnitude_initial),
        column(|p| p.magnitude_calibrated),
    );
    let figure = Figure::new(
        "fig08_magnitude_histograms",
        "Measured Sun-vector magnitude",
    );
    let panels = [
        HistogramPanel {
            label: "initial parameters",
            values: &initial,
        },
        HistogramPanel {
            label: "calibrated parameters",
            values: &calibrated,
        },
    ];
    histograms(dir, &figure, "magnitude (-)", 40, BinRange::Shared, &panels)?;
    push(
        out,
        "Figs. 8-9: Sun-vector magnitude, initial and calibrated",
        "fig08_magnitude_histograms",
    );

    let stride = stride_for(points.len());
    let t = minutes(&every(&column(|p| p.t_s), stride));
    let (raw, calibrated) = (
        every(&column(|p| p.magnitude_uncompensated), stride),
        every(&calibrated, stride),
    );
    let series = [
        Series::new("uncompensated", &raw, Mark::Circle).with_colour([220, 40, 40]),
        Series::new("albedo compensated", &calibrated, Mark::Dot).with_colour([30, 80, 220]),
    ];
    let figure = Figure::new(
        "fig10_magnitude_time",
        "Sun-vector magnitude with and without albedo compensation",
    );
    lines(
        dir,
        &figure,
        &LineAxes::new("time (min)", "magnitude (-)"),
        &t,
        &series,
    )?;
    push(
        out,
        "Fig. 10: magnitude over time, with and without albedo compensation",
        "fig10_magnitude_time",
    );

    let figure = Figure::new(
        "fig11_direction_change",
        "Change of the measured Sun direction by the calibration",
    );
    let panels = [HistogramPanel {
        label: "initial vs calibrated",
        values: &column(|p| p.direction_change_deg),
    }];
    histograms(dir, &figure, "angle (deg)", 40, BinRange::PerPanel, &panels)?;
    push(
        out,
        "Fig. 11: Sun-direction change, initial vs calibrated",
        "fig11_direction_change",
    );
    Ok(())
}

fn attitude_sigma(dir: &Path, forward: &[StepEstimate], out: &mut Vec<FigureEntry>) -> Result<()> {
    let broken = Broken::segments(forward);
    let t = &broken.t_min;
    let axis = |k: usize| -> Vec<f64> { broken.pick(|i| forward[i].attitude_sigma_deg[k]) };
    let (x, y, z) = (axis(0), axis(1), axis(2));
    let series = [
        Series::new("x", &x, Mark::Line),
        Series::new("y", &y, Mark::Line),
        Series::new("z", &z, Mark::Line),
    ];
    let axes = LineAxes::new("time (min)", "1-sigma (deg)").with_y_scale(YScale::Log10);
    lines(
        dir,
        &Figure::new("fig12_attitude_sigma", "Attitude accuracy (1-sigma)"),
        &axes,
        t,
        &series,
    )?;
    push(
        out,
        "Fig. 12: attitude 1-sigma per body axis",
        "fig12_attitude_sigma",
    );
    Ok(())
}

/// Writes index.html: the summary table (and evaluation rows when given) and the figures.
pub fn write_index(
    dir: &Path,
    summary: &Summary,
    evaluation: Option<&[(String, String)]>,
    figures: &[FigureEntry],
) -> Result<()> {
    let magnitude = &summary.sun_vector_magnitude;
    let residuals = &summary.residuals;
    let mut rows: Vec<(String, String)> = vec![
        ("dataset".into(), summary.dataset.clone()),
        ("mode".into(), summary.mode.to_owned()),
        (
            "Sun-vector magnitude, initial (mean / std)".into(),
            mean_std_cell(&magnitude.initial),
        ),
        (
            "Sun-vector magnitude, calibrated (mean / std)".into(),
            mean_std_cell(&magnitude.calibrated),
        ),
        (
            "Sun-direction change, mean (deg)".into(),
            available(summary.sun_direction_change_deg.mean, NO_SUN_VECTOR, |x| {
                format!("{x:.2}")
            }),
        ),
        (
            "photodiode residual RMS (V)".into(),
            available(residuals.photodiode_rms_V, NO_RESIDUALS, |x| {
                format!("{x:.4}")
            }),
        ),
        (
            "photodiode residuals inside 3-sigma".into(),
            available(residuals.fraction_within_3sigma, NO_RESIDUALS, |x| {
                format!("{:.2} %", 100.0 * x)
            }),
        ),
        (
            "filter run time (s)".into(),
            format!("{:.2}", summary.runtime_s),
        ),
    ];
    if let Some(extra) = evaluation {
        rows.extend(extra.iter().cloned());
    }
    rows.extend(
        crate::tables::normals_rotation_text(summary)
            .map(|t| (crate::tables::NORMALS_ROTATION_TITLE.to_owned(), t)),
    );
    rows.extend(
        summary
            .warnings
            .iter()
            .map(|w| ("warning".to_owned(), w.clone())),
    );
    let tables: Vec<pdcal_report::Table> = [
        Some(crate::tables::photodiode_table(summary)),
        Some(crate::tables::consistency_table(&summary.consistency)),
        crate::tables::repeatability_table(summary),
        Some(crate::tables::segment_table(summary)),
    ]
    .into_iter()
    .flatten()
    .collect();
    pdcal_report::index_html_with_tables(
        dir,
        &format!("pdcal: {}", summary.dataset),
        &tables,
        &rows,
        figures,
    )?;
    Ok(())
}

/// Why the Sun-vector statistics have no sample.
const NO_SUN_VECTOR: &str = "no row in full Sun with every photodiode in use sampled and the \
     Sun vector observable (three lit photodiodes in independent directions) with both the \
     initial and the calibrated parameters";

/// Why the residual statistics have no sample.
const NO_RESIDUALS: &str = "no photodiode update was made";

/// `x` formatted, or `not available` with `why` where it could not be computed.
fn available(x: f64, why: &str, format: impl Fn(f64) -> String) -> String {
    match x.is_finite() {
        true => format(x),
        false => format!("not available: {why}"),
    }
}

/// A mean and standard deviation, each `not available` with the reason where it could not
/// be computed.
fn mean_std_cell(m: &crate::schema::MeanStd) -> String {
    if !m.mean.is_finite() {
        return format!("not available: {NO_SUN_VECTOR}");
    }
    let std = available(m.std, m.reason.unwrap_or("not finite"), |x| {
        format!("{x:.4}")
    });
    format!("{:.4} / {std}", m.mean)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_break_separates_segments_and_time_gaps() {
        let t_s = [0.0, 60.0, 120.0, 1200.0, 1260.0];
        let broken = Broken::new(&t_s, |i| i == 3);
        assert_eq!(
            broken.at,
            [Some(0), Some(1), Some(2), None, Some(3), Some(4)]
        );
        assert_eq!(broken.t_min[3], 11.0);
        let y = broken.pick(|i| i as f64);
        assert!(y[3].is_nan() && y[4] == 3.0);
        // Ten median spacings (600 s) decide a time gap.
        assert_eq!(Broken::time_gaps(&t_s).at, broken.at);
        assert!(Broken::time_gaps(&t_s[..3]).at.iter().all(Option::is_some));
    }
}
