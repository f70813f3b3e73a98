//! `htfid diagnose` for a config whose `[model]` names a model file: read the record, call
//! `htfid_diagnose::diagnose_model`, write the findings. The science is in `htfid-diagnose`.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Result;
use htfid_diagnose::{diagnose_model, ModelCause, ModelDiagnosis, ModelRecord};
use htfid_plot::{stacked_figure, Panel, Role, Series, Style};
use serde_json::json;

use crate::model_diagnose_config::ModelDiagnoseSettings;
use crate::output::{json_text, open, resolve_dir};
use crate::records::{read_record, Columns};

pub fn run(
    config: &std::path::Path,
    data: Option<PathBuf>,
    out: Option<PathBuf>,
    force: bool,
) -> Result<()> {
    let s = ModelDiagnoseSettings::from_file(config, data)?;
    crate::limits::check_data_file(&s.path, "data.file", &s.file)?;
    if let Some(v) = &s.validation {
        crate::limits::check_data_file(&s.path, "data.validation", v)?;
    }
    let dir = resolve_dir(out, &s.name);
    let mut outdir = open(
        &dir,
        force,
        &[
            "diagnosis.json",
            "report.md",
            "compare.svg",
            "compare.png",
            "resid.svg",
            "resid.png",
        ],
    )?;
    let record = read_model_record(&s, &s.file)?;
    let validation = match &s.validation {
        Some(path) => Some(read_model_record(&s, path)?),
        None => None,
    };
    crate::progress::line(&format!(
        "diagnosing {} ({} samples) against model `{}`, refitting {:?}",
        s.file.display(),
        record.t.len(),
        s.model.name(),
        s.options.free
    ));
    let d = crate::progress::Stages::new()
        .run("output-error fit", || {
            diagnose_model(&s.model, &record, validation.as_ref(), &s.options)
        })
        .map_err(|e| {
            // The keys a user changes to repair each failure.
            let key = match &e {
                htfid_diagnose::DiagnoseError::ScaleMismatch { .. } => {
                    "model.parameters (or the units of data.outputs)"
                }
                _ => "model.parameters",
            };
            anyhow::anyhow!(
                "{}: {key}: diagnosis of \"{}\" failed: {e}",
                s.path.display(),
                s.file.display()
            )
        })?;
    // The figure shows the held-out data: the validation record when there is one.
    let shown = validation.as_ref().unwrap_or(&record);
    let n = shown.t.len();
    let dt = (shown.t[n - 1] - shown.t[0]) / (n - 1).max(1) as f64;
    // The samples the library scores as held-out: the validation record after its burn-in,
    // or the part of the record after the fit fraction.
    let held_out = match &validation {
        Some(_) => ((s.options.burn_in / dt).ceil() as usize).min(n / 4)..n,
        None => ((n as f64 * s.options.fit_fraction) as usize).min(n)..n,
    };
    let checks: Vec<crate::validation::OutputValidation> = s
        .outputs
        .iter()
        .enumerate()
        .map(|(o, name)| {
            crate::validation::validate(
                name,
                &shown.y[o],
                &shown.u,
                &models_of(&d, o),
                held_out.clone(),
            )
        })
        .collect();
    let mut validation_json = checks.first().map_or(serde_json::Value::Null, |v| {
        crate::validation::json(v, "refitted model")
    });
    if validation_json.is_object() {
        validation_json["by_output"] = serde_json::Value::Object(
            checks
                .iter()
                .map(|v| {
                    (
                        v.output.clone(),
                        crate::validation::json(v, "refitted model"),
                    )
                })
                .collect(),
        );
    }

    let json = json!({
        "name": s.name,
        "config": s.path.display().to_string(),
        "data": s.file.display().to_string(),
        "validation_data": s.validation.as_ref().map(|p| p.display().to_string()),
        "units": s.format.units_json(),
        "model": s.model.name(),
        "cause": d.cause,
        "gain": d.gain,
        "configured": d.configured,
        "refitted": d.refitted,
        "parameters": d.parameters,
        "stderr_inflation": d.stderr_inflation,
        "iterations": d.iterations,
        "stop": d.stop,
        "candidates": d.candidates,
        "extended": d.extended,
        "alternatives": d.alternatives,
        "noise_floor": d.noise_floor,
        "explained": d.explained,
        "validation": validation_json,
        "options": {
            "free": s.options.free,
            "fit_fraction": s.options.fit_fraction,
            "burn_in": s.options.burn_in,
            "significance_sigma": s.options.significance_sigma,
            "min_gain": s.options.min_gain,
            "alpha": s.options.alpha,
            "rival_margin": s.options.rival_margin,
            "unexplained_ratio": s.options.unexplained_ratio,
            "min_explained": s.options.min_explained,
            "effects": s.options.effects.iter().map(|e| e.name()).collect::<Vec<_>>(),
        },
    });
    outdir.write_text("diagnosis.json", &json_text(&json))?;
    let mut text = report(&s, &d);
    text.push_str(&crate::validation::report(
        "## Validation",
        &checks.iter().collect::<Vec<_>>(),
        "refitted model",
        &format!("input `{}`", s.input),
    ));
    outdir.write_text("report.md", &text)?;
    // A few forcing periods at the end of the held-out part: measured, configured, refitted.
    let win = crate::validation::window(held_out.clone(), dt, s.model.period());
    let mut panels: Vec<Panel> = Vec::new();
    for (o, name) in s.outputs.iter().enumerate() {
        // The unit the data are measured in (data.units), else the model's.
        let unit = s
            .format
            .unit(name)
            .or(s.model.outputs()[o].unit.as_deref())
            .map_or(String::new(), |u| format!(" ({u})"));
        panels.push(crate::validation::compare_panel(
            &format!("{name}: measured and simulated (held-out data; fit over all of it)"),
            &format!("{name}{unit}"),
            &shown.t,
            &shown.y[o],
            &models_of(&d, o),
            &checks[o].fits,
            win.clone(),
        ));
        let tw = shown.t[win.clone()].to_vec();
        let residual =
            |sim: &[f64]| -> Vec<f64> { win.clone().map(|i| shown.y[o][i] - sim[i]).collect() };
        let mut panel = Panel::new(
            format!("{name}: residual, measured minus simulated"),
            htfid_plot::TIME_LABEL,
            format!("residual{unit}"),
        );
        panel.series = vec![
            Series::new(
                "configured model",
                tw.clone(),
                residual(&d.simulated_configured[o]),
                Style::Dashed,
            )
            .with_role(Role::Nominal),
            Series::new("refitted model", tw, residual(&d.simulated[o]), Style::Line)
                .with_role(Role::Extended),
        ];
        panels.push(panel);
    }
    let fig = stacked_figure(format!("{}: {}", s.name, d.cause.name()), panels);
    crate::plots::write(&mut outdir, "compare", &fig)?;
    if let Some(fig) = crate::validation::resid_figure(
        &format!(
            "{}: residual analysis of the refitted model (held-out data)",
            s.name
        ),
        &checks.iter().collect::<Vec<_>>(),
        &s.input,
        dt,
    ) {
        crate::plots::write(&mut outdir, "resid", &fig)?;
    }
    let written = outdir.commit()?;
    let unit = |name: &str| {
        s.model
            .parameters()
            .iter()
            .find(|p| p.name == name)
            .and_then(|p| p.unit.clone())
    };
    crate::results::diagnose_model(&json, &unit, &dir, &written);
    Ok(())
}

