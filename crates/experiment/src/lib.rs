//! One experiment on any rhythmic model.
//!
//! A [`Rhythmic`] model is a hybrid system with inputs and outputs, named parameters and a
//! periodic forcing that drives it onto a limit cycle: every model-language
//! [`htfid_lang::Model`] and the built-in [`htfid_model::Hopper`], or a Rust user's own. On it:
//!
//! - [`drive`]: the model driven by an input from its orbit, every output sampled on a grid
//!   (the trajectory kept for states, modes, switches and sliding); [`drive_sampled`] the
//!   same with the input's values at the grid given (an experiment's input is known before it
//!   runs, and may be sampled on another thread meanwhile);
//! - [`add_noise`]: seeded white measurement noise on the sampled outputs;
//! - [`orbit_deviation`]: what the estimators see, each output minus its value on the
//!   unexcited orbit (one period tiled when the grid repeats every period);
//! - [`distortion_bootstrap`]: the error an estimator and a parametric fit make without noise
//!   on the fitted model (a parametric bootstrap), the known bias of a line estimator's fit.
//!
//! ```
//! use std::sync::Arc;
//! use htfid_experiment::{drive, orbit_deviation, Rhythmic};
//! use htfid_hybrid::Options;
//! use htfid_model::{Hopper, HopperParams};
//! use htfid_orbit::ShootingOptions;
//!
//! let hopper = Hopper::new(HopperParams::paper())?;
//! let opts = Options::default();
//! let cycle = Rhythmic::limit_cycle(&hopper, &ShootingOptions::default(), &opts)?;
//! let times: Vec<f64> = (0..500).map(|i| 0.01 * f64::from(i)).collect();
//! // Without input the record is the orbit itself: its deviation is zero.
//! let run = drive(&hopper, &cycle, None, &times, &opts)?;
//! let dev = orbit_deviation(&hopper, &cycle, &times, &run.outputs, &opts)?;
//! assert!(dev[0].iter().all(|d| d.abs() < 1e-9));
//! // A small step force moves the mass by about u / k.
//! let step: htfid_experiment::Input = Arc::new(|t| if t > 1.0 { 0.01 } else { 0.0 });
//! let run = drive(&hopper, &cycle, Some(step), &times, &opts)?;
//! let dev = orbit_deviation(&hopper, &cycle, &times, &run.outputs, &opts)?;
//! assert!((dev[0][499] - 0.01 / 200.0).abs() < 2e-5);
//! # Ok::<(), htfid_experiment::ExperimentError>(())
//! ```

mod equations;

use std::sync::Arc;

use htfid_estimate::HtfEstimate;
use htfid_hybrid::{simulate, HybridError, Options, Trajectory};
use htfid_identify::{fit_to_htf, HtfFit, HtfFitSpec, IdentifyError, Parametric};
use htfid_lang::Model;
use htfid_model::Hopper;
use htfid_orbit::{find_limit_cycle, LimitCycle, ShootingOptions};
use htfid_theory::{HarmonicTransferFunction, LinearisedHtf, TheoryError};
use num_complex::Complex64;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// A time-varying input `u(t)` added to the model's forcing. Absolute time, s.
pub type Input = Arc<dyn Fn(f64) -> f64 + Send + Sync>;

