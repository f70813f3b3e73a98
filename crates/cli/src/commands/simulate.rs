//! `htfid simulate CONFIG`: the limit cycle and the excited time series, for any configured
//! model ([`Subject`]).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use htfid_data::{CsvWriter, OutputDir, TimeSeries};
use htfid_experiment::{add_noise, drive_sampled, Driven};
use htfid_hybrid::{simulate, SlidingInterval, Stats};
use htfid_orbit::LimitCycle;
use serde_json::{json, Map, Value};

use crate::output::{json_text, open, resolve_dir};
use crate::progress::Stages;
use crate::settings::Settings;
use crate::signals::{self, Built};
use crate::subject::{limit_cycle, with_subject, Column, Subject};

/// Samples of the orbit written to `limit_cycle.csv`.
const ORBIT_SAMPLES: usize = 1000;

/// The configured experiment simulated from the orbit.
pub struct Record<S: Subject> {
    /// The input and every output as recorded (sensor and measurement noise applied).
    pub record: TimeSeries,
    /// The columns the model derives from the time and the input ([`Subject::input_columns`]).
    pub derived: Vec<Vec<f64>>,
    /// Per state.
    pub states: Vec<Vec<f64>>,
    /// The mode at every sample ([`Subject::mode_value`]).
    pub modes: Vec<f64>,
    pub excitation: Built,
    pub stats: Stats,
    pub switches: usize,
    /// Intervals during which the orbit slides along a switching surface.
    pub sliding: Vec<SlidingInterval<S::Mode>>,
}

pub fn run(config: &Path, out: Option<PathBuf>, force: bool) -> Result<()> {
    let settings = Settings::from_file(config)?;
    crate::limits::check_experiment(&settings, crate::limits::Stage::Simulate)?;
    with_subject!(&settings, |subject| simulate_command(
        &settings, subject, out, force
    ))
}

fn simulate_command<S: Subject>(
    settings: &Settings,
    subject: &S,
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
    let cycle = limit_cycle(settings, subject, &mut stages)?;
    let rec = simulate_on(settings, subject, &cycle, &mut stages)?;
    stages.run("write outputs", || -> Result<()> {
        let path = outdir.path_for("timeseries.csv")?;
        write_timeseries(&path, subject, &rec)?;
        let csv = limit_cycle_csv(&mut outdir, subject)?;
        fill_limit_cycle(csv, settings, subject, &cycle)
    })?;
    let mut summary = base_summary(settings, subject, &cycle, &rec)?;
    summary["timings_ms"] = stages.to_json();
    outdir.write_text("summary.json", &json_text(&summary))?;
    let written = outdir.commit()?;
    crate::results::simulate(&summary, &dir, &written);
    Ok(())
}

/// The configured excitation, the record's sample times and the input at them: what an
/// experiment knows before it runs.
pub fn experiment_input(settings: &Settings) -> Result<(Built, Vec<f64>, Vec<f64>)> {
    let (excitation, grid) = experiment_grid(settings)?;
    let u = sample_input(&excitation, &grid);
    Ok((excitation, grid, u))
}

/// The configured excitation and the record's sample times, without the input's values.
pub fn experiment_grid(settings: &Settings) -> Result<(Built, Vec<f64>)> {
    let excitation = signals::build(settings)?;
    let (_, grid) = settings.record_grid(excitation.end);
    Ok((excitation, grid))
}

/// The excitation's input at the sample times `grid`.
pub fn sample_input(excitation: &Built, grid: &[f64]) -> Vec<f64> {
    match &excitation.signal {
        Some(s) => s.sample(grid),
        None => vec![0.0; grid.len()],
    }
}

/// The input `u` at the sample times and the columns the model derives from it: the columns
/// of the record that the simulation does not produce.
pub struct InputColumns {
    pub u: Vec<f64>,
    pub derived: Vec<Vec<f64>>,
}

impl InputColumns {
    pub fn new<S: Subject>(subject: &S, grid: &[f64], u: Vec<f64>) -> Self {
        let derived = subject.input_columns(grid, &u);
        Self { u, derived }
    }
}

/// The configured experiment on `subject`, from `t = 0` on its limit cycle `cycle`.
pub fn simulate_on<S: Subject>(
    settings: &Settings,
    subject: &S,
    cycle: &LimitCycle<S::Mode>,
    stages: &mut Stages,
) -> Result<Record<S>> {
    let (excitation, grid) = experiment_grid(settings)?;
    let columns = |excitation: &Built, grid: &[f64]| {
        InputColumns::new(subject, grid, sample_input(excitation, grid))
    };
    simulate_with_columns(
        settings,
        subject,
        cycle,
        (excitation, grid),
        columns,
        stages,
    )
}

