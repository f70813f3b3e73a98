//! `htfid simulate CONFIG`: the limit cycle and the excited time series.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use htfid_data::OutputDir;
use htfid_experiment::{add_noise, drive_sampled, Driven};
use htfid_hybrid::{SlidingInterval, Stats};
use htfid_model::{Hopper, HopperMode, HopperOrbit};
use htfid_orbit::ShootingOptions;
use serde_json::{json, Value};

use crate::output::{json_text, open, resolve_dir};
use crate::progress::Stages;
use crate::settings::{Settings, System};
use crate::signals::{self, Built};

/// Samples of the orbit written to `limit_cycle.csv`.
const ORBIT_SAMPLES: usize = 1000;

/// Everything `simulate` computes; `run` continues from it.
pub struct Simulated {
    pub hopper: Hopper,
    pub orbit: HopperOrbit,
    pub excitation: Built,
    pub t: Vec<f64>,
    pub f: Vec<f64>,
    pub u: Vec<f64>,
    pub x: Vec<f64>,
    pub xd: Vec<f64>,
    pub stats: Stats,
    pub switches: usize,
    /// Intervals during which the mass sticks (slides along the damper switch).
    pub sliding: Vec<SlidingInterval<HopperMode>>,
}

pub fn run(config: &Path, out: Option<PathBuf>, force: bool) -> Result<()> {
    let settings = Settings::from_file(config)?;
    crate::limits::check_experiment(&settings, crate::limits::Stage::Simulate)?;
    if let System::Model(model) = &settings.system {
        return crate::commands::models::simulate_model(&settings, model, out, force);
    }
    let dir = resolve_dir(out, &settings.name);
    let mut outdir = open(
        &dir,
        force,
        &["timeseries.csv", "limit_cycle.csv", "summary.json"],
    )?;
    let mut stages = Stages::new();
    let sim = simulate_experiment(&settings, &mut stages)?;
    stages.run("write outputs", || {
        write_simulation(&settings, &sim, &mut outdir)
    })?;
    let mut summary = base_summary(&settings, &sim);
    summary["timings_ms"] = stages.to_json();
    outdir.write_text("summary.json", &json_text(&summary))?;
    let written = outdir.commit()?;
    crate::results::simulate(&summary, &dir, &written);
    Ok(())
}

/// The configured hopper and its limit cycle (settling plus Newton shooting).
pub fn hopper_and_orbit(settings: &Settings, stages: &mut Stages) -> Result<(Hopper, HopperOrbit)> {
    let (params, damper, effects) = settings.hopper("simulate")?;
    let hopper = Hopper::with_effects(params, damper, effects)
        .with_context(|| format!("{}: invalid model", settings.path.display()))?;
    let shooting = ShootingOptions {
        settle_periods: settings.settle_periods.max(30),
        ..ShootingOptions::default()
    };
    let orbit = stages
        .run("limit cycle", || {
            hopper.limit_cycle(&shooting, &settings.integrator)
        })
        .with_context(|| {
            format!(
                "{}: model: no limit cycle for these parameters ([model] and [forcing])",
                settings.path.display()
            )
        })?;
    Ok((hopper, orbit))
}

