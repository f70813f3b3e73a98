//! Diagnosis of a model written in the model language: the configured simulation is the
//! baseline, the free parameters are refitted by output error, and every parameter that moved
//! significantly is a finding (`parameter_error`).

use std::sync::Arc;

use htfid_estimate::{levenberg_marquardt, LmOptions};
use htfid_hybrid::{simulate, Options};
use htfid_lang::{InputFn, Model};
use htfid_orbit::ShootingOptions;
use serde::Serialize;

use crate::interp::{Interpolation, SampledSignal};
use crate::DiagnoseError;

/// A measured record for a model: uniform times, the input `u`, and one column per model
/// output (in the model's order).
#[derive(Debug, Clone)]
pub struct ModelRecord {
    /// Sample times (s), uniform.
    pub t: Vec<f64>,
    /// The model's input at the samples.
    pub u: Vec<f64>,
    /// Measured outputs, one column per model output.
    pub y: Vec<Vec<f64>>,
}

/// How a model is refitted.
#[derive(Debug, Clone)]
pub struct ModelFitOptions {
    /// Parameters refitted (names); the others stay as configured.
    pub free: Vec<String>,
    /// Share of the record (from its start) the fit uses; the rest is held out.
    pub fit_fraction: f64,
    /// Seconds at the start of the record left out of every score (the unknown initial
    /// transient).
    pub burn_in: f64,
    /// A parameter counts as moved when `|fitted - configured| >= significance_sigma * stderr`.
    pub significance_sigma: f64,
    /// Smallest held-out improvement that makes a refit a finding.
    pub min_gain: f64,
    /// Integrator tolerance of every simulation.
    pub rtol: f64,
}

impl Default for ModelFitOptions {
    fn default() -> Self {
        ModelFitOptions {
            free: Vec::new(),
            fit_fraction: 0.7,
            burn_in: 2.0,
            significance_sigma: 5.0,
            min_gain: 0.05,
            rtol: 1e-8,
        }
    }
}

/// How well a simulation matches the record.
#[derive(Debug, Clone, Serialize)]
pub struct ModelScore {
    /// Per output: RMS of (simulated - measured) over its standard deviation, on the fit part.
    pub nrmse_fit: Vec<f64>,
    /// Per output, on the held-out part.
    pub nrmse_validation: Vec<f64>,
    /// Per output: RMS error on the held-out part (output units).
    pub rmse_validation: Vec<f64>,
}

impl ModelScore {
    /// The mean held-out NRMSE over the outputs.
    pub fn validation(&self) -> f64 {
        self.nrmse_validation.iter().sum::<f64>() / self.nrmse_validation.len().max(1) as f64
    }
}

/// One refitted parameter.
#[derive(Debug, Clone, Serialize)]
pub struct ParameterChange {
    /// Its name.
    pub name: String,
    /// Its value as configured.
    pub configured: f64,
    /// Its refitted value.
    pub fitted: f64,
    /// Standard error of the refitted value, inflated for correlated residuals.
    pub stderr: f64,
    /// `(fitted - configured) / stderr`.
    pub z: f64,
}

/// What a model-file diagnosis names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ModelCause {
    /// Some parameter moved significantly and the refit improves the held-out error by at
    /// least `min_gain`.
    ParameterError,
    /// Nothing: the configured model describes the data as well as a refit.
    None,
}

impl ModelCause {
    /// The name used in `diagnosis.json`.
    pub fn name(self) -> &'static str {
        match self {
            ModelCause::ParameterError => "parameter_error",
            ModelCause::None => "none",
        }
    }
}