/// [`simulate_on`] with the input's columns from `columns`, called once the trajectory is
/// known: a caller may have them computed on another thread meanwhile.
pub fn simulate_with_columns<S: Subject>(
    settings: &Settings,
    subject: &S,
    cycle: &LimitCycle<S::Mode>,
    (excitation, grid): (Built, Vec<f64>),
    columns: impl FnOnce(&Built, &[f64]) -> InputColumns,
    stages: &mut Stages,
) -> Result<Record<S>> {
    let n = grid.len();
    let mut input = None;
    let driven = stages
        .run("simulate", || {
            // The outputs read the input's values already sampled.
            drive_sampled(
                subject,
                cycle,
                excitation.input_fn(),
                &grid,
                &settings.integrator,
                || {
                    let c = columns(&excitation, &grid);
                    let u = c.u.clone();
                    input = Some(c);
                    u
                },
            )
        })
        .map_err(|e| {
            crate::limits::experiment_failed(settings, crate::limits::Simulated::Experiment, e)
        })?;
    let InputColumns { u, derived } = input.context("the simulation read the input's columns")?;
    let Driven {
        trajectory: traj,
        mut outputs,
    } = driven;
    // The first output's sensor (the hopper's `[effects]` lag, offset and gain; ideal for a
    // model file, whose outputs are written in the model), then measurement noise on every
    // output (seeded), as configured.
    if let Some(first) = outputs.first_mut() {
        settings.sensor().apply(1.0 / settings.sample_rate, first);
    }
    if let Some(noise) = settings.noise {
        add_noise(&mut outputs, noise.output_std, noise.seed).context("noise.output_std")?;
    }
    let states: Vec<Vec<f64>> = (0..subject.dim())
        .map(|j| (0..n).map(|i| traj.state(i)[j]).collect())
        .collect();
    let modes = traj.modes.iter().map(|&m| subject.mode_value(m)).collect();
    let switches = traj.switches().count();
    let record = TimeSeries::with_outputs(grid, u, outputs, settings.path.clone())
        .context("the simulated record")?;
    Ok(Record {
        record,
        derived,
        states,
        modes,
        excitation,
        stats: traj.stats,
        switches,
        sliding: traj.sliding,
    })
}

/// `timeseries.csv` to an already registered path (so it can be written on another thread):
/// `t` and the model's columns ([`Subject::timeseries_columns`]).
pub fn write_timeseries<S: Subject>(path: &Path, subject: &S, rec: &Record<S>) -> Result<()> {
    let named = subject.timeseries_columns();
    let columns: Vec<(&str, &[f64])> = named
        .iter()
        .map(|(name, column)| {
            let values: &[f64] = match *column {
                Column::Input => rec.record.input(),
                Column::Derived(i) => &rec.derived[i],
                Column::Output(i) => &rec.record.outputs()[i],
                Column::State(i) => &rec.states[i],
                Column::Mode => &rec.modes,
            };
            (name.as_str(), values)
        })
        .collect();
    htfid_data::write_timeseries_csv(path, rec.record.time(), &columns)?;
    Ok(())
}

/// `limit_cycle.csv` opened with its header: `phase` and the model's columns
/// ([`Subject::cycle_columns`]).
pub fn limit_cycle_csv<S: Subject>(outdir: &mut OutputDir, subject: &S) -> Result<CsvWriter> {
    let mut header = vec!["phase".to_string()];
    header.extend(subject.cycle_columns());
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    Ok(outdir.csv("limit_cycle.csv", &header)?)
}

/// Writes the rows of `limit_cycle.csv` into `csv` (from [`limit_cycle_csv`]): one period of
/// the orbit, input off: the states, the mode, and 1 where the orbit slides.
pub fn fill_limit_cycle<S: Subject>(
    mut csv: CsvWriter,
    settings: &Settings,
    subject: &S,
    cycle: &LimitCycle<S::Mode>,
) -> Result<()> {
    let period = cycle.period;
    let phases: Vec<f64> = (0..ORBIT_SAMPLES)
        .map(|i| period * i as f64 / ORBIT_SAMPLES as f64)
        .collect();
    let unforced = subject.with_input(None);
    let orbit = simulate(
        &unforced,
        cycle.mode0,
        0.0,
        &cycle.state0,
        period,
        &phases,
        &settings.integrator,
    )?;
    let mut row = Vec::with_capacity(subject.dim() + 3);
    for (i, &phase) in phases.iter().enumerate() {
        row.clear();
        row.push(phase);
        row.extend_from_slice(orbit.state(i));
        row.push(subject.mode_value(orbit.modes[i]));
        row.push(f64::from(u8::from(orbit.sliding_at(phase).is_some())));
        csv.write_row(&row)?;
    }
    csv.finish()?;
    Ok(())
}

/// The `simulation` block of `summary.json`.
fn simulation_json<S: Subject>(settings: &Settings, subject: &S, rec: &Record<S>) -> Value {
    let mut block = Map::new();
    block.insert(
        "t_end".into(),
        json!(rec.record.time().last().copied().unwrap_or(0.0)),
    );
    block.insert("samples".into(), json!(rec.record.len()));
    block.insert("sample_rate".into(), json!(settings.sample_rate));
    block.insert("switches".into(), json!(rec.switches));
    block.insert("steps".into(), json!(rec.stats.steps));
    block.insert("rejected_steps".into(), json!(rec.stats.rejected));
    block.insert("rhs_evaluations".into(), json!(rec.stats.rhs_evals));
    block.insert(
        "excitation_segments".into(),
        rec.excitation
            .segments
            .iter()
            .map(|s| json!({"index": s.index, "start": s.start, "end": s.end, "phase": s.delay}))
            .collect(),
    );
    subject.sliding_json(&rec.sliding, &mut block);
    Value::Object(block)
}

/// The summary common to every command that simulates: the config, the model, its limit
/// cycle and the simulation.
pub fn base_summary<S: Subject>(
    settings: &Settings,
    subject: &S,
    cycle: &LimitCycle<S::Mode>,
    rec: &Record<S>,
) -> Result<Value> {
    let mut summary = head_summary(settings, subject, cycle)?;
    summary["simulation"] = simulation_json(settings, subject, rec);
    Ok(summary)
}

/// The summary's head: the config, the model and its limit cycle.
pub fn head_summary<S: Subject>(
    settings: &Settings,
    subject: &S,
    cycle: &LimitCycle<S::Mode>,
) -> Result<Value> {
    let mut summary = json!({
        "name": settings.name,
        "config": settings.path.display().to_string(),
        "htfid_version": env!("CARGO_PKG_VERSION"),
        "limit_cycle": subject.cycle_json(cycle)?,
    });
    if let Some(model) = subject.model_json() {
        summary["model"] = model;
    }
    Ok(summary)
}
