//! The experiment config: raw options (as written in TOML) and resolved settings.
//!
//! Every key is documented in `docs/config.md`.

use std::ops::Range;
use std::path::{Path, PathBuf};

use htfid_hybrid::{Method, Options};
use htfid_model::{DamperLaw, Effects, HopperParams};
use serde::Deserialize;
use toml::Spanned;

use crate::config::{load, quote_list, show, ConfigError, Kind, Source};

type Num = Spanned<f64>;
type OptNum = Option<Spanned<f64>>;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawConfig {
    pub name: Option<Spanned<String>>,
    pub model: RawModel,
    pub forcing: Option<RawForcing>,
    #[serde(default)]
    pub simulation: RawSimulation,
    pub excitation: Option<RawExcitation>,
    pub theory: Option<RawTheory>,
    pub noise: Option<RawNoise>,
    pub estimation: Option<RawEstimation>,
    pub effects: Option<RawEffects>,
}

/// Extra physical terms of the simulated system (a "truth" that differs from the nominal
/// hopper); all absent by default.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawEffects {
    pub k3: OptNum,
    pub mu: OptNum,
    pub c_f: OptNum,
    pub c2: OptNum,
    pub tau: OptNum,
    pub delay: OptNum,
    pub v_th: OptNum,
    pub x_stop: OptNum,
    pub k_stop: OptNum,
    pub input_offset: OptNum,
}

