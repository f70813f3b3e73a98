use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use plotters::prelude::*;

use crate::error::PlotError;
use crate::figure::Figure;
use crate::font::ensure_font;
use crate::render::{draw_figure, prepare, PlotPanel};

/// Writes `fig` as `<path>.svg` and `<path>.png` and returns those two paths (SVG first).
///
/// `path` has no extension; one already present is kept (`fig.v2` gives `fig.v2.svg`). Missing
/// parent directories are created. Both images are rendered to hidden temporary files in the
/// target directory, synced to disk and renamed into place only when both succeeded, so a
/// failure (or a crash) never leaves a partial image under the final name.
///
/// # Errors
/// [`PlotError::EmptyFigure`], [`PlotError::NoColumns`], [`PlotError::InvalidSize`],
/// [`PlotError::LengthMismatch`] and [`PlotError::InvalidRange`] for an unusable figure (nothing
/// is written); [`PlotError::Io`] and [`PlotError::Render`] when writing fails.
pub fn save(fig: &Figure, path: &Path) -> Result<Vec<PathBuf>, PlotError> {
    let panels = prepare(fig, path)?;
    ensure_font()?;

    let svg_path = with_suffix(path, "svg");
    let png_path = with_suffix(path, "png");
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent).map_err(|source| PlotError::Io {
            path: parent.to_path_buf(),
            source,
        })?;
    }
    let svg_tmp = temp_path(path, "svg");
    let png_tmp = temp_path(path, "png");

    let result = write_svg(fig, &panels, &svg_tmp, &svg_path)
        .and_then(|()| write_png(fig, &panels, &png_tmp, &png_path))
        .and_then(|()| rename(&svg_tmp, &svg_path))
        .and_then(|()| rename(&png_tmp, &png_path));
    if result.is_err() {
        // Best effort: the temporary files may not exist, and the original error matters more.
        let _ = std::fs::remove_file(&svg_tmp);
        let _ = std::fs::remove_file(&png_tmp);
    }
    result.map(|()| vec![svg_path, png_path])
}

fn with_suffix(path: &Path, ext: &str) -> PathBuf {
    let mut s: OsString = path.as_os_str().to_owned();
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}

/// A hidden sibling of the target that still ends in `.ext`, because the PNG encoder picks its
/// format from the extension.
fn temp_path(path: &Path, ext: &str) -> PathBuf {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let mut name = OsString::from(".");
    name.push(path.file_name().unwrap_or_else(|| "figure".as_ref()));
    name.push(format!(".{}-{n}.tmp.{ext}", std::process::id()));
    match path.parent() {
        Some(parent) => parent.join(name),
        None => PathBuf::from(name),
    }
}

/// Syncs the finished image to disk, so that a crash cannot leave it renamed but empty, and
/// moves it into place.
fn rename(from: &Path, to: &Path) -> Result<(), PlotError> {
    std::fs::OpenOptions::new()
        .write(true)
        .open(from)
        .and_then(|f| f.sync_all())
        .and_then(|()| std::fs::rename(from, to))
        .map_err(|source| PlotError::Io {
            path: to.to_path_buf(),
            source,
        })
}

fn render_error(path: &Path) -> impl Fn(String) -> PlotError + '_ {
    move |message| PlotError::Render {
        path: path.to_path_buf(),
        message,
    }
}

fn write_svg(
    fig: &Figure,
    panels: &[PlotPanel],
    tmp: &Path,
    target: &Path,
) -> Result<(), PlotError> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (fig.width, fig.height)).into_drawing_area();
        draw_figure(&root, fig, panels, false).map_err(|e| render_error(target)(e.to_string()))?;
        root.present()
            .map_err(|e| render_error(target)(e.to_string()))?;
    }
    std::fs::write(tmp, svg).map_err(|source| PlotError::Io {
        path: tmp.to_path_buf(),
        source,
    })
}

fn write_png(
    fig: &Figure,
    panels: &[PlotPanel],
    tmp: &Path,
    target: &Path,
) -> Result<(), PlotError> {
    let root = BitMapBackend::new(tmp, (fig.width, fig.height)).into_drawing_area();
    draw_figure(&root, fig, panels, true).map_err(|e| render_error(target)(e.to_string()))?;
    root.present()
        .map_err(|e| render_error(target)(e.to_string()))
}
