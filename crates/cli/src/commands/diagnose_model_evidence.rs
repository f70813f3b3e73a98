//! The evidence figures of a model-file diagnosis: the held-out residual in time and its
//! spectrum, the period-averaged orbit with its uncertainty, and the held-out error from the
//! configured to the final model. The numbers come from `htfid-diagnose` (the simulations,
//! [`ModelDiagnosis::error_waterfall`], [`htfid_diagnose::period_average`], [`amplitude_spectrum`]); this
//! module draws them.

use std::ops::Range;

use anyhow::Result;
use htfid_data::{OutputDir, TimeSeries};
use htfid_diagnose::{amplitude_spectrum, ErrorStep, ModelDiagnosis};
use htfid_number::sig;
use htfid_plot::{
    grid_figure, spectrum_panel, stacked_figure, Panel, Series, SpectrumScale, Style,
};

use super::diagnose_evidence::{fold_sampled, means_on, rms_per_block, waterfall_figure};
use super::diagnose_model::models_shown;
use crate::model_diagnose_config::ModelDiagnoseSettings;
use crate::plots;

/// The figures this module writes (each as `.svg` and `.png`); `orbit` only for a model with a
/// forcing period.
pub const FIGURES: [&str; 4] = [
    "residual_time",
    "residual_spectrum",
    "orbit",
    "error_waterfall",
];

/// Forcing periods in the window of the residual in time.
const WINDOW_PERIODS: f64 = 4.0;
/// Samples in that window, and per block of the RMS in time, for a model without forcing.
const UNFORCED_WINDOW: usize = 500;
/// The orbit's band: this many standard errors of the measured period average either side.
const BAND_STDERRS: f64 = 2.0;

