//! How a model's linearisation about its orbit moves with its parameters, exactly: the
//! tangents that `htfid_theory::ExactHtf::derivatives` and `htfid_theory::OrbitHtf::derivatives`
//! turn into the exact derivatives of the HTFs, so that HTF fits of model files take an exact
//! Jacobian.
//!
//! A parameter `p` changes three things:
//!
//! - the matrices: `dA/dp = d(df/dx)/dp` with the state held (plus `A_x z` where `A` varies
//!   with the state), `d(df/du)/dp`, `d(dy/dx)/dp`, `d(dy/du)/dp`, second derivatives formed
//!   symbolically;
//! - when each switch happens: the orbit's own sensitivity `z = dx/dp` (periodic, from
//!   [`crate::forward`]) moves the crossing of guard `h` by
//!   `d tau = -(h_x z- + h_p) / (h_x f- + h_t)`;
//! - each switch's jump, the saltation matrix
//!   `S(t, x) = DR + (f+(t, R(t, x)) - DR f- - R_t) h_x^T / (h_x f- + h_t)`, written out as
//!   expressions and differentiated symbolically. It changes with `p` directly and through the
//!   crossing it is evaluated at, which moves in time by `d tau` and in state by
//!   `z- + f- d tau`: `dS = S_p + S_x (z- + f- d tau) + S_t d tau`.
//!
//! [`Model::piecewise_tangents`] gives these as tangents of the piecewise-LTI model, for a
//! model whose `A`, `B`, `C`, `D` are constant within each mode. For any model,
//! [`Model::orbit_tangents`] gives them along the orbit ([`OrbitTangents`]): the orbit's
//! sensitivity with its dynamics and jumps (those of [`crate::output_sensitivities`]),
//! `dA = A_p + A_x z` from the field's second derivatives (and the same for `B`, `C`, `D`), and
//! the saltation's change, for `htfid_theory::OrbitHtf::derivatives`.

use std::cell::RefCell;
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use htfid_expr::{Expr, Program};
use htfid_hybrid::{EventKind, HybridSystem, Options};
use htfid_ltp::{Linearisation, OrbitTangents, PiecewiseTangent};
use htfid_orbit::{transition_jump, LimitCycle};
use nalgebra::DMatrix;

use crate::forward::{periodic_sensitivity, periodic_start, Augmented, ForwardError};
use crate::model::{constant_in_mode, fold, Mode, Model};
use crate::ModelError;

/// A switch of the orbit must lie within this fraction of the period of the event that the
/// sensitivity's own integration finds for it: both locate the same crossing, to the event
/// tolerance.
const SAME_SWITCH: f64 = 1e-6;

