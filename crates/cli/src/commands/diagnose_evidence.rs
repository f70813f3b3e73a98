//! The evidence figures of a diagnosis: the held-out residual in time and its
//! spectrum, the period-averaged orbit with its uncertainty, and the held-out error from the
//! configured to the final model. The numbers come from `htfid-diagnose` (the simulations,
//! [`ModelDiagnosis::error_waterfall`], [`htfid_diagnose::period_average`], [`amplitude_spectrum`]); this
//! module draws them.

use std::ops::Range;

use anyhow::Result;
use htfid_data::{OutputDir, TimeSeries};
use htfid_diagnose::{
    amplitude_spectrum, Bin, BinnedResidual, ErrorStep, EstimatedComparison, HarmonicDifference,
    ModelDiagnosis, PairResidual, Structure, DIFFERENCE_SIGMAS,
};
use htfid_number::sig;
use htfid_plot::{
    binned_panel, grid_figure, magnitude_panel, spectrum_panel, stacked_figure, waterfall_panel,
    BinnedSeries, BodeSeries, Panel, Role, Series, SpectrumScale, Style, WaterfallBar,
    SIGNIFICANT_RATIO,
};
use serde_json::{json, Value};

use super::diagnose::models_shown;
use crate::model_diagnose_config::ModelDiagnoseSettings;
use crate::plots;

/// The figures this module writes (each as `.svg` and `.png`); `orbit` only for a model with a
/// forcing period.
pub const FIGURES: [&str; 5] = [
    "residual_time",
    "residual_spectrum",
    "orbit",
    "residual_bins",
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
        s.output_unit(o)
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

    // Where the equations miss the data: one set of panels per output that reads a position.
    let mut panels = Vec::new();
    let ext_label = d.extended.as_ref().map(|c| format!("with {}", c.effect));
    for (i, p) in d.residual_bins.iter().enumerate() {
        let u = position_unit(s, p).unwrap_or("output units");
        panels.extend(bins_panels(&BinsFigure {
            position: format!("position {} ({u})", p.output),
            unit: u,
            block_words: &block_words_of(p, period),
            nominal: &p.nominal,
            extended: p.extended.as_ref().zip(ext_label.as_deref()),
            period,
            first: i == 0,
            prefix: if d.residual_bins.len() > 1 {
                format!("{}: ", p.output)
            } else {
                String::new()
            },
        }));
    }
    if bins_drawn(d) {
        let fig = stacked_figure(
            format!(
                "{}: residual acceleration, measured minus model (held-out data)",
                s.name
            ),
            panels,
        );
        plots::write(out, "residual_bins", &fig)?;
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

/// Whether `residual_bins.png` is drawn: some pair's refitted residual fills a bin.
pub fn bins_drawn(d: &ModelDiagnosis) -> bool {
    d.residual_bins.iter().any(|p| {
        let b = &p.nominal;
        !(b.by_position.is_empty() && b.by_velocity.is_empty() && b.by_phase.is_empty())
    })
}

/// What a block of the binned residual's standard errors is, in words.
fn block_words_of(p: &PairResidual, period: Option<f64>) -> String {
    match period {
        Some(_) => "one forcing period".to_string(),
        None => format!("{} s", sig(p.block_s, 3)),
    }
}

/// The unit of a pair's position: its output's, when known.
fn position_unit<'s>(s: &'s ModelDiagnoseSettings, p: &PairResidual) -> Option<&'s str> {
    let o = s.model.outputs().iter().position(|o| o.name == p.output)?;
    s.output_unit(o)
}

/// One pair's `residual_bins` object of `diagnosis.json`.
fn pair_json(s: &ModelDiagnoseSettings, p: &PairResidual) -> Value {
    json!({
        "quantity": "acceleration",
        "unit": position_unit(s, p).map(|u| format!("{u}/s^2")),
        "output": p.output,
        "position": p.position,
        "velocity": p.velocity,
        "block_s": p.block_s,
        "band_stderrs": htfid_plot::BIN_BAND_STDERRS,
        "nominal": p.nominal,
        "extended": p.extended,
    })
}

/// `residual_bins` of `diagnosis.json`: the first pair's object, with `by_output` holding
/// every pair's by its output's name; `null` for a model without a pair.
pub fn bins_json(s: &ModelDiagnoseSettings, d: &ModelDiagnosis) -> Value {
    let Some(first) = d.residual_bins.first() else {
        return Value::Null;
    };
    let mut v = pair_json(s, first);
    let by_output: serde_json::Map<String, Value> = d
        .residual_bins
        .iter()
        .map(|p| (p.output.clone(), pair_json(s, p)))
        .collect();
    v["by_output"] = Value::Object(by_output);
    v
}

