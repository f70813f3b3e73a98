//! Resolving a model as written into its definition: names checked, named definitions and
//! forcing signals inlined, so that every expression depends only on `t`, the states, the
//! input and the parameters.

use std::collections::{BTreeMap, BTreeSet};

use htfid_expr::{parse, Expr, ExprError};
use htfid_hybrid::Crossing;

use crate::error::ModelError;
use crate::read::{suggestion, ExprSrc, ModeSpec, Source, Spec};

/// A state of a model.
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    /// Its name in expressions.
    pub name: String,
    /// Its unit, when declared.
    pub unit: Option<String>,
}

/// A parameter of a model.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameter {
    /// Its name in expressions.
    pub name: String,
    /// Its value.
    pub value: f64,
    /// Its unit, when declared.
    pub unit: Option<String>,
    /// Lower bound (`-inf` when none).
    pub min: f64,
    /// Upper bound (`+inf` when none).
    pub max: f64,
    /// Whether fits estimate it by default.
    pub free: bool,
}

/// An output of a model.
#[derive(Debug, Clone, PartialEq)]
pub struct Output {
    /// Its name (a column name in result files).
    pub name: String,
    /// Its unit, when declared.
    pub unit: Option<String>,
    /// The expression, as resolved (definitions inlined).
    pub expr: Expr,
}

#[derive(Debug, Clone)]
pub(crate) struct GuardDef {
    pub name: String,
    pub to: usize,
    pub when: Expr,
    pub direction: Crossing,
    /// The state after the reset, one expression per state; `None` for the identity.
    pub reset: Option<Vec<Expr>>,
}

#[derive(Debug, Clone)]
pub(crate) struct ModelDef {
    pub name: String,
    pub description: Option<String>,
    pub states: Vec<State>,
    pub params: Vec<Parameter>,
    pub input: String,
    pub input_unit: Option<String>,
    pub period: Option<Expr>,
    /// Named forcing signals with where they are written.
    pub signals: Vec<(String, Expr, Option<usize>)>,
    /// Named definitions, resolved (signals and earlier definitions inlined).
    pub definitions: Vec<(String, Expr)>,
    pub modes: Vec<String>,
    /// Per mode, one expression per state.
    pub flows: Vec<Vec<Expr>>,
    pub guards: Vec<GuardDef>,
    /// Per mode, the indices of its guards.
    pub guards_of: Vec<Vec<usize>>,
    pub outputs: Vec<Output>,
    pub initial_mode: usize,
    pub initial_state: Vec<f64>,
}

/// Names a user may not take: time, the constant, and the functions of the expression
/// language.
pub(crate) const RESERVED: &[&str] = &[
    "t", "pi", "sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "exp", "ln",
    "log", "log10", "sqrt", "abs", "sign", "min", "max", "atan2", "pow", "hypot", "step", "pos",
    "clamp", "if", "sat",
];

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Kind {
    State,
    Param,
    Input,
    Signal,
    Definition,
}

impl Kind {
    fn word(self) -> &'static str {
        match self {
            Kind::State => "a state",
            Kind::Param => "a parameter",
            Kind::Input => "the input",
            Kind::Signal => "a forcing signal",
            Kind::Definition => "a definition",
        }
    }
}

struct Resolver<'a> {
    src: &'a Source,
    names: BTreeMap<String, Kind>,
    /// Inlined values of signals and definitions.
    inline: Vec<(String, Expr)>,
}

pub(crate) fn is_identifier(s: &str) -> bool {
    let mut c = s.chars();
    matches!(c.next(), Some(ch) if ch.is_ascii_alphabetic() || ch == '_')
        && c.all(|ch| ch.is_ascii_alphanumeric() || ch == '_')
}

