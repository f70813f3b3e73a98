//! What the commands need of a model beyond the pipeline's [`Rhythmic`] trait: its names and
//! units in files and reports, and the blocks of `summary.json` that only it can fill. The
//! commands `simulate`, `theory` and `run` are written once over [`Subject`]; the built-in
//! hopper and every model-language [`Model`] are its two implementations. No science here:
//! the limit cycle, the linearisation and the HTFs come from the library crates.

use anyhow::{Context, Result};
use htfid_experiment::Rhythmic;
use htfid_hybrid::{EventKind, SlidingInterval};
use htfid_lang::{Mode, Model};
use htfid_ltp::{square_wave_fourier, Floquet};
use htfid_model::{Hopper, HopperMode, HopperOrbit};
use htfid_orbit::{saltation, LimitCycle, ShootingOptions};
use htfid_theory::{HtfGrid, HtfMethod, LinearisedHtf};
use num_complex::Complex64;
use serde_json::{json, Map, Value};

use crate::progress::Stages;
use crate::report::ParamInfo;
use crate::settings::{Settings, System};

/// One column of `timeseries.csv` after the time.
#[derive(Debug, Clone, Copy)]
pub enum Column {
    /// The excitation `u`.
    Input,
    /// A column the model derives from the time and the input ([`Subject::input_columns`]).
    Derived(usize),
    /// An output as recorded (sensor and noise applied).
    Output(usize),
    /// A state of the simulation.
    State(usize),
    /// The mode, as [`Subject::mode_value`].
    Mode,
}

/// A rhythmic model as the commands write it.
pub trait Subject: Rhythmic + Clone + Send + Sync {
    /// The `model` block of `summary.json`, for a model that describes itself there.
    fn model_json(&self) -> Option<Value>;

    /// How a failed search for the limit cycle reads: `err` with the config's words.
    fn no_cycle(&self, settings: &Settings, err: anyhow::Error) -> anyhow::Error;

    /// The `limit_cycle` block of `summary.json`.
    ///
    /// # Errors
    /// When the orbit does not have the shape the model's summary describes.
    fn cycle_json(&self, cycle: &LimitCycle<Self::Mode>) -> Result<Value>;

    /// The outputs' names, in order.
    fn output_names(&self) -> Vec<String>;

    /// The unit of the first output's HTF (`m/N`), when known.
    fn htf_unit(&self) -> Option<String>;

    /// A parameter's unit.
    fn parameter_unit(&self, name: &str) -> Option<String>;

    /// A parameter's configured value and unit, for the report.
    fn parameter_info(&self, name: &str) -> ParamInfo {
        ParamInfo {
            configured: self.parameter(name).map(|(v, _)| v),
            unit: self.parameter_unit(name),
        }
    }

    /// The columns of `timeseries.csv` after `t`, with their names.
    fn timeseries_columns(&self) -> Vec<(String, Column)>;

    /// The columns the model derives from the time and the input, at the sample times `grid`
    /// with the input `u` there ([`Column::Derived`]).
    fn input_columns(&self, _grid: &[f64], _u: &[f64]) -> Vec<Vec<f64>> {
        Vec::new()
    }

    /// The names of `limit_cycle.csv`'s columns after `phase`: every state, the mode, and
    /// whether the orbit slides.
    fn cycle_columns(&self) -> Vec<String>;

    /// The mode as a number in the files.
    fn mode_value(&self, mode: Self::Mode) -> f64;

    /// The mode in `summary.json`.
    fn mode_json(&self, mode: Self::Mode) -> Value;

    /// What the `simulation` block of `summary.json` adds about sliding along a switching
    /// surface.
    fn sliding_json(
        &self,
        _sliding: &[SlidingInterval<Self::Mode>],
        _block: &mut Map<String, Value>,
    ) {
    }

    /// What the `ltp` block adds beyond the linearisation's own keys.
    fn ltp_extra(&self, _cycle: &LimitCycle<Self::Mode>, _block: &mut Map<String, Value>) {}