/// Where each pair's refitted residual acceleration varies most, in words (one sentence per
/// output that reads a position).
pub fn bins_words(s: &ModelDiagnoseSettings, d: &ModelDiagnosis) -> Vec<String> {
    let several = d.residual_bins.len() > 1;
    d.residual_bins
        .iter()
        .filter_map(|p| {
            let u = position_unit(s, p).unwrap_or("output units");
            let whose = if several {
                format!(" of `{}`", p.output)
            } else {
                String::new()
            };
            strongest_in(&p.nominal, p.extended.as_ref(), p.block_s, u, &whose)
        })
        .collect()
}

/// The HTF's unit of output `o`: the output's unit over the input's, when both are known.
fn htf_unit(s: &ModelDiagnoseSettings, o: usize) -> Option<String> {
    Some(format!("{}/{}", s.output_unit(o)?, s.input_unit()?))
}

/// `htf_data` and `htf_difference` (suffixed by the output's name after the first) for every
/// output: the data's HTFs with ±2 standard errors against the refitted and the final model's,
/// and per harmonic the difference against the estimate's noise.
pub fn draw_htf(
    out: &mut OutputDir,
    s: &ModelDiagnoseSettings,
    d: &ModelDiagnosis,
    cmp: &[EstimatedComparison],
) -> Result<()> {
    use crate::plots::Curve;
    let ext_label = d.extended.as_ref().map(|c| format!("with {}", c.effect));
    let ext_difference = ext_label.as_ref().map(|l| format!("{l}: measured - model"));
    for (o, c) in cmp.iter().enumerate() {
        let suffix = super::theory::suffix(&s.outputs, o);
        let unit = htf_unit(s, o);
        let per_harmonic: Vec<(i32, Vec<Curve<'_>>)> = c
            .differences
            .iter()
            .filter_map(|diff| {
                let m = c.measured.harmonic(diff.n)?;
                let nom = c.nominal.harmonic(diff.n)?;
                let mut curves = vec![
                    Curve {
                        label: "measured (Siddiqi estimate)",
                        omega: m.omegas,
                        values: m.values,
                        style: Style::Line,
                        stderr: Some(m.stderr),
                    },
                    Curve {
                        label: "refitted, same estimator",
                        omega: nom.omegas,
                        values: nom.values,
                        style: Style::Line,
                        stderr: None,
                    },
                ];
                if let (Some(e), Some(label)) = (&c.extended, &ext_label) {
                    let ext = e.harmonic(diff.n)?;
                    curves.push(Curve {
                        label,
                        omega: ext.omegas,
                        values: ext.values,
                        style: Style::Dashed,
                        stderr: None,
                    });
                }
                Some((diff.n, curves))
            })
            .collect();
        let fig = plots::with_htf_unit(
            plots::harmonics(
                &format!(
                    "{}: HTFs of {} from the held-out data against the models'",
                    s.name, s.outputs[o]
                ),
                &per_harmonic,
            ),
            unit.as_deref(),
        );
        plots::write(out, &format!("htf_data{suffix}"), &fig)?;
        let fig = htf_difference_figure(
            &format!(
                "{}: HTF of {} from the data minus each model's (the same estimator), per harmonic",
                s.name, s.outputs[o]
            ),
            &c.differences,
            "refitted: measured - model",
            ext_difference.as_deref(),
            unit.as_deref(),
        );
        plots::write(out, &format!("htf_difference{suffix}"), &fig)?;
    }
    Ok(())
}

/// Where the data's HTFs differ from the refitted and the final model's beyond the noise, in
/// words, output by output.
pub fn htf_words(
    s: &ModelDiagnoseSettings,
    d: &ModelDiagnosis,
    cmp: &[EstimatedComparison],
) -> String {
    let Some(first) = cmp.first() else {
        return String::new();
    };
    let mut text = format!(
        "The HTFs `G_-2 .. G_2` estimated from {} held-out forcing periods (Siddiqi's estimator, \
         output frequencies {} to {} rad/s) against each model's, estimated the same way from \
         its simulation with the measured input: the difference is the estimate of the \
         residual's response, and beyond {DIFFERENCE_SIGMAS} standard errors it is more than \
         the noise.",
        first.periods,
        sig(first.band.0, 3),
        sig(first.band.1, 3)
    );
    for (o, c) in cmp.iter().enumerate() {
        let share = |f: fn(&htfid_diagnose::HarmonicDifference) -> f64| {
            let n = c.differences.len().max(1) as f64;
            c.differences.iter().map(f).sum::<f64>() / n
        };
        let worst = c
            .differences
            .iter()
            .max_by(|a, b| a.nominal_outside().total_cmp(&b.nominal_outside()));
        text.push_str(&format!(
            " For `{}`, {} of the refitted model's points lie outside the noise{}",
            s.outputs[o],
            pct(share(|h| h.nominal_outside())),
            worst.map_or(String::new(), |w| format!(
                " (most in `G_{}`: {})",
                w.n,
                pct(w.nominal_outside())
            ))
        ));
        if d.extended.is_some() {
            text.push_str(&format!(
                ", {} of the final model's",
                pct(share(|h| h.extended_outside()))
            ));
        }
        text.push('.');
    }
    text
}

fn pct(x: f64) -> String {
    format!("{} %", sig(100.0 * x, 3))
}

fn columns(bins: &[Bin]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    (
        bins.iter().map(|b| b.centre).collect(),
        bins.iter().map(|b| b.mean).collect(),
        bins.iter().map(|b| b.stderr).collect(),
    )
}

/// What [`bins_panels`] draws: one pair's binned residual acceleration.
struct BinsFigure<'a> {
    /// The position axis's label, unit included.
    pub position: String,
    /// The position's unit, or words for it.
    pub unit: &'a str,
    /// What a block of the standard errors is, in words.
    pub block_words: &'a str,
    /// The refitted nominal model's bins.
    pub nominal: &'a BinnedResidual,
    /// The extended model's, with its legend label.
    pub extended: Option<(&'a BinnedResidual, &'a str)>,
    /// The forcing period (the phase axis's range).
    pub period: Option<f64>,
    /// Whether these are the figure's first panels (the legend, and the blocks' words).
    pub first: bool,
    /// Put before each panel's title: the pair's output where a figure shows several.
    pub prefix: String,
}