/// The outcome.
#[derive(Debug, Clone, Serialize)]
pub struct ModelDiagnosis {
    /// What the diagnosis names.
    pub cause: ModelCause,
    /// The configured simulation's score (the baseline).
    pub configured: ModelScore,
    /// The refitted simulation's score.
    pub refitted: ModelScore,
    /// Every free parameter, refitted.
    pub parameters: Vec<ParameterChange>,
    /// Held-out improvement of the refit over the configured simulation:
    /// `1 - NRMSE_refitted / NRMSE_configured` (mean over outputs).
    pub gain: f64,
    /// Factor by which the residuals' correlation inflates the standard errors.
    pub stderr_inflation: f64,
    /// Levenberg-Marquardt iterations.
    pub iterations: usize,
    /// Why it stopped.
    pub stop: String,
    /// The refitted model's simulated outputs at every sample.
    #[serde(skip)]
    pub simulated: Vec<Vec<f64>>,
    /// The configured model's simulated outputs at every sample.
    #[serde(skip)]
    pub simulated_configured: Vec<Vec<f64>>,
}

fn sim_failure(reason: impl ToString) -> DiagnoseError {
    DiagnoseError::Simulation {
        time: f64::NAN,
        reason: reason.to_string(),
    }
}

/// The state at the record's start: on the model's limit cycle (input off) at phase
/// `t0 mod T` when it has a forcing period, else its `[initial]` state.
fn start_state(
    model: &Model,
    t0: f64,
    opts: &Options,
) -> Result<(htfid_lang::Mode, Vec<f64>), DiagnoseError> {
    match model.period() {
        Some(period) => {
            let shooting = ShootingOptions::default();
            let cycle = model.limit_cycle(&shooting, opts).map_err(sim_failure)?;
            let traj = simulate(
                model,
                cycle.mode0,
                0.0,
                &cycle.state0,
                t0.rem_euclid(period),
                &[],
                opts,
            )
            .map_err(sim_failure)?;
            Ok((traj.final_mode, traj.final_state))
        }
        None => Ok((model.initial_mode(), model.initial_state().to_vec())),
    }
}

/// Largest RMS error, in standard deviations of the measured output, of the configured model
/// simulated from its starting guess. A model in the right units misses by a few at most
/// (the start is not fitted yet); a thousand means a wrong unit or a wrong order of magnitude.
const MAX_CONFIGURED_NRMSE: f64 = 1e3;

/// Simulates `model` driven by the record's input from `(mode, x0)` at the record's first
/// time, in the record's own (absolute) times.
fn simulate_outputs(
    model: &Model,
    rec: &ModelRecord,
    input: &InputFn,
    (mode, x0): (htfid_lang::Mode, &[f64]),
    opts: &Options,
) -> Result<Vec<Vec<f64>>, DiagnoseError> {
    let t0 = rec.t[0];
    let driven = model.with_input(Some(input.clone()));
    let end = *rec.t.last().unwrap_or(&t0);
    let traj = simulate(&driven, mode, t0, x0, end, &rec.t, opts).map_err(|e| {
        DiagnoseError::Simulation {
            time: end,
            reason: e.to_string(),
        }
    })?;
    let p = model.outputs().len();
    let mut out = vec![vec![0.0; rec.t.len()]; p];
    let mut y = vec![0.0; p];
    for i in 0..rec.t.len() {
        driven.eval_outputs(traj.modes[i], rec.t[i], traj.state(i), rec.u[i], &mut y);
        for (column, v) in out.iter_mut().zip(&y) {
            column[i] = *v;
        }
    }
    Ok(out)
}

/// Inflation of least-squares standard errors for residuals correlated in time:
/// `sqrt(1 + 2 sum_k (1 - k/L) rho_k)` with Bartlett weights up to lag `L = 4 n^(1/3)`.
fn correlation_inflation(r: &[f64]) -> f64 {
    let n = r.len();
    if n < 8 {
        return 1.0;
    }
    let mean = r.iter().sum::<f64>() / n as f64;
    let var = r.iter().map(|v| (v - mean).powi(2)).sum::<f64>();
    if var <= 0.0 {
        return 1.0;
    }
    let lags = ((4.0 * (n as f64).cbrt()) as usize).min(n - 1);
    let mut s = 1.0;
    for k in 1..=lags {
        let c: f64 = (k..n)
            .map(|i| (r[i] - mean) * (r[i - k] - mean))
            .sum::<f64>()
            / var;
        s += 2.0 * (1.0 - k as f64 / (lags + 1) as f64) * c;
    }
    s.max(1.0).sqrt()
}

