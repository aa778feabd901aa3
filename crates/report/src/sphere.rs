//! Body-frame directions as an azimuth/elevation scatter (paper Fig. 3).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use crate::axes::DegreeAxis;
use crate::render::{DrawError, Figure, Plot, Written, check_figure, render};
use crate::style::{self, LegendEntry, Mark};
use crate::{MAX_SERIES, ReportError};

/// Unit vectors in the body frame from one source (e.g. one data set).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DirectionSet<'a> {
    /// Legend name.
    pub name: &'a str,
    /// Directions `[x, y, z]` in the body frame (any positive length; normalised here).
    /// Non-finite or zero vectors are skipped.
    pub dirs_body: &'a [[f64; 3]],
}

/// Azimuth and elevation (deg) of `v_body`, the inverse of the paper's Eq. (16)
/// `n = [cos el cos az, cos el sin az, sin el]`: `az = atan2(y, x)` in -180..180,
/// `el = asin(z / |v|)` in -90..90. `None` for a zero or non-finite vector.
pub fn az_el_deg(v_body: [f64; 3]) -> Option<(f64, f64)> {
    let [x, y, z] = v_body;
    let norm = (x * x + y * y + z * z).sqrt();
    if !(norm.is_finite() && norm > 0.0) {
        return None;
    }
    let el = (z / norm).clamp(-1.0, 1.0).asin();
    Some((y.atan2(x).to_degrees(), el.to_degrees()))
}

/// Write `<stem>.png` and `<stem>.svg`: each set's directions as dots on azimuth (-180..180
/// deg, ticks every 45 deg) against elevation (-90..90 deg, ticks every 30 deg), one colour
/// per set, with a legend beside the chart when there is more than one set.
///
/// Sets without any valid vector give an empty chart with "no finite data".
///
/// Errors: invalid stem or size, 0 or more than [`MAX_SERIES`] sets, or an I/O / rendering
/// failure.
pub fn sphere_directions(
    out_dir: &Path,
    figure: &Figure<'_>,
    sets: &[DirectionSet<'_>],
) -> Result<Written, ReportError> {
    check_figure(figure)?;
    if sets.is_empty() || sets.len() > MAX_SERIES {
        return Err(ReportError::Count {
            stem: figure.stem.to_owned(),
            what: "direction sets",
            found: sets.len(),
            min: 1,
            max: MAX_SERIES,
        });
    }
    let points: Vec<Vec<(f64, f64)>> = sets
        .iter()
        .map(|s| s.dirs_body.iter().filter_map(|&v| az_el_deg(v)).collect())
        .collect();
    let plot = SpherePlot {
        title: figure.title,
        sets,
        points,
    };
    render(out_dir, figure, &plot)
}

struct SpherePlot<'a> {
    title: &'a str,
    sets: &'a [DirectionSet<'a>],
    points: Vec<Vec<(f64, f64)>>,
}

impl Plot for SpherePlot<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), DrawError> {
        let body = style::titled(root, self.title)?;
        let area = if self.sets.len() > 1 {
            let legend: Vec<LegendEntry> = self
                .sets
                .iter()
                .enumerate()
                .map(|(i, s)| LegendEntry {
                    name: s.name.to_owned(),
                    colour: style::palette(i),
                    mark: Mark::Dot,
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
        let mut chart = ChartBuilder::on(&area)
            .margin(10)
            .x_label_area_size(55)
            .y_label_area_size(75)
            .build_cartesian_2d(
                DegreeAxis::new(-180.0, 180.0, 45.0),
                DegreeAxis::new(-90.0, 90.0, 30.0),
            )?;
        style::draw_mesh(&mut chart, Some("azimuth (deg)"), "elevation (deg)")?;
        if self.points.iter().all(Vec::is_empty) {
            return style::draw_no_data(&chart.plotting_area().strip_coord_spec());
        }
        for (i, pts) in self.points.iter().enumerate() {
            let colour = style::palette(i);
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 2, colour.filled())))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn az_el_inverts_eq16() {
        // Round trip through Eq. (16) on a grid; 1e-9 deg is far below any plotted pixel and
        // well above the f64 rounding of asin/atan2 (~1e-14 deg).
        for az in (-170..=180).step_by(10) {
            for el in (-80..=80).step_by(20) {
                let (a, e) = (f64::from(az).to_radians(), f64::from(el).to_radians());
                let v = [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()];
                let (az2, el2) = az_el_deg([2.0 * v[0], 2.0 * v[1], 2.0 * v[2]]).unwrap();
                assert!((az2 - f64::from(az)).abs() < 1e-9, "az {az} -> {az2}");
                assert!((el2 - f64::from(el)).abs() < 1e-9, "el {el} -> {el2}");
            }
        }
        assert_eq!(az_el_deg([0.0, 0.0, 0.0]), None);
        assert_eq!(az_el_deg([f64::NAN, 0.0, 1.0]), None);
        assert_eq!(az_el_deg([0.0, 0.0, 3.0]).map(|(_, e)| e), Some(90.0));
    }
}
