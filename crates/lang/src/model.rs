//! The compiled model: one type for simulation, orbits, linearisation and fits.

use std::fmt;
use std::path::Path;
use std::sync::Arc;

use htfid_expr::{Expr, Program, Variables};
use htfid_hybrid::{Crossing, HybridSystem, Options};
use htfid_orbit::{find_limit_cycle, LimitCycle, ShootingOptions};

use crate::build::{build, ModelDef, Output, Parameter, State};
use crate::error::ModelError;
use crate::read::read;

/// A time-varying input `u(t)` (absolute time).
pub type InputFn = Arc<dyn Fn(f64) -> f64 + Send + Sync>;

/// A mode (chart) of a model: an index into [`Model::modes`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Mode(pub(crate) u32);

impl Mode {
    /// Its index into [`Model::modes`].
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// The programs of a model for one set of parameter values (parameters folded in as
/// constants). Every program reads the variables `[t, x_1..x_n, u]`.
#[derive(Debug)]
struct Compiled {
    /// Per mode: `f` (n values).
    flow: Vec<Program>,
    /// Per mode: `df/dx` (n x n row-major).
    jacobian: Vec<Program>,
    /// Per mode: `df/du` (n). Apart from the Jacobian, so that each is evaluated alone.
    input_gain: Vec<Program>,
    /// Per guard: `h`.
    guard: Vec<Program>,
    /// Per guard: `dh/dx` (n) then `dh/dt`.
    guard_linear: Vec<Program>,
    /// Per guard: the reset (n values) and its Jacobian (n x n) followed by its time
    /// derivative (n), or `None` for the identity.
    reset: Vec<Option<(Program, Program)>>,
    /// Per guard that reads the input (in `h` or its reset): `dh/du` then `dR/du` (n).
    crossing_input: Vec<Option<Program>>,
    /// Outputs (p values).
    output: Program,
    /// `dy/dx` (p x n row-major) then `dy/du` (p).
    output_linear: Program,
    period: Option<f64>,
    /// `A, B, C, D` are constant within every mode (no dependence on `t` or the state).
    piecewise_constant: bool,
}

/// A hybrid model written in the model language (or built in code), compiled for one set of
/// parameter values. Cheap to clone; [`Model::with_parameters`] recompiles.
#[derive(Clone)]
pub struct Model {
    def: Arc<ModelDef>,
    values: Vec<f64>,
    compiled: Arc<Compiled>,
    input: Option<InputFn>,
    /// The programs of the linearisation's tangents, per set of parameters, shared by every
    /// model with this definition (they read the parameters' values as variables).
    tangents: Arc<crate::tangent::Cache>,
}

impl fmt::Debug for Model {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Model")
            .field("name", &self.def.name)
            .field("states", &self.def.states)
            .field("modes", &self.def.modes)
            .field("parameters", &self.values)
            .field("input", &self.input.as_ref().map(|_| "<fn>"))
            .finish()
    }
}

/// Variables of every program: `[t, x..., u]`, written straight into its registers.
struct Vars<'a> {
    t: f64,
    x: &'a [f64],
    u: f64,
}

impl Variables for Vars<'_> {
    fn count(&self) -> usize {
        self.x.len() + 2
    }

    fn load(&self, regs: &mut [f64]) {
        // Element by element: for a handful of values a `memcpy` costs more than the copies.
        let values = std::iter::once(self.t)
            .chain(self.x.iter().copied())
            .chain(std::iter::once(self.u));
        for (r, v) in regs.iter_mut().zip(values) {
            *r = v;
        }
    }
}

fn with_vars<R>(t: f64, x: &[f64], u: f64, f: impl FnOnce(&Vars) -> R) -> R {
    f(&Vars { t, x, u })
}

/// Evaluates a program with more outputs than the caller wants, into a stack buffer.
fn with_outputs<R>(p: &Program, vars: &Vars, f: impl FnOnce(&[f64]) -> R) -> R {
    const STACK_OUT: usize = 256;
    if p.len() <= STACK_OUT {
        let mut buf = [0.0; STACK_OUT];
        p.eval(vars, &mut buf[..p.len()]);
        f(&buf[..p.len()])
    } else {
        let mut buf = vec![0.0; p.len()];
        p.eval(vars, &mut buf);
        f(&buf)
    }
}

