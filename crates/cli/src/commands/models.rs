//! `simulate`, `theory` and `run` for models written in the model language: reading the config,
//! calling the libraries, writing files. The science is in `htfid-lang` (the model),
//! `htfid-orbit` (the limit cycle) and `htfid-theory` ([`LinearisedHtf`]).

use std::path::PathBuf;

use anyhow::{Context, Result};
use htfid_data::TimeSeries;
use htfid_estimate::{HtfEstimate, Method};
use htfid_experiment::{add_noise, distortion_bootstrap, drive_sampled, Driven};
use htfid_hybrid::{simulate, EventKind, HybridSystem};
use htfid_identify::{fit_to_htf, HtfFit, HtfFitSpec};
use htfid_lang::{Mode, Model};
use htfid_orbit::{saltation, LimitCycle, ShootingOptions};
use htfid_theory::{HarmonicTransferFunction, HtfChannel, HtfGrid, LinearisedHtf, Tabulated};
use num_complex::Complex64;
use serde_json::{json, Value};

use crate::commands::run::{
    aliasing, design, estimate, fill_estimate_csv, harmonic_errors, prepare_all, run_plots,
    truths_at, Prepared, Truths, ESTIMATE_HEADER,
};
use crate::commands::simulate::experiment_input;
use crate::commands::theory::{fill_theory_csv, theory_plots, write_theory_csv, THEORY_HEADER};
use crate::output::{json_text, open, resolve_dir};
use crate::progress::Stages;
use crate::settings::{Estimator, Settings};
use crate::signals;

/// Samples of the orbit written to `limit_cycle.csv`.
const ORBIT_SAMPLES: usize = 1000;

fn matrix(m: &nalgebra::DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
        .collect()
}

/// The configured model's limit cycle (settling plus Newton shooting).
fn limit_cycle(
    settings: &Settings,
    model: &Model,
    stages: &mut Stages,
) -> Result<LimitCycle<Mode>> {
    let shooting = ShootingOptions {
        settle_periods: settings.settle_periods.max(30),
        ..ShootingOptions::default()
    };
    let found = stages.run("limit cycle", || {
        model.limit_cycle(&shooting, &settings.integrator)
    });
    let Err(e) = found else {
        return Ok(found?);
    };
    // A model file's own values have a limit cycle but the configured ones do not: name the
    // override that loses it (g = 1e308 overflows the simulation), tried one at a time.
    if let Some(o) = &settings.overrides {
        if o.base.limit_cycle(&shooting, &settings.integrator).is_ok() {
            for (name, value, line, column) in &o.entries {
                let Ok(one) = o.base.with_parameters(&[(name.as_str(), *value)]) else {
                    continue;
                };
                if one.limit_cycle(&shooting, &settings.integrator).is_err() {
                    let file_value = o.base.parameter_index(name).map(|i| o.base.values()[i]);
                    return Err(anyhow::Error::new(e).context(format!(
                        "{}:{line}:{column}: model.parameters.{name}: with {name} = {value:e} \
                         the model `{}` has no stable limit cycle from its [initial] state (with \
                         the model file's value{} it has one)",
                        settings.path.display(),
                        model.name(),
                        file_value.map_or(String::new(), |v| format!(" {v}"))
                    )));
                }
            }
        }
    }
    Err(anyhow::Error::new(e).context(format!(
        "{}: no stable limit cycle of model `{}` from its [initial] state",
        settings.path.display(),
        model.name()
    )))
}

/// The `model` block of `summary.json`.
fn model_json(model: &Model) -> Value {
    json!({
        "name": model.name(),
        "states": model.states().iter().map(|s| &s.name).collect::<Vec<_>>(),
        "modes": model.modes(),
        "input": model.input_name(),
        "outputs": model.outputs().iter().map(|o| &o.name).collect::<Vec<_>>(),
        "parameters": model.parameters().iter().zip(model.values())
            .map(|(p, v)| (p.name.clone(), json!(v)))
            .collect::<serde_json::Map<_, _>>(),
    })
}

