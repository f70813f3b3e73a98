//! `[model]` and `[forcing]`: the built-in hopper with its effects, or a model file with
//! overrides, and the checks that keep its scales simulable.

use super::*;

/// Where the built-in hopper's numbers are written.
pub(super) struct HopperSpans {
    pub(super) m: Option<Range<usize>>,
    pub(super) k: Option<Range<usize>>,
    pub(super) c: Option<Range<usize>>,
    pub(super) g: Option<Range<usize>>,
    pub(super) x0: Option<Range<usize>>,
    pub(super) amplitude: Option<Range<usize>>,
}

/// Lengths beyond this (m) mean a unit slip, not a hopper, and overflow the simulation's squares.
const MAX_LENGTH: f64 = 1e6;
/// The natural period may be this many times shorter or longer than the forcing period: one
/// adaptive simulation still resolves both with steps of sensible size.
const MAX_PERIOD_RATIO: f64 = 1e4;
/// Damping ratios beyond this lock the damper rigidly and make the equations stiff.
const MAX_DAMPING_RATIO: f64 = 1e4;

/// `model.damper`: `"switching"` (the default) or `"always_on"`.
pub(super) fn damper_law(
    src: &Source,
    damper: Option<&Spanned<String>>,
) -> Result<DamperLaw, ConfigError> {
    Ok(match damper {
        None => DamperLaw::Switching,
        Some(d) => match src.choice(d, "model.damper", &["switching", "always_on"])? {
            "always_on" => DamperLaw::AlwaysOn,
            _ => DamperLaw::Switching,
        },
    })
}

/// Refuses hopper parameters that are each finite but leave no meaningful simulation: an
/// overflowing static sag (`g = 1e308`), a natural period no step size can share with the
/// forcing period (`k = 1e300` hangs the integrator, `m = 1e-300` collapses its step).
pub(super) fn check_hopper_scales(
    src: &Source,
    p: &HopperParams,
    forced: bool,
    at: &HopperSpans,
) -> Result<(), ConfigError> {
    let natural = 2.0 * std::f64::consts::PI * (p.m / p.k).sqrt();
    let ratio = natural / p.period;
    if forced && !(1.0 / MAX_PERIOD_RATIO..=MAX_PERIOD_RATIO).contains(&ratio) {
        // Name the parameter further from the forcing's scale.
        let (key, span) = if p.m.log10().abs() > p.k.log10().abs() {
            ("model.m", &at.m)
        } else {
            ("model.k", &at.k)
        };
        return Err(src.error(
            span.as_ref(),
            key,
            format!(
                "the natural period 2 pi sqrt(m / k) = {natural:e} s must be within \
                 {MAX_PERIOD_RATIO:e} times the forcing period {} s either way, or one simulation \
                 cannot resolve both (got m = {}, k = {})",
                show(p.period),
                show(p.m),
                show(p.k)
            ),
        ));
    }
    // A free mass (k = 0, diagnosis only) has no damping ratio, static sag or deflection.
    let free_mass = p.k == 0.0;
    let per_k = |force: f64| if free_mass { 0.0 } else { force / p.k };
    let zeta = p.c / (2.0 * (p.k * p.m).sqrt());
    if !free_mass && zeta > MAX_DAMPING_RATIO {
        return Err(src.error(
            at.c.as_ref(),
            "model.c",
            format!(
                "the damping ratio c / (2 sqrt(k m)) = {zeta:e} must be <= {MAX_DAMPING_RATIO:e}: \
                 beyond it the damper locks the mass and the equations are too stiff to \
                 integrate (got c = {})",
                show(p.c)
            ),
        ));
    }
    for (key, span, what, length, got) in [
        (
            "model.g",
            &at.g,
            "the spring's static sag m g / k",
            per_k(p.m * p.g),
            format!("g = {}", show(p.g)),
        ),
        (
            "model.x0",
            &at.x0,
            "the spring rest length x0",
            p.x0,
            format!("x0 = {}", show(p.x0)),
        ),
        (
            "forcing.amplitude",
            &at.amplitude,
            "the static deflection amplitude / k",
            per_k(p.forcing_amplitude),
            format!("amplitude = {}", show(p.forcing_amplitude)),
        ),
    ] {
        if length.is_nan() || length.abs() > MAX_LENGTH {
            return Err(src.error(
                span.as_ref(),
                key,
                format!(
                    "{what} = {length:e} m must be within +-{MAX_LENGTH:e} m, or the simulation \
                     overflows (got {got})"
                ),
            ));
        }
    }
    Ok(())
}