/// The configured and the refitted simulation of output `o`, the refitted last.
fn models_of(d: &ModelDiagnosis, o: usize) -> Vec<crate::validation::Simulated<'_>> {
    vec![
        crate::validation::Simulated {
            label: "configured model".into(),
            role: Role::Nominal,
            style: Style::Dashed,
            y: &d.simulated_configured[o],
        },
        crate::validation::Simulated {
            label: "refitted model".into(),
            role: Role::Extended,
            style: Style::Line,
            y: &d.simulated[o],
        },
    ]
}

fn read_model_record(s: &ModelDiagnoseSettings, file: &std::path::Path) -> Result<ModelRecord> {
    let (mut t, mut u, mut y) = (Vec::new(), Vec::new(), Vec::new());
    for (o, column) in s.outputs.iter().enumerate() {
        let columns = Columns {
            input: &s.input,
            output: column,
            time: s.time.as_deref(),
            sample_rate: s.sample_rate,
            time_tolerance: s.time_tolerance,
            format: &s.format,
        };
        let series = read_record(&s.path, file, columns)?;
        if o == 0 {
            check_time_scale(s, &series)?;
            t = series.time().to_vec();
            u = series.input().to_vec();
        }
        y.push(series.output().to_vec());
    }
    Ok(ModelRecord { t, u, y })
}

