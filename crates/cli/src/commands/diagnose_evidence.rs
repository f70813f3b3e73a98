//! The evidence figures of `htfid diagnose` and the paragraph that opens its report: the
//! residual acceleration binned against position, velocity and forcing phase, the held-out
//! error from the configured to the final model, the HTF difference per harmonic, and a
//! readable window of the residual in time. The numbers come from `htfid-diagnose`; this
//! module draws them and puts them into words.

use std::ops::Range;
use std::path::Path;

use anyhow::Result;
use htfid_data::OutputDir;
use htfid_diagnose::{
    error_waterfall, quantile_range, residual_acceleration, Bin, BinnedResidual, DiagnosisReport,
    ErrorStep, HarmonicDifference, Interpolation, Structure, TimeSeries,
};
use htfid_plot::{
    binned_panel, grid_figure, magnitude_panel, stacked_figure, waterfall_panel, BinnedSeries,
    BodeSeries, Panel, Role, Series, Style, WaterfallBar, SIGNIFICANT_RATIO,
};
use serde_json::{json, Value};

use crate::plots;
use crate::settings::DiagnoseSettings;
use htfid_number::sig as num;

/// Natural periods of the nominal model per block of the standard errors, and per window of
/// the residual in time, when no forcing period is known.
const NATURAL_PERIODS_PER_BLOCK: f64 = 10.0;
const NATURAL_PERIODS_PER_WINDOW: f64 = 20.0;
/// Forcing periods in the window of the residual in time.
const WINDOW_PERIODS: f64 = 4.0;

/// The binned residual accelerations and the held-out error steps.
pub struct Evidence {
    /// Length of the blocks taken as independent in the standard errors (s).
    pub block_s: f64,
    /// What a block is, in words.
    pub block_words: String,
    /// The refitted nominal model's residual.
    pub nominal: BinnedResidual,
    /// The extended model's, when it differs from the nominal one.
    pub extended: Option<BinnedResidual>,
    /// Configured, refitted, each effect, final.
    pub waterfall: Vec<ErrorStep>,
}

/// The output's unit, when the record's columns or the config say it.
pub fn output_unit(s: &DiagnoseSettings) -> Option<String> {
    if let Some(u) = s.data.format.unit(&s.data.output) {
        Some(u.to_string())
    } else if s.data.output == "x" {
        Some("m".into())
    } else {
        None
    }
}

fn unit_or_words(s: &DiagnoseSettings) -> String {
    output_unit(s).unwrap_or_else(|| "output units".into())
}

/// What the nominal model's natural period is called: a spring's period, or for a free mass
/// (`k = 0`) `2 pi m / c`, its velocity's time constant times 2 pi.
pub fn natural_periods(k: f64) -> &'static str {
    if k > 0.0 {
        "natural periods of the nominal model"
    } else {
        "periods 2 pi m / c of the free mass"
    }
}

fn natural_period(report: &DiagnosisReport) -> f64 {
    let p = &report.nominal_model.params;
    2.0 * std::f64::consts::PI / p.natural_rate()
}

fn forcing_period(s: &DiagnoseSettings) -> Option<f64> {
    (s.params.forcing_amplitude.abs() > 0.0 && s.params.period > 0.0).then_some(s.params.period)
}

/// The residual accelerations of both models on the held-out samples, binned.
pub fn compute(
    s: &DiagnoseSettings,
    record: &TimeSeries,
    report: &DiagnosisReport,
    interpolation: Interpolation,
) -> Result<Evidence> {
    let period = forcing_period(s);
    let (block_s, block_words) = match period {
        Some(p) => (p, "one forcing period".to_string()),
        None => {
            let b = NATURAL_PERIODS_PER_BLOCK * natural_period(report);
            (
                b,
                format!(
                    "{} s, ten {}",
                    num(b, 3),
                    natural_periods(report.nominal_model.params.k)
                ),
            )
        }
    };
    let ranges = &report.validation_ranges;
    let nominal = residual_acceleration(
        record,
        &report.nominal_model,
        ranges,
        report.burn_in_s,
        interpolation,
    )?;
    let (xr, vr) = (quantile_range(&nominal.x), quantile_range(&nominal.v));
    let binned_nominal = BinnedResidual::new(&nominal, block_s, period, Some(xr), Some(vr));
    let extended = if report.extended_model == report.nominal_model {
        None
    } else {
        let e = residual_acceleration(
            record,
            &report.extended_model,
            ranges,
            report.burn_in_s,
            interpolation,
        )?;
        Some(BinnedResidual::new(&e, block_s, period, Some(xr), Some(vr)))
    };
    Ok(Evidence {
        block_s,
        block_words,
        nominal: binned_nominal,
        extended,
        waterfall: error_waterfall(&report.diagnosis),
    })
}

