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
    /// Asymmetric friction (the diagnosis's `asymmetric_friction`): `mu_pos` while `x' > 0`,
    /// `mu_neg` while `x' < 0`, simulated as `mu` and a constant force.
    pub mu_pos: OptNum,
    pub mu_neg: OptNum,
    /// The position sensor's lag, offset and gain (the diagnosis's `sensor_lag` and
    /// `sensor_offset_gain`): the recorded `x` is `b + g s` with `tau_s s' = x - s`.
    pub tau_s: OptNum,
    pub b: OptNum,
    pub g: OptNum,
}

/// The position sensor of an `[effects]` table (`tau_s`, `b`, `g`); the ideal one without.
pub fn resolve_sensor(
    src: &Source,
    e: Option<&RawEffects>,
    table: &str,
) -> Result<htfid_diagnose::Sensor, ConfigError> {
    let ideal = htfid_diagnose::Sensor::default();
    let Some(e) = e else {
        return Ok(ideal);
    };
    let key = |k: &str| format!("{table}.{k}");
    Ok(htfid_diagnose::Sensor {
        tau_s: src.opt_number(&e.tau_s, 0.0, &key("tau_s"), ">= 0 (s)", |v| v >= 0.0)?,
        b: src.opt_number(&e.b, 0.0, &key("b"), "a finite number (m)", f64::is_finite)?,
        g: src.opt_number(
            &e.g,
            1.0,
            &key("g"),
            "a finite number other than 0 (the sensor's gain; gravity is model.g)",
            |v| v.is_finite() && v != 0.0,
        )?,
    })
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
    let input_offset = src.opt_number(
        &e.input_offset,
        0.0,
        &key("input_offset"),
        "a finite number (N)",
        any,
    )?;
    // Asymmetric friction is symmetric friction, their mean, and a constant force, half their
    // difference: the same force law, sticking included.
    let (mu, input_offset) = match (&e.mu_pos, &e.mu_neg) {
        (None, None) => (
            src.opt_number(&e.mu, 0.0, &key("mu"), ">= 0 (N)", nonneg)?,
            input_offset,
        ),
        (Some(pos), Some(neg)) => {
            if let Some(mu) = &e.mu {
                return Err(src.error(
                    Some(&mu.span()),
                    &key("mu"),
                    "is not used with mu_pos and mu_neg (asymmetric friction has both levels)",
                ));
            }
            let pos = src.number(pos, &key("mu_pos"), ">= 0 (N)", nonneg)?;
            let neg = src.number(neg, &key("mu_neg"), ">= 0 (N)", nonneg)?;
            (0.5 * (pos + neg), input_offset + 0.5 * (neg - pos))
        }
        (Some(one), None) | (None, Some(one)) => {
            let (given, other) = if e.mu_pos.is_some() {
                ("mu_pos", "mu_neg")
            } else {
                ("mu_neg", "mu_pos")
            };
            return Err(src.error(
                Some(&one.span()),
                &key(given),
                format!("needs {other} too (asymmetric friction has both levels)"),
            ));
        }
    };
    Ok(Effects {
        k3: src.opt_number(&e.k3, 0.0, &key("k3"), "a finite number (N/m^3)", any)?,
        mu,
        c_f: src.opt_number(&e.c_f, 0.0, &key("c_f"), ">= 0 (N s/m)", nonneg)?,
        c2: src.opt_number(&e.c2, 0.0, &key("c2"), ">= 0 (N s^2/m^2)", nonneg)?,
        tau: src.opt_number(&e.tau, 0.0, &key("tau"), ">= 0 (s)", nonneg)?,
        delay: src.opt_number(&e.delay, 0.0, &key("delay"), ">= 0 (s)", nonneg)?,
        v_th: src.opt_number(&e.v_th, 0.0, &key("v_th"), "a finite number (m/s)", any)?,
        hard_stop,
        input_offset,
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
        /// What the position sensor does to the recorded `x` (`[effects] tau_s`, `b`, `g`).
        sensor: htfid_diagnose::Sensor,
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
        let name = src.run_name(raw.name.as_ref(), "experiment")?;
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

    /// The position sensor between the simulated position and the recorded `x`: the
    /// configured one for the built-in hopper, the ideal one for a model file (whose outputs
    /// are written in the model).
    pub fn sensor(&self) -> htfid_diagnose::Sensor {
        match &self.system {
            System::Hopper { sensor, .. } => *sensor,
            System::Model(_) => htfid_diagnose::Sensor::default(),
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

mod estimation;
mod excitation;
mod system;

use estimation::resolve_estimation;
use excitation::resolve_excitation;
use system::resolve_system;
pub use system::with_overrides;