/// Why an experiment step failed; each variant wraps the error of the crate that failed.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum ExperimentError {
    /// The built-in hopper's parameters or its limit cycle.
    #[error(transparent)]
    Hopper(#[from] htfid_model::ModelError),
    /// A model-language model's parameters or its limit cycle.
    #[error(transparent)]
    Model(#[from] htfid_lang::ModelError),
    /// A limit cycle found with `htfid-orbit` directly (a model of a Rust user's own).
    #[error(transparent)]
    Orbit(#[from] htfid_orbit::OrbitError),
    /// A simulation.
    #[error(transparent)]
    Simulation(#[from] HybridError),
    /// The linearisation or the HTFs of the fitted model.
    #[error(transparent)]
    Theory(#[from] TheoryError),
    /// The refit of the bootstrap.
    #[error(transparent)]
    Identify(#[from] IdentifyError),
    /// The limit cycle of a model changed by a fit.
    #[error("the fitted model has no limit cycle: {0}")]
    FittedModel(String),
    /// The input's values handed to [`drive_sampled`] do not match its grid.
    #[error("{found} input values for a grid of {expected} times")]
    InputSamples {
        /// Times of the grid.
        expected: usize,
        /// Input values given.
        found: usize,
    },
    /// The re-run of the experiment lacks an estimate the fit used.
    #[error("the re-run of the experiment has no estimate of G_{n} at {omega} rad/s (output {output}) that the fit used")]
    MissingEstimate {
        /// Output index.
        output: usize,
        /// Harmonic.
        n: i32,
        /// Output frequency, rad/s.
        omega: f64,
    },
    /// The noise level is not a finite number `>= 0`.
    #[error("measurement noise standard deviation must be finite and >= 0 (got {0})")]
    InvalidNoise(f64),
}

/// A rhythmic model: a hybrid system with inputs and outputs ([`InputOutput`](htfid_ltp::InputOutput)), named
/// parameters ([`Parametric`]), driven onto a limit cycle by its periodic forcing.
pub trait Rhythmic: Parametric {
    /// The limit cycle with the input off (settling, then Newton shooting).
    ///
    /// # Errors
    /// When no stable periodic orbit is found.
    fn limit_cycle(
        &self,
        shooting: &ShootingOptions,
        integrator: &Options,
    ) -> Result<LimitCycle<Self::Mode>, ExperimentError>;

    /// The same model driven by `input` (added to its forcing), or undriven with `None`.
    fn with_input(&self, input: Option<Input>) -> Self;

    /// The outputs at `(mode, t, x)` with input `u`, into `y` (length
    /// [`num_outputs`](htfid_ltp::InputOutput::num_outputs)).
    fn outputs(&self, mode: Self::Mode, t: f64, x: &[f64], u: f64, y: &mut [f64]);

    /// The same model, input off, written in the model language: its states, parameters,
    /// modes, guards and outputs as equations. The diagnosis (`htfid_diagnose::diagnose_model`)
    /// needs them, because it adds each candidate effect as a term to a named equation, guard,
    /// input or output and fits its parameters with exact sensitivities; every other step
    /// works on the model's code alone. `None` (the default) for a model that has no such
    /// equations; an error when writing them fails (a Rust model whose text does not read).
    ///
    /// A model-language [`Model`] is its own equations. The built-in [`Hopper`] writes
    /// `models/hopper.toml` with its values and each of its extra terms in the equations, and
    /// has none with an input delay, which the language cannot write.
    fn equations(&self) -> Option<Result<Model, ExperimentError>> {
        None
    }

    /// Whether [`equations`](Rhythmic::equations) are this very model (a model-language
    /// [`Model`]): the diagnosis then has nothing to check them against. `false` (the
    /// default) for every model written in code, whose equations the diagnosis drives beside
    /// it before any fit.
    fn is_its_own_equations(&self) -> bool {
        false
    }
}

impl Rhythmic for Hopper {
    fn limit_cycle(
        &self,
        shooting: &ShootingOptions,
        integrator: &Options,
    ) -> Result<LimitCycle<Self::Mode>, ExperimentError> {
        Ok(Hopper::limit_cycle(self, shooting, integrator)?.cycle)
    }

    fn with_input(&self, input: Option<Input>) -> Self {
        Hopper::with_input(self, input)
    }

    /// The hopper's one output is the position `x` (m).
    fn outputs(&self, _mode: Self::Mode, _t: f64, x: &[f64], _u: f64, y: &mut [f64]) {
        y[0] = x[0];
    }

    fn equations(&self) -> Option<Result<Model, ExperimentError>> {
        equations::hopper_equations(self)
    }
}

impl Rhythmic for Model {
    fn limit_cycle(
        &self,
        shooting: &ShootingOptions,
        integrator: &Options,
    ) -> Result<LimitCycle<Self::Mode>, ExperimentError> {
        Ok(Model::limit_cycle(self, shooting, integrator)?)
    }

    fn with_input(&self, input: Option<Input>) -> Self {
        Model::with_input(self, input)
    }

    fn outputs(&self, mode: Self::Mode, t: f64, x: &[f64], u: f64, y: &mut [f64]) {
        self.eval_outputs(mode, t, x, u, y);
    }

    fn equations(&self) -> Option<Result<Model, ExperimentError>> {
        Some(Ok(self.with_input(None)))
    }

    fn is_its_own_equations(&self) -> bool {
        true
    }
}

/// A driven run: the trajectory on the grid and every output sampled on it.
#[derive(Debug, Clone)]
pub struct Driven<M> {
    /// States, modes, events, sliding intervals and work counters on the grid.
    pub trajectory: Trajectory<M>,
    /// One vector per output, one value per grid time.
    pub outputs: Vec<Vec<f64>>,
}

/// The model driven by `input` from its orbit `cycle` (at the orbit's phase-0 time), every
/// output sampled at `times` (non-decreasing, from the orbit's start).
///
/// # Errors
/// [`ExperimentError::Simulation`] when the integrator cannot proceed or `times` is not a grid.
pub fn drive<S: Rhythmic>(
    system: &S,
    cycle: &LimitCycle<S::Mode>,
    input: Option<Input>,
    times: &[f64],
    opts: &Options,
) -> Result<Driven<S::Mode>, ExperimentError> {
    let samples = || {
        times
            .iter()
            .map(|&t| input.as_ref().map_or(0.0, |u| u(t)))
            .collect()
    };
    drive_sampled(system, cycle, input.clone(), times, opts, samples)
}

/// [`drive`] with the input's values at `times` given by the caller, who often has them
/// already (an experiment's input is known before it is run). `samples` is called once the
/// trajectory is known, so they may be computed meanwhile on another thread; they must equal
/// `input` at `times`, one value per time, which the outputs read.
///
/// # Errors
/// As [`drive`]; [`ExperimentError::InputSamples`] when `samples` gives a value per time
/// of another count.
pub fn drive_sampled<S: Rhythmic>(
    system: &S,
    cycle: &LimitCycle<S::Mode>,
    input: Option<Input>,
    times: &[f64],
    opts: &Options,
    samples: impl FnOnce() -> Vec<f64>,
) -> Result<Driven<S::Mode>, ExperimentError> {
    let driven = system.with_input(input);
    let t_end = times.last().copied().unwrap_or(cycle.t0).max(cycle.t0);
    let trajectory = simulate(
        &driven,
        cycle.mode0,
        cycle.t0,
        &cycle.state0,
        t_end,
        times,
        opts,
    )?;
    let u = samples();
    if u.len() != trajectory.times.len() {
        return Err(ExperimentError::InputSamples {
            expected: trajectory.times.len(),
            found: u.len(),
        });
    }
    let outputs = sample_outputs(&driven, &trajectory, &u);
    Ok(Driven {
        trajectory,
        outputs,
    })
}

/// Every output along a trajectory, with the input's value `u[i]` at grid time `i`.
fn sample_outputs<S: Rhythmic>(system: &S, traj: &Trajectory<S::Mode>, u: &[f64]) -> Vec<Vec<f64>> {
    let p = system.num_outputs();
    let n = traj.times.len();
    let mut outputs = vec![vec![0.0; n]; p];
    let mut y = vec![0.0; p];
    for (i, &t) in traj.times.iter().enumerate() {
        system.outputs(traj.modes[i], t, traj.state(i), u[i], &mut y);
        for (column, v) in outputs.iter_mut().zip(&y) {
            column[i] = *v;
        }
    }
    outputs
}

/// Adds white Gaussian noise of standard deviation `std` to every sample of every output,
/// drawn from a ChaCha8 generator seeded with `seed` (output by output, in time order), so a
/// record is reproducible from its seed.
///
/// # Errors
/// [`ExperimentError::InvalidNoise`] for a negative or non-finite `std`.
pub fn add_noise(outputs: &mut [Vec<f64>], std: f64, seed: u64) -> Result<(), ExperimentError> {
    if !(std.is_finite() && std >= 0.0) {
        return Err(ExperimentError::InvalidNoise(std));
    }
    if std == 0.0 {
        return Ok(());
    }
    let normal = Normal::new(0.0, std).map_err(|_| ExperimentError::InvalidNoise(std))?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    for column in outputs {
        for v in column.iter_mut() {
            *v += normal.sample(&mut rng);
        }
    }
    Ok(())
}

/// Tolerance on "the grid repeats every period": `samples per period` within this of an
/// integer.
const WHOLE_PERIOD_TOL: f64 = 1e-9;

/// What the estimators see: each output minus its value on the unexcited orbit at the same
/// times. When the grid starts at phase 0 and repeats every period, one period of the orbit
/// is computed and tiled; otherwise the orbit is followed over the whole grid.
///
/// # Errors
/// [`ExperimentError::Simulation`] when the orbit's integration fails.
pub fn orbit_deviation<S: Rhythmic>(
    system: &S,
    cycle: &LimitCycle<S::Mode>,
    times: &[f64],
    outputs: &[Vec<f64>],
    opts: &Options,
) -> Result<Vec<Vec<f64>>, ExperimentError> {
    let dt = if times.len() >= 2 {
        times[1] - times[0]
    } else {
        0.0
    };
    let per_period = if dt > 0.0 { cycle.period / dt } else { 0.0 };
    let m = per_period.round() as usize;
    let tiled = (per_period - per_period.round()).abs() < WHOLE_PERIOD_TOL
        && m >= 1
        && times.len() >= m
        && (times[0] - cycle.t0).abs() < 1e-12;
    let grid = if tiled { &times[..m] } else { times };
    let free = system.with_input(None);
    let orbit = drive(&free, cycle, None, grid, opts)?;
    Ok(outputs
        .iter()
        .zip(&orbit.outputs)
        .map(|(y, y0)| {
            y.iter()
                .enumerate()
                .map(|(i, v)| v - y0[i % grid.len()])
                .collect()
        })
        .collect())
}

/// A fit's error without noise, from [`distortion_bootstrap`].
#[derive(Debug, Clone)]
pub struct Bootstrap {
    /// At every point of [`HtfFit::fitted`]: the re-run's estimate minus the fitted model's
    /// exact HTF.
    pub htf_bias: Vec<Complex64>,
    /// The refit of the re-run minus the fitted values, per parameter.
    pub parameter_bias: Vec<f64>,
}

/// The error an estimator and a fit make without noise on the fitted model: `model` with the
/// values of `fit`, its limit cycle found again from `cycle`, the experiment run on it again
/// by `rerun` (which simulates without noise and returns one estimate per output), refitted
/// with `spec`, and compared with the fitted model's exact HTFs.
///
/// # Errors
/// The fitted model's limit cycle, linearisation or refit fails, `rerun` fails (its error is
/// passed through), or the re-run lacks a point the fit used.
pub fn distortion_bootstrap<S, E>(
    model: &S,
    cycle: &LimitCycle<S::Mode>,
    fit: &HtfFit,
    spec: &HtfFitSpec,
    opts: &Options,
    rerun: impl Fn(&S, &LimitCycle<S::Mode>) -> Result<Vec<HtfEstimate>, E>,
) -> Result<Bootstrap, E>
where
    S: Rhythmic,
    E: From<ExperimentError>,
{
    let changes: Vec<(&str, f64)> = fit
        .parameters
        .iter()
        .map(String::as_str)
        .zip(fit.values.iter().copied())
        .collect();
    let fitted = model
        .unforced_with(&changes)
        .map_err(ExperimentError::FittedModel)?;
    let period = cycle.period;
    let shooting = ShootingOptions {
        settle_periods: 0,
        ..ShootingOptions::default()
    };
    let orbit = find_limit_cycle(
        &fitted,
        cycle.mode0,
        cycle.t0,
        &cycle.state0,
        period,
        &shooting,
        opts,
    )
    .map_err(|e| ExperimentError::FittedModel(e.to_string()))?;
    let estimates = rerun(&fitted, &orbit)?;
    let of_outputs: Vec<(usize, &HtfEstimate)> = estimates.iter().enumerate().collect();
    let refit =
        fit_to_htf(&fitted, &orbit, &of_outputs, spec, opts).map_err(ExperimentError::from)?;
    let htf = LinearisedHtf::new(&fitted, &orbit, opts).map_err(ExperimentError::from)?;
    let channels = (0..htf.n_outputs())
        .map(|o| htf.channel(o))
        .collect::<Result<Vec<_>, _>>()
        .map_err(ExperimentError::from)?;
    let mut htf_bias = Vec::with_capacity(fit.fitted.len());
    for p in &fit.fitted {
        let missing = || ExperimentError::MissingEstimate {
            output: p.output,
            n: p.n,
            omega: p.omega,
        };
        let h = estimates
            .get(p.output)
            .and_then(|e| e.harmonic(p.n))
            .ok_or_else(missing)?;
        let i = h
            .omegas
            .iter()
            .position(|&o| (o - p.omega).abs() <= 1e-9 * p.omega.abs().max(1.0))
            .ok_or_else(missing)?;
        let channel = channels.get(p.output).ok_or_else(missing)?;
        htf_bias.push(h.values[i] - channel.g(p.n, p.omega));
    }
    let parameter_bias = refit
        .values
        .iter()
        .zip(&fit.values)
        .map(|(a, b)| a - b)
        .collect();
    Ok(Bootstrap {
        htf_bias,
        parameter_bias,
    })
}