pub(crate) fn fold(e: &Expr, params: &[Parameter], values: &[f64]) -> Expr {
    let mut out = e.clone();
    for (p, &v) in params.iter().zip(values) {
        if out.depends_on(&p.name) {
            out = out.substitute(&p.name, &Expr::constant(v));
        }
    }
    out.simplify()
}

pub(crate) fn constant_in_mode(exprs: &[Expr], vars: &[&str], input: &str) -> bool {
    // Constant within a mode: no time, no state; an input term is linear-affine and its
    // derivative no longer depends on it only if it does not appear.
    exprs.iter().all(|e| {
        !e.depends_on("t") && !e.depends_on(input) && vars.iter().all(|v| !e.depends_on(v))
    })
}

impl Compiled {
    fn new(def: &ModelDef, values: &[f64]) -> Result<Compiled, ModelError> {
        let n = def.states.len();
        let names: Vec<&str> = std::iter::once("t")
            .chain(def.states.iter().map(|s| s.name.as_str()))
            .chain(std::iter::once(def.input.as_str()))
            .collect();
        let state_names: Vec<&str> = def.states.iter().map(|s| s.name.as_str()).collect();
        let p = &def.params;
        let compile = |exprs: &[Expr]| -> Result<Program, ModelError> {
            Program::compile(exprs, &names).map_err(|e| ModelError::Invalid {
                location: Default::default(),
                key: def.name.clone(),
                message: format!("internal: a resolved expression failed to compile: {e}"),
            })
        };
        let mut piecewise_constant = true;
        let (mut flow, mut jacobian, mut input_gain) = (Vec::new(), Vec::new(), Vec::new());
        for f in &def.flows {
            let folded: Vec<Expr> = f.iter().map(|e| fold(e, p, values)).collect();
            let mut jac = Vec::with_capacity(n * n);
            for fi in &folded {
                for s in &state_names {
                    jac.push(fi.derivative(s));
                }
            }
            let gain: Vec<Expr> = folded.iter().map(|fi| fi.derivative(&def.input)).collect();
            piecewise_constant &= constant_in_mode(&jac, &state_names, &def.input)
                && constant_in_mode(&gain, &state_names, &def.input);
            flow.push(compile(&folded)?);
            jacobian.push(compile(&jac)?);
            input_gain.push(compile(&gain)?);
        }
        let (mut guard, mut guard_linear, mut reset) = (Vec::new(), Vec::new(), Vec::new());
        let mut crossing_input = Vec::new();
        for g in &def.guards {
            let h = fold(&g.when, p, values);
            let reset_exprs: Vec<Expr> = match &g.reset {
                Some(r) => r.iter().map(|e| fold(e, p, values)).collect(),
                None => state_names.iter().map(|s| Expr::var(s)).collect(),
            };
            let by_input: Vec<Expr> = std::iter::once(&h)
                .chain(&reset_exprs)
                .map(|e| e.derivative(&def.input))
                .collect();
            crossing_input.push(if by_input.iter().all(|e| e.as_constant() == Some(0.0)) {
                None
            } else {
                piecewise_constant = false;
                Some(compile(&by_input)?)
            });
            let mut lin: Vec<Expr> = state_names.iter().map(|s| h.derivative(s)).collect();
            lin.push(h.derivative("t"));
            guard.push(compile(std::slice::from_ref(&h))?);
            guard_linear.push(compile(&lin)?);
            reset.push(match &g.reset {
                None => None,
                Some(r) => {
                    let folded: Vec<Expr> = r.iter().map(|e| fold(e, p, values)).collect();
                    let mut jac = Vec::with_capacity(n * n);
                    for ri in &folded {
                        for s in &state_names {
                            jac.push(ri.derivative(s));
                        }
                    }
                    for ri in &folded {
                        jac.push(ri.derivative("t"));
                    }
                    Some((compile(&folded)?, compile(&jac)?))
                }
            });
        }
        let outs: Vec<Expr> = def
            .outputs
            .iter()
            .map(|o| fold(&o.expr, p, values))
            .collect();
        let mut olin = Vec::with_capacity(outs.len() * (n + 1));
        for o in &outs {
            for s in &state_names {
                olin.push(o.derivative(s));
            }
        }
        for o in &outs {
            olin.push(o.derivative(&def.input));
        }
        piecewise_constant &= constant_in_mode(&olin, &state_names, &def.input);
        let period = match &def.period {
            Some(e) => {
                let v = fold(e, p, values).as_constant().unwrap_or(f64::NAN);
                if !(v.is_finite() && v > 0.0) {
                    return Err(ModelError::Invalid {
                        location: Default::default(),
                        key: "forcing.period".into(),
                        message: format!("must be > 0 and finite (got {v})"),
                    });
                }
                Some(v)
            }
            None => None,
        };
        Ok(Compiled {
            flow,
            jacobian,
            input_gain,
            guard,
            guard_linear,
            reset,
            crossing_input,
            output: compile(&outs)?,
            output_linear: compile(&olin)?,
            period,
            piecewise_constant,
        })
    }
}

