//! Validation views of the commands that simulate a model against data: the
//! measured-against-simulated window with fit percentages (`compare.png`), the residual
//! correlations with their bounds (`resid.png`), and the matching JSON and report text. The
//! statistics are computed in `htfid-validate`.

use std::fmt::Write as _;
use std::ops::Range;

use htfid_plot::{stacked_figure, Figure, Panel, Role, Series, Style};
use htfid_validate::{fit_percent, resid, Resid, DEFAULT_LAGS};
use serde_json::{json, Value};

/// Periods of the forcing shown in a comparison window: enough to see the cycle repeat,
/// few enough that the waveform reads.
const WINDOW_PERIODS: f64 = 4.0;
/// Samples shown when no period is known: a few hundred keep a broadband record readable.
const WINDOW_SAMPLES: usize = 500;

/// One simulated output of a model.
pub struct Simulated<'a> {
    pub label: String,
    pub role: Role,
    pub style: Style,
    pub y: &'a [f64],
}

/// The validation of one output: fit percent per model, and the residual analysis of the last
/// model (the one a user keeps) against the input. `error` says why a part could not be computed.
#[derive(Clone)]
pub struct OutputValidation {
    pub output: String,
    pub fits: Vec<(String, Option<f64>)>,
    pub resid: Result<Resid, String>,
}

/// A readable window at the end of `range` (furthest from the simulation's start):
/// `WINDOW_PERIODS` periods, or `WINDOW_SAMPLES` samples without a period.
pub fn window(range: Range<usize>, dt: f64, period: Option<f64>) -> Range<usize> {
    let len = match period {
        Some(p) if p > 0.0 && dt > 0.0 => ((WINDOW_PERIODS * p / dt).ceil() as usize).max(16),
        _ => WINDOW_SAMPLES,
    };
    range.end.saturating_sub(len).max(range.start)..range.end
}

