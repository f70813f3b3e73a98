//! `htfid diagnose CONFIG [--data CSV]`: measured data against the model: what the model gets
//! wrong, the cause, the extended model and its gain.

use std::fmt::Write as _;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use anyhow::{Context, Result};
use htfid_data::{OutputDir, TimeSeries};

use crate::records::{read_record, Columns};
use htfid_diagnose::{
    amplitude_spectrum, diagnose_with_progress, htf_comparison, score_on_record, DiagnoseOptions,
    DiagnosisReport, Effect, HarmonicDifference, HtfComparisonSpec, NominalModel, NominalParam,
};
use htfid_model::Effects;
use htfid_plot::{
    grid_figure, spectrum_panel, stacked_figure, time_panel, Panel, Role, Series, SpectrumScale,
    Style,
};
use num_complex::Complex64;
use serde_json::{json, Value};

use crate::commands::diagnose_evidence as evidence;
use crate::output::{json_text, open, resolve_dir};
use crate::plots;
use crate::settings::DiagnoseSettings;

const PLOTS: [&str; 7] = [
    "residual_time",
    "residual_spectrum",
    "orbit",
    "compare",
    "resid",
    "residual_bins",
    "error_waterfall",
];

/// Harmonics of the data-against-theory HTF figure.
const HTF_HARMONICS: [i32; 5] = [-2, -1, 0, 1, 2];
/// Output band of the data's HTF figure, rad/s.
const HTF_BAND: (f64, f64) = (1.0, 40.0);

pub fn run(config: &Path, data: Option<PathBuf>, out: Option<PathBuf>, force: bool) -> Result<()> {
    if crate::model_diagnose_config::names_a_model_file(config) {
        return crate::commands::diagnose_model::run(config, data, out, force);
    }
    let mut settings = DiagnoseSettings::from_file(config)?;
    if let Some(d) = data {
        settings.data.file = d;
    }
    crate::limits::check_data_file(&settings.path, "data.file", &settings.data.file)?;
    let dir = resolve_dir(out, &settings.name);
    let files: Vec<String> = PLOTS
        .iter()
        .flat_map(|p| [format!("{p}.svg"), format!("{p}.png")])
        .collect();
    let mut names: Vec<&str> = vec!["diagnosis.json", "report.md"];
    names.extend(files.iter().map(String::as_str));
    let periodic = settings.params.forcing_amplitude.abs() > 0.0;
    if periodic {
        names.extend([
            "htf_data.svg",
            "htf_data.png",
            "htf_difference.svg",
            "htf_difference.png",
        ]);
    }
    let mut outdir = open(&dir, force, &names)?;

    let started = Instant::now();
    let record = read_series(&settings)?;
    check_time_scale(&settings, &record)?;
    let nominal = nominal_model(&settings)?;
    let opts = options(&settings, record.len())?;
    crate::progress::line(&format!(
        "diagnosing {} ({} samples at {:.6} Hz) against the {} model, {} candidates",
        settings.data.file.display(),
        record.len(),
        1.0 / record.dt(),
        match settings.damper {
            htfid_model::DamperLaw::Switching => "switching hopper",
            htfid_model::DamperLaw::AlwaysOn => "spring-mass-damper",
        },
        opts.candidates.len()
    ));
    // The library reports the nominal fit and then each candidate as it finishes: a counted
    // stage of 1 + candidates steps.
    let counter = Mutex::new(crate::progress::Counter::new(
        "diagnosis",
        1 + opts.candidates.len() as u64,
    ));
    let progress = |msg: &str| {
        let counter = counter.lock().unwrap_or_else(|e| e.into_inner());
        counter.step(msg, !msg.starts_with("fitting"));
    };
    let report =
        diagnose_with_progress(&record, &nominal, &opts, &progress).with_context(|| {
            format!(
                "{}: diagnosis of data.file = \"{}\" against [model] failed",
                settings.path.display(),
                settings.data.file.display()
            )
        })?;
    drop(counter);

    let tests = test_scores(&settings, &record, &report, &opts)?;
    let mut json = serde_json::to_value(&report.diagnosis)?;
    json["data"] = json!({
        "file": settings.data.file.display().to_string(),
        "samples": record.len(),
        "sample_rate": 1.0 / record.dt(),
        "fit_ranges": ranges_json(&report.fit_ranges),
        "validation_ranges": ranges_json(&report.validation_ranges),
        "units": settings.data.format.units_json(),
    });
    json["noise_floor"] = json!(report.noise_floor);
    if let Some(i) = report.input_noise {
        json["input_noise"] = serde_json::to_value(i)?;
    }
    json["burn_in_s"] = json!(report.burn_in_s);
    // The settings the decision used, defaults included (the ranges are under `data`).
    let mut used = serde_json::to_value(&opts)?;
    if let Some(o) = used.as_object_mut() {
        o.remove("fit");
        o.remove("validation");
    }
    json["options"] = used;
    json["nominal_fit"] = serde_json::to_value(report.nominal_fit_score)?;
    json["nominal_model"] = serde_json::to_value(report.nominal_model)?;
    json["extended_model"] = serde_json::to_value(report.extended_model)?;
    if !tests.is_empty() {
        json["test"] = Value::Array(tests.clone());
    }
    let check = validate(&settings, &record, &report);
    json["validation"] = crate::validation::json(&check, &validation_key(&report));
    let ev = evidence::compute(&settings, &record, &report, opts.interpolation)?;
    let (bins, waterfall) = evidence::json(&ev, &settings);
    json["residual_bins"] = bins;
    json["error_waterfall"] = waterfall;
    let mut figures = draw(&mut outdir, &settings, &record, &report)?;
    draw_validation(&mut outdir, &settings, &record, &report, &check)?;
    evidence::draw_bins(&mut outdir, &settings, &report, &ev)?;
    evidence::draw_waterfall(&mut outdir, &settings, &report, &ev)?;
    let mut htf_diffs = Vec::new();
    if periodic {
        figures.htf = match htf_figure(&mut outdir, &settings, &record, &report) {
            Ok(diffs) => {
                htf_diffs = diffs;
                Some(String::new())
            }
            Err(e) => Some(format!("{e:#}")),
        };
        json["htf_difference"] = evidence::htf_json(&htf_diffs);
    }
    json["elapsed_s"] = json!(started.elapsed().as_secs_f64());
    outdir.write_text("diagnosis.json", &json_text(&json))?;
    let mut text = report_md(
        &settings, &record, &report, &tests, &figures, &ev, &htf_diffs,
    );
    text.push_str(&crate::validation::report(
        "## 5. Validation",
        &[&check],
        &format!("{} model", ext_label(&report)),
        &format!("input `{}`", settings.data.input),
    ));
    if report.input_noise.is_some() {
        text.push('\n');
        text.push_str(&crate::validation::noisy_input_note(&format!(
            "`{}`",
            settings.data.input
        )));
    }
    outdir.write_text("report.md", &text)?;
    let written = outdir.commit()?;
    crate::results::diagnose(&json, htf_unit(&settings).is_some(), &dir, &written);
    Ok(())
}

