//! Effects inside a model's equations: a term added to a named state equation or guard of any
//! model written in the model language, with new parameters (`htfid_lang::Extension`). The
//! library finds its sites in the model itself: every state pair `q' = v` (a position and its
//! velocity) gets drag, Coulomb friction, a stiffness law and a hard stop on either side on
//! `v`'s equation, every mode of a model with several gets its own extra damping, and every
//! switching surface may sit elsewhere. A user writes any other suspected effect as a formula
//! in the config (`[[diagnose.terms]]`).

use htfid_expr::Expr;
use htfid_lang::{Extension, Model, Parameter, Site};
use serde::{Deserialize, Serialize};

/// The kinds of term the library proposes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TermKind {
    /// `-drag_V |V| V` added to `V'` for each velocity state `V`.
    QuadraticDrag,
    /// A spring law added to `V'` for each pair `Q' = V`. About the rest point `Qr` of the
    /// model's own linear spring on `Q` (read from its equations: `rest_point`), a cubic
    /// spring, `-k3_Q (Q - Qr)^3`: one coefficient, so its constant force, its curvature and
    /// its slope on the motion are tied to each other as a real spring's are. Without a rest
    /// point, `-(k2_Q (Q - Qm)^2 + k3_Q (Q - Qm)^3)` about the mean `Qm` of `Q` on the record,
    /// its linear part left to the model's own stiffness. A free constant, or a second
    /// coefficient about the rest point, took the constant force or the sensor offset beside
    /// another effect in records of two effects; a law about the mean left a cubic spring's
    /// constant to them (see `docs/diagnosis.md`).
    NonlinearStiffness,
    /// `-damping_V_M V` added to `V'` in mode `M` only, for each mode of a model with several.
    ModeDamping,
    /// `-shift_i` added to every guard whose expression is the `i`-th distinct one: the
    /// switching surface `h = 0` moves to `h = shift_i`.
    GuardShift,
    /// `-friction_V tanh(V / eps)` added to `V'` for each velocity state `V`: Coulomb friction
    /// of size `friction_V` (a force over the mass, `>= 0`), its sign change smoothed over
    /// `eps`, a thousandth of `V`'s spread on the record (see [`FRICTION_SMOOTHING`]).
    CoulombFriction,
    /// `k_floor_Q max(0, floor_Q - Q)` (below) and `-k_ceiling_Q max(0, Q - ceiling_Q)`
    /// (above) added to `V'` for each pair `Q' = V`: a one-sided contact spring that pushes
    /// back beyond a position. Its stiffness (over the mass) is at least the model's own
    /// ([`StateStats::stiffness`]): a softer one-sided spring is a stiffness law, which it
    /// would otherwise mimic. Started from the best of a grid of positions touched by 1 to
    /// 30 % of the motion and stiffnesses 2 to 100 times the model's own; named only with its
    /// position inside the motion ([`Placement`]).
    HardStop,
}

/// The velocity, as a fraction of the velocity's spread on the record, over which the
/// library's Coulomb friction changes sign (`tanh(V / eps)`). Within `|V| < eps` the friction
/// is a viscous damping `friction_V / eps`: a stick of true Coulomb friction becomes a creep
/// at about `eps`, whose displacement over a stick of a tenth of a period is under a
/// thousandth of the motion's; a smaller `eps` makes the field stiffer for the integrator.
pub const FRICTION_SMOOTHING: f64 = 1e-3;

impl TermKind {
    /// Every kind, in the order tried.
    pub const ALL: [TermKind; 6] = [
        TermKind::QuadraticDrag,
        TermKind::NonlinearStiffness,
        TermKind::ModeDamping,
        TermKind::GuardShift,
        TermKind::CoulombFriction,
        TermKind::HardStop,
    ];