    /// The name of an HTF method in `summary.json`.
    fn method_name(&self, method: HtfMethod) -> &'static str {
        method.name()
    }

    /// The `htf` block of `theory`'s `summary.json`, given the method's name and its grids.
    fn theory_htf_json(&self, method: Value, grids: &[HtfGrid]) -> Value {
        let mut block = method;
        block["outputs"] = json!(self.output_names());
        block["max_abs"] = json!(grids.iter().map(HtfGrid::max_abs).collect::<Vec<_>>());
        block
    }

    /// Whether `run`'s `summary.json` has an `htf` block (`method`, `outputs`).
    fn run_htf_block(&self) -> bool {
        true
    }
}

/// Runs `$body` with `$subject` bound to the configured model: the built-in hopper or a
/// model file's [`Model`].
macro_rules! with_subject {
    ($settings:expr, |$subject:ident| $body:expr) => {
        match $crate::subject::Configured::of($settings)? {
            $crate::subject::Configured::Hopper(hopper) => {
                let $subject = &hopper;
                $body
            }
            $crate::subject::Configured::Model(model) => {
                let $subject = model;
                $body
            }
        }
    };
}
pub(crate) use with_subject;

/// The model a config describes.
pub enum Configured<'a> {
    Hopper(Hopper),
    Model(&'a Model),
}

impl<'a> Configured<'a> {
    /// The configured model, checked.
    ///
    /// # Errors
    /// Parameters the hopper refuses, with the config's path.
    pub fn of(settings: &'a Settings) -> Result<Self> {
        Ok(match &settings.system {
            System::Hopper {
                params,
                damper,
                effects,
                ..
            } => Configured::Hopper(
                Hopper::with_effects(*params, *damper, *effects)
                    .with_context(|| format!("{}: invalid model", settings.path.display()))?,
            ),
            System::Model(model) => Configured::Model(model),
        })
    }
}

/// How the commands find a limit cycle: settling for the configured periods (at least 30),
/// then Newton shooting.
fn shooting(settings: &Settings) -> ShootingOptions {
    ShootingOptions {
        settle_periods: settings.settle_periods.max(30),
        ..ShootingOptions::default()
    }
}

/// The limit cycle of `subject` ([`shooting`]).
pub fn limit_cycle<S: Subject>(
    settings: &Settings,
    subject: &S,
    stages: &mut Stages,
) -> Result<LimitCycle<S::Mode>> {
    let shooting = shooting(settings);
    stages
        .run("limit cycle", || {
            subject.limit_cycle(&shooting, &settings.integrator)
        })
        .map_err(|e| subject.no_cycle(settings, anyhow::Error::new(e)))
}

/// The limit cycle of `subject` ([`limit_cycle`]) and its HTFs, linearised about it
/// (`LinearisedHtf`): the start of `theory` and `run`.
pub fn about_orbit<'a, S: Subject>(
    settings: &Settings,
    subject: &'a S,
    stages: &mut Stages,
) -> Result<(LimitCycle<S::Mode>, LinearisedHtf<'a, S>)> {
    let cycle = limit_cycle(settings, subject, stages)?;
    let htf = stages
        .run("linearise", || {
            LinearisedHtf::new(subject, &cycle, &settings.integrator)
        })
        .context("linearisation about the orbit failed")?;
    Ok((cycle, htf))
}

fn matrix(m: &nalgebra::DMatrix<f64>) -> Vec<Vec<f64>> {
    (0..m.nrows())
        .map(|i| (0..m.ncols()).map(|j| m[(i, j)]).collect())
        .collect()
}

fn complex_list(values: &[Complex64]) -> Vec<[f64; 2]> {
    values.iter().map(|m| [m.re, m.im]).collect()
}

