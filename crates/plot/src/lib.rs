//! Figures for htfid as SVG and PNG.
//!
//! Data in, files out: build a [`Figure`] of [`Panel`]s, each holding [`Series`], and [`save`]
//! writes `<path>.svg` and `<path>.png`. Conveniences build the project's usual panels:
//! [`bode_panels`] (magnitude and phase of frequency responses), [`magnitude_panel`] for grids of
//! harmonics laid out by [`grid_figure`], [`time_panel`] and [`spectrum_panel`] stacked by
//! [`stacked_figure`]; for a diagnosis's evidence, [`binned_panel`] (bin means with bands of
//! +-2 standard errors) and [`waterfall_panel`] (levels and steps, named under the axis through
//! [`Panel::x_ticks`]).
//!
//! # Conventions
//! - Frequencies are angular, in rad/s; magnitudes in dB are `20 log10 |G|`; phases are in
//!   degrees, unwrapped along each series (see [`phase_panel`]).
//! - On a [`Scale::Log10`] axis, values that are not positive are skipped. NaN, infinite
//!   values and values beyond 1e300 in magnitude are skipped on every axis. A skipped point
//!   breaks a line into separate pieces; it never panics and never draws a line to the edge of
//!   the image. Lines leaving an explicit range are clipped at the axes.
//! - Automatic ranges fit the finite data exactly along x (with a small margin when markers are
//!   drawn) and with a 5 % margin along y, counting only points inside the x range.
//! - A series with a [`Role`] (measured, nominal, extended, theory, estimate, bound) takes that
//!   meaning's colour, the same in every figure; one without takes its colour from a fixed
//!   ten-colour palette by its index in the panel.
//! - [`Style::Band`] shades a confidence region; [`Style::FadedMarkers`] draws estimates that
//!   are not significant; [`Style::Stems`] draws correlations over lags.
//! - The legend lists series with a non-empty label. It sits in the corner of the plot where it
//!   covers the fewest line segments and markers, on a translucent white background.
//! - Text is set in DejaVu Sans, embedded in the crate, so PNG output needs no system fonts.
//!
//! # Example
//! ```
//! use htfid_plot::{bode_panels, grid_figure, save, Style};
//! use num_complex::Complex64;
//!
//! let omega: Vec<f64> = (0..200).map(|i| 10f64.powf(-1.0 + 3.0 * f64::from(i) / 199.0)).collect();
//! let g: Vec<Complex64> = omega
//!     .iter()
//!     .map(|&w| 1.0 / (Complex64::new(0.0, w) + 1.0))
//!     .collect();
//! let panels = bode_panels("1/(s+1)", &omega, [("G", g, Style::Line)]);
//! let fig = grid_figure("first-order lag", panels.to_vec(), 1);
//!
//! let dir = tempfile::tempdir()?;
//! let files = save(&fig, &dir.path().join("lag"))?;
//! assert!(files.iter().all(|f| f.exists()));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod convenience;
mod error;
mod evidence;
mod figure;
mod font;
mod output;
mod render;
mod ticks;

pub use convenience::{
    add_magnitude_confidence, add_phase_confidence, bode_panels, bode_panels_each, grid_figure,
    magnitude_panel, phase_panel, spectrum_panel, stacked_figure, time_panel, BodeSeries,
    SpectrumScale, FREQUENCY_LABEL, MAGNITUDE_DB_LABEL, PHASE_DEG_LABEL, SIGNIFICANT_RATIO,
    TIME_LABEL, Z_95,
};
pub use error::PlotError;
pub use evidence::{
    binned_panel, waterfall_panel, BinnedSeries, WaterfallBar, BIN_BAND_STDERRS, WATERFALL_LOG_SPAN,
};
pub use figure::{Figure, Panel, Role, Scale, Series, Style};
pub use output::save;