    /// The name in configs (`diagnose.effects`).
    pub fn name(self) -> &'static str {
        match self {
            TermKind::QuadraticDrag => "quadratic_drag",
            TermKind::NonlinearStiffness => "nonlinear_stiffness",
            TermKind::ModeDamping => "mode_damping",
            TermKind::GuardShift => "guard_shift",
            TermKind::CoulombFriction => "coulomb_friction",
            TermKind::HardStop => "hard_stop",
        }
    }

    /// The kind of this name, if any.
    pub fn from_name(name: &str) -> Option<TermKind> {
        TermKind::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// A candidate effect written as terms added to a model.
#[derive(Debug, Clone, PartialEq)]
pub struct TermEffect {
    /// Its name in results: the kind and its site, e.g. `quadratic_drag(v)`; a user's own name
    /// for a term from the config.
    pub name: String,
    /// The terms and their parameters (at their starting values).
    pub extension: Extension,
    /// Where its fit starts.
    pub start: TermStart,
    /// The parameter that places it on the motion, if one does.
    pub placed: Option<Placement>,
    /// For a law written without its linear part (the stiffness law about the motion's mean):
    /// the position whose slope on the equation the term joins it changes. A free parameter
    /// that sets that slope takes up the law's linear part, so beside the law its change is
    /// not a parameter error. `None` for the cubic spring about the model's rest point, whose
    /// slope is its own.
    pub linear_part: Option<String>,
}

/// A parameter that places a term on the motion: the term acts only beyond the parameter's
/// value along a state. Outside the state's range on the record it acts everywhere or nowhere,
/// and only mimics the model's own structure (a contact touched everywhere is a stiffer spring
/// and a constant force), so the diagnosis names it only with its value inside that range.
#[derive(Debug, Clone, PartialEq)]
pub struct Placement {
    /// The term's parameter.
    pub parameter: String,
    /// The state it is a value of.
    pub state: String,
}

/// Where the fit of a term's parameters starts.
#[derive(Debug, Clone, PartialEq)]
pub enum TermStart {
    /// From the extension's values (zero: the model as it was). Beside effects chosen before
    /// it, the first parameter starts from the best of zero and a few sizes of either sign.
    Given,
    /// From the best of both signs of the first parameter at a few sizes, never zero: a moved
    /// switching surface, whose cost is not convex in the shift and whose derivative may
    /// vanish at zero.
    BothSigns,
    /// From the best of these points, each a value of every one of the term's parameters in
    /// order (a contact: nothing moves while it lies beyond the motion).
    Points(Vec<Vec<f64>>),
}

/// What the library reads of one of a model's states along its simulation on a record: where
/// a stiffness law is centred, where a stop may sit, how fast a velocity changes sign.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StateStats {
    /// The mean.
    pub mean: f64,
    /// The RMS about the mean.
    pub spread: f64,
    /// The quantiles at 1, 3, 10, 30, 70, 90, 97 and 99 %.
    pub quantiles: [f64; 8],
    /// For a position `Q` with `Q' = V`: the RMS of `-d(V')/dQ` (the model's own stiffness
    /// over its mass), else 0.
    pub stiffness: f64,
}

impl TermEffect {
    /// What it adds, in words: "`-drag_v*abs(v)*v` added to dv/dt".
    pub fn describe(&self) -> String {
        self.extension
            .terms
            .iter()
            .map(|(site, term)| format!("`{term}` added to {site}"))
            .collect::<Vec<_>>()
            .join("; ")
    }

    /// The names of its parameters.
    pub fn parameter_names(&self) -> Vec<String> {
        self.extension
            .parameters
            .iter()
            .map(|p| p.name.clone())
            .collect()
    }
}

/// A parameter starting at zero, unbounded, with no unit.
fn zero(name: String) -> Parameter {
    Parameter {
        name,
        value: 0.0,
        unit: None,
        min: f64::NEG_INFINITY,
        max: f64::INFINITY,
        free: true,
    }
}

/// A parameter starting at zero, bounded below by zero, with no unit.
fn nonnegative(name: String) -> Parameter {
    Parameter {
        min: 0.0,
        ..zero(name)
    }
}