/// The `limit_cycle` block of `summary.json`, with the saltation matrix of every crossing.
fn cycle_json(model: &Model, cycle: &LimitCycle<Mode>) -> Value {
    let events: Vec<Value> = cycle
        .events
        .iter()
        .filter(|e| e.kind == EventKind::Transition)
        .map(|e| {
            let (s, _) = saltation(model, e.from, e.guard, e.time, &e.state);
            json!({
                "time": e.time,
                "phase": e.time.rem_euclid(cycle.period),
                "guard": model.guard_name(e.from, e.guard),
                "from": model.mode_name(e.from),
                "to": model.mode_name(e.to),
                "state_before": e.state,
                "saltation": matrix(&s),
            })
        })
        .collect();
    // A guard that never fires on the orbit is worth a word: a threshold beyond the motion or
    // a direction the wrong way round gives a valid orbit without its switches.
    let fired: Vec<&str> = cycle
        .events
        .iter()
        .filter(|e| e.kind == EventKind::Transition)
        .map(|e| model.guard_name(e.from, e.guard))
        .chain(
            cycle
                .sliding
                .iter()
                .map(|s| model.guard_name(s.chart, s.guard)),
        )
        .collect();
    let silent: Vec<&str> = model
        .guard_names()
        .into_iter()
        .filter(|g| !fired.contains(g))
        .collect();
    json!({
        "period": cycle.period,
        "guards_not_firing": silent,
        "state_phase0": cycle.state0,
        "mode_phase0": model.mode_name(cycle.mode0),
        "events": events,
        "period_map_jacobian": matrix(&cycle.jacobian),
        "floquet_multipliers": cycle.multipliers.iter().map(|m| [m.re, m.im]).collect::<Vec<_>>(),
        "periodicity_residual": cycle.residual,
        "newton_iterations": cycle.newton_iterations,
        "sliding_intervals": cycle.sliding.iter().map(|s| json!({
            "start": s.start - cycle.t0,
            "end": s.end - cycle.t0,
            "guard": model.guard_name(s.chart, s.guard),
            "arrived": model.mode_name(s.chart),
            "left": s.exit.map(|m| model.mode_name(m)),
        })).collect::<Vec<_>>(),
    })
}

/// The configured experiment simulated from the orbit: its record (the input and every
/// output, with measurement noise when configured), and every state.
pub struct ModelRun {
    pub record: TimeSeries,
    /// Per state.
    pub states: Vec<Vec<f64>>,
    pub modes: Vec<f64>,
    pub excitation: signals::Built,
    pub stats: htfid_hybrid::Stats,
    pub switches: usize,
}

fn simulate_record(
    settings: &Settings,
    model: &Model,
    cycle: &LimitCycle<Mode>,
    stages: &mut Stages,
) -> Result<ModelRun> {
    let (excitation, grid, u) = experiment_input(settings)?;
    let n = grid.len();
    let Driven {
        trajectory: traj,
        mut outputs,
    } = stages
        .run("simulate", || {
            // The outputs read the input's values already sampled.
            drive_sampled(
                model,
                cycle,
                excitation.input_fn(),
                &grid,
                &settings.integrator,
                || u.clone(),
            )
        })
        .map_err(|e| {
            crate::limits::experiment_failed(settings, crate::limits::Simulated::Experiment, e)
        })?;
    if let Some(noise) = settings.noise {
        add_noise(&mut outputs, noise.output_std, noise.seed).context("noise.output_std")?;
    }
    let states: Vec<Vec<f64>> = (0..model.dim())
        .map(|j| (0..n).map(|i| traj.state(i)[j]).collect())
        .collect();
    let record = TimeSeries::with_outputs(grid, u, outputs, settings.path.clone())
        .context("the simulated record")?;
    Ok(ModelRun {
        modes: traj.modes.iter().map(|m| m.index() as f64).collect(),
        switches: traj.switches().count(),
        stats: traj.stats,
        record,
        states,
        excitation,
    })
}