/// The panels of one pair's binned residual acceleration: against position, velocity and the
/// forcing phase (those with bins), the nominal model's and the extended one's bin means with
/// bands of two standard errors.
fn bins_panels(f: &BinsFigure<'_>) -> Vec<Panel> {
    let u = f.unit;
    let y_label = format!("residual acceleration ({u}/s^2)");
    type Pick = fn(&BinnedResidual) -> &Vec<Bin>;
    let mut panels: Vec<Panel> = Vec::new();
    let kinds: [(&str, String, Pick); 3] = [
        ("against position", f.position.clone(), |b| &b.by_position),
        ("against velocity", format!("velocity ({u}/s)"), |b| {
            &b.by_velocity
        }),
        (
            "against the forcing phase",
            "time into the forcing period (s)".to_string(),
            |b| &b.by_phase,
        ),
    ];
    for (title, x_label, pick) in kinds {
        let nom = columns(pick(f.nominal));
        if nom.0.is_empty() {
            continue;
        }
        // One legend, in the first panel: the others show the same series.
        let first = f.first && panels.is_empty();
        let ext = f.extended.map(|(e, label)| (columns(pick(e)), label));
        let mut series = vec![BinnedSeries {
            label: if first { "nominal (refitted)" } else { "" },
            centre: &nom.0,
            mean: &nom.1,
            stderr: &nom.2,
            role: Role::Nominal,
        }];
        if let Some((e, label)) = &ext {
            series.push(BinnedSeries {
                label: if first { label } else { "" },
                centre: &e.0,
                mean: &e.1,
                stderr: &e.2,
                role: Role::Extended,
            });
        }
        let title = if panels.is_empty() {
            format!(
                "{}{title} (bin means; blocks of {} independent)",
                f.prefix, f.block_words
            )
        } else {
            format!("{}{title}", f.prefix)
        };
        let mut p = binned_panel(&title, &x_label, &y_label, &series);
        if first {
            // Room above the data for the legend, which would otherwise hide the outer bins.
            let (lo, hi) = series
                .iter()
                .flat_map(|b| {
                    b.mean.iter().zip(b.stderr).flat_map(|(m, e)| {
                        let e = if e.is_finite() { 2.0 * e } else { 0.0 };
                        [m - e, m + e]
                    })
                })
                .filter(|v| v.is_finite())
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(v), b.max(v))
                });
            if lo < hi {
                let pad = 0.05 * (hi - lo);
                p.y_range = Some((lo - pad, hi + 0.55 * (hi - lo)));
            }
        }
        if title.contains("phase") {
            if let Some(period) = f.period {
                p.x_range = Some((0.0, period));
            }
        }
        panels.push(p);
    }
    panels
}

