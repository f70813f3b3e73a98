//! Effects inside a model's equations: a term added to a named state equation or guard of any
//! model written in the model language, with new parameters (`htfid_lang::Extension`). The
//! library finds its sites in the model itself: every state pair `q' = v` (a position and its
//! velocity) gets drag and a stiffness law on `v`'s equation, every mode of a model with
//! several gets its own extra damping, and every switching surface may sit elsewhere. A user
//! writes any other suspected effect as a formula in the config (`[[diagnose.terms]]`).

use htfid_expr::Expr;
use htfid_lang::{Extension, Model, Parameter, Site};
use serde::{Deserialize, Serialize};

/// The kinds of term the library proposes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TermKind {
    /// `-drag_V |V| V` added to `V'` for each velocity state `V`.
    QuadraticDrag,
    /// `-(k2_Q (Q - Qm)^2 + k3_Q (Q - Qm)^3)` added to `V'` for each pair `Q' = V`, about the
    /// mean `Qm` of `Q` on the record.
    NonlinearStiffness,
    /// `-damping_V_M V` added to `V'` in mode `M` only, for each mode of a model with several.
    ModeDamping,
    /// `-shift_i` added to every guard whose expression is the `i`-th distinct one: the
    /// switching surface `h = 0` moves to `h = shift_i`.
    GuardShift,
}

impl TermKind {
    /// Every kind, in the order tried.
    pub const ALL: [TermKind; 4] = [
        TermKind::QuadraticDrag,
        TermKind::NonlinearStiffness,
        TermKind::ModeDamping,
        TermKind::GuardShift,
    ];

    /// The name in configs (`diagnose.effects`).
    pub fn name(self) -> &'static str {
        match self {
            TermKind::QuadraticDrag => "quadratic_drag",
            TermKind::NonlinearStiffness => "nonlinear_stiffness",
            TermKind::ModeDamping => "mode_damping",
            TermKind::GuardShift => "guard_shift",
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
    /// Whether to try both signs of the first parameter at a few sizes before fitting (a
    /// moved surface: the cost is not convex in the shift).
    pub multistart: bool,
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

/// The library's candidates of `kinds` for `model`; `means` are the states' means on the
/// record (the centre of a stiffness law).
pub fn term_library(model: &Model, kinds: &[TermKind], means: &[f64]) -> Vec<TermEffect> {
    let states = model.states();
    let pairs = velocity_pairs(model);
    // Each velocity state once, even when several positions integrate it.
    let mut velocities: Vec<usize> = pairs.iter().map(|&(_, v)| v).collect();
    velocities.sort_unstable();
    velocities.dedup();
    let mut out = Vec::new();
    let flow = |state: &str, mode: Option<&str>| Site::Flow {
        state: state.to_string(),
        mode: mode.map(String::from),
    };
    for &kind in kinds {
        match kind {
            TermKind::QuadraticDrag => {
                for &v in &velocities {
                    let vn = &states[v].name;
                    let p = fresh(model, &[], &format!("drag_{vn}"));
                    out.push(TermEffect {
                        name: format!("quadratic_drag({vn})"),
                        extension: Extension {
                            terms: vec![(flow(vn, None), format!("-{p}*abs({vn})*{vn}"))],
                            parameters: vec![zero(p)],
                        },
                        multistart: false,
                    });
                }
            }
            TermKind::NonlinearStiffness => {
                for &(q, v) in &pairs {
                    let (qn, vn) = (&states[q].name, &states[v].name);
                    let k2 = fresh(model, &[], &format!("k2_{qn}"));
                    let k3 = fresh(model, std::slice::from_ref(&k2), &format!("k3_{qn}"));
                    let centre = means.get(q).copied().unwrap_or(0.0);
                    // Six significant digits: the centre only needs to be near the mean.
                    let centre: f64 = format!("{centre:.5e}").parse().unwrap_or(0.0);
                    let d = if centre < 0.0 {
                        format!("({qn} + {})", -centre)
                    } else {
                        format!("({qn} - {centre})")
                    };
                    out.push(TermEffect {
                        name: format!("nonlinear_stiffness({qn})"),
                        extension: Extension {
                            terms: vec![(flow(vn, None), format!("-({k2}*{d}^2 + {k3}*{d}^3)"))],
                            parameters: vec![zero(k2), zero(k3)],
                        },
                        multistart: false,
                    });
                }
            }
            TermKind::ModeDamping if model.modes().len() > 1 => {
                for &v in &velocities {
                    let vn = &states[v].name;
                    for mode in model.modes() {
                        let p = fresh(model, &[], &format!("damping_{vn}_{mode}"));
                        out.push(TermEffect {
                            name: format!("mode_damping({vn}, {mode})"),
                            extension: Extension {
                                terms: vec![(flow(vn, Some(mode)), format!("-{p}*{vn}"))],
                                parameters: vec![zero(p)],
                            },
                            multistart: false,
                        });
                    }
                }
            }
            TermKind::ModeDamping => {}
            TermKind::GuardShift => {
                let names = model.guard_names();
                let mut groups: Vec<(Expr, Vec<String>)> = Vec::new();
                for (i, name) in names.iter().enumerate() {
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
                        multistart: true,
                    });
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
        .map(|(i, s)| {
            let c: f64 = format!("{:.5e}", means.get(i).copied().unwrap_or(0.0))
                .parse()
                .unwrap_or(0.0);
            if c == 0.0 {
                s.name.clone()
            } else if c < 0.0 {
                format!("({} + {})", s.name, -c)
            } else {
                format!("({} - {c})", s.name)
            }
        })
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