/// Refuses a record the model's forcing period says is in the wrong time unit, or one whose
/// simulation cannot finish under the integrator's step cap (each fit simulates the whole
/// record many times). A model without forcing has no period to compare with.
fn check_time_scale(s: &ModelDiagnoseSettings, series: &htfid_data::TimeSeries) -> Result<()> {
    let Some(period) = s.model.period() else {
        return Ok(());
    };
    let what = format!("the forcing period of model `{}`", s.model.name());
    let hint = crate::records::unit_hint(s.sample_rate);
    crate::records::check_time_scale(
        &s.path,
        series.dt(),
        series.len(),
        crate::records::TimeScale {
            period,
            what: &what,
        },
        hint,
    )?;
    let duration = series.dt() * series.len().saturating_sub(1) as f64;
    let steps = htfid_hybrid::min_steps(duration, period);
    let cap = htfid_hybrid::Options::default().max_steps;
    if steps > cap as f64 {
        anyhow::bail!(
            "{}: the record lasts {} s, {} forcing periods of model `{}`: one simulation of it \
             needs at least {} integration steps (limit {cap}): {hint}, or shorten the record",
            s.path.display(),
            crate::limits::approx(duration),
            crate::limits::approx(duration / period),
            s.model.name(),
            crate::limits::approx(steps)
        );
    }
    Ok(())
}

