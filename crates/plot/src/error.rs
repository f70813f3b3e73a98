use std::path::PathBuf;

/// Why a figure could not be saved.
///
/// Every variant names the output path (without extension) it was meant for, so a driver that
/// saves many figures can report which one failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    /// The figure has no panels to draw.
    #[error("figure {path:?} has no panels")]
    EmptyFigure {
        /// Output path without extension.
        path: PathBuf,
    },
    /// The figure asks for zero columns.
    #[error("figure {path:?} has 0 columns; it needs at least 1")]
    NoColumns {
        /// Output path without extension.
        path: PathBuf,
    },
    /// The figure size is outside the supported pixel range.
    #[error("figure {path:?} is {width}x{height} px; each side must lie in {min}..={max} px")]
    InvalidSize {
        /// Output path without extension.
        path: PathBuf,
        /// Requested width in pixels.
        width: u32,
        /// Requested height in pixels.
        height: u32,
        /// Smallest allowed side in pixels.
        min: u32,
        /// Largest allowed side in pixels.
        max: u32,
    },
    /// A series has different numbers of x and y values.
    #[error(
        "figure {path:?}, panel {panel} ({title:?}), series {series:?}: {x_len} x values but {y_len} y values"
    )]
    LengthMismatch {
        /// Output path without extension.
        path: PathBuf,
        /// Zero-based panel index.
        panel: usize,
        /// Panel title.
        title: String,
        /// Series label.
        series: String,
        /// Number of x values.
        x_len: usize,
        /// Number of y values.
        y_len: usize,
    },
    /// An explicit axis range is not finite, empty, or non-positive on a logarithmic axis.
    #[error(
        "figure {path:?}, panel {panel} ({title:?}): {axis} range ({lo}, {hi}) is invalid: {reason}"
    )]
    InvalidRange {
        /// Output path without extension.
        path: PathBuf,
        /// Zero-based panel index.
        panel: usize,
        /// Panel title.
        title: String,
        /// `"x"` or `"y"`.
        axis: &'static str,
        /// Requested lower bound.
        lo: f64,
        /// Requested upper bound.
        hi: f64,
        /// What is wrong with the bounds.
        reason: &'static str,
    },
    /// Reading or writing a file failed.
    #[error("cannot write {path:?}: {source}")]
    Io {
        /// The file being written or renamed.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The drawing backend reported an error.
    #[error("cannot render {path:?}: {message}")]
    Render {
        /// The file being rendered.
        path: PathBuf,
        /// The backend's description of the failure.
        message: String,
    },
    /// The embedded font could not be registered with the text renderer.
    #[error("the embedded DejaVu Sans font could not be loaded")]
    Font,
}
