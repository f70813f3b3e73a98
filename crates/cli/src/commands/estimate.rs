//! `htfid estimate CONFIG [--data FILE]`: HTFs from measured data alone, no model. The period
//! is given or estimated, the orbit is the period average of the record (input and outputs),
//! and Siddiqi's estimator takes the deviations. The science is in `htfid-estimate`
//! (`PeriodicRecord`: the period, the split, the estimator, what the record allows); this file
//! reads, names the config keys in errors and notes, writes.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use htfid_data::TimeSeries;
use htfid_estimate::{
    periodic_value, Alpha, DataEstimate, DataSpec, FromDataError, HtfEstimate, PeriodChoice,
    PeriodicRecord, Signal, MIN_PERIODS,
};
use htfid_plot::Style;
use num_complex::Complex64;
use serde_json::{json, Value};

use crate::commands::run::write_estimate_csv;
use crate::estimate_config::{EstimateSettings, PeriodSetting};
use crate::output::{json_text, open, resolve_dir};
use crate::plots::{self, Curve};
use crate::progress::Stages;
use crate::records::{read_record, Columns};

/// Harmonics added on each side of the estimated set to check that it holds the response.
const OUTER_HARMONICS: i32 = 2;

/// A library error of the estimate from data in the config's words: the key that decides it,
/// what to do.
fn explain(settings: &EstimateSettings, e: FromDataError, hint: &str) -> anyhow::Error {
    let path = settings.path.display();
    let name = |signal: Signal| match signal {
        Signal::Input => "input".to_string(),
        Signal::Output(o) => format!("output {}", settings.outputs[o]),
    };
    match e {
        FromDataError::PeriodNotWhole {
            period,
            dt,
            per_period,
        } => {
            // Six significant digits, without trailing zeros.
            let short = |x: f64| {
                let scale = 10f64.powi(5 - x.abs().log10().floor() as i32);
                (x * scale).round() / scale
            };
            let rate = |m: f64| short(m / period);
            let (below, above) = (
                per_period.floor().max(1.0),
                per_period.floor().max(1.0) + 1.0,
            );
            anyhow::anyhow!(
                "{path}: period.value = {period} s is {per_period:.4} samples of the record's \
                 step {} s, not a whole number: the period average and Siddiqi's estimator need \
                 a whole number of samples per period. Resample the record so that a period \
                 holds one, e.g. at {} Hz ({below} samples per period) or {} Hz ({above}), or \
                 check period.value",
                short(dt),
                rate(below),
                rate(above)
            )
        }
        FromDataError::PeriodNotFound(e) => {
            anyhow::Error::new(e).context("the period could not be estimated from the first output")
        }
        FromDataError::EstimatedPeriodNotWhole { period, per_period } => anyhow::anyhow!(
            "{path}: the estimated period {period:.9} s is {per_period:.4} samples, not a whole \
             number; give period.value (s), or resample the data so that a period holds a \
             whole number of samples"
        ),
        FromDataError::TooFewPeriods { periods, period } => anyhow::anyhow!(
            "{path}: the record after data.start holds {periods} period(s) of {period} s; at \
             least 2 are needed (and {MIN_PERIODS} for a usable estimate)"
        ),
        FromDataError::BeyondNyquist {
            largest,
            needed,
            nyquist,
        } => {
            let (_, hi) = settings.band;
            anyhow::anyhow!(
                "{path}: estimation.omega_max = {hi} with harmonics up to {largest} needs input \
                 up to {needed:.3} rad/s, at or beyond the record's Nyquist frequency \
                 {nyquist:.3e} rad/s (sampled every {:.3e} s): narrow the band \
                 (estimation.omega_min, omega_max) or the harmonics, or {hint}",
                std::f64::consts::PI / nyquist
            )
        }
        FromDataError::PeriodContradicted {
            given,
            own,
            given_share,
            periods,
            drift,
        } => anyhow::anyhow!(
            "{path}: period.value = {given} s, but the first output's own period is {} s: its \
             orbit carries {} of the output's variance there and {} at the given period, and \
             over the {} periods of the record the two periods part by {} periods, so every \
             harmonic would be read at the wrong frequency. Correct period.value, or set it to \
             \"estimate\"",
            htfid_number::sig(own.period, 9),
            htfid_number::percent(own.periodic_share, 3),
            htfid_number::percent(given_share, 3),
            htfid_number::sig(periods, 3),
            htfid_number::sig(drift, 3)
        ),
        FromDataError::Split { signal, source } => {
            anyhow::Error::new(source).context(format!("{}: period average", name(signal)))
        }
        FromDataError::Estimator { output, source } => anyhow::Error::new(source).context(format!(
            "{path}: Siddiqi's estimator on output {} (estimation.alpha = {})",
            settings.outputs[output],
            settings
                .alpha
                .map_or("\"gcv\"".to_string(), |a| a.to_string())
        )),
        other => anyhow::Error::new(other).context(format!("{path}")),
    }
}