impl Model {
    /// The tangents of the piecewise linearisation `lin` about `cycle` (of this model, its
    /// input off) along each of the parameters `names`: per piece the exact change of its
    /// matrices, of the jump that opens it and of the time it starts (module docs of
    /// `tangent.rs`). `Ok(None)` when the model's linearisation is not constant within each
    /// mode for every value of those parameters, when one of them sets the forcing's period,
    /// or when a guard or reset reads the input: the closed-form HTF then does not describe
    /// the model's neighbours.
    ///
    /// # Errors
    /// [`ForwardError`]: a name the model does not have, a failed or sliding integration of the
    /// orbit's sensitivity, a unit Floquet multiplier, or a switch of `lin` that the orbit's
    /// own integration does not find.
    pub fn piecewise_tangents(
        &self,
        names: &[&str],
        cycle: &LimitCycle<Mode>,
        lin: &Linearisation<Mode>,
        opts: &Options,
    ) -> Result<Option<Vec<PiecewiseTangent>>, ForwardError> {
        self.check_names(names)?;
        let sym = Symbolic::new(self, names);
        if sym.sets_period() || sym.crossings_read_input() || !sym.piecewise_constant() {
            return Ok(None);
        }
        let programs = self.tangent_cache().programs(&sym)?;
        let orbit = periodic_sensitivity(self, names, cycle, opts)?;
        let sens = self.parameter_sensitivity(names)?;
        let (n, k, period) = (self.dim(), names.len(), cycle.period);
        let piecewise = &lin.piecewise;
        let mut tangents = vec![PiecewiseTangent::zero(piecewise); k];

        // Each switch opens the piece of the same index (`htfid_ltp::linearise`).
        for (i, switch) in lin.switches.iter().enumerate() {
            let event = orbit
                .events
                .iter()
                .filter(|e| e.kind == EventKind::Transition)
                .min_by(|a, b| {
                    let apart = |t: f64| {
                        let d = (t - switch.time).rem_euclid(period);
                        d.min(period - d)
                    };
                    apart(a.time).total_cmp(&apart(b.time))
                })
                .filter(|e| {
                    let d = (e.time - switch.time).rem_euclid(period);
                    d.min(period - d) <= SAME_SWITCH * period && e.from == switch.from
                })
                .ok_or_else(|| {
                    ForwardError::Simulation(format!(
                        "the orbit's switch at t = {} s (from mode {}) is missing from its \
                         sensitivity's integration",
                        switch.time,
                        self.mode_name(switch.from)
                    ))
                })?;
            let (t, x) = (event.time, &event.state[..n]);
            let z = &event.state[n..];
            let u = self.input_value(t);
            let jump = transition_jump(self, event.from, event.guard, t, x);
            if !(jump.speed.is_finite() && jump.speed != 0.0) {
                return Err(ForwardError::Simulation(format!(
                    "the orbit grazes guard {} at t = {t} s: its switch does not move smoothly",
                    self.guard_name(event.from, event.guard)
                )));
            }
            let global = self.global_guard(event.from, event.guard);
            let mut h_p = vec![0.0; k];
            sens.guard(global, t, x, u, &mut h_p);
            let mut f_minus = vec![0.0; n];
            self.vector_field(event.from, t, x, &mut f_minus);
            let salt = programs
                .saltation
                .get(&(event.from.index(), global))
                .ok_or_else(|| {
                    ForwardError::Simulation(format!(
                        "internal: no saltation program for guard {global} left from mode {}",
                        self.mode_name(event.from)
                    ))
                })?;
            let mut ds = vec![0.0; salt.len()];
            salt.eval(&self.vars(t, x, u), &mut ds);
            for (j, tangent) in tangents.iter_mut().enumerate() {
                let moved = (0..n)
                    .map(|l| jump.guard_gradient[l] * z[l * k + j])
                    .sum::<f64>()
                    + h_p[j];
                let dtau = -moved / jump.speed;
                let dx: Vec<f64> = (0..n).map(|l| z[l * k + j] + f_minus[l] * dtau).collect();
                let piece = &mut tangent.pieces_mut()[i];
                piece.start = dtau;
                let mut dj = vec![0.0; n * n];
                total_change(&ds, n, k, j, &dx, dtau, &mut dj);
                piece.jump = DMatrix::from_row_slice(n, n, &dj);
            }
        }

        // The pieces' matrices: constant within each mode, read anywhere on the orbit.
        let p = self.outputs().len();
        let at = self.vars(cycle.t0, &cycle.state0, self.input_value(cycle.t0));
        let mut out_d = vec![0.0; programs.outputs.len()];
        programs.outputs.eval(&at, &mut out_d);
        for i in 0..piecewise.pieces().len() {
            let mode = lin.switches.get(i).map_or(cycle.mode0, |s| s.to);
            let mut flow_d = vec![0.0; programs.flows[mode.index()].len()];
            programs.flows[mode.index()].eval(&at, &mut flow_d);
            // Each entry's derivatives by the states (zero here), then by the parameters.
            let by = |d: &[f64], entry: usize, j: usize| d[entry * (n + k) + n + j];
            for (j, tangent) in tangents.iter_mut().enumerate() {
                let piece = &mut tangent.pieces_mut()[i];
                piece.a = DMatrix::from_fn(n, n, |r, c| by(&flow_d, r * n + c, j));
                piece.b = DMatrix::from_fn(n, 1, |r, _| by(&flow_d, n * n + r, j));
                piece.c = DMatrix::from_fn(p, n, |r, c| by(&out_d, r * n + c, j));
                piece.d = DMatrix::from_fn(p, 1, |r, _| by(&out_d, p * n + r, j));
            }
        }
        for tangent in &tangents {
            tangent
                .check(piecewise)
                .map_err(|e| ForwardError::Simulation(format!("internal: {e}")))?;
        }
        Ok(Some(tangents))
    }
}