impl Resolver<'_> {
    fn declare(
        &mut self,
        name: &str,
        kind: Kind,
        key: &str,
        at: Option<usize>,
    ) -> Result<(), ModelError> {
        if !is_identifier(name) {
            return Err(self.src.invalid(
                at,
                key,
                format!("`{name}` is not a valid name (letters, digits and _, not starting with a digit)"),
            ));
        }
        if RESERVED.contains(&name) {
            return Err(self.src.invalid(
                at,
                key,
                format!("`{name}` is reserved (time, the constant pi, or a function name)"),
            ));
        }
        if let Some(k) = self.names.get(name) {
            return Err(self
                .src
                .invalid(at, key, format!("`{name}` is already {}", k.word())));
        }
        self.names.insert(name.to_string(), kind);
        Ok(())
    }

    fn expr_error(&self, e: &ExprSrc, err: ExprError) -> ModelError {
        let mut location = self.src.location(e.at);
        if let (Some(col), Some(off)) = (location.column, err.span().map(|s| s.start)) {
            location.column = Some(col + off);
        }
        ModelError::Invalid {
            location,
            key: e.key.clone(),
            message: err.to_string(),
        }
    }

    /// Parses `e`, checks that it uses only names of the allowed kinds (and `t` if allowed),
    /// and inlines signals and definitions.
    fn resolve(&self, e: &ExprSrc, allowed: &[Kind], time: bool) -> Result<Expr, ModelError> {
        let expr = parse(&e.text).map_err(|err| self.expr_error(e, err))?;
        for name in expr.variables() {
            let ok = if name == "t" {
                time
            } else {
                match self.names.get(&name) {
                    Some(k) => allowed.contains(k),
                    None => false,
                }
            };
            if !ok {
                let span = expr.span_of(&name);
                let mut location = self.src.location(e.at);
                if let (Some(col), Some(s)) = (location.column, span.as_ref()) {
                    location.column = Some(col + s.start);
                }
                let message = if name == "t" {
                    "`t` (time) is not allowed here".to_string()
                } else if let Some(k) = self.names.get(&name) {
                    format!("`{name}` is {} and cannot be used here", k.word())
                } else {
                    let candidates: Vec<&str> = self
                        .names
                        .iter()
                        .filter(|(_, k)| allowed.contains(k))
                        .map(|(n, _)| n.as_str())
                        .chain(time.then_some("t"))
                        .collect();
                    format!(
                        "unknown name `{name}`{}",
                        suggestion(&name, candidates.iter().copied())
                    )
                };
                return Err(ModelError::Invalid {
                    location,
                    key: e.key.clone(),
                    message,
                });
            }
        }
        let mut out = expr;
        for (name, value) in self.inline.iter().rev() {
            if out.depends_on(name) {
                out = out.substitute(name, value);
            }
        }
        Ok(out)
    }
}

const ALL: &[Kind] = &[
    Kind::State,
    Kind::Param,
    Kind::Input,
    Kind::Signal,
    Kind::Definition,
];

