//! `simulate` and `theory` for models written in the model language: reading the config,
//! calling the libraries, writing files. The science is in `htfid-lang` (the model),
//! `htfid-orbit` (the limit cycle) and `htfid-theory` ([`LinearisedHtf`]).

use std::path::PathBuf;

use anyhow::{Context, Result};
use htfid_hybrid::{simulate, EventKind, HybridSystem};
use htfid_lang::{Mode, Model};
use htfid_orbit::{saltation, LimitCycle, ShootingOptions};
use htfid_theory::{HtfGrid, LinearisedHtf};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use serde_json::{json, Value};

use crate::commands::simulate::report_written;
use crate::commands::theory::{theory_plots, write_theory_csv};
use crate::output::{json_text, open, resolve_dir};
use crate::progress::Stages;
use crate::settings::Settings;
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
    stages
        .run("limit cycle", || {
            model.limit_cycle(&shooting, &settings.integrator)
        })
        .with_context(|| {
            format!(
                "{}: no stable limit cycle of model `{}` from its [initial] state",
                settings.path.display(),
                model.name()
            )
        })
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
    json!({
        "period": cycle.period,
        "state_phase0": cycle.state0,
        "mode_phase0": model.mode_name(cycle.mode0),
        "events": events,
        "period_map_jacobian": matrix(&cycle.jacobian),
        "floquet_multipliers": cycle.multipliers.iter().map(|m| [m.re, m.im]).collect::<Vec<_>>(),
        "periodicity_residual": cycle.residual,
        "newton_iterations": cycle.newton_iterations,
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
    let mut stages = Stages::new(false);
    let cycle = limit_cycle(settings, model, &mut stages)?;
    let excitation = signals::build(settings)?;
    let period = settings.period;
    let start = settings.settle_time();
    let end = start + ((excitation.end - start).max(0.0) / period - 1e-9).ceil() * period;
    let end = end.max(period);
    let dt = 1.0 / settings.sample_rate;
    let n = (end / dt + 1e-9).floor() as usize + 1;
    let grid: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
    let driven = model.with_input(excitation.input_fn());
    let traj = stages
        .run("simulate", || {
            simulate(
                &driven,
                cycle.mode0,
                0.0,
                &cycle.state0,
                end,
                &grid,
                &settings.integrator,
            )
        })
        .context("simulation of the experiment failed")?;
    let u: Vec<f64> = match &excitation.signal {
        Some(s) => s.sample(&grid),
        None => vec![0.0; n],
    };
    let p = model.outputs().len();
    let mut outputs = vec![vec![0.0; n]; p];
    let mut y = vec![0.0; p];
    for i in 0..n {
        model.eval_outputs(traj.modes[i], grid[i], traj.state(i), u[i], &mut y);
        for (column, v) in outputs.iter_mut().zip(&y) {
            column[i] = *v;
        }
    }
    if let Some(noise) = settings.noise {
        if noise.output_std > 0.0 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(noise.seed);
            let normal = Normal::new(0.0, noise.output_std).context("noise.output_std")?;
            for column in &mut outputs {
                for v in column.iter_mut() {
                    *v += normal.sample(&mut rng);
                }
            }
        }
    }
    let dim = model.dim();
    let states: Vec<Vec<f64>> = (0..dim)
        .map(|j| (0..n).map(|i| traj.state(i)[j]).collect())
        .collect();
    let modes: Vec<f64> = traj.modes.iter().map(|m| m.index() as f64).collect();
    let state_names: Vec<String> = model
        .states()
        .iter()
        .map(|s| format!("state.{}", s.name))
        .collect();
    stages.run("write outputs", || -> Result<()> {
        let mut columns: Vec<(&str, &[f64])> = vec![("u", &u)];
        for (o, column) in model.outputs().iter().zip(&outputs) {
            columns.push((&o.name, column));
        }
        for (name, column) in state_names.iter().zip(&states) {
            columns.push((name, column));
        }
        columns.push(("mode", &modes));
        outdir.write_timeseries_csv("timeseries.csv", &grid, &columns)?;
        // One period of the orbit, input off.
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
        let mut header = vec!["phase"];
        header.extend(state_names.iter().map(String::as_str));
        header.push("mode");
        let mut csv = outdir.csv("limit_cycle.csv", &header)?;
        let mut row = Vec::with_capacity(dim + 2);
        for i in 0..ORBIT_SAMPLES {
            row.clear();
            row.push(phases[i]);
            row.extend_from_slice(orbit.state(i));
            row.push(orbit.modes[i].index() as f64);
            csv.write_row(&row)?;
        }
        csv.finish()?;
        Ok(())
    })?;
    let summary = json!({
        "name": settings.name,
        "config": settings.path.display().to_string(),
        "htfid_version": env!("CARGO_PKG_VERSION"),
        "model": model_json(model),
        "limit_cycle": cycle_json(model, &cycle),
        "simulation": {
            "t_end": end,
            "samples": n,
            "sample_rate": settings.sample_rate,
            "switches": traj.transitions().count(),
            "steps": traj.stats.steps,
            "rejected_steps": traj.stats.rejected,
            "rhs_evaluations": traj.stats.rhs_evals,
            "excitation_segments": excitation.segments.iter().map(|s| json!({
                "index": s.index, "start": s.start, "end": s.end, "phase": s.delay,
            })).collect::<Vec<_>>(),
        },
        "timings_ms": stages.to_json(),
    });
    outdir.write_text("summary.json", &json_text(&summary))?;
    report_written(&outdir.commit()?);
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
    if !no_plots {
        for stem in ["theory_g0", "theory_harmonics", "theory_phases"] {
            names.push(format!("{stem}.svg"));
            names.push(format!("{stem}.png"));
        }
    }
    let name_refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let dir = resolve_dir(out, &settings.name);
    let mut outdir = open(&dir, force, &name_refs)?;
    let mut stages = Stages::new(false);
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
        stages.run("plots", || theory_plots(&mut outdir, settings, &grids[0]))?;
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
    report_written(&outdir.commit()?);
    Ok(())
}