/// The total change `e_p + e_x dx + e_t dt` along parameter `j` (of `k`) of each of `out`'s
/// entries (the saltation's `n x n`, row-major, or the input jump's `n`), from a crossing
/// program's values `ds` (per entry: by `t`, by each of the `n` states, by each parameter).
fn total_change(ds: &[f64], n: usize, k: usize, j: usize, dx: &[f64], dt: f64, out: &mut [f64]) {
    let stride = 1 + n + k;
    for (entry, v) in out.iter_mut().enumerate() {
        let d = &ds[entry * stride..(entry + 1) * stride];
        *v = d[1 + n + j] + d[0] * dt + (0..n).map(|l| d[1 + l] * dx[l]).sum::<f64>();
    }
}

impl Model {
    /// [`ModelError::Parameter`] for a name that is not one of the model's parameters.
    fn check_names(&self, names: &[&str]) -> Result<(), ModelError> {
        match names.iter().find(|n| self.parameter_index(n).is_none()) {
            Some(name) => Err(ModelError::Parameter {
                name: (*name).to_string(),
                message: "the model has no such parameter".into(),
            }),
            None => Ok(()),
        }
    }

    /// `[t, x, u, parameter values]`: the tangents' programs' variables.
    fn vars(&self, t: f64, x: &[f64], u: f64) -> Vec<f64> {
        let mut v = Vec::with_capacity(x.len() + 2 + self.values().len());
        self.fill_vars(t, x, u, &mut v);
        v
    }

    /// [`Model::vars`] into `v`.
    fn fill_vars(&self, t: f64, x: &[f64], u: f64, v: &mut Vec<f64>) {
        v.clear();
        v.push(t);
        v.extend_from_slice(x);
        v.push(u);
        v.extend_from_slice(self.values());
    }
}

/// The tangents' programs per set of parameters, compiled once for a model's definition: they
/// read the parameters' values as variables, so every model with other values (every trial of
/// a fit) shares them.
#[derive(Debug, Default)]
pub(crate) struct Cache(Mutex<HashMap<Vec<String>, Arc<Programs>>>);

impl Cache {
    fn programs(&self, sym: &Symbolic<'_>) -> Result<Arc<Programs>, ModelError> {
        let key: Vec<String> = sym.names.iter().map(|n| (*n).to_string()).collect();
        // A poisoned lock only means another thread panicked while compiling: compile anew.
        if let Some(found) = self.0.lock().ok().and_then(|m| m.get(&key).cloned()) {
            return Ok(found);
        }
        let programs = Arc::new(sym.programs()?);
        if let Ok(mut map) = self.0.lock() {
            map.insert(key, programs.clone());
        }
        Ok(programs)
    }
}

/// What [`Model::piecewise_tangents`] evaluates, for one set of parameters `p`.
#[derive(Debug)]
struct Programs {
    /// Per mode, per entry of `df/dx` (`n x n`) then of `df/du` (`n`): its derivatives by
    /// every state, then by each parameter (`n + k`).
    flows: Vec<Program>,
    /// The same for `dy/dx` (`p x n`) and `dy/du` (`p`).
    outputs: Program,
    /// Per (mode left, guard): the saltation matrix's entries' derivatives (row-major; per
    /// entry by `t`, by every state, by each parameter).
    saltation: HashMap<(usize, usize), Program>,
}

