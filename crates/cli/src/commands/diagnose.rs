//! `htfid diagnose CONFIG`: read the record and the model file the config names, call
//! `htfid_diagnose::diagnose_model`, write the findings. The science is in `htfid-diagnose`.

use std::path::PathBuf;

use anyhow::Result;
use htfid_data::TimeSeries;
use htfid_diagnose::{diagnose_model, ModelCause, ModelDiagnosis};
use htfid_plot::{stacked_figure, Panel, Role, Series, Style};
use serde_json::json;

use crate::model_diagnose_config::ModelDiagnoseSettings;
use crate::output::{json_text, open, resolve_dir};
use crate::records::{read_record, Columns};
use crate::report::{shown_path, Report};
use htfid_number::{percent, sig, Quantity};

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
    let mut names: Vec<String> = ["diagnosis.json", "report.md"]
        .iter()
        .map(|n| n.to_string())
        .collect();
    // The orbit is drawn for a model with a forcing period only, the binned residual
    // acceleration for one with an output that reads a position.
    let pairs = !htfid_diagnose::second_order_pairs(&s.model).is_empty();
    for figure in ["compare", "resid"]
        .into_iter()
        .chain(super::diagnose_evidence::FIGURES)
        .filter(|f| *f != "orbit" || s.model.period().is_some())
        .filter(|f| *f != "residual_bins" || pairs)
    {
        names.extend([format!("{figure}.svg"), format!("{figure}.png")]);
    }
    // The HTFs from the data against the models', per output, for a model with a forcing
    // period.
    if s.model.period().is_some() {
        for o in 0..s.outputs.len() {
            let suffix = super::theory::suffix(&s.outputs, o);
            for figure in ["htf_data", "htf_difference"] {
                names.extend(["svg", "png"].map(|ext| format!("{figure}{suffix}.{ext}")));
            }
        }
    }
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let mut outdir = open(&dir, force, &names)?;
    let record = read_rows(&s, &s.file, s.rows.clone(), "data.rows")?;
    let validation = match s.held_out_file() {
        Some(path) => Some(read_rows(
            &s,
            path,
            s.validation_rows.clone(),
            "data.validation_rows",
        )?),
        None => None,
    };
    crate::progress::line(&format!(
        "diagnosing {} ({} samples) against model `{}`, refitting {:?}",
        s.file.display(),
        record.len(),
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
                htfid_diagnose::DiagnoseError::ModelMismatch { .. } => {
                    "data.outputs (or data.input, model.parameters)"
                }
                htfid_diagnose::DiagnoseError::ConstantOutput { .. } => "data.outputs",
                htfid_diagnose::DiagnoseError::StartState { .. } => {
                    "diagnose.rtol (a smaller tolerance), or model.parameters"
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
    let n = shown.len();
    let dt = shown.dt();
    // The samples the library scores as held-out: the validation record after its burn-in,
    // or the part of the record after the fit fraction.
    let held_out = match &validation {
        Some(_) => ((s.options.burn_in / dt).ceil() as usize).min(n / 4)..n,
        None => ((n as f64 * s.options.fit_fraction) as usize).min(n)..n,
    };
    // The HTFs the data hold against the models' (the same estimator on their simulations),
    // on the held-out data of a model with a forcing period.
    let htf = s.model.period().map(|p| {
        htfid_diagnose::estimated_comparison(
            shown,
            held_out.clone(),
            p,
            &d.simulated,
            d.simulated_extended.as_deref(),
        )
    });
    // Every output's validation of the last of the models `models` gives for it.
    let validate_with =
        |models: fn(&ModelDiagnosis, usize) -> Vec<crate::validation::Simulated<'_>>| {
            s.outputs
                .iter()
                .enumerate()
                .map(|(o, name)| {
                    crate::validation::validate(
                        name,
                        &shown.outputs()[o],
                        shown.input(),
                        &models(&d, o),
                        held_out.clone(),
                    )
                })
                .collect::<Vec<_>>()
        };
    let checks = validate_with(models_of);
    // With an effect named, the final model too: its residual is the one a user keeps.
    let final_label = d.extended.as_ref().map(|c| format!("with {}", c.effect));
    let checks_final = d
        .simulated_extended
        .as_ref()
        .and(final_label.as_ref())
        .map(|_| validate_with(models_shown));
    let validation_of = |checks: &[crate::validation::OutputValidation], model: &str| {
        let mut v = checks.first().map_or(serde_json::Value::Null, |v| {
            crate::validation::json(v, model)
        });
        if v.is_object() {
            v["by_output"] = serde_json::Value::Object(
                checks
                    .iter()
                    .map(|c| (c.output.clone(), crate::validation::json(c, model)))
                    .collect(),
            );
        }
        v
    };
    let validation_json = validation_of(&checks, "refitted model");
    let validation_final_json = match (&checks_final, &final_label) {
        (Some(c), Some(label)) => validation_of(c, label),
        _ => serde_json::Value::Null,
    };

    let steps = d.error_waterfall(!s.options.free.is_empty());
    let options = serde_json::json!({
        "free": s.options.free,
        "fit_fraction": s.options.fit_fraction,
        "burn_in": s.options.burn_in,
        "significance_sigma": s.options.significance_sigma,
        "min_gain": s.options.min_gain,
        "alpha": s.options.alpha,
        "rival_margin": s.options.rival_margin,
        "bic_margin": s.options.bic_margin,
        "unexplained_ratio": s.options.unexplained_ratio,
        "min_explained": s.options.min_explained,
        "max_effects": s.options.max_effects,
        "input_noise_share": s.options.input_noise_share,
        "input_noise_flatness": s.options.input_noise_flatness,
        "noise_band": [s.options.noise_band.0, s.options.noise_band.1],
        "resolution": s.options.resolution,
        "second_effect_floor_ratio": s.options.second_effect_floor_ratio,
        "rtol": s.options.rtol,
        "fit_tolerance": s.options.fit_tolerance,
        "max_iterations": s.options.max_iterations,
        "candidate_max_iterations": s.options.candidate_max_iterations,
        "effects": s.options.effects.iter().map(|e| e.name()).collect::<Vec<_>>(),
        "parameter_error": s.options.parameter_error,
        "terms": s.options.terms.iter().map(|k| k.name()).collect::<Vec<_>>(),
        "user_terms": s.options.user_terms.iter().map(|t| serde_json::json!({
            "name": t.name,
            "term": t.describe(),
        })).collect::<Vec<_>>(),
    });
    let json = json!({
        "name": s.name,
        "config": s.path.display().to_string(),
        "data": s.file.display().to_string(),
        "validation_data": s.held_out_file().map(|p| p.display().to_string()),
        "rows": s.rows.as_ref().map(|r| [r.start, r.end]),
        "validation_rows": s.validation_rows.as_ref().map(|r| [r.start, r.end]),
        "units": s.format.units_json(),
        "model": s.model.name(),
        "cause": d.cause,
        "parameters": d.parameters,
        "stderr": d.stderr,
        "nominal": { "nrmse": d.refitted.validation() },
        "gain": d.gain,
        "gain_vs_configured": d.gain_vs_configured,
        "configured": d.configured,
        "refitted": d.refitted,
        "refit_parameters": d.refit_parameters,
        "refit_gain": d.refit_gain,
        "stderr_inflation": d.stderr_inflation,
        "iterations": d.iterations,
        "stop": d.stop,
        "candidates": d.candidates,
        "causes": d.causes,
        "pairs": d.pairs,
        "later_rounds": d.later_rounds,
        "backward": d.backward,
        "extended": extended_json(&d),
        "parameters_beside": d.parameters_beside,
        "alternatives": d.alternatives,
        "noise_floor": d.noise_floor,
        "explained": d.explained,
        "validation": validation_json,
        "validation_final": validation_final_json,
        "options": options,
        "error_waterfall": steps,
        "residual_bins": super::diagnose_evidence::bins_json(&s, &d),
    });
    let mut json = json;
    if let Some(found) = &d.discovered {
        json["discovered"] = serde_json::to_value(found).unwrap_or_default();
    }
    if let Some(sentence) = &d.term_search {
        json["term_search"] = serde_json::Value::String(sentence.clone());
    }
    if let Some(noise) = d.input_noise {
        json["input_noise"] = serde_json::to_value(noise)?;
    }
    match &htf {
        Some(Ok(cmp)) => {
            let by_output = |c: &htfid_diagnose::EstimatedComparison| {
                super::diagnose_evidence::htf_json(&c.differences)
            };
            json["htf_difference"] = cmp.first().map_or(serde_json::Value::Null, by_output);
            json["htf_difference_by_output"] = serde_json::Value::Object(
                s.outputs
                    .iter()
                    .zip(cmp)
                    .map(|(name, c)| (name.clone(), by_output(c)))
                    .collect(),
            );
        }
        Some(Err(e)) => {
            json["htf_difference"] = serde_json::Value::Null;
            json["htf_difference_note"] = serde_json::Value::String(e.to_string());
        }
        None => {}
    }
    outdir.write_text("diagnosis.json", &json_text(&json))?;
    outdir.write_text(
        "report.md",
        &report(&s, &d, &checks, checks_final.as_deref(), htf.as_ref()),
    )?;
    // A few forcing periods at the end of the held-out part: measured, configured, refitted.
    let win = crate::validation::window(held_out.clone(), dt, s.model.period());
    let mut panels: Vec<Panel> = Vec::new();
    for (o, name) in s.outputs.iter().enumerate() {
        let unit = s
            .output_unit(o)
            .map_or(String::new(), |u| format!(" ({u})"));
        // Beside the configured and the refitted model, the model with the chosen effect.
        let models = models_shown(&d, o);
        let fits = match &checks_final {
            Some(f) => f[o].fits.clone(),
            None => checks[o].fits.clone(),
        };
        panels.push(crate::validation::compare_panel(
            &format!("{name}: measured and simulated (held-out data; fit over all of it)"),
            &format!("{name}{unit}"),
            shown.time(),
            &shown.outputs()[o],
            &models,
            &fits,
            win.clone(),
        ));
        let tw = shown.time()[win.clone()].to_vec();
        let residual = |sim: &[f64]| -> Vec<f64> {
            win.clone()
                .map(|i| shown.outputs()[o][i] - sim[i])
                .collect()
        };
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
            Series::new(
                "refitted model",
                tw.clone(),
                residual(&d.simulated[o]),
                Style::Line,
            )
            .with_role(if d.simulated_extended.is_some() {
                Role::Refitted
            } else {
                Role::Extended
            }),
        ];
        if let (Some(ext), Some(c)) = (&d.simulated_extended, &d.extended) {
            panel.series.push(
                Series::new(
                    format!("with {}", c.effect),
                    tw,
                    residual(&ext[o]),
                    Style::Line,
                )
                .with_role(Role::Extended),
            );
        }
        panels.push(panel);
    }
    // Several effects named: all of them in the title.
    let named = if d.causes.len() > 1 {
        d.causes
            .iter()
            .map(|c| c.effect.as_str())
            .collect::<Vec<_>>()
            .join(" + ")
    } else {
        d.cause.name().to_string()
    };
    let fig = stacked_figure(format!("{}: {named}", s.name), panels);
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
    super::diagnose_evidence::draw(&mut outdir, &s, &d, &steps, shown, held_out.clone())?;
    if let Some(Ok(cmp)) = &htf {
        super::diagnose_evidence::draw_htf(&mut outdir, &s, &d, cmp)?;
    }
    let written = outdir.commit()?;
    let unit = |name: &str| parameter_unit(&s, name);
    crate::results::diagnose(&json, &unit, &dir, &written);
    Ok(())
}