/// `name` less `value` (to six significant digits: a centre only needs to be near) as an
/// expression: `(q - 0.15)`, `(q + 0.15)`, or `q` for zero.
fn offset(name: &str, value: f64) -> String {
    let value: f64 = format!("{value:.5e}").parse().unwrap_or(0.0);
    if value == 0.0 {
        name.to_string()
    } else if value < 0.0 {
        format!("({name} + {})", -value)
    } else {
        format!("({name} - {value})")
    }
}

/// A name not yet taken in `model`: `base`, else `base_2`, `base_3`, ...
pub(crate) fn fresh(model: &Model, taken: &[String], base: &str) -> String {
    let used = |n: &str| {
        model.parameter_index(n).is_some()
            || model.states().iter().any(|s| s.name == n)
            || model.input_name() == n
            || taken.iter().any(|t| t == n)
    };
    if !used(base) {
        return base.to_string();
    }
    (2..)
        .map(|i| format!("{base}_{i}"))
        .find(|n| !used(n))
        .unwrap_or_default()
}

/// Where the model's own linear spring on `q` rests: the zero of the terms of `v`'s equation
/// that depend on `q` and on nothing but the parameters ([`Expr::terms`]), if in every mode
/// that has such terms they are linear in `q` and vanish at the same point. On the hopper,
/// whose `v' = (-m*g - k*(x - x0) - c*v + f0 + u)/m`, it is `x0`. `None` when no mode has such
/// a term, one is not linear, or the modes disagree.
pub fn rest_point(model: &Model, q: usize, v: usize) -> Option<f64> {
    let states = model.states();
    let qn = states[q].name.as_str();
    let known = |n: &str| model.parameter(n);
    let mut rest: Option<f64> = None;
    for mode in model.modes().iter().filter_map(|m| model.mode(m)) {
        let own: Vec<Expr> = model
            .equation(mode, v)
            .terms()
            .into_iter()
            .filter(|t| {
                let vars = t.variables();
                vars.contains(qn) && vars.iter().all(|n| n == qn || known(n).is_some())
            })
            .collect();
        let Some(spring) = own.into_iter().reduce(Expr::plus) else {
            continue;
        };
        let slope = spring.derivative(qn);
        if slope.derivative(qn).as_constant() != Some(0.0) {
            return None;
        }
        let at = |x: f64| spring.eval_with(&|n| if n == qn { Some(x) } else { known(n) });
        let (Ok(s0), Ok(a)) = (at(0.0), slope.eval_with(&known)) else {
            return None;
        };
        // Not finite for a spring of no stiffness.
        let here = -s0 / a;
        if !here.is_finite() {
            return None;
        }
        match rest {
            Some(r) if (r - here).abs() > 1e-9 * r.abs().max(1.0) => return None,
            _ => rest = Some(here),
        }
    }
    rest
}

/// The state pairs `(q, v)` with `q' = v` in every mode.
pub fn velocity_pairs(model: &Model) -> Vec<(usize, usize)> {
    let states = model.states();
    let modes: Vec<_> = model.modes().iter().filter_map(|m| model.mode(m)).collect();
    let mut pairs = Vec::new();
    for q in 0..states.len() {
        for v in 0..states.len() {
            if v != q
                && modes
                    .iter()
                    .all(|&m| *model.equation(m, q) == Expr::var(&states[v].name))
            {
                pairs.push((q, v));
            }
        }
    }
    pairs
}

