//! `htfid diagnose` for a config whose `[model]` names a model file: read the record, call
//! `htfid_diagnose::diagnose_model`, write the findings. The science is in `htfid-diagnose`.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result};
use htfid_diagnose::{diagnose_model, ModelCause, ModelDiagnosis, ModelRecord};
use htfid_plot::{stacked_figure, time_panel, Panel, Series, Style};
use serde_json::json;

use crate::commands::simulate::report_written;
use crate::model_diagnose_config::ModelDiagnoseSettings;
use crate::output::{json_text, open, resolve_dir};
use crate::records::{read_record, Columns};

/// Seconds of the held-out part drawn in the comparison figure (a readable window).
const WINDOW_S: f64 = 10.0;

pub fn run(
    config: &std::path::Path,
    data: Option<PathBuf>,
    out: Option<PathBuf>,
    force: bool,
) -> Result<()> {
    let s = ModelDiagnoseSettings::from_file(config, data)?;
    let dir = resolve_dir(out, &s.name);
    let mut outdir = open(
        &dir,
        force,
        &["diagnosis.json", "report.md", "compare.svg", "compare.png"],
    )?;
    let record = read_model_record(&s, &s.file)?;
    let validation = match &s.validation {
        Some(path) => Some(read_model_record(&s, path)?),
        None => None,
    };
    eprintln!(
        "[htfid] diagnosing {} ({} samples) against model `{}`, refitting {:?}",
        s.file.display(),
        record.t.len(),
        s.model.name(),
        s.options.free
    );
    let d = diagnose_model(&s.model, &record, validation.as_ref(), &s.options)
        .context("diagnosis failed")?;
    // The figure shows the held-out data: the validation record when there is one.
    let shown = validation.as_ref().unwrap_or(&record);

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
        "options": {
            "free": s.options.free,
            "fit_fraction": s.options.fit_fraction,
            "burn_in": s.options.burn_in,
            "significance_sigma": s.options.significance_sigma,
            "min_gain": s.options.min_gain,
        },
    });
    outdir.write_text("diagnosis.json", &json_text(&json))?;
    outdir.write_text("report.md", &report(&s, &d))?;
    // The last WINDOW_S seconds of the held-out part: measured, configured, refitted.
    let n = shown.t.len();
    let dt = (shown.t[n - 1] - shown.t[0]) / (n - 1) as f64;
    let start = n.saturating_sub((WINDOW_S / dt) as usize);
    let mut panels: Vec<Panel> = Vec::new();
    for (o, name) in s.outputs.iter().enumerate() {
        // The unit the data are measured in (data.units), else the model's.
        let unit = s
            .format
            .unit(name)
            .or(s.model.outputs()[o].unit.as_deref())
            .map_or(String::new(), |u| format!(" ({u})"));
        let tw = shown.t[start..].to_vec();
        let mut panel = time_panel(
            &format!("{name}: measured and simulated (held-out data)"),
            &format!("{name}{unit}"),
            &tw,
            [("measured", &shown.y[o][start..])],
        );
        panel.series.push(Series::new(
            "configured model",
            tw.clone(),
            d.simulated_configured[o][start..].to_vec(),
            Style::Dashed,
        ));
        panel.series.push(Series::new(
            "refitted model",
            tw.clone(),
            d.simulated[o][start..].to_vec(),
            Style::Line,
        ));
        panels.push(panel);
        let residual =
            |sim: &[f64]| -> Vec<f64> { (start..n).map(|i| shown.y[o][i] - sim[i]).collect() };
        let mut panel = time_panel(
            &format!("{name}: residual, measured minus simulated"),
            &format!("residual{unit}"),
            &tw,
            [("configured model", residual(&d.simulated_configured[o]))],
        );
        panel.series[0].style = Style::Dashed;
        panel.series.push(Series::new(
            "refitted model",
            tw,
            residual(&d.simulated[o]),
            Style::Line,
        ));
        panels.push(panel);
    }
    let fig = stacked_figure(format!("{}: {}", s.name, d.cause.name()), panels);
    crate::plots::write(&mut outdir, "compare", &fig)?;
    eprintln!(
        "[htfid] cause: {} (held-out gain of the refit {:.1} %)",
        d.cause.name(),
        100.0 * d.gain
    );
    report_written(&outdir.commit()?);
    Ok(())
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
            t = series.time().to_vec();
            u = series.input().to_vec();
        }
        y.push(series.output().to_vec());
    }
    Ok(ModelRecord { t, u, y })
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
        "Only the model's own parameters are refitted here: an effect the model lacks (friction, \
         an extra damping, a sensor lag) shows as shifted parameters and a residual with \
         structure. Extend the model with a candidate term and diagnose again to measure its gain.\n"
    );
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
         Figure: `compare.png` (the last {WINDOW_S} s of the held-out data).",
        d.stderr_inflation
    );
    r
}
