//! How a model's piecewise linearisation moves with its parameters, exactly: the tangents
//! ([`PiecewiseTangent`]) that `htfid_theory::ExactHtf::derivatives` turns into the exact
//! derivatives of the HTFs, so that HTF fits of model files take an exact Jacobian.
//!
//! For a model whose `A`, `B`, `C`, `D` are constant within each mode (for every value of the
//! parameters asked about), a parameter `p` changes three things:
//!
//! - each piece's matrices: `dA/dp = d(df/dx)/dp`, `d(df/du)/dp`, `d(dy/dx)/dp`,
//!   `d(dy/du)/dp`, second derivatives formed symbolically;
//! - when each switch happens: the orbit's own sensitivity `z = dx/dp` (periodic, from
//!   [`crate::forward`]) moves the crossing of guard `h` by
//!   `d tau = -(h_x z- + h_p) / (h_x f- + h_t)`;
//! - each switch's jump, the saltation matrix
//!   `S(t, x) = DR + (f+(t, R(t, x)) - DR f- - R_t) h_x^T / (h_x f- + h_t)`, written out as
//!   expressions and differentiated symbolically. It changes with `p` directly and through the
//!   crossing it is evaluated at, which moves in time by `d tau` and in state by
//!   `z- + f- d tau`: `dS = S_p + S_x (z- + f- d tau) + S_t d tau`.
//!
//! Models whose linearisation varies within a mode take their HTFs along the orbit
//! (`htfid_theory::OrbitHtf`); this module gives them no tangents.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use htfid_expr::{Expr, Program};
use htfid_hybrid::{EventKind, HybridSystem, Options};
use htfid_ltp::{Linearisation, PiecewiseTangent};
use htfid_orbit::{transition_jump, LimitCycle};
use nalgebra::DMatrix;

use crate::forward::{periodic_sensitivity, ForwardError};
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
    /// mode for every value of those parameters, or when one of them sets the forcing's
    /// period: the closed-form HTF then does not describe the model's neighbours.
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
        for name in names {
            if self.parameter_index(name).is_none() {
                return Err(ModelError::Parameter {
                    name: (*name).to_string(),
                    message: "the model has no such parameter".into(),
                }
                .into());
            }
        }
        let sym = Symbolic::new(self, names);
        if !sym.piecewise_constant() {
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
            // Per entry (a, b) of S: d/dt, d/dx_1 .. d/dx_n, d/dp_1 .. d/dp_k.
            let stride = 1 + n + k;
            let mut ds = vec![0.0; n * n * stride];
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
                piece.jump = DMatrix::from_fn(n, n, |a, b| {
                    let d = &ds[(a * n + b) * stride..(a * n + b + 1) * stride];
                    d[1 + n + j] + d[0] * dtau + (0..n).map(|l| d[1 + l] * dx[l]).sum::<f64>()
                });
            }
        }

        // The pieces' matrices: constant within each mode, read anywhere on the orbit.
        let p = self.outputs().len();
        let at = self.vars(cycle.t0, &cycle.state0, self.input_value(cycle.t0));
        let mut out_d = vec![0.0; (p * n + p) * k];
        programs.outputs.eval(&at, &mut out_d);
        for i in 0..piecewise.pieces().len() {
            let mode = lin.switches.get(i).map_or(cycle.mode0, |s| s.to);
            let mut flow_d = vec![0.0; (n * n + n) * k];
            programs.flows[mode.index()].eval(&at, &mut flow_d);
            for (j, tangent) in tangents.iter_mut().enumerate() {
                let piece = &mut tangent.pieces_mut()[i];
                piece.a = DMatrix::from_fn(n, n, |r, c| flow_d[(r * n + c) * k + j]);
                piece.b = DMatrix::from_fn(n, 1, |r, _| flow_d[(n * n + r) * k + j]);
                piece.c = DMatrix::from_fn(p, n, |r, c| out_d[(r * n + c) * k + j]);
                piece.d = DMatrix::from_fn(p, 1, |r, _| out_d[(p * n + r) * k + j]);
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

impl Model {
    /// `[t, x, u, parameter values]`: the tangents' programs' variables.
    fn vars(&self, t: f64, x: &[f64], u: f64) -> Vec<f64> {
        let mut v = Vec::with_capacity(x.len() + 2 + self.values().len());
        v.push(t);
        v.extend_from_slice(x);
        v.push(u);
        v.extend_from_slice(self.values());
        v
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
    /// Per mode: `d(df/dx)/dp` (`n x n x k`), then `d(df/du)/dp` (`n x k`).
    flows: Vec<Program>,
    /// `d(dy/dx)/dp` (`p x n x k`), then `d(dy/du)/dp` (`p x k`).
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

    /// Whether `A`, `B` of every mode and `C`, `D` are free of time, state and input for
    /// every value of `names`, and the period does not depend on them.
    fn piecewise_constant(&self) -> bool {
        let def = self.model.def();
        if def
            .period
            .as_ref()
            .is_some_and(|e| self.names.iter().any(|n| e.depends_on(n)))
        {
            return false;
        }
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

    /// `d/dp_j` of `d e_i / d x_l` for every `e_i` and `l`, then of `d e_i / du`, in the
    /// order `((i, l), j)`.
    fn linear_by_parameters(&self, exprs: &[Expr]) -> Vec<Expr> {
        let (states, input) = (self.states(), self.input());
        let mut out = Vec::new();
        for e in exprs {
            for s in states {
                let d = e.derivative(s);
                out.extend(self.names.iter().map(|p| d.derivative(p)));
            }
        }
        for e in exprs {
            let d = e.derivative(input);
            out.extend(self.names.iter().map(|p| d.derivative(p)));
        }
        out
    }

    fn programs(&self) -> Result<Programs, ModelError> {
        let def = self.model.def();
        let flows = def
            .flows
            .iter()
            .map(|f| self.compile(&self.linear_by_parameters(f)))
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
            outputs: self.compile(&self.linear_by_parameters(&outputs))?,
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
        self.compile(&entries)
    }
}
