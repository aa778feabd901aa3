//! Rendering one figure into both formats and writing the files atomically.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicU64, Ordering};

use image::ImageEncoder;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;

use crate::ReportError;
pub(crate) use crate::error::DrawError;
use crate::style::FAMILY;

/// The embedded font (DejaVu Sans, licence in fixtures/fonts/DejaVu-LICENSE.txt): the build
/// machine and CI have no system fonts, and plotters' `ab_glyph` backend draws only registered
/// fonts.
static FONT_TTF: &[u8] = include_bytes!("../../../fixtures/fonts/DejaVuSans.ttf");

/// Smallest image side (px): below this the axes, labels and legend cannot fit.
pub const MIN_SIDE_PX: u32 = 200;
/// Largest image side (px): bounds the RGB buffer (8000^2 * 3 bytes = 192 MB).
pub const MAX_SIDE_PX: u32 = 8000;

/// Name, title and pixel size of one figure. The files are `<stem>.png` and `<stem>.svg`
/// (the SVG has the same size in user units).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Figure<'a> {
    /// File stem: 1-100 characters of `A-Z a-z 0-9 . _ -`, not starting with '.'.
    pub stem: &'a str,
    /// Title printed on top of the figure.
    pub title: &'a str,
    /// Image width (px).
    pub width_px: u32,
    /// Image height (px).
    pub height_px: u32,
}

impl<'a> Figure<'a> {
    /// A 1200 x 800 px figure.
    pub fn new(stem: &'a str, title: &'a str) -> Self {
        Self {
            stem,
            title,
            width_px: 1200,
            height_px: 800,
        }
    }

    /// The same figure with another size (px).
    pub fn with_size(self, width_px: u32, height_px: u32) -> Self {
        Self {
            width_px,
            height_px,
            ..self
        }
    }
}

/// The two files written for one figure.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Written {
    /// `<out_dir>/<stem>.png`
    pub png: PathBuf,
    /// `<out_dir>/<stem>.svg`
    pub svg: PathBuf,
}

/// A validated figure that can draw itself on any plotters backend (so one drawing routine
/// serves both the bitmap and the SVG).
pub(crate) trait Plot {
    /// Draw on `root`, which is already filled white and has the figure's size.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), DrawError>;
}

/// Check the stem and size of `figure` (done before any input is looked at, so errors about
/// the name come first).
pub(crate) fn check_figure(figure: &Figure<'_>) -> Result<(), ReportError> {
    check_stem(figure.stem)?;
    let ok = |s: u32| (MIN_SIDE_PX..=MAX_SIDE_PX).contains(&s);
    if !ok(figure.width_px) || !ok(figure.height_px) {
        return Err(ReportError::InvalidSize {
            stem: figure.stem.to_owned(),
            width_px: figure.width_px,
            height_px: figure.height_px,
            min_px: MIN_SIDE_PX,
            max_px: MAX_SIDE_PX,
        });
    }
    Ok(())
}

/// A stem is a plain file name: no separators, no leading dot (hidden/temporary files), and
/// nothing that needs quoting in a URL.
pub(crate) fn check_stem(stem: &str) -> Result<(), ReportError> {
    let valid = !stem.is_empty()
        && stem.len() <= 100
        && !stem.starts_with('.')
        && stem
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'-'));
    if valid {
        Ok(())
    } else {
        Err(ReportError::InvalidStem {
            stem: stem.to_owned(),
        })
    }
}

fn ensure_font() -> Result<(), ReportError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(FAMILY, FontStyle::Normal, FONT_TTF).is_ok()
    });
    if ok { Ok(()) } else { Err(ReportError::Font) }
}

/// Render `plot` as PNG and SVG and write `<out_dir>/<stem>.{png,svg}` atomically.
pub(crate) fn render(
    out_dir: &Path,
    figure: &Figure<'_>,
    plot: &impl Plot,
) -> Result<Written, ReportError> {
    check_figure(figure)?;
    ensure_font()?;
    let png = render_png(figure, plot)?;
    let svg = render_svg(figure, plot)?;
    let written = Written {
        png: out_dir.join(format!("{}.png", figure.stem)),
        svg: out_dir.join(format!("{}.svg", figure.stem)),
    };
    write_files_atomically(&[(&written.png, &png), (&written.svg, svg.as_bytes())])?;
    Ok(written)
}

fn render_png(figure: &Figure<'_>, plot: &impl Plot) -> Result<Vec<u8>, ReportError> {
    let (w, h) = (figure.width_px, figure.height_px);
    let mut rgb = vec![255u8; w as usize * h as usize * 3];
    let render_err = |e: DrawError| ReportError::Render {
        stem: figure.stem.to_owned(),
        format: "PNG",
        message: e.0,
    };
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        draw_root(&root, plot).map_err(render_err)?;
    }
    let mut bytes = Vec::new();
    // Fast compression: the figures are mostly flat colour, so the size cost is small and the
    // encoder time stays a few ms.
    PngEncoder::new_with_quality(&mut bytes, CompressionType::Fast, FilterType::Sub)
        .write_image(&rgb, w, h, image::ColorType::Rgb8)
        .map_err(|source| ReportError::Encode {
            stem: figure.stem.to_owned(),
            source,
        })?;
    Ok(bytes)
}

fn render_svg(figure: &Figure<'_>, plot: &impl Plot) -> Result<String, ReportError> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (figure.width_px, figure.height_px))
            .into_drawing_area();
        draw_root(&root, plot).map_err(|e| ReportError::Render {
            stem: figure.stem.to_owned(),
            format: "SVG",
            message: e.0,
        })?;
    }
    Ok(svg)
}

fn draw_root<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    plot: &impl Plot,
) -> Result<(), DrawError> {
    root.fill(&WHITE)?;
    plot.draw(root)?;
    root.present()?;
    Ok(())
}

/// Write every `(path, bytes)` pair atomically: all contents go to temporary files in the
/// target directory first, and only when every one is complete are they renamed over the
/// final names. On any failure the temporary files are removed, so no partial file remains.
pub(crate) fn write_files_atomically(files: &[(&Path, &[u8])]) -> Result<(), ReportError> {
    let mut temps: Vec<PathBuf> = Vec::with_capacity(files.len());
    let result = (|| {
        for (path, bytes) in files {
            let temp = temp_path(path);
            temps.push(temp.clone());
            write_synced(&temp, bytes)?;
        }
        for ((path, _), temp) in files.iter().zip(&temps) {
            std::fs::rename(temp, path).map_err(|source| ReportError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        }
        Ok(())
    })();
    if result.is_err() {
        for temp in &temps {
            // Already renamed or never created: nothing to remove, so the error is moot.
            let _ = std::fs::remove_file(temp);
        }
    }
    result
}

/// `<dir>/.<name>.tmp-<pid>-<n>`: same directory (rename stays on one filesystem), hidden, and
/// unique per process and call.
fn temp_path(path: &Path) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}-{n}", std::process::id()))
}

fn write_synced(path: &Path, bytes: &[u8]) -> Result<(), ReportError> {
    let io = |source| ReportError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
        .map_err(io)?;
    file.write_all(bytes).map_err(io)?;
    file.sync_all().map_err(io)
}