/// Refuses effects that are finite but swamp the hopper they are added to (a cubic spring a
/// million times the linear one at the hopper's size, a lag of ten thousand periods): such
/// values overflow or stall the simulation, whose message could not name the key.
fn check_effect_scales(
    src: &Source,
    p: &HopperParams,
    e: &Effects,
    raw: &RawEffects,
    table: &str,
) -> Result<(), ConfigError> {
    // The hopper's length scale: its static sag, forced deflection or rest length, and at
    // least 1 mm so an unforced, weightless hopper still has one.
    let length = (p.m * p.g / p.k)
        .abs()
        .max((p.forcing_amplitude / p.k).abs())
        .max(p.x0.abs())
        .max(1e-3);
    let omega = (p.k / p.m).sqrt();
    let critical = 2.0 * (p.k * p.m).sqrt();
    let stop_k = e.hard_stop.map_or(0.0, |h| h.k_stop);
    let stop_x = e.hard_stop.map_or(0.0, |h| h.x_stop);
    // A key's value as written (0 where absent).
    let given = |v: &OptNum| v.as_ref().map_or(0.0, |v| *v.get_ref());
    // The levels of asymmetric friction come before `mu` and `input_offset`, which they set.
    let checks: [(&str, &OptNum, f64, f64, String); 12] = [
        (
            "k3",
            &raw.k3,
            (e.k3 * length * length / p.k).abs(),
            1e6,
            format!(
                "the cubic force's share k3 L^2 / k at the hopper's length L = {} m",
                show(length)
            ),
        ),
        (
            "c2",
            &raw.c2,
            e.c2 * length * omega / critical,
            MAX_DAMPING_RATIO,
            "the quadratic drag's damping ratio c2 L wn / (2 sqrt(k m))".to_owned(),
        ),
        (
            "c_f",
            &raw.c_f,
            e.c_f / critical,
            MAX_DAMPING_RATIO,
            "the flight damping ratio c_f / (2 sqrt(k m))".to_owned(),
        ),
        (
            "mu_pos",
            &raw.mu_pos,
            given(&raw.mu_pos) / p.k,
            MAX_LENGTH,
            "the friction force's deflection mu_pos / k (m)".to_owned(),
        ),
        (
            "mu_neg",
            &raw.mu_neg,
            given(&raw.mu_neg) / p.k,
            MAX_LENGTH,
            "the friction force's deflection mu_neg / k (m)".to_owned(),
        ),
        (
            "mu",
            &raw.mu,
            e.mu / p.k,
            MAX_LENGTH,
            "the friction force's deflection mu / k (m)".to_owned(),
        ),
        (
            "input_offset",
            &raw.input_offset,
            (e.input_offset / p.k).abs(),
            MAX_LENGTH,
            "the offset's deflection |input_offset| / k (m)".to_owned(),
        ),
        (
            "tau",
            &raw.tau,
            e.tau / p.period,
            MAX_PERIOD_RATIO,
            "the lag in forcing periods, tau / T".to_owned(),
        ),
        (
            "delay",
            &raw.delay,
            e.delay / p.period,
            MAX_PERIOD_RATIO,
            "the delay in forcing periods, delay / T".to_owned(),
        ),
        (
            "tau_s",
            &raw.tau_s,
            given(&raw.tau_s) / p.period,
            MAX_PERIOD_RATIO,
            "the sensor's lag in forcing periods, tau_s / T".to_owned(),
        ),
        (
            "k_stop",
            &raw.k_stop,
            stop_k / p.k,
            MAX_PERIOD_RATIO * MAX_PERIOD_RATIO,
            "the stop's stiffness against the spring's, k_stop / k".to_owned(),
        ),
        (
            "x_stop",
            &raw.x_stop,
            stop_x.abs(),
            MAX_LENGTH,
            "the stop's position |x_stop| (m)".to_owned(),
        ),
    ];
    for (name, raw_value, value, limit, what) in checks {
        if value.is_nan() || value > limit {
            let got = given(raw_value);
            return Err(src.error(
                raw_value.as_ref().map(Spanned::span).as_ref(),
                &format!("{table}.{name}"),
                format!(
                    "{what} = {value:.3e} must be <= {limit:e}, or the simulation overflows or \
                     stalls (got {name} = {})",
                    show(got)
                ),
            ));
        }
    }
    Ok(())
}

