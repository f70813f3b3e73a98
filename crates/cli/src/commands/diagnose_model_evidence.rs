//! The evidence figures of a model-file diagnosis: the held-out residual in time and its
//! spectrum, the period-averaged orbit with its uncertainty, and the held-out error from the
//! configured to the final model. The numbers come from `htfid-diagnose` (the simulations,
//! [`ModelDiagnosis::error_waterfall`], [`period_average`], [`amplitude_spectrum`]); this
//! module draws them.

use std::ops::Range;

use anyhow::Result;
use htfid_data::{OutputDir, TimeSeries};
use htfid_diagnose::{amplitude_spectrum, binned_means, period_average, ModelDiagnosis};
use htfid_number::sig;
use htfid_plot::{
    grid_figure, spectrum_panel, stacked_figure, Panel, Role, Series, SpectrumScale, Style,
};

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
/// Phase bins of the period-averaged orbit.
const ORBIT_BINS: usize = 100;
/// The orbit's band: this many standard errors of the measured period average either side.
const BAND_STDERRS: f64 = 2.0;

/// One model's simulated outputs, as drawn.
struct Drawn<'a> {
    label: String,
    role: Role,
    style: Style,
    y: &'a [Vec<f64>],
}

/// The configured, the refitted and (when an effect is named) the extended model.
fn models(d: &ModelDiagnosis) -> Vec<Drawn<'_>> {
    let mut v = vec![
        Drawn {
            label: "configured model".into(),
            role: Role::Nominal,
            style: Style::Dashed,
            y: &d.simulated_configured,
        },
        Drawn {
            label: "refitted model".into(),
            role: if d.simulated_extended.is_some() {
                Role::Refitted
            } else {
                Role::Extended
            },
            style: Style::Line,
            y: &d.simulated,
        },
    ];
    if let (Some(ext), Some(c)) = (&d.simulated_extended, &d.extended) {
        v.push(Drawn {
            label: format!("with {}", c.effect),
            role: Role::Extended,
            style: Style::Line,
            y: ext,
        });
    }
    v
}

/// Writes `residual_time`, `residual_spectrum`, `orbit` (with a forcing period) and
/// `error_waterfall` for the held-out samples `held_out` of `shown` (the record the held-out
/// simulations run on).
pub fn draw(
    out: &mut OutputDir,
    s: &ModelDiagnoseSettings,
    d: &ModelDiagnosis,
    shown: &TimeSeries,
    held_out: Range<usize>,
) -> Result<()> {
    let period = s.model.period().filter(|p| p.is_finite() && *p > 0.0);
    let dt = shown.dt();
    let t = &shown.time()[held_out.clone()];
    let drawn = models(d);
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
        for m in &drawn {
            let r = residual(&m.y[o], o);
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
        for m in &drawn {
            let (w, a) = amplitude_spectrum(&residual(&m.y[o], o), dt);
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
        // At most one bin per sample interval, the bins' edges half a sample from the
        // samples: each bin holds the same phases in every period (a bin that caught two
        // phases in some periods and one in others would mix the orbit's slope into its
        // standard error).
        let bins = ORBIT_BINS.min((period / dt).round() as usize).max(4);
        let t_shifted: Vec<f64> = t.iter().map(|v| v + 0.5 * dt).collect();
        let t = &t_shifted[..];
        let mut panels = Vec::new();
        for (o, name) in s.outputs.iter().enumerate() {
            let measured = period_average(t, &shown.outputs()[o][held_out.clone()], period, bins);
            let phase: Vec<f64> = measured.iter().map(|b| b.centre - 0.5 * dt).collect();
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
            for (j, m) in drawn.iter().enumerate() {
                let sim = &m.y[o][held_out.clone()];
                let y = super::diagnose_evidence::means_on(
                    &measured,
                    &period_average(t, sim, period, bins),
                );
                // The difference's own period average: the measured input's response, common
                // to both, leaves its standard error.
                let diff: Vec<f64> = sim
                    .iter()
                    .zip(&shown.outputs()[o][held_out.clone()])
                    .map(|(a, b)| a - b)
                    .collect();
                let diff = period_average(t, &diff, period, bins);
                if j + 1 == drawn.len() {
                    q.series.push(Series::band(
                        format!("± {BAND_STDERRS} standard errors ({})", m.label),
                        diff.iter().map(|b| b.centre - 0.5 * dt).collect(),
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
                        diff.iter().map(|b| b.centre - 0.5 * dt).collect(),
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
    let steps = d.error_waterfall(!s.options.free.is_empty());
    let fig = super::diagnose_evidence::waterfall_figure(
        &s.name,
        &steps,
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

/// The RMS of `r` (at times `t`) per block of `block` s from the first sample: `(centre of
/// each block, RMS)`; blocks without samples are left out.
fn rms_per_block(t: &[f64], r: &[f64], block: f64) -> (Vec<f64>, Vec<f64>) {
    let (Some(&t0), Some(&t1)) = (t.first(), t.last()) else {
        return (Vec::new(), Vec::new());
    };
    let nb = (((t1 - t0) / block).ceil() as usize).clamp(1, 5000);
    let sq: Vec<f64> = r.iter().map(|v| v * v).collect();
    let own: Vec<usize> = (0..t.len()).collect();
    binned_means(t, &sq, &own, nb, (t0, t0 + nb as f64 * block))
        .iter()
        .map(|b| (0.5 * (b.lo + b.hi), b.mean.sqrt()))
        .unzip()
}