/// The parameters of the candidate `parameter_error` (`diagnose.parameter_error`) as the
/// final fit holds them: each from its configured value, with its standard error and by how
/// many standard errors it moved.
fn suspect_list(
    d: &ModelDiagnosis,
    s: &ModelDiagnoseSettings,
    unit: &dyn Fn(&str) -> Option<String>,
) -> String {
    let Some(c) = &d.extended else {
        return String::new();
    };
    let values = s.model.values();
    let (mut moved, mut kept) = (Vec::new(), Vec::new());
    for name in &s.options.parameter_error {
        let (Some(i), Some(&v), Some(&se)) = (
            s.model.parameter_index(name),
            c.parameters.get(name),
            c.stderr.get(name),
        ) else {
            continue;
        };
        let z = (v - values[i]) / se;
        if z.abs() >= s.options.significance_sigma {
            moved.push(format!(
                "`{name}` moves from {} to {} ({} standard errors)",
                sig(values[i], 4),
                Quantity::new(v).stderr(se).unit(unit(name).as_deref()),
                sig(z.abs(), 2)
            ));
        } else {
            kept.push(format!("`{name}`"));
        }
    }
    let mut out = moved.join(", ");
    if !kept.is_empty() {
        out.push_str(&format!(
            "{}{} {} within {} standard errors of {} configured value{}",
            if out.is_empty() { "" } else { "; " },
            kept.join(" and "),
            if kept.len() == 1 { "stays" } else { "stay" },
            sig(s.options.significance_sigma, 2),
            if kept.len() == 1 { "its" } else { "their" },
            if kept.len() == 1 { "" } else { "s" },
        ));
    }
    out
}