impl Model {
    /// Reads a model file (its whole document is the model).
    pub fn from_file(path: &Path) -> Result<Model, ModelError> {
        let text = std::fs::read_to_string(path).map_err(|e| ModelError::Io {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        Model::from_document(&text, Some(path), &[])
    }

    /// Reads a model from TOML text (the whole document is the model).
    pub fn parse(text: &str) -> Result<Model, ModelError> {
        Model::from_document(text, None, &[])
    }

    /// Reads the model held in the table at `table_path` of a TOML document (for example
    /// `["model"]` for a model written inline in an experiment config). `path` only labels
    /// error messages.
    pub fn from_document(
        text: &str,
        path: Option<&Path>,
        table_path: &[&str],
    ) -> Result<Model, ModelError> {
        let (spec, src) = read(text, path, table_path)?;
        let def = build(&spec, &src)?;
        let values: Vec<f64> = def.params.iter().map(|p| p.value).collect();
        let compiled = Compiled::new(&def, &values)?;
        let model = Model {
            def: Arc::new(def),
            values,
            compiled: Arc::new(compiled),
            input: None,
            tangents: Arc::default(),
        };
        model.check_signals_periodic(&src)?;
        Ok(model)
    }

    fn check_signals_periodic(&self, src: &crate::read::Source) -> Result<(), ModelError> {
        let Some(period) = self.compiled.period else {
            return Ok(());
        };
        for (name, e, at) in &self.def.signals {
            let folded = fold(e, &self.def.params, &self.values);
            let program = Program::compile(std::slice::from_ref(&folded), &["t"])
                .map_err(|e| src.invalid(*at, &format!("forcing.signals.{name}"), e.to_string()))?;
            for i in 0..7 {
                let t = period * (0.137 + 0.711 * i as f64);
                let (a, b) = (
                    program.eval_one(0, &[t]),
                    program.eval_one(0, &[t + period]),
                );
                if (a - b).abs() > 1e-9 * (1.0 + a.abs().max(b.abs())) {
                    return Err(src.invalid(
                        *at,
                        &format!("forcing.signals.{name}"),
                        format!(
                            "is not periodic with the forcing period {period}: \
                             {name}({t:.4}) = {a:.6e} but {name}({:.4}) = {b:.6e}",
                            t + period
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// A model from a resolved definition and its parameter values.
    pub(crate) fn from_def(
        def: ModelDef,
        values: Vec<f64>,
        input: Option<InputFn>,
    ) -> Result<Model, ModelError> {
        let compiled = Compiled::new(&def, &values)?;
        Ok(Model {
            def: Arc::new(def),
            values,
            compiled: Arc::new(compiled),
            input,
            tangents: Arc::default(),
        })
    }

    /// The input function, when one drives the model.
    pub(crate) fn input_fn(&self) -> Option<&InputFn> {
        self.input.as_ref()
    }

    /// The resolved definition.
    pub(crate) fn def(&self) -> &ModelDef {
        &self.def
    }

    pub(crate) fn tangent_cache(&self) -> &crate::tangent::Cache {
        &self.tangents
    }

    /// The model's name.
    pub fn name(&self) -> &str {
        &self.def.name
    }

    /// Its description, when given.
    pub fn description(&self) -> Option<&str> {
        self.def.description.as_deref()
    }

    /// The states, in order.
    pub fn states(&self) -> &[State] {
        &self.def.states
    }

    /// The parameters as declared (their declared values; see [`Model::values`]).
    pub fn parameters(&self) -> &[Parameter] {
        &self.def.params
    }

    /// The current parameter values, in the order of [`Model::parameters`].
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// The index of parameter `name`.
    pub fn parameter_index(&self, name: &str) -> Option<usize> {
        self.def.params.iter().position(|p| p.name == name)
    }

    /// The declared unit of parameter `name`, if it has one.
    pub fn parameter_unit(&self, name: &str) -> Option<&str> {
        let i = self.parameter_index(name)?;
        self.def.params[i].unit.as_deref()
    }

    /// The current value of parameter `name`.
    pub fn parameter(&self, name: &str) -> Option<f64> {
        self.parameter_index(name).map(|i| self.values[i])
    }

    /// The same model with some parameters changed (checked against their bounds) and
    /// recompiled.
    pub fn with_parameters(&self, changes: &[(&str, f64)]) -> Result<Model, ModelError> {
        let mut values = self.values.clone();
        for &(name, v) in changes {
            let Some(i) = self.parameter_index(name) else {
                let names: Vec<&str> = self.def.params.iter().map(|p| p.name.as_str()).collect();
                return Err(ModelError::Parameter {
                    name: name.to_string(),
                    message: format!(
                        "the model has no such parameter{}; parameters: {}",
                        crate::read::suggestion(name, names.iter().copied()),
                        names.join(", ")
                    ),
                });
            };
            values[i] = v;
        }
        self.with_values(&values)
    }

    /// The same model with all parameter values replaced (in the order of
    /// [`Model::parameters`]), checked against their bounds.
    pub fn with_values(&self, values: &[f64]) -> Result<Model, ModelError> {
        if values.len() != self.def.params.len() {
            return Err(ModelError::Parameter {
                name: "*".into(),
                message: format!(
                    "expected {} values, got {}",
                    self.def.params.len(),
                    values.len()
                ),
            });
        }
        for (p, &v) in self.def.params.iter().zip(values) {
            if !v.is_finite() || v < p.min || v > p.max {
                return Err(ModelError::Parameter {
                    name: p.name.clone(),
                    message: format!(
                        "value {v} is outside its bounds [{}, {}] or not finite",
                        p.min, p.max
                    ),
                });
            }
        }
        let compiled = Compiled::new(&self.def, values)?;
        Ok(Model {
            def: self.def.clone(),
            values: values.to_vec(),
            compiled: Arc::new(compiled),
            input: self.input.clone(),
            tangents: self.tangents.clone(),
        })
    }

    /// The same model driven by `u(t)` (`None`: no input).
    pub fn with_input(&self, input: Option<InputFn>) -> Model {
        Model {
            input,
            ..self.clone()
        }
    }

    /// The input's name in expressions (`u` unless declared otherwise).
    pub fn input_name(&self) -> &str {
        &self.def.input
    }

    /// The input's unit, when declared.
    pub fn input_unit(&self) -> Option<&str> {
        self.def.input_unit.as_deref()
    }

    /// The mode names; [`Mode::index`] indexes this list.
    pub fn modes(&self) -> &[String] {
        &self.def.modes
    }

    /// The mode named `name`.
    pub fn mode(&self, name: &str) -> Option<Mode> {
        self.def
            .modes
            .iter()
            .position(|m| m == name)
            .map(|i| Mode(i as u32))
    }

    /// Whether `x` at `t` lies on the side of every guard of `mode` from which that guard can
    /// fire: a guard that fires falling is not below zero, one that fires rising not above.
    /// A state past one of its mode's guards would run that mode's field where the model
    /// never does.
    pub fn admits(&self, mode: Mode, t: f64, x: &[f64]) -> bool {
        (0..self.num_guards(mode)).all(|g| {
            let h = self.guard(mode, g, t, x);
            match self.guard_direction(mode, g) {
                Crossing::Falling => h >= 0.0,
                Crossing::Rising => h <= 0.0,
                Crossing::Either => true,
            }
        })
    }

    /// The mode a simulation of a given state starts in: `preferred` when it
    /// [admits](Model::admits) the state, else the first mode that does (a fitted initial
    /// state that moved across a switching surface starts on its far side), else `preferred`.
    pub fn start_mode(&self, preferred: Mode, t: f64, x: &[f64]) -> Mode {
        if self.admits(preferred, t, x) {
            return preferred;
        }
        (0..self.def.modes.len())
            .map(|i| Mode(i as u32))
            .find(|&m| self.admits(m, t, x))
            .unwrap_or(preferred)
    }

    /// The name of a mode.
    pub fn mode_name(&self, mode: Mode) -> &str {
        &self.def.modes[mode.index()]
    }

    /// The guards' names, in declaration order.
    pub fn guard_names(&self) -> Vec<&str> {
        self.def.guards.iter().map(|g| g.name.as_str()).collect()
    }

    /// The name of guard `index` of `mode` (the index the integrator reports in events).
    pub fn guard_name(&self, mode: Mode, index: usize) -> &str {
        &self.def.guards[self.def.guards_of[mode.index()][index]].name
    }

    /// The equation of state `state` (its index) in `mode`, as resolved: definitions and
    /// forcing signals inlined, parameters by name.
    pub fn equation(&self, mode: Mode, state: usize) -> &Expr {
        &self.def.flows[mode.index()][state]
    }

    /// The expression of guard `index` (in the order of [`Model::guard_names`]), as resolved.
    pub fn guard_expr(&self, index: usize) -> &Expr {
        &self.def.guards[index].when
    }

    /// The value of guard `index` (in the order of [`Model::guard_names`]) at `(t, x, u)`.
    pub fn guard_value(&self, index: usize, t: f64, x: &[f64], u: f64) -> f64 {
        with_vars(t, x, u, |v| self.compiled.guard[index].eval_one(0, v))
    }

    /// The outputs.
    pub fn outputs(&self) -> &[Output] {
        &self.def.outputs
    }

    /// The forcing period, when the model declares `[forcing]`.
    pub fn period(&self) -> Option<f64> {
        self.compiled.period
    }

    /// The starting mode for orbit searches (`[initial] mode`, else the first mode).
    pub fn initial_mode(&self) -> Mode {
        Mode(self.def.initial_mode as u32)
    }

    /// The starting state for orbit searches (`[initial]`, zeros elsewhere).
    pub fn initial_state(&self) -> &[f64] {
        &self.def.initial_state
    }

    /// Whether the linearisation `A, B, C, D` is constant within every mode, so that the
    /// exact piecewise-LTI HTF applies (the hopper); otherwise the general periodic-response
    /// HTF is needed.
    pub fn is_piecewise_constant(&self) -> bool {
        self.compiled.piecewise_constant
    }

    fn u(&self, t: f64) -> f64 {
        self.input.as_ref().map_or(0.0, |u| u(t))
    }

    /// The input's value at `t`: the input function's, or 0 without one.
    pub fn input_value(&self, t: f64) -> f64 {
        self.u(t)
    }

    /// The vector field of `mode` and its state Jacobian at `(t, x)` with input value `u`
    /// (read once by the caller), into `dxdt` (n) and `jac` (`n x n` row-major): the forward
    /// sensitivities need both at every stage.
    pub(crate) fn field_and_jacobian(
        &self,
        mode: Mode,
        t: f64,
        x: &[f64],
        u: f64,
        dxdt: &mut [f64],
        jac: &mut [f64],
    ) {
        let n = x.len();
        with_vars(t, x, u, |v| {
            self.compiled.flow[mode.index()].eval(v, dxdt);
            self.compiled.jacobian[mode.index()].eval(v, &mut jac[..n * n]);
        });
    }

    /// The outputs' Jacobian `dy/dx` at `(t, x)` with input value `u`, into `c` (`p x n`
    /// row-major).
    pub fn output_state_jacobian(&self, t: f64, x: &[f64], u: f64, c: &mut [f64]) {
        let (n, p) = (x.len(), self.def.outputs.len());
        with_vars(t, x, u, |v| {
            with_outputs(&self.compiled.output_linear, v, |out| {
                c[..p * n].copy_from_slice(&out[..p * n]);
            })
        });
    }

    /// The index among all the model's guards (in the order it declares them) of guard
    /// `index` of `mode`.
    pub(crate) fn global_guard(&self, mode: Mode, index: usize) -> usize {
        self.def.guards_of[mode.index()][index]
    }

    /// The outputs `y` at `(mode, t, x)` with input value `u`, into `y` (length p).
    pub fn eval_outputs(&self, _mode: Mode, t: f64, x: &[f64], u: f64, y: &mut [f64]) {
        with_vars(t, x, u, |v| self.compiled.output.eval(v, y));
    }

    /// Settles onto the forced periodic orbit with the input off and refines it by Newton
    /// shooting, starting from [`Model::initial_state`] in [`Model::initial_mode`].
    pub fn limit_cycle(
        &self,
        shooting: &ShootingOptions,
        opts: &Options,
    ) -> Result<LimitCycle<Mode>, ModelError> {
        self.limit_cycle_from(self.initial_mode(), self.initial_state(), shooting, opts)
    }

    /// As [`Model::limit_cycle`] from a given mode and state (for example a nearby orbit).
    pub fn limit_cycle_from(
        &self,
        mode: Mode,
        x0: &[f64],
        shooting: &ShootingOptions,
        opts: &Options,
    ) -> Result<LimitCycle<Mode>, ModelError> {
        let period = self.period().ok_or(ModelError::NoPeriod)?;
        let unforced = self.with_input(None);
        Ok(find_limit_cycle(
            &unforced, mode, 0.0, x0, period, shooting, opts,
        )?)
    }
}

impl HybridSystem for Model {
    type Mode = Mode;

    fn dim(&self) -> usize {
        self.def.states.len()
    }

    fn vector_field(&self, mode: Mode, t: f64, x: &[f64], dxdt: &mut [f64]) {
        let u = self.u(t);
        with_vars(t, x, u, |v| self.compiled.flow[mode.index()].eval(v, dxdt));
    }

    fn num_guards(&self, mode: Mode) -> usize {
        self.def.guards_of[mode.index()].len()
    }

    fn guard(&self, mode: Mode, index: usize, t: f64, x: &[f64]) -> f64 {
        let g = self.def.guards_of[mode.index()][index];
        let u = self.u(t);
        with_vars(t, x, u, |v| self.compiled.guard[g].eval_one(0, v))
    }

    fn guard_direction(&self, mode: Mode, index: usize) -> Crossing {
        self.def.guards[self.def.guards_of[mode.index()][index]].direction
    }

    fn transition(&self, mode: Mode, index: usize, t: f64, x: &mut [f64]) -> Mode {
        let g = self.def.guards_of[mode.index()][index];
        if let Some((reset, _)) = &self.compiled.reset[g] {
            let u = self.u(t);
            let n = x.len();
            // The new state on the stack for small models.
            const STACK_STATES: usize = 32;
            let mut out = [0.0; STACK_STATES];
            if n <= STACK_STATES {
                with_vars(t, x, u, |v| reset.eval(v, &mut out[..n]));
                x.copy_from_slice(&out[..n]);
            } else {
                let mut out = vec![0.0; n];
                with_vars(t, x, u, |v| reset.eval(v, &mut out));
                x.copy_from_slice(&out);
            }
        }
        Mode(self.def.guards[g].to as u32)
    }

    /// A guard is a switching surface, along which the motion may slide, when it leads to
    /// another mode without a reset and that mode has a guard back, also without a reset, on
    /// the same expression: the state is then continuous across one surface and only the flow
    /// changes (Coulomb friction written as two modes, say). Guards with a reset (impacts) and
    /// pairs on different surfaces (hysteresis, touchdown and liftoff) are not.
    fn sliding_chart(&self, mode: Mode, index: usize) -> Option<Mode> {
        let def = &self.def;
        let guard = &def.guards[*def.guards_of[mode.index()].get(index)?];
        if guard.reset.is_some() || guard.to == mode.index() {
            return None;
        }
        def.guards_of[guard.to]
            .iter()
            .map(|&back| &def.guards[back])
            .any(|back| back.to == mode.index() && back.reset.is_none() && back.when == guard.when)
            .then_some(Mode(guard.to as u32))
    }

    fn jacobian(&self, mode: Mode, t: f64, x: &[f64], jac: &mut [f64]) -> bool {
        let n = x.len();
        let u = self.u(t);
        with_vars(t, x, u, |v| {
            self.compiled.jacobian[mode.index()].eval(v, &mut jac[..n * n])
        });
        true
    }

    fn guard_gradient(
        &self,
        mode: Mode,
        index: usize,
        t: f64,
        x: &[f64],
        grad: &mut [f64],
    ) -> bool {
        let g = self.def.guards_of[mode.index()][index];
        let n = x.len();
        let u = self.u(t);
        with_vars(t, x, u, |v| {
            with_outputs(&self.compiled.guard_linear[g], v, |out| {
                grad.copy_from_slice(&out[..n]);
            })
        });
        true
    }

    fn guard_time_derivative(&self, mode: Mode, index: usize, t: f64, x: &[f64]) -> Option<f64> {
        let g = self.def.guards_of[mode.index()][index];
        let n = x.len();
        let u = self.u(t);
        Some(with_vars(t, x, u, |v| {
            self.compiled.guard_linear[g].eval_one(n, v)
        }))
    }

    fn reset_jacobian(&self, mode: Mode, index: usize, t: f64, x: &[f64], jac: &mut [f64]) -> bool {
        let g = self.def.guards_of[mode.index()][index];
        let n = x.len();
        match &self.compiled.reset[g] {
            None => {
                jac.iter_mut().for_each(|v| *v = 0.0);
                for i in 0..n {
                    jac[i * n + i] = 1.0;
                }
            }
            Some((_, rj)) => {
                let u = self.u(t);
                with_vars(t, x, u, |v| {
                    with_outputs(rj, v, |out| jac.copy_from_slice(&out[..n * n]))
                });
            }
        }
        true
    }

    fn reset_time_derivative(
        &self,
        mode: Mode,
        index: usize,
        t: f64,
        x: &[f64],
        out: &mut [f64],
    ) -> bool {
        let g = self.def.guards_of[mode.index()][index];
        let n = x.len();
        match &self.compiled.reset[g] {
            None => out.iter_mut().for_each(|v| *v = 0.0),
            Some((_, rj)) => {
                let u = self.u(t);
                with_vars(t, x, u, |v| {
                    with_outputs(rj, v, |all| out.copy_from_slice(&all[n * n..n * n + n]))
                });
            }
        }
        true
    }
}

impl htfid_ltp::InputOutput for Model {
    fn is_piecewise_constant(&self) -> bool {
        self.compiled.piecewise_constant
    }

    fn input_gain(&self, mode: Mode, t: f64, x: &[f64], b: &mut [f64]) {
        let n = x.len();
        with_vars(t, x, 0.0, |v| {
            self.compiled.input_gain[mode.index()].eval(v, &mut b[..n])
        });
    }

    fn num_outputs(&self) -> usize {
        self.def.outputs.len()
    }

    fn crossing_input(
        &self,
        mode: Mode,
        index: usize,
        t: f64,
        x: &[f64],
        h_u: &mut f64,
        r_u: &mut [f64],
    ) -> bool {
        let g = self.def.guards_of[mode.index()][index];
        let Some(program) = &self.compiled.crossing_input[g] else {
            return false;
        };
        let n = x.len();
        with_vars(t, x, 0.0, |v| {
            with_outputs(program, v, |out| {
                *h_u = out[0];
                r_u.copy_from_slice(&out[1..=n]);
            })
        });
        true
    }

    fn output_gain(&self, _mode: Mode, t: f64, x: &[f64], c: &mut [f64]) {
        let (n, p) = (x.len(), self.def.outputs.len());
        with_vars(t, x, 0.0, |v| {
            with_outputs(&self.compiled.output_linear, v, |out| {
                c.copy_from_slice(&out[..p * n]);
            })
        });
    }

    fn feedthrough(&self, _mode: Mode, t: f64, x: &[f64], d: &mut [f64]) {
        let (n, p) = (x.len(), self.def.outputs.len());
        with_vars(t, x, 0.0, |v| {
            with_outputs(&self.compiled.output_linear, v, |out| {
                d.copy_from_slice(&out[p * n..p * n + p]);
            })
        });
    }
}

/// Exact derivatives of a model with respect to some of its parameters, at the model's
/// current values: `df/dp` per mode, `dh/dp` per guard, `dR/dp` per reset, `dy/dp` of the
/// outputs. Symbolic, like every derivative of the model language; for the forward
/// sensitivity equations of output-error fits (`dx/dp' = A dx/dp + df/dp`, with the
/// saltation's parameter terms at the guards).
#[derive(Debug, Clone)]
pub struct ParameterSensitivity {
    params: Vec<String>,
    n: usize,
    /// Per mode: `df/dp`, `n x k` row-major.
    flow: Vec<Program>,
    /// Per guard: `dh/dp` (k).
    guard: Vec<Program>,
    /// Per guard: `dR/dp` (`n x k`), `None` for the identity reset.
    reset: Vec<Option<Program>>,
    /// `dy/dp`, `p x k`.
    output: Program,
}

impl Model {
    /// The exact parameter derivatives for `params` (names of this model's parameters).
    ///
    /// # Errors
    /// [`ModelError::Parameter`] for a name the model does not have.
    pub fn parameter_sensitivity(
        &self,
        params: &[&str],
    ) -> Result<ParameterSensitivity, ModelError> {
        for name in params {
            if self.parameter_index(name).is_none() {
                return Err(ModelError::Parameter {
                    name: (*name).to_string(),
                    message: "the model has no such parameter".into(),
                });
            }
        }
        self.derivatives_by(params)
    }

    /// The exact derivatives by the input, in the shape of [`Model::parameter_sensitivity`]
    /// with one column: `df/du` per mode, `dh/du` per guard, `dR/du` per reset, `dy/du` of the
    /// outputs. For the sensitivities to a change of the input itself (its offset, delay or
    /// lag), which enter as `df/du` times the change.
    ///
    /// # Errors
    /// [`ModelError::Invalid`] should a derivative fail to compile (internal).
    pub fn input_sensitivity(&self) -> Result<ParameterSensitivity, ModelError> {
        let input = self.def.input.clone();
        self.derivatives_by(&[input.as_str()])
    }

    /// The derivatives of every flow, guard, reset and output by the variables `by`
    /// (parameters or the input), compiled.
    fn derivatives_by(&self, params: &[&str]) -> Result<ParameterSensitivity, ModelError> {
        let def = &self.def;
        let names: Vec<&str> = std::iter::once("t")
            .chain(def.states.iter().map(|s| s.name.as_str()))
            .chain(std::iter::once(def.input.as_str()))
            .collect();
        let compile = |exprs: Vec<Expr>| -> Result<Program, ModelError> {
            let folded: Vec<Expr> = exprs
                .iter()
                .map(|e| fold(e, &def.params, &self.values))
                .collect();
            Program::compile(&folded, &names).map_err(|e| ModelError::Invalid {
                location: Default::default(),
                key: def.name.clone(),
                message: format!("internal: a parameter derivative failed to compile: {e}"),
            })
        };
        let jac = |exprs: &[Expr]| -> Vec<Expr> {
            exprs
                .iter()
                .flat_map(|e| params.iter().map(move |p| e.derivative(p)))
                .collect()
        };
        let flow = def
            .flows
            .iter()
            .map(|f| compile(jac(f)))
            .collect::<Result<Vec<_>, _>>()?;
        let guard = def
            .guards
            .iter()
            .map(|g| compile(jac(std::slice::from_ref(&g.when))))
            .collect::<Result<Vec<_>, _>>()?;
        let reset = def
            .guards
            .iter()
            .map(|g| g.reset.as_ref().map(|r| compile(jac(r))).transpose())
            .collect::<Result<Vec<_>, _>>()?;
        let outputs: Vec<Expr> = def.outputs.iter().map(|o| o.expr.clone()).collect();
        let output = compile(jac(&outputs))?;
        Ok(ParameterSensitivity {
            params: params.iter().map(|p| (*p).to_string()).collect(),
            n: def.states.len(),
            flow,
            guard,
            reset,
            output,
        })
    }
}

impl ParameterSensitivity {
    /// The parameters, in the order of every column.
    pub fn parameters(&self) -> &[String] {
        &self.params
    }

    /// `df/dp` of `mode` at `(t, x, u)`, into `out` (`n x k` row-major).
    pub fn flow(&self, mode: Mode, t: f64, x: &[f64], u: f64, out: &mut [f64]) {
        with_vars(t, x, u, |v| self.flow[mode.index()].eval(v, out));
    }

    /// `dh/dp` of guard `index` (in the order the model declares its guards) at `(t, x, u)`,
    /// into `out` (k).
    pub fn guard(&self, index: usize, t: f64, x: &[f64], u: f64, out: &mut [f64]) {
        with_vars(t, x, u, |v| self.guard[index].eval(v, out));
    }

    /// `dR/dp` of the reset of guard `index` at `(t, x, u)`, into `out` (`n x k`); zeros for
    /// the identity reset.
    pub fn reset(&self, index: usize, t: f64, x: &[f64], u: f64, out: &mut [f64]) {
        match &self.reset[index] {
            Some(p) => with_vars(t, x, u, |v| p.eval(v, out)),
            None => out[..self.n * self.params.len()]
                .iter_mut()
                .for_each(|v| *v = 0.0),
        }
    }

    /// `dy/dp` of the outputs at `(t, x, u)`, into `out` (`p x k`).
    pub fn output(&self, t: f64, x: &[f64], u: f64, out: &mut [f64]) {
        with_vars(t, x, u, |v| self.output.eval(v, out));
    }
}
