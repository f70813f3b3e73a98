//! Diagnosis of a model written in the model language: the configured simulation is the
//! baseline, the free parameters are refitted by output error, and every parameter that moved
//! significantly is a finding (`parameter_error`).

use std::sync::Arc;

use htfid_estimate::{levenberg_marquardt_with_jacobian, LmOptions};
use htfid_hybrid::{simulate, HybridSystem, Options};
use htfid_lang::{output_sensitivities, ForwardError, InputFn, Model};
use htfid_orbit::ShootingOptions;
use rayon::prelude::*;
use serde::Serialize;

use crate::boundary::{Boundary, BoundaryEffect};
use crate::interp::{Interpolation, SampledSignal};
use crate::noise::{input_noise_level, with_white_noise};
use crate::sensor::Sensor;
use crate::term::{term_library, TermEffect, TermKind};
use crate::{DiagnoseError, TimeSeries};
use htfid_lang::Site;

mod search;
pub use search::{ModelDiscovered, ModelDiscoveredTerm};

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
    /// Boundary effects tried after the refit (all by default).
    pub effects: Vec<BoundaryEffect>,
    /// Kinds of term the library adds to the model's own equations and guards, at every site
    /// the model offers (all by default).
    pub terms: Vec<TermKind>,
    /// The user's own candidate terms (`[[diagnose.terms]]`), tried with the library's.
    pub user_terms: Vec<TermEffect>,
    /// Significance level of the likelihood-ratio test of an effect.
    pub alpha: f64,
    /// Two significant effects whose held-out NRMSEs differ by less than this fraction of the
    /// better one may explain the data equally well; the fit data decide (`bic_margin`). The
    /// default 0.05 is a difference of mean squares of about a tenth of the better one's,
    /// below what a few thousand held-out samples of a residual near the noise floor resolve.
    pub rival_margin: f64,
    /// Of the effects within `rival_margin` held out, the one with the lowest BIC on the fit
    /// data is named; the others are its rivals only when their BIC is within this margin of
    /// it (as the built-in diagnosis's `bic_margin`, default 10: a likelihood ratio of about 10
    /// at equal parameter counts). Near the noise floor the held-out NRMSEs of a right and a
    /// wrong effect differ by a few percent, while the fit data still tell them apart by
    /// hundreds.
    pub bic_margin: f64,
    /// The answer is `unexplained` when the best model's held-out residual stays above this
    /// many times the noise floor while its effect removes less than `min_explained` of the
    /// refit's error above the floor.
    pub unexplained_ratio: f64,
    /// See `unexplained_ratio`.
    pub min_explained: f64,
    /// Held-out NRMSE below which a model explains the data (the simulation's own accuracy
    /// on noise-free records: the input read between its samples, the integrator's
    /// tolerance): no effect is claimed and nothing is unexplained below it. Default 1e-4, as
    /// the built-in diagnosis's `resolution`.
    pub resolution: f64,
    /// Most effects named together (forward selection stops there); at least 1.
    pub max_effects: usize,
    /// As the built-in diagnosis's
    /// [`input_noise_share`](crate::DiagnoseOptions::input_noise_share): the measured input's
    /// own noise, read from its spectrum, is propagated through the refitted model into the
    /// noise floor unless white noise of that level would carry more than this share of the
    /// input's variance; 0 leaves it out. Default 0.1.
    pub input_noise_share: f64,
    /// As the built-in diagnosis's
    /// [`input_noise_flatness`](crate::DiagnoseOptions::input_noise_flatness): the input's
    /// noise band is read as white noise only where its quarters' levels lie within this
    /// factor of each other, `>= 1`. Default 1.5.
    pub input_noise_flatness: f64,
    /// Band of the residual's (and the input's) spectrum whose level is the noise floor, as
    /// fractions of the Nyquist frequency, `0 < lo < hi <= 1`. Default (0.6, 0.95), as the
    /// built-in diagnosis's [`noise_band`](crate::DiagnoseOptions::noise_band).
    pub noise_band: (f64, f64),
    /// A second effect is tried beside the best one while the best one's held-out residual
    /// stays above this many times the noise floor, `>= 1`: below it a second effect could
    /// not gain `min_gain`. Default 1.2.
    pub second_effect_floor_ratio: f64,
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
            effects: BoundaryEffect::ALL.to_vec(),
            terms: TermKind::ALL.to_vec(),
            user_terms: Vec::new(),
            alpha: 1e-4,
            rival_margin: 0.05,
            bic_margin: 10.0,
            unexplained_ratio: 5.0,
            min_explained: 0.999,
            resolution: 1e-4,
            max_effects: 3,
            input_noise_share: 0.1,
            input_noise_flatness: crate::noise::WHITE_SPREAD,
            noise_band: (0.6, 0.95),
            second_effect_floor_ratio: SECOND_EFFECT_FLOOR_RATIO,
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

/// What a model-file diagnosis names (in JSON, its [`ModelCause::name`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ModelCause {
    /// An effect (on the boundary, or a term in the model's equations or guards; by its name)
    /// passes the likelihood-ratio test and improves the held-out error over the refit by at
    /// least `min_gain`, and no other explains the data as well.
    Effect(String),
    /// Two or more effects pass and fit equally well (`alternatives`).
    Ambiguous,
    /// Clear structure remains that neither the refit nor any effect tried explains.
    Unexplained,
    /// Some parameter moved significantly and the refit improves the held-out error by at
    /// least `min_gain`.
    ParameterError,
    /// Nothing: the configured model describes the data as well as a refit.
    None,
}

impl ModelCause {
    /// The name used in `diagnosis.json`.
    pub fn name(&self) -> &str {
        match self {
            ModelCause::Effect(e) => e,
            ModelCause::Ambiguous => "ambiguous",
            ModelCause::Unexplained => "unexplained",
            ModelCause::ParameterError => "parameter_error",
            ModelCause::None => "none",
        }
    }
}