fn state_columns(model: &Model) -> Vec<String> {
    model
        .states()
        .iter()
        .map(|s| format!("state.{}", s.name))
        .collect()
}

/// `timeseries.csv` to an already registered path (so it can be written on another thread).
fn write_timeseries(path: &std::path::Path, model: &Model, rec: &ModelRun) -> Result<()> {
    let state_names = state_columns(model);
    let mut columns: Vec<(&str, &[f64])> = vec![("u", rec.record.input())];
    for (o, column) in model.outputs().iter().zip(rec.record.outputs()) {
        columns.push((&o.name, column));
    }
    for (name, column) in state_names.iter().zip(&rec.states) {
        columns.push((name, column));
    }
    columns.push(("mode", &rec.modes));
    htfid_data::write_timeseries_csv(path, rec.record.time(), &columns)?;
    Ok(())
}

/// `limit_cycle.csv`: one period of the orbit, input off.
fn write_limit_cycle(
    settings: &Settings,
    model: &Model,
    cycle: &LimitCycle<Mode>,
    outdir: &mut htfid_data::OutputDir,
) -> Result<()> {
    let header = limit_cycle_header(model);
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    fill_limit_cycle(
        outdir.csv("limit_cycle.csv", &header)?,
        settings,
        model,
        cycle,
    )
}

/// The columns of `limit_cycle.csv` for `model`.
fn limit_cycle_header(model: &Model) -> Vec<String> {
    let mut header = vec!["phase".to_string()];
    header.extend(state_columns(model));
    header.push("mode".into());
    header.push("sliding".into());
    header
}

/// Writes the rows of `limit_cycle.csv` into `csv` (opened with [`limit_cycle_header`]).
fn fill_limit_cycle(
    mut csv: htfid_data::CsvWriter,
    settings: &Settings,
    model: &Model,
    cycle: &LimitCycle<Mode>,
) -> Result<()> {
    let period = settings.period;
    let phases: Vec<f64> = (0..ORBIT_SAMPLES)
        .map(|i| period * i as f64 / ORBIT_SAMPLES as f64)
        .collect();
    let orbit = simulate(
        model,
        cycle.mode0,
        0.0,
        &cycle.state0,
        period,
        &phases,
        &settings.integrator,
    )?;
    let mut row = Vec::with_capacity(model.dim() + 3);
    for i in 0..ORBIT_SAMPLES {
        row.clear();
        row.push(phases[i]);
        row.extend_from_slice(orbit.state(i));
        row.push(orbit.modes[i].index() as f64);
        row.push(f64::from(u8::from(orbit.sliding_at(phases[i]).is_some())));
        csv.write_row(&row)?;
    }
    csv.finish()?;
    Ok(())
}

fn simulation_json(settings: &Settings, rec: &ModelRun) -> Value {
    json!({
        "t_end": rec.record.time().last().copied().unwrap_or(0.0),
        "samples": rec.record.len(),
        "sample_rate": settings.sample_rate,
        "switches": rec.switches,
        "steps": rec.stats.steps,
        "rejected_steps": rec.stats.rejected,
        "rhs_evaluations": rec.stats.rhs_evals,
        "excitation_segments": rec.excitation.segments.iter().map(|s| json!({
            "index": s.index, "start": s.start, "end": s.end, "phase": s.delay,
        })).collect::<Vec<_>>(),
    })
}

