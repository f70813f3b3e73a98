//! The figures the commands write: staged into the output directory as SVG and PNG.

use anyhow::{Context, Result};
use htfid_data::OutputDir;
use htfid_plot::{
    bode_panels_each, grid_figure, magnitude_panel, phase_panel, save, BodeSeries, Figure, Style,
};
use num_complex::Complex64;

/// A named frequency response on its own grid.
pub struct Curve<'a> {
    pub label: &'a str,
    pub omega: &'a [f64],
    pub values: &'a [Complex64],
    pub style: Style,
}

impl<'a> Curve<'a> {
    fn series(&self) -> BodeSeries<'a> {
        BodeSeries {
            label: self.label,
            omega: self.omega,
            response: self.values,
            style: self.style,
        }
    }
}

/// Stages `<name>.svg` and `<name>.png`.
pub fn write(out: &mut OutputDir, name: &str, fig: &Figure) -> Result<()> {
    let svg = out.path_for(&format!("{name}.svg"))?;
    out.path_for(&format!("{name}.png"))?;
    save(fig, &svg.with_extension("")).with_context(|| format!("cannot draw {name}"))?;
    Ok(())
}

/// Magnitude and phase of one harmonic (the paper's figure 4 for `G_0`).
pub fn bode(title: &str, curves: &[Curve<'_>]) -> Figure {
    let series: Vec<BodeSeries<'_>> = curves.iter().map(Curve::series).collect();
    let panels = bode_panels_each(title, &series);
    grid_figure(title, panels.to_vec(), 1)
}

/// One magnitude panel per harmonic (the paper's figure 5).
pub fn harmonics(title: &str, per_harmonic: &[(i32, Vec<Curve<'_>>)]) -> Figure {
    let panels = per_harmonic
        .iter()
        .map(|(n, curves)| {
            let series: Vec<BodeSeries<'_>> = curves.iter().map(Curve::series).collect();
            magnitude_panel(&format!("G_{n}"), &series)
        })
        .collect::<Vec<_>>();
    let columns = if panels.len() > 4 {
        3
    } else {
        panels.len().max(1)
    };
    grid_figure(title, panels, columns)
}

/// One phase panel per harmonic.
pub fn harmonic_phases(title: &str, per_harmonic: &[(i32, Vec<Curve<'_>>)]) -> Figure {
    let panels = per_harmonic
        .iter()
        .map(|(n, curves)| {
            let series: Vec<BodeSeries<'_>> = curves.iter().map(Curve::series).collect();
            phase_panel(&format!("G_{n}"), &series)
        })
        .collect::<Vec<_>>();
    let columns = if panels.len() > 4 {
        3
    } else {
        panels.len().max(1)
    };
    grid_figure(title, panels, columns)
}