/// Writes `residual_time`, `residual_spectrum`, `orbit` (with a forcing period) and
/// `error_waterfall` (the held-out error's `steps`) for the held-out samples `held_out` of
/// `shown` (the record the held-out simulations run on), for the models
/// [`models_shown`].
pub fn draw(
    out: &mut OutputDir,
    s: &ModelDiagnoseSettings,
    d: &ModelDiagnosis,
    steps: &[ErrorStep],
    shown: &TimeSeries,
    held_out: Range<usize>,
) -> Result<()> {
    let period = s.model.period().filter(|p| p.is_finite() && *p > 0.0);
    let dt = shown.dt();
    let t = &shown.time()[held_out.clone()];
    let unit = |o: usize| {
        s.format
            .unit(&s.outputs[o])
            .or(s.model.outputs()[o].unit.as_deref())
            .map_or(String::new(), |u| format!(" ({u})"))
    };
    let residual = |sim: &[f64], o: usize| -> Vec<f64> {
        held_out
            .clone()
            .map(|i| shown.outputs()[o][i] - sim[i])
            .collect()
    };

    // In time: the RMS per forcing period over all held-out data, then a window a person can
    // read at its start.
    let block = period.unwrap_or(UNFORCED_WINDOW as f64 * dt);
    let block_words = match period {
        Some(p) => format!("forcing period ({} s)", sig(p, 3)),
        None => format!("{UNFORCED_WINDOW} samples"),
    };
    let window = match period {
        Some(p) => ((WINDOW_PERIODS * p / dt).ceil() as usize).max(16),
        None => UNFORCED_WINDOW,
    }
    .min(t.len());
    let window_words = match period {
        Some(_) => format!("{WINDOW_PERIODS} forcing periods"),
        None => format!("{UNFORCED_WINDOW} samples"),
    };
    let mut panels = Vec::new();
    for (o, name) in s.outputs.iter().enumerate() {
        let mut top = Panel::new(
            format!("{name}: RMS of the residual per {block_words}, all held-out data"),
            htfid_plot::TIME_LABEL,
            format!("RMS residual{}", unit(o)),
        );
        let mut bottom = Panel::new(
            format!("{name}: measured - simulated over the first {window_words} of held-out data"),
            htfid_plot::TIME_LABEL,
            format!("residual{}", unit(o)),
        );
        let mut top_max = 0.0f64;
        for m in &models_shown(d, o) {
            let r = residual(m.y, o);
            let (tb, rms) = rms_per_block(t, &r, block);
            top_max = rms
                .iter()
                .copied()
                .filter(|v| v.is_finite())
                .fold(top_max, f64::max);
            top.series
                .push(Series::new(m.label.clone(), tb, rms, m.style).with_role(m.role));
            bottom.series.push(
                Series::new(
                    m.label.clone(),
                    t[..window].to_vec(),
                    r[..window].to_vec(),
                    m.style,
                )
                .with_role(m.role),
            );
        }
        if top_max > 0.0 {
            top.y_range = Some((0.0, 1.1 * top_max));
        }
        panels.push(top);
        panels.push(bottom);
    }
    let fig = stacked_figure(
        format!("{}: what the model gets wrong, in time", s.name),
        panels,
    );
    plots::write(out, "residual_time", &fig)?;

    // In frequency: the held-out residual's amplitude spectrum, per output.
    let mut panels = Vec::new();
    for (o, name) in s.outputs.iter().enumerate() {
        let mut panel = spectrum_panel::<&str, Vec<f64>>(
            &format!("{name}: residual spectrum (held-out data)"),
            &[],
            [],
            SpectrumScale::LogLog,
        );
        panel.y_label = format!("amplitude{}", unit(o));
        for m in &models_shown(d, o) {
            let (w, a) = amplitude_spectrum(&residual(m.y, o), dt);
            panel
                .series
                .push(Series::new(m.label.clone(), w, a, m.style).with_role(m.role));
        }
        panels.push(panel);
    }
    let fig = stacked_figure(format!("{}: residual spectrum", s.name), panels);
    plots::write(out, "residual_spectrum", &fig)?;

    // The orbit: every output folded over the forcing period, the measured average with a
    // band of two standard errors across the periods; beside it each model minus the measured.
    if let Some(period) = period {
        let mut panels = Vec::new();
        for (o, name) in s.outputs.iter().enumerate() {
            let measured = fold_sampled(t, &shown.outputs()[o][held_out.clone()], period, dt);
            let phase: Vec<f64> = measured.iter().map(|b| b.centre).collect();
            let mean: Vec<f64> = measured.iter().map(|b| b.mean).collect();
            let half: Vec<f64> = measured.iter().map(|b| BAND_STDERRS * b.stderr).collect();
            let mut p = Panel::new(
                format!("{name}: period-averaged orbit (held-out data)"),
                "time into the forcing period (s)",
                format!("{name}{}", unit(o)),
            );
            p.series.push(Series::band(
                format!("measured ± {BAND_STDERRS} standard errors"),
                phase.clone(),
                mean.iter().zip(&half).map(|(m, h)| m - h).collect(),
                mean.iter().zip(&half).map(|(m, h)| m + h).collect(),
            ));
            p.series.push(Series::new(
                "measured",
                phase.clone(),
                mean.clone(),
                Style::Markers,
            ));
            let mut q = Panel::new(
                format!("{name}: model - measured, period-averaged"),
                "time into the forcing period (s)",
                format!("difference{}", unit(o)),
            );
            let drawn = models_shown(d, o);
            for (j, m) in drawn.iter().enumerate() {
                let sim = &m.y[held_out.clone()];
                let y = means_on(&measured, &fold_sampled(t, sim, period, dt));
                // The difference's own period average: the measured input's response, common
                // to both, leaves its standard error.
                let diff: Vec<f64> = sim
                    .iter()
                    .zip(&shown.outputs()[o][held_out.clone()])
                    .map(|(a, b)| a - b)
                    .collect();
                let diff = fold_sampled(t, &diff, period, dt);
                if j + 1 == drawn.len() {
                    q.series.push(Series::band(
                        format!("± {BAND_STDERRS} standard errors ({})", m.label),
                        diff.iter().map(|b| b.centre).collect(),
                        diff.iter().map(|b| -BAND_STDERRS * b.stderr).collect(),
                        diff.iter().map(|b| BAND_STDERRS * b.stderr).collect(),
                    ));
                }
                p.series.push(
                    Series::new(m.label.clone(), phase.clone(), y, m.style).with_role(m.role),
                );
                q.series.push(
                    Series::new(
                        m.label.clone(),
                        diff.iter().map(|b| b.centre).collect(),
                        diff.iter().map(|b| b.mean).collect(),
                        m.style,
                    )
                    .with_role(m.role),
                );
            }
            panels.push(p);
            panels.push(q);
        }
        let fig = grid_figure(format!("{}: the orbit", s.name), panels, 2);
        plots::write(out, "orbit", &fig)?;
    }

    // The held-out error, step by step.
    let fig = waterfall_figure(
        &s.name,
        steps,
        &format!("refit {}", s.options.free.join(", ")),
        (
            "held-out NRMSE (mean over the outputs)",
            "held-out NRMSE (fraction of the output's spread)",
        ),
        d.noise_floor.is_finite().then(|| {
            (
                d.noise_floor,
                format!("noise floor ({})", sig(d.noise_floor, 3)),
            )
        }),
    );
    plots::write(out, "error_waterfall", &fig)
}