/// The model's expressions with the parameters `names` kept as symbols and every other one
/// folded in.
struct Symbolic<'a> {
    model: &'a Model,
    names: &'a [&'a str],
    /// `t`, the states, the input: the programs' variables.
    vars: Vec<&'a str>,
}

impl<'a> Symbolic<'a> {
    fn new(model: &'a Model, names: &'a [&'a str]) -> Self {
        let def = model.def();
        let vars = std::iter::once("t")
            .chain(def.states.iter().map(|s| s.name.as_str()))
            .chain(std::iter::once(def.input.as_str()))
            .collect();
        Symbolic { model, names, vars }
    }

    fn states(&self) -> &[&'a str] {
        &self.vars[1..self.vars.len() - 1]
    }

    fn input(&self) -> &'a str {
        self.vars[self.vars.len() - 1]
    }

    /// `e` with every parameter but `names` folded in as its value.
    fn partly_folded(&self, e: &Expr) -> Expr {
        let def = self.model.def();
        let (params, values): (Vec<_>, Vec<_>) = def
            .params
            .iter()
            .zip(self.model.values())
            .filter(|(p, _)| !self.names.contains(&p.name.as_str()))
            .map(|(p, v)| (p.clone(), *v))
            .unzip();
        fold(e, &params, &values)
    }

    /// Whether one of `names` sets the forcing's period (which the tangents hold fixed).
    fn sets_period(&self) -> bool {
        let def = self.model.def();
        def.period
            .as_ref()
            .is_some_and(|e| self.names.iter().any(|n| e.depends_on(n)))
    }

    /// Whether a guard or a reset reads the input: the linearised state then jumps by the
    /// input too, a term these tangents do not differentiate.
    fn crossings_read_input(&self) -> bool {
        let input = self.input();
        self.model.def().guards.iter().any(|g| {
            g.when.depends_on(input)
                || g.reset
                    .as_ref()
                    .is_some_and(|r| r.iter().any(|e| e.depends_on(input)))
        })
    }

    /// Whether `A`, `B` of every mode and `C`, `D` are free of time, state and input for
    /// every value of `names`.
    fn piecewise_constant(&self) -> bool {
        let def = self.model.def();
        let (states, input) = (self.states(), self.input());
        let linear = |e: &Expr| -> Vec<Expr> {
            let e = self.partly_folded(e);
            states
                .iter()
                .chain(std::iter::once(&input))
                .map(|s| e.derivative(s))
                .collect()
        };
        def.flows
            .iter()
            .flatten()
            .chain(def.outputs.iter().map(|o| &o.expr))
            .all(|e| constant_in_mode(&linear(e), states, input))
    }

    /// `exprs` compiled over `[t, x, u, parameters]`.
    fn compile(&self, exprs: &[Expr]) -> Result<Program, ModelError> {
        let def = self.model.def();
        let vars: Vec<&str> = self
            .vars
            .iter()
            .copied()
            .chain(def.params.iter().map(|p| p.name.as_str()))
            .collect();
        let simplified: Vec<Expr> = exprs.iter().map(Expr::simplify).collect();
        Program::compile(&simplified, &vars).map_err(|e| ModelError::Invalid {
            location: Default::default(),
            key: def.name.clone(),
            message: format!("internal: a derivative for the tangents failed to compile: {e}"),
        })
    }

    /// For every `e_i`, `d e_i / d x_l` for every `l` then `d e_i / du`, each differentiated
    /// by every state and then by each of `names`: entry-major, `n + k` per entry.
    fn linear_by_states_and_parameters(&self, exprs: &[Expr]) -> Vec<Expr> {
        let (states, input) = (self.states(), self.input());
        let by: Vec<&str> = states.iter().chain(self.names).copied().collect();
        let mut out = Vec::new();
        for e in exprs {
            for s in states {
                let d = e.derivative(s);
                out.extend(by.iter().map(|v| d.derivative(v)));
            }
        }
        for e in exprs {
            let d = e.derivative(input);
            out.extend(by.iter().map(|v| d.derivative(v)));
        }
        out
    }