/// The `ltp` block of `summary.json`: the Floquet multipliers of the linearisation, and with
/// a piecewise-LTI linearisation its monodromy, exponents, switches and pieces.
pub fn ltp_json<S: Subject>(
    subject: &S,
    htf: &LinearisedHtf<'_, S>,
    cycle: &LimitCycle<S::Mode>,
) -> Value {
    let Some(linearisation) = htf.linearisation() else {
        return json!({ "floquet_multipliers": complex_list(htf.floquet_multipliers()) });
    };
    let lti = &linearisation.piecewise;
    let floquet = Floquet::new(lti);
    let mono = lti.monodromy_from(0.0);
    let pieces: Vec<Value> = lti
        .pieces()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            json!({
                "start": lti.piece_start(i),
                "duration": p.duration(),
                "a": matrix(p.a()),
                "jump": p.jump().map(matrix),
            })
        })
        .collect();
    let mut block = Map::new();
    block.insert("monodromy".into(), json!(matrix(&mono)));
    block.insert(
        "floquet_multipliers".into(),
        json!(complex_list(floquet.multipliers())),
    );
    block.insert(
        "floquet_exponents".into(),
        json!(complex_list(&floquet.exponents())),
    );
    block.insert("monodromy_determinant".into(), json!(mono.determinant()));
    block.insert(
        "liouville_determinant".into(),
        json!(lti.liouville_determinant()),
    );
    subject.ltp_extra(cycle, &mut block);
    block.insert(
        "switches".into(),
        linearisation
            .switches
            .iter()
            .map(|s| {
                json!({
                    "time": s.time,
                    "from": subject.mode_json(s.from),
                    "to": subject.mode_json(s.to),
                    "saltation": matrix(&s.saltation),
                })
            })
            .collect(),
    );
    block.insert("pieces".into(), Value::Array(pieces));
    Value::Object(block)
}

impl Subject for Hopper {
    /// The hopper's summary predates the `model` block and keeps its own keys.
    fn model_json(&self) -> Option<Value> {
        None
    }

    fn no_cycle(&self, settings: &Settings, err: anyhow::Error) -> anyhow::Error {
        err.context(format!(
            "{}: model: no limit cycle for these parameters ([model] and [forcing])",
            settings.path.display()
        ))
    }

    fn cycle_json(&self, cycle: &LimitCycle<HopperMode>) -> Result<Value> {
        let orbit = HopperOrbit::from_cycle(cycle.clone())?;
        Ok(json!({
            "period": cycle.period,
            "t_on": orbit.t_on,
            "t_off": orbit.t_off,
            "duty": orbit.duty,
            "state_phase0": cycle.state0,
            "mode_phase0": cycle.mode0,
            "period_map_jacobian": matrix(&cycle.jacobian),
            "floquet_multipliers": complex_list(&cycle.multipliers),
            "periodicity_residual": cycle.residual,
            "newton_iterations": cycle.newton_iterations,
            "stick_intervals": stick_json(&cycle.sliding, cycle.t0),
            "stick_fraction": cycle.sliding.iter().map(|s| s.end - s.start).sum::<f64>() / cycle.period,
        }))
    }

    fn output_names(&self) -> Vec<String> {
        vec!["x".into()]
    }

    fn htf_unit(&self) -> Option<String> {
        Some("m/N".into())
    }

    fn parameter_unit(&self, name: &str) -> Option<String> {
        crate::results::hopper_unit(name).map(str::to_string)
    }

    /// `t,f,x,xd,u`: the first three are the measured-data format `diagnose` reads.
    fn timeseries_columns(&self) -> Vec<(String, Column)> {
        vec![
            ("f".into(), Column::Derived(0)),
            ("x".into(), Column::Output(0)),
            ("xd".into(), Column::State(1)),
            ("u".into(), Column::Input),
        ]
    }

    /// The applied force `f = forcing + u`.
    fn input_columns(&self, grid: &[f64], u: &[f64]) -> Vec<Vec<f64>> {
        vec![grid
            .iter()
            .zip(u)
            .map(|(&t, &u)| self.forcing(t) + u)
            .collect()]
    }