/// `residual_bins` and `error_waterfall` of `diagnosis.json`.
pub fn json(ev: &Evidence, s: &DiagnoseSettings) -> (Value, Value) {
    let unit = output_unit(s).map_or(Value::Null, |u| json!(format!("{u}/s^2")));
    let bins = json!({
        "quantity": "acceleration",
        "unit": unit,
        "block_s": ev.block_s,
        "band_stderrs": htfid_plot::BIN_BAND_STDERRS,
        "nominal": ev.nominal,
        "extended": ev.extended,
    });
    (bins, json!(ev.waterfall))
}

fn columns(bins: &[Bin]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    (
        bins.iter().map(|b| b.centre).collect(),
        bins.iter().map(|b| b.mean).collect(),
        bins.iter().map(|b| b.stderr).collect(),
    )
}

/// `residual_bins.png`: one panel per binned variable.
pub fn draw_bins(
    out: &mut OutputDir,
    s: &DiagnoseSettings,
    report: &DiagnosisReport,
    ev: &Evidence,
) -> Result<()> {
    let u = unit_or_words(s);
    let ext_label = super::diagnose::ext_label(report);
    let panels = bins_panels(&BinsFigure {
        position: format!("position {} ({u})", s.data.output),
        unit: &u,
        block_words: &ev.block_words,
        nominal: &ev.nominal,
        extended: ev.extended.as_ref().map(|e| (e, ext_label.as_str())),
        period: forcing_period(s),
        first: true,
        prefix: String::new(),
    });
    if panels.is_empty() {
        // Too few held-out samples to fill a bin: no figure (the report says nothing of bins).
        return Ok(());
    }
    let fig = stacked_figure(
        format!(
            "{}: residual acceleration, measured minus model (held-out data)",
            s.name
        ),
        panels,
    );
    plots::write(out, "residual_bins", &fig)
}