/// The free parameters beside the named effects, when some moved: a parameter error when
/// setting them back costs held-out accuracy, else a note; and any the stiffness law's
/// linear part moved. Empty when none moved.
fn beside_sentence(
    d: &ModelDiagnosis,
    min_gain: f64,
    unit: &dyn Fn(&str) -> Option<String>,
) -> String {
    let Some(p) = &d.parameters_beside else {
        return String::new();
    };
    let list = |changes: &[htfid_diagnose::ParameterChange]| {
        changes
            .iter()
            .map(|c| {
                format!(
                    "`{}` to {} (configured {}, {} standard errors)",
                    c.name,
                    Quantity::new(c.fitted)
                        .stderr(c.stderr)
                        .unit(unit(&c.name).as_deref()),
                    sig(c.configured, 4),
                    sig(c.z.abs(), 2)
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut out = String::new();
    if !p.moved.is_empty() {
        out.push_str(&if p.named {
            format!(
                " **The configured parameters are off as well** (`parameter_error`): beside \
                 the effects the fit moves {}; set back, the held-out NRMSE rises from {} to \
                 {} ({} lower with them as fitted).",
                list(&p.moved),
                percent(
                    d.extended.as_ref().map_or(f64::NAN, |c| c.nrmse_validation),
                    3
                ),
                percent(p.nrmse_reset, 3),
                percent(p.gain, 3)
            )
        } else {
            format!(
                " Beside the effects the fit moves {}, but setting them back costs only {} of \
                 the held-out NRMSE (under {}): not a finding.",
                list(&p.moved),
                percent(p.gain, 3),
                percent(min_gain, 2)
            )
        });
    }
    if !p.excused.is_empty() {
        out.push_str(&format!(
            " The stiffness law leaves its linear part to the model, which moves {}: that is \
             the law's slope about the motion's mean, not an error of the configured value.",
            list(&p.excused)
        ));
    }
    out
}

/// The model's parameters a diagnosis holds at their configured values (not in `free`), as
/// advice: one of them may be what is off, which no effect of the library stands in for.
fn held_parameters(s: &ModelDiagnoseSettings) -> String {
    let held: Vec<String> = s
        .model
        .parameters()
        .iter()
        .filter(|p| !s.options.free.contains(&p.name))
        .map(|p| format!("`{}`", p.name))
        .collect();
    if held.is_empty() {
        String::new()
    } else {
        format!(
            ", or free more of the model's parameters (`[model] free`; held at their configured \
             values now: {}): one of them may be what is off",
            held.join(", ")
        )
    }
}

/// The unit of a fitted parameter: the model's own parameters as declared (a term's are not
/// declared); on the boundary, a delay or a lag in s, an input offset in the input's unit and a sensor offset
/// `b_<output>` in that output's (the data's `data.units`, else the model's).
fn parameter_unit(s: &ModelDiagnoseSettings, name: &str) -> Option<String> {
    if s.model.parameter_index(name).is_some() {
        return s.model.parameter_unit(name).map(str::to_string);
    }
    let output = |output: &str| {
        let o = s.outputs.iter().position(|n| n == output)?;
        s.output_unit(o)
    };
    boundary_unit(name, s.input_unit(), output)
}

/// The unit of a boundary effect's parameter `name`: `delay`, `tau`, `tau_s` in s,
/// `input_offset` in the input's unit, `b_<output>` in that output's. A boundary parameter
/// whose name a model parameter holds takes the next free one (`tau_2`), so a name that is
/// none of these is read again without a trailing `_<number>`.
fn boundary_unit<'a>(
    name: &str,
    input: Option<&'a str>,
    output: impl Fn(&str) -> Option<&'a str>,
) -> Option<String> {
    let exact = |name: &str| match name {
        "delay" | "tau" | "tau_s" => Some("s".to_string()),
        "input_offset" => input.map(str::to_string),
        _ => output(name.strip_prefix("b_")?).map(str::to_string),
    };
    exact(name).or_else(|| {
        let (base, number) = name.rsplit_once('_')?;
        let renamed = !number.is_empty() && number.bytes().all(|b| b.is_ascii_digit());
        renamed.then(|| exact(base)).flatten()
    })
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

/// The models shown for output `o`: the configured and the refitted one, and the model with
/// the chosen effects when some are named (the refitted one then in its own colour).
pub(super) fn models_shown(d: &ModelDiagnosis, o: usize) -> Vec<crate::validation::Simulated<'_>> {
    let mut models = models_of(d, o);
    if let (Some(ext), Some(c)) = (&d.simulated_extended, &d.extended) {
        models[1].role = Role::Refitted;
        models.push(crate::validation::Simulated {
            label: format!("with {}", c.effect),
            role: Role::Extended,
            style: Style::Line,
            y: &ext[o],
        });
    }
    models
}

/// The record in `file`, or its `rows` (configured at `key`) when given.
fn read_rows(
    s: &ModelDiagnoseSettings,
    file: &std::path::Path,
    rows: Option<std::ops::Range<usize>>,
    key: &str,
) -> Result<TimeSeries> {
    let record = read_model_record(s, file)?;
    let Some(rows) = rows else {
        return Ok(record);
    };
    if rows.end > record.len() {
        anyhow::bail!(
            "{}: {key}: [{}, {}) reaches past the end of \"{}\", which has {} samples",
            s.path.display(),
            rows.start,
            rows.end,
            file.display(),
            record.len()
        );
    }
    Ok(record.slice(rows)?)
}

/// The record with one column per model output, each read from `file`.
fn read_model_record(s: &ModelDiagnoseSettings, file: &std::path::Path) -> Result<TimeSeries> {
    let mut parts = Vec::with_capacity(s.outputs.len());
    for column in &s.outputs {
        let columns = Columns {
            input: &s.input,
            output: column,
            time: s.time.as_deref(),
            sample_rate: s.sample_rate,
            time_tolerance: s.time_tolerance,
            format: &s.format,
        };
        let series = read_record(&s.path, file, columns)?;
        if parts.is_empty() {
            check_time_scale(s, &series)?;
        }
        parts.push(series);
    }
    Ok(TimeSeries::join_outputs(parts)?)
}

/// Refuses a record the model's forcing period says is in the wrong time unit, or one whose
/// simulation cannot finish under the integrator's step cap (each fit simulates the whole
/// record many times). A model without forcing has no period to compare with.
fn check_time_scale(s: &ModelDiagnoseSettings, series: &TimeSeries) -> Result<()> {
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

/// `report.md`: the decision in one paragraph, then the errors, the parameters, the
/// validation (`checks`, one per output).
fn report(
    s: &ModelDiagnoseSettings,
    d: &ModelDiagnosis,
    checks: &[crate::validation::OutputValidation],
    checks_final: Option<&[crate::validation::OutputValidation]>,
    htf: Option<&Result<Vec<htfid_diagnose::EstimatedComparison>, htfid_diagnose::DiagnoseError>>,
) -> String {
    let mut r = Report::new(&format!("Diagnosis: {}", s.name));
    r.para(&decision(s, d, checks, checks_final));
    notes(&mut r, s, d);
    data_section(&mut r, s);
    effects_sections(&mut r, s, d);
    errors_and_parameters(&mut r, s, d, checks, checks_final);
    figures_section(&mut r, s, d, htf);
    r.finish()
}

/// Where an effect without a term acts: the candidate `parameter_error` (alone or in a set) on
/// the model's own parameters, any other on its boundary.
fn where_boundary(effect: &str) -> String {
    if effect.split(" + ").any(|e| e == "parameter_error") {
        "the model's own parameters".into()
    } else {
        "on the boundary".into()
    }
}

/// The evidence figures (beside `compare` and `resid`, shown with the validation), each with
/// what it shows.
fn figures_section(
    r: &mut Report,
    s: &ModelDiagnoseSettings,
    d: &ModelDiagnosis,
    htf: Option<&Result<Vec<htfid_diagnose::EstimatedComparison>, htfid_diagnose::DiagnoseError>>,
) {
    r.section("Where the error sits");
    r.figure(
        "residual_time.png",
        "The held-out residual in time: its RMS per forcing period, and the first periods",
    );
    r.figure(
        "residual_spectrum.png",
        "Where in frequency the held-out residual sits",
    );
    if s.model.period().is_some() {
        r.figure(
            "orbit.png",
            "The orbit folded over the forcing period, with ±2 standard errors across the periods",
        );
    }
    if super::diagnose_evidence::bins_drawn(d) {
        let words = super::diagnose_evidence::bins_words(s, d);
        if !words.is_empty() {
            r.para(&words.join(" "));
        }
        r.figure(
            "residual_bins.png",
            "The residual acceleration against position, velocity and forcing phase, with ±2 \
             standard errors of each bin's mean",
        );
    }
    match htf {
        Some(Ok(cmp)) => {
            r.para(&super::diagnose_evidence::htf_words(s, d, cmp));
            r.figure(
                "htf_data.png",
                "The HTFs estimated from the held-out data, ±2 standard errors, against the \
                 models' (the same estimator on their simulations)",
            );
            r.figure(
                "htf_difference.png",
                "Per harmonic, the data's HTF minus each model's, against the estimate's noise",
            );
        }
        Some(Err(e)) => {
            // The error reads "the data's HTFs cannot be compared with the models': ...".
            let text = e.to_string();
            let mut chars = text.chars();
            let first = chars.next().map(|c| c.to_uppercase().to_string());
            r.para(&format!("{}{}.", first.unwrap_or_default(), chars.as_str()));
        }
        None => {}
    }
    r.figure(
        "error_waterfall.png",
        "The held-out NRMSE from the configured to the final model, step by step",
    );
}

/// The extended fit as in `diagnosis.json`: the candidate, with its held-out NRMSE also as
/// `nrmse` (as `nominal.nrmse`).
fn extended_json(d: &ModelDiagnosis) -> serde_json::Value {
    let mut v = serde_json::to_value(&d.extended).unwrap_or(serde_json::Value::Null);
    if let (Some(o), Some(c)) = (v.as_object_mut(), &d.extended) {
        o.insert("nrmse".into(), json!(c.nrmse_validation));
    }
    v
}

/// The decision in words, and whether the refitted model's residual is white.
fn decision(
    s: &ModelDiagnoseSettings,
    d: &ModelDiagnosis,
    checks: &[crate::validation::OutputValidation],
    checks_final: Option<&[crate::validation::OutputValidation]>,
) -> String {
    let model = s.model.name();
    let unit = |name: &str| parameter_unit(s, name);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
    let (before, after) = (
        mean(&d.configured.nrmse_validation),
        mean(&d.refitted.nrmse_validation),
    );
    let moved: Vec<String> = d
        .refit_parameters
        .iter()
        .filter(|p| p.z.abs() >= s.options.significance_sigma)
        .map(|p| {
            let u = unit(&p.name);
            format!(
                "`{}` from {} to {} ({} standard errors)",
                p.name,
                Quantity::new(p.configured).unit(u.as_deref()),
                Quantity::new(p.fitted).stderr(p.stderr).unit(u.as_deref()),
                sig(p.z.abs(), 2)
            )
        })
        .collect();
    let mut decision = match &d.cause {
        // The candidate `parameter_error` chosen first: its own fit.
        ModelCause::ParameterError if d.extended.is_some() => {
            let c = d.extended.as_ref();
            let others: Vec<String> = d
                .causes
                .iter()
                .filter(|c| c.effect != "parameter_error")
                .map(|c| format!("`{}`", c.effect))
                .collect();
            format!(
                "**The configured parameters of model `{model}` are off.** Refitted as the \
                 candidate `parameter_error`, {}; the held-out error falls from {} to {} \
                 NRMSE (likelihood ratio {:.1}, at least {:.1} needed).{}",
                suspect_list(d, s, &unit),
                percent(after, 3),
                percent(c.map_or(f64::NAN, |c| c.nrmse_validation), 3),
                c.map_or(f64::NAN, |c| c.likelihood_ratio),
                c.map_or(f64::NAN, |c| c.critical),
                if others.is_empty() {
                    String::new()
                } else {
                    format!(" Beside it the model misses {}.", others.join(" and "))
                }
            )
        }
        ModelCause::ParameterError => format!(
            "**The configured parameters of model `{model}` are off.** Refitting them moves {}, \
             and lowers the error on held-out data from {} to {} NRMSE, {} less.",
            moved.join(", "),
            percent(before, 3),
            percent(after, 3),
            percent(d.refit_gain, 3)
        ),
        ModelCause::Effect(e) => {
            let c = d.extended.as_ref();
            // Where an effect acts, from its own first-round fit.
            let site = |name: &str| match d
                .candidates
                .iter()
                .find(|c| c.effect == name)
                .and_then(|c| c.term.as_ref())
            {
                Some(term) => format!("in its equations ({term})"),
                None => "on its boundary".to_string(),
            };
            let fitted = c
                .map(|c| {
                    c.parameters
                        .iter()
                        // The free parameters, and the candidate parameter_error's (their
                        // own sentence), are not the effects'.
                        .filter(|(k, _)| {
                            !s.options.free.contains(k) && !s.options.parameter_error.contains(k)
                        })
                        .map(|(k, v)| {
                            format!(
                                "{k} = {}",
                                Quantity::new(*v)
                                    .stderr(c.stderr.get(k).copied().unwrap_or(f64::NAN))
                                    .unit(unit(k).as_deref())
                            )
                        })
                        .collect::<Vec<_>>()
                        .join(", ")
                })
                .unwrap_or_default();
            let overall = 1.0 - c.map_or(f64::NAN, |c| c.nrmse_validation) / after;
            let baseline = if s.options.free.is_empty() {
                "the model as configured"
            } else {
                "the refit of the free parameters"
            };
            // The effects named, in the order chosen (a parameter error has its own sentence).
            let effects: Vec<&str> = d
                .chosen()
                .into_iter()
                .filter(|n| *n != "parameter_error")
                .collect();
            let text = match effects.as_slice() {
                [.., last] if effects.len() >= 2 => {
                    let named: Vec<String> = effects
                        .iter()
                        .map(|n| format!("`{n}` {}", site(n)))
                        .collect();
                    let before: Vec<String> = effects[..effects.len() - 1]
                        .iter()
                        .map(|n| format!("`{n}`"))
                        .collect();
                    let count = match effects.len() {
                        2 => "two".to_string(),
                        3 => "three".to_string(),
                        k => k.to_string(),
                    };
                    // The last effect's test beside those before it: the fit of these
                    // effects alone (beside a parameter error the final fit has one more).
                    let set = effects.join(" + ");
                    let own = d
                        .pairs
                        .iter()
                        .chain(d.later_rounds.iter().flatten())
                        .find(|c| c.effect == set)
                        .or(c);
                    format!(
                        "The configured model `{model}` misses {count} effects: {} and {}. \
                         Fitted together ({fitted}), they lower the held-out error by {:.1} % \
                         beyond {baseline}; beside {}, `{last}` passes \
                         with a likelihood ratio of {:.1} (at least {:.1} needed) and lowers \
                         the held-out error by a further {:.1} %.",
                        named[..named.len() - 1].join(", "),
                        named[named.len() - 1],
                        100.0 * overall,
                        before.join(" and "),
                        own.map_or(f64::NAN, |c| c.likelihood_ratio),
                        own.map_or(f64::NAN, |c| c.critical),
                        100.0 * own.map_or(f64::NAN, |c| c.gain),
                    )
                }
                _ => {
                    // The effect's own test against the refit (beside a parameter error the
                    // final fit is the pair's).
                    let own = d.candidates.iter().find(|c| c.effect == *e).or(c);
                    format!(
                        "The configured model `{model}` misses an effect {}: `{e}` ({fitted}) \
                         lowers the held-out error by {:.1} % beyond {baseline} (likelihood \
                         ratio {:.1}, at least {:.1} needed).",
                        site(e),
                        100.0 * own.map_or(f64::NAN, |c| c.gain),
                        own.map_or(f64::NAN, |c| c.likelihood_ratio),
                        own.map_or(f64::NAN, |c| c.critical)
                    )
                }
            };
            let suspects = if d.causes.iter().any(|c| c.effect == "parameter_error")
                && !d.parameters_beside.as_ref().is_some_and(|p| p.named)
            {
                format!(
                    " **The configured parameters are off as well** (the candidate \
                     `parameter_error`, fitted with them): {}.",
                    suspect_list(d, s, &unit)
                )
            } else {
                String::new()
            };
            text + &suspects + &beside_sentence(d, s.options.min_gain, &unit)
        }
        ModelCause::Ambiguous => format!(
            "**Several effects explain the data of `{}` equally well:** {}. \
             The data cannot tell them apart; to do so, {}.",
            s.model.name(),
            d.alternatives
                .iter()
                .map(|a| format!("`{a}`"))
                .collect::<Vec<_>>()
                .join(", "),
            htfid_diagnose::separating_experiment(&d.alternatives)
        ),
        ModelCause::Unexplained => format!(
            "Clear structure remains in the residual of `{}` that neither the refit nor any \
             effect tried explains: the best model's held-out NRMSE {:.3} % stays above {} \
             times the noise floor {:.3} %{}. Write the suspected effect as a term of the \
             model's equations (`[[diagnose.terms]]`, see docs/config.md) and diagnose \
             again{}.",
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
            },
            held_parameters(s)
        ),
        ModelCause::None if s.options.free.is_empty() => format!(
            "**The configured model `{model}` describes the data.** No candidate effect{} \
             passes both tests against it: the held-out NRMSE is {} as configured.",
            if s.options.parameter_error.is_empty() {
                ""
            } else {
                ", the candidate `parameter_error` included,"
            },
            percent(before, 3)
        ),
        ModelCause::None => format!(
            "**The configured model `{model}` describes the data.** A refit moves no parameter \
             by {} standard errors or more while lowering the held-out error by at least {}: \
             the held-out NRMSE is {} as configured and {} refitted.",
            sig(s.options.significance_sigma, 2),
            percent(s.options.min_gain, 2),
            percent(before, 3),
            percent(after, 3)
        ),
    };
    let structured_in = |checks: &[crate::validation::OutputValidation]| -> Vec<String> {
        checks
            .iter()
            .filter(|c| c.resid.as_ref().is_ok_and(|r| !r.whiteness.passed))
            .map(|c| format!("`{}`", c.output))
            .collect()
    };
    let structured: Vec<String> = structured_in(checks);
    // Whose residual the validation above analyses: with nothing free, the model as
    // configured (its initial state fitted).
    let refit = !s.options.free.is_empty();
    let analysed = if refit {
        "refitted model's"
    } else {
        "configured model's"
    };
    // With an effect named, the residual a user keeps is the final model's.
    if let (Some(fin), Some(c)) = (checks_final, &d.extended) {
        let left = structured_in(fin);
        decision.push_str(&if left.is_empty() {
            format!(
                " The final model's residual (with `{}`) is white: no structure is left for \
                 an effect the model lacks.",
                c.effect
            )
        } else {
            format!(
                " The final model's residual (with `{}`) in {} is not white: its held-out \
                 NRMSE is {} times the noise floor{}.",
                c.effect,
                left.join(", "),
                sig(c.nrmse_validation / d.noise_floor, 3),
                if d.input_noise.is_some() {
                    ", which holds the model's response to the noise on the measured input, \
                     a filtered noise (see below)"
                } else {
                    ""
                }
            )
        });
        return decision;
    }
    if structured.is_empty() {
        decision.push_str(&format!(
            " The {} residual is white: no structure is left for an effect the model lacks.",
            analysed
        ));
    } else if d.input_noise.is_some() && matches!(d.cause, ModelCause::None) {
        // The response to the input's noise is filtered noise: not white, and not an effect.
        decision.push_str(&format!(
            " The {} residual in {} is not white, and need not be: its held-out \
             NRMSE is {} times the noise floor, which holds the model's response to the noise \
             on the measured input, a filtered noise (see below).",
            analysed,
            structured.join(", "),
            sig(d.refitted.validation() / d.noise_floor, 3)
        ));
    } else {
        let next = match (&d.cause, &d.extended) {
            (ModelCause::Effect(_) | ModelCause::Ambiguous, Some(c)) => format!(
                "the effects above account for it: `{}` removes {} of the error above the \
                 noise floor.",
                c.effect,
                percent(d.explained, 3)
            ),
            // The candidate parameter_error chosen: the model's own parameters, held as
            // configured in the refit, explain it.
            (ModelCause::ParameterError, Some(c)) => format!(
                "the refit held the suspected parameters as configured, and the candidate \
                 `{}` removes {} of the error above the noise floor.",
                c.effect,
                percent(d.explained, 3)
            ),
            // The decision above already says what to do.
            _ if matches!(d.cause, ModelCause::Unexplained) => {
                "no effect tried accounts for it.".to_string()
            }
            _ => "no effect tried accounts for it. Write the suspected effect as a term of \
                  the model's equations (`[[diagnose.terms]]`) and diagnose again to measure \
                  its gain."
                .to_string(),
        };
        decision.push_str(&format!(
            " The {} residual in {} is not white: structure remains{}; {next}",
            analysed,
            structured.join(", "),
            if refit {
                " that the model's own parameters cannot explain"
            } else {
                ""
            }
        ));
    }
    decision
}

/// Fits that stopped at their iteration limit, the noise floor's share from the measured
/// input's noise, and the term search outside the library, when they apply.
fn notes(r: &mut Report, s: &ModelDiagnoseSettings, d: &ModelDiagnosis) {
    // A fit stopped at its limit has not converged: its tests are not to be trusted.
    let limit = format!("{:?}", htfid_estimate::LmStop::MaxIterations);
    let unconverged = d
        .candidates
        .iter()
        .chain(&d.pairs)
        .chain(d.later_rounds.iter().flatten())
        .filter(|c| c.iterations >= s.options.candidate_max_iterations)
        .count();
    if d.stop == limit {
        r.para(&format!(
            "**The refit did not converge.** It stopped at its limit of {} iterations \
             (`diagnose.max_iterations`) while still improving, so the refitted values are not \
             its optimum, and every candidate fitted from it also improves the refit's own \
             parameters: their likelihood ratios are inflated. Raise `diagnose.max_iterations`, \
             or free fewer parameters, and diagnose again.",
            s.options.max_iterations
        ));
    }
    // Parameters the final fit cannot tell apart: no standard error.
    let unresolved: Vec<String> = d
        .parameters
        .keys()
        .filter(|n| !d.stderr.get(*n).is_some_and(|e| e.is_finite()))
        .map(|n| format!("`{n}`"))
        .collect();
    if !unresolved.is_empty() {
        r.para(&format!(
            "**The record cannot tell some of the final model's parameters apart**: {} have no \
             standard error (the final fit's covariance is singular, or its residual has no \
             degrees of freedom left). Other values of them fit as well; hold one of them fixed \
             (`model.free`, or leave out the effect that adds it) to read the others. A sensor's \
             gain beside a free mass, stiffness and damping is one such case: it only rescales \
             the state, which they undo.",
            crate::report::join_and(&unresolved)
        ));
    }
    if unconverged > 0 {
        r.para(&format!(
            "{unconverged} of the candidate fits stopped at their limit of {} iterations \
             (`diagnose.candidate_max_iterations`) before converging; their scores are upper \
             bounds (their notes say which).",
            s.options.candidate_max_iterations
        ));
    }
    if let Some(noise) = d.input_noise {
        r.para(&format!(
            "The noise floor, {} of the outputs' spread, holds the refitted model's response to \
             the noise on the measured input, {}: the input's spectrum between {} % and {} % of \
             the Nyquist frequency is that of white noise of {} RMS, and the simulation is \
             driven by the measured input, so no model driven by it predicts the outputs closer \
             than that (`input_noise` in `diagnosis.json`).",
            percent(d.noise_floor, 3),
            percent(noise.propagated, 3),
            // Percentages of the band's edges, rounded off the binary fractions' tails.
            (1e6 * s.options.noise_band.0).round() / 1e4,
            (1e6 * s.options.noise_band.1).round() / 1e4,
            sig(noise.sigma, 3)
        ));
    }
    if let Some(sentence) = &d.term_search {
        r.para(&match &d.discovered {
            Some(found) => format!(
                "**Outside the library**, a search over products of the states in the \
                 equations of the velocity states writes what the refit leaves as `{}`: with \
                 it the refitted model predicts the held-out data with NRMSE {} instead of {} \
                 ({} lower). The search stopped because {}. This is a hint beside the \
                 decision above, which it does not change; to test it as an effect, write it as \
                 a term of the model (`[[diagnose.terms]]`) and diagnose again.",
                found.formula,
                percent(found.nrmse_after, 3),
                percent(found.nrmse_before, 3),
                percent(found.gain, 3),
                found.stopped
            ),
            None => format!("**Outside the library**, nothing: {sentence}."),
        });
    }
}

/// The config, the data, what was refitted and what held out.
fn data_section(r: &mut Report, s: &ModelDiagnoseSettings) {
    r.section("Data");
    let rows = |r: &Option<std::ops::Range<usize>>| {
        r.as_ref().map_or(String::new(), |r| {
            format!(", rows {} to {}", r.start, r.end - 1)
        })
    };
    let held_out = match (&s.validation, s.held_out_file()) {
        (Some(p), _) => format!(
            "the separate record `{}`{}",
            shown_path(p),
            rows(&s.validation_rows)
        ),
        (None, Some(p)) => format!("`{}`{}", shown_path(p), rows(&s.validation_rows)),
        (None, None) => format!(
            "the last {} of the record",
            percent(1.0 - s.options.fit_fraction, 2)
        ),
    };
    let listed = |names: &[String]| {
        names
            .iter()
            .map(|p| format!("`{p}`"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut items = vec![
        format!(
            "Config: `{}`; data: `{}`{}.",
            shown_path(&s.path),
            shown_path(&s.file),
            rows(&s.rows)
        ),
        if s.options.free.is_empty() {
            "Refitted with every candidate: nothing (the model as configured).".to_string()
        } else {
            format!(
                "Refitted with every candidate: {} (the model's own parameters only).",
                listed(&s.options.free)
            )
        },
    ];
    if !s.options.parameter_error.is_empty() {
        items.push(format!(
            "Held at their configured values, and refitted together only as the candidate \
             `parameter_error`: {}.",
            listed(&s.options.parameter_error)
        ));
    }
    items.push(format!(
        "Held out from the fit and used to judge it: {held_out}."
    ));
    r.list(&items);
}

/// One row per effect of `list` in the tables of effects tried: its parameters (those of
/// the effect, not the free ones), scores and tests, or why its fit failed.
fn effect_rows(
    r: &mut Report,
    s: &ModelDiagnoseSettings,
    list: &[htfid_diagnose::ModelCandidate],
) -> Vec<Vec<String>> {
    let mut rows = Vec::new();
    for c in list {
        if c.nrmse_validation.is_finite() {
            let own: Vec<String> = c
                .parameters
                .iter()
                .filter(|(k, _)| !s.options.free.contains(*k))
                .map(|(k, v)| {
                    format!(
                        "{k} = {}",
                        Quantity::new(*v)
                            .stderr(c.stderr.get(k).copied().unwrap_or(f64::NAN))
                            .unit(parameter_unit(s, k).as_deref())
                    )
                })
                .collect();
            rows.push(vec![
                format!("`{}`", c.effect),
                c.term.clone().unwrap_or_else(|| where_boundary(&c.effect)),
                own.join(", "),
                percent(c.nrmse_validation, 3),
                percent(c.gain, 3),
                format!("{} ({})", sig(c.likelihood_ratio, 3), sig(c.critical, 3)),
                if c.significant { "yes" } else { "no" }.to_string(),
            ]);
        } else {
            let why = r.missing(&c.note);
            rows.push(vec![
                format!("`{}`", c.effect),
                c.term.clone().unwrap_or_else(|| where_boundary(&c.effect)),
                why.clone(),
                why.clone(),
                why.clone(),
                why,
                "no".to_string(),
            ]);
        }
    }
    rows
}

/// The tables of the effects tried: the first round, the second effect, the later rounds and
/// the backward pass.
fn effects_sections(r: &mut Report, s: &ModelDiagnoseSettings, d: &ModelDiagnosis) {
    if !d.candidates.is_empty() {
        r.section("Effects tried");
        r.para(
            "Beside the model's own parameters, candidate effects are tried, each fitted \
             jointly with the free parameters and the initial state. On the model's boundary: \
             an input offset, delay or lag, and a sensor offset and gain or lag. Inside its \
             equations, at every site the model offers: drag and a stiffness law on the \
             equation of each velocity state, an extra damping in each mode, each switching \
             surface moved; and the config's own terms. An effect is significant when its \
             likelihood ratio against the refit (corrected for the residuals' correlation) \
             passes the chi-square critical value and it lowers the held-out NRMSE by at least \
             the minimum gain.",
        );
        let rows = effect_rows(r, s, &d.candidates);
        r.table(
            &[
                "effect",
                "where",
                "its parameters",
                "held-out NRMSE",
                "gain over the refit",
                "likelihood ratio (critical)",
                "significant",
            ],
            &rows,
        );
    }
    if !d.pairs.is_empty() {
        r.section("A second effect");
        r.para(
            "The best effect left the held-out residual above the noise floor, so every other \
             candidate was refitted jointly with it (and with its rivals), all parameters and \
             the initial state together, and tested against it as it was against the refit: \
             the likelihood ratio is against the first effect alone, the gain is over it.",
        );
        let rows = effect_rows(r, s, &d.pairs);
        r.table(
            &[
                "effects",
                "where the second acts",
                "their parameters",
                "held-out NRMSE",
                "gain over the first alone",
                "likelihood ratio (critical)",
                "significant",
            ],
            &rows,
        );
    }

    for (k, round) in d.later_rounds.iter().enumerate() {
        r.section(&format!("Effect {} beside the others", k + 3));
        r.para(
            "The effects chosen so far still left the held-out residual above the noise floor, \
             so every other candidate was refitted jointly with them and tested against their \
             fit: the likelihood ratio is against the chosen effects alone, the gain over them.",
        );
        let rows = effect_rows(r, s, round);
        r.table(
            &[
                "effects",
                "where the last acts",
                "their parameters",
                "held-out NRMSE",
                "gain over the others",
                "likelihood ratio (critical)",
                "significant",
            ],
            &rows,
        );
    }
    if !d.backward.is_empty() {
        r.section("Is each effect still needed?");
        r.para(
            "A backward pass: each chosen effect tested against the fit of the others without \
             it. The held-out NRMSE is that without it, the gain and the likelihood ratio \
             those of adding it back; the weakest effect that no longer passes is dropped and \
             the pass repeats.",
        );
        let rows: Vec<Vec<String>> = d
            .backward
            .iter()
            .map(|c| {
                vec![
                    format!("`{}`", c.effect),
                    percent(c.nrmse_validation, 3),
                    percent(c.gain, 3),
                    format!("{:.1} ({:.1})", c.likelihood_ratio, c.critical),
                    if c.significant {
                        "needed"
                    } else {
                        "not needed"
                    }
                    .to_string(),
                ]
            })
            .collect();
        r.table(
            &[
                "effect",
                "held-out NRMSE without it",
                "gain with it",
                "likelihood ratio (critical)",
                "verdict",
            ],
            &rows,
        );
    }
}

/// The held-out errors, the parameters and the validation of the refitted model.
fn errors_and_parameters(
    r: &mut Report,
    s: &ModelDiagnoseSettings,
    d: &ModelDiagnosis,
    checks: &[crate::validation::OutputValidation],
    checks_final: Option<&[crate::validation::OutputValidation]>,
) {
    let unit = |name: &str| parameter_unit(s, name);
    r.section("Error on held-out data");
    r.para(
        "NRMSE (normalised root-mean-square error): the RMS of measured minus simulated output \
         over the standard deviation of the measured output, in %. 0 % is a perfect \
         simulation; 100 % is no better than the measured mean.",
    );
    let rows: Vec<Vec<String>> = s
        .outputs
        .iter()
        .enumerate()
        .map(|(o, name)| {
            vec![
                format!("`{name}`"),
                percent(d.configured.nrmse_validation[o], 3),
                percent(d.refitted.nrmse_validation[o], 3),
            ]
        })
        .collect();
    r.table(&["output", "configured model", "refitted model"], &rows);

    r.section("Parameters");
    if d.refit_parameters.is_empty() {
        r.para(
            "Nothing is refitted with every candidate (`[model] free = []`): the model's \
             parameters stay as configured, and only the candidate `parameter_error` (when \
             `[diagnose] parameter_error` names some) refits them; its values are in the \
             paragraph at the top and in the table of effects tried.",
        );
    } else {
        parameter_table(r, d, &unit);
    }
    match (checks_final, &d.extended) {
        // One table: each output's refitted model, then its final model.
        (Some(fin), Some(c)) => {
            let rows: Vec<crate::validation::OutputValidation> = checks
                .iter()
                .zip(fin)
                .flat_map(|(a, b)| {
                    let mut a = a.clone();
                    let mut b = b.clone();
                    a.output = format!("{}: refitted model", a.output);
                    b.output = format!("{}: with {}", b.output, c.effect);
                    [a, b]
                })
                .collect();
            r.push(&crate::validation::report(
                "## Validation",
                &rows.iter().collect::<Vec<_>>(),
                &format!(
                    "refitted model and of the final one (with `{}`), a row each",
                    c.effect
                ),
                &format!("input `{}`", s.input),
            ));
        }
        _ => r.push(&crate::validation::report(
            "## Validation",
            &checks.iter().collect::<Vec<_>>(),
            "refitted model",
            &format!("input `{}`", s.input),
        )),
    }
    if d.input_noise.is_some() {
        r.para(crate::validation::noisy_input_note(&format!("input `{}`", s.input)).trim_end());
    }
}

/// The refitted free parameters: configured, refitted with its standard error, and by how many
/// standard errors they moved; and the widening of the standard errors.
fn parameter_table(r: &mut Report, d: &ModelDiagnosis, unit: &dyn Fn(&str) -> Option<String>) {
    let mut rows = Vec::new();
    for p in &d.refit_parameters {
        let u = unit(&p.name);
        let z = if p.z.is_finite() {
            sig(p.z, 2)
        } else {
            r.missing("no standard error: the fit's covariance is singular for this parameter")
        };
        rows.push(vec![
            format!("`{}`", p.name),
            Quantity::new(p.configured).unit(u.as_deref()).to_string(),
            Quantity::new(p.fitted)
                .stderr(p.stderr)
                .unit(u.as_deref())
                .to_string(),
            z,
        ]);
    }
    r.table(
        &[
            "parameter",
            "configured",
            "refitted ± standard error",
            "(refitted − configured) / standard error",
        ],
        &rows,
    );
    r.para(&if d.stderr_inflation > 1.0 {
        format!(
            "The standard errors are widened by a factor {} because the residuals are \
             correlated in time.",
            sig(d.stderr_inflation, 3)
        )
    } else {
        "The residuals show no correlation in time that would widen the standard errors."
            .to_string()
    });
}

#[cfg(test)]
mod tests {
    use super::boundary_unit;

    #[test]
    fn a_renamed_boundary_parameter_keeps_its_unit() {
        let output = |o: &str| match o {
            "x" => Some("m"),
            "x_2" => Some("mm"),
            _ => None,
        };
        let unit = |name: &str| boundary_unit(name, Some("N"), output);
        assert_eq!(unit("tau").as_deref(), Some("s"));
        assert_eq!(unit("tau_2").as_deref(), Some("s"));
        assert_eq!(unit("tau_s_3").as_deref(), Some("s"));
        assert_eq!(unit("delay_2").as_deref(), Some("s"));
        assert_eq!(unit("input_offset_2").as_deref(), Some("N"));
        assert_eq!(unit("b_x").as_deref(), Some("m"));
        assert_eq!(unit("b_x_2").as_deref(), Some("mm"), "an output named x_2");
        assert_eq!(unit("b_x_3").as_deref(), Some("m"), "b_x renamed");
        assert_eq!(
            unit("drag_v_2"),
            None,
            "a term's parameter has no declared unit"
        );
        assert_eq!(unit("tau_"), None);
        assert_eq!(unit("g_x"), None, "a gain has no unit");
    }
}