/// The library's candidates of `kinds` for `model`; `states` is what the model's states do on
/// the record (one per state: the centre of a stiffness law, where a stop may sit, the
/// smoothing of friction).
pub fn term_library(model: &Model, kinds: &[TermKind], states: &[StateStats]) -> Vec<TermEffect> {
    let names = model.states();
    let pairs = velocity_pairs(model);
    // Each velocity state once, even when several positions integrate it.
    let mut velocities: Vec<usize> = pairs.iter().map(|&(_, v)| v).collect();
    velocities.sort_unstable();
    velocities.dedup();
    let stats = |i: usize| states.get(i).copied().unwrap_or_default();
    let mut out = Vec::new();
    let flow = |state: &str, mode: Option<&str>| Site::Flow {
        state: state.to_string(),
        mode: mode.map(String::from),
    };
    for &kind in kinds {
        match kind {
            TermKind::QuadraticDrag => {
                for &v in &velocities {
                    let vn = &names[v].name;
                    let p = fresh(model, &[], &format!("drag_{vn}"));
                    out.push(TermEffect {
                        name: format!("quadratic_drag({vn})"),
                        extension: Extension {
                            terms: vec![(flow(vn, None), format!("-{p}*abs({vn})*{vn}"))],
                            parameters: vec![zero(p)],
                        },
                        start: TermStart::Given,
                        placed: None,
                        linear_part: None,
                    });
                }
            }
            TermKind::NonlinearStiffness => {
                for &(q, v) in &pairs {
                    let (qn, vn) = (&names[q].name, &names[v].name);
                    // About the rest point the law is a whole spring, its slope on the
                    // motion its own: a refitted stiffness beside it is the model's error.
                    let rest = rest_point(model, q, v);
                    let linear_part = rest.is_none().then(|| qn.clone());
                    let extension = match rest {
                        Some(rest) => {
                            let k3 = fresh(model, &[], &format!("k3_{qn}"));
                            let d = offset(qn, rest);
                            Extension {
                                terms: vec![(flow(vn, None), format!("-{k3}*{d}^3"))],
                                parameters: vec![zero(k3)],
                            }
                        }
                        None => {
                            let k2 = fresh(model, &[], &format!("k2_{qn}"));
                            let k3 = fresh(model, std::slice::from_ref(&k2), &format!("k3_{qn}"));
                            let d = offset(qn, stats(q).mean);
                            Extension {
                                terms: vec![(
                                    flow(vn, None),
                                    format!("-({k2}*{d}^2 + {k3}*{d}^3)"),
                                )],
                                parameters: vec![zero(k2), zero(k3)],
                            }
                        }
                    };
                    out.push(TermEffect {
                        name: format!("nonlinear_stiffness({qn})"),
                        extension,
                        start: TermStart::Given,
                        placed: None,
                        linear_part,
                    });
                }
            }
            TermKind::ModeDamping if model.modes().len() > 1 => {
                for &v in &velocities {
                    let vn = &names[v].name;
                    for mode in model.modes() {
                        let p = fresh(model, &[], &format!("damping_{vn}_{mode}"));
                        out.push(TermEffect {
                            name: format!("mode_damping({vn}, {mode})"),
                            extension: Extension {
                                terms: vec![(flow(vn, Some(mode)), format!("-{p}*{vn}"))],
                                parameters: vec![zero(p)],
                            },
                            start: TermStart::Given,
                            placed: None,
                            linear_part: None,
                        });
                    }
                }
            }
            TermKind::ModeDamping => {}
            TermKind::GuardShift => {
                let guards = model.guard_names();
                let mut groups: Vec<(Expr, Vec<String>)> = Vec::new();
                for (i, name) in guards.iter().enumerate() {
                    let e = model.guard_expr(i);
                    match groups.iter_mut().find(|(g, _)| g == e) {
                        Some((_, members)) => members.push((*name).to_string()),
                        None => groups.push((e.clone(), vec![(*name).to_string()])),
                    }
                }
                for (i, (expr, members)) in groups.iter().enumerate() {
                    let p = fresh(model, &[], &format!("shift_{}", i + 1));
                    out.push(TermEffect {
                        name: format!("guard_shift({expr})"),
                        extension: Extension {
                            terms: members
                                .iter()
                                .map(|g| (Site::Guard { name: g.clone() }, format!("-{p}")))
                                .collect(),
                            parameters: vec![zero(p)],
                        },
                        start: TermStart::BothSigns,
                        placed: None,
                        linear_part: None,
                    });
                }
            }
            TermKind::CoulombFriction => {
                for &v in &velocities {
                    let vn = &names[v].name;
                    let eps = FRICTION_SMOOTHING * stats(v).spread;
                    if !(eps.is_finite() && eps > 0.0) {
                        // A velocity that does not move on the record shows no friction.
                        continue;
                    }
                    let eps: f64 = format!("{eps:.3e}").parse().unwrap_or(eps);
                    let p = fresh(model, &[], &format!("friction_{vn}"));
                    out.push(TermEffect {
                        name: format!("coulomb_friction({vn})"),
                        extension: Extension {
                            terms: vec![(flow(vn, None), format!("-{p}*tanh({vn} / {eps:e})"))],
                            parameters: vec![nonnegative(p)],
                        },
                        start: TermStart::Given,
                        placed: None,
                        linear_part: None,
                    });
                }
            }
            TermKind::HardStop => {
                for &(q, v) in &pairs {
                    let (qn, vn) = (&names[q].name, &names[v].name);
                    let s = stats(q);
                    // Without a restoring force of its own (a free mass), the motion's own
                    // rate squared, `(spread of V / spread of Q)^2`.
                    let stiffness = if s.stiffness > 0.0 {
                        s.stiffness
                    } else {
                        (stats(v).spread / s.spread).powi(2)
                    };
                    if !(stiffness.is_finite() && stiffness > 0.0 && s.spread > 0.0) {
                        // A position that does not move on the record touches no stop.
                        continue;
                    }
                    for (below, at, beyond) in [
                        (true, &s.quantiles[..4], "floor"),
                        (false, &s.quantiles[4..], "ceiling"),
                    ] {
                        let position = fresh(model, &[], &format!("{beyond}_{qn}"));
                        let k = fresh(
                            model,
                            std::slice::from_ref(&position),
                            &format!("k_{beyond}_{qn}"),
                        );
                        // The term, and a start beyond the motion (the model as it was).
                        let (side, term, beyond_motion) = if below {
                            let term = format!("{k}*max(0, {position} - {qn})");
                            ("below", term, s.mean - 1e3 * s.spread)
                        } else {
                            let term = format!("-{k}*max(0, {qn} - {position})");
                            ("above", term, s.mean + 1e3 * s.spread)
                        };
                        // Positions touched by 1, 3, 10 and 30 % of the motion, stiffnesses 2, 10
                        // and 100 times the model's own: a contact beyond the motion moves
                        // nothing, so a fit could not start there.
                        let points = at
                            .iter()
                            .flat_map(|&x| [2.0, 10.0, 100.0].map(|f| vec![x, f * stiffness]))
                            .collect();
                        let placed = Some(Placement {
                            parameter: position.clone(),
                            state: qn.clone(),
                        });
                        let position = Parameter {
                            value: beyond_motion,
                            ..zero(position)
                        };
                        out.push(TermEffect {
                            name: format!("hard_stop({qn}, {side})"),
                            extension: Extension {
                                terms: vec![(flow(vn, None), term)],
                                parameters: vec![
                                    position,
                                    Parameter {
                                        min: stiffness,
                                        value: stiffness,
                                        ..zero(k)
                                    },
                                ],
                            },
                            start: TermStart::Points(points),
                            placed,
                            linear_part: None,
                        });
                    }
                }
            }
        }
    }
    out
}