/// Units of the record: the hopper's SI units (m, N) when its columns are the hopper's own
/// position `x` and force `f`; otherwise the columns' names, whose units the config does not
/// state.
fn output_label(s: &DiagnoseSettings) -> String {
    if let Some(unit) = s.data.format.unit(&s.data.output) {
        format!("{} ({unit})", s.data.output)
    } else if s.data.output == "x" {
        "position x (m)".into()
    } else {
        format!("{} (data units)", s.data.output)
    }
}

fn residual_label(s: &DiagnoseSettings) -> String {
    if let Some(unit) = s.data.format.unit(&s.data.output) {
        format!("residual of {} ({unit})", s.data.output)
    } else if s.data.output == "x" {
        "residual (m)".into()
    } else {
        format!("residual of {} (data units)", s.data.output)
    }
}

fn htf_unit(s: &DiagnoseSettings) -> Option<&'static str> {
    (s.data.output == "x" && s.data.input == "f").then_some("m/N")
}

/// The extended model's key in `validation.fit_percent` (`docs/outputs.md`): by the cause.
fn validation_key(report: &DiagnosisReport) -> String {
    format!("extended ({})", report.diagnosis.cause)
}

/// The extended model in figures: by the effects it adds.
pub(crate) fn ext_label(report: &DiagnosisReport) -> String {
    let added = added_effects(&report.diagnosis);
    if added.is_empty() {
        "extended (nothing added)".to_string()
    } else {
        format!("extended ({})", added.join(" + "))
    }
}

/// The effects the extended model adds to the nominal one, strongest first (a refit of the
/// configured parameters is no added effect).
fn added_effects(d: &htfid_diagnose::Diagnosis) -> Vec<&str> {
    d.causes
        .iter()
        .map(|c| c.effect.as_str())
        .filter(|e| *e != "parameter_error")
        .collect()
}

/// Held-out samples after each range's burn-in, in order.
fn held_out(record: &TimeSeries, report: &DiagnosisReport) -> Vec<usize> {
    let burn = (report.burn_in_s / record.dt()).ceil() as usize;
    report
        .validation_ranges
        .iter()
        .flat_map(|r| (r.start + burn).min(r.end)..r.end)
        .filter(|&i| report.nominal_output[i].is_finite() && report.extended_output[i].is_finite())
        .collect()
}

/// Fit percent of both models and the residual analysis of the extended model against the
/// applied force, on the held-out samples (ranges joined end to end).
fn validate(
    s: &DiagnoseSettings,
    record: &TimeSeries,
    report: &DiagnosisReport,
) -> crate::validation::OutputValidation {
    let idx = held_out(record, report);
    let pick = |v: &[f64]| -> Vec<f64> { idx.iter().map(|&i| v[i]).collect() };
    let (x, f) = (pick(record.output()), pick(record.input()));
    let (nom, ext) = (pick(&report.nominal_output), pick(&report.extended_output));
    crate::validation::validate(
        &s.data.output,
        &x,
        &f,
        &[
            crate::validation::Simulated {
                label: "nominal".into(),
                role: Role::Nominal,
                style: Style::Dashed,
                y: &nom,
            },
            crate::validation::Simulated {
                label: ext_label(report),
                role: Role::Extended,
                style: Style::Line,
                y: &ext,
            },
        ],
        0..x.len(),
    )
}