/// What [`bins_panels`] draws: one pair's binned residual acceleration.
pub struct BinsFigure<'a> {
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
pub fn bins_panels(f: &BinsFigure<'_>) -> Vec<Panel> {
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
pub fn fold_sampled(t: &[f64], y: &[f64], period: f64, dt: f64) -> Vec<Bin> {
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
pub fn rms_per_block(t: &[f64], r: &[f64], block: f64) -> (Vec<f64>, Vec<f64>) {
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
pub fn means_on(reference: &[Bin], other: &[Bin]) -> Vec<f64> {
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

/// `error_waterfall.png`.
pub fn draw_waterfall(
    out: &mut OutputDir,
    s: &DiagnoseSettings,
    report: &DiagnosisReport,
    ev: &Evidence,
) -> Result<()> {
    let u = unit_or_words(s);
    let fig = waterfall_figure(
        &s.name,
        &ev.waterfall,
        &format!("refit {}", s.free.join(", ")),
        ("held-out RMSE", &format!("held-out RMSE ({u})")),
        report
            .noise_floor
            .map(|floor| (floor, format!("noise floor ({} {u})", num(floor, 3)))),
    );
    plots::write(out, "error_waterfall", &fig)
}

/// The figure of a held-out error from the configured to the final model, step by step
/// (`steps` as `htfid-diagnose` gives them: `configured`, `refitted`, the effects, `final`):
/// the refit's bar named `refit` under the axis, the error's name and axis label in `measure`,
/// and the noise floor with its legend.
pub fn waterfall_figure(
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

/// The samples of the residual-in-time window: a few forcing periods (or natural periods of
/// the nominal model) from the start of the first held-out range, after its burn-in.
pub fn time_window(
    s: &DiagnoseSettings,
    record: &TimeSeries,
    report: &DiagnosisReport,
) -> Range<usize> {
    let dt = record.dt();
    let r = report
        .validation_ranges
        .first()
        .cloned()
        .unwrap_or(0..record.len());
    let burn = (report.burn_in_s / dt).ceil() as usize;
    let start = (r.start + burn).min(r.end);
    let span = forcing_period(s).map_or(NATURAL_PERIODS_PER_WINDOW * natural_period(report), |p| {
        WINDOW_PERIODS * p
    });
    let len = ((span / dt).ceil() as usize).max(64);
    start..(start + len).min(r.end)
}

/// Words for the window's length.
pub fn window_words(s: &DiagnoseSettings) -> String {
    match forcing_period(s) {
        Some(_) => format!("{WINDOW_PERIODS} forcing periods"),
        None => format!(
            "{NATURAL_PERIODS_PER_WINDOW} {}",
            natural_periods(s.params.k)
        ),
    }
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

/// `htf_difference.png`: per harmonic, `|measured - model|` for both models over the
/// estimate's noise level `2 stderr`, shaded from the bottom of the axes.
pub fn draw_htf_difference(
    out: &mut OutputDir,
    s: &DiagnoseSettings,
    report: &DiagnosisReport,
    diffs: &[HarmonicDifference],
    unit: Option<&str>,
) -> Result<()> {
    let ext_label = format!("{}: measured - theory", super::diagnose::ext_label(report));
    let fig = htf_difference_figure(
        &format!(
            "{}: HTF estimated from the data minus each model's theory, per harmonic",
            s.name
        ),
        diffs,
        "nominal: measured - theory",
        (report.extended_model != report.nominal_model).then_some(ext_label.as_str()),
        unit,
    );
    plots::write(out, "htf_difference", &fig)
}

/// Per harmonic, `|measured - model|` for the nominal model (`nominal_label`) and the
/// extended one (`ext_label`, when it differs) over the estimate's noise level `2 stderr`,
/// shaded from the bottom of the axes.
pub fn htf_difference_figure(
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

/// Which binned variable shows the nominal residual most, in words with its numbers.
fn strongest(ev: &Evidence, s: &DiagnoseSettings) -> Option<String> {
    strongest_in(
        &ev.nominal,
        ev.extended.as_ref(),
        ev.block_s,
        &unit_or_words(s),
        "",
    )
}

/// Where the refitted nominal model's binned residual acceleration `nominal` varies most (the
/// largest chi-square per bin), in words, with the extended model's there; `whose` names the
/// pair (`""` for a model with one).
pub fn strongest_in(
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
        num(block_s, 3),
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
                num(st.max_abs_z, 3)
            )
        }
    });
    Some(format!(
        "The refitted nominal model's residual acceleration{whose} varies most against {what}: bin means from {} to {} {u}/s^2, up to {} standard errors of the bin mean from zero (`residual_bins.png`){}.",
        num(st.min_mean, 4),
        num(st.max_mean, 4),
        num(st.max_abs_z, 3),
        ext.unwrap_or_default()
    ))
}

fn pct(x: f64) -> String {
    format!("{} %", num(100.0 * x, 4))
}

/// The path as a reader finds it: relative to the working directory (with `..` where it lies
/// outside), or as given when that cannot be worked out.
pub fn shown_path(p: &Path) -> String {
    use std::path::Component;
    let (Ok(abs), Ok(cwd)) = (std::fs::canonicalize(p), std::env::current_dir()) else {
        return p.display().to_string();
    };
    let cwd = std::fs::canonicalize(&cwd).unwrap_or(cwd);
    let a: Vec<Component<'_>> = abs.components().collect();
    let c: Vec<Component<'_>> = cwd.components().collect();
    let common = a.iter().zip(&c).take_while(|(x, y)| x == y).count();
    if common == 0 {
        return abs.display().to_string();
    }
    let mut rel = std::path::PathBuf::new();
    for _ in common..c.len() {
        rel.push("..");
    }
    for part in &a[common..] {
        rel.push(part.as_os_str());
    }
    rel.display().to_string()
}

/// The opening paragraph of `report.md`: the decision in words, with its numbers.
pub fn summary(
    s: &DiagnoseSettings,
    report: &DiagnosisReport,
    ev: &Evidence,
    htf: &[HarmonicDifference],
    param_text: &dyn Fn(&str, f64, f64) -> String,
) -> String {
    let d = &report.diagnosis;
    let u = unit_or_words(s);
    let rmse = |v: f64| format!("{} {u}", num(v, 4));
    let mut p = format!(
        "On the held-out data of `{}`, the model as configured",
        shown_path(&s.data.file)
    );
    if d.configured.nrmse.is_finite() {
        p.push_str(&format!(
            " predicts {} with NRMSE {} (RMSE {}; NRMSE is the RMS of measured minus simulated {} over the standard deviation of the measured {}, in %)",
            s.data.output,
            pct(d.configured.nrmse),
            rmse(d.configured.rmse),
            s.data.output,
            s.data.output
        ));
        p.push_str(&format!(
            "; with {} refitted the nominal model reaches {} ({}).",
            s.free.join(", "),
            pct(d.nominal.nrmse),
            rmse(d.nominal.rmse)
        ));
    } else {
        p.push_str(&format!(
            " could not be simulated; with {} refitted the nominal model predicts {} with NRMSE {} (RMSE {}; NRMSE is the RMS of measured minus simulated {} over the standard deviation of the measured {}, in %).",
            s.free.join(", "),
            s.data.output,
            pct(d.nominal.nrmse),
            rmse(d.nominal.rmse),
            s.data.output,
            s.data.output
        ));
    }
    let effects: Vec<&htfid_diagnose::Cause> = d
        .causes
        .iter()
        .filter(|c| c.effect != "parameter_error")
        .collect();
    if effects.is_empty() {
        p.push_str(&match d.cause.as_str() {
            "none" => " No effect is needed: the refitted nominal model explains the data down to the noise.".to_string(),
            "parameter_error" => " Only the configured parameters are off; no effect of the library improves on the refit.".to_string(),
            "model_mismatch" => " The model does not describe these data at all, so no effect is named.".to_string(),
            _ => " No library effect passes the tests, yet structure remains in the residual.".to_string(),
        });
    } else {
        let named: Vec<String> = effects
            .iter()
            .map(|c| {
                let params: Vec<String> = c
                    .parameters
                    .iter()
                    .map(|(k, v)| param_text(k, *v, c.stderr.get(k).copied().unwrap_or(f64::NAN)))
                    .collect();
                format!("`{}` ({})", c.effect, params.join(", "))
            })
            .collect();
        p.push_str(&format!(
            " Adding {} brings it to {} ({}), {} below the refitted model",
            named.join(" and "),
            pct(d.extended.nrmse),
            rmse(d.extended.rmse),
            pct(d.gain)
        ));
        match report.noise_floor {
            Some(f) if f > 0.0 => p.push_str(&format!(
                ", at {} times the noise floor ({})",
                num(d.extended.rmse / f, 3),
                rmse(f)
            )),
            _ => {}
        }
        p.push_str(&format!(
            "; the diagnosis is `{}` (`error_waterfall.png` shows each step).",
            d.cause
        ));
    }
    if let Some(words) = strongest(ev, s) {
        p.push(' ');
        p.push_str(&words);
    }
    if !htf.is_empty() {
        let parts: Vec<String> = htf
            .iter()
            .map(|h| {
                if report.extended_model == report.nominal_model {
                    format!("`G_{}` {}", h.n, pct(h.nominal_outside()))
                } else {
                    format!(
                        "`G_{}` {} (extended {})",
                        h.n,
                        pct(h.nominal_outside()),
                        pct(h.extended_outside())
                    )
                }
            })
            .collect();
        p.push_str(&format!(
            " In the HTFs estimated from the data, the difference from the nominal model's theory exceeds the estimate's noise (2 standard errors) at these shares of the frequency bins: {} (for noise alone, about 2 % or fewer; `htf_difference.png`).",
            parts.join(", ")
        ));
    }
    p
}