/// `htfid simulate` for a model-language model.
pub fn simulate_model(
    settings: &Settings,
    model: &Model,
    out: Option<PathBuf>,
    force: bool,
) -> Result<()> {
    let dir = resolve_dir(out, &settings.name);
    let mut outdir = open(
        &dir,
        force,
        &["timeseries.csv", "limit_cycle.csv", "summary.json"],
    )?;
    let mut stages = Stages::new();
    let cycle = limit_cycle(settings, model, &mut stages)?;
    let rec = simulate_record(settings, model, &cycle, &mut stages)?;
    stages.run("write outputs", || -> Result<()> {
        let path = outdir.path_for("timeseries.csv")?;
        write_timeseries(&path, model, &rec)?;
        write_limit_cycle(settings, model, &cycle, &mut outdir)
    })?;
    let summary = json!({
        "name": settings.name,
        "config": settings.path.display().to_string(),
        "htfid_version": env!("CARGO_PKG_VERSION"),
        "model": model_json(model),
        "limit_cycle": cycle_json(model, &cycle),
        "simulation": simulation_json(settings, &rec),
        "timings_ms": stages.to_json(),
    });
    outdir.write_text("summary.json", &json_text(&summary))?;
    let written = outdir.commit()?;
    crate::results::simulate(&summary, &dir, &written);
    Ok(())
}

/// `htfid theory` for a model-language model: exact HTFs of every output.
pub fn theory_model(
    settings: &Settings,
    model: &Model,
    omegas: &[f64],
    out: Option<PathBuf>,
    force: bool,
    no_plots: bool,
) -> Result<()> {
    let outputs: Vec<String> = model.outputs().iter().map(|o| o.name.clone()).collect();
    let mut names: Vec<String> = vec!["theory.csv".into(), "summary.json".into()];
    if outputs.len() > 1 {
        names.extend(outputs.iter().map(|o| format!("theory_{o}.csv")));
    }
    // Figures of the first output under the plain names, of every further one with its name.
    let suffixes: Vec<String> = outputs
        .iter()
        .enumerate()
        .map(|(i, o)| {
            if i == 0 {
                String::new()
            } else {
                format!("_{o}")
            }
        })
        .collect();
    if !no_plots {
        for suffix in &suffixes {
            for stem in ["theory_g0", "theory_harmonics", "theory_phases"] {
                names.push(format!("{stem}{suffix}.svg"));
                names.push(format!("{stem}{suffix}.png"));
            }
        }
    }
    let name_refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let dir = resolve_dir(out, &settings.name);
    let mut outdir = open(&dir, force, &name_refs)?;
    let mut stages = Stages::new();
    let cycle = limit_cycle(settings, model, &mut stages)?;
    let htf = stages
        .run("linearise", || {
            LinearisedHtf::new(model, &cycle, &settings.integrator)
        })
        .context("linearisation about the orbit failed")?;
    let harmonics = settings.theory.harmonics.clone();
    let grids: Vec<HtfGrid> = stages
        .run("HTF", || htf.grids(&harmonics, omegas))
        .context("harmonic transfer functions")?;
    stages.run("write outputs", || -> Result<()> {
        write_theory_csv(&mut outdir, "theory.csv", &grids[0])?;
        if outputs.len() > 1 {
            for (o, grid) in outputs.iter().zip(&grids) {
                write_theory_csv(&mut outdir, &format!("theory_{o}.csv"), grid)?;
            }
        }
        Ok(())
    })?;
    if !no_plots {
        // Each output's figures; its name in the title where there are several.
        stages.run("plots", || -> Result<()> {
            for ((output, suffix), grid) in outputs.iter().zip(&suffixes).zip(&grids) {
                let title = if outputs.len() > 1 {
                    format!("{} (output {output})", settings.name)
                } else {
                    settings.name.clone()
                };
                theory_plots(&mut outdir, &title, suffix, settings, grid)?;
            }
            Ok(())
        })?;
    }
    let summary = json!({
        "name": settings.name,
        "config": settings.path.display().to_string(),
        "htfid_version": env!("CARGO_PKG_VERSION"),
        "model": model_json(model),
        "limit_cycle": cycle_json(model, &cycle),
        "ltp": {
            "floquet_multipliers": htf.floquet_multipliers().iter().map(|m| [m.re, m.im]).collect::<Vec<_>>(),
        },
        "htf": {
            "method": htf.method().name(),
            "harmonics": harmonics,
            "points": omegas.len(),
            "outputs": outputs,
            "max_abs": grids.iter().map(HtfGrid::max_abs).collect::<Vec<_>>(),
        },
        "timings_ms": stages.to_json(),
    });
    outdir.write_text("summary.json", &json_text(&summary))?;
    let written = outdir.commit()?;
    crate::results::theory(&summary, &dir, &written);
    Ok(())
}

