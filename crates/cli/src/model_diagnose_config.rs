//! Diagnosis configs whose `[model]` names a model file (the model language). Every key is
//! documented in `docs/config.md`.

use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use crate::config::{load, ConfigError, Kind, Source};
use crate::raw_format;
use crate::records::{resolve_format, DataFormat};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawModelDiagnoseConfig {
    name: Option<Spanned<String>>,
    data: RawData,
    model: RawModelRef,
    diagnose: Option<RawOptions>,
    /// Refused with a reason: a model file's forcing is part of the model.
    forcing: Option<Spanned<toml::Value>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawData {
    file: Spanned<String>,
    time: Option<Spanned<String>>,
    sample_rate: Option<Spanned<f64>>,
    input: Spanned<String>,
    outputs: Spanned<Vec<String>>,
    time_tolerance: Option<Spanned<f64>>,
    validation: Option<Spanned<String>>,
    rows: Option<Spanned<Vec<i64>>>,
    validation_rows: Option<Spanned<Vec<i64>>>,
    delimiter: Option<Spanned<String>>,
    matrix: Option<Spanned<String>>,
    columns: Option<Spanned<Vec<String>>>,
    units: Option<Spanned<std::collections::BTreeMap<String, String>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawModelRef {
    file: Spanned<String>,
    free: Option<Spanned<Vec<String>>>,
    parameters: Option<Spanned<toml::Table>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawOptions {
    fit_fraction: Option<Spanned<f64>>,
    burn_in: Option<Spanned<f64>>,
    significance_sigma: Option<Spanned<f64>>,
    min_gain: Option<Spanned<f64>>,
    effects: Option<Spanned<Vec<String>>>,
    parameter_error: Option<Spanned<Vec<String>>>,
    alpha: Option<Spanned<f64>>,
    rival_margin: Option<Spanned<f64>>,
    bic_margin: Option<Spanned<f64>>,
    unexplained_ratio: Option<Spanned<f64>>,
    min_explained: Option<Spanned<f64>>,
    max_effects: Option<Spanned<f64>>,
    input_noise_share: Option<Spanned<f64>>,
    input_noise_flatness: Option<Spanned<f64>>,
    noise_band: Option<Spanned<Vec<f64>>>,
    resolution: Option<Spanned<f64>>,
    second_effect_floor_ratio: Option<Spanned<f64>>,
    rtol: Option<Spanned<f64>>,
    fit_tolerance: Option<Spanned<f64>>,
    max_iterations: Option<Spanned<f64>>,
    candidate_max_iterations: Option<Spanned<f64>>,
    terms: Option<Vec<Spanned<RawTerm>>>,
}

/// `[[diagnose.terms]]`: a user's own candidate effect, a term added to a state equation or a
/// guard of the model.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTerm {
    name: Spanned<String>,
    state: Option<Spanned<String>>,
    mode: Option<Spanned<String>>,
    guard: Option<Spanned<String>>,
    term: Spanned<String>,
    parameters: Spanned<toml::Table>,
}

/// Resolved settings of a diagnosis.
#[derive(Debug, Clone)]
pub struct ModelDiagnoseSettings {
    pub name: String,
    pub path: PathBuf,
    pub file: PathBuf,
    /// A separate held-out record (same columns), when given.
    pub validation: Option<PathBuf>,
    /// `data.rows`: the rows of `file` that are the fitted record (all of it when `None`).
    pub rows: Option<std::ops::Range<usize>>,
    /// `data.validation_rows`: the rows of the held-out record, of `validation` when given,
    /// else of `file` (then they must not meet `rows`).
    pub validation_rows: Option<std::ops::Range<usize>>,
    pub time: Option<String>,
    pub sample_rate: Option<f64>,
    pub input: String,
    pub outputs: Vec<String>,
    pub time_tolerance: f64,
    /// `data.delimiter`, `data.matrix`, `data.columns`, `data.units`.
    pub format: DataFormat,
    pub model: htfid_lang::Model,
    pub options: htfid_diagnose::ModelFitOptions,
}

/// A list of the model's parameters at `key` (`model.free`, `diagnose.parameter_error`): each
/// a parameter of the model, none twice, none of `free` (the free parameters, which
/// `diagnose.parameter_error` may not name).
fn parameter_names(
    src: &Source,
    model: &htfid_lang::Model,
    list: &Spanned<Vec<String>>,
    key: &str,
    free: &[String],
) -> Result<Vec<String>, ConfigError> {
    for (i, name) in list.get_ref().iter().enumerate() {
        let problem = if model.parameter_index(name).is_none() {
            format!(
                "the model has no parameter \"{name}\"; it has {}",
                model
                    .parameters()
                    .iter()
                    .map(|p| p.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        } else if free.contains(name) {
            format!(
                "\"{name}\" is in model.free, refitted with every candidate already; list here \
                 only parameters held at their configured values"
            )
        } else if list.get_ref()[..i].contains(name) {
            format!("\"{name}\" is listed twice")
        } else {
            continue;
        };
        return Err(src.error(Some(&list.span()), key, problem));
    }
    Ok(list.get_ref().clone())
}

impl ModelDiagnoseSettings {
    /// Output `o`'s unit: the data's (`data.units`), else the model's.
    pub fn output_unit(&self, o: usize) -> Option<&str> {
        self.format
            .unit(&self.outputs[o])
            .or(self.model.outputs()[o].unit.as_deref())
    }

    /// The file the held-out record is read from: `validation`, else `file` when
    /// `validation_rows` name a section of it; `None` when the held-out data are the fitted
    /// record's tail.
    pub fn held_out_file(&self) -> Option<&Path> {
        match (&self.validation, &self.validation_rows) {
            (Some(path), _) => Some(path),
            (None, Some(_)) => Some(&self.file),
            (None, None) => None,
        }
    }

    /// The input's unit: the data's (`data.units`), else the model's.
    pub fn input_unit(&self) -> Option<&str> {
        self.format.unit(&self.input).or(self.model.input_unit())
    }

    pub fn from_file(path: &Path, data: Option<PathBuf>) -> Result<Self, ConfigError> {
        let (raw, src): (RawModelDiagnoseConfig, Source) = load(path, Kind::Diagnosis)?;
        if let Some(f) = &raw.forcing {
            return Err(src.error(
                Some(&f.span()),
                "forcing",
                "is not used with a model file: its [forcing] is part of the model (change the \
                 period or the amplitude through [model.parameters])",
            ));
        }
        let name = src.run_name(raw.name.as_ref(), "diagnosis")?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let d = &raw.data;
        if d.time.is_some() == d.sample_rate.is_some() {
            return Err(src.error(
                Some(&d.file.span()),
                "data",
                "give exactly one of `time` (the time column) and `sample_rate` (Hz)",
            ));
        }
        let model_path = dir.join(raw.model.file.get_ref());
        let mut model = htfid_lang::Model::from_file(&model_path).map_err(|e| ConfigError {
            path: src.path.clone(),
            line: Some(src.line_of(&raw.model.file.span())),
            column: Some(src.column_of(&raw.model.file.span())),
            key: "model.file".into(),
            message: e.to_string(),
        })?;
        if let Some(table) = &raw.model.parameters {
            model = crate::settings::with_overrides(&src, model, table)?;
        }
        let outputs = d.outputs.get_ref().clone();
        if outputs.len() != model.outputs().len() {
            return Err(src.error(
                Some(&d.outputs.span()),
                "data.outputs",
                format!(
                    "the model has {} output(s) ({}); name one measured column for each, in order",
                    model.outputs().len(),
                    model
                        .outputs()
                        .iter()
                        .map(|o| o.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
        if outputs.contains(d.input.get_ref()) {
            return Err(src.error(
                Some(&d.outputs.span()),
                "data.outputs",
                format!("\"{}\" is also the input column", d.input.get_ref()),
            ));
        }
        let mut used: Vec<&str> = vec![d.input.get_ref()];
        used.extend(outputs.iter().map(String::as_str));
        used.extend(d.time.as_ref().map(|t| t.get_ref().as_str()));
        let format = resolve_format(&src, raw_format!(d), &used)?;
        let free = match &raw.model.free {
            Some(list) => parameter_names(&src, &model, list, "model.free", &[])?,
            None => model
                .parameters()
                .iter()
                .filter(|p| p.free)
                .map(|p| p.name.clone())
                .collect(),
        };
        let o = raw.diagnose.as_ref();
        let parameter_error = match o.and_then(|o| o.parameter_error.as_ref()) {
            Some(list) => parameter_names(&src, &model, list, "diagnose.parameter_error", &free)?,
            None => Vec::new(),
        };
        let mut options = htfid_diagnose::ModelFitOptions {
            free,
            parameter_error,
            ..Default::default()
        };
        if let Some(v) = o.and_then(|o| o.fit_fraction.as_ref()) {
            options.fit_fraction =
                src.number(v, "diagnose.fit_fraction", "in [0.1, 0.95]", |x| {
                    (0.1..=0.95).contains(&x)
                })?;
        }
        if let Some(v) = o.and_then(|o| o.burn_in.as_ref()) {
            options.burn_in = src.non_negative(v, "diagnose.burn_in")?;
        }
        if let Some(v) = o.and_then(|o| o.significance_sigma.as_ref()) {
            options.significance_sigma = src.positive(v, "diagnose.significance_sigma")?;
        }
        if let Some(v) = o.and_then(|o| o.min_gain.as_ref()) {
            options.min_gain = src.number(v, "diagnose.min_gain", "in [0, 1)", |x| {
                (0.0..1.0).contains(&x)
            })?;
        }
        if let Some(v) = o.and_then(|o| o.alpha.as_ref()) {
            options.alpha =
                src.number(v, "diagnose.alpha", "in (0, 0.5]", |x| x > 0.0 && x <= 0.5)?;
        }
        if let Some(v) = o.and_then(|o| o.rival_margin.as_ref()) {
            options.rival_margin = src.number(v, "diagnose.rival_margin", "in [0, 1]", |x| {
                (0.0..=1.0).contains(&x)
            })?;
        }
        if let Some(v) = o.and_then(|o| o.bic_margin.as_ref()) {
            options.bic_margin = src.number(v, "diagnose.bic_margin", ">= 0", |x| x >= 0.0)?;
        }
        if let Some(v) = o.and_then(|o| o.unexplained_ratio.as_ref()) {
            options.unexplained_ratio =
                src.number(v, "diagnose.unexplained_ratio", ">= 1", |x| x >= 1.0)?;
        }
        if let Some(v) = o.and_then(|o| o.min_explained.as_ref()) {
            options.min_explained = src.number(v, "diagnose.min_explained", "in [0, 1]", |x| {
                (0.0..=1.0).contains(&x)
            })?;
        }
        if let Some(v) = o.and_then(|o| o.input_noise_share.as_ref()) {
            options.input_noise_share =
                src.number(v, "diagnose.input_noise_share", "in [0, 1]", |x| {
                    (0.0..=1.0).contains(&x)
                })?;
        }
        if let Some(v) = o.and_then(|o| o.input_noise_flatness.as_ref()) {
            options.input_noise_flatness =
                src.number(v, "diagnose.input_noise_flatness", ">= 1", |x| x >= 1.0)?;
        }
        if let Some(v) = o.and_then(|o| o.noise_band.as_ref()) {
            options.noise_band = src.band(v, "diagnose.noise_band")?;
        }
        if let Some(v) = o.and_then(|o| o.resolution.as_ref()) {
            options.resolution = src.non_negative(v, "diagnose.resolution")?;
        }
        if let Some(v) = o.and_then(|o| o.second_effect_floor_ratio.as_ref()) {
            options.second_effect_floor_ratio =
                src.number(v, "diagnose.second_effect_floor_ratio", ">= 1", |x| {
                    x >= 1.0
                })?;
        }
        if let Some(v) = o.and_then(|o| o.rtol.as_ref()) {
            options.rtol = src.number(v, "diagnose.rtol", "in [1e-14, 1e-3]", |x| {
                (1e-14..=1e-3).contains(&x)
            })?;
        }
        if let Some(v) = o.and_then(|o| o.fit_tolerance.as_ref()) {
            options.fit_tolerance = src.positive(v, "diagnose.fit_tolerance")?;
        }
        for (raw, key, slot) in [
            (
                o.and_then(|o| o.max_iterations.as_ref()),
                "diagnose.max_iterations",
                &mut options.max_iterations,
            ),
            (
                o.and_then(|o| o.candidate_max_iterations.as_ref()),
                "diagnose.candidate_max_iterations",
                &mut options.candidate_max_iterations,
            ),
        ] {
            if let Some(v) = raw {
                *slot = src.number(v, key, "a whole number from 1 to 100000", |x| {
                    x.fract() == 0.0 && (1.0..=1e5).contains(&x)
                })? as usize;
            }
        }
        if let Some(v) = o.and_then(|o| o.max_effects.as_ref()) {
            options.max_effects = src.number(
                v,
                "diagnose.max_effects",
                "a whole number from 1 to 10",
                |x| x.fract() == 0.0 && (1.0..=10.0).contains(&x),
            )? as usize;
        }
        if let Some(list) = o.and_then(|o| o.effects.as_ref()) {
            let (mut effects, mut terms) = (Vec::new(), Vec::new());
            for name in list.get_ref() {
                if let Some(e) = htfid_diagnose::BoundaryEffect::from_name(name) {
                    if !effects.contains(&e) {
                        effects.push(e);
                    }
                } else if let Some(k) = htfid_diagnose::TermKind::from_name(name) {
                    if !terms.contains(&k) {
                        terms.push(k);
                    }
                } else {
                    let known: Vec<&str> = htfid_diagnose::BoundaryEffect::ALL
                        .iter()
                        .map(|e| e.name())
                        .chain(htfid_diagnose::TermKind::ALL.iter().map(|k| k.name()))
                        .collect();
                    // The names of the effects' earlier form, with what they are now.
                    let now = match name.as_str() {
                        "cubic_stiffness" => Some("nonlinear_stiffness"),
                        "flight_damping" => Some("mode_damping"),
                        "switch_threshold" => Some("guard_shift"),
                        "asymmetric_friction" => Some("coulomb_friction beside input_offset"),
                        "parameter_error" => Some("diagnose.parameter_error = [...]"),
                        _ => None,
                    };
                    let hint = now
                        .map(|n| format!(" (\"{name}\" is now {n})"))
                        .unwrap_or_default();
                    return Err(src.error(
                        Some(&list.span()),
                        "diagnose.effects",
                        format!(
                            "unknown effect \"{name}\"{hint}; expected some of {}",
                            known.join(", ")
                        ),
                    ));
                }
            }
            options.effects = effects;
            options.terms = terms;
        }
        for (i, raw) in o
            .and_then(|o| o.terms.as_ref())
            .into_iter()
            .flatten()
            .enumerate()
        {
            options
                .user_terms
                .push(user_term(&src, &model, raw, i, &options.user_terms)?);
        }
        let rows = d
            .rows
            .as_ref()
            .map(|r| src.rows(r, "data.rows"))
            .transpose()?;
        let validation_rows = d
            .validation_rows
            .as_ref()
            .map(|r| src.rows(r, "data.validation_rows"))
            .transpose()?;
        if let (Some(v), None) = (&validation_rows, &d.validation) {
            let fitted = rows.clone().unwrap_or(0..usize::MAX);
            if v.start < fitted.end && fitted.start < v.end {
                return Err(src.error(
                    d.validation_rows.as_ref().map(|r| r.span()).as_ref(),
                    "data.validation_rows",
                    format!(
                        "the held-out rows [{}, {}) of data.file meet the fitted rows{}; give \
                         data.rows apart from them",
                        v.start,
                        v.end,
                        match &rows {
                            Some(r) => format!(" [{}, {})", r.start, r.end),
                            None => " (all of the file, data.rows not given)".into(),
                        }
                    ),
                ));
            }
        }
        Ok(ModelDiagnoseSettings {
            name,
            path: path.to_path_buf(),
            file: data.unwrap_or_else(|| dir.join(d.file.get_ref())),
            validation: d.validation.as_ref().map(|v| dir.join(v.get_ref())),
            rows,
            validation_rows,
            time: d.time.as_ref().map(|t| t.get_ref().clone()),
            sample_rate: match &d.sample_rate {
                Some(v) => Some(src.positive(v, "data.sample_rate")?),
                None => None,
            },
            input: d.input.get_ref().clone(),
            outputs,
            time_tolerance: match &d.time_tolerance {
                Some(v) => src.number(v, "data.time_tolerance", "in [0, 0.1]", |x| {
                    (0.0..=0.1).contains(&x)
                })?,
                None => htfid_data::DEFAULT_TIME_TOLERANCE,
            },
            format,
            model,
            options,
        })
    }
}

/// One `[[diagnose.terms]]` entry, checked by extending the model with it.
fn user_term(
    src: &Source,
    model: &htfid_lang::Model,
    raw: &Spanned<RawTerm>,
    i: usize,
    earlier: &[htfid_diagnose::TermEffect],
) -> Result<htfid_diagnose::TermEffect, ConfigError> {
    use htfid_lang::{Extension, Parameter, Site};
    let key = |k: &str| format!("diagnose.terms[{i}].{k}");
    let r = raw.get_ref();
    let name = r.name.get_ref().trim().to_string();
    if name.is_empty() || earlier.iter().any(|t| t.name == name) {
        return Err(src.error(
            Some(&r.name.span()),
            &key("name"),
            "must be a name not used by another term",
        ));
    }
    if htfid_diagnose::BoundaryEffect::from_name(&name).is_some() {
        return Err(src.error(
            Some(&r.name.span()),
            &key("name"),
            format!("\"{name}\" is the name of a library effect; choose another"),
        ));
    }
    let site = match (&r.state, &r.guard, &r.mode) {
        (Some(state), None, mode) => Site::Flow {
            state: state.get_ref().clone(),
            mode: mode.as_ref().map(|m| m.get_ref().clone()),
        },
        (None, Some(guard), None) => Site::Guard {
            name: guard.get_ref().clone(),
        },
        (None, Some(_), Some(mode)) => {
            return Err(src.error(
                Some(&mode.span()),
                &key("mode"),
                "a mode goes with `state`, not with `guard`",
            ))
        }
        _ => {
            return Err(src.error(
                Some(&raw.span()),
                &format!("diagnose.terms[{i}]"),
                "needs exactly one of `state` (the equation of that state gains the term) and \
                 `guard` (that guard's expression gains it)",
            ))
        }
    };
    let mut parameters = Vec::new();
    for (p, v) in r.parameters.get_ref() {
        let value = match v {
            toml::Value::Float(f) if f.is_finite() => *f,
            toml::Value::Integer(n) => *n as f64,
            other => {
                return Err(src.error(
                    Some(&r.parameters.span()),
                    &key(&format!("parameters.{p}")),
                    format!("must be a finite number, the starting value (got {other})"),
                ))
            }
        };
        parameters.push(Parameter {
            name: p.clone(),
            value,
            unit: None,
            min: f64::NEG_INFINITY,
            max: f64::INFINITY,
            free: true,
        });
    }
    if parameters.is_empty() {
        return Err(src.error(
            Some(&r.parameters.span()),
            &key("parameters"),
            "needs at least one parameter to fit, `name = starting value`",
        ));
    }
    let extension = Extension {
        parameters,
        terms: vec![(site, r.term.get_ref().clone())],
    };
    // Checked here, against the model, so that a mistake names this config's line.
    if let Err(e) = model.with_extension(&extension) {
        let message = match &e {
            htfid_lang::ModelError::Invalid { message, .. } => message.clone(),
            other => other.to_string(),
        };
        // The key the mistake is in: the state, mode or guard named, a parameter's name, or
        // the term itself.
        let (span, k) = if message.contains("is not a state") {
            (r.state.as_ref().map(|v| v.span()), "state")
        } else if message.starts_with("no mode") {
            (r.mode.as_ref().map(|v| v.span()), "mode")
        } else if message.starts_with("no guard") {
            (r.guard.as_ref().map(|v| v.span()), "guard")
        } else if message.contains("already a name") || message.contains("usable name") {
            (Some(r.parameters.span()), "parameters")
        } else {
            (Some(r.term.span()), "term")
        };
        return Err(src.error(span.as_ref(), &key(k), message));
    }
    // A moved guard's cost is not convex in the shift: try both signs.
    let start = if r.guard.is_some() {
        htfid_diagnose::TermStart::BothSigns
    } else {
        htfid_diagnose::TermStart::Given
    };
    Ok(htfid_diagnose::TermEffect {
        name,
        extension,
        start,
        placed: None,
        linear_part: None,
    })
}