/// `compare.png` (a few forcing periods at the end of the last held-out range) and `resid.png`.
fn draw_validation(
    out: &mut OutputDir,
    s: &DiagnoseSettings,
    record: &TimeSeries,
    report: &DiagnosisReport,
    check: &crate::validation::OutputValidation,
) -> Result<()> {
    let burn = (report.burn_in_s / record.dt()).ceil() as usize;
    let last = report
        .validation_ranges
        .last()
        .cloned()
        .unwrap_or(0..record.len());
    let period = (s.params.forcing_amplitude.abs() > 0.0).then_some(s.params.period);
    let win = crate::validation::window(
        (last.start + burn).min(last.end)..last.end,
        record.dt(),
        period,
    );
    let ext = ext_label(report);
    let models = [
        crate::validation::Simulated {
            label: "nominal".into(),
            role: Role::Nominal,
            style: Style::Dashed,
            y: &report.nominal_output,
        },
        crate::validation::Simulated {
            label: ext.clone(),
            role: Role::Extended,
            style: Style::Line,
            y: &report.extended_output,
        },
    ];
    let compare = crate::validation::compare_panel(
        &format!(
            "{}: measured and simulated (held-out data; fit over all of it)",
            s.data.output
        ),
        &output_label(s),
        record.time(),
        record.output(),
        &models,
        &check.fits,
        win.clone(),
    );
    let tw = record.time()[win.clone()].to_vec();
    let residual =
        |sim: &[f64]| -> Vec<f64> { win.clone().map(|i| record.output()[i] - sim[i]).collect() };
    let mut res = Panel::new(
        "residual, measured minus simulated",
        htfid_plot::TIME_LABEL,
        residual_label(s),
    );
    res.series = vec![
        Series::new(
            "nominal",
            tw.clone(),
            residual(&report.nominal_output),
            Style::Dashed,
        )
        .with_role(Role::Nominal),
        Series::new(ext, tw, residual(&report.extended_output), Style::Line)
            .with_role(Role::Extended),
    ];
    let fig = stacked_figure(
        format!("{}: measured against simulated", s.name),
        vec![compare, res],
    );
    plots::write(out, "compare", &fig)?;
    if let Some(fig) = crate::validation::resid_figure(
        &format!(
            "{}: residual analysis of the {} model (held-out data)",
            s.name,
            ext_label(report)
        ),
        &[check],
        &format!("input {}", s.data.input),
        record.dt(),
    ) {
        plots::write(out, "resid", &fig)?;
    }
    Ok(())
}

fn read_series(settings: &DiagnoseSettings) -> Result<TimeSeries> {
    let d = &settings.data;
    let columns = Columns {
        input: &d.input,
        output: &d.output,
        time: d.time.as_deref(),
        sample_rate: d.sample_rate,
        time_tolerance: d.time_tolerance,
        format: &d.format,
    };
    read_record(&settings.path, &d.file, columns)
}

fn nominal_model(s: &DiagnoseSettings) -> Result<NominalModel> {
    let free = s
        .free
        .iter()
        .map(|f| match f.as_str() {
            "m" => NominalParam::M,
            "k" => NominalParam::K,
            "c" => NominalParam::C,
            "x0" => NominalParam::X0,
            _ => NominalParam::InputOffset,
        })
        .collect();
    let effects = Effects {
        input_offset: s.input_offset,
        ..Effects::default()
    };
    NominalModel::new(s.params, s.damper, effects, free)
        .with_context(|| format!("{}: [model]", s.path.display()))
}

fn options(s: &DiagnoseSettings, n: usize) -> Result<DiagnoseOptions> {
    let check = |ranges: &[Range<usize>], key: &str| -> Result<()> {
        if let Some(r) = ranges.iter().find(|r| r.end > n) {
            anyhow::bail!(
                "{}: data.{key}: range [{}, {}) runs past the {n} samples of the data",
                s.path.display(),
                r.start,
                r.end
            );
        }
        Ok(())
    };
    check(&s.data.fit, "fit")?;
    check(&s.data.validation, "validation")?;
    check(&s.data.test, "test")?;
    let mut opts = DiagnoseOptions {
        fit: s.data.fit.clone(),
        validation: s.data.validation.clone(),
        burn_in_s: s.burn_in,
        ..DiagnoseOptions::default()
    };
    if let Some(v) = s.fit_initial_state {
        opts.fit_initial_state = v;
    }
    if let Some(c) = &s.candidates {
        opts.candidates = c
            .iter()
            .map(|name| name.parse::<Effect>().map_err(|e| anyhow::anyhow!("{e}")))
            .collect::<Result<_>>()?;
    }
    if let Some(v) = s.significance_sigma {
        opts.significance_sigma = v;
    }
    if let Some(v) = s.min_gain {
        opts.min_gain = v;
    }
    let t = &s.thresholds;
    if let Some(v) = t.alpha {
        opts.alpha = v;
    }
    if let Some(v) = t.max_effects {
        opts.max_effects = v;
    }
    if let Some(v) = t.bic_margin {
        opts.bic_margin = v;
    }
    if let Some(v) = t.unexplained_ratio {
        opts.unexplained_ratio = v;
    }
    if let Some(v) = t.min_explained {
        opts.min_explained = v;
    }
    if let Some(v) = t.fit_tolerance {
        opts.fit_tolerance = v;
    }
    if let Some(v) = t.input_noise_share {
        opts.input_noise_share = v;
    }
    if let Some(v) = t.input_noise_flatness {
        opts.input_noise_flatness = v;
    }
    if let Some(v) = t.noise_band {
        opts.noise_band = v;
    }
    if let Some(v) = t.resolution {
        opts.resolution = v;
    }
    if let Some(v) = t.max_delay_periods {
        opts.max_delay_periods = v;
    }
    if let Some(v) = t.max_iterations {
        opts.max_iterations = v;
    }
    Ok(opts)
}

fn ranges_json(r: &[Range<usize>]) -> Value {
    Value::Array(r.iter().map(|r| json!([r.start, r.end])).collect())
}

/// Scores of the nominal and extended models on the config's extra test ranges.
fn test_scores(
    s: &DiagnoseSettings,
    record: &TimeSeries,
    report: &DiagnosisReport,
    opts: &DiagnoseOptions,
) -> Result<Vec<Value>> {
    let mut out = Vec::new();
    for r in &s.data.test {
        let score = |model| {
            score_on_record(
                record,
                model,
                r.clone(),
                report.burn_in_s,
                opts.interpolation,
                opts.sim,
            )
        };
        let nominal = score(&report.nominal_model)?;
        let extended = score(&report.extended_model)?;
        out.push(json!({
            "range": [r.start, r.end],
            "nominal": nominal,
            "extended": extended,
            "gain": 1.0 - extended.rmse / nominal.rmse,
        }));
    }
    Ok(out)
}