/// `htfid run` for a model-language model: simulate, estimate the HTFs of every output, fit
/// the configured parameters, compare with the exact theory.
pub fn run_model(
    settings: &Settings,
    model: &Model,
    out: Option<PathBuf>,
    force: bool,
    no_plots: bool,
) -> Result<()> {
    let outputs: Vec<String> = model.outputs().iter().map(|o| o.name.clone()).collect();
    let mut names: Vec<String> = [
        "timeseries.csv",
        "limit_cycle.csv",
        "theory.csv",
        "summary.json",
        "report.md",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    if outputs.len() > 1 {
        names.extend(outputs.iter().map(|o| format!("theory_{o}.csv")));
    }
    for est in &settings.estimation.estimators {
        for o in 0..outputs.len() {
            names.push(format!(
                "estimate_{}{}.csv",
                est.name(),
                suffix(&outputs, o)
            ));
        }
    }
    if !no_plots {
        for stem in ["htf_g0", "htf_harmonics"] {
            names.push(format!("{stem}.svg"));
            names.push(format!("{stem}.png"));
        }
    }
    let name_refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let dir = resolve_dir(out, &settings.name);
    let mut outdir = open(&dir, force, &name_refs)?;
    let mut stages = Stages::new();

    let cycle = limit_cycle(settings, model, &mut stages)?;
    let htf = stages
        .run("linearise", || {
            LinearisedHtf::new(model, &cycle, &settings.integrator)
        })
        .context("linearisation about the orbit failed")?;
    let channels = (0..outputs.len())
        .map(|o| htf.channel(o))
        .collect::<Result<Vec<_>, _>>()?;

    // The HTF's tables and the sampled orbit need only the orbit: they are computed and
    // written on the second core while the experiment is simulated.
    let mut theory_csvs = vec![outdir.csv("theory.csv", THEORY_HEADER)?];
    if outputs.len() > 1 {
        for o in &outputs {
            theory_csvs.push(outdir.csv(&format!("theory_{o}.csv"), THEORY_HEADER)?);
        }
    }
    let header = limit_cycle_header(model);
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    let cycle_csv = outdir.csv("limit_cycle.csv", &header)?;
    let (rec, side) = std::thread::scope(|scope| -> Result<_> {
        let (htf, cycle, channels) = (&htf, &cycle, &channels);
        let side = scope.spawn(
            move || -> Result<(Stages, Option<Vec<Prepared>>, Truths<'_>)> {
                let mut local = Stages::silent();
                let grids = local
                    .run("theory grid", || {
                        htf.grids(&settings.theory.harmonics, &settings.theory.omegas)
                    })
                    .context("harmonic transfer functions")?;
                local.run("write theory", || -> Result<()> {
                    // `theory.csv` is the first output's table; with several outputs each also
                    // has its own.
                    let mut csvs = theory_csvs.into_iter();
                    if let Some(first) = csvs.next() {
                        fill_theory_csv(first, &grids[0])?;
                    }
                    for (csv, grid) in csvs.zip(&grids) {
                        fill_theory_csv(csv, grid)?;
                    }
                    fill_limit_cycle(cycle_csv, settings, model, cycle)
                })?;
                // The estimators' work on the input alone (`htfid_estimate::Design`); should it
                // fail, the chains prepare them again from the simulated input and say why.
                let designs = local
                    .run("prepare estimators", || {
                        prepare_all(settings, experiment_input(settings)?)
                    })
                    .ok();
                // Each output's HTF at the rows an estimate will have, where the input fixes
                // them, for its errors.
                let truths = local.run("HTF at the estimates", || {
                    let htfs: Vec<&(dyn HarmonicTransferFunction + Sync)> = channels
                        .iter()
                        .map(|c| c as &(dyn HarmonicTransferFunction + Sync))
                        .collect();
                    truths_at(&htfs, designs.as_deref())
                });
                Ok((local, designs, truths))
            },
        );
        let rec = simulate_record(settings, model, cycle, &mut stages);
        let side = side.join().expect("the theory writer does not panic");
        Ok((rec?, side?))
    })?;
    let (side, designs, truths) = side;
    stages.absorb(side);
    let deviation = stages.run("orbit deviation", || {
        orbit_deviation(settings, model, &cycle, &rec)
    })?;

    // The time series is the largest file; it is written on the second core while the
    // estimators and fits run, one thread per estimator.
    let ts_path = outdir.path_for("timeseries.csv")?;
    let est_csvs = settings
        .estimation
        .estimators
        .iter()
        .map(|est| {
            (0..outputs.len())
                .map(|o| {
                    let name = format!("estimate_{}{}.csv", est.name(), suffix(&outputs, o));
                    outdir.csv(&name, ESTIMATE_HEADER)
                })
                .collect::<Result<Vec<_>, _>>()
        })
        .collect::<Result<Vec<_>, _>>()?;
    let rec_ref = &rec;
    let found = std::thread::scope(|scope| -> Result<_> {
        let writer = scope.spawn(move || write_timeseries(&ts_path, model, rec_ref));
        let found = estimate_and_fit(
            settings,
            model,
            &cycle,
            &channels,
            rec_ref,
            &deviation,
            est_csvs,
            designs,
            truths,
            &mut stages,
        );
        writer.join().expect("the CSV writer does not panic")?;
        found
    })?;
    let (estimates, errors, fits) = found;
    if !no_plots {
        stages.run("plots", || {
            let unit = crate::plots::htf_unit(
                model.outputs().first().and_then(|o| o.unit.as_deref()),
                model.input_unit(),
            );
            run_plots(
                &mut outdir,
                settings,
                &channels[0],
                &estimates[0],
                unit.as_deref(),
            )
        })?;
    }
    let mut summary = json!({
        "name": settings.name,
        "config": settings.path.display().to_string(),
        "htfid_version": env!("CARGO_PKG_VERSION"),
        "model": model_json(model),
        "limit_cycle": cycle_json(model, &cycle),
        "simulation": simulation_json(settings, &rec),
        "ltp": {
            "floquet_multipliers": htf.floquet_multipliers().iter().map(|m| [m.re, m.im]).collect::<Vec<_>>(),
        },
        "htf": {"method": htf.method().name(), "outputs": outputs},
        "fit": Value::Object(fits),
        "errors": Value::Object(errors),
        "estimation": {
            "harmonics": settings.estimation.harmonics,
            "band": [settings.estimation.band.0, settings.estimation.band.1],
            "estimators": settings.estimation.estimators.iter().map(|e| e.name()).collect::<Vec<_>>(),
            "noise_output_std": settings.noise.map_or(0.0, |n| n.output_std),
        },
    });
    if let Some(a) = aliasing(settings, &channels[0])? {
        summary["aliasing"] = a;
    }
    if let Some(d) = &rec.excitation.design {
        summary["design"] = serde_json::to_value(d.report())?;
    }
    summary["timings_ms"] = stages.to_json();
    outdir.write_text("summary.json", &json_text(&summary))?;
    let info = |name: &str| {
        let p = model.parameters().iter().find(|p| p.name == name);
        crate::report::ParamInfo {
            configured: p.map(|p| p.value),
            unit: p.and_then(|p| p.unit.clone()),
        }
    };
    let g_unit = crate::plots::htf_unit(
        model.outputs().first().and_then(|o| o.unit.as_deref()),
        model.input_unit(),
    );
    outdir.write_text(
        "report.md",
        &crate::report::run(
            &summary,
            &settings.path,
            &settings.estimation.fit,
            &info,
            g_unit.as_deref(),
            !no_plots,
        ),
    )?;
    let written = outdir.commit()?;
    let unit = |name: &str| model.parameter_unit(name).map(str::to_string);
    crate::results::run(&summary, &settings.estimation.fit, &unit, &dir, &written);
    Ok(())
}

/// The first output keeps the single-output file names; others get their name appended.
fn suffix(outputs: &[String], o: usize) -> String {
    if o == 0 {
        String::new()
    } else {
        format!("_{}", outputs[o])
    }
}

/// What the estimators see: each output minus its value on the unexcited orbit
/// (`htfid_experiment::orbit_deviation`).
fn orbit_deviation(
    settings: &Settings,
    model: &Model,
    cycle: &LimitCycle<Mode>,
    rec: &ModelRun,
) -> Result<Vec<Vec<f64>>> {
    htfid_experiment::orbit_deviation(
        model,
        cycle,
        rec.record.time(),
        rec.record.outputs(),
        &settings.integrator,
    )
    .map_err(|e| crate::limits::experiment_failed(settings, crate::limits::Simulated::Orbit, e))
}

type Estimates = Vec<Vec<(Estimator, HtfEstimate)>>;
type JsonMap = serde_json::Map<String, Value>;

/// Estimates per output and estimator, their errors against the theory, and the fits (one
/// per estimator, to the estimates of every output together), each estimator's on a thread
/// of its own, which also writes its estimates into `csvs` (one per output).
#[allow(clippy::too_many_arguments)]
fn estimate_and_fit(
    settings: &Settings,
    model: &Model,
    cycle: &LimitCycle<Mode>,
    channels: &[HtfChannel<'_, '_, Model>],
    rec: &ModelRun,
    deviation: &[Vec<f64>],
    csvs: Vec<Vec<htfid_data::CsvWriter>>,
    designs: Option<Vec<Prepared>>,
    truths: Truths<'_>,
    stages: &mut Stages,
) -> Result<(Estimates, JsonMap, JsonMap)> {
    let outputs: Vec<String> = model.outputs().iter().map(|o| o.name.clone()).collect();
    let chain = |est: Estimator,
                 csvs: Vec<htfid_data::CsvWriter>,
                 prepared: Option<Prepared>,
                 truth: Option<Vec<Tabulated<'_>>>,
                 stages: &mut Stages| {
        // Every output is estimated with the estimator prepared once from the input: during
        // the simulation from the same input, checked sample by sample, or here.
        let input = rec.record.input();
        let prepared = match prepared.filter(|p| p.serves(input)) {
            Some(p) => p,
            None => stages
                .run(&format!("prepare ({})", est.name()), || {
                    design(settings, (rec.record.time(), input), &rec.excitation, est)
                })
                .with_context(|| format!("estimator \"{}\" failed", est.name()))?,
        };
        let mut per_output = Vec::new();
        for (o, y) in deviation.iter().enumerate() {
            let e = stages
                .run(
                    &format!("estimate ({}, {})", est.name(), outputs[o]),
                    || prepared.estimate(y),
                )
                .with_context(|| format!("estimator \"{}\" failed", est.name()))?;
            per_output.push(e);
        }
        let errors: Vec<Value> = per_output
            .iter()
            .enumerate()
            .map(|(o, e)| match &truth {
                Some(truth) => harmonic_errors(settings, &truth[o], e),
                None => harmonic_errors(settings, &channels[o], e),
            })
            .collect();
        let of_est: Vec<(usize, &HtfEstimate)> = per_output.iter().enumerate().collect();
        let fit = stages
            .run(&format!("fit ({})", est.name()), || {
                fit_model(settings, model, cycle, est, &of_est)
            })
            .with_context(|| {
                format!("parametric fit to the \"{}\" estimates failed", est.name())
            })?;
        stages.run(&format!("write estimate ({})", est.name()), || {
            csvs.into_iter()
                .zip(&per_output)
                .try_for_each(|(csv, e)| fill_estimate_csv(csv, e))
        })?;
        anyhow::Ok((per_output, errors, fit))
    };
    let mut designs = designs.map(Vec::into_iter);
    let mut truths = truths.into_iter();
    let chains = std::thread::scope(|scope| {
        let handles: Vec<_> = settings
            .estimation
            .estimators
            .iter()
            .zip(csvs)
            .map(|(&est, csvs)| {
                let chain = &chain;
                let prepared = designs.as_mut().and_then(Iterator::next);
                let truth = truths.next().flatten();
                scope.spawn(move || {
                    let mut local = Stages::silent();
                    let found = chain(est, csvs, prepared, truth, &mut local);
                    (local, found)
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("an estimator chain does not panic"))
            .collect::<Vec<_>>()
    });
    let mut estimates: Estimates = vec![Vec::new(); outputs.len()];
    let mut errors = JsonMap::new();
    let mut fits = JsonMap::new();
    for ((local, found), &est) in chains.into_iter().zip(&settings.estimation.estimators) {
        stages.absorb(local);
        let (per_output, errs, fit) = found?;
        for (o, (e, err)) in per_output.into_iter().zip(errs).enumerate() {
            errors.insert(format!("{}{}", est.name(), suffix(&outputs, o)), err);
            estimates[o].push((est, e));
        }
        fits.insert(est.name().into(), fit);
    }
    Ok((estimates, errors, fits))
}

/// The configured parameters fitted to the estimates of every output (`htfid-identify`), with
/// the fit's error budget. A line estimator's distortion (what a `+u` / `-u` pairing leaves,
/// or all of the nonlinear response without pairing) comes from a parametric bootstrap: the
/// experiment simulated again on the fitted model without noise, estimated and fitted the
/// same way; the regularised estimators carry their own smoothing bias.
fn fit_model(
    settings: &Settings,
    model: &Model,
    cycle: &LimitCycle<Mode>,
    est: Estimator,
    estimates: &[(usize, &HtfEstimate)],
) -> Result<Value> {
    let spec = crate::commands::run::fit_spec(settings);
    let fit = fit_to_htf(model, cycle, estimates, &spec, &settings.integrator)?;
    let mut out = crate::commands::run::fit_json(settings, &fit);
    // Every output's estimate comes from the same estimator.
    let method = estimates
        .first()
        .map_or(Method::Siddiqi, |(_, e)| e.method());
    out["uncertainty"] = crate::commands::run::budget_json(&fit, method, || {
        bootstrap(settings, model, cycle, est, &spec, &fit)
    });
    Ok(out)
}

/// The error the estimator and fit make without noise on the fitted model
/// (`htfid_experiment::distortion_bootstrap`): the experiment simulated again on it without
/// noise, estimated per output the same way. Returns the HTF error at every fitted point and
/// the parameter error.
fn bootstrap(
    settings: &Settings,
    model: &Model,
    cycle: &LimitCycle<Mode>,
    est: Estimator,
    spec: &HtfFitSpec,
    fit: &HtfFit,
) -> Result<(Vec<Complex64>, Vec<f64>)> {
    let mut again = settings.clone();
    again.noise = None;
    let b = distortion_bootstrap(
        model,
        cycle,
        fit,
        spec,
        &again.integrator,
        |fitted: &Model, orbit: &LimitCycle<Mode>| -> Result<Vec<HtfEstimate>> {
            let mut quiet = Stages::silent();
            let rec = simulate_record(&again, fitted, orbit, &mut quiet)?;
            orbit_deviation(&again, fitted, orbit, &rec)?
                .iter()
                .map(|y| {
                    estimate(
                        &again,
                        (rec.record.time(), rec.record.input()),
                        &rec.excitation,
                        y,
                        est,
                    )
                })
                .collect()
        },
    )?;
    Ok((b.htf_bias, b.parameter_bias))
}