pub(crate) fn build(spec: &Spec, src: &Source) -> Result<ModelDef, ModelError> {
    let mut r = Resolver {
        src,
        names: BTreeMap::new(),
        inline: Vec::new(),
    };
    let mut states = Vec::new();
    for (i, (name, unit, at)) in spec.states.iter().enumerate() {
        r.declare(name, Kind::State, &format!("states[{i}]"), *at)?;
        states.push(State {
            name: name.clone(),
            unit: unit.clone(),
        });
    }
    let mut params = Vec::new();
    for p in &spec.params {
        r.declare(
            &p.name,
            Kind::Param,
            &format!("parameters.{}", p.name),
            p.at,
        )?;
        params.push(Parameter {
            name: p.name.clone(),
            value: p.value,
            unit: p.unit.clone(),
            min: p.min,
            max: p.max,
            free: p.free,
        });
    }
    r.declare(&spec.input.0, Kind::Input, "input.name", spec.at)?;

    let period = match &spec.period {
        Some(e) => Some(r.resolve(e, &[Kind::Param], false)?),
        None => None,
    };
    let mut signals = Vec::new();
    for (name, e) in &spec.signals {
        let value = r.resolve(e, &[Kind::Param, Kind::Signal], true)?;
        r.declare(name, Kind::Signal, &e.key, e.at)?;
        r.inline.push((name.clone(), value.clone()));
        signals.push((name.clone(), value, e.at));
    }
    let mut definitions = Vec::new();
    for (name, e) in &spec.definitions {
        let value = r.resolve(e, ALL, true)?;
        r.declare(name, Kind::Definition, &e.key, e.at)?;
        r.inline.push((name.clone(), value.clone()));
        definitions.push((name.clone(), value));
    }

    // Modes: `[modes.NAME]` tables, or one implicit mode from `[flow]`.
    let state_names: Vec<&str> = states.iter().map(|s| s.name.as_str()).collect();
    let check_state_keys = |eqs: &[(String, ExprSrc)]| -> Result<(), ModelError> {
        for (k, e) in eqs {
            if !state_names.contains(&k.as_str()) {
                return Err(src.invalid(
                    e.at,
                    &e.key,
                    format!(
                        "`{k}` is not a state{}; states: {}",
                        suggestion(k, state_names.iter().copied()),
                        state_names.join(", ")
                    ),
                ));
            }
        }
        Ok(())
    };
    check_state_keys(&spec.flow)?;
    let mut modes = Vec::new();
    let mut flows = Vec::new();
    let mode_list: Vec<ModeSpec> = if spec.modes.is_empty() {
        vec![("main".to_string(), Vec::new(), spec.at)]
    } else {
        spec.modes.clone()
    };
    for (name, eqs, at) in &mode_list {
        if !is_identifier(name) {
            return Err(src.invalid(
                *at,
                &format!("modes.{name}"),
                "a mode name must be letters, digits and _",
            ));
        }
        check_state_keys(eqs)?;
        let mut flow = Vec::new();
        for s in &state_names {
            let e = eqs
                .iter()
                .find(|(k, _)| k == s)
                .or_else(|| spec.flow.iter().find(|(k, _)| k == s))
                .map(|(_, e)| e);
            let Some(e) = e else {
                let key = if spec.modes.is_empty() {
                    "flow".to_string()
                } else {
                    format!("modes.{name}")
                };
                return Err(src.invalid(
                    *at,
                    &key,
                    format!("no equation for state `{s}` (give `{s} = \"...\"` here or in [flow])"),
                ));
            };
            flow.push(r.resolve(e, ALL, true)?);
        }
        modes.push(name.clone());
        flows.push(flow);
    }

    let find_mode = |name: &str, key: &str, at: Option<usize>| -> Result<usize, ModelError> {
        modes.iter().position(|m| m == name).ok_or_else(|| {
            src.invalid(
                at,
                key,
                format!(
                    "no mode `{name}`{}; modes: {}",
                    suggestion(name, modes.iter().map(String::as_str)),
                    modes.join(", ")
                ),
            )
        })
    };
    let mut guards = Vec::new();
    let mut guards_of = vec![Vec::new(); modes.len()];
    for g in &spec.guards {
        let from = match &g.from {
            Some((name, at)) => find_mode(name, &format!("{}.from", g.key), *at)?,
            None if modes.len() == 1 => 0,
            None => {
                return Err(src.invalid(
                    g.at,
                    &g.key,
                    "needs `from`: the mode in which this guard is watched",
                ))
            }
        };
        let to = match &g.to {
            Some((name, at)) => find_mode(name, &format!("{}.to", g.key), *at)?,
            None => from,
        };
        let when = r.resolve(&g.when, ALL, true)?;
        let direction = match g.direction.0.as_str() {
            "rising" => Crossing::Rising,
            "falling" => Crossing::Falling,
            "either" => Crossing::Either,
            other => {
                return Err(src.invalid(
                    g.direction.1,
                    &format!("{}.direction", g.key),
                    format!("must be \"rising\", \"falling\" or \"either\" (got \"{other}\")"),
                ))
            }
        };
        check_state_keys(&g.reset)?;
        let reset = if g.reset.is_empty() {
            None
        } else {
            let mut out = Vec::new();
            for s in &state_names {
                match g.reset.iter().find(|(k, _)| k == s) {
                    Some((_, e)) => out.push(r.resolve(e, ALL, true)?),
                    None => out.push(Expr::var(s)),
                }
            }
            Some(out)
        };
        let name = g
            .name
            .clone()
            .unwrap_or_else(|| format!("{}->{}", modes[from], modes[to]));
        guards_of[from].push(guards.len());
        guards.push(GuardDef {
            name,
            to,
            when,
            direction,
            reset,
        });
    }

    let outputs = if spec.outputs.is_empty() {
        vec![Output {
            name: states[0].name.clone(),
            unit: states[0].unit.clone(),
            expr: Expr::var(&states[0].name),
        }]
    } else {
        let mut seen = BTreeSet::new();
        let mut out = Vec::new();
        for o in &spec.outputs {
            if !seen.insert(o.name.clone()) {
                return Err(src.invalid(o.expr.at, &o.expr.key, "duplicate output name"));
            }
            out.push(Output {
                name: o.name.clone(),
                unit: o.unit.clone(),
                expr: r.resolve(&o.expr, ALL, true)?,
            });
        }
        out
    };

    let initial_mode = match &spec.initial_mode {
        Some((name, at)) => find_mode(name, "initial.mode", *at)?,
        None => 0,
    };
    let mut initial_state = vec![0.0; states.len()];
    for (name, value, at) in &spec.initial_state {
        match state_names.iter().position(|s| s == name) {
            Some(i) => initial_state[i] = *value,
            None => {
                return Err(src.invalid(
                    *at,
                    &format!("initial.{name}"),
                    format!(
                        "`{name}` is not a state{} (keys here: mode and the state names)",
                        suggestion(name, state_names.iter().copied())
                    ),
                ))
            }
        }
    }

    Ok(ModelDef {
        name: spec.name.clone(),
        description: spec.description.clone(),
        states,
        params,
        input: spec.input.0.clone(),
        input_unit: spec.input.1.clone(),
        period,
        signals,
        definitions,
        modes,
        flows,
        guards,
        guards_of,
        outputs,
        initial_mode,
        initial_state,
    })
}