/// Most phase bins of a folded orbit.
const ORBIT_BINS: usize = 100;

/// `y`, sampled every `dt` s at times `t`, folded over `period` by
/// [`htfid_diagnose::period_average`] in at most [`ORBIT_BINS`] bins and at most one per sample
/// interval, the bins' edges half a sample from the samples: each bin holds the same phases in
/// every period (a bin that caught two phases in some periods and one in others would mix the
/// orbit's slope into its standard error). Bins as that function gives them, in time into the
/// period.
fn fold_sampled(t: &[f64], y: &[f64], period: f64, dt: f64) -> Vec<Bin> {
    let bins = ORBIT_BINS.min((period / dt).round() as usize).max(4);
    let shifted: Vec<f64> = t.iter().map(|v| v + 0.5 * dt).collect();
    htfid_diagnose::period_average(&shifted, y, period, bins)
        .into_iter()
        .map(|b| Bin {
            lo: b.lo - 0.5 * dt,
            hi: b.hi - 0.5 * dt,
            centre: b.centre - 0.5 * dt,
            ..b
        })
        .collect()
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
    htfid_diagnose::binned_means(t, &sq, &own, nb, (t0, t0 + nb as f64 * block))
        .iter()
        .map(|b| (0.5 * (b.lo + b.hi), b.mean.sqrt()))
        .unzip()
}

/// The means of `other` on the bins of `reference` (NaN where `other` has no such bin), two
/// binnings of one range with the same number of bins (the same edges, matched within half a
/// bin's width), for curves drawn over the reference's bin centres.
fn means_on(reference: &[Bin], other: &[Bin]) -> Vec<f64> {
    reference
        .iter()
        .map(|b| {
            other
                .iter()
                .find(|a| (a.lo - b.lo).abs() < 0.5 * (b.hi - b.lo))
                .map_or(f64::NAN, |a| a.mean)
        })
        .collect()
}

/// The figure of a held-out error from the configured to the final model, step by step
/// (`steps` as `htfid-diagnose` gives them: `configured`, `refitted`, the effects, `final`):
/// the refit's bar named `refit` under the axis, the error's name and axis label in `measure`,
/// and the noise floor with its legend.
fn waterfall_figure(
    name: &str,
    steps: &[ErrorStep],
    refit: &str,
    measure: (&str, &str),
    floor: Option<(f64, String)>,
) -> htfid_plot::Figure {
    // Without an effect the final model is the nominal one, and coloured so.
    let effects = steps
        .iter()
        .any(|s| !matches!(s.step.as_str(), "configured" | "refitted" | "final"));
    let mut bars = Vec::new();
    let mut seen_nominal = false;
    let mut seen_extended = false;
    for (i, step) in steps.iter().enumerate() {
        let (name, from, role) = match step.step.as_str() {
            "configured" => ("configured".to_string(), 0.0, Role::Nominal),
            // Without a configured level the refitted model's level comes first.
            "refitted" if i == 0 => ("refitted".to_string(), 0.0, Role::Nominal),
            "refitted" => (refit.to_string(), step.before, Role::Nominal),
            "final" if effects => ("final model".to_string(), 0.0, Role::Extended),
            "final" => ("final model".to_string(), 0.0, Role::Nominal),
            effect => (format!("+ {effect}"), step.before, Role::Extended),
        };
        let legend = match role {
            Role::Nominal if !seen_nominal => {
                seen_nominal = true;
                "nominal model: as configured, then refitted".to_string()
            }
            Role::Extended if !seen_extended => {
                seen_extended = true;
                "each effect added, and the final model".to_string()
            }
            _ => String::new(),
        };
        bars.push(WaterfallBar {
            name,
            from,
            to: step.after,
            role,
            legend,
        });
    }
    let panel = waterfall_panel(
        &format!("{}, step by step", measure.0),
        measure.1,
        &bars,
        floor,
    );
    let fig = stacked_figure(
        format!("{name}: held-out error from the configured to the final model"),
        vec![panel],
    );
    htfid_plot::Figure { height: 420, ..fig }
}