/// One record prepared for output-error fits: its input as a function of time, the samples
/// scored, the output scales, and the model's starting point.
struct Prepared<'a> {
    rec: &'a ModelRecord,
    input: InputFn,
    rows: std::ops::Range<usize>,
    scale: Vec<f64>,
    mode0: htfid_lang::Mode,
    guess: Vec<f64>,
    sim_opts: Options,
}

impl<'a> Prepared<'a> {
    fn new(
        model: &Model,
        rec: &'a ModelRecord,
        rows_end: usize,
        opts: &ModelFitOptions,
    ) -> Result<Self, DiagnoseError> {
        let n = rec.t.len();
        if n < 32 || rec.u.len() != n || rec.y.iter().any(|y| y.len() != n) {
            return Err(DiagnoseError::TooShort { min: 32, found: n });
        }
        if rec.y.len() != model.outputs().len() {
            return Err(DiagnoseError::InvalidOption {
                name: "outputs",
                expected: "one measured column per model output",
                value: rec.y.len() as f64,
            });
        }
        let dt = (rec.t[n - 1] - rec.t[0]) / (n - 1) as f64;
        let skip = ((opts.burn_in / dt).ceil() as usize).min(n / 4);
        let rows = skip..rows_end.min(n);
        let scale: Vec<f64> = rec
            .y
            .iter()
            .map(|y| {
                let part = &y[rows.clone()];
                let m = part.iter().sum::<f64>() / part.len() as f64;
                let v = part.iter().map(|v| (v - m).powi(2)).sum::<f64>() / part.len() as f64;
                v.sqrt().max(f64::MIN_POSITIVE)
            })
            .collect();
        let signal = Arc::new(SampledSignal::new(
            rec.t[0],
            dt,
            &rec.u,
            Interpolation::CubicSpline,
        ));
        let input: InputFn = Arc::new(move |t| signal.eval(t));
        let sim_opts = Options {
            rtol: opts.rtol,
            atol: opts.rtol * 1e-2,
            ..Options::default()
        };
        let (mode0, guess) = start_state(model, rec.t[0], &sim_opts)?;
        Ok(Prepared {
            rec,
            input,
            rows,
            scale,
            mode0,
            guess,
            sim_opts,
        })
    }

    fn residual_len(&self) -> usize {
        self.rec.y.len() * self.rows.len()
    }

    fn simulate(&self, model: &Model, x0: &[f64]) -> Result<Vec<Vec<f64>>, DiagnoseError> {
        simulate_outputs(
            model,
            self.rec,
            &self.input,
            (self.mode0, x0),
            &self.sim_opts,
        )
    }

    fn fill(&self, sim: &[Vec<f64>], r: &mut [f64]) {
        let rows = self.rows.len();
        for o in 0..self.rec.y.len() {
            for (j, i) in self.rows.clone().enumerate() {
                r[o * rows + j] = (sim[o][i] - self.rec.y[o][i]) / self.scale[o];
            }
        }
    }

    /// The initial state that best fits the scored samples with `model`'s parameters fixed:
    /// the record starts wherever the measured system was, so neither the configured nor the
    /// refitted model is charged with a start nobody specified.
    fn fit_state(&self, model: &Model, x0: &[f64]) -> Result<Vec<f64>, DiagnoseError> {
        let residuals = |z: &[f64], r: &mut [f64]| -> Result<(), String> {
            let sim = self.simulate(model, z).map_err(|e| e.to_string())?;
            self.fill(&sim, r);
            Ok(())
        };
        let lm = LmOptions {
            scales: Some(x0.iter().map(|v| v.abs().max(1e-3)).collect()),
            ..LmOptions::default()
        };
        levenberg_marquardt(residuals, x0, self.residual_len(), &lm)
            .map(|f| f.params)
            .map_err(|e| DiagnoseError::NominalFit {
                reason: format!("initial state: {e}"),
            })
    }

