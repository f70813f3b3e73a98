//! Extending a model: terms added to named state equations and guards, with new parameters.
//! A diagnosis tries candidate effects this way on any model, and a user writes a suspected
//! effect as a formula the same way (`[[diagnose.terms]]` in a config).

use htfid_expr::parse;

use crate::build::{is_identifier, Parameter, RESERVED};
use crate::error::ModelError;
use crate::model::Model;
use crate::read::suggestion;

/// Where an added term goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Site {
    /// The equation `d(state)/dt = ...`, in every mode, or in the named mode only.
    Flow {
        /// The state whose equation gains the term.
        state: String,
        /// The mode, or `None` for every mode.
        mode: Option<String>,
    },
    /// The expression of the named guard (its surface moves where the term is not zero).
    Guard {
        /// The guard's name ([`Model::guard_names`]).
        name: String,
    },
}

impl std::fmt::Display for Site {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Site::Flow { state, mode: None } => write!(f, "d{state}/dt"),
            Site::Flow {
                state,
                mode: Some(m),
            } => write!(f, "d{state}/dt in mode {m}"),
            Site::Guard { name } => write!(f, "guard {name}"),
        }
    }
}

/// Terms added to a model, with the parameters they introduce. Terms are expressions of `t`,
/// the states, the input, the forcing signals, the definitions and the parameters (the
/// model's and the new ones).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Extension {
    /// New parameters (names not yet taken in the model).
    pub parameters: Vec<Parameter>,
    /// `(site, term)` pairs; the term is added to the expression at the site.
    pub terms: Vec<(Site, String)>,
}

fn invalid(key: String, message: String) -> ModelError {
    ModelError::Invalid {
        location: Default::default(),
        key,
        message,
    }
}

impl Model {
    /// The model with `ext`'s terms added and its parameters declared (at their values), then
    /// recompiled: every derivative the pipeline uses (Jacobians, saltation, parameter
    /// sensitivities) is taken of the extended expressions, exactly.
    ///
    /// ```
    /// use htfid_lang::{Extension, Model, Parameter, Site};
    ///
    /// let model = Model::parse(r#"
    ///     states = ["x", "v"]
    ///     parameters = { k = 4.0, c = 0.5 }
    ///     flow = { x = "v", v = "-k*x - c*v + u" }
    /// "#)?;
    /// let drag = Extension {
    ///     parameters: vec![Parameter {
    ///         name: "d".into(),
    ///         value: 0.1,
    ///         unit: None,
    ///         min: 0.0,
    ///         max: f64::INFINITY,
    ///         free: true,
    ///     }],
    ///     terms: vec![(Site::Flow { state: "v".into(), mode: None }, "-d*abs(v)*v".into())],
    /// };
    /// let extended = model.with_extension(&drag)?;
    /// assert_eq!(extended.parameter("d"), Some(0.1));
    /// # Ok::<(), htfid_lang::ModelError>(())
    /// ```
    ///
    /// # Errors
    /// [`ModelError::Invalid`], keyed `parameters.NAME` or `terms[i]`, for a parameter name that
    /// is taken or not a valid name, a term that does not parse or names something unknown
    /// (the column of the offending character is not known here: the key says which term),
    /// a state, mode or guard the model does not have.
    pub fn with_extension(&self, ext: &Extension) -> Result<Model, ModelError> {
        let mut def = self.def().clone();
        let mut values = self.values().to_vec();
        for p in &ext.parameters {
            let key = format!("parameters.{}", p.name);
            if !is_identifier(&p.name) || RESERVED.contains(&p.name.as_str()) {
                return Err(invalid(key, format!("`{}` is not a usable name", p.name)));
            }
            let taken = def.states.iter().any(|s| s.name == p.name)
                || def.params.iter().any(|q| q.name == p.name)
                || def.input == p.name
                || def.signals.iter().any(|(n, _, _)| *n == p.name)
                || def.definitions.iter().any(|(n, _)| *n == p.name);
            if taken {
                return Err(invalid(
                    key,
                    format!("`{}` is already a name of the model", p.name),
                ));
            }
            if !(p.value.is_finite() && p.min <= p.value && p.value <= p.max) {
                return Err(invalid(
                    key,
                    format!(
                        "value {} is outside its bounds [{}, {}] or not finite",
                        p.value, p.min, p.max
                    ),
                ));
            }
            def.params.push(p.clone());
            values.push(p.value);
        }
        let mut known: Vec<&str> = vec!["t", def.input.as_str()];
        known.extend(def.states.iter().map(|s| s.name.as_str()));
        known.extend(def.params.iter().map(|p| p.name.as_str()));
        known.extend(def.signals.iter().map(|(n, _, _)| n.as_str()));
        known.extend(def.definitions.iter().map(|(n, _)| n.as_str()));
        let mut flows = def.flows.clone();
        let mut guards = def.guards.clone();
        for (i, (site, text)) in ext.terms.iter().enumerate() {
            let key = format!("terms[{i}]");
            let mut term =
                parse(text).map_err(|e| invalid(key.clone(), format!("`{text}`: {e}")))?;
            if let Some(name) = term
                .variables()
                .into_iter()
                .find(|n| !known.contains(&n.as_str()))
            {
                return Err(invalid(
                    key,
                    format!(
                        "`{text}`: unknown name `{name}`{}",
                        suggestion(&name, known.iter().copied())
                    ),
                ));
            }
            // Definitions may read signals and earlier definitions: inline the latest first.
            for (name, value) in def.definitions.iter().rev() {
                if term.depends_on(name) {
                    term = term.substitute(name, value);
                }
            }
            for (name, value, _) in def.signals.iter().rev() {
                if term.depends_on(name) {
                    term = term.substitute(name, value);
                }
            }
            match site {
                Site::Flow { state, mode } => {
                    let Some(s) = def.states.iter().position(|x| x.name == *state) else {
                        let names = def.states.iter().map(|x| x.name.as_str());
                        return Err(invalid(
                            key,
                            format!(
                                "`{state}` is not a state{}",
                                suggestion(state, names.clone())
                            ),
                        ));
                    };
                    let modes: Vec<usize> = match mode {
                        None => (0..def.modes.len()).collect(),
                        Some(m) => match def.modes.iter().position(|x| x == m) {
                            Some(j) => vec![j],
                            None => {
                                return Err(invalid(
                                    key,
                                    format!(
                                        "no mode `{m}`{}; modes: {}",
                                        suggestion(m, def.modes.iter().map(String::as_str)),
                                        def.modes.join(", ")
                                    ),
                                ))
                            }
                        },
                    };
                    for j in modes {
                        flows[j][s] = flows[j][s].clone().plus(term.clone());
                    }
                }
                Site::Guard { name } => {
                    let Some(g) = guards.iter().position(|g| g.name == *name) else {
                        return Err(invalid(
                            key,
                            format!(
                                "no guard `{name}`{}; guards: {}",
                                suggestion(name, def.guards.iter().map(|g| g.name.as_str())),
                                self.guard_names().join(", ")
                            ),
                        ));
                    };
                    guards[g].when = guards[g].when.clone().plus(term.clone());
                }
            }
        }
        def.flows = flows;
        def.guards = guards;
        Model::from_def(def, values, self.input_fn().cloned())
    }
}