/// Fit percentages and the residual analysis of the last model in `models`, over `range`;
/// non-finite samples (a simulation that stopped) are left out.
pub fn validate(
    output: &str,
    measured: &[f64],
    input: &[f64],
    models: &[Simulated<'_>],
    range: Range<usize>,
) -> OutputValidation {
    let fits = models
        .iter()
        .map(|m| {
            (
                m.label.clone(),
                fit_percent(&measured[range.clone()], &m.y[range.clone()]).ok(),
            )
        })
        .collect();
    let resid = match models.last() {
        None => Err("no model".to_string()),
        Some(m) => {
            let (e, u): (Vec<f64>, Vec<f64>) = range
                .clone()
                .filter(|&i| measured[i].is_finite() && m.y[i].is_finite() && input[i].is_finite())
                .map(|i| (measured[i] - m.y[i], input[i]))
                .unzip();
            resid(&e, &u, DEFAULT_LAGS).map_err(|err| err.to_string())
        }
    };
    OutputValidation {
        output: output.to_string(),
        fits,
        resid,
    }
}

/// `fit_percent` per model, `whiteness` and `independence` of the residual analysis.
pub fn json(v: &OutputValidation, model: &str) -> Value {
    let fits: serde_json::Map<String, Value> = v
        .fits
        .iter()
        .map(|(label, f)| (label.clone(), json!(f)))
        .collect();
    match &v.resid {
        Ok(r) => json!({
            "fit_percent": fits,
            "residual_of": model,
            "lags": DEFAULT_LAGS,
            "whiteness": r.whiteness,
            "independence": r.independence,
        }),
        Err(e) => json!({
            "fit_percent": fits,
            "residual_of": model,
            "lags": DEFAULT_LAGS,
            "whiteness": null,
            "independence": null,
            "error": e,
        }),
    }
}

/// A measured-against-simulated panel over `window`, fit percent (over the whole held-out
/// part) in each model's legend entry.
pub fn compare_panel(
    title: &str,
    y_label: &str,
    t: &[f64],
    measured: &[f64],
    models: &[Simulated<'_>],
    fits: &[(String, Option<f64>)],
    window: Range<usize>,
) -> Panel {
    let mut p = Panel::new(title, htfid_plot::TIME_LABEL, y_label);
    let tw = t[window.clone()].to_vec();
    p.series.push(
        Series::new(
            "measured",
            tw.clone(),
            measured[window.clone()].to_vec(),
            Style::Line,
        )
        .with_role(Role::Measured),
    );
    for (m, (_, fit)) in models.iter().zip(fits) {
        let label = match fit {
            Some(f) => format!("{}: fit {f:.1} %", m.label),
            None => format!("{}: fit not defined", m.label),
        };
        p.series.push(
            Series::new(label, tw.clone(), m.y[window.clone()].to_vec(), m.style).with_role(m.role),
        );
    }
    p
}

/// Autocorrelation of the residual and its cross-correlation with the input, per output, with
/// the 99 % bounds.
pub fn resid_figure(
    title: &str,
    outputs: &[&OutputValidation],
    input: &str,
    dt: f64,
) -> Option<Figure> {
    let lag_label = format!("lag (samples of {} s)", crate::limits::approx(dt));
    let p_eq = |p: f64| {
        let t = p_text(p);
        if t.starts_with('<') {
            t
        } else {
            format!("= {t}")
        }
    };
    let mut panels = Vec::new();
    for v in outputs {
        let Ok(r) = &v.resid else { continue };
        let bound = r.whiteness.bound;
        let lags: Vec<f64> = (0..r.autocorrelation.len()).map(|k| k as f64).collect();
        let mut a = Panel::new(
            format!(
                "{}: autocorrelation of the residual ({} of {} lags outside, Ljung-Box p {})",
                v.output,
                r.whiteness.outside,
                r.whiteness.tested,
                p_eq(r.whiteness.p_value)
            ),
            lag_label.as_str(),
            "autocorrelation (1)",
        );
        a.series = bounds_and_stems(&lags, &r.autocorrelation, bound);
        let xl: Vec<f64> = r.cross_lags.iter().map(|&k| k as f64).collect();
        let mut c = Panel::new(
            format!(
                "{}: cross-correlation of residual and {input} ({} of {} lags 0..{} outside, portmanteau p {})",
                v.output,
                r.independence.outside,
                r.independence.tested,
                DEFAULT_LAGS,
                p_eq(r.independence.p_value)
            ),
            format!("{lag_label}; positive: input earlier"),
            "cross-correlation (1)",
        );
        c.series = bounds_and_stems(&xl, &r.cross_correlation, r.independence.bound);
        panels.push(a);
        panels.push(c);
    }
    if panels.is_empty() {
        return None;
    }
    Some(stacked_figure(title, panels))
}

fn bounds_and_stems(x: &[f64], r: &[f64], bound: f64) -> Vec<Series> {
    let (lo, hi) = (x[0] - 0.5, x[x.len() - 1] + 0.5);
    let max = r.iter().fold(bound, |m, v| m.max(v.abs()));
    vec![
        Series::new("correlation", x.to_vec(), r.to_vec(), Style::Stems).with_role(Role::Estimate),
        Series::new(
            "99 % bounds, +-2.58/sqrt(N)",
            vec![lo, hi],
            vec![bound, bound],
            Style::Dashed,
        )
        .with_role(Role::Bound),
        Series::new("", vec![lo, hi], vec![-bound, -bound], Style::Dashed).with_role(Role::Bound),
        // Keeps the vertical range symmetric about zero.
        Series::new("", vec![lo], vec![-max], Style::Line),
    ]
}

/// A p-value for people: below 1e-10 it only says so.
fn p_text(p: f64) -> String {
    if p < 1e-10 {
        "< 10⁻¹⁰".into()
    } else {
        htfid_number::sig(p, 2)
    }
}

/// What the validation section says when the measured input carries noise the diagnosis read
/// from its spectrum: the residual then holds the model's response to that noise.
pub fn noisy_input_note(input: &str) -> String {
    format!(
        "The measured {input} carries noise (see the noise floor above): the residual holds the \
         model's response to it, a filtered noise, so it is neither white nor independent of \
         the measured {input}, however right the model.\n"
    )
}

/// The validation section of a report.
pub fn report(heading: &str, vs: &[&OutputValidation], residual_of: &str, input: &str) -> String {
    let mut m = String::new();
    let _ = writeln!(m, "{heading}\n");
    let _ = writeln!(
        m,
        "Fit is `100 (1 - NRMSE)` on the held-out data (100 % a perfect simulation, 0 % no \
         better than the measured mean). The residual analysis is of the {residual_of}: the \
         autocorrelation of its residual at lags 1..{DEFAULT_LAGS} (whiteness) and the \
         cross-correlation with the {input} at lags 0..{DEFAULT_LAGS} (independence), against \
         99 % bounds `+-2.58/sqrt(N)`, each with a portmanteau test at the 1 % level: \
         Ljung-Box's for whiteness, and for independence the lags weighed by their covariance \
         (a band-limited input makes neighbouring lags move together, which Ljung-Box's sum \
         would read as dependence). A model that has captured the dynamics leaves about 1 % \
         of the lags outside the bounds.\n"
    );
    let _ = writeln!(
        m,
        "| output | fit | whiteness: lags outside | Ljung-Box p | verdict | independence: lags outside | portmanteau p | verdict |"
    );
    let _ = writeln!(m, "|---|---|---|---|---|---|---|---|");
    for v in vs {
        let fits = v
            .fits
            .iter()
            .map(|(l, f)| match f {
                Some(f) => format!("{l} {}", htfid_number::sig(*f, 3)) + " %",
                None => format!(
                    "{l} — (not defined: a constant measured output or too few finite samples)"
                ),
            })
            .collect::<Vec<_>>()
            .join(", ");
        match &v.resid {
            Ok(r) => {
                let verdict = |passed: bool, yes: &str, no: &str| {
                    if passed {
                        yes.to_string()
                    } else {
                        format!("**{no}**")
                    }
                };
                let _ =
                    writeln!(
                    m,
                    "| {} | {fits} | {} of {} ({:.0} %) | {} | {} | {} of {} ({:.0} %) | {} | {} |",
                    v.output,
                    r.whiteness.outside,
                    r.whiteness.tested,
                    100.0 * r.whiteness.outside_share,
                    p_text(r.whiteness.p_value),
                    verdict(r.whiteness.passed, "white", "not white"),
                    r.independence.outside,
                    r.independence.tested,
                    100.0 * r.independence.outside_share,
                    p_text(r.independence.p_value),
                    verdict(r.independence.passed, "independent", "correlated with the input"),
                );
            }
            Err(e) => {
                let _ = writeln!(m, "| {} | {fits} | not computed: {e} | | | | | |", v.output);
            }
        }
    }
    let _ = writeln!(m, "\n![measured against simulated](compare.png)\n");
    let _ = writeln!(m, "![residual analysis](resid.png)\n");
    m
}