    /// Per output: RMS error and RMS error over the output's scale, on `range`.
    fn errors(&self, sim: &[Vec<f64>], range: std::ops::Range<usize>) -> (Vec<f64>, Vec<f64>) {
        let n = range.len().max(1) as f64;
        (0..self.rec.y.len())
            .map(|o| {
                let rms = (range
                    .clone()
                    .map(|i| (sim[o][i] - self.rec.y[o][i]).powi(2))
                    .sum::<f64>()
                    / n)
                    .sqrt();
                (rms, rms / self.scale[o])
            })
            .unzip()
    }
}

/// Refits the free parameters of `model` to `rec` by output error and compares the configured
/// and refitted simulations on held-out data: the last `1 - fit_fraction` of `rec`, or the
/// whole of `validation` when a separate validation record is given (then all of `rec` is
/// fitted; on the validation record the initial state is fitted for each model with its
/// parameters fixed, as a comparison of simulations from measured data does).
///
/// # Errors
/// [`DiagnoseError::InvalidOption`] for bad options or an unknown parameter,
/// [`DiagnoseError::Simulation`] when the configured model cannot be simulated on the record,
/// [`DiagnoseError::NominalFit`] when the refit fails.
pub fn diagnose_model(
    model: &Model,
    rec: &ModelRecord,
    validation: Option<&ModelRecord>,
    opts: &ModelFitOptions,
) -> Result<ModelDiagnosis, DiagnoseError> {
    if !(0.1..=0.95).contains(&opts.fit_fraction) {
        return Err(DiagnoseError::InvalidOption {
            name: "fit_fraction",
            expected: "in [0.1, 0.95]",
            value: opts.fit_fraction,
        });
    }
    let n = rec.t.len();
    let cut = match validation {
        Some(_) => n,
        None => ((n as f64) * opts.fit_fraction) as usize,
    };
    let est = Prepared::new(model, rec, cut, opts)?;
    let val = match validation {
        Some(v) => Some(Prepared::new(model, v, v.t.len(), opts)?),
        None => None,
    };
    // Score of a model with fitted state `x_est` on the estimation record.
    let score_of =
        |m: &Model, x_est: &[f64]| -> Result<(ModelScore, Vec<Vec<f64>>), DiagnoseError> {
            let sim = est.simulate(m, x_est)?;
            let (_, nrmse_fit) = est.errors(&sim, est.rows.clone());
            let (rmse_validation, nrmse_validation, shown) = match &val {
                None => {
                    let (r, q) = est.errors(&sim, cut..n);
                    (r, q, sim)
                }
                Some(v) => {
                    let x = v.fit_state(m, &v.guess)?;
                    let vsim = v.simulate(m, &x)?;
                    let (r, q) = v.errors(&vsim, v.rows.clone());
                    (r, q, vsim)
                }
            };
            Ok((
                ModelScore {
                    nrmse_fit,
                    nrmse_validation,
                    rmse_validation,
                },
                shown,
            ))
        };
    // A configured model off by orders of magnitude is refused before the fits, which would
    // spend hundreds of simulations on it.
    let first = est.simulate(model, &est.guess)?;
    let (_, nrmse) = est.errors(&first, est.rows.clone());
    if let Some((o, &q)) = nrmse
        .iter()
        .enumerate()
        .find(|(_, q)| q.is_nan() || **q > MAX_CONFIGURED_NRMSE)
    {
        return Err(DiagnoseError::ScaleMismatch {
            output: model.outputs()[o].name.clone(),
            nrmse: q,
            limit: MAX_CONFIGURED_NRMSE,
        });
    }
    let x_configured = est.fit_state(model, &est.guess)?;
    let (configured, configured_sim) = score_of(model, &x_configured)?;

    let index: Vec<usize> = opts
        .free
        .iter()
        .map(|name| {
            model
                .parameter_index(name)
                .ok_or(DiagnoseError::InvalidOption {
                    name: "free",
                    expected: "names of the model's parameters",
                    value: f64::NAN,
                })
        })
        .collect::<Result<_, _>>()?;
    if index.is_empty() {
        return Ok(ModelDiagnosis {
            cause: ModelCause::None,
            refitted: configured.clone(),
            configured,
            parameters: Vec::new(),
            gain: 0.0,
            stderr_inflation: 1.0,
            iterations: 0,
            stop: "nothing to fit".into(),
            simulated: configured_sim.clone(),
            simulated_configured: configured_sim,
        });
    }
    let k = index.len();
    let dim = est.guess.len();
    // Parameters first, then the initial state.
    let mut p0: Vec<f64> = index.iter().map(|&i| model.values()[i]).collect();
    p0.extend_from_slice(&x_configured);
    let names: Vec<&str> = opts.free.iter().map(String::as_str).collect();
    let residuals = |p: &[f64], r: &mut [f64]| -> Result<(), String> {
        let changes: Vec<(&str, f64)> = names.iter().copied().zip(p.iter().copied()).collect();
        let trial = model.with_parameters(&changes).map_err(|e| e.to_string())?;
        let sim = est.simulate(&trial, &p[k..]).map_err(|e| e.to_string())?;
        est.fill(&sim, r);
        Ok(())
    };
    let params = model.parameters();
    let mut bounds: Vec<(f64, f64)> = index
        .iter()
        .map(|&i| (params[i].min, params[i].max))
        .collect();
    bounds.extend(std::iter::repeat((f64::NEG_INFINITY, f64::INFINITY)).take(dim));
    let lm = LmOptions {
        scales: Some(p0.iter().map(|v| v.abs().max(1e-3)).collect()),
        bounds: Some(bounds),
        ..LmOptions::default()
    };
    let fit = levenberg_marquardt(residuals, &p0, est.residual_len(), &lm).map_err(|e| {
        DiagnoseError::NominalFit {
            reason: e.to_string(),
        }
    })?;
    let changes: Vec<(&str, f64)> = names
        .iter()
        .copied()
        .zip(fit.params[..k].iter().copied())
        .collect();
    let refitted_model =
        model
            .with_parameters(&changes)
            .map_err(|e| DiagnoseError::NominalFit {
                reason: e.to_string(),
            })?;
    let (refitted, refitted_sim) = score_of(&refitted_model, &fit.params[k..])?;
    let inflation = correlation_inflation(&fit.residuals);
    let parameters: Vec<ParameterChange> = names
        .iter()
        .enumerate()
        .map(|(j, name)| {
            let stderr = fit.stderr.as_ref().map_or(f64::NAN, |s| s[j]) * inflation;
            ParameterChange {
                name: (*name).to_string(),
                configured: p0[j],
                fitted: fit.params[j],
                stderr,
                z: (fit.params[j] - p0[j]) / stderr,
            }
        })
        .collect();
    let gain = 1.0 - refitted.validation() / configured.validation();
    let moved = parameters
        .iter()
        .any(|p| p.z.abs() >= opts.significance_sigma);
    let cause = if moved && gain >= opts.min_gain {
        ModelCause::ParameterError
    } else {
        ModelCause::None
    };
    Ok(ModelDiagnosis {
        cause,
        configured,
        refitted,
        parameters,
        gain,
        stderr_inflation: inflation,
        iterations: fit.iterations,
        stop: format!("{:?}", fit.stop),
        simulated: refitted_sim,
        simulated_configured: configured_sim,
    })
}