    fn programs(&self) -> Result<Programs, ModelError> {
        let def = self.model.def();
        let flows = def
            .flows
            .iter()
            .map(|f| self.compile(&self.linear_by_states_and_parameters(f)))
            .collect::<Result<_, _>>()?;
        let outputs: Vec<Expr> = def.outputs.iter().map(|o| o.expr.clone()).collect();
        let mut saltation = HashMap::new();
        for (mode, guards) in def.guards_of.iter().enumerate() {
            for &guard in guards {
                saltation.insert((mode, guard), self.saltation_derivatives(mode, guard)?);
            }
        }
        Ok(Programs {
            flows,
            outputs: self.compile(&self.linear_by_states_and_parameters(&outputs))?,
            saltation,
        })
    }

    /// The saltation matrix of guard `guard` (its global index) left from mode `from` (its
    /// index), as
    /// expressions of `t`, the pre-crossing state, the input and the parameters, and for each
    /// entry (row-major) its derivatives by `t`, by every state and by each of `names`.
    fn saltation_derivatives(&self, from: usize, guard: usize) -> Result<Program, ModelError> {
        let def = self.model.def();
        let g = &def.guards[guard];
        let states = self.states();
        let n = states.len();
        // The reset, each state's own value where it names none.
        let reset: Vec<Expr> = match &g.reset {
            Some(r) => r.clone(),
            None => states.iter().map(|s| Expr::var(s)).collect(),
        };
        let f_minus = &def.flows[from];
        // `f+` at the reset state: rename the states first, so that one reset entry is not
        // substituted into another.
        let f_plus: Vec<Expr> = def.flows[g.to]
            .iter()
            .map(|f| {
                let renamed = states.iter().enumerate().fold(f.clone(), |e, (l, s)| {
                    e.substitute(s, &Expr::var(&format!("#reset{l}")))
                });
                reset
                    .iter()
                    .enumerate()
                    .fold(renamed, |e, (l, r)| e.substitute(&format!("#reset{l}"), r))
            })
            .collect();
        let dr = |a: usize, b: usize| reset[a].derivative(states[b]);
        let grad: Vec<Expr> = states.iter().map(|s| g.when.derivative(s)).collect();
        let speed = grad
            .iter()
            .zip(f_minus)
            .fold(g.when.derivative("t"), |acc, (h, f)| {
                acc.plus(h.clone().times(f.clone()))
            });
        let mut entries = Vec::with_capacity(n * n * (1 + n + self.names.len()));
        for a in 0..n {
            // `f+ - DR f- - R_t`, row a.
            let jump = (0..n).fold(
                f_plus[a].clone().minus(reset[a].derivative("t")),
                |acc, l| acc.minus(dr(a, l).times(f_minus[l].clone())),
            );
            for b in 0..n {
                let s = dr(a, b)
                    .plus(jump.clone().times(grad[b].clone()).over(speed.clone()))
                    .simplify();
                entries.push(s.derivative("t"));
                entries.extend(states.iter().map(|x| s.derivative(x)));
                entries.extend(self.names.iter().map(|p| s.derivative(p)));
            }
        }
        // Where the guard or the reset reads the input, the state's jump per unit input,
        // `R_u + jump h_u / speed`, row by row, after the saltation's entries.
        let input = self.input();
        let h_u = g.when.derivative(input);
        let r_u: Vec<Expr> = reset.iter().map(|r| r.derivative(input)).collect();
        let reads_input = std::iter::once(&h_u)
            .chain(&r_u)
            .any(|e| e.as_constant() != Some(0.0));
        if reads_input {
            for a in 0..n {
                let jump = (0..n).fold(
                    f_plus[a].clone().minus(reset[a].derivative("t")),
                    |acc, l| acc.minus(dr(a, l).times(f_minus[l].clone())),
                );
                let e = r_u[a]
                    .clone()
                    .plus(jump.times(h_u.clone()).over(speed.clone()))
                    .simplify();
                entries.push(e.derivative("t"));
                entries.extend(states.iter().map(|x| e.derivative(x)));
                entries.extend(self.names.iter().map(|p| e.derivative(p)));
            }
        }
        self.compile(&entries)
    }
}

