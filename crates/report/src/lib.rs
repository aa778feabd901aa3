//! Figures of a pdcal run (PNG and SVG) and the run's `index.html`.
//!
//! This crate owns the look of the report: it draws plain data (slices of `f64`, time in
//! minutes) and knows nothing of the other pdcal crates, so the driver decides what goes in
//! each figure. Every figure function writes `<out_dir>/<stem>.png` and `<out_dir>/<stem>.svg`
//! and returns their paths ([`Written`]).
//!
//! | function | paper figure | content |
//! | --- | --- | --- |
//! | [`series_with_bounds`] | 4, 5-7 | dots of a residual / estimate / estimation error and its `+-3 sigma` lines, panels stacked on one time axis |
//! | [`lines`] | 2, 10, 12-13 | several series over time as lines, dots or circles, linear or log y |
//! | [`histograms`] | 8-9, 11 | one or more histograms side by side with mean, std and count printed |
//! | [`sphere_directions`] | 3 | body-frame unit vectors as azimuth / elevation dots |
//! | [`index_html`] | - | summary table and every figure (PNG, linking the SVG) |
//!
//! # Conventions
//!
//! - Time axes are in minutes (`t_min`); units of the other axes are in the caller's labels.
//! - NaN (or infinite) samples are gaps: not drawn, and lines break there. Bound lines are
//!   broken where `sigma` is NaN or negative.
//! - **No finite data is not an error**: a panel whose samples are all NaN (or empty) is drawn
//!   as a valid empty panel with the text "no finite data" (a photodiode that was never lit
//!   should not stop the report). Structural problems are errors ([`ReportError`]): bad stem
//!   or size, no panels / series, mismatched slice lengths, invalid bin count or axis range.
//! - Azimuth / elevation follow the paper's Eq. (16): `n = [cos el cos az, cos el sin az,
//!   sin el]` ([`az_el_deg`]).
//! - Legends sit in a strip beside the plots, never over the data; a legend is drawn only
//!   when there is more than one series.
//!
//! # Files
//!
//! Each write is atomic: the bytes are rendered in memory, written to a hidden temporary file
//! in `out_dir` (`.<name>.tmp-<pid>-<n>`), synced, and renamed over the final name. A figure's
//! PNG and SVG are renamed only after both temporaries are complete; on any failure the
//! temporaries are removed, so no partial file remains.
//!
//! # Why some things are written here
//!
//! - The text font is DejaVu Sans embedded with `include_bytes!` and registered with plotters'
//!   `ab_glyph` registry under the family name "sans-serif": build machines and CI have no
//!   system fonts (licence: `fixtures/fonts/DejaVu-LICENSE.txt`).
//! - Line clipping (Liang-Barsky): plotters clamps out-of-range points onto the plot border,
//!   which draws bounds that leave the axis range as lines along the frame.
//! - Histogram binning and mean/std: a few lines, and they must match the printed numbers.
//! - The legend: plotters draws its series legend inside the plotting area, over the data.
//! - The degree axis of [`sphere_directions`]: ticks every 45 / 30 deg instead of plotters'
//!   1-2-5 steps.

mod axes;
mod bounds;
mod error;
mod histogram;
mod html;
mod lines;
mod render;
mod sphere;
mod style;

pub use bounds::{BoundsPanel, N_SIGMA, series_with_bounds};
pub use error::ReportError;
pub use histogram::{BinRange, HistogramPanel, MAX_BINS, bin_counts, histograms, mean_std};
pub use html::{Table, index_html, index_html_with_tables};
pub use lines::{LineAxes, Series, YScale, lines};
pub use render::{Figure, MAX_SIDE_PX, MIN_SIDE_PX, Written};
pub use sphere::{DirectionSet, az_el_deg, sphere_directions};
pub use style::Mark;

/// Most panels [`series_with_bounds`] stacks in one figure.
pub const MAX_PANELS: usize = 8;
/// Most series in one [`lines`] chart, and most sets in [`sphere_directions`].
pub const MAX_SERIES: usize = 40;
/// Most side-by-side panels in [`histograms`].
pub const MAX_HISTOGRAMS: usize = 4;