    fn cycle_columns(&self) -> Vec<String> {
        ["x", "xd", "s", "stick"].map(String::from).to_vec()
    }

    /// The damping switch `s`: 1 with the damper on.
    fn mode_value(&self, mode: HopperMode) -> f64 {
        mode.switch()
    }

    fn mode_json(&self, mode: HopperMode) -> Value {
        json!(mode)
    }

    fn sliding_json(
        &self,
        sliding: &[SlidingInterval<HopperMode>],
        block: &mut Map<String, Value>,
    ) {
        block.insert("stick_intervals".into(), json!(sliding.len()));
        block.insert(
            "stick_time".into(),
            json!(sliding.iter().map(|s| s.end - s.start).sum::<f64>()),
        );
    }

    /// The Fourier coefficients of the damping switch, `n = 0..10`.
    fn ltp_extra(&self, cycle: &LimitCycle<HopperMode>, block: &mut Map<String, Value>) {
        let Ok(orbit) = HopperOrbit::from_cycle(cycle.clone()) else {
            return;
        };
        let s_fourier: Vec<[f64; 2]> = (0..=10)
            .map(|n| {
                let c = if orbit.duty >= 1.0 {
                    Complex64::new(if n == 0 { 1.0 } else { 0.0 }, 0.0)
                } else {
                    square_wave_fourier(orbit.t_on, orbit.t_off, cycle.period, n)
                };
                [c.re, c.im]
            })
            .collect();
        block.insert("s_fourier".into(), json!(s_fourier));
    }

    fn method_name(&self, method: HtfMethod) -> &'static str {
        match method {
            HtfMethod::ExactPiecewise => "exact",
            HtfMethod::PeriodicResponse => method.name(),
        }
    }

    /// One output: `max_abs` is a number.
    fn theory_htf_json(&self, method: Value, grids: &[HtfGrid]) -> Value {
        let mut block = method;
        block["max_abs"] = json!(grids.first().map_or(0.0, HtfGrid::max_abs));
        block
    }

    fn run_htf_block(&self) -> bool {
        false
    }
}