/// One term of the term search's dictionary for a model file: a function of the states added,
/// with a coefficient of its own, to the equation of a velocity state.
#[derive(Debug, Clone)]
pub(crate) struct DictionaryTerm {
    /// The velocity state whose equation it joins.
    pub state: String,
    /// The function, as an expression of the states (centred on their means).
    pub function: String,
}

/// The term search's dictionary for `model`: in the equation of every velocity state (one that
/// a position state's equation integrates), every product of two or three states, each taken
/// from its mean on the record (`means`), and `|v| v` of every velocity. Linear terms are the
/// refit's own (its free parameters) and are left out.
pub(crate) fn term_dictionary(model: &Model, means: &[f64]) -> Vec<DictionaryTerm> {
    let states = model.states();
    let pairs = velocity_pairs(model);
    let mut velocities: Vec<usize> = pairs.iter().map(|&(_, v)| v).collect();
    velocities.sort_unstable();
    velocities.dedup();
    let centred: Vec<String> = states
        .iter()
        .enumerate()
        .map(|(i, s)| offset(&s.name, means.get(i).copied().unwrap_or(0.0)))
        .collect();
    let n = states.len();
    let mut functions = Vec::new();
    for i in 0..n {
        for j in i..n {
            functions.push(format!("{}*{}", centred[i], centred[j]));
            for k in j..n {
                functions.push(format!("{}*{}*{}", centred[i], centred[j], centred[k]));
            }
        }
    }
    for &v in &velocities {
        let vn = &states[v].name;
        functions.push(format!("abs({vn})*{vn}"));
    }
    velocities
        .iter()
        .flat_map(|&v| {
            functions.iter().map(move |f| DictionaryTerm {
                state: states[v].name.clone(),
                function: f.clone(),
            })
        })
        .collect()
}