/// Residuals of both models over the held-out ranges, and where they are.
fn residuals(record: &TimeSeries, report: &DiagnosisReport) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (mut t, mut r0, mut r1) = (Vec::new(), Vec::new(), Vec::new());
    let burn = (report.burn_in_s / record.dt()).ceil() as usize;
    for r in &report.validation_ranges {
        for i in (r.start + burn).min(r.end)..r.end {
            let (a, b) = (report.nominal_output[i], report.extended_output[i]);
            if a.is_finite() && b.is_finite() {
                t.push(record.time()[i]);
                r0.push(record.output()[i] - a);
                r1.push(record.output()[i] - b);
            }
        }
    }
    (t, r0, r1)
}

struct Figures {
    orbit: bool,
    /// `Some("")` when the HTF figure was drawn, `Some(reason)` when it could not be.
    htf: Option<String>,
}

/// The data's HTFs against the exact theory of the nominal and the extended model
/// (`htfid_diagnose::htf_comparison`), drawn: `htf_data` and `htf_difference`.
fn htf_figure(
    out: &mut OutputDir,
    s: &DiagnoseSettings,
    record: &TimeSeries,
    report: &DiagnosisReport,
) -> Result<Vec<HarmonicDifference>> {
    use htfid_plot::Style;
    let omegas = crate::settings::log_grid(HTF_BAND.0, HTF_BAND.1, 400);
    let spec = HtfComparisonSpec {
        forcing_amplitude: s.params.forcing_amplitude,
        period: s.params.period,
        harmonics: HTF_HARMONICS.to_vec(),
        band: HTF_BAND,
        alpha: 1.0,
        theory_omegas: omegas.clone(),
    };
    let cmp = htf_comparison(record, &report.nominal_model, &report.extended_model, &spec)?;
    let ext_label = format!("{}, theory", ext_label(report));
    let measured: Vec<Vec<Complex64>> = cmp
        .differences
        .iter()
        .map(|d| {
            cmp.estimate
                .rows()
                .filter(|r| r.n == d.n)
                .map(|r| r.value)
                .collect()
        })
        .collect();
    let per_harmonic: Vec<(i32, Vec<plots::Curve<'_>>)> = cmp
        .differences
        .iter()
        .zip(&measured)
        .zip(cmp.nominal_theory.iter().zip(&cmp.extended_theory))
        .map(|((d, values), (g0, g1))| {
            (
                d.n,
                vec![
                    plots::Curve {
                        label: "measured (Siddiqi estimate)",
                        omega: &d.omega,
                        values,
                        style: Style::Line,
                        stderr: Some(&d.stderr),
                    },
                    plots::Curve {
                        label: "nominal, theory",
                        omega: &omegas,
                        values: g0,
                        style: Style::Line,
                        stderr: None,
                    },
                    plots::Curve {
                        label: &ext_label,
                        omega: &omegas,
                        values: g1,
                        style: Style::Dashed,
                        stderr: None,
                    },
                ],
            )
        })
        .collect();
    let fig = plots::with_htf_unit(
        plots::harmonics(
            &format!("{}: HTFs of the data against the models", s.name),
            &per_harmonic,
        ),
        htf_unit(s),
    );
    plots::write(out, "htf_data", &fig)?;
    evidence::draw_htf_difference(out, s, report, &cmp.differences, htf_unit(s))?;
    Ok(cmp.differences)
}

fn draw(
    out: &mut OutputDir,
    s: &DiagnoseSettings,
    record: &TimeSeries,
    report: &DiagnosisReport,
) -> Result<Figures> {
    let (t, r0, r1) = residuals(record, report);
    let ext_label = ext_label(report);
    let same = report.extended_model == report.nominal_model;
    // The whole held-out record as an RMS per block (a full-rate trace is a solid band), then a
    // window of a few periods that a person can read.
    let period = if s.params.forcing_amplitude.abs() > 0.0 && s.params.period > 0.0 {
        s.params.period
    } else {
        let p = &report.nominal_model.params;
        10.0 * 2.0 * std::f64::consts::PI / (p.k / p.m).sqrt()
    };
    let (tb, q0) = evidence::rms_per_block(&t, &r0, period);
    let (_, q1) = evidence::rms_per_block(&t, &r1, period);
    let block_words = if s.params.forcing_amplitude.abs() > 0.0 {
        format!("forcing period ({} s)", htfid_number::sig(period, 3))
    } else {
        format!(
            "{} s (ten {})",
            htfid_number::sig(period, 3),
            super::diagnose_evidence::natural_periods(s.params.k)
        )
    };
    let mut top = Panel::new(
        format!("RMS of the residual per {block_words}, all held-out data"),
        htfid_plot::TIME_LABEL,
        residual_label(s).replace("residual", "RMS residual"),
    );
    let top_max = q0
        .iter()
        .chain(&q1)
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    if top_max > 0.0 {
        top.y_range = Some((0.0, 1.1 * top_max));
    }
    top.series = vec![Series::new("nominal", tb.clone(), q0, Style::Line).with_role(Role::Nominal)];
    if !same {
        top.series
            .push(Series::new(ext_label.clone(), tb, q1, Style::Line).with_role(Role::Extended));
    }
    let win = evidence::time_window(s, record, report);
    let tw = record.time()[win.clone()].to_vec();
    let res =
        |sim: &[f64]| -> Vec<f64> { win.clone().map(|i| record.output()[i] - sim[i]).collect() };
    let mut bottom = Panel::new(
        format!(
            "measured - simulated over the first {} of held-out data after the burn-in",
            evidence::window_words(s)
        ),
        htfid_plot::TIME_LABEL,
        residual_label(s),
    );
    bottom.series = vec![Series::new(
        "nominal",
        tw.clone(),
        res(&report.nominal_output),
        Style::Line,
    )
    .with_role(Role::Nominal)];
    if !same {
        bottom.series.push(
            Series::new(
                ext_label.clone(),
                tw,
                res(&report.extended_output),
                Style::Line,
            )
            .with_role(Role::Extended),
        );
    }
    let fig = stacked_figure(
        format!("{}: what the nominal model gets wrong, in time", s.name),
        vec![top, bottom],
    );
    plots::write(out, "residual_time", &fig)?;

    let (w0, a0) = amplitude_spectrum(&r0, record.dt());
    let (w1, a1) = amplitude_spectrum(&r1, record.dt());
    let mut panel = spectrum_panel(
        "residual spectrum (held-out data)",
        &w0,
        [("nominal", a0)],
        SpectrumScale::LogLog,
    );
    if !w1.is_empty() {
        panel
            .series
            .push(Series::new(ext_label.clone(), w1, a1, Style::Line));
    }
    let fig = stacked_figure(format!("{}: residual spectrum", s.name), vec![panel]);
    plots::write(out, "residual_spectrum", &fig)?;

    // Period-averaged orbit: measured against both models, folded over the forcing period
    // when one is known, else the measured against simulated position over a short window.
    let orbit = s.params.forcing_amplitude.abs() > 0.0;
    let fig = if orbit {
        let period = s.params.period;
        // The held-out samples where both models were simulated, folded over the period.
        let held: Vec<usize> = report
            .validation_ranges
            .iter()
            .flat_map(|r| r.clone())
            .filter(|&i| {
                report.nominal_output[i].is_finite() && report.extended_output[i].is_finite()
            })
            .collect();
        let t: Vec<f64> = held.iter().map(|&i| record.time()[i]).collect();
        let fold = |y: &[f64]| -> Vec<htfid_diagnose::Bin> {
            let v: Vec<f64> = held.iter().map(|&i| y[i]).collect();
            evidence::fold_sampled(&t, &v, period, record.dt())
        };
        let folded = [
            fold(record.output()),
            fold(&report.nominal_output),
            fold(&report.extended_output),
        ];
        let phase: Vec<f64> = folded[0].iter().map(|b| b.centre).collect();
        // Each model's mean on the measured one's bins.
        let col = |j: usize| -> Vec<f64> { evidence::means_on(&folded[0], &folded[j]) };
        let (measured, nom, ext) = (col(0), col(1), col(2));
        let mut p = Panel::new(
            "period-averaged orbit (held-out data)",
            "phase (s)",
            output_label(s),
        );
        p.series = vec![
            Series::new("measured", phase.clone(), measured.clone(), Style::Markers),
            Series::new("nominal", phase.clone(), nom.clone(), Style::Line),
        ];
        let diff =
            |m: &[f64]| -> Vec<f64> { m.iter().zip(&measured).map(|(a, b)| a - b).collect() };
        let mut q = Panel::new(
            "model - measured, period-averaged",
            "phase (s)",
            residual_label(s).replace("residual", "difference"),
        );
        q.series = vec![
            Series::new("nominal", phase.clone(), diff(&nom), Style::Line),
            Series::new(ext_label.clone(), phase, diff(&ext), Style::Dashed),
        ];
        grid_figure(format!("{}: the orbit", s.name), vec![p, q], 2)
    } else {
        let r = report
            .validation_ranges
            .first()
            .cloned()
            .unwrap_or(0..record.len());
        let burn = (report.burn_in_s / record.dt()).ceil() as usize;
        let a = (r.start + burn).min(r.end);
        let b = (a + (1.0 / record.dt()) as usize).min(r.end);
        let tt = record.time()[a..b].to_vec();
        let panel = time_panel(
            "one second of held-out data",
            &output_label(s),
            &tt,
            [
                ("measured", record.output()[a..b].to_vec()),
                ("nominal", report.nominal_output[a..b].to_vec()),
                (ext_label.as_str(), report.extended_output[a..b].to_vec()),
            ],
        );
        stacked_figure(
            format!("{}: measured against simulated", s.name),
            vec![panel],
        )
    };
    plots::write(out, "orbit", &fig)?;
    Ok(Figures { orbit, htf: None })
}

/// A parameter as `value ± stderr unit`, to the precision its standard error allows; the
/// hopper's units only when the record is the hopper's own `x` and `f`.
fn param_text(s: &DiagnoseSettings, name: &str, v: f64, se: f64) -> String {
    use htfid_number::{sig as num, Quantity};
    // In a diagnosis `g` is the sensor's gain (gravity is never refitted) and `b` its offset.
    let unit = match name {
        _ if htf_unit(s).is_none() => None,
        "g" => None,
        "b" => Some("m"),
        "tau_s" => Some("s"),
        "input_offset" => Some("N"),
        _ => crate::results::hopper_unit(name),
    };
    if se.is_finite() {
        format!("`{name}` = {}", Quantity::new(v).stderr(se).unit(unit))
    } else {
        let unit = unit.map_or(String::new(), |u| format!(" {u}"));
        format!("`{name}` = {}{unit} (no standard error)", num(v, 4))
    }
}

fn fmt_params(
    s: &DiagnoseSettings,
    p: &std::collections::BTreeMap<String, f64>,
    se: &std::collections::BTreeMap<String, f64>,
) -> String {
    p.iter()
        .map(|(k, v)| param_text(s, k, *v, se.get(k).copied().unwrap_or(f64::NAN)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A table cell: `v` with 4 significant digits, or a dash when it is not a number.
fn cell(v: f64) -> String {
    if v.is_finite() {
        htfid_number::sig(v, 4)
    } else {
        "–".to_string()
    }
}

/// A fraction as a percentage cell.
fn pct_cell(v: f64) -> String {
    if v.is_finite() {
        format!("{} %", htfid_number::sig(100.0 * v, 4))
    } else {
        "–".to_string()
    }
}

/// The verdict of a diagnosis with several causes: the cause first (what the nominal model
/// lacks most), the other effects beside it, a refit of the configured parameters apart, then
/// every share of the explained error.
fn several_causes(d: &htfid_diagnose::Diagnosis, cause: &str) -> String {
    let quoted = |names: Vec<&str>| {
        names
            .iter()
            .map(|n| format!("`{n}`"))
            .collect::<Vec<_>>()
            .join(" and ")
    };
    let beside: Vec<&str> = d
        .causes
        .iter()
        .map(|c| c.effect.as_str())
        .filter(|&e| e != cause && e != "parameter_error")
        .collect();
    let mut v = format!("**Cause: `{cause}`**");
    if !beside.is_empty() {
        v += &format!(", with {}", quoted(beside));
    }
    if cause != "parameter_error" && d.causes.iter().any(|c| c.effect == "parameter_error") {
        v += "; the configured parameters are off as well (`parameter_error`)";
    }
    v += &format!(
        ". Together they lower the held-out simulation error by {} % against the refitted \
         nominal model. Shares of the error they explain, from the configured model to the \
         final one: {}; each step is in `error_waterfall.png`.",
        htfid_number::sig(100.0 * d.gain, 4),
        causes_text(d)
    );
    let has = |e: &str| d.causes.iter().any(|c| c.effect == e);
    if has("cubic_stiffness") && has("sensor_offset_gain") {
        v += " A cubic spring beside a sensor offset is the same model as an asymmetric spring \
              (a quadratic term beside the cubic one) with the sensor's zero right: the record \
              cannot tell them apart, and a reading of the sensor at rest separates them (see \
              the evidence).";
    }
    if let Some(w) = &d.held_out_on_windows {
        v += &format!(
            " A switching threshold among the speed's extremes decides, period by period, \
             whether the damper switches, and that decides the motion after it: the whole \
             held-out simulation parts from the data however right the threshold, so the \
             effects were judged on held-out windows of two natural periods, each simulated \
             from the data's smoothed state. There they lower the error by {} % (RMSE {} \
             against the refitted nominal's {}).",
            htfid_number::sig(100.0 * w.gain, 4),
            htfid_number::sig(w.extended_rmse, 4),
            htfid_number::sig(w.nominal_rmse, 4)
        );
    }
    v
}

/// The causes with their shares, strongest first.
fn causes_text(d: &htfid_diagnose::Diagnosis) -> String {
    d.causes
        .iter()
        .map(|c| {
            format!(
                "`{}` {} %",
                c.effect,
                htfid_number::sig(100.0 * c.gain_share, 3)
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// A held-out residual at least this multiple of the noise floor is more than noise: three
/// quarters of its mean square or more are not.
const LEFT_OVER_RATIO: f64 = 2.0;

/// Beside a named cause, a sentence on a residual still well above the noise floor though
/// below `unexplained_ratio` (where it would count as clear structure): a smaller effect may be
/// missing, and the headline says so.
fn left_over(s: &DiagnoseSettings, report: &DiagnosisReport) -> Option<String> {
    let d = &report.diagnosis;
    if matches!(
        d.cause.as_str(),
        "none" | "unexplained" | "ambiguous" | "model_mismatch"
    ) {
        return None;
    }
    let floor = report.noise_floor.filter(|f| f.is_finite() && *f > 0.0)?;
    let ratio = d.extended.rmse / floor;
    (ratio >= LEFT_OVER_RATIO).then(|| {
        let limit = s
            .thresholds
            .unexplained_ratio
            .unwrap_or(DiagnoseOptions::default().unexplained_ratio);
        format!(
            " The extended model's held-out residual is still {} times the noise floor: below \
             `unexplained_ratio` ({limit}), where it would count as clear structure, but more \
             than noise ({} % of its mean square or more is not), so a smaller effect may be \
             missing (the whiteness test below says whether the residual is still correlated).",
            htfid_number::sig(ratio, 3),
            htfid_number::sig(100.0 * (1.0 - 1.0 / (ratio * ratio)), 2)
        )
    })
}

#[allow(clippy::too_many_arguments)] // reason: the report reads every result of the run
fn report_md(
    s: &DiagnoseSettings,
    record: &TimeSeries,
    report: &DiagnosisReport,
    tests: &[Value],
    figures: &Figures,
    ev: &evidence::Evidence,
    htf: &[HarmonicDifference],
) -> String {
    use htfid_number::sig as num;
    let d = &report.diagnosis;
    let unit = evidence::output_unit(s).unwrap_or_else(|| "output units".into());
    let mut m = String::new();
    let _ = writeln!(m, "# Diagnosis: {}\n", s.name);
    let verdict = match d.cause.as_str() {
        "none" => "**No effect found**: the nominal model explains the data down to the noise.".to_string(),
        "unexplained" if d.causes.is_empty() => "**Unexplained**: the nominal model leaves clear structure in the residual that no candidate effect in the library explains with confidence.".to_string(),
        "unexplained" => format!("**Unexplained**: the library effects found ({}: their shares of the error they explain) lower the held-out simulation error by {} %, but clear structure remains that they do not explain.", causes_text(d), num(100.0 * d.gain, 4)),
        "ambiguous" => format!("**Ambiguous**: {} explain the data equally well; the data cannot tell them apart (see the evidence for the experiment that would).", d.alternatives.iter().map(|a| format!("`{a}`")).collect::<Vec<_>>().join(" and ")),
        "model_mismatch" => format!("**Model mismatch**: the nominal model does not describe these data at all, so no effect is named. Likely reasons: {}", d.mismatch.join("; ")),
        c if d.causes.len() > 1 => several_causes(d, c),
        c => format!("**Cause: `{c}`.** The extended model lowers the held-out simulation error by {} %.", num(100.0 * d.gain, 4)),
    };
    let _ = writeln!(m, "{verdict}{}\n", left_over(s, report).unwrap_or_default());
    let _ = writeln!(
        m,
        "{}\n",
        evidence::summary(s, report, ev, htf, &|k, v, e| param_text(s, k, v, e))
    );
    if let Some(found) = &d.discovered {
        // A hint beside the verdict, never a cause: the library did not hold this term.
        let _ = writeln!(
            m,
            "**Outside the library**, a term search on the residual of {} proposes the extra force `{}` N (`x_eq` = {} m{}): added to it, it lowers the held-out RMSE from {} to {} {unit} (gain {} %). Coefficients with standard errors: {}.\n",
            if found.read_from == "nominal" {
                "the refitted nominal model (beside the selected effects, which partly mimic it, no formula held up)"
            } else {
                "the final model"
            },
            found.formula,
            num(found.x_eq, 4),
            if found.period > 0.0 { format!(", `T` = {} s", num(found.period, 4)) } else { String::new() },
            num(found.rmse_before, 4),
            num(found.rmse_after, 4),
            num(100.0 * found.gain, 4),
            found
                .terms
                .iter()
                .map(|t| format!("`{}` {} ± {}", t.term, num(t.coefficient, 4), num(t.stderr, 3)))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    let _ = writeln!(
        m,
        "Data: `{}`, {} samples at {} Hz. Fitted on samples {:?}, judged on held-out samples {:?} (the first {} s of each range are a burn-in, simulated but not scored).\n",
        evidence::shown_path(&s.data.file),
        record.len(),
        num(1.0 / record.dt(), 6),
        report.fit_ranges,
        report.validation_ranges,
        num(report.burn_in_s, 3)
    );
    let _ = writeln!(m, "## 1. What the nominal model gets wrong\n");
    let _ = writeln!(
        m,
        "The nominal model ({}) with {} refitted: held-out NRMSE **{}** (RMSE {} {unit}); the noise floor of the residual is {}{}.\n",
        match s.damper {
            htfid_model::DamperLaw::Switching => "the switching hopper",
            htfid_model::DamperLaw::AlwaysOn => "a linear spring-mass-damper",
        },
        s.free.join(", "),
        pct_cell(d.nominal.nrmse),
        cell(d.nominal.rmse),
        report
            .noise_floor
            .map_or("not estimable (ranges too short)".into(), |v| format!("{} {unit}", num(v, 4))),
        report.input_noise.map_or(String::new(), |i| format!(
            ", of which {} {unit} is the model's response to the noise on the measured {inp} (its spectrum in the same band is that of white noise of {}{in_unit} RMS, and the simulation is driven by the measured {inp})",
            num(i.propagated, 3),
            num(i.sigma, 3),
            inp = s.data.input,
            in_unit = s.data.format.unit(&s.data.input).map_or(String::new(), |u| format!(" {u}")),
        ))
    );
    let _ = writeln!(
        m,
        "Where the residual sits: the residual acceleration (the acceleration of the measured {out}, from five-point differences, minus the model's acceleration at the measured {out} and velocity driven by the measured {inp}, smoothed as the screening's Savitzky-Golay filter smooths an acceleration) on the held-out data, averaged in bins of {phase}. Each band is ±2 standard errors of the bin mean, with blocks of {block} taken as independent: a mean whose band holds zero is noise. A missing force shows as a function of the state: a cubic spring against position, friction as a step at zero velocity, a damping the model lacks on one side of zero velocity as a change of slope there (the refitted parameters spread part of any missing force over both sides).\n",
        out = s.data.output,
        inp = s.data.input,
        phase = if ev.nominal.by_phase.is_empty() { "position and velocity (no forcing period is configured, so no phase)" } else { "position, velocity and the forcing phase" },
        block = ev.block_words,
    );
    if ev.nominal.by_position.is_empty() && ev.nominal.by_velocity.is_empty() {
        let _ = writeln!(
            m,
            "The held-out data are too short to fill a bin: no `residual_bins.png`.\n"
        );
    } else {
        let _ = writeln!(m, "![residual acceleration in bins](residual_bins.png)\n");
    }
    let _ = writeln!(
        m,
        "The residual in time: its RMS per block over all held-out data, and the residual itself over the first {} after the burn-in:\n",
        evidence::window_words(s)
    );
    let _ = writeln!(m, "![residual in time](residual_time.png)\n");
    let _ = writeln!(m, "![residual spectrum](residual_spectrum.png)\n");
    if figures.orbit {
        let _ = writeln!(
            m,
            "The measured orbit, averaged over the forcing period, against both models:\n"
        );
    } else {
        let _ = writeln!(m, "Measured against simulated position:\n");
    }
    let _ = writeln!(m, "![orbit](orbit.png)\n");
    match &figures.htf {
        Some(reason) if reason.is_empty() => {
            let _ = writeln!(m, "Harmonic transfer functions estimated from the data (Siddiqi's estimator on the excited part of the record, deviations from the measured period-averaged orbit) against the exact theory of both models:\n");
            let _ = writeln!(m, "![HTFs of the data](htf_data.png)\n");
            let _ = writeln!(m, "The same per harmonic as a difference, measured minus each model's theory, over the estimate's noise (shaded up to 2 standard errors): a difference inside the shading is noise.\n");
            let _ = writeln!(m, "| harmonic | frequency bins | outside the noise, nominal | outside the noise, extended |");
            let _ = writeln!(m, "|---|---|---|---|");
            for h in htf {
                let _ = writeln!(
                    m,
                    "| `G_{}` | {} | {} | {} |",
                    h.n,
                    h.omega.len(),
                    pct_cell(h.nominal_outside()),
                    pct_cell(h.extended_outside())
                );
            }
            let _ = writeln!(m, "\n![HTF differences](htf_difference.png)\n");
        }
        Some(reason) => {
            let _ = writeln!(m, "(No HTF figure: {reason}.)\n");
        }
        None => {}
    }
    let _ = writeln!(m, "## 2. The evidence\n");
    for e in &d.evidence {
        let _ = writeln!(m, "- {e}");
    }
    let _ = writeln!(
        m,
        "\nEvery candidate, best first (held-out NRMSE; BIC on the fit data, lower is better; – where the candidate was not fitted):\n"
    );
    let _ = writeln!(
        m,
        "| effect | parameters | held-out NRMSE | BIC | significant | note |"
    );
    let _ = writeln!(m, "|---|---|---|---|---|---|");
    for c in &d.candidates {
        let params = fmt_params(s, &c.parameters, &c.stderr);
        let _ = writeln!(
            m,
            "| `{}` | {} | {} | {} | {} | {} |",
            c.effect,
            if params.is_empty() {
                "–".to_string()
            } else {
                params
            },
            pct_cell(c.nrmse_validation),
            // BIC differences of a unit matter, its size does not: whole numbers.
            if c.bic.is_finite() {
                format!("{:.0}", c.bic).replace('-', "−")
            } else {
                "–".to_string()
            },
            if c.significant { "yes" } else { "no" },
            c.note.replace('|', "/")
        );
    }
    let _ = writeln!(m, "\n## 3. The extended model\n");
    let added = added_effects(d);
    if added.is_empty() {
        let _ = writeln!(
            m,
            "No effect is added; the extended model is the refitted nominal model: {}.\n",
            fmt_params(s, &d.parameters, &d.stderr)
        );
    } else {
        let names: Vec<String> = added.iter().map(|e| format!("`{e}`")).collect();
        let _ = writeln!(
            m,
            "The nominal model plus {}: {}.\n",
            names.join(" and "),
            fmt_params(s, &d.parameters, &d.stderr)
        );
    }
    let _ = writeln!(m, "## 4. The gain\n");
    let _ = writeln!(m, "| model | held-out NRMSE | held-out RMSE ({unit}) |");
    let _ = writeln!(m, "|---|---|---|");
    if d.configured.rmse.is_finite() {
        let _ = writeln!(
            m,
            "| configured | {} | {} |",
            pct_cell(d.configured.nrmse),
            cell(d.configured.rmse)
        );
    }
    let _ = writeln!(
        m,
        "| nominal (refitted) | {} | {} |",
        pct_cell(d.nominal.nrmse),
        cell(d.nominal.rmse)
    );
    let _ = writeln!(
        m,
        "| extended | {} | {} |",
        pct_cell(d.extended.nrmse),
        cell(d.extended.rmse)
    );
    let _ = writeln!(
        m,
        "\nGain `1 - rmse_extended / rmse_nominal` = **{}**.\n",
        pct_cell(d.gain)
    );
    let _ = writeln!(
        m,
        "From the configured model to the final one, step by step (each effect's step is its share of the explained error when there are several):\n"
    );
    let _ = writeln!(m, "![held-out error, step by step](error_waterfall.png)\n");
    if !tests.is_empty() {
        let _ = writeln!(
            m,
            "Further test ranges (simulated from their own start, burn-in excluded):\n"
        );
        let _ = writeln!(
            m,
            "| samples | nominal RMSE ({unit}) | extended RMSE ({unit}) | gain |"
        );
        let _ = writeln!(m, "|---|---|---|---|");
        for t in tests {
            let _ = writeln!(
                m,
                "| {} | {} | {} | {} |",
                t["range"],
                cell(t["nominal"]["rmse"].as_f64().unwrap_or(f64::NAN)),
                cell(t["extended"]["rmse"].as_f64().unwrap_or(f64::NAN)),
                pct_cell(t["gain"].as_f64().unwrap_or(f64::NAN))
            );
        }
        let _ = writeln!(m);
    }
    m
}

/// Refuses a record whose time scale cannot hold the nominal model's dynamics (see
/// [`crate::records::check_time_scale`]).
fn check_time_scale(settings: &DiagnoseSettings, record: &TimeSeries) -> Result<()> {
    let p = &settings.params;
    let wn = p.natural_rate();
    let what = if p.k > 0.0 {
        format!("one natural period of the nominal model (sqrt(k/m) = {wn:.3} rad/s)")
    } else {
        format!("one time constant of the free mass (c/m = {wn:.3} 1/s) times 2 pi")
    };
    crate::records::check_time_scale(
        &settings.path,
        record.dt(),
        record.len(),
        crate::records::TimeScale {
            period: 2.0 * std::f64::consts::PI / wn,
            what: &what,
        },
        crate::records::unit_hint(settings.data.sample_rate),
    )
}