fn report(s: &ModelDiagnoseSettings, d: &ModelDiagnosis) -> String {
    let mut r = String::new();
    let _ = writeln!(r, "# Diagnosis: {}\n", s.name);
    let verdict = match d.cause {
        ModelCause::ParameterError => format!(
            "The configured model `{}` misdescribes the data through its parameters: refitting {} \
             lowers the held-out error by {:.1} %.",
            s.model.name(),
            d.parameters
                .iter()
                .filter(|p| p.z.abs() >= s.options.significance_sigma)
                .map(|p| format!("`{}` ({:.4} -> {:.4})", p.name, p.configured, p.fitted))
                .collect::<Vec<_>>()
                .join(", "),
            100.0 * d.gain
        ),
        ModelCause::Effect(e) => {
            let c = d.extended.as_ref();
            format!(
                "The configured model `{}` misses an effect on its boundary: `{}` ({}) lowers the \
                 held-out error by {:.1} % beyond the refit of the free parameters (likelihood \
                 ratio {:.1}, at least {:.1} needed).",
                s.model.name(),
                e.name(),
                c.map(|c| {
                    c.parameters
                        .iter()
                        .filter(|(k, _)| !s.options.free.contains(k))
                        .map(|(k, v)| format!("{k} = {v:.4} ± {:.2}", c.stderr[k]))
                        .collect::<Vec<_>>()
                        .join(", ")
                })
                .unwrap_or_default(),
                100.0 * c.map_or(f64::NAN, |c| c.gain),
                c.map_or(f64::NAN, |c| c.likelihood_ratio),
                c.map_or(f64::NAN, |c| c.critical)
            )
        }
        ModelCause::Ambiguous => format!(
            "Several effects on the boundary of `{}` explain the data equally well: {}. An \
             experiment that separates the input side from the output side (a measured actuator \
             output, or a second sensor) would tell them apart.",
            s.model.name(),
            d.alternatives
                .iter()
                .map(|a| format!("`{a}`"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        ModelCause::Unexplained => format!(
            "Clear structure remains in the residual of `{}` that neither the refit nor an \
             effect on its boundary explains: the best model's held-out NRMSE {:.3} % stays \
             above {} times the noise floor {:.3} %{}. The cause is likely inside the model's \
             equations (friction, an extra damping, a stiffness law): extend the model with a \
             candidate term and diagnose again.",
            s.model.name(),
            100.0
                * d.extended
                    .as_ref()
                    .map_or(d.refitted.validation(), |c| c.nrmse_validation),
            s.options.unexplained_ratio,
            100.0 * d.noise_floor,
            match &d.extended {
                Some(c) => format!(
                    ", and the best effect, `{}`, removes only {:.1} % of the error above it",
                    c.effect,
                    100.0 * d.explained
                ),
                None => String::new(),
            }
        ),
        ModelCause::None => format!(
            "No parameter of `{}` moved by {} standard errors with a held-out gain of {:.0} %: \
             the configured model describes the data as well as a refit does.",
            s.model.name(),
            s.options.significance_sigma,
            100.0 * s.options.min_gain
        ),
    };
    let _ = writeln!(r, "{verdict}\n");
    let _ = writeln!(
        r,
        "Beside the model's own parameters, effects on its boundary are tried, each fitted \
         jointly with the free parameters: an input offset, delay or lag, and a sensor offset \
         and gain or lag. An effect inside the model's equations (friction, an extra damping) \
         shows as shifted parameters and a residual with structure: extend the model with a \
         candidate term and diagnose again to measure its gain.\n"
    );
    if !d.candidates.is_empty() {
        let _ = writeln!(
            r,
            "| effect | held-out NRMSE | gain over the refit | likelihood ratio (critical) | \
             significant |\n|---|---|---|---|---|"
        );
        for c in &d.candidates {
            if c.nrmse_validation.is_finite() {
                let _ = writeln!(
                    r,
                    "| `{}` | {:.3} % | {:.1} % | {:.1} ({:.1}) | {} |",
                    c.effect,
                    100.0 * c.nrmse_validation,
                    100.0 * c.gain,
                    c.likelihood_ratio,
                    c.critical,
                    if c.significant { "yes" } else { "no" }
                );
            } else {
                let _ = writeln!(r, "| `{}` | — | — | — | no: {} |", c.effect, c.note);
            }
        }
        let _ = writeln!(r);
    }
    let _ = writeln!(
        r,
        "NRMSE is the RMS error over the standard deviation of the measured output, in %; the \
         held-out data are {}.\n",
        match &s.validation {
            Some(p) => format!("the separate record `{}`", p.display()),
            None => format!(
                "the last {:.0} % of the record",
                100.0 * (1.0 - s.options.fit_fraction)
            ),
        }
    );
    let _ = writeln!(
        r,
        "| output | configured, held-out NRMSE | refitted, held-out NRMSE |"
    );
    let _ = writeln!(r, "|---|---|---|");
    for (o, name) in s.outputs.iter().enumerate() {
        let _ = writeln!(
            r,
            "| {name} | {:.3} % | {:.3} % |",
            100.0 * d.configured.nrmse_validation[o],
            100.0 * d.refitted.nrmse_validation[o]
        );
    }
    let _ = writeln!(
        r,
        "\n| parameter | configured | refitted | standard error | shift in standard errors |"
    );
    let _ = writeln!(r, "|---|---|---|---|---|");
    for p in &d.parameters {
        let _ = writeln!(
            r,
            "| {} | {:.5} | {:.5} | {:.2e} | {:.1} |",
            p.name, p.configured, p.fitted, p.stderr, p.z
        );
    }
    let _ = writeln!(
        r,
        "\nStandard errors are inflated by {:.2} for the residuals' correlation in time. \
         Figures: `compare.png` (a few periods at the end of the held-out data), `resid.png`.",
        d.stderr_inflation
    );
    r
}