impl Serialize for ModelCause {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

/// One effect fitted jointly with the free parameters.
#[derive(Debug, Clone, Serialize)]
pub struct ModelCandidate {
    /// The effect's name ([`BoundaryEffect::name`], or [`TermEffect::name`]).
    pub effect: String,
    /// For a term in the model's equations or guards: what it adds, where
    /// ([`TermEffect::describe`]); `null` for an effect on the boundary.
    pub term: Option<String>,
    /// The fitted free parameters and the effect's parameters, by name.
    pub parameters: std::collections::BTreeMap<String, f64>,
    /// Their standard errors, inflated for correlated residuals.
    pub stderr: std::collections::BTreeMap<String, f64>,
    /// Mean held-out NRMSE over the outputs (NaN, `null` in JSON, when the fit failed).
    pub nrmse_validation: f64,
    /// Held-out improvement over the refit without the effect.
    pub gain: f64,
    /// Likelihood ratio against the refit, corrected for the residuals' correlation.
    pub likelihood_ratio: f64,
    /// The ratio it must reach (chi-square quantile at `alpha`, one degree per parameter).
    pub critical: f64,
    /// Whether both tests pass.
    pub significant: bool,
    /// Levenberg-Marquardt iterations of its fit (0 when it failed).
    pub iterations: usize,
    /// Why, in words; or why the fit failed.
    pub note: String,
}

impl ModelCandidate {
    fn failed(trial: &Trial, note: String) -> Self {
        ModelCandidate {
            effect: trial.name(),
            term: trial.describe(),
            parameters: Default::default(),
            stderr: Default::default(),
            nrmse_validation: f64::NAN,
            gain: f64::NAN,
            likelihood_ratio: f64::NAN,
            critical: f64::NAN,
            significant: false,
            iterations: 0,
            note,
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
    /// Every effect tried (on the boundary and inside the model), best held-out score first.
    pub candidates: Vec<ModelCandidate>,
    /// Every effect named, strongest first: the best single effect, then a second one that
    /// passes beside it (empty when no effect is named).
    pub causes: Vec<String>,
    /// Every other candidate refitted jointly with the best one (named `first + second`),
    /// best held-out score first; empty when nothing passes or the best one leaves the
    /// held-out residual within 1.2 times the noise floor.
    pub pairs: Vec<ModelCandidate>,
    /// The rounds after the pairs, one list per round: every candidate fitted beside the
    /// effects chosen before it (named `a + b + c`), best held-out score first.
    pub later_rounds: Vec<Vec<ModelCandidate>>,
    /// The backward pass over two or more chosen effects: each tested against the fit
    /// without it (its held-out score there, the likelihood ratio and the gain with it);
    /// `significant` false marks one that no longer passed (the weakest such was dropped).
    pub backward: Vec<ModelCandidate>,
    /// The chosen effects' fit, when the cause is an effect: the pair's when a second effect
    /// passed.
    pub extended: Option<ModelCandidate>,
    /// With `ambiguous`: the effects that fit equally well, the best first.
    pub alternatives: Vec<String>,
    /// Noise floor of the best model's residual on the fit data, in NRMSE units (the white
    /// noise level of its spectrum between 60 % and 95 % of the Nyquist frequency, with
    /// `input_noise`'s response added in quadrature).
    pub noise_floor: f64,
    /// The measured input's own noise, when it could be read from its spectrum: its level
    /// `sigma` in the input's units and the refitted model's RMS response to it, `propagated`,
    /// in NRMSE units (the root mean square over the outputs), which `noise_floor` includes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input_noise: Option<crate::InputNoise>,
    /// Share of the refit's held-out error above the noise floor that the chosen effect
    /// removes (0 without one).
    pub explained: f64,
    /// The refitted model's simulated outputs at every sample.
    #[serde(skip)]
    pub simulated: Vec<Vec<f64>>,
    /// The configured model's simulated outputs at every sample.
    #[serde(skip)]
    pub simulated_configured: Vec<Vec<f64>>,
    /// The extended model's simulated outputs (with the chosen effect), when there is one.
    #[serde(skip)]
    pub simulated_extended: Option<Vec<Vec<f64>>>,
    /// The term search outside the library, when it found terms that pass (it runs while
    /// clear structure remains and the cause is not a single library effect): a hint beside
    /// the cause, which it never changes.
    pub discovered: Option<ModelDiscovered>,
    /// What the term search found or why it proposed nothing; `None` when it did not run.
    pub term_search: Option<String>,
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

/// Spans of the configured simulation's range of a state by which a fitted initial state may
/// lie outside it ([`state_box`]).
const STATE_BOX_SPANS: f64 = 10.0;

/// Bounds of a fitted initial state: the range each state covers when the configured model is
/// simulated from its start `guess` over the record (`samples`), widened by
/// [`STATE_BOX_SPANS`] times that range on each side. Where a start's influence dies out before
/// the scored samples, the output barely depends on it and an unbounded fit can wander to
/// absurd values (a position of -2.5e5 m on a record of millimetres), whose simulation is stiff
/// or fails; the bound keeps such a start among the states the system visits. A state that does
/// not move in that simulation stays unbounded.
fn state_box(guess: &[f64], samples: &[Vec<f64>]) -> Vec<(f64, f64)> {
    guess
        .iter()
        .enumerate()
        .map(|(i, &g)| {
            let (lo, hi) = samples
                .iter()
                .filter_map(|x| x.get(i).copied())
                .filter(|v| v.is_finite())
                .fold((g, g), |(lo, hi), v| (lo.min(v), hi.max(v)));
            let pad = STATE_BOX_SPANS * (hi - lo);
            if pad > 0.0 && pad.is_finite() {
                (lo - pad, hi + pad)
            } else {
                (f64::NEG_INFINITY, f64::INFINITY)
            }
        })
        .collect()
}

/// The default [`ModelFitOptions::second_effect_floor_ratio`].
const SECOND_EFFECT_FLOOR_RATIO: f64 = 1.2;

/// Share of the scored samples on which the initial state is fitted first
/// ([`Prepared::fit_state`]).
const FIRST_HORIZON: f64 = 1.0 / 64.0;

/// Fewest samples of the first horizon of the initial state's fit.
const MIN_HORIZON_SAMPLES: usize = 50;

/// Most iterations of a candidate effect's fit. Candidates start from the refit, and those
/// that converge do so in 2 to 50 iterations on the shipped and the test records; one that has
/// not converged by then creeps along a flat valley (a lag trading against the refitted
/// parameters), each iteration a handful of simulations. It stops there, its score so far
/// reported, and its note says so.
const CANDIDATE_MAX_ITER: usize = 80;

/// Largest RMS error, in standard deviations of the measured output, of the configured model
/// simulated from its starting guess. A model in the right units misses by a few at most
/// (the start is not fitted yet); a thousand means a wrong unit or a wrong order of magnitude.
const MAX_CONFIGURED_NRMSE: f64 = 1e3;

/// Simulates `model` driven by the record's input from `(mode, x0)` at the record's first
/// time, in the record's own (absolute) times, over its first `upto` samples.
fn simulate_outputs(
    model: &Model,
    rec: &TimeSeries,
    input: &InputFn,
    (mode, x0): (htfid_lang::Mode, &[f64]),
    opts: &Options,
    upto: usize,
) -> Result<Vec<Vec<f64>>, DiagnoseError> {
    let t0 = rec.time()[0];
    let times = &rec.time()[..upto.clamp(1, rec.len())];
    let driven = model.with_input(Some(input.clone()));
    let end = *times.last().unwrap_or(&t0);
    // A fitted start can lie across a switching surface from the guess's mode.
    let mode = driven.start_mode(mode, t0, x0);
    let traj = simulate(&driven, mode, t0, x0, end, times, opts).map_err(|e| {
        DiagnoseError::Simulation {
            time: end,
            reason: e.to_string(),
        }
    })?;
    let p = model.outputs().len();
    let mut out = vec![vec![0.0; times.len()]; p];
    let mut y = vec![0.0; p];
    for (i, &t) in times.iter().enumerate() {
        // Outputs that read the input see the applied one.
        let u = input(t);
        driven.eval_outputs(traj.modes[i], t, traj.state(i), u, &mut y);
        for (column, v) in out.iter_mut().zip(&y) {
            column[i] = *v;
        }
    }
    Ok(out)
}

/// The likelihood ratio of a fit (sum of squares `big_rss`, residuals `big_residuals`) against
/// a nested fit of sum of squares `small_rss` on `n` residuals, divided by the variance
/// inflation `kappa` of the bigger fit's correlated residuals; and `kappa`.
fn nested_ratio(small_rss: f64, big_rss: f64, big_residuals: &[f64], n: usize) -> (f64, f64) {
    let kappa = correlation_inflation(big_residuals).powi(2);
    (
        crate::select::likelihood_ratio(small_rss, big_rss, n, kappa),
        kappa,
    )
}

/// The fits that may explain the data as well as `tried[best]` (the best held-out score):
/// it and every significant fit within `rival_margin` of its held-out NRMSE. Of those, the one
/// with the lowest BIC on the fit data (`n` residuals; every fitted parameter counted) and
/// those within `bic_margin` of it, best BIC first: the winner and its rivals.
fn rivals_by_bic(
    tried: &[Tried],
    best: usize,
    n: usize,
    opts: &ModelFitOptions,
) -> (usize, Vec<usize>) {
    let limit = tried[best].candidate.nrmse_validation * (1.0 + opts.rival_margin);
    let bic = |i: usize| {
        let t = &tried[i];
        let b = crate::fit::bic(t.rss, n, t.candidate.parameters.len());
        if b.is_finite() {
            b
        } else {
            f64::INFINITY
        }
    };
    let mut order: Vec<usize> = (0..tried.len())
        .filter(|&i| {
            i == best
                || (tried[i].candidate.significant && tried[i].candidate.nrmse_validation <= limit)
        })
        .collect();
    // Stable: equal BICs keep the held-out order.
    order.sort_by(|&a, &b| bic(a).total_cmp(&bic(b)));
    let w = order[0];
    let rivals = order[1..]
        .iter()
        .copied()
        .filter(|&i| bic(i) - bic(w) < opts.bic_margin)
        .collect();
    (w, rivals)
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
/// A fit's residual function: the scaled residuals at a point, or why they failed.
type Residual<'a> = dyn Fn(&[f64], &mut [f64]) -> Result<(), String> + 'a;

/// Central differences (one-sided against a bound) of `residuals` at `p`, where they are
/// `r`, for the columns `cols` of `jac` (column-major, `r.len()` rows): for the parameters no
/// forward sensitivity covers (a boundary effect's lag, delay or sensor), and for every
/// parameter when the motion slides along a switching surface (or the simulation with
/// sensitivities fails). The step of parameter `j` is
/// `step * max(|p_j|, typical_j)`.
fn difference_columns(
    residuals: &Residual<'_>,
    p: &[f64],
    r: &[f64],
    cols: &[usize],
    (step, typical, bounds): (f64, &[f64], &[(f64, f64)]),
    jac: &mut [f64],
) -> Result<(), String> {
    let m = r.len();
    let (mut up, mut down) = (vec![0.0; m], vec![0.0; m]);
    for &j in cols {
        let h = step * p[j].abs().max(typical[j]);
        let (lo, hi) = bounds[j];
        let mut q = p.to_vec();
        let plus = p[j] + h <= hi && {
            q[j] = p[j] + h;
            residuals(&q, &mut up).is_ok()
        };
        let minus = p[j] - h >= lo && {
            q[j] = p[j] - h;
            residuals(&q, &mut down).is_ok()
        };
        let col = &mut jac[j * m..(j + 1) * m];
        match (plus, minus) {
            (true, true) => {
                for i in 0..m {
                    col[i] = (up[i] - down[i]) / (2.0 * h);
                }
            }
            (true, false) => {
                for i in 0..m {
                    col[i] = (up[i] - r[i]) / h;
                }
            }
            (false, true) => {
                for i in 0..m {
                    col[i] = (r[i] - down[i]) / h;
                }
            }
            (false, false) => {
                return Err(format!(
                    "parameter {j} at {}: the simulation failed on both sides",
                    p[j]
                ))
            }
        }
    }
    Ok(())
}

struct Prepared<'a> {
    rec: &'a TimeSeries,
    signal: Arc<SampledSignal>,
    dt: f64,
    rows: std::ops::Range<usize>,
    scale: Vec<f64>,
    mode0: htfid_lang::Mode,
    guess: Vec<f64>,
    sim_opts: Options,
    /// Bounds of every fitted initial state ([`state_box`]).
    state_box: Vec<(f64, f64)>,
}

impl<'a> Prepared<'a> {
    fn new(
        model: &Model,
        rec: &'a TimeSeries,
        rows_end: usize,
        opts: &ModelFitOptions,
    ) -> Result<Self, DiagnoseError> {
        let n = rec.len();
        crate::record::check_length(n)?;
        if rec.outputs().len() != model.outputs().len() {
            return Err(DiagnoseError::InvalidOption {
                name: "outputs",
                expected: "one measured column per model output",
                value: rec.outputs().len() as f64,
            });
        }
        let dt = rec.dt();
        let skip = ((opts.burn_in / dt).ceil() as usize).min(n / 4);
        let rows = skip..rows_end.min(n);
        for (o, y) in rec.outputs().iter().enumerate() {
            let name = model.outputs()[o].name.as_str();
            crate::record::check_varies(y, std::slice::from_ref(&rows), &format!("scored {name}"))?;
        }
        let scale: Vec<f64> = rec
            .outputs()
            .iter()
            .map(|y| {
                let part = &y[rows.clone()];
                let m = part.iter().sum::<f64>() / part.len() as f64;
                let v = part.iter().map(|v| (v - m).powi(2)).sum::<f64>() / part.len() as f64;
                v.sqrt().max(f64::MIN_POSITIVE)
            })
            .collect();
        let signal = Arc::new(SampledSignal::new(
            rec.time()[0],
            dt,
            rec.input(),
            Interpolation::CubicSpline,
        ));
        let sim_opts = Options {
            rtol: opts.rtol,
            atol: opts.rtol * 1e-2,
            ..Options::default()
        };
        let (mode0, guess) = start_state(model, rec.time()[0], &sim_opts)?;
        let mut prepared = Prepared {
            rec,
            signal,
            dt,
            rows,
            scale,
            state_box: vec![(f64::NEG_INFINITY, f64::INFINITY); guess.len()],
            mode0,
            guess,
            sim_opts,
        };
        if let Ok(samples) = prepared.state_samples(model, &prepared.guess) {
            prepared.state_box = state_box(&prepared.guess, &samples.x);
        }
        Ok(prepared)
    }

    /// The states of `model` from `x0` at (at most about 2000 of) the scored samples, with
    /// their modes, times and inputs.
    fn state_samples(&self, model: &Model, x0: &[f64]) -> Result<StateSamples, DiagnoseError> {
        let input = Boundary::default().input(&self.signal);
        let driven = model.with_input(Some(input.clone()));
        let stride = (self.rows.len() / 2000).max(1);
        let times: Vec<f64> = self
            .rows
            .clone()
            .step_by(stride)
            .map(|i| self.rec.time()[i])
            .collect();
        let (t0, end) = (
            self.rec.time()[0],
            *times.last().unwrap_or(&self.rec.time()[0]),
        );
        let mode = driven.start_mode(self.mode0, t0, x0);
        let traj =
            simulate(&driven, mode, t0, x0, end, &times, &self.sim_opts).map_err(sim_failure)?;
        Ok(StateSamples {
            modes: traj.modes.clone(),
            x: (0..times.len()).map(|i| traj.state(i).to_vec()).collect(),
            u: times.iter().map(|&t| input(t)).collect(),
            t: times,
        })
    }

    /// `model` with its parameter `name` at the best of 0 and +-0.03, 0.1, 0.3, 1 and 3 times
    /// `scale`, by the output error from `x0` (a moved switching surface: the cost is not
    /// convex in the shift, and the neutral start may sit in the wrong valley).
    ///
    /// With `surface` (the parameter moves a switching surface), 0 is never the start: where
    /// the field is continuous across the unmoved surface (a damper switching at zero
    /// velocity), the output's derivative by the shift vanishes there, so a fit with exact
    /// derivatives could not leave it; the better of the two smallest steps is taken instead,
    /// from which a fit returns to 0 if that is the optimum.
    fn best_shift(
        &self,
        model: &Model,
        name: &str,
        scale: f64,
        x0: &[f64],
        surface: bool,
    ) -> Model {
        let mut r = vec![0.0; self.residual_len()];
        let mut best = (f64::INFINITY, model.clone());
        let steps: &[f64] = if surface {
            &[0.03, -0.03, 0.1, -0.1, 0.3, -0.3, 1.0, -1.0, 3.0, -3.0]
        } else {
            &[0.0, 0.03, -0.03, 0.1, -0.1, 0.3, -0.3, 1.0, -1.0, 3.0, -3.0]
        };
        for &step in steps {
            let Ok(m) = model.with_parameters(&[(name, step * scale)]) else {
                continue;
            };
            if let Ok(sim) = self.simulate(&m, x0, &Boundary::default()) {
                self.fill(&sim, &mut r);
                let cost: f64 = r.iter().map(|v| v * v).sum();
                if cost < best.0 {
                    best = (cost, m);
                }
            }
        }
        best.1
    }

    /// The relative step of the fits' central differences. A simulation at relative tolerance
    /// `rtol` moves by about `rtol` when a parameter's change makes the integrator choose other
    /// steps, so differences must be taken with that noise, not rounding, in mind: the step
    /// that balances it against the central difference's `O(h^2)` error is `rtol^(1/3)`
    /// (2e-3 at the default 1e-8), where machine precision would give 6e-6 and derivatives
    /// with errors of tens of percent.
    fn fd_step(&self) -> f64 {
        self.sim_opts.rtol.cbrt()
    }

    fn residual_len(&self) -> usize {
        self.rec.outputs().len() * self.rows.len()
    }

    /// The recorded outputs `model` gives from `x0` with the boundary `b`.
    fn simulate(
        &self,
        model: &Model,
        x0: &[f64],
        b: &Boundary,
    ) -> Result<Vec<Vec<f64>>, DiagnoseError> {
        self.simulate_upto(model, x0, b, self.rec.len())
    }

    /// [`Prepared::simulate`] over the first `upto` samples only.
    fn simulate_upto(
        &self,
        model: &Model,
        x0: &[f64],
        b: &Boundary,
        upto: usize,
    ) -> Result<Vec<Vec<f64>>, DiagnoseError> {
        let input = b.input(&self.signal);
        let mut y = simulate_outputs(
            model,
            self.rec,
            &input,
            (self.mode0, x0),
            &self.sim_opts,
            upto,
        )?;
        b.outputs(self.dt, &mut y);
        Ok(y)
    }

    fn fill(&self, sim: &[Vec<f64>], r: &mut [f64]) {
        self.fill_rows(sim, r, self.rows.clone());
    }

    /// Scaled residuals on `rows`, output by output.
    fn fill_rows(&self, sim: &[Vec<f64>], r: &mut [f64], rows: std::ops::Range<usize>) {
        let len = rows.len();
        for o in 0..self.rec.outputs().len() {
            for (j, i) in rows.clone().enumerate() {
                r[o * len + j] = (sim[o][i] - self.rec.outputs()[o][i]) / self.scale[o];
            }
        }
    }

    /// The exact derivatives of the scaled residuals on `rows` by the parameters `names` of
    /// `model` and by the initial state `x0`, from forward sensitivities
    /// ([`output_sensitivities`]) simulated over the first `upto` samples with the boundary
    /// `b` (its sensors are linear in the outputs up to their offsets, so they map the
    /// derivatives by their linear part). Column `i` of the result (`names` first, then the
    /// states) goes to column `at[i]` of `jac` (column-major, one column per fitted value).
    #[allow(clippy::too_many_arguments)] // reason: the model, the point, the rows and the target
    fn sensitivities(
        &self,
        model: &Model,
        names: &[&str],
        x0: &[f64],
        b: &Boundary,
        upto: usize,
        rows: std::ops::Range<usize>,
        at: &[usize],
        jac: &mut [f64],
    ) -> Result<(), ForwardError> {
        let driven = model.with_input(Some(b.input(&self.signal)));
        let t0 = self.rec.time()[0];
        let times = &self.rec.time()[..upto.clamp(1, self.rec.len())];
        let mode = driven.start_mode(self.mode0, t0, x0);
        let sens = output_sensitivities(&driven, names, true, mode, t0, x0, times, &self.sim_opts)?;
        let len = rows.len();
        let m = self.rec.outputs().len() * len;
        for (mut column, &j) in sens.columns.into_iter().zip(at) {
            for (o, sensor) in b.sensors.iter().enumerate() {
                let linear = Sensor { b: 0.0, ..*sensor };
                linear.apply(self.dt, &mut column[o]);
            }
            let target = &mut jac[j * m..(j + 1) * m];
            for (o, y) in column.iter().enumerate() {
                for (k, i) in rows.clone().enumerate() {
                    target[o * len + k] = y[i] / self.scale[o];
                }
            }
        }
        Ok(())
    }

    /// The initial state that best fits the scored samples with `model`'s parameters fixed:
    /// the record starts wherever the measured system was, so neither the configured nor the
    /// refitted model is charged with a start nobody specified.
    ///
    /// Over a long record the output depends on the start through many switches and its cost
    /// has narrow valleys far from the guess (the model's limit cycle), where the iteration
    /// stalls. The start is therefore fitted on a growing horizon: the first
    /// [`FIRST_HORIZON`] of the scored samples, then four times as many, until all; each fit
    /// starts from the last.
    fn fit_state(
        &self,
        model: &Model,
        x0: &[f64],
        b: &Boundary,
    ) -> Result<Vec<f64>, DiagnoseError> {
        let typical: Vec<f64> = x0.iter().map(|v| v.abs().max(1e-3)).collect();
        let lm = LmOptions {
            scales: Some(typical.clone()),
            bounds: Some(self.state_box.clone()),
            ..LmOptions::default()
        };
        let outputs = self.rec.outputs().len();
        let full = self.rows.clone();
        let first = ((full.len() as f64 * FIRST_HORIZON).ceil() as usize)
            .max(MIN_HORIZON_SAMPLES)
            .min(full.len());
        let mut x = x0.to_vec();
        let mut len = first;
        loop {
            let rows = full.start..full.start + len;
            let residuals = |z: &[f64], r: &mut [f64]| -> Result<(), String> {
                let sim = self
                    .simulate_upto(model, z, b, rows.end)
                    .map_err(|e| e.to_string())?;
                self.fill_rows(&sim, r, rows.clone());
                Ok(())
            };
            let every: Vec<usize> = (0..x.len()).collect();
            let bounds = &self.state_box;
            // Once the sensitivities fail (the motion slides), the rest of the fit differences.
            let failed = std::cell::Cell::new(false);
            let jacobian = |z: &[f64], r: &[f64], jac: &mut [f64]| -> Result<(), String> {
                let exact = !failed.get()
                    && self
                        .sensitivities(model, &[], z, b, rows.end, rows.clone(), &every, jac)
                        .is_ok();
                failed.set(!exact);
                if exact {
                    return Ok(());
                }
                difference_columns(
                    &residuals,
                    z,
                    r,
                    &every,
                    (self.fd_step(), &typical, bounds),
                    jac,
                )
            };
            x = levenberg_marquardt_with_jacobian(
                &residuals,
                jacobian,
                &x,
                outputs * rows.len(),
                &lm,
            )
            .map(|f| f.params)
            .map_err(|e| DiagnoseError::NominalFit {
                reason: format!("initial state: {e}"),
            })?;
            if len == full.len() {
                return Ok(x);
            }
            len = (4 * len).min(full.len());
        }
    }

    /// The input's white-noise level on the scored rows ([`input_noise_level`]) and the RMS
    /// response of `model` (from `x0`) to white noise of that level added to the input, in
    /// NRMSE units over the outputs; `None` where the level cannot be told from the input or a
    /// simulation fails.
    fn input_noise(
        &self,
        model: &Model,
        x0: &[f64],
        opts: &ModelFitOptions,
    ) -> Option<crate::InputNoise> {
        let u = self.rec.input();
        let sigma = input_noise_level(
            &[&u[self.rows.clone()]],
            opts.noise_band,
            opts.input_noise_share,
            opts.input_noise_flatness,
        )?;
        let noisy = with_white_noise(u, sigma)?;
        let signal = Arc::new(SampledSignal::new(
            self.rec.time()[0],
            self.dt,
            &noisy,
            Interpolation::CubicSpline,
        ));
        let ideal = Boundary::default();
        let clean = self.simulate(model, x0, &ideal).ok()?;
        let driven = simulate_outputs(
            model,
            self.rec,
            &ideal.input(&signal),
            (self.mode0, x0),
            &self.sim_opts,
            self.rec.len(),
        )
        .ok()?;
        let n = self.rows.len().max(1) as f64;
        let mean_square = (0..clean.len())
            .map(|o| {
                self.rows
                    .clone()
                    .map(|i| ((driven[o][i] - clean[o][i]) / self.scale[o]).powi(2))
                    .sum::<f64>()
                    / n
            })
            .sum::<f64>()
            / clean.len().max(1) as f64;
        let propagated = mean_square.sqrt();
        propagated
            .is_finite()
            .then_some(crate::InputNoise { sigma, propagated })
    }

    /// Per output: RMS error and RMS error over the output's scale, on `range`.
    fn errors(&self, sim: &[Vec<f64>], range: std::ops::Range<usize>) -> (Vec<f64>, Vec<f64>) {
        let n = range.len().max(1) as f64;
        (0..self.rec.outputs().len())
            .map(|o| {
                let rms = (range
                    .clone()
                    .map(|i| (sim[o][i] - self.rec.outputs()[o][i]).powi(2))
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
    rec: &TimeSeries,
    validation: Option<&TimeSeries>,
    opts: &ModelFitOptions,
) -> Result<ModelDiagnosis, DiagnoseError> {
    if !(0.1..=0.95).contains(&opts.fit_fraction) {
        return Err(DiagnoseError::InvalidOption {
            name: "fit_fraction",
            expected: "in [0.1, 0.95]",
            value: opts.fit_fraction,
        });
    }
    if opts.max_effects == 0 {
        return Err(DiagnoseError::InvalidOption {
            name: "max_effects",
            expected: ">= 1",
            value: 0.0,
        });
    }
    crate::noise::check_reading(opts.noise_band, opts.input_noise_flatness)?;
    if !(opts.second_effect_floor_ratio.is_finite() && opts.second_effect_floor_ratio >= 1.0) {
        return Err(DiagnoseError::InvalidOption {
            name: "second_effect_floor_ratio",
            expected: ">= 1 and finite",
            value: opts.second_effect_floor_ratio,
        });
    }
    let n = rec.len();
    let cut = match validation {
        Some(_) => n,
        None => ((n as f64) * opts.fit_fraction) as usize,
    };
    let est = Prepared::new(model, rec, cut, opts)?;
    let val = match validation {
        Some(v) => Some(Prepared::new(model, v, v.len(), opts)?),
        None => None,
    };
    // Score of a model with fitted state `x_est` on the estimation record.
    let score_of = |m: &Model,
                    x_est: &[f64],
                    b: &Boundary|
     -> Result<(ModelScore, Vec<Vec<f64>>), DiagnoseError> {
        let sim = est.simulate(m, x_est, b)?;
        let (_, nrmse_fit) = est.errors(&sim, est.rows.clone());
        let (rmse_validation, nrmse_validation, shown) = match &val {
            None => {
                let (r, q) = est.errors(&sim, cut..n);
                (r, q, sim)
            }
            Some(v) => {
                let x = v.fit_state(m, &v.guess, b)?;
                let vsim = v.simulate(m, &x, b)?;
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
    let ideal = Boundary::default();
    let first = est.simulate(model, &est.guess, &ideal)?;
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
    let x_configured = est.fit_state(model, &est.guess, &ideal)?;
    let (configured, configured_sim) = score_of(model, &x_configured, &ideal)?;

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
    let names: Vec<&str> = opts.free.iter().map(String::as_str).collect();
    let outputs: Vec<String> = model.outputs().iter().map(|o| o.name.clone()).collect();
    let joint = Joint {
        est: &est,
        model,
        names: &names,
        index: &index,
        scales: index
            .iter()
            .map(|&i| model.values()[i].abs().max(1e-3))
            .collect(),
        max_iter: LmOptions::default().max_iter,
    };
    // The refit of the free parameters (and the initial state) alone.
    let base = joint.fit(&[], &[], &x_configured)?;
    let k = index.len();
    let refitted_model = joint.model_at(&base.params[..k])?;
    let (refitted, refitted_sim) = score_of(&refitted_model, &base.state, &ideal)?;
    let inflation = correlation_inflation(&base.residuals);
    let p0: Vec<f64> = index.iter().map(|&i| model.values()[i]).collect();
    let parameters: Vec<ParameterChange> = names
        .iter()
        .enumerate()
        .map(|(j, name)| {
            let stderr = base.stderr[j] * inflation;
            ParameterChange {
                name: (*name).to_string(),
                configured: p0[j],
                fitted: base.params[j],
                stderr,
                z: (base.params[j] - p0[j]) / stderr,
            }
        })
        .collect();
    let gain = if k == 0 {
        0.0
    } else {
        1.0 - refitted.validation() / configured.validation()
    };
    let moved = parameters
        .iter()
        .any(|p| p.z.abs() >= opts.significance_sigma);

    // Every candidate effect, each fitted jointly with the free parameters and tested against
    // the refit: a likelihood ratio corrected for the residuals' correlation, and a held-out
    // gain. On the boundary, and inside the model: the library's terms at every site the
    // model offers, and the user's own.
    let samples = est.state_samples(&refitted_model, &base.state)?;
    let means = samples.means(model.states().len());
    let trials: Vec<Trial> = opts
        .effects
        .iter()
        .map(|&e| Trial::Boundary(e))
        .chain(
            term_library(model, &opts.terms, &means)
                .into_iter()
                .chain(opts.user_terms.iter().cloned())
                .map(Trial::Term),
        )
        .collect();
    let n = est.residual_len();
    let mut candidates: Vec<Tried> = Vec::new();
    // The candidates' fits are independent: in parallel.
    let fits: Vec<_> = trials
        .par_iter()
        .map(|trial| match trial {
            Trial::Boundary(effect) => {
                let effect = *effect;
                let start = joint.effect_start(effect, &base, &outputs);
                // From the refit: its parameters and its state.
                let joint_b = Joint {
                    model: &refitted_model,
                    scales: joint.scales.clone(),
                    max_iter: CANDIDATE_MAX_ITER,
                    ..joint
                };
                joint_b.fit(&[effect], &start, &base.state).and_then(|f| {
                    let m = joint_b.model_at(&f.params[..k])?;
                    let b = Boundary::with(effect, &f.params[k..], outputs.len());
                    let (score, sim) = score_of(&m, &f.state, &b)?;
                    Ok((f, score, sim))
                })
            }
            Trial::Term(term) => {
                let extended = refitted_model
                    .with_extension(&term.extension)
                    .map_err(|e| DiagnoseError::NominalFit {
                        reason: e.to_string(),
                    })?;
                let added = term.parameter_names();
                let all: Vec<&str> = names
                    .iter()
                    .copied()
                    .chain(added.iter().map(String::as_str))
                    .collect();
                let index_t: Vec<usize> = all
                    .iter()
                    .filter_map(|n| extended.parameter_index(n))
                    .collect();
                let mut scales = joint.scales.clone();
                scales.extend(samples.term_scales(&extended, &est.signal, term));
                let mut extended = extended;
                if term.multistart {
                    extended = est.best_shift(&extended, &added[0], scales[k], &base.state, true);
                }
                let joint_t = Joint {
                    est: &est,
                    model: &extended,
                    names: &all,
                    index: &index_t,
                    scales,
                    max_iter: CANDIDATE_MAX_ITER,
                };
                joint_t.fit(&[], &[], &base.state).and_then(|f| {
                    let m = joint_t.model_at(&f.params)?;
                    let (score, sim) = score_of(&m, &f.state, &ideal)?;
                    Ok((f, score, sim))
                })
            }
        })
        .collect();
    for (ti, (trial, fitted)) in trials.iter().zip(fits).enumerate() {
        let names_e = trial.parameter_names(&outputs);
        let (f, score, sim) = match fitted {
            Ok(v) => v,
            Err(e) => {
                candidates.push(Tried {
                    candidate: ModelCandidate::failed(trial, format!("fit failed: {e}")),
                    simulated: None,
                    residuals: Vec::new(),
                    state: Vec::new(),
                    rss: f64::NAN,
                    set: vec![ti],
                });
                continue;
            }
        };
        let (lr, kappa) = nested_ratio(base.rss, f.rss, &f.residuals, n);
        let critical = crate::select::chi2_quantile(names_e.len(), opts.alpha);
        let gain_e = 1.0 - score.validation() / refitted.validation();
        // Nothing is left to explain once the refit is within the resolution.
        let significant =
            lr >= critical && gain_e >= opts.min_gain && refitted.validation() > opts.resolution;
        let infl = kappa.sqrt();
        let mut parameters = std::collections::BTreeMap::new();
        let mut stderr = std::collections::BTreeMap::new();
        for (j, name) in names.iter().enumerate() {
            parameters.insert((*name).to_string(), f.params[j]);
            stderr.insert((*name).to_string(), f.stderr[j] * infl);
        }
        for (j, name) in names_e.iter().enumerate() {
            parameters.insert(name.clone(), f.params[k + j]);
            stderr.insert(name.clone(), f.stderr[k + j] * infl);
        }
        let mut note = format!(
            "likelihood ratio {lr:.1} (critical {critical:.1}), held-out gain {:.1} % over the \
             refit (at least {:.1} %)",
            100.0 * gain_e,
            100.0 * opts.min_gain
        );
        if f.stop == format!("{:?}", htfid_estimate::LmStop::MaxIterations) {
            note.push_str(&format!(
                "; its fit stopped at the limit of {CANDIDATE_MAX_ITER} iterations, not \
                 converged: its score is an upper bound"
            ));
        }
        candidates.push(Tried {
            candidate: ModelCandidate {
                effect: trial.name(),
                term: trial.describe(),
                parameters,
                stderr,
                nrmse_validation: score.validation(),
                gain: gain_e,
                likelihood_ratio: lr,
                critical,
                significant,
                iterations: f.iterations,
                note,
            },
            simulated: Some(sim),
            residuals: f.residuals,
            state: f.state,
            rss: f.rss,
            set: vec![ti],
        });
    }
    candidates
        .sort_by(|a, b| (a.candidate.nrmse_validation).total_cmp(&b.candidate.nrmse_validation));
    let best = candidates.iter().position(|c| c.candidate.significant);
    // A significant rival within `rival_margin` of the best held-out score may explain the
    // data as well: of those, the lowest BIC on the fit data is named, and the others within
    // `bic_margin` of it are its rivals (the data cannot tell them apart).
    let (best, alternatives) = match best {
        Some(b) => {
            let (w, rivals) = rivals_by_bic(&candidates, b, n, opts);
            let names = rivals
                .iter()
                .map(|&i| candidates[i].candidate.effect.clone())
                .collect();
            (Some(w), names)
        }
        None => (None, Vec::new()),
    };
    // The noise floor of the best model's residual (scaled by each output's spread, so in
    // NRMSE units), from the band 60-95 % of the Nyquist frequency.
    let best_residuals = match best {
        Some(b) => &candidates[b].residuals,
        None => &base.residuals,
    };
    let rows = est.rows.len().max(1);
    let per_output: Vec<&[f64]> = best_residuals.chunks(rows).collect();
    let reading_floor = crate::noise::noise_floor(&per_output, opts.noise_band).unwrap_or(f64::NAN);
    // A perfect model driven by a noisy input still leaves its response to that noise.
    let input_noise = est.input_noise(&refitted_model, &base.state, opts);
    let noise_floor = input_noise.map_or(reading_floor, |i| reading_floor.hypot(i.propagated));
    let best_score = best.map_or(refitted.validation(), |b| {
        candidates[b].candidate.nrmse_validation
    });

    // Further effects beside the best one (forward selection), while the chosen effects leave
    // the held-out residual clearly above the noise floor: every other candidate refitted
    // jointly with them (all their parameters, the free ones and the start together, the
    // chosen ones' from their fit), and tested against their fit as the first was against the
    // refit. In the second round the best effect's rivals (within `rival_margin` held out) are
    // tried as the first effect too: beside a second effect, the right one of two look-alikes
    // fits clearly better.
    let fit_set = |set: &[usize],
                   known: &std::collections::BTreeMap<String, f64>,
                   x0: &[f64]|
     -> Result<SetFit, DiagnoseError> {
        let to_err = |e: htfid_lang::ModelError| DiagnoseError::NominalFit {
            reason: e.to_string(),
        };
        let chosen: Vec<&Trial> = set.iter().map(|&i| &trials[i]).collect();
        let terms: Vec<&TermEffect> = chosen
            .iter()
            .filter_map(|t| match t {
                Trial::Term(term) => Some(term),
                Trial::Boundary(_) => None,
            })
            .collect();
        let boundary: Vec<BoundaryEffect> = chosen
            .iter()
            .filter_map(|t| match t {
                Trial::Boundary(e) => Some(*e),
                Trial::Term(_) => None,
            })
            .collect();
        let mut m = refitted_model.clone();
        for term in &terms {
            m = m.with_extension(&term.extension).map_err(to_err)?;
        }
        // The free parameters and the terms' parameters, those fitted before at their values.
        let mut all: Vec<String> = names.iter().map(|n| (*n).to_string()).collect();
        for term in &terms {
            all.extend(term.parameter_names());
        }
        let values: Vec<(&str, f64)> = all
            .iter()
            .filter_map(|n| known.get(n).map(|v| (n.as_str(), *v)))
            .collect();
        m = m.with_parameters(&values).map_err(to_err)?;
        let mut scales = joint.scales.clone();
        for term in &terms {
            scales.extend(samples.term_scales(&m, &est.signal, term));
        }
        // A term not fitted before starts its first parameter from the best of a grid across
        // its scale, zero included: beside the chosen effects the free parameters have
        // compensated for them, and from zero its fit can stay in that basin (drag beside a
        // sensor lag, taken up by the linear dampers).
        for term in &terms {
            let name = &term.parameter_names()[0];
            if !known.contains_key(name) {
                if let Some(j) = all.iter().position(|a| a == name) {
                    m = est.best_shift(&m, name, scales[j], x0, term.multistart);
                }
            }
        }
        let refs: Vec<&str> = all.iter().map(String::as_str).collect();
        let index_x: Vec<usize> = refs
            .iter()
            .map(|n| {
                m.parameter_index(n)
                    .ok_or_else(|| DiagnoseError::NominalFit {
                        reason: format!("no parameter {n} in the extended model"),
                    })
            })
            .collect::<Result<_, _>>()?;
        let joint_x = Joint {
            est: &est,
            model: &m,
            names: &refs,
            index: &index_x,
            scales,
            max_iter: CANDIDATE_MAX_ITER,
        };
        // Boundary parameters fitted before from their values, a new effect's from its start.
        let mut start: Vec<f64> = Vec::new();
        for &e in &boundary {
            let pn = e.parameter_names(&outputs);
            match pn.iter().map(|n| known.get(n).copied()).collect() {
                Some(v) => start.extend::<Vec<f64>>(v),
                None => start.extend(joint.effect_start(e, &base, &outputs)),
            }
        }
        let f = joint_x.fit(&boundary, &start, x0)?;
        let kx = index_x.len();
        let fitted = joint_x.model_at(&f.params[..kx])?;
        let bd = Boundary::with_all(&boundary, &f.params[kx..], outputs.len());
        let (score, sim) = score_of(&fitted, &f.state, &bd)?;
        for e in &boundary {
            all.extend(e.parameter_names(&outputs));
        }
        Ok((f, score, sim, all))
    };
    // The fit of `set` (its last trial added beside the others) as a tried candidate, tested
    // against the fit without that trial (`rss`, held-out `score`).
    let judge = |set: &[usize],
                 fitted: Result<SetFit, DiagnoseError>,
                 rss: f64,
                 score_without: f64|
     -> Tried {
        let (&added, beside) = set.split_last().expect("a set holds its added trial");
        let t2 = &trials[added];
        let name = set
            .iter()
            .map(|&i| trials[i].name())
            .collect::<Vec<_>>()
            .join(" + ");
        let without = beside
            .iter()
            .map(|&i| trials[i].name())
            .collect::<Vec<_>>()
            .join(" + ");
        let (f, score, sim, all) = match fitted {
            Ok(v) => v,
            Err(e) => {
                let mut c = ModelCandidate::failed(t2, format!("fit failed: {e}"));
                c.effect = name;
                return Tried {
                    candidate: c,
                    simulated: None,
                    residuals: Vec::new(),
                    state: Vec::new(),
                    rss: f64::NAN,
                    set: set.to_vec(),
                };
            }
        };
        let (lr, kappa) = nested_ratio(rss, f.rss, &f.residuals, n);
        let critical = crate::select::chi2_quantile(t2.parameter_names(&outputs).len(), opts.alpha);
        let gain_e = 1.0 - score.validation() / score_without;
        let significant = lr >= critical && gain_e >= opts.min_gain;
        let infl = kappa.sqrt();
        let parameters = all.iter().cloned().zip(f.params.iter().copied()).collect();
        let stderr = all
            .iter()
            .cloned()
            .zip(f.stderr.iter().map(|s| s * infl))
            .collect();
        Tried {
            candidate: ModelCandidate {
                effect: name,
                term: t2.describe(),
                parameters,
                stderr,
                nrmse_validation: score.validation(),
                gain: gain_e,
                likelihood_ratio: lr,
                critical,
                significant,
                iterations: f.iterations,
                note: format!(
                    "beside {without}: likelihood ratio {lr:.1} (critical {critical:.1}), \
                     held-out gain {:.1} % over {without} alone (at least {:.1} %)",
                    100.0 * gain_e,
                    100.0 * opts.min_gain
                ),
            },
            simulated: Some(sim),
            residuals: f.residuals,
            state: f.state,
            rss: f.rss,
            set: set.to_vec(),
        }
    };
    // One round: every trial outside `chosen` (the effects of `current`) fitted beside them.
    let round = |current: &Tried| -> Vec<Tried> {
        let outside: Vec<usize> = (0..trials.len())
            .filter(|i| !current.set.contains(i))
            .collect();
        let fits: Vec<_> = outside
            .par_iter()
            .map(|&i| {
                let mut set = current.set.clone();
                set.push(i);
                let f = fit_set(&set, &current.candidate.parameters, &current.state);
                (set, f)
            })
            .collect();
        fits.into_iter()
            .map(|(set, f)| judge(&set, f, current.rss, current.candidate.nrmse_validation))
            .collect()
    };
    let by_score = |a: &Tried, b: &Tried| {
        a.candidate
            .nrmse_validation
            .total_cmp(&b.candidate.nrmse_validation)
    };
    let room = |score: f64| {
        noise_floor.is_finite() && score > opts.second_effect_floor_ratio * noise_floor
    };
    let mut pairs: Vec<Tried> = Vec::new();
    let firsts: Vec<usize> = match best {
        Some(b) if room(best_score) && opts.max_effects >= 2 => std::iter::once(b)
            .chain(
                (0..candidates.len())
                    .filter(|&i| i != b && alternatives.contains(&candidates[i].candidate.effect)),
            )
            .collect(),
        _ => Vec::new(),
    };
    for &b in &firsts {
        pairs.extend(round(&candidates[b]));
    }
    pairs.sort_by(by_score);
    let second = pairs.iter().position(|p| p.candidate.significant);
    // With a pair, its first effect is the cause; the first effects of other passing pairs
    // within `rival_margin` of it held out and `bic_margin` on the fit data are its rivals
    // (of those within `rival_margin`, the lowest BIC is named, as in the first round).
    let (second, mut alternatives): (Option<usize>, Vec<String>) = match second {
        Some(s) => {
            let (w, rival_pairs) = rivals_by_bic(&pairs, s, n, opts);
            let lead = trials[pairs[w].set[0]].name();
            let mut rivals: Vec<String> = Vec::new();
            for i in rival_pairs {
                let name = trials[pairs[i].set[0]].name();
                if name != lead && !rivals.contains(&name) {
                    rivals.push(name);
                }
            }
            (Some(w), rivals)
        }
        None => (None, alternatives),
    };
    // The effects chosen so far and their joint fit (an index into `candidates` or `pairs`,
    // or a later round's fit).
    let mut current: Option<Tried> = match (second, best) {
        (Some(s), _) => Some(pairs[s].clone()),
        (None, Some(b)) => Some(candidates[b].clone()),
        (None, None) => None,
    };
    let lead_before = current.as_ref().map(|c| c.set[0]);
    // Rounds three onwards.
    let mut later_rounds: Vec<Vec<Tried>> = Vec::new();
    if second.is_some() {
        while let Some(cur) = current
            .as_ref()
            .filter(|c| c.set.len() < opts.max_effects && room(c.candidate.nrmse_validation))
        {
            let mut tried = round(cur);
            tried.sort_by(by_score);
            let next = tried.iter().position(|t| t.candidate.significant);
            let chosen = next.map(|i| tried[i].clone());
            later_rounds.push(tried);
            match chosen {
                Some(c) => current = Some(c),
                None => break,
            }
        }
    }
    // The backward pass: each chosen effect (of two or more) tested against the fit without
    // it; the weakest that no longer passes is dropped, and the pass repeats.
    let mut backward: Vec<ModelCandidate> = Vec::new();
    while let Some(cur) = current.as_ref().filter(|c| c.set.len() >= 2) {
        let reduced: Vec<(usize, Vec<usize>)> = (0..cur.set.len())
            .map(|j| {
                let mut r = cur.set.clone();
                let e = r.remove(j);
                (e, r)
            })
            .collect();
        let fits: Vec<Result<Tried, DiagnoseError>> = reduced
            .par_iter()
            .map(|(_, r)| {
                // A set fitted in an earlier round (the same effects in any order) is taken as
                // it was fitted; another is fitted from the chosen set's values.
                let same = |c: &&Tried| {
                    let (mut a, mut b) = (c.set.clone(), r.clone());
                    a.sort_unstable();
                    b.sort_unstable();
                    a == b && c.rss.is_finite()
                };
                if let Some(earlier) = candidates
                    .iter()
                    .chain(pairs.iter())
                    .chain(later_rounds.iter().flatten())
                    .find(same)
                {
                    return Ok(earlier.clone());
                }
                // Only its fit is used: tested against nothing.
                let f = fit_set(r, &cur.candidate.parameters, &cur.state)?;
                let score = f.1.validation();
                Ok(judge(r, Ok(f), f64::NAN, score))
            })
            .collect();
        // The test of each effect: the chosen set against the set without it.
        let mut weakest: Option<(f64, usize, Tried)> = None;
        for ((e, _), fit) in reduced.iter().zip(fits) {
            let Ok(without) = fit else { continue };
            let critical = crate::select::chi2_quantile(
                trials[*e].parameter_names(&outputs).len(),
                opts.alpha,
            );
            let (lr, _) = nested_ratio(without.rss, cur.rss, &cur.residuals, n);
            let gain_e = 1.0 - cur.candidate.nrmse_validation / without.candidate.nrmse_validation;
            let passes = lr >= critical && gain_e >= opts.min_gain;
            if !passes && weakest.as_ref().map_or(true, |w| lr < w.0) {
                weakest = Some((lr, backward.len(), without.clone()));
            }
            backward.push(ModelCandidate {
                effect: trials[*e].name(),
                term: trials[*e].describe(),
                parameters: cur.candidate.parameters.clone(),
                stderr: cur.candidate.stderr.clone(),
                nrmse_validation: without.candidate.nrmse_validation,
                gain: gain_e,
                likelihood_ratio: lr,
                critical,
                significant: passes,
                iterations: without.candidate.iterations,
                note: format!(
                    "beside {}: without it the held-out NRMSE is {:.3e}; likelihood ratio \
                     {lr:.1} (critical {critical:.1}), held-out gain {:.1} % with it (at least \
                     {:.1} %)",
                    cur.candidate.effect,
                    without.candidate.nrmse_validation,
                    100.0 * gain_e,
                    100.0 * opts.min_gain
                ),
            });
        }
        match weakest {
            Some((_, at, without)) => {
                backward[at].note.push_str("; no longer needed: dropped");
                current = Some(without);
            }
            None => break,
        }
    }
    let final_score = current
        .as_ref()
        .map_or(best_score, |c| c.candidate.nrmse_validation);
    let floor2 = noise_floor * noise_floor;
    let explained = if current.is_some() {
        1.0 - (final_score.powi(2) - floor2).max(0.0)
            / (refitted.validation().powi(2) - floor2).max(f64::MIN_POSITIVE)
    } else {
        0.0
    };
    let structure_left = noise_floor.is_finite()
        && final_score > opts.unexplained_ratio * noise_floor
        && final_score > opts.resolution;
    let lead = current.as_ref().map(|c| trials[c.set[0]].name());
    // The rivals were those of the first effect: gone with it when the backward pass dropped it.
    if current.as_ref().map(|c| c.set[0]) != lead_before {
        alternatives.clear();
    }
    let cause = match &lead {
        _ if structure_left && explained < opts.min_explained => ModelCause::Unexplained,
        Some(_) if !alternatives.is_empty() => ModelCause::Ambiguous,
        Some(name) => ModelCause::Effect(name.clone()),
        None if moved && gain >= opts.min_gain => ModelCause::ParameterError,
        None => ModelCause::None,
    };
    if let (ModelCause::Ambiguous, Some(name)) = (&cause, &lead) {
        alternatives.insert(0, name.clone());
    }
    let causes: Vec<String> = current
        .as_ref()
        .map(|c| c.set.iter().map(|&i| trials[i].name()).collect())
        .unwrap_or_default();
    // Outside the library: a term search on the refitted model while clear structure remains
    // that no chosen effect accounts for (with an effect named, its own fit is the answer).
    let searched = structure_left && !matches!(cause, ModelCause::Effect(_));
    let (discovered, term_search) = if searched {
        let score = |m: &Model, x: &[f64]| score_of(m, x, &ideal).map(|(s, _)| s);
        let (found, sentence) = search::Search {
            est: &est,
            model: &refitted_model,
            names: &names,
            scales: &joint.scales,
            base: &base,
            samples: &samples,
            means: &means,
            refitted: &refitted,
            score: &score,
            opts,
        }
        .run();
        (found, Some(sentence))
    } else {
        (None, None)
    };
    let (extended, simulated_extended) = match current {
        Some(mut c) => {
            let sim = c.simulated.take();
            (Some(c.candidate), sim)
        }
        None => (None, None),
    };
    Ok(ModelDiagnosis {
        cause,
        configured,
        refitted,
        parameters,
        gain,
        stderr_inflation: inflation,
        iterations: base.iterations,
        stop: base.stop,
        candidates: candidates.into_iter().map(|c| c.candidate).collect(),
        causes,
        pairs: pairs.into_iter().map(|c| c.candidate).collect(),
        later_rounds: later_rounds
            .into_iter()
            .map(|r| r.into_iter().map(|c| c.candidate).collect())
            .collect(),
        backward,
        extended,
        alternatives,
        noise_floor,
        input_noise,
        explained,
        simulated: refitted_sim,
        simulated_configured: configured_sim,
        simulated_extended,
        discovered,
        term_search,
    })
}

/// A model's states at samples of a record: where a term's parameters are scaled.
struct StateSamples {
    t: Vec<f64>,
    modes: Vec<htfid_lang::Mode>,
    x: Vec<Vec<f64>>,
    u: Vec<f64>,
}

impl StateSamples {
    /// Each state's mean.
    fn means(&self, n: usize) -> Vec<f64> {
        let count = self.x.len().max(1) as f64;
        (0..n)
            .map(|j| self.x.iter().map(|x| x[j]).sum::<f64>() / count)
            .collect()
    }

    /// The size of a meaningful value of each of `term`'s parameters in `model` (extended by
    /// it): the RMS of the expressions the term joins (a state's equation, a guard) over the
    /// RMS of their exact derivative by the parameter, on these samples. A parameter that
    /// changes nothing here gets 1.
    fn term_scales(
        &self,
        model: &Model,
        signal: &Arc<SampledSignal>,
        term: &TermEffect,
    ) -> Vec<f64> {
        let names = term.parameter_names();
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let k = refs.len();
        let Ok(sens) = model.parameter_sensitivity(&refs) else {
            return vec![1.0; k];
        };
        let input = Boundary::default().input(signal);
        let driven = model.with_input(Some(input));
        let n = model.states().len();
        let guards = model.guard_names();
        let (mut size, mut slope) = (vec![0.0; k], vec![0.0; k]);
        let mut f = vec![0.0; n];
        let mut dfdp = vec![0.0; n * k];
        let mut dhdp = vec![0.0; k];
        for (site, _) in &term.extension.terms {
            for i in 0..self.t.len() {
                let (t, x, u, mode) = (self.t[i], &self.x[i], self.u[i], self.modes[i]);
                match site {
                    Site::Flow { state, mode: only } => {
                        if only.as_deref().is_some_and(|m| m != model.mode_name(mode)) {
                            continue;
                        }
                        let Some(s) = model.states().iter().position(|q| q.name == *state) else {
                            continue;
                        };
                        driven.vector_field(mode, t, x, &mut f);
                        sens.flow(mode, t, x, u, &mut dfdp);
                        for j in 0..k {
                            size[j] += f[s] * f[s];
                            slope[j] += dfdp[s * k + j].powi(2);
                        }
                    }
                    Site::Guard { name } => {
                        let Some(g) = guards.iter().position(|h| h == name) else {
                            continue;
                        };
                        let h = model.guard_value(g, t, x, u);
                        sens.guard(g, t, x, u, &mut dhdp);
                        for j in 0..k {
                            size[j] += h * h;
                            slope[j] += dhdp[j].powi(2);
                        }
                    }
                }
            }
        }
        size.iter()
            .zip(&slope)
            .map(|(a, b)| {
                let v = (a / b).sqrt();
                if v.is_finite() && v > 0.0 {
                    v
                } else {
                    1.0
                }
            })
            .collect()
    }
}

/// A candidate effect to try.
enum Trial {
    Boundary(BoundaryEffect),
    Term(TermEffect),
}

impl Trial {
    fn name(&self) -> String {
        match self {
            Trial::Boundary(e) => e.name().to_string(),
            Trial::Term(t) => t.name.clone(),
        }
    }

    fn describe(&self) -> Option<String> {
        match self {
            Trial::Boundary(_) => None,
            Trial::Term(t) => Some(t.describe()),
        }
    }

    fn parameter_names(&self, outputs: &[String]) -> Vec<String> {
        match self {
            Trial::Boundary(e) => e.parameter_names(outputs),
            Trial::Term(t) => t.parameter_names(),
        }
    }
}

/// An effect tried: its result, its simulated outputs (when fitted) and its scaled residuals
/// on the fit data (outputs one after another).
#[derive(Clone)]
struct Tried {
    candidate: ModelCandidate,
    simulated: Option<Vec<Vec<f64>>>,
    residuals: Vec<f64>,
    /// The fitted initial state and the fit's sum of squares (empty and NaN when it failed).
    state: Vec<f64>,
    rss: f64,
    /// The trials fitted together, in the order they were chosen (`trial` last).
    set: Vec<usize>,
}

/// The joint fit of several effects, its held-out score, its simulated outputs and the names
/// of its fitted parameters (in the fit's order).
type SetFit = (JointFit, ModelScore, Vec<Vec<f64>>, Vec<String>);

/// One joint output-error fit: free parameters, effect parameters and the initial state.
struct JointFit {
    /// Free parameters, then the effect's.
    params: Vec<f64>,
    stderr: Vec<f64>,
    state: Vec<f64>,
    residuals: Vec<f64>,
    rss: f64,
    iterations: usize,
    stop: String,
}

/// Joint fits of a model's free parameters with a boundary effect on one record.
struct Joint<'a, 'r> {
    est: &'a Prepared<'r>,
    model: &'a Model,
    names: &'a [&'a str],
    index: &'a [usize],
    /// The size of a meaningful change of each parameter in `names` (the fit's scaling).
    scales: Vec<f64>,
    /// Most iterations of a fit.
    max_iter: usize,
}

impl Joint<'_, '_> {
    /// The longest lag or delay tried: a tenth of the record and, for a forced model, half its
    /// period (a delay of a whole period reproduces a periodic response).
    fn longest_lag(&self) -> f64 {
        let record = 0.1 * self.est.dt * self.est.rec.len() as f64;
        self.model
            .period()
            .map_or(record, |period| record.min(0.5 * period))
    }

    fn model_at(&self, values: &[f64]) -> Result<Model, DiagnoseError> {
        let changes: Vec<(&str, f64)> = self
            .names
            .iter()
            .copied()
            .zip(values.iter().copied())
            .collect();
        self.model
            .with_parameters(&changes)
            .map_err(|e| DiagnoseError::NominalFit {
                reason: e.to_string(),
            })
    }

    /// A start for `effect`'s parameters: the neutral values for an offset and a gain; for a
    /// lag or delay, the best of a grid across decades (1 to 300 sample intervals, up to a
    /// tenth of the record) by the output error with the refit's parameters and state.
    fn effect_start(
        &self,
        effect: BoundaryEffect,
        base: &JointFit,
        outputs: &[String],
    ) -> Vec<f64> {
        if !effect.is_lag() {
            return effect.neutral(outputs.len());
        }
        let est = self.est;
        let longest = self.longest_lag();
        let Ok(m) = self.model_at(&base.params[..self.index.len()]) else {
            return vec![est.dt];
        };
        let mut r = vec![0.0; est.residual_len()];
        let mut best = (f64::INFINITY, 0.0);
        // Zero (the refit itself) competes, so the start is never worse than the refit.
        for steps in [0.0, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0] {
            let v = steps * est.dt;
            if v > longest {
                break;
            }
            let b = Boundary::with(effect, &[v], outputs.len());
            if let Ok(sim) = est.simulate(&m, &base.state, &b) {
                est.fill(&sim, &mut r);
                let cost: f64 = r.iter().map(|v| v * v).sum();
                if cost < best.0 {
                    best = (cost, v);
                }
            }
        }
        vec![best.1]
    }

    /// Fits the free parameters, the parameters of the boundary `effects` (from
    /// `effect_start`, one effect's after another) and the initial state (from `x0`) together.
    fn fit(
        &self,
        effects: &[BoundaryEffect],
        effect_start: &[f64],
        x0: &[f64],
    ) -> Result<JointFit, DiagnoseError> {
        let (est, model) = (self.est, self.model);
        let k = self.index.len();
        let e = effect_start.len();
        let outputs = model.outputs().len();
        let mut p0: Vec<f64> = self.index.iter().map(|&i| model.values()[i]).collect();
        p0.extend_from_slice(effect_start);
        p0.extend_from_slice(x0);
        let residuals = |p: &[f64], r: &mut [f64]| -> Result<(), String> {
            let trial = self.model_at(&p[..k]).map_err(|e| e.to_string())?;
            let b = Boundary::with_all(effects, &p[k..k + e], outputs);
            let sim = est
                .simulate(&trial, &p[k + e..], &b)
                .map_err(|e| e.to_string())?;
            est.fill(&sim, r);
            Ok(())
        };
        let params = model.parameters();
        let mut bounds: Vec<(f64, f64)> = self
            .index
            .iter()
            .map(|&i| (params[i].min, params[i].max))
            .collect();
        let counted: usize = effects.iter().map(|x| x.parameter_count(outputs)).sum();
        if counted != e {
            return Err(DiagnoseError::NominalFit {
                reason: format!(
                    "{e} starting values for boundary effects with {counted} parameters"
                ),
            });
        }
        let mut scales: Vec<f64> = self.scales.clone();
        let mut at = 0;
        for &effect in effects {
            let n = effect.parameter_count(outputs);
            let start = &effect_start[at..at + n];
            at += n;
            for (j, v) in start.iter().enumerate() {
                if effect.is_lag() {
                    bounds.push((0.0, self.longest_lag()));
                    scales.push(v.abs().max(est.dt));
                } else {
                    bounds.push((f64::NEG_INFINITY, f64::INFINITY));
                    scales.push(match effect {
                        BoundaryEffect::InputOffset => input_scale(est.rec),
                        _ if j % 2 == 0 => est.scale[j / 2],
                        _ => 0.1,
                    });
                }
            }
        }
        bounds.extend_from_slice(&est.state_box);
        scales.extend(x0.iter().map(|v| v.abs().max(1e-3)));
        // Exact columns for the model's parameters and the initial state; differences for the
        // boundary effects' own, and for all where the sensitivities do not hold (the motion
        // slides) or their simulation fails (a fit must not fail where differences work).
        let exact_at: Vec<usize> = (0..k).chain(k + e..k + e + x0.len()).collect();
        let boundary: Vec<usize> = (k..k + e).collect();
        let every: Vec<usize> = (0..k + e + x0.len()).collect();
        // Once the sensitivities fail (the motion slides), the rest of the fit differences.
        let failed = std::cell::Cell::new(false);
        let jacobian = |p: &[f64], r: &[f64], jac: &mut [f64]| -> Result<(), String> {
            let trial = self.model_at(&p[..k]).map_err(|e| e.to_string())?;
            let b = Boundary::with_all(effects, &p[k..k + e], outputs);
            let differences = |cols: &[usize], jac: &mut [f64]| {
                difference_columns(
                    &residuals,
                    p,
                    r,
                    cols,
                    (est.fd_step(), &scales, &bounds),
                    jac,
                )
            };
            let exact = !failed.get()
                && est
                    .sensitivities(
                        &trial,
                        self.names,
                        &p[k + e..],
                        &b,
                        est.rec.len(),
                        est.rows.clone(),
                        &exact_at,
                        jac,
                    )
                    .is_ok();
            failed.set(!exact);
            differences(if exact { &boundary } else { &every }, jac)
        };
        let lm = LmOptions {
            scales: Some(scales.clone()),
            bounds: Some(bounds.clone()),
            max_iter: self.max_iter,
            ..LmOptions::default()
        };
        let fit =
            levenberg_marquardt_with_jacobian(&residuals, jacobian, &p0, est.residual_len(), &lm)
                .map_err(|e| DiagnoseError::NominalFit {
                reason: e.to_string(),
            })?;
        let np = k + e;
        Ok(JointFit {
            params: fit.params[..np].to_vec(),
            stderr: match &fit.stderr {
                Some(s) => s[..np].to_vec(),
                None => vec![f64::NAN; np],
            },
            state: fit.params[np..].to_vec(),
            rss: fit.residuals.iter().map(|v| v * v).sum(),
            residuals: fit.residuals,
            iterations: fit.iterations,
            stop: format!("{:?}", fit.stop),
        })
    }
}

/// The input's standard deviation (at least 1e-3), the scale of an input offset.
fn input_scale(rec: &TimeSeries) -> f64 {
    let n = rec.input().len().max(1) as f64;
    let mean = rec.input().iter().sum::<f64>() / n;
    let var = rec.input().iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    var.sqrt().max(1e-3)
}