/// `htf_difference` of `diagnosis.json`.
pub fn htf_json(diffs: &[HarmonicDifference]) -> Value {
    Value::Array(
        diffs
            .iter()
            .map(|d| {
                json!({
                    "n": d.n,
                    "points": d.omega.len(),
                    "nominal_outside_noise": d.nominal_outside(),
                    "extended_outside_noise": d.extended_outside(),
                })
            })
            .collect(),
    )
}

/// Per harmonic, `|measured - model|` for the nominal model (`nominal_label`) and the
/// extended one (`ext_label`, when it differs) over the estimate's noise level `2 stderr`,
/// shaded from the bottom of the axes.
fn htf_difference_figure(
    title: &str,
    diffs: &[HarmonicDifference],
    nominal_label: &str,
    ext_label: Option<&str>,
    unit: Option<&str>,
) -> htfid_plot::Figure {
    let panels: Vec<Panel> = diffs
        .iter()
        .map(|d| {
            let mut curves = vec![BodeSeries {
                label: nominal_label,
                omega: &d.omega,
                response: &d.nominal,
                style: Style::Line,
            }];
            if let Some(label) = ext_label {
                curves.push(BodeSeries {
                    label,
                    omega: &d.omega,
                    response: &d.extended,
                    style: Style::Dashed,
                });
            }
            let mut p = magnitude_panel(&format!("G_{}: measured minus model", d.n), &curves);
            for (c, role) in p.series.iter_mut().zip([Role::Nominal, Role::Extended]) {
                c.role = Some(role);
            }
            let noise: Vec<f64> = d
                .stderr
                .iter()
                .map(|se| 20.0 * (SIGNIFICANT_RATIO * se).log10())
                .collect();
            p.series.insert(
                0,
                Series::band(
                    "estimate's noise: |difference| < 2 stderr",
                    d.omega.clone(),
                    vec![f64::NAN; d.omega.len()],
                    noise,
                )
                .with_role(Role::Estimate),
            );
            p.y_label = match unit {
                Some(u) => format!("|difference| (dB re 1 {u})"),
                None => "|difference| (dB)".into(),
            };
            p
        })
        .collect();
    let columns = if panels.len() > 4 {
        3
    } else {
        panels.len().max(1)
    };
    grid_figure(title.to_string(), panels, columns)
}

/// Where the refitted nominal model's binned residual acceleration `nominal` varies most (the
/// largest chi-square per bin), in words, with the extended model's there; `whose` names the
/// pair (`""` for a model with one).
fn strongest_in(
    nominal: &BinnedResidual,
    extended: Option<&BinnedResidual>,
    block_s: f64,
    u: &str,
    whose: &str,
) -> Option<String> {
    let cands = [
        ("position", Structure::of(&nominal.by_position)),
        ("velocity", Structure::of(&nominal.by_velocity)),
        ("the forcing phase", Structure::of(&nominal.by_phase)),
    ];
    let few = format!(
        "too few independent blocks of {} s (at least {} per bin) for standard errors of the \
         bin means",
        sig(block_s, 3),
        htfid_diagnose::MIN_BLOCKS
    );
    let Some((what, st)) = cands.iter().filter(|(_, st)| st.bins > 0).max_by(|a, b| {
        (a.1.chi_square / a.1.bins as f64).total_cmp(&(b.1.chi_square / b.1.bins as f64))
    }) else {
        let of = if whose.is_empty() {
            String::new()
        } else {
            format!(" of the residual acceleration{whose}")
        };
        return Some(format!(
            "The held-out data hold {few}{of}: `residual_bins.png` shows the means alone, and \
             no bin is said to stand off zero."
        ));
    };
    let ext = extended.map(|e| {
        let st = match *what {
            "position" => Structure::of(&e.by_position),
            "velocity" => Structure::of(&e.by_velocity),
            _ => Structure::of(&e.by_phase),
        };
        if st.bins == 0 {
            format!("; the extended model's bins there hold {few}")
        } else {
            format!(
                "; the extended model's stand at most {} standard errors from zero there",
                sig(st.max_abs_z, 3)
            )
        }
    });
    Some(format!(
        "The refitted nominal model's residual acceleration{whose} varies most against {what}: bin means from {} to {} {u}/s^2, up to {} standard errors of the bin mean from zero (`residual_bins.png`){}.",
        sig(st.min_mean, 4),
        sig(st.max_mean, 4),
        sig(st.max_abs_z, 3),
        ext.unwrap_or_default()
    ))
}