/// The directions of change of a model's orbit and linearisation along some of its parameters
/// ([`OrbitTangents`]), for the derivatives of its HTFs along the orbit
/// (`htfid_theory::OrbitHtf::derivatives`): made by [`Model::orbit_tangents`].
pub struct ModelOrbitTangents<'a> {
    model: &'a Model,
    programs: Arc<Programs>,
    /// The orbit's sensitivity and its jumps.
    sensitivity: Augmented<'a>,
    start: Vec<f64>,
    n: usize,
    k: usize,
    buffers: RefCell<Buffers>,
}

/// Reused buffers of [`ModelOrbitTangents`]: the state with its sensitivities and their
/// rates, the programs' variables and values.
#[derive(Default)]
struct Buffers {
    augmented: Vec<f64>,
    vars: Vec<f64>,
    flow: Vec<f64>,
    outputs: Vec<f64>,
}

impl std::fmt::Debug for ModelOrbitTangents<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ModelOrbitTangents")
            .field("model", &self.model.name())
            .field("directions", &self.k)
            .field("start", &self.start)
            .finish_non_exhaustive()
    }
}

impl Model {
    /// The directions of change of this model's orbit `cycle` (its input off) and of its
    /// linearisation along the parameters `names`, exactly (module docs of `tangent.rs`): for
    /// `htfid_theory::OrbitHtf::derivatives`, the derivatives of HTFs whose linearisation
    /// varies along the orbit (and for guards or resets that read the input). `Ok(None)` when
    /// one of `names` sets the forcing's period.
    ///
    /// # Errors
    /// [`ForwardError`]: a name the model does not have, a failed or sliding integration of the
    /// orbit's sensitivity, a unit Floquet multiplier.
    pub fn orbit_tangents<'a>(
        &'a self,
        names: &[&str],
        cycle: &LimitCycle<Mode>,
        opts: &Options,
    ) -> Result<Option<ModelOrbitTangents<'a>>, ForwardError> {
        self.check_names(names)?;
        let sym = Symbolic::new(self, names);
        if sym.sets_period() {
            return Ok(None);
        }
        let programs = self.tangent_cache().programs(&sym)?;
        let start = periodic_start(self, names, cycle, opts)?;
        let sensitivity = Augmented::for_parameters(self, self.parameter_sensitivity(names)?);
        Ok(Some(ModelOrbitTangents {
            model: self,
            programs,
            sensitivity,
            start,
            n: self.dim(),
            k: names.len(),
            buffers: RefCell::new(Buffers::default()),
        }))
    }
}