/// Reads `[model]` (and `[forcing]`, `[effects]` for the built-in hopper).
pub(super) fn resolve_system(src: &Source, raw: &RawConfig) -> Result<System, ConfigError> {
    let m = &raw.model;
    let language = m.file.is_some() || m.states.is_some();
    if !language {
        let why = "for the built-in hopper (or give model.file = \"models/NAME.toml\")";
        let forcing = raw
            .forcing
            .as_ref()
            .ok_or_else(|| src.error(None, "forcing", format!("is required {why}")))?;
        for (v, key) in [
            (&m.parameters.is_some(), "model.parameters"),
            (&m.inline_keys().is_some(), "model"),
        ] {
            if *v {
                return Err(src.error(
                    None,
                    key,
                    "model-language keys need model.file or model.states (see docs/models.md)",
                ));
            }
        }
        let params = HopperParams {
            m: src.positive(src.require(&m.m, "model.m", why)?, "model.m")?,
            k: src.positive(src.require(&m.k, "model.k", why)?, "model.k")?,
            c: src.non_negative(src.require(&m.c, "model.c", why)?, "model.c")?,
            g: src.finite(src.require(&m.g, "model.g", why)?, "model.g")?,
            x0: src.finite(src.require(&m.x0, "model.x0", why)?, "model.x0")?,
            forcing_amplitude: src.finite(&forcing.amplitude, "forcing.amplitude")?,
            period: src.positive(&forcing.period, "forcing.period")?,
        };
        let span = |v: &OptNum| v.as_ref().map(Spanned::span);
        check_hopper_scales(
            src,
            &params,
            true,
            &HopperSpans {
                m: span(&m.m),
                k: span(&m.k),
                c: span(&m.c),
                g: span(&m.g),
                x0: span(&m.x0),
                amplitude: Some(forcing.amplitude.span()),
            },
        )?;
        let damper = damper_law(src, m.damper.as_ref())?;
        let effects = resolve_effects(src, raw.effects.as_ref(), "effects")?;
        let sensor = resolve_sensor(src, raw.effects.as_ref(), "effects")?;
        if let Some(e) = &raw.effects {
            check_effect_scales(src, &params, &effects, e, "effects")?;
        }
        return Ok(System::Hopper {
            params,
            damper,
            effects,
            sensor,
        });
    }
    let why = "with a model-language model (its parameters are in [model.parameters])";
    for (v, key) in [
        (&m.m, "model.m"),
        (&m.k, "model.k"),
        (&m.c, "model.c"),
        (&m.g, "model.g"),
        (&m.x0, "model.x0"),
    ] {
        src.forbid(v, key, why)?;
    }
    src.forbid(&m.damper, "model.damper", why)?;
    if let Some(f) = &raw.forcing {
        return Err(src.error(
            Some(&f.period.span()),
            "forcing",
            "is not used with a model-language model: its [forcing] is part of the model",
        ));
    }
    if raw.effects.is_some() {
        return Err(src.error(
            None,
            "effects",
            "is not used with a model-language model: write the effect into the model",
        ));
    }
    let lang_error = |e: htfid_lang::ModelError| ConfigError {
        path: src.path.clone(),
        line: None,
        column: None,
        key: "model".into(),
        message: e.to_string(),
    };
    let model = match &m.file {
        Some(file) => {
            if let Some(key) = m.inline_keys() {
                return Err(src.error(
                    Some(&file.span()),
                    &format!("model.{key}"),
                    "give the model either in model.file or inline, not both",
                ));
            }
            let dir = src.path.parent().unwrap_or(Path::new("."));
            let path = dir.join(file.get_ref());
            let model = htfid_lang::Model::from_file(&path).map_err(lang_error)?;
            match &m.parameters {
                None => model,
                Some(table) => with_overrides(src, model, table)?,
            }
        }
        None => htfid_lang::Model::from_document(&src.text, Some(&src.path), &["model"])
            .map_err(lang_error)?,
    };
    Ok(System::Model(Box::new(model)))
}

/// `model` with the values of a `[model.parameters]` table; a wrong entry is reported at its
/// own line.
pub fn with_overrides(
    src: &Source,
    model: htfid_lang::Model,
    table: &Spanned<toml::Table>,
) -> Result<htfid_lang::Model, ConfigError> {
    let at = |name: &str| {
        src.key_in_table(table.span().start, name)
            .unwrap_or_else(|| table.span())
    };
    let mut changes = Vec::new();
    for (name, value) in table.get_ref() {
        let v = match value {
            toml::Value::Float(f) => *f,
            toml::Value::Integer(i) => *i as f64,
            _ => {
                return Err(src.error(
                    Some(&at(name)),
                    &format!("model.parameters.{name}"),
                    "must be a number (a new value for the model's parameter)",
                ))
            }
        };
        changes.push((name.as_str(), v));
    }
    model.with_parameters(&changes).map_err(|e| {
        let (span, key) = match &e {
            htfid_lang::ModelError::Parameter { name, .. } => {
                (at(name), format!("model.parameters.{name}"))
            }
            _ => (table.span(), "model.parameters".to_string()),
        };
        src.error(Some(&span), &key, e.to_string())
    })
}

impl RawModel {
    /// The first inline model-language key present, if any.
    fn inline_keys(&self) -> Option<&'static str> {
        [
            (self.name.is_some(), "name"),
            (self.description.is_some(), "description"),
            (self.states.is_some(), "states"),
            (self.input.is_some(), "input"),
            (self.forcing.is_some(), "forcing"),
            (self.definitions.is_some(), "definitions"),
            (self.flow.is_some(), "flow"),
            (self.modes.is_some(), "modes"),
            (self.guards.is_some(), "guards"),
            (self.outputs.is_some(), "outputs"),
            (self.initial.is_some(), "initial"),
        ]
        .into_iter()
        .find(|(present, _)| *present)
        .map(|(_, k)| k)
    }
}