/// Limit cycle, then the whole experiment from `t = 0` on the orbit.
pub fn simulate_experiment(settings: &Settings, stages: &mut Stages) -> Result<Simulated> {
    let (hopper, orbit) = hopper_and_orbit(settings, stages)?;
    simulate_on(settings, hopper, orbit, stages)
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

/// The input `u` and the commanded force `f = forcing + u` at the sample times `grid`: the
/// columns of the record that the simulation does not produce.
pub struct InputColumns {
    pub u: Vec<f64>,
    pub f: Vec<f64>,
}

impl InputColumns {
    pub fn new(hopper: &Hopper, grid: &[f64], u: Vec<f64>) -> Self {
        let f = grid
            .iter()
            .zip(&u)
            .map(|(&t, &u)| hopper.forcing(t) + u)
            .collect();
        Self { u, f }
    }
}

/// The configured experiment on `hopper`, from `t = 0` on its limit cycle `orbit`.
pub fn simulate_on(
    settings: &Settings,
    hopper: Hopper,
    orbit: HopperOrbit,
    stages: &mut Stages,
) -> Result<Simulated> {
    let (excitation, grid) = experiment_grid(settings)?;
    let columns = |hopper: &Hopper, excitation: &Built, grid: &[f64]| {
        InputColumns::new(hopper, grid, sample_input(excitation, grid))
    };
    simulate_with_columns(
        settings,
        (hopper, orbit),
        (excitation, grid),
        columns,
        stages,
    )
}

/// [`simulate_on`] with the input's columns from `columns`, called once the trajectory is
/// known: a caller may have them computed on another thread meanwhile.
pub fn simulate_with_columns(
    settings: &Settings,
    (hopper, orbit): (Hopper, HopperOrbit),
    (excitation, grid): (Built, Vec<f64>),
    columns: impl FnOnce(&Hopper, &Built, &[f64]) -> InputColumns,
    stages: &mut Stages,
) -> Result<Simulated> {
    let n = grid.len();
    let mut input = None;
    let driven = stages
        .run("simulate", || {
            drive_sampled(
                &hopper,
                &orbit.cycle,
                excitation.input_fn(),
                &grid,
                &settings.integrator,
                || {
                    let c = columns(&hopper, &excitation, &grid);
                    let u = c.u.clone();
                    input = Some(c);
                    u
                },
            )
        })
        .map_err(|e| {
            crate::limits::experiment_failed(settings, crate::limits::Simulated::Experiment, e)
        })?;
    let InputColumns { u, f } = input.context("the simulation read the input's columns")?;
    let Driven {
        trajectory: traj,
        mut outputs,
    } = driven;
    // The position sensor's lag, offset and gain, then measurement noise on the recorded
    // position (seeded), as configured.
    settings
        .sensor()
        .apply(1.0 / settings.sample_rate, &mut outputs[0]);
    if let Some(noise) = settings.noise {
        add_noise(&mut outputs, noise.output_std, noise.seed).context("noise.output_std")?;
    }
    let x = outputs.swap_remove(0);
    let xd = (0..n).map(|i| traj.state(i)[1]).collect();
    let switches = traj.switches().count();
    let sliding = traj.sliding.clone();
    Ok(Simulated {
        hopper,
        orbit,
        excitation,
        t: grid,
        f,
        u,
        x,
        xd,
        stats: traj.stats,
        switches,
        sliding,
    })
}

/// `timeseries.csv` and `limit_cycle.csv`.
pub fn write_simulation(settings: &Settings, sim: &Simulated, out: &mut OutputDir) -> Result<()> {
    let path = out.path_for("timeseries.csv")?;
    write_timeseries(&path, sim)?;
    write_limit_cycle(settings, sim, out)
}

/// `timeseries.csv` to an already registered path (so it can be written on another thread).
pub fn write_timeseries(path: &Path, sim: &Simulated) -> Result<()> {
    htfid_data::write_timeseries_csv(
        path,
        &sim.t,
        &[("f", &sim.f), ("x", &sim.x), ("xd", &sim.xd), ("u", &sim.u)],
    )?;
    Ok(())
}

/// The columns of `limit_cycle.csv`.
pub const LIMIT_CYCLE_HEADER: &[&str] = &["phase", "x", "xd", "s", "stick"];

/// `limit_cycle.csv`.
pub fn write_limit_cycle(settings: &Settings, sim: &Simulated, out: &mut OutputDir) -> Result<()> {
    fill_limit_cycle(
        out.csv("limit_cycle.csv", LIMIT_CYCLE_HEADER)?,
        settings,
        &sim.hopper,
        &sim.orbit,
    )
}

/// Writes the rows of `limit_cycle.csv` into `csv` (opened with [`LIMIT_CYCLE_HEADER`]).
pub fn fill_limit_cycle(
    mut csv: htfid_data::CsvWriter,
    settings: &Settings,
    hopper: &Hopper,
    orbit: &HopperOrbit,
) -> Result<()> {
    let samples = hopper.sample_orbit(orbit, ORBIT_SAMPLES, &settings.integrator)?;
    for s in &samples {
        // While stuck the velocity is zero and `s` is the chart the mass arrived in; the
        // `stick` column marks those phases.
        csv.write_row(&[s.phase, s.x, s.xd, s.s, f64::from(u8::from(s.stick))])?;
    }
    csv.finish()?;
    Ok(())
}

/// The `limit_cycle` block of `summary.json`.
pub fn limit_cycle_json(orbit: &HopperOrbit) -> Value {
    let c = &orbit.cycle;
    let n = c.jacobian.nrows();
    let jac: Vec<Vec<f64>> = (0..n)
        .map(|i| (0..n).map(|j| c.jacobian[(i, j)]).collect())
        .collect();
    json!({
        "period": c.period,
        "t_on": orbit.t_on,
        "t_off": orbit.t_off,
        "duty": orbit.duty,
        "state_phase0": c.state0,
        "mode_phase0": c.mode0,
        "period_map_jacobian": jac,
        "floquet_multipliers": c.multipliers.iter().map(|m| [m.re, m.im]).collect::<Vec<_>>(),
        "periodicity_residual": c.residual,
        "newton_iterations": c.newton_iterations,
        "stick_intervals": sliding_json(&c.sliding, c.t0),
        "stick_fraction": c.sliding.iter().map(|s| s.end - s.start).sum::<f64>() / c.period,
    })
}

/// Sliding intervals as JSON: times from `origin`, the chart the mass arrived in and the one
/// it left into (`null` when still stuck at the end).
pub fn sliding_json(sliding: &[SlidingInterval<HopperMode>], origin: f64) -> Value {
    sliding
        .iter()
        .map(|s| {
            json!({
                "start": s.start - origin,
                "end": s.end - origin,
                "arrived": s.chart,
                "left": s.exit,
            })
        })
        .collect()
}

/// The summary common to every command that simulates.
pub fn base_summary(settings: &Settings, sim: &Simulated) -> Value {
    json!({
        "name": settings.name,
        "config": settings.path.display().to_string(),
        "htfid_version": env!("CARGO_PKG_VERSION"),
        "limit_cycle": limit_cycle_json(&sim.orbit),
        "simulation": {
            "t_end": sim.t.last().copied().unwrap_or(0.0),
            "samples": sim.t.len(),
            "sample_rate": settings.sample_rate,
            "switches": sim.switches,
            "stick_intervals": sim.sliding.len(),
            "stick_time": sim.sliding.iter().map(|s| s.end - s.start).sum::<f64>(),
            "steps": sim.stats.steps,
            "rejected_steps": sim.stats.rejected,
            "rhs_evaluations": sim.stats.rhs_evals,
            "excitation_segments": sim.excitation.segments.iter().map(|s| json!({
                "index": s.index, "start": s.start, "end": s.end, "phase": s.delay,
            })).collect::<Vec<_>>(),
        },
    })
}