/// The hopper's stick intervals: times from `origin`, the chart the mass arrived in and the
/// one it left into (`null` when still stuck at the end).
fn stick_json(sliding: &[SlidingInterval<HopperMode>], origin: f64) -> Value {
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

impl Subject for Model {
    fn model_json(&self) -> Option<Value> {
        Some(json!({
            "name": self.name(),
            "states": self.states().iter().map(|s| &s.name).collect::<Vec<_>>(),
            "modes": self.modes(),
            "input": self.input_name(),
            "outputs": self.outputs().iter().map(|o| &o.name).collect::<Vec<_>>(),
            "parameters": self.parameters().iter().zip(self.values())
                .map(|(p, v)| (p.name.clone(), json!(v)))
                .collect::<Map<_, _>>(),
        }))
    }

    /// A model file's own values may have a limit cycle where the configured ones do not: the
    /// message names the override that loses it, tried one at a time.
    fn no_cycle(&self, settings: &Settings, err: anyhow::Error) -> anyhow::Error {
        let shooting = shooting(settings);
        if let Some(o) = &settings.overrides {
            if o.base.limit_cycle(&shooting, &settings.integrator).is_ok() {
                for (name, value, line, column) in &o.entries {
                    let Ok(one) = o.base.with_parameters(&[(name.as_str(), *value)]) else {
                        continue;
                    };
                    if one.limit_cycle(&shooting, &settings.integrator).is_err() {
                        let file_value = o.base.parameter_index(name).map(|i| o.base.values()[i]);
                        return err.context(format!(
                            "{}:{line}:{column}: model.parameters.{name}: with {name} = {value:e} \
                             the model `{}` has no stable limit cycle from its [initial] state \
                             (with the model file's value{} it has one)",
                            settings.path.display(),
                            self.name(),
                            file_value.map_or(String::new(), |v| format!(" {v}"))
                        ));
                    }
                }
            }
        }
        err.context(format!(
            "{}: no stable limit cycle of model `{}` from its [initial] state",
            settings.path.display(),
            self.name()
        ))
    }

    /// With the saltation matrix of every crossing, and the guards that never fire.
    fn cycle_json(&self, cycle: &LimitCycle<Mode>) -> Result<Value> {
        let events: Vec<Value> = cycle
            .events
            .iter()
            .filter(|e| e.kind == EventKind::Transition)
            .map(|e| {
                let (s, _) = saltation(self, e.from, e.guard, e.time, &e.state);
                json!({
                    "time": e.time,
                    "phase": e.time.rem_euclid(cycle.period),
                    "guard": self.guard_name(e.from, e.guard),
                    "from": self.mode_name(e.from),
                    "to": self.mode_name(e.to),
                    "state_before": e.state,
                    "saltation": matrix(&s),
                })
            })
            .collect();
        // A guard that never fires on the orbit is worth a word: a threshold beyond the motion
        // or a direction the wrong way round gives a valid orbit without its switches.
        let fired: Vec<&str> = cycle
            .events
            .iter()
            .filter(|e| e.kind == EventKind::Transition)
            .map(|e| self.guard_name(e.from, e.guard))
            .chain(
                cycle
                    .sliding
                    .iter()
                    .map(|s| self.guard_name(s.chart, s.guard)),
            )
            .collect();
        let silent: Vec<&str> = self
            .guard_names()
            .into_iter()
            .filter(|g| !fired.contains(g))
            .collect();
        Ok(json!({
            "period": cycle.period,
            "guards_not_firing": silent,
            "state_phase0": cycle.state0,
            "mode_phase0": self.mode_name(cycle.mode0),
            "events": events,
            "period_map_jacobian": matrix(&cycle.jacobian),
            "floquet_multipliers": complex_list(&cycle.multipliers),
            "periodicity_residual": cycle.residual,
            "newton_iterations": cycle.newton_iterations,
            "sliding_intervals": cycle.sliding.iter().map(|s| json!({
                "start": s.start - cycle.t0,
                "end": s.end - cycle.t0,
                "guard": self.guard_name(s.chart, s.guard),
                "arrived": self.mode_name(s.chart),
                "left": s.exit.map(|m| self.mode_name(m)),
            })).collect::<Vec<_>>(),
        }))
    }

    fn output_names(&self) -> Vec<String> {
        self.outputs().iter().map(|o| o.name.clone()).collect()
    }

    fn htf_unit(&self) -> Option<String> {
        crate::plots::htf_unit(
            self.outputs().first().and_then(|o| o.unit.as_deref()),
            self.input_unit(),
        )
    }

    fn parameter_unit(&self, name: &str) -> Option<String> {
        Model::parameter_unit(self, name).map(str::to_string)
    }

    /// `u`, every output by its name, every state as `state.<name>`, the mode's index.
    fn timeseries_columns(&self) -> Vec<(String, Column)> {
        let mut columns = vec![("u".to_string(), Column::Input)];
        for (i, o) in self.outputs().iter().enumerate() {
            columns.push((o.name.clone(), Column::Output(i)));
        }
        for (i, name) in state_columns(self).enumerate() {
            columns.push((name, Column::State(i)));
        }
        columns.push(("mode".into(), Column::Mode));
        columns
    }

    fn cycle_columns(&self) -> Vec<String> {
        let mut header: Vec<String> = state_columns(self).collect();
        header.push("mode".into());
        header.push("sliding".into());
        header
    }

    fn mode_value(&self, mode: Mode) -> f64 {
        mode.index() as f64
    }

    fn mode_json(&self, mode: Mode) -> Value {
        json!(self.mode_name(mode))
    }
}

/// The columns of a model's states in the files: `state.<name>`.
fn state_columns(model: &Model) -> impl Iterator<Item = String> + '_ {
    model.states().iter().map(|s| format!("state.{}", s.name))
}
