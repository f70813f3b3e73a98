//! The figures the commands write: staged into the output directory as SVG and PNG.

use anyhow::{Context, Result};
use htfid_data::OutputDir;
use htfid_plot::{
    add_magnitude_confidence, add_phase_confidence, bode_panels_each, grid_figure, magnitude_panel,
    phase_panel, save, BodeSeries, Figure, Panel, Role, Style,
};
use num_complex::Complex64;

/// A named frequency response on its own grid.
pub struct Curve<'a> {
    pub label: &'a str,
    pub omega: &'a [f64],
    pub values: &'a [Complex64],
    pub style: Style,
    /// Standard errors of an estimate (same length as `values`): a 95 % band is drawn and
    /// insignificant points are faded.
    pub stderr: Option<&'a [f64]>,
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

/// Stages `<name>.svg` and `<name>.png`, every series without a role coloured by the meaning
/// its label names (see [`role_of`]).
pub fn write(out: &mut OutputDir, name: &str, fig: &Figure) -> Result<()> {
    let mut fig = fig.clone();
    for p in &mut fig.panels {
        for s in &mut p.series {
            if s.role.is_none() {
                s.role = role_of(&s.label);
            }
        }
    }
    let svg = out.path_for(&format!("{name}.svg"))?;
    out.path_for(&format!("{name}.png"))?;
    save(&fig, &svg.with_extension("")).with_context(|| format!("cannot draw {name}"))?;
    Ok(())
}

/// The meaning a legend label names, so one meaning has one colour in every figure: measured
/// data, the nominal or configured model, the extended or refitted model, the exact theory, and
/// the estimates (one colour per estimator). Derived series (bands, faded points) begin with
/// their parent's label and take its colour.
pub fn role_of(label: &str) -> Option<Role> {
    let l = label.to_ascii_lowercase();
    if l.starts_with("measured") || l.starts_with("data") {
        Some(Role::Measured)
    } else if l.starts_with("nominal") || l.starts_with("configured") {
        Some(Role::Nominal)
    } else if l.starts_with("extended") || l.starts_with("refitted") {
        Some(Role::Extended)
    } else if l.starts_with("theory") {
        Some(Role::Theory)
    } else if l.contains("multi") {
        Some(Role::EstimateAlt)
    } else if l.contains("lines") {
        Some(Role::EstimateAlt2)
    } else if l.starts_with("estimate") || l.contains("siddiqi") {
        Some(Role::Estimate)
    } else {
        None
    }
}

/// Adds bands and fades insignificant points for every curve with standard errors; `phase`
/// says which kind of panel it is.
fn confidence(panel: &mut htfid_plot::Panel, curves: &[Curve<'_>], phase: bool) {
    for (i, c) in curves.iter().enumerate() {
        if let Some(se) = c.stderr {
            // Derived series (band, faded and lone points) copy the estimate's role.
            if let Some(s) = panel.series.get_mut(i) {
                s.role = s.role.or_else(|| role_of(&s.label));
            }
            if phase {
                add_phase_confidence(panel, i, c.values, se);
            } else {
                add_magnitude_confidence(panel, i, c.values, se);
            }
        }
    }
}

/// The HTF unit `output unit / input unit` when both are known.
pub fn htf_unit(output: Option<&str>, input: Option<&str>) -> Option<String> {
    let input = input?;
    // `m/(m/s^2)`, not `m/m/s^2`.
    if input.contains(['/', ' ', '*']) {
        Some(format!("{}/({input})", output?))
    } else {
        Some(format!("{}/{input}", output?))
    }
}

/// Magnitude axes labelled `|G| (dB re 1 <unit>)` when the unit is known.
pub fn with_htf_unit(mut fig: Figure, unit: Option<&str>) -> Figure {
    if let Some(unit) = unit {
        for p in &mut fig.panels {
            if p.y_label == htfid_plot::MAGNITUDE_DB_LABEL {
                p.y_label = format!("|G| (dB re 1 {unit})");
            }
        }
    }
    fig
}

/// Smallest vertical span of a magnitude axis, dB. An HTF constant in frequency (an output
/// that depends on the input statically, whose HTFs are the Fourier coefficients of its gain)
/// would otherwise be stretched over the whole axis until its round-off, 1e-11 dB, looked like
/// a response.
const MIN_DB_SPAN: f64 = 6.0;

/// Smallest vertical span of a phase axis, degrees (as [`MIN_DB_SPAN`]).
const MIN_DEGREE_SPAN: f64 = 20.0;

/// Widens an automatic vertical range narrower than `span` to `span`, about its middle.
fn keep_span(p: &mut Panel, span: f64) {
    if p.y_range.is_some() {
        return;
    }
    let (lo, hi) = p
        .series
        .iter()
        .flat_map(|s| s.y.iter().chain(&s.upper))
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    if lo.is_finite() && hi - lo < span {
        let mid = 0.5 * (lo + hi);
        p.y_range = Some((mid - 0.5 * span, mid + 0.5 * span));
    }
}

/// Magnitude and phase of one harmonic (the paper's figure 4 for `G_0`).
pub fn bode(title: &str, curves: &[Curve<'_>]) -> Figure {
    let series: Vec<BodeSeries<'_>> = curves.iter().map(Curve::series).collect();
    let [mut mag, mut ph] = bode_panels_each(title, &series);
    confidence(&mut mag, curves, false);
    confidence(&mut ph, curves, true);
    keep_span(&mut mag, MIN_DB_SPAN);
    keep_span(&mut ph, MIN_DEGREE_SPAN);
    grid_figure(title, vec![mag, ph], 1)
}

/// One magnitude panel per harmonic (the paper's figure 5).
pub fn harmonics(title: &str, per_harmonic: &[(i32, Vec<Curve<'_>>)]) -> Figure {
    let panels = per_harmonic
        .iter()
        .map(|(n, curves)| {
            let series: Vec<BodeSeries<'_>> = curves.iter().map(Curve::series).collect();
            let mut p = magnitude_panel(&format!("G_{n}"), &series);
            confidence(&mut p, curves, false);
            keep_span(&mut p, MIN_DB_SPAN);
            p
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
            let mut p = phase_panel(&format!("G_{n}"), &series);
            confidence(&mut p, curves, true);
            keep_span(&mut p, MIN_DEGREE_SPAN);
            p
        })
        .collect::<Vec<_>>();
    let columns = if panels.len() > 4 {
        3
    } else {
        panels.len().max(1)
    };
    grid_figure(title, panels, columns)
}