fn read(settings: &EstimateSettings, output: &str) -> Result<TimeSeries> {
    let columns = Columns {
        input: &settings.input,
        output,
        time: settings.time.as_deref(),
        sample_rate: settings.sample_rate,
        time_tolerance: settings.time_tolerance,
        format: &settings.format,
    };
    read_record(&settings.path, &settings.file, columns)
}

pub fn run(config: &Path, data: Option<PathBuf>, out: Option<PathBuf>, force: bool) -> Result<()> {
    let settings = EstimateSettings::from_file(config, data)?;
    crate::limits::check_data_file(&settings.path, "data.file", &settings.file)?;
    let outputs = &settings.outputs;
    let suffix = |o: usize| {
        if o == 0 {
            String::new()
        } else {
            format!("_{}", outputs[o])
        }
    };
    let mut names: Vec<String> = vec![
        "summary.json".into(),
        "orbit.csv".into(),
        "report.md".into(),
    ];
    for o in 0..outputs.len() {
        names.push(format!("estimate_siddiqi{}.csv", suffix(o)));
        names.push(format!("estimate_harmonics{}.svg", suffix(o)));
        names.push(format!("estimate_harmonics{}.png", suffix(o)));
    }
    let name_refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let dir = resolve_dir(out, &settings.name);
    let mut outdir = open(&dir, force, &name_refs)?;
    let mut stages = Stages::new();

    let series: Vec<TimeSeries> = stages.run("read data", || {
        outputs
            .iter()
            .map(|o| read(&settings, o))
            .collect::<Result<Vec<_>>>()
    })?;
    let first = &series[0];
    let dt = first.dt();
    let hint = crate::records::unit_hint(settings.sample_rate);
    if let PeriodSetting::Given(t) = settings.period {
        crate::records::check_time_scale(
            &settings.path,
            dt,
            first.len(),
            crate::records::TimeScale {
                period: t,
                what: "the period (period.value)",
            },
            hint,
        )?;
    }
    let i0 = first.time().partition_point(|&t| t < settings.start);
    if first.len() - i0 < 64 {
        bail!(
            "{}: data.start = {} leaves {} samples; at least 64 are needed",
            settings.path.display(),
            settings.start,
            first.len() - i0
        );
    }

    // The period (given, or estimated from the first output and snapped to a whole number of
    // samples: the split and the estimator need N dt = P T exactly), the whole periods read,
    // and the band against the Nyquist frequency (`htfid_estimate::PeriodicRecord`).
    let spec = DataSpec {
        outer_harmonics: OUTER_HARMONICS,
        ..DataSpec::new(
            settings.harmonics.clone(),
            settings.band,
            settings.alpha.map_or(Alpha::Gcv, Alpha::Fixed),
        )
    };
    let choice = match settings.period {
        PeriodSetting::Given(t) => PeriodChoice::Given(t),
        PeriodSetting::Estimate => PeriodChoice::Estimate,
    };
    let plan = stages
        .run("period", || {
            PeriodicRecord::plan(&first.output()[i0..], dt, choice, &spec)
        })
        .map_err(|e| explain(&settings, e, hint))?;
    let (period, dt, n, periods) = (plan.period, plan.dt, plan.samples, plan.periods);
    let t_start = first.time()[i0];
    check_memory(&settings, dt, n)?;
    let ys: Vec<&[f64]> = series.iter().map(|s| &s.output()[i0..]).collect();
    let found = stages
        .run("estimate", || {
            plan.estimate(t_start, &first.input()[i0..], &ys, &spec)
        })
        .map_err(|e| explain(&settings, e, hint))?;
    let estimates: Vec<&HtfEstimate> = found.outputs.iter().map(|o| &o.estimate).collect();
    let notes = notes(&settings, &plan, &found);
    let wp = plan.pumping_frequency();
    let (lo, hi) = settings.band;

    stages.run("write outputs", || -> Result<()> {
        for (o, e) in estimates.iter().enumerate() {
            write_estimate_csv(
                &mut outdir,
                &format!("estimate_siddiqi{}.csv", suffix(o)),
                e,
            )?;
        }
        // One period of the measured orbit (the periodic part), from its harmonics.
        let mut header = vec!["phase".to_string(), settings.input.clone()];
        header.extend(outputs.iter().cloned());
        let header_refs: Vec<&str> = header.iter().map(String::as_str).collect();
        let mut csv = outdir.csv("orbit.csv", &header_refs)?;
        let samples = 200;
        for i in 0..samples {
            let t = period * i as f64 / samples as f64;
            let mut row = vec![t, periodic_value(&found.input_orbit, wp, t)];
            row.extend(
                found
                    .outputs
                    .iter()
                    .map(|o| periodic_value(&o.orbit, wp, t)),
            );
            csv.write_row(&row)?;
        }
        csv.finish()?;
        for (o, e) in estimates.iter().enumerate() {
            let fig = figure(&settings, &outputs[o], e);
            plots::write(
                &mut outdir,
                &format!("estimate_harmonics{}", suffix(o)),
                &fig,
            )?;
        }
        Ok(())
    })?;

    let per_output: Vec<Value> = found
        .outputs
        .iter()
        .zip(outputs)
        .map(|(o, name)| {
            let by_n: serde_json::Map<String, Value> = o
                .summaries
                .iter()
                .map(|h| {
                    (
                        h.n.to_string(),
                        json!({
                            "max_abs_g": h.max_abs_g,
                            "max_abs_g_significant": h.max_abs_g_significant,
                            "median_abs_g_over_stderr": h.median_abs_g_over_stderr,
                            "significant_points": h.significant_points,
                            "points": h.points,
                            "max_bias_over_stderr": h.max_bias_over_stderr,
                        }),
                    )
                })
                .collect();
            let e = &o.estimate;
            json!({"output": name, "alpha": e.alpha(), "alpha_effective": e.alpha_effective(), "harmonics": by_n})
        })
        .collect();
    let estimated = plan.estimated;
    let summary = json!({
        "name": settings.name,
        "config": settings.path.display().to_string(),
        "data": settings.file.display().to_string(),
        "units": settings.format.units_json(),
        "htfid_version": env!("CARGO_PKG_VERSION"),
        "period": {
            "value": period,
            "source": if estimated.is_some() { "estimated" } else { "given" },
            "estimated": estimated.map(|e| e.period),
            "periodic_share": estimated.map(|e| e.periodic_share),
            "pumping_frequency": wp,
        },
        "record": {
            "start": t_start,
            "samples": n,
            "sample_rate": 1.0 / dt,
            "duration": n as f64 * dt,
            "periods": periods,
            "frequency_resolution": plan.resolution(),
            "nyquist": plan.nyquist(),
        },
        "checks": {
            "excited_band": found.excited_band.map(|(a, b)| [a, b]),
            "unexcited": found.unexcited.iter().map(|(n, ranges)| json!({
                "n": n,
                "omega": ranges.iter().map(|&(a, b)| [a, b]).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
            "notes": notes,
            "outer_harmonics": found.outputs.iter().zip(outputs).map(|(o, name)| json!({
                "output": name,
                "harmonics": o.outer.as_deref().unwrap_or_default().iter().map(|h| json!({
                    "n": h.n,
                    "significant_share": h.significant_share,
                    "max_abs_g": h.max_abs,
                })).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
        },
        "estimation": {
            "estimator": "siddiqi",
            "input": settings.input,
            "harmonics": settings.harmonics,
            "band": [lo, hi],
        },
        "estimates": per_output,
        "timings_ms": stages.to_json(),
    });
    outdir.write_text("summary.json", &json_text(&summary))?;
    let plots: Vec<String> = (0..outputs.len())
        .map(|o| format!("estimate_harmonics{}.png", suffix(o)))
        .collect();
    outdir.write_text(
        "report.md",
        &crate::report::estimate(&summary, &settings.path, &settings.file, &plots),
    )?;
    // The notes are part of the results: printed with them on stdout.
    let written = outdir.commit()?;
    crate::results::estimate(&summary, &dir, &written);
    Ok(())
}

/// `|G_n|` of one output with its 95 % confidence region (`|G| +- 1.96 stderr`) shaded and
/// the estimates that are not significant (`|G| < 2 stderr`) faded.
fn figure(settings: &EstimateSettings, output: &str, e: &HtfEstimate) -> htfid_plot::Figure {
    type Series = (Vec<f64>, Vec<Complex64>, Vec<f64>);
    let series: Vec<(i32, Series)> = settings
        .harmonics
        .iter()
        .map(|&k| {
            let rows: Vec<_> = e.rows().filter(|r| r.n == k).collect();
            (
                k,
                (
                    rows.iter().map(|r| r.omega).collect(),
                    rows.iter().map(|r| r.value).collect(),
                    rows.iter().map(|r| r.stderr).collect(),
                ),
            )
        })
        .collect();
    let per: Vec<(i32, Vec<Curve<'_>>)> = series
        .iter()
        .map(|(k, (w, g, se))| {
            (
                *k,
                vec![Curve {
                    label: "estimate (Siddiqi)",
                    omega: w,
                    values: g,
                    style: Style::Line,
                    stderr: Some(se),
                }],
            )
        })
        .collect();
    // |G_n| carries the output's unit per the input's (data.units), when both are given.
    let f = &settings.format;
    let unit = match (f.unit(output), f.unit(&settings.input)) {
        (Some(y), Some(u)) => format!(", dB re 1 {y}/{u}"),
        _ => String::new(),
    };
    plots::harmonics(
        &format!(
            "{}: |G_n| of {output} from data (Siddiqi{unit})",
            settings.name
        ),
        &per,
    )
}

/// Refuses, before any transform, an estimate of `samples` samples `dt` apart that cannot fit
/// in `--max-memory`.
fn check_memory(settings: &EstimateSettings, dt: f64, samples: usize) -> Result<()> {
    let limit = crate::limits::get().max_memory;
    let estimator = htfid_estimate::estimator_bytes(
        1,
        samples as u64,
        dt,
        settings.harmonics.len(),
        settings.band,
    );
    // The records of every output stay in memory beside the estimator (time, input, output,
    // and the periodic split of each).
    let records = (samples as u64)
        .saturating_mul(8 * 5)
        .saturating_mul(settings.outputs.len() as u64);
    let total = estimator.saturating_add(records);
    if total > limit {
        bail!(
            "{}: data.file = \"{}\" ({} samples after data.start) needs about {} for the \
             estimate (limit {}; raise with --max-memory, or narrow the band or set data.start)",
            settings.path.display(),
            settings.file.display(),
            samples,
            crate::limits::Bytes(total),
            crate::limits::Bytes(limit)
        );
    }
    Ok(())
}

/// What the experiment allows, in sentences for the summary and the report.
fn notes(settings: &EstimateSettings, plan: &PeriodicRecord, found: &DataEstimate) -> Vec<String> {
    let periods = plan.periods;
    let nyquist = plan.nyquist();
    let (lo, hi) = settings.band;
    let mut notes: Vec<String> = Vec::new();
    if periods < MIN_PERIODS {
        notes.push(format!(
            "only {periods} periods: the estimate has few degrees of freedom per bin"
        ));
    }
    if let Some((a, b)) = found.excited_band {
        if a > lo * 1.05 || b < hi * 0.95 {
            notes.push(format!(
                "the input excites {a:.3}-{b:.3} rad/s (within 40 dB of its peak), not the whole \
                 band {lo}-{hi} rad/s: outside it the estimates rest on regularisation alone"
            ));
        }
    } else {
        notes.push("the input has no broadband content apart from its periodic part".into());
    }
    if !found.unexcited.is_empty() {
        notes.push(format!(
            "{}: the input frequencies these read (w - n wp) lie outside the excited band; \
             there the estimates rest on regularisation and noise alone",
            found
                .unexcited
                .iter()
                .map(|(n, ranges)| format!(
                    "G_{n} at {}",
                    ranges
                        .iter()
                        .map(|(a, b)| format!("{a:.3}-{b:.3} rad/s"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
                .collect::<Vec<_>>()
                .join("; ")
        ));
    }
    if !found.aliased.is_empty() {
        notes.push(format!(
            "harmonics {:?} map part of the band past the Nyquist frequency \
             ({nyquist:.1} rad/s): they alias and cannot be resolved at this sample rate",
            found.aliased
        ));
    }
    for (o, out) in found.outputs.iter().enumerate() {
        if let Err(e) = &out.outer {
            notes.push(format!(
                "output {}: harmonics beyond estimation.harmonics could not be checked: {e}",
                settings.outputs[o]
            ));
        }
    }
    // With few periods the standard errors the check weighs against rest on few residual
    // degrees of freedom: its claims would be noise (a 5-period record named G_-4 and G_4 over
    // the whole band where they are 1e-5 of G_0).
    let checkable = periods >= MIN_PERIODS;
    let any_outer = found
        .outputs
        .iter()
        .any(|o| o.outer.as_ref().is_ok_and(|l| !l.is_empty()));
    if !checkable && any_outer {
        notes.push(format!(
            "with only {periods} periods (fewer than {MIN_PERIODS}) the harmonics outside \
             estimation.harmonics cannot be checked: their standard errors rest on too few \
             degrees of freedom (summary.json keeps the numbers)"
        ));
    }
    for (o, out) in found.outputs.iter().enumerate().filter(|_| checkable) {
        let carried = out.carried_outside();
        if !carried.is_empty() {
            notes.push(format!(
                "output {}: the response carries harmonics outside estimation.harmonics ({}), \
                 significant where estimated beside the others; left out, they are absorbed \
                 by the harmonics estimated as a bias their standard errors do not show: add \
                 them to estimation.harmonics (an orbit with impacts carries every harmonic: \
                 add until those beyond stay near the noise's 2 %, or read the estimates as \
                 biased by them)",
                settings.outputs[o],
                carried
                    .iter()
                    .map(|h| format!(
                        "G_{} at {:.0} % of the band",
                        h.n,
                        100.0 * h.significant_share
                    ))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    }
    if hi > nyquist {
        notes.push(format!(
            "estimation.omega_max = {hi} rad/s is above the Nyquist frequency {nyquist:.1} rad/s"
        ));
    }
    notes
}