impl OrbitTangents for ModelOrbitTangents<'_> {
    type Mode = Mode;

    fn directions(&self) -> usize {
        self.k
    }

    fn start(&self) -> &[f64] {
        &self.start
    }

    fn sensitivity_field(&self, mode: Mode, t: f64, x: &[f64], z: &[f64], dz: &mut [f64]) {
        let n = self.n;
        let mut guard = self.buffers.borrow_mut();
        let buf = &mut guard.augmented;
        buf.resize(2 * n * (1 + self.k), 0.0);
        let (state, out) = buf.split_at_mut(n * (1 + self.k));
        state[..n].copy_from_slice(x);
        state[n..].copy_from_slice(z);
        self.sensitivity.vector_field(mode, t, state, out);
        dz.copy_from_slice(&out[n..]);
    }

    fn sensitivity_jump(
        &self,
        mode: Mode,
        index: usize,
        t: f64,
        x_minus: &[f64],
        z: &mut [f64],
        dtau: &mut [f64],
    ) {
        let n = self.n;
        let mut state = Vec::with_capacity(n * (1 + self.k));
        state.extend_from_slice(x_minus);
        state.extend_from_slice(z);
        self.sensitivity.cross(mode, index, t, &mut state, dtau);
        z.copy_from_slice(&state[n..]);
    }

    fn linearisation_change(
        &self,
        mode: Mode,
        t: f64,
        x: &[f64],
        z: &[f64],
        da: &mut [f64],
        db: &mut [f64],
        dc: &mut [f64],
        dd: &mut [f64],
    ) {
        let (n, k) = (self.n, self.k);
        let mut guard = self.buffers.borrow_mut();
        let Buffers {
            vars,
            flow,
            outputs,
            ..
        } = &mut *guard;
        self.model.fill_vars(t, x, self.model.input_value(t), vars);
        let program = &self.programs.flows[mode.index()];
        flow.resize(program.len(), 0.0);
        program.eval(vars, flow);
        outputs.resize(self.programs.outputs.len(), 0.0);
        self.programs.outputs.eval(vars, outputs);
        // Per entry: its derivatives by the states, then by the parameters (`n + k`).
        let stride = n + k;
        let total = |d: &[f64], entry: usize, j: usize| {
            let e = &d[entry * stride..(entry + 1) * stride];
            e[n + j] + (0..n).map(|l| e[l] * z[l * k + j]).sum::<f64>()
        };
        let (na, pc) = (n * n, dc.len() / k.max(1));
        for j in 0..k {
            for e in 0..na {
                da[j * na + e] = total(flow, e, j);
            }
            for e in 0..n {
                db[j * n + e] = total(flow, na + e, j);
            }
            for e in 0..pc {
                dc[j * pc + e] = total(outputs, e, j);
            }
            let p = dd.len() / k.max(1);
            for e in 0..p {
                dd[j * p + e] = total(outputs, pc + e, j);
            }
        }
    }

    fn saltation_change(
        &self,
        mode: Mode,
        index: usize,
        t: f64,
        x_minus: &[f64],
        j: usize,
        dx: &[f64],
        dt: f64,
        ds: &mut [f64],
    ) {
        match self.crossing(mode, index, t, x_minus) {
            Some(values) => total_change(&values, self.n, self.k, j, dx, dt, ds),
            None => ds.iter_mut().for_each(|v| *v = f64::NAN),
        }
    }

    fn input_jump_change(
        &self,
        mode: Mode,
        index: usize,
        t: f64,
        x_minus: &[f64],
        j: usize,
        dx: &[f64],
        dt: f64,
        de: &mut [f64],
    ) -> bool {
        let (n, k) = (self.n, self.k);
        let stride = 1 + n + k;
        match self.crossing(mode, index, t, x_minus) {
            // The jump's rows follow the saltation's entries.
            Some(values) if values.len() == (n * n + n) * stride => {
                total_change(&values[n * n * stride..], n, k, j, dx, dt, de);
                true
            }
            _ => false,
        }
    }
}

impl ModelOrbitTangents<'_> {
    /// The crossing program's values (the saltation's entries, then the input jump's rows
    /// where the crossing reads the input) for guard `index` of `mode` at `(t, x_minus)`.
    fn crossing(&self, mode: Mode, index: usize, t: f64, x_minus: &[f64]) -> Option<Vec<f64>> {
        let global = self.model.global_guard(mode, index);
        let program = self.programs.saltation.get(&(mode.index(), global))?;
        let mut values = vec![0.0; program.len()];
        program.eval(
            &self.model.vars(t, x_minus, self.model.input_value(t)),
            &mut values,
        );
        Some(values)
    }
}