/// Resolves an `[effects]` table.
pub fn resolve_effects(
    src: &Source,
    e: Option<&RawEffects>,
    table: &str,
) -> Result<Effects, ConfigError> {
    let Some(e) = e else {
        return Ok(Effects::default());
    };
    let key = |k: &str| format!("{table}.{k}");
    let any = |v: f64| v.is_finite();
    let nonneg = |v: f64| v >= 0.0;
    let hard_stop = match (&e.x_stop, &e.k_stop) {
        (None, None) => None,
        (Some(x), Some(k)) => Some(htfid_model::HardStop {
            x_stop: src.number(x, &key("x_stop"), "a finite number (m)", any)?,
            k_stop: src.number(k, &key("k_stop"), ">= 0 (N/m)", nonneg)?,
        }),
        (Some(x), None) => {
            return Err(src.error(
                Some(&x.span()),
                &key("x_stop"),
                "needs k_stop too (a hard stop has both)",
            ))
        }
        (None, Some(k)) => {
            return Err(src.error(
                Some(&k.span()),
                &key("k_stop"),
                "needs x_stop too (a hard stop has both)",
            ))
        }
    };
    Ok(Effects {
        k3: src.opt_number(&e.k3, 0.0, &key("k3"), "a finite number (N/m^3)", any)?,
        mu: src.opt_number(&e.mu, 0.0, &key("mu"), ">= 0 (N)", nonneg)?,
        c_f: src.opt_number(&e.c_f, 0.0, &key("c_f"), ">= 0 (N s/m)", nonneg)?,
        c2: src.opt_number(&e.c2, 0.0, &key("c2"), ">= 0 (N s^2/m^2)", nonneg)?,
        tau: src.opt_number(&e.tau, 0.0, &key("tau"), ">= 0 (s)", nonneg)?,
        delay: src.opt_number(&e.delay, 0.0, &key("delay"), ">= 0 (s)", nonneg)?,
        v_th: src.opt_number(&e.v_th, 0.0, &key("v_th"), "a finite number (m/s)", any)?,
        hard_stop,
        input_offset: src.opt_number(
            &e.input_offset,
            0.0,
            &key("input_offset"),
            "a finite number (N)",
            any,
        )?,
    })
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawNoise {
    pub output_std: Num,
    pub seed: Option<Spanned<i64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawEstimation {
    pub harmonics: Option<Spanned<Vec<i64>>>,
    pub omega_min: OptNum,
    pub omega_max: OptNum,
    pub estimators: Option<Spanned<Vec<String>>>,
    pub alpha: Option<Spanned<toml::Value>>,
    pub fit: Option<Spanned<Vec<String>>>,
    pub fit_harmonics: Option<Spanned<Vec<i64>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawModel {
    // The built-in hopper.
    pub m: OptNum,
    pub k: OptNum,
    pub c: OptNum,
    pub g: OptNum,
    pub x0: OptNum,
    pub damper: Option<Spanned<String>>,
    // A model-language model: a file (relative to the config) with parameter overrides, or
    // the model written inline (read by htfid-lang, which locates its own errors).
    pub file: Option<Spanned<String>>,
    pub parameters: Option<Spanned<toml::Table>>,
    pub name: Option<toml::Value>,
    pub description: Option<toml::Value>,
    pub states: Option<toml::Value>,
    pub input: Option<toml::Value>,
    pub forcing: Option<toml::Value>,
    pub definitions: Option<toml::Value>,
    pub flow: Option<toml::Value>,
    pub modes: Option<toml::Value>,
    pub guards: Option<toml::Value>,
    pub outputs: Option<toml::Value>,
    pub initial: Option<toml::Value>,
}

/// The system an experiment is about.
#[derive(Debug, Clone)]
pub enum System {
    /// The built-in hopper (`[model] m = ..., k = ...` with `[forcing]`).
    Hopper {
        params: HopperParams,
        damper: DamperLaw,
        effects: Effects,
    },
    /// A model written in the model language (`[model] file = "..."`, or inline).
    Model(Box<htfid_lang::Model>),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawForcing {
    pub amplitude: Num,
    pub period: Num,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawSimulation {
    pub settle_periods: Option<Spanned<i64>>,
    pub sample_rate: OptNum,
    pub rtol: OptNum,
    pub atol: OptNum,
    pub method: Option<Spanned<String>>,
    pub max_steps: Option<Spanned<i64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawExcitation {
    pub kind: Spanned<String>,
    pub waveform: Option<Spanned<String>>,
    pub f_start_hz: OptNum,
    pub f_end_hz: OptNum,
    pub duration: OptNum,
    pub amplitude: OptNum,
    pub copies: Option<Spanned<i64>>,
    pub max_harmonic: Option<Spanned<i64>>,
    pub omega_min: OptNum,
    pub omega_max: OptNum,
    pub spacing: OptNum,
    pub even_order: Option<Spanned<String>>,
    pub phases: Option<Spanned<String>>,
    pub seed: Option<Spanned<i64>>,
    pub settle: OptNum,
    pub max_record: OptNum,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawTheory {
    pub harmonics: Option<Spanned<Vec<i64>>>,
    pub omega_min: OptNum,
    pub omega_max: OptNum,
    pub points: Option<Spanned<i64>>,
    pub spacing: Option<Spanned<String>>,
    pub plot_harmonics: Option<Spanned<Vec<i64>>>,
}

/// Resolved, range-checked settings of one experiment.
#[derive(Debug, Clone)]
pub struct Settings {
    pub name: String,
    pub path: PathBuf,
    pub system: System,
    /// The forcing period, s.
    pub period: f64,
    pub settle_periods: usize,
    pub sample_rate: f64,
    pub integrator: Options,
    pub excitation: Excitation,
    pub theory: TheorySettings,
    pub noise: Option<NoiseSettings>,
    pub estimation: EstimationSettings,
    /// A model file's `[model.parameters]` overrides and the model as the file has it, so a
    /// failure of the configured model can be traced to the override that causes it.
    pub overrides: Option<Overrides>,
}

/// The parameter overrides of a model-file config.
#[derive(Debug, Clone)]
pub struct Overrides {
    /// The model with the file's own values.
    pub base: Box<htfid_lang::Model>,
    /// Each override: name, value and where it is written (line, column).
    pub entries: Vec<(String, f64, usize, usize)>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseSettings {
    pub output_std: f64,
    pub seed: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Estimator {
    Siddiqi,
    Multi,
    Lines,
}

impl Estimator {
    pub fn name(self) -> &'static str {
        match self {
            Estimator::Siddiqi => "siddiqi",
            Estimator::Multi => "multi",
            Estimator::Lines => "lines",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AlphaSetting {
    Fixed(f64),
    Gcv,
}

#[derive(Debug, Clone, PartialEq)]
pub struct EstimationSettings {
    pub harmonics: Vec<i32>,
    pub band: (f64, f64),
    pub estimators: Vec<Estimator>,
    pub alpha: AlphaSetting,
    /// Model parameters fitted to the estimates (names checked against the system's).
    pub fit: Vec<String>,
    pub fit_harmonics: Vec<i32>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Waveform {
    /// `u = a sin(14 pi t^2 / 30)`, exactly as printed in the paper (rises to 14 Hz).
    Paper,
    Linear,
    Log,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EvenOrderSetting {
    SignReversal,
    QuadraticGuard,
    Unprotected,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PhaseSetting {
    Schroeder,
    Random(u64),
}

#[derive(Debug, Clone, PartialEq)]
pub enum Excitation {
    None,
    /// A periodic multisine designed so that every (line, harmonic) pair has its own output bin.
    MultisineDesign {
        max_harmonic: u32,
        omega_min: f64,
        omega_max: f64,
        spacing: f64,
        amplitude: f64,
        even_order: EvenOrderSetting,
        phases: PhaseSetting,
        settle: f64,
        max_record: f64,
    },
    ChirpTrain {
        waveform: Waveform,
        f_start_hz: f64,
        f_end_hz: f64,
        duration: f64,
        amplitude: f64,
        copies: usize,
    },
}

impl Excitation {
    /// The input's amplitude, if there is an input.
    pub fn amplitude(&self) -> Option<f64> {
        match self {
            Excitation::None => None,
            Excitation::MultisineDesign { amplitude, .. }
            | Excitation::ChirpTrain { amplitude, .. } => Some(*amplitude),
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct TheorySettings {
    pub harmonics: Vec<i32>,
    pub omegas: Vec<f64>,
    pub plot_harmonics: Vec<i32>,
}

/// Largest smoothness weight `estimation.alpha` accepts. The weight is dimensionless
/// (`alpha = 1` weighs one bin's curvature like one bin's data), and the second-difference
/// penalty leaves straight lines free: far above the data, the normal matrix keeps the data's
/// part only in its last digits and its Cholesky factor breaks down. Cross-validation searches
/// 1e-8..1e4; 1e6 leaves two decades above that.
pub const ALPHA_MAX: f64 = 1e6;

/// `estimation.alpha`: a number in [0, [`ALPHA_MAX`]], or `"gcv"` (returned as `None`).
pub(crate) fn smoothness_weight(
    src: &Source,
    v: &Spanned<toml::Value>,
) -> Result<Option<f64>, ConfigError> {
    let weight = match v.get_ref() {
        toml::Value::String(s) if s == "gcv" => return Ok(None),
        toml::Value::Float(f) => Some(*f),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    };
    match weight {
        Some(a) if a.is_finite() && (0.0..=ALPHA_MAX).contains(&a) => Ok(Some(a)),
        _ => Err(src.error(
            Some(&v.span()),
            "estimation.alpha",
            format!(
                "must be a number in [0, {ALPHA_MAX:e}] or \"gcv\" (got {}); a larger weight \
                 drowns the data in the smoothness penalty",
                v.get_ref()
            ),
        )),
    }
}

fn int_in(src: &Source, v: &Spanned<i64>, key: &str, lo: i64, hi: i64) -> Result<i64, ConfigError> {
    let x = *v.get_ref();
    if (lo..=hi).contains(&x) {
        Ok(x)
    } else {
        Err(src.error(
            Some(&v.span()),
            key,
            format!("must be an integer in {lo}..={hi} (got {x})"),
        ))
    }
}

fn harmonics_list(src: &Source, v: &Spanned<Vec<i64>>, key: &str) -> Result<Vec<i32>, ConfigError> {
    let list = v.get_ref();
    if list.is_empty() {
        return Err(src.error(Some(&v.span()), key, "must list at least one harmonic"));
    }
    let mut out = Vec::with_capacity(list.len());
    for &n in list {
        if !(-50..=50).contains(&n) {
            return Err(src.error(
                Some(&v.span()),
                key,
                format!("harmonics must lie in -50..=50 (got {n})"),
            ));
        }
        if out.contains(&(n as i32)) {
            return Err(src.error(
                Some(&v.span()),
                key,
                format!("harmonic {n} is listed twice"),
            ));
        }
        out.push(n as i32);
    }
    Ok(out)
}

impl Settings {
    /// Loads and resolves a config file.
    pub fn from_file(path: &Path) -> Result<Settings, ConfigError> {
        let (raw, src): (RawConfig, Source) = load(path, Kind::Experiment)?;
        Self::resolve(raw, &src)
    }

    pub fn resolve(raw: RawConfig, src: &Source) -> Result<Settings, ConfigError> {
        let name = match &raw.name {
            Some(n) => {
                let s = n.get_ref().trim().to_string();
                if s.is_empty() || s.contains(['/', '\\']) || s.starts_with('.') {
                    return Err(src.error(
                        Some(&n.span()),
                        "name",
                        format!("must be a plain file name (no slashes, not empty, not starting with '.') (got \"{s}\")"),
                    ));
                }
                s
            }
            None => src
                .path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "experiment".into()),
        };
        let system = resolve_system(src, &raw)?;
        let overrides = match (&raw.model.file, &raw.model.parameters) {
            (Some(file), Some(table)) => {
                let dir = src.path.parent().unwrap_or(Path::new("."));
                // Read without error: the same file was just read successfully.
                htfid_lang::Model::from_file(&dir.join(file.get_ref()))
                    .ok()
                    .map(|base| Overrides {
                        base: Box::new(base),
                        entries: table
                            .get_ref()
                            .iter()
                            .filter_map(|(name, v)| {
                                let value = v.as_float().or(v.as_integer().map(|i| i as f64))?;
                                let at = src
                                    .key_in_table(table.span().start, name)
                                    .unwrap_or_else(|| table.span());
                                Some((name.clone(), value, src.line_of(&at), src.column_of(&at)))
                            })
                            .collect(),
                    })
            }
            _ => None,
        };
        let period = match &system {
            System::Hopper { params, .. } => params.period,
            System::Model(model) => model.period().ok_or_else(|| {
                src.error(
                    None,
                    "model",
                    "the model has no [forcing] with a period: an experiment needs a forced orbit",
                )
            })?,
        };
        let s = &raw.simulation;
        let settle_periods = match &s.settle_periods {
            Some(v) => int_in(src, v, "simulation.settle_periods", 0, 100_000)? as usize,
            None => 30,
        };
        let sample_rate = src.opt_number(
            &s.sample_rate,
            100.0,
            "simulation.sample_rate",
            "> 0 (Hz)",
            |v| v > 0.0,
        )?;
        let mut integrator = Options {
            // Below these the error target is finer than double-precision rounding of the
            // states (rtol: a few dozen ulps; atol: of a state crossing zero), the step size
            // collapses and the message would wrongly say "no limit cycle".
            rtol: src.opt_number(
                &s.rtol,
                1e-10,
                "simulation.rtol",
                "in [1e-14, 0.1] (below 1e-14 the target is finer than double-precision rounding)",
                |v| (1e-14..=0.1).contains(&v),
            )?,
            atol: src.opt_number(
                &s.atol,
                1e-12,
                "simulation.atol",
                "in [1e-20, 0.1] (below 1e-20 the target is finer than the rounding of a state \
                 near zero, and the step size collapses)",
                |v| (1e-20..=0.1).contains(&v),
            )?,
            ..Options::default()
        };
        if let Some(v) = &s.max_steps {
            integrator.max_steps = int_in(src, v, "simulation.max_steps", 1, i64::MAX)? as u64;
        }
        if let Some(method) = &s.method {
            integrator.method =
                match src.choice(method, "simulation.method", &["dop853", "dopri5"])? {
                    "dopri5" => Method::Dopri5,
                    _ => Method::Dop853,
                };
        }
        let excitation = match &raw.excitation {
            None => Excitation::None,
            Some(e) => resolve_excitation(src, e, period)?,
        };
        let theory = resolve_theory(src, raw.theory.as_ref())?;
        let noise = match &raw.noise {
            None => None,
            Some(n) => Some(NoiseSettings {
                // Noise beyond 1e6 output units swamps any measurement, and past 1e307 its
                // samples overflow to inf in the written record.
                output_std: src.number(
                    &n.output_std,
                    "noise.output_std",
                    "in [0, 1e6] (in the outputs' units)",
                    |v| (0.0..=1e6).contains(&v),
                )?,
                seed: match &n.seed {
                    Some(v) => int_in(src, v, "noise.seed", 0, i64::MAX)? as u64,
                    None => 1,
                },
            }),
        };
        let estimation = resolve_estimation(
            src,
            raw.estimation.as_ref(),
            &excitation,
            &system,
            (period, sample_rate),
        )?;
        Ok(Settings {
            name,
            path: src.path.clone(),
            system,
            period,
            settle_periods,
            sample_rate,
            integrator,
            excitation,
            theory,
            noise,
            estimation,
            overrides,
        })
    }

    /// Time at which the excitation starts (end of settling), s.
    pub fn settle_time(&self) -> f64 {
        self.settle_periods as f64 * self.period
    }

    /// The sample grid of the experiment's record, from `t = 0` to its end: a whole number of
    /// periods after the settling, covering an excitation that ends at `excitation_end`, so the
    /// estimators can use all of it.
    pub fn record_grid(&self, excitation_end: f64) -> (f64, Vec<f64>) {
        let (start, period) = (self.settle_time(), self.period);
        let end = start + ((excitation_end - start).max(0.0) / period - 1e-9).ceil() * period;
        let end = end.max(period);
        let dt = 1.0 / self.sample_rate;
        let n = (end / dt + 1e-9).floor() as usize + 1;
        (end, (0..n).map(|i| i as f64 * dt).collect())
    }

    /// The built-in hopper's settings, or an error for a command that does not take
    /// model-language configs yet.
    pub fn hopper(&self, command: &str) -> Result<(HopperParams, DamperLaw, Effects), ConfigError> {
        match &self.system {
            System::Hopper {
                params,
                damper,
                effects,
            } => Ok((*params, *damper, *effects)),
            System::Model(_) => Err(ConfigError {
                path: self.path.clone(),
                line: None,
                column: None,
                key: "model".into(),
                message: format!(
                    "this part of `htfid {command}` takes the built-in hopper ([model] m, k, c, \
                     g, x0) only"
                ),
            }),
        }
    }
}

/// Where the built-in hopper's numbers are written.
struct HopperSpans {
    m: Option<Range<usize>>,
    k: Option<Range<usize>>,
    c: Option<Range<usize>>,
    g: Option<Range<usize>>,
    x0: Option<Range<usize>>,
    amplitude: Option<Range<usize>>,
}

/// Lengths beyond this (m) mean a unit slip, not a hopper, and overflow the simulation's squares.
const MAX_LENGTH: f64 = 1e6;
/// The natural period may be this many times shorter or longer than the forcing period: one
/// adaptive simulation still resolves both with steps of sensible size.
const MAX_PERIOD_RATIO: f64 = 1e4;
/// Damping ratios beyond this lock the damper rigidly and make the equations stiff.
const MAX_DAMPING_RATIO: f64 = 1e4;

/// Refuses hopper parameters that are each finite but leave no meaningful simulation: an
/// overflowing static sag (`g = 1e308`), a natural period no step size can share with the
/// forcing period (`k = 1e300` hangs the integrator, `m = 1e-300` collapses its step).
fn check_hopper_scales(
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
    let zeta = p.c / (2.0 * (p.k * p.m).sqrt());
    if zeta > MAX_DAMPING_RATIO {
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
            p.m * p.g / p.k,
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
            p.forcing_amplitude / p.k,
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
    let checks: [(&str, &OptNum, f64, f64, String); 9] = [
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
            let got = raw_value.as_ref().map_or(0.0, |v| *v.get_ref());
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
fn resolve_system(src: &Source, raw: &RawConfig) -> Result<System, ConfigError> {
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
        let damper = match &m.damper {
            None => DamperLaw::Switching,
            Some(d) => match src.choice(d, "model.damper", &["switching", "always_on"])? {
                "always_on" => DamperLaw::AlwaysOn,
                _ => DamperLaw::Switching,
            },
        };
        let effects = resolve_effects(src, raw.effects.as_ref(), "effects")?;
        if let Some(e) = &raw.effects {
            check_effect_scales(src, &params, &effects, e, "effects")?;
        }
        return Ok(System::Hopper {
            params,
            damper,
            effects,
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
        let span = match &e {
            htfid_lang::ModelError::Parameter { name, .. } => at(name),
            _ => table.span(),
        };
        src.error(Some(&span), "model.parameters", e.to_string())
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

fn resolve_excitation(
    src: &Source,
    e: &RawExcitation,
    _period: f64,
) -> Result<Excitation, ConfigError> {
    let multisine_only: [(&Option<Spanned<f64>>, &str); 5] = [
        (&e.omega_min, "excitation.omega_min"),
        (&e.omega_max, "excitation.omega_max"),
        (&e.spacing, "excitation.spacing"),
        (&e.settle, "excitation.settle"),
        (&e.max_record, "excitation.max_record"),
    ];
    match src.choice(
        &e.kind,
        "excitation.kind",
        &["none", "chirp_train", "multisine_design"],
    )? {
        "multisine_design" => {
            let why = "with kind = \"multisine_design\"";
            src.forbid(&e.waveform, "excitation.waveform", why)?;
            src.forbid(&e.copies, "excitation.copies", why)?;
            src.forbid(&e.f_start_hz, "excitation.f_start_hz", why)?;
            src.forbid(&e.f_end_hz, "excitation.f_end_hz", why)?;
            src.forbid(&e.duration, "excitation.duration", why)?;
            let max_harmonic = match &e.max_harmonic {
                Some(v) => int_in(src, v, "excitation.max_harmonic", 0, 50)? as u32,
                None => 3,
            };
            let omega_min = src.opt_number(
                &e.omega_min,
                1.0,
                "excitation.omega_min",
                "> 0 (rad/s)",
                |v| v > 0.0,
            )?;
            let omega_max = src.opt_number(
                &e.omega_max,
                40.0,
                "excitation.omega_max",
                &format!("> omega_min ({omega_min})"),
                |v| v > omega_min,
            )?;
            let spacing =
                src.opt_number(&e.spacing, 0.45, "excitation.spacing", "> 0 (rad/s)", |v| {
                    v > 0.0
                })?;
            let amplitude = src.positive(
                src.require(&e.amplitude, "excitation.amplitude", why)?,
                "excitation.amplitude",
            )?;
            let even_order = match &e.even_order {
                None => EvenOrderSetting::SignReversal,
                Some(v) => match src.choice(
                    v,
                    "excitation.even_order",
                    &["sign_reversal", "quadratic_guard", "unprotected"],
                )? {
                    "quadratic_guard" => EvenOrderSetting::QuadraticGuard,
                    "unprotected" => EvenOrderSetting::Unprotected,
                    _ => EvenOrderSetting::SignReversal,
                },
            };
            let seed = match &e.seed {
                Some(v) => Some(int_in(src, v, "excitation.seed", 0, i64::MAX)? as u64),
                None => None,
            };
            let phases = match &e.phases {
                None => PhaseSetting::Schroeder,
                Some(v) => match src.choice(v, "excitation.phases", &["schroeder", "random"])? {
                    "random" => PhaseSetting::Random(seed.unwrap_or(1)),
                    _ => PhaseSetting::Schroeder,
                },
            };
            let settle = src.opt_number(&e.settle, 20.0, "excitation.settle", ">= 0 (s)", |v| {
                v >= 0.0
            })?;
            let max_record = src.opt_number(
                &e.max_record,
                600.0,
                "excitation.max_record",
                "> 0 (s)",
                |v| v > 0.0,
            )?;
            Ok(Excitation::MultisineDesign {
                max_harmonic,
                omega_min,
                omega_max,
                spacing,
                amplitude,
                even_order,
                phases,
                settle,
                max_record,
            })
        }
        "none" => {
            let why = "when excitation.kind = \"none\"";
            for (v, key) in multisine_only {
                src.forbid(v, key, why)?;
            }
            src.forbid(&e.waveform, "excitation.waveform", why)?;
            src.forbid(&e.amplitude, "excitation.amplitude", why)?;
            src.forbid(&e.copies, "excitation.copies", why)?;
            Ok(Excitation::None)
        }
        _ => {
            for (v, key) in multisine_only {
                src.forbid(v, key, "with kind = \"chirp_train\"")?;
            }
            src.forbid(
                &e.max_harmonic,
                "excitation.max_harmonic",
                "with kind = \"chirp_train\"",
            )?;
            src.forbid(
                &e.even_order,
                "excitation.even_order",
                "with kind = \"chirp_train\"",
            )?;
            src.forbid(
                &e.phases,
                "excitation.phases",
                "with kind = \"chirp_train\"",
            )?;
            let waveform = match &e.waveform {
                None => Waveform::Linear,
                Some(w) => {
                    match src.choice(w, "excitation.waveform", &["paper", "linear", "log"])? {
                        "paper" => Waveform::Paper,
                        "log" => Waveform::Log,
                        _ => Waveform::Linear,
                    }
                }
            };
            let copies = match &e.copies {
                Some(v) => int_in(src, v, "excitation.copies", 1, 1000)? as usize,
                None => 1,
            };
            let (f_start_hz, f_end_hz, duration, amplitude) = if waveform == Waveform::Paper {
                let why = "with waveform = \"paper\" (the paper's chirp is fixed: 0.004 sin(14 pi t^2/30), 30 s)";
                src.forbid(&e.f_start_hz, "excitation.f_start_hz", why)?;
                src.forbid(&e.f_end_hz, "excitation.f_end_hz", why)?;
                src.forbid(&e.duration, "excitation.duration", why)?;
                src.forbid(&e.amplitude, "excitation.amplitude", why)?;
                (0.0, 14.0, 30.0, 0.004)
            } else {
                let why = "for a linear or log chirp";
                let f0 = src.non_negative(
                    src.require(&e.f_start_hz, "excitation.f_start_hz", why)?,
                    "excitation.f_start_hz",
                )?;
                let f1v = src.require(&e.f_end_hz, "excitation.f_end_hz", why)?;
                let f1 = src.number(
                    f1v,
                    "excitation.f_end_hz",
                    &format!("> f_start_hz ({f0})"),
                    |v| v > f0,
                )?;
                if waveform == Waveform::Log && f0 <= 0.0 {
                    return Err(src.error(
                        e.f_start_hz.as_ref().map(|v| v.span()).as_ref(),
                        "excitation.f_start_hz",
                        "must be > 0 for a log chirp (got 0)",
                    ));
                }
                let d = src.positive(
                    src.require(&e.duration, "excitation.duration", why)?,
                    "excitation.duration",
                )?;
                let a = src.positive(
                    src.require(&e.amplitude, "excitation.amplitude", why)?,
                    "excitation.amplitude",
                )?;
                (f0, f1, d, a)
            };
            Ok(Excitation::ChirpTrain {
                waveform,
                f_start_hz,
                f_end_hz,
                duration,
                amplitude,
                copies,
            })
        }
    }
}

fn resolve_theory(src: &Source, t: Option<&RawTheory>) -> Result<TheorySettings, ConfigError> {
    let default_h: Vec<i32> = (-3..=3).collect();
    let Some(t) = t else {
        return Ok(TheorySettings {
            harmonics: default_h.clone(),
            omegas: log_grid(1.0, 40.0, 400),
            plot_harmonics: default_h,
        });
    };
    let harmonics = match &t.harmonics {
        Some(h) => harmonics_list(src, h, "theory.harmonics")?,
        None => default_h,
    };
    let lo = src.opt_number(&t.omega_min, 1.0, "theory.omega_min", "> 0 (rad/s)", |v| {
        v > 0.0
    })?;
    let hi = src.opt_number(
        &t.omega_max,
        40.0,
        "theory.omega_max",
        &format!("> omega_min ({lo})"),
        |v| v > lo,
    )?;
    let points = match &t.points {
        Some(p) => int_in(src, p, "theory.points", 2, 1_000_000)? as usize,
        None => 400,
    };
    let omegas = match &t.spacing {
        None => log_grid(lo, hi, points),
        Some(s) => match src.choice(s, "theory.spacing", &["log", "linear"])? {
            "linear" => (0..points)
                .map(|i| lo + (hi - lo) * i as f64 / (points - 1) as f64)
                .collect(),
            _ => log_grid(lo, hi, points),
        },
    };
    let plot_harmonics = match &t.plot_harmonics {
        Some(h) => {
            let list = harmonics_list(src, h, "theory.plot_harmonics")?;
            if let Some(n) = list.iter().find(|n| !harmonics.contains(n)) {
                return Err(src.error(
                    Some(&h.span()),
                    "theory.plot_harmonics",
                    format!("harmonic {n} is not among theory.harmonics {harmonics:?}"),
                ));
            }
            list
        }
        None => harmonics.clone(),
    };
    Ok(TheorySettings {
        harmonics,
        omegas,
        plot_harmonics,
    })
}

/// `points` logarithmically spaced values from `lo` to `hi` inclusive.
pub fn log_grid(lo: f64, hi: f64, points: usize) -> Vec<f64> {
    let (a, b) = (lo.ln(), hi.ln());
    (0..points)
        .map(|i| (a + (b - a) * i as f64 / (points.max(2) - 1) as f64).exp())
        .collect()
}

/// The parameters fitted when `estimation.fit` is not given: `k` and `c` of the hopper, the
/// parameters a model file marks `free`.
fn default_fit(system: &System) -> Vec<String> {
    match system {
        System::Hopper { .. } => vec!["k".into(), "c".into()],
        System::Model(model) => model
            .parameters()
            .iter()
            .filter(|p| p.free)
            .map(|p| p.name.clone())
            .collect(),
    }
}

fn resolve_estimation(
    src: &Source,
    e: Option<&RawEstimation>,
    excitation: &Excitation,
    system: &System,
    (period, sample_rate): (f64, f64),
) -> Result<EstimationSettings, ConfigError> {
    let default_estimators = match excitation {
        Excitation::MultisineDesign { .. } => vec![Estimator::Lines],
        _ => vec![Estimator::Siddiqi, Estimator::Multi],
    };
    let default_h: Vec<i32> = (-3..=3).collect();
    let Some(e) = e else {
        return Ok(EstimationSettings {
            harmonics: default_h,
            band: (1.0, 40.0),
            estimators: default_estimators,
            alpha: AlphaSetting::Fixed(1e-3),
            fit: default_fit(system),
            fit_harmonics: vec![-1, 0, 1],
        });
    };
    let harmonics = match &e.harmonics {
        Some(h) => harmonics_list(src, h, "estimation.harmonics")?,
        None => default_h,
    };
    let lo = src.opt_number(
        &e.omega_min,
        1.0,
        "estimation.omega_min",
        "> 0 (rad/s)",
        |v| v > 0.0,
    )?;
    let hi = src.opt_number(
        &e.omega_max,
        40.0,
        "estimation.omega_max",
        &format!("> omega_min ({lo})"),
        |v| v > lo,
    )?;
    // Every output bin the chirp estimators read, `omega + n omega_T`, must lie below Nyquist.
    let h_max = harmonics
        .iter()
        .map(|h| h.unsigned_abs())
        .max()
        .unwrap_or(0);
    let top = hi + f64::from(h_max) * std::f64::consts::TAU / period;
    let nyquist = std::f64::consts::PI * sample_rate;
    // (A multisine design checks its own lines against Nyquist, with the design's keys.)
    if matches!(excitation, Excitation::ChirpTrain { .. }) && top >= nyquist {
        return Err(src.error(
            e.omega_max.as_ref().map(|v| v.span()).as_ref(),
            "estimation.omega_max",
            format!(
                "= {} rad/s with harmonics up to {h_max} reads outputs up to {} rad/s, at or \
                 beyond the Nyquist frequency {} rad/s of simulation.sample_rate = {} Hz; lower \
                 estimation.omega_max or raise simulation.sample_rate",
                htfid_number::sig(hi, 4),
                htfid_number::sig(top, 4),
                htfid_number::sig(nyquist, 4),
                htfid_number::sig(sample_rate, 4)
            ),
        ));
    }
    let estimators = match &e.estimators {
        None => default_estimators,
        Some(list) => {
            let mut out = Vec::new();
            for name in list.get_ref() {
                let est = match name.as_str() {
                    "siddiqi" => Estimator::Siddiqi,
                    "multi" => Estimator::Multi,
                    "lines" => Estimator::Lines,
                    other => {
                        return Err(src.error(
                            Some(&list.span()),
                            "estimation.estimators",
                            format!("unknown estimator \"{other}\"; expected \"siddiqi\", \"multi\" or \"lines\""),
                        ))
                    }
                };
                let fits = match excitation {
                    Excitation::MultisineDesign { .. } => est == Estimator::Lines,
                    Excitation::ChirpTrain { .. } => est != Estimator::Lines,
                    Excitation::None => false,
                };
                if !fits {
                    return Err(src.error(
                        Some(&list.span()),
                        "estimation.estimators",
                        format!(
                            "estimator \"{name}\" does not fit the excitation: \"lines\" needs kind = \"multisine_design\", \"siddiqi\" and \"multi\" need kind = \"chirp_train\""
                        ),
                    ));
                }
                out.push(est);
            }
            if out.is_empty() {
                return Err(src.error(
                    Some(&list.span()),
                    "estimation.estimators",
                    "must name at least one estimator",
                ));
            }
            out
        }
    };
    let alpha = match &e.alpha {
        None => AlphaSetting::Fixed(1e-3),
        Some(v) => smoothness_weight(src, v)?.map_or(AlphaSetting::Gcv, AlphaSetting::Fixed),
    };
    let fit = match &e.fit {
        None => default_fit(system),
        Some(list) => {
            let known: Vec<&str> = match system {
                System::Hopper { .. } => vec!["k", "c", "m"],
                System::Model(model) => {
                    model.parameters().iter().map(|p| p.name.as_str()).collect()
                }
            };
            if list.get_ref().is_empty() {
                return Err(src.error(
                    Some(&list.span()),
                    "estimation.fit",
                    format!(
                        "must name at least one parameter, among {}",
                        quote_list(&known)
                    ),
                ));
            }
            for (i, name) in list.get_ref().iter().enumerate() {
                if !known.contains(&name.as_str()) {
                    return Err(src.error(
                        Some(&list.span()),
                        "estimation.fit",
                        format!(
                            "unknown parameter \"{name}\"; expected any of {}",
                            quote_list(&known)
                        ),
                    ));
                }
                if list.get_ref()[..i].contains(name) {
                    return Err(src.error(
                        Some(&list.span()),
                        "estimation.fit",
                        format!("parameter \"{name}\" is listed twice"),
                    ));
                }
            }
            list.get_ref().clone()
        }
    };
    let fit_harmonics = match &e.fit_harmonics {
        Some(h) => harmonics_list(src, h, "estimation.fit_harmonics")?,
        None => vec![-1, 0, 1],
    };
    if let Some(n) = fit_harmonics.iter().find(|n| !harmonics.contains(n)) {
        let span = e.fit_harmonics.as_ref().map(|v| v.span());
        return Err(src.error(
            span.as_ref(),
            "estimation.fit_harmonics",
            format!("harmonic {n} is not among estimation.harmonics {harmonics:?}"),
        ));
    }
    if let Excitation::ChirpTrain { copies, .. } = excitation {
        if estimators.contains(&Estimator::Multi) && harmonics.len() > *copies {
            let span = e.harmonics.as_ref().map(|v| v.span());
            return Err(src.error(
                span.as_ref(),
                "estimation.harmonics",
                format!(
                    "{} harmonics cannot be separated with {copies} phase shifts (excitation.copies): \
                     the multi-experiment estimator needs at least as many phase-shifted copies as harmonics",
                    harmonics.len()
                ),
            ));
        }
    }
    Ok(EstimationSettings {
        harmonics,
        band: (lo, hi),
        estimators,
        alpha,
        fit,
        fit_harmonics,
    })
}

// ----------------------------------------------------------------------------------------
// Diagnosis configs (`htfid diagnose`).

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDiagnoseConfig {
    pub name: Option<Spanned<String>>,
    pub data: RawData,
    pub model: RawNominal,
    pub forcing: Option<RawForcing>,
    pub diagnose: Option<RawDiagnoseOptions>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawData {
    pub file: Spanned<String>,
    pub time: Option<Spanned<String>>,
    pub sample_rate: OptNum,
    pub input: Option<Spanned<String>>,
    pub output: Option<Spanned<String>>,
    pub fit: Option<Spanned<Vec<[i64; 2]>>>,
    pub validation: Option<Spanned<Vec<[i64; 2]>>>,
    pub test: Option<Spanned<Vec<[i64; 2]>>>,
    pub time_tolerance: OptNum,
    pub delimiter: Option<Spanned<String>>,
    pub matrix: Option<Spanned<String>>,
    pub columns: Option<Spanned<Vec<String>>>,
    pub units: Option<Spanned<std::collections::BTreeMap<String, String>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawNominal {
    pub m: Num,
    pub k: Num,
    pub c: Num,
    pub g: Option<Num>,
    pub x0: Option<Num>,
    pub damper: Option<Spanned<String>>,
    pub input_offset: OptNum,
    pub free: Option<Spanned<Vec<String>>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawDiagnoseOptions {
    pub candidates: Option<Spanned<Vec<String>>>,
    pub significance_sigma: OptNum,
    pub min_gain: OptNum,
    pub burn_in: OptNum,
    pub fit_initial_state: Option<Spanned<bool>>,
    pub alpha: OptNum,
    pub max_effects: OptNum,
    pub bic_margin: OptNum,
    pub unexplained_ratio: OptNum,
    pub min_explained: OptNum,
}

/// Where the measured data are and how to read them.
#[derive(Debug, Clone)]
pub struct DataSettings {
    pub file: PathBuf,
    pub time: Option<String>,
    pub sample_rate: Option<f64>,
    pub input: String,
    pub output: String,
    pub fit: Vec<std::ops::Range<usize>>,
    pub validation: Vec<std::ops::Range<usize>>,
    /// Extra held-out ranges reported separately (for example a benchmark's test sections).
    pub test: Vec<std::ops::Range<usize>>,
    /// Relative tolerance on the time step.
    pub time_tolerance: f64,
    /// `data.delimiter`, `data.matrix`, `data.columns`, `data.units`.
    pub format: crate::records::DataFormat,
}

#[derive(Debug, Clone)]
pub struct DiagnoseSettings {
    pub name: String,
    pub path: PathBuf,
    pub data: DataSettings,
    pub params: HopperParams,
    pub damper: DamperLaw,
    pub input_offset: f64,
    pub free: Vec<String>,
    pub candidates: Option<Vec<String>>,
    pub significance_sigma: Option<f64>,
    pub min_gain: Option<f64>,
    pub burn_in: Option<f64>,
    pub fit_initial_state: Option<bool>,
    /// The decision's thresholds (`diagnose.alpha`, ...), when set.
    pub thresholds: Thresholds,
}

/// The diagnosis's decision thresholds as set in the config (`None`: the library default).
#[derive(Debug, Clone, Default)]
pub struct Thresholds {
    pub alpha: Option<f64>,
    pub max_effects: Option<usize>,
    pub bic_margin: Option<f64>,
    pub unexplained_ratio: Option<f64>,
    pub min_explained: Option<f64>,
}

fn ranges(
    src: &Source,
    v: &Option<Spanned<Vec<[i64; 2]>>>,
    key: &str,
) -> Result<Vec<std::ops::Range<usize>>, ConfigError> {
    let Some(list) = v else {
        return Ok(Vec::new());
    };
    let mut out = Vec::new();
    for [a, b] in list.get_ref() {
        if *a < 0 || b <= a {
            return Err(src.error(
                Some(&list.span()),
                key,
                format!(
                    "ranges are [start, end) sample indices with 0 <= start < end (got [{a}, {b}])"
                ),
            ));
        }
        out.push(*a as usize..*b as usize);
    }
    Ok(out)
}

impl DiagnoseSettings {
    pub fn from_file(path: &Path) -> Result<DiagnoseSettings, ConfigError> {
        let (raw, src): (RawDiagnoseConfig, Source) = load(path, Kind::Diagnosis)?;
        let name = match &raw.name {
            Some(n) => n.get_ref().trim().to_string(),
            None => path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "diagnosis".into()),
        };
        if name.is_empty() || name.contains(['/', '\\']) || name.starts_with('.') {
            return Err(src.error(
                raw.name.as_ref().map(|n| n.span()).as_ref(),
                "name",
                "must be a plain file name",
            ));
        }
        let d = &raw.data;
        // A relative data path is relative to the config file's folder.
        let file = {
            let p = PathBuf::from(d.file.get_ref());
            if p.is_absolute() {
                p
            } else {
                path.parent().unwrap_or(Path::new(".")).join(p)
            }
        };
        let sample_rate = match &d.sample_rate {
            Some(v) => Some(src.positive(v, "data.sample_rate")?),
            None => None,
        };
        if sample_rate.is_some() && d.time.is_some() {
            return Err(src.error(
                d.time.as_ref().map(|t| t.span()).as_ref(),
                "data.time",
                "give either a time column or data.sample_rate, not both",
            ));
        }
        let time = match (&d.time, sample_rate) {
            (Some(t), _) => Some(t.get_ref().clone()),
            (None, Some(_)) => None,
            (None, None) => Some("t".to_string()),
        };
        let input = d.input.as_ref().map_or("f".into(), |v| v.get_ref().clone());
        let output = d
            .output
            .as_ref()
            .map_or("x".into(), |v| v.get_ref().clone());
        if input == output {
            let span = d.output.as_ref().or(d.input.as_ref()).map(|v| v.span());
            return Err(src.error(
                span.as_ref(),
                "data.output",
                format!("\"{output}\" is also the input column; the output must be another column"),
            ));
        }
        let used: Vec<&str> = [Some(input.as_str()), Some(output.as_str()), time.as_deref()]
            .into_iter()
            .flatten()
            .collect();
        let format = crate::records::resolve_format(&src, crate::raw_format!(d), &used)?;
        let data = DataSettings {
            format,
            file,
            time,
            sample_rate,
            input,
            output,
            fit: ranges(&src, &d.fit, "data.fit")?,
            validation: ranges(&src, &d.validation, "data.validation")?,
            test: ranges(&src, &d.test, "data.test")?,
            time_tolerance: src.opt_number(
                &d.time_tolerance,
                htfid_data::DEFAULT_TIME_TOLERANCE,
                "data.time_tolerance",
                "in [0, 0.1]",
                |v| (0.0..=0.1).contains(&v),
            )?,
        };
        for t in &data.test {
            if let Some(f) = data.fit.iter().find(|f| f.start < t.end && t.start < f.end) {
                return Err(src.error(
                    d.test.as_ref().map(|v| v.span()).as_ref(),
                    "data.test",
                    format!(
                        "test range [{}, {}) overlaps fit range [{}, {}): held-out data must not be fitted",
                        t.start, t.end, f.start, f.end
                    ),
                ));
            }
        }
        let m = &raw.model;
        let zero = |v: &Option<Num>, key: &str| -> Result<f64, ConfigError> {
            match v {
                Some(v) => src.finite(v, key),
                None => Ok(0.0),
            }
        };
        let (amplitude, period) = match &raw.forcing {
            Some(f) => (
                src.finite(&f.amplitude, "forcing.amplitude")?,
                src.positive(&f.period, "forcing.period")?,
            ),
            None => (0.0, 1.0),
        };
        let params = HopperParams {
            m: src.positive(&m.m, "model.m")?,
            k: src.positive(&m.k, "model.k")?,
            c: src.non_negative(&m.c, "model.c")?,
            g: zero(&m.g, "model.g")?,
            x0: zero(&m.x0, "model.x0")?,
            forcing_amplitude: amplitude,
            period,
        };
        check_hopper_scales(
            &src,
            &params,
            raw.forcing.is_some(),
            &HopperSpans {
                m: Some(m.m.span()),
                k: Some(m.k.span()),
                c: Some(m.c.span()),
                g: m.g.as_ref().map(Spanned::span),
                x0: m.x0.as_ref().map(Spanned::span),
                amplitude: raw.forcing.as_ref().map(|f| f.amplitude.span()),
            },
        )?;
        let damper = match &m.damper {
            None => DamperLaw::Switching,
            Some(d) => match src.choice(d, "model.damper", &["switching", "always_on"])? {
                "always_on" => DamperLaw::AlwaysOn,
                _ => DamperLaw::Switching,
            },
        };
        let input_offset = src.opt_number(
            &m.input_offset,
            0.0,
            "model.input_offset",
            "a finite number",
            |_| true,
        )?;
        let free = match &m.free {
            None => vec!["k".to_string(), "c".to_string()],
            Some(list) => {
                for f in list.get_ref() {
                    if !["m", "k", "c", "x0", "input_offset"].contains(&f.as_str()) {
                        return Err(src.error(Some(&list.span()), "model.free", format!("unknown parameter \"{f}\"; expected any of \"m\", \"k\", \"c\", \"x0\", \"input_offset\"")));
                    }
                }
                list.get_ref().clone()
            }
        };
        let o = raw.diagnose.as_ref();
        let candidates = match o.and_then(|o| o.candidates.as_ref()) {
            None => None,
            Some(list) => {
                for c in list.get_ref() {
                    if c.parse::<htfid_diagnose::Effect>().is_err() {
                        return Err(src.error(
                            Some(&list.span()),
                            "diagnose.candidates",
                            format!(
                                "unknown effect \"{c}\"; the library has {}",
                                crate::config::quote_list(
                                    &htfid_diagnose::Effect::ALL
                                        .iter()
                                        .map(|e| e.name())
                                        .collect::<Vec<_>>()
                                )
                            ),
                        ));
                    }
                }
                Some(list.get_ref().clone())
            }
        };
        let opt = |v: Option<&OptNum>,
                   key: &str,
                   expected: &str,
                   ok: fn(f64) -> bool|
         -> Result<Option<f64>, ConfigError> {
            match v.and_then(|v| v.as_ref()) {
                Some(v) => Ok(Some(src.number(v, key, expected, ok)?)),
                None => Ok(None),
            }
        };
        Ok(DiagnoseSettings {
            name,
            path: path.to_path_buf(),
            data,
            params,
            damper,
            input_offset,
            free,
            candidates,
            significance_sigma: opt(
                o.map(|o| &o.significance_sigma),
                "diagnose.significance_sigma",
                "> 0",
                |v| v > 0.0,
            )?,
            min_gain: opt(
                o.map(|o| &o.min_gain),
                "diagnose.min_gain",
                "in [0, 1)",
                |v| (0.0..1.0).contains(&v),
            )?,
            burn_in: opt(o.map(|o| &o.burn_in), "diagnose.burn_in", ">= 0 (s)", |v| {
                v >= 0.0
            })?,
            fit_initial_state: o
                .and_then(|o| o.fit_initial_state.as_ref())
                .map(|v| *v.get_ref()),
            thresholds: Thresholds {
                alpha: opt(o.map(|o| &o.alpha), "diagnose.alpha", "in (0, 0.5)", |v| {
                    v > 0.0 && v < 0.5
                })?,
                max_effects: opt(
                    o.map(|o| &o.max_effects),
                    "diagnose.max_effects",
                    "a whole number from 1 to 13",
                    |v| v.fract() == 0.0 && (1.0..=13.0).contains(&v),
                )?
                .map(|v| v as usize),
                bic_margin: opt(
                    o.map(|o| &o.bic_margin),
                    "diagnose.bic_margin",
                    ">= 0",
                    |v| v >= 0.0,
                )?,
                unexplained_ratio: opt(
                    o.map(|o| &o.unexplained_ratio),
                    "diagnose.unexplained_ratio",
                    ">= 1",
                    |v| v >= 1.0,
                )?,
                min_explained: opt(
                    o.map(|o| &o.min_explained),
                    "diagnose.min_explained",
                    "in [0, 1]",
                    |v| (0.0..=1.0).contains(&v),
                )?,
            },
        })
    }
}