/// The terms `chosen` of `dictionary` as one extension of `model`, each with a coefficient
/// of its own starting at zero (named `theta_1`, `theta_2`, ... or the next free names).
pub(crate) fn dictionary_extension(
    model: &Model,
    dictionary: &[DictionaryTerm],
    chosen: &[usize],
) -> Extension {
    let mut names: Vec<String> = Vec::new();
    let mut terms = Vec::new();
    for (i, &j) in chosen.iter().enumerate() {
        let p = fresh(model, &names, &format!("theta_{}", i + 1));
        let d = &dictionary[j];
        terms.push((
            Site::Flow {
                state: d.state.clone(),
                mode: None,
            },
            format!("{p}*{}", d.function),
        ));
        names.push(p);
    }
    Extension {
        parameters: names.into_iter().map(zero).collect(),
        terms,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn shipped(name: &str) -> Model {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../models/{name}.toml"));
        Model::from_file(&path).unwrap()
    }

    fn rest(model: &Model, q: &str, v: &str) -> Option<f64> {
        let at = |n: &str| model.states().iter().position(|s| s.name == n).unwrap();
        rest_point(model, at(q), at(v))
    }

    /// The rest points read from the shipped models' equations, against their files: the
    /// hopper's `x0` (0.2 m), the flight hopper's leg length `L0` (0.5 m, from its stance mode;
    /// its flight mode has no spring). None where the own spring is not linear (the two-dof's
    /// first mass, a cubic spring), where the position's only force also depends on another
    /// state (the second mass's coupling) or on the input (the closed loop's controller).
    #[test]
    fn the_rest_point_of_a_models_own_spring_is_read_from_its_equations() {
        assert_eq!(rest(&shipped("hopper"), "x", "v"), Some(0.2));
        assert_eq!(rest(&shipped("flight-hopper"), "y", "v"), Some(0.5));
        let two = shipped("two-dof");
        assert_eq!(rest(&two, "x1", "v1"), None);
        assert_eq!(rest(&two, "x2", "v2"), None);
        assert_eq!(rest(&shipped("closed-loop-friction"), "x", "v"), None);
        // A second spring on x joins the first (m = 1): -200 (x - 0.2) - 50 (x - 0.1) rests at
        // (40 + 5) / 250. A term of the parameters alone (gravity) is not a spring's.
        let two_springs = shipped("hopper")
            .with_extension(&Extension {
                terms: vec![(
                    Site::Flow {
                        state: "v".into(),
                        mode: None,
                    },
                    "-50 * (x - 0.1) - 3 * k".into(),
                )],
                parameters: vec![],
            })
            .unwrap();
        let r = rest(&two_springs, "x", "v").unwrap();
        assert!((r - 45.0 / 250.0).abs() < 1e-12, "{r}");
    }
}
