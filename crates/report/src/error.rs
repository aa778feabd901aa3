//! The crate's error type.

use std::path::PathBuf;

use plotters::drawing::DrawingAreaErrorKind;

/// What can go wrong while making a figure or the index page.
///
/// Data without any finite value is *not* an error: it gives an empty-but-valid figure with a
/// "no finite data" note (see the crate docs). Errors are for structural problems only.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// The file stem is empty, too long, starts with '.', or has characters other than
    /// `A-Z a-z 0-9 . _ -` (it becomes a file name and an HTML link).
    #[error(
        "invalid figure stem {stem:?}: use 1-100 characters of A-Z a-z 0-9 . _ -, not starting with '.'"
    )]
    InvalidStem {
        /// The rejected stem.
        stem: String,
    },
    /// The requested image size is outside the supported range.
    #[error(
        "figure {stem}: size {width_px}x{height_px} px is outside {min_px}..={max_px} px per side"
    )]
    InvalidSize {
        /// Figure stem.
        stem: String,
        /// Requested width (px).
        width_px: u32,
        /// Requested height (px).
        height_px: u32,
        /// Smallest allowed side (px).
        min_px: u32,
        /// Largest allowed side (px).
        max_px: u32,
    },
    /// A list that must not be empty (panels, series, direction sets) is empty, or longer than
    /// the figure can show.
    #[error("figure {stem}: {what} must have {min}..={max} entries, got {found}")]
    Count {
        /// Figure stem.
        stem: String,
        /// Which list.
        what: &'static str,
        /// Entries given.
        found: usize,
        /// Fewest allowed.
        min: usize,
        /// Most allowed.
        max: usize,
    },
    /// Two slices that must be sample-aligned have different lengths.
    #[error("figure {stem}: {what} has {found} samples but the time axis has {expected}")]
    LengthMismatch {
        /// Figure stem.
        stem: String,
        /// Which slice (panel or series name and field).
        what: String,
        /// Its length.
        found: usize,
        /// The time axis length.
        expected: usize,
    },
    /// Any other invalid argument (bin count, axis range, ...).
    #[error("figure {stem}: {message}")]
    InvalidArgument {
        /// Figure stem.
        stem: String,
        /// What is wrong, with the offending value.
        message: String,
    },
    /// The embedded font was rejected by plotters' font registry.
    #[error("the embedded DejaVu Sans font could not be registered with plotters")]
    Font,
    /// plotters failed while drawing.
    #[error("figure {stem}: rendering the {format} failed: {message}")]
    Render {
        /// Figure stem.
        stem: String,
        /// "PNG" or "SVG".
        format: &'static str,
        /// plotters' message.
        message: String,
    },
    /// The PNG encoder failed.
    #[error("figure {stem}: PNG encoding failed: {source}")]
    Encode {
        /// Figure stem.
        stem: String,
        /// The encoder's error.
        #[source]
        source: image::ImageError,
    },
    /// Creating, writing or renaming a file failed (no partial file is left behind).
    #[error("writing {path}: {source}")]
    Io {
        /// The file (temporary or final) being written.
        path: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
}

/// A plotters failure with the backend type erased.
pub(crate) struct DrawError(pub String);

impl<E: std::error::Error + Send + Sync> From<DrawingAreaErrorKind<E>> for DrawError {
    fn from(e: DrawingAreaErrorKind<E>) -> Self {
        Self(e.to_string())
    }
}
