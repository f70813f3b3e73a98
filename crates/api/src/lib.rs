//! htfid as a library: the common path in a few lines, over the crates that do the work.
//!
//! - [`Htf::of`]: a rhythmic hybrid system (the built-in [`Hopper`], or any [`Model`] read from
//!   a model file) to its exact harmonic transfer functions: limit cycle by Newton shooting,
//!   linearisation about it with saltation at every switch, exact (untruncated) HTFs.
//! - [`estimate`]: a measured record (input and output, uniformly sampled) to estimated HTFs
//!   with standard errors: the orbit is the record's period average, Siddiqi's regularised
//!   estimator works on the deviations from it.
//!
//! Each step has options ([`HtfOptions`], [`EstimateOptions`]) with defaults that suit the
//! shipped models; the option types of the crates underneath are re-exported here. For more
//! (truncated HTFs, other estimators, parametric fits, the diagnosis's evidence) use the crates
//! directly: `htfid-theory`, `htfid-estimate`, `htfid-identify`, `htfid-diagnose`.
//! [`diagnose_model`] is re-exported: from a record to what the model gets wrong.
//!
//! # Conventions
//!
//! The paper's output equation `Y(jw) = sum_n G_n(jw) U(jw - j n wp)`: `G_n` is indexed by the
//! **output** frequency `w` (rad/s), `wp = 2 pi / T` is the pumping frequency of the orbit's
//! period `T`. Time is absolute and `t = 0` is the forcing's phase 0. SI units.
//!
//! # From the hopper to its exact HTFs
//!
//! The paper's hopper `m x'' = -m g - c s x' - k (x - x0) + f` with its damper on while the mass
//! moves up. A constant input force moves the orbit by `u / k` and changes no switch time (the
//! damper switches where `x' = 0`, where it exerts no force), so `G_0(j0) = 1 / k` exactly:
//!
//! ```
//! use htfid_api::{Hopper, HopperParams, Htf};
//!
//! let hopper = Hopper::new(HopperParams::paper())?; // k = 200 N/m, c = 2 N s/m, T = 1 s
//! let htf = Htf::of(&hopper)?;
//! let dc = htf.g(0, 0.0)?;
//! assert!((dc.re - 1.0 / 200.0).abs() < 1e-8 && dc.im.abs() < 1e-8, "G_0(j0) = {dc}");
//! // The switching damper couples frequencies: G_1 is far from zero near resonance.
//! assert!(htf.g(1, 14.0)?.norm() > 1e-3);
//! # Ok::<(), htfid_api::Error>(())
//! ```
//!
//! # From data to estimated HTFs, compared with the theory
//!
//! Here the "measurement" is a simulation of the hopper driven by a small random force; with
//! measured data, `t0`, `dt`, `u` and `y` come from the file instead. The single-record
//! estimator leans on smoothness across frequency bins, so the record must be long against
//! the width of the resonance (about 1 rad/s at 14 rad/s): 200 s give bins of 0.03 rad/s.
//! The estimate then matches the exact theory with a median error of 0.7 % of `max |G_0|` and
//! a worst one of 12 % (the random input does not repeat, so it leaks between bins); the
//! example checks 2 % and 20 %:
//!
//! ```
//! use std::sync::Arc;
//! use htfid_api::{estimate, simulate, EstimateOptions, Hopper, HopperParams, Htf};
//!
//! let hopper = Hopper::new(HopperParams::paper())?;
//! let htf = Htf::of(&hopper)?;
//! // A pseudo-random force (xorshift, fixed seed), linear between knots 0.05 s apart: flat to
//! // well beyond the band, and small (3 mN RMS against the 1 N forcing) so the response
//! // stays linear.
//! let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
//! let knots: Vec<f64> = (0..=4500)
//!     .map(|_| {
//!         state ^= state << 13;
//!         state ^= state >> 7;
//!         state ^= state << 17;
//!         (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
//!     })
//!     .collect();
//! let input = Arc::new(move |t: f64| {
//!     let x = t / 0.05;
//!     let i = (x.floor().max(0.0) as usize).min(knots.len() - 2);
//!     let a = x - i as f64;
//!     0.01 * ((1.0 - a) * knots[i] + a * knots[i + 1])
//! });
//! let (t0, dt, period) = (20.0, 0.01, 1.0); // 20 s of settling, 100 Hz, T = 1 s
//! let t: Vec<f64> = (0..20_000).map(|i| t0 + i as f64 * dt).collect();
//! let u: Vec<f64> = t.iter().map(|&t| input(t)).collect();
//! let y = simulate(&htf, input, &t)?; // one vector per output: the hopper's position
//!
//! let options = EstimateOptions {
//!     harmonics: vec![-1, 0, 1],
//!     band: (1.0, 25.0),
//!     ..Default::default()
//! };
//! let estimated = estimate(t0, dt, &u, &y[0], period, &options)?;
//! let scale = (1..=250).map(|k| htf.g(0, 0.1 * k as f64).unwrap().norm()).fold(0.0, f64::max);
//! let mut errors: Vec<f64> = Vec::new();
//! for row in estimated.rows().filter(|r| r.n == 0) {
//!     errors.push((row.value - htf.g(0, row.omega)?).norm() / scale);
//! }
//! errors.sort_by(f64::total_cmp);
//! let (median, worst) = (errors[errors.len() / 2], errors[errors.len() - 1]);
//! assert!(median < 0.02 && worst < 0.2, "G_0 error: median {median:e}, worst {worst:e}");
//! # Ok::<(), htfid_api::Error>(())
//! ```
//!
//! # From data to what the model gets wrong
//!
//! [`diagnose_model`] takes the same models. Here the "measured" hopper has a damper of
//! 0.2 N s/m also while it moves down, which the nominal hopper lacks; its record is simulated
//! by the hopper's Rust code, and the diagnosis works on the nominal hopper's equations in the
//! model language ([`Rhythmic::equations`]), a second description of the same system written
//! separately. It refits `k` and `c`, tries every candidate effect at every site the equations
//! offer, and names the damping in the `free` mode with its coefficient per unit mass (the
//! fit gives 0.2000; the example checks 2 %):
//!
//! ```
//! use std::sync::Arc;
//! use htfid_api::{
//!     diagnose_model, simulate, DamperLaw, Effects, Hopper, HopperParams, Htf, ModelFitOptions,
//!     TimeSeries,
//! };
//!
//! let measured = Hopper::with_effects(
//!     HopperParams::paper(),
//!     DamperLaw::Switching,
//!     Effects { c_f: 0.2, ..Effects::default() },
//! )?;
//! // 60 s of a small three-sine force at 100 Hz from the orbit.
//! let input = Arc::new(|t: f64| 0.01 * ((9.0 * t).sin() + (14.5 * t).sin() + (23.0 * t).cos()));
//! let t: Vec<f64> = (0..6000).map(|i| i as f64 * 0.01).collect();
//! let u: Vec<f64> = t.iter().map(|&t| input(t)).collect();
//! let y = simulate(&Htf::of(&measured)?, input, &t)?;
//! let record = TimeSeries::new(t, u, y[0].clone(), "simulated")?;
//!
//! let nominal = Hopper::new(HopperParams::paper())?;
//! let options = ModelFitOptions { free: vec!["k".into(), "c".into()], ..Default::default() };
//! let diagnosis = diagnose_model(&nominal, &record, None, &options)?;
//! assert_eq!(diagnosis.cause.name(), "mode_damping(v, free)");
//! let damping = diagnosis.causes[0].parameters["damping_v_free"];
//! assert!((damping / 0.2 - 1.0).abs() < 0.02, "{damping}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # A model of your own, written in Rust
//!
//! A Rust model takes the whole path by implementing four traits: its charts, vector field and
//! guards ([`HybridSystem`]), how the input enters and what is measured ([`InputOutput`]), its
//! named parameters ([`Parametric`]), and its limit cycle ([`Rhythmic`]: usually
//! [`find_limit_cycle`] on the system with its input off). The input is not an argument of the
//! vector field: the system holds it ([`Rhythmic::with_input`]) and reads it at `t`. To be
//! diagnosed (`htfid_diagnose::diagnose_model`), it also gives its equations in the model
//! language ([`Rhythmic::equations`]), to which the diagnosis adds its candidate effects.
//!
//! Here a forced oscillator `x'' = -k x - c x' + cos(wp t) + u` whose damping is `c_up` while it
//! moves up and `c_down` while it moves down: two charts, switched where `x' = 0`. As for the
//! hopper, the damping switches where it exerts no force, so a constant input moves the orbit by
//! `u / k` and `G_0(j0) = 1 / k` exactly; the two dampings couple frequencies (`G_1 != 0`):
//!
//! ```
//! use htfid_api::{
//!     find_limit_cycle, Crossing, ExperimentError, HybridSystem, Htf, Input, InputOutput,
//!     IntegratorOptions, LimitCycle, Parametric, Rhythmic, ShootingOptions,
//! };
//!
//! #[derive(Clone, Copy, Debug, PartialEq, Eq)]
//! enum Moving { Up, Down }
//!
//! #[derive(Clone)]
//! struct TwoDampers { k: f64, c_up: f64, c_down: f64, wp: f64, input: Option<Input> }
//!
//! impl HybridSystem for TwoDampers {
//!     type Mode = Moving;
//!     fn dim(&self) -> usize { 2 }
//!     fn vector_field(&self, mode: Moving, t: f64, x: &[f64], dx: &mut [f64]) {
//!         let c = if mode == Moving::Up { self.c_up } else { self.c_down };
//!         let u = self.input.as_ref().map_or(0.0, |u| u(t));
//!         dx[0] = x[1];
//!         dx[1] = -self.k * x[0] - c * x[1] + (self.wp * t).cos() + u;
//!     }
//!     // One guard per chart, x' = 0, crossed downwards while moving up and upwards while
//!     // moving down; crossing it changes the chart and resets nothing.
//!     fn num_guards(&self, _: Moving) -> usize { 1 }
//!     fn guard(&self, _: Moving, _: usize, _t: f64, x: &[f64]) -> f64 { x[1] }
//!     fn guard_direction(&self, mode: Moving, _: usize) -> Crossing {
//!         if mode == Moving::Up { Crossing::Falling } else { Crossing::Rising }
//!     }
//!     fn transition(&self, mode: Moving, _: usize, _t: f64, _x: &mut [f64]) -> Moving {
//!         if mode == Moving::Up { Moving::Down } else { Moving::Up }
//!     }
//! }
//!
//! impl InputOutput for TwoDampers {
//!     fn input_gain(&self, _: Moving, _t: f64, _x: &[f64], b: &mut [f64]) {
//!         b.copy_from_slice(&[0.0, 1.0]);
//!     }
//!     fn output_gain(&self, _: Moving, _t: f64, _x: &[f64], c: &mut [f64]) {
//!         c.copy_from_slice(&[1.0, 0.0]); // the position is measured
//!     }
//!     // A(t) is constant in each chart: the HTFs in closed form.
//!     fn is_piecewise_constant(&self) -> bool { true }
//! }
//!
//! impl Parametric for TwoDampers {
//!     fn parameter(&self, name: &str) -> Option<(f64, (f64, f64))> {
//!         match name {
//!             "k" => Some((self.k, (1e-9, f64::INFINITY))),
//!             _ => None,
//!         }
//!     }
//!     fn unforced_with(&self, changes: &[(&str, f64)]) -> Result<Self, String> {
//!         let mut s = self.with_input(None);
//!         for &(name, v) in changes {
//!             match name {
//!                 "k" => s.k = v,
//!                 _ => return Err(format!("no parameter {name}")),
//!             }
//!         }
//!         Ok(s)
//!     }
//!     fn forcing_period(&self) -> Option<f64> { Some(std::f64::consts::TAU / self.wp) }
//! }
//!
//! impl Rhythmic for TwoDampers {
//!     fn limit_cycle(
//!         &self,
//!         shooting: &ShootingOptions,
//!         integrator: &IntegratorOptions,
//!     ) -> Result<LimitCycle<Moving>, ExperimentError> {
//!         let period = std::f64::consts::TAU / self.wp;
//!         // Start anywhere near the orbit: settling and Newton shooting do the rest.
//!         let start = [0.0, 0.1];
//!         Ok(find_limit_cycle(&self.with_input(None), Moving::Up, 0.0, &start, period, shooting,
//!             integrator)?)
//!     }
//!     fn with_input(&self, input: Option<Input>) -> Self { TwoDampers { input, ..self.clone() } }
//!     fn outputs(&self, _: Moving, _t: f64, x: &[f64], _u: f64, y: &mut [f64]) { y[0] = x[0]; }
//! }
//!
//! let system = TwoDampers { k: 10.0, c_up: 1.0, c_down: 0.2, wp: 2.0, input: None };
//! let htf = Htf::of(&system)?;
//! let dc = htf.g(0, 0.0)?;
//! assert!((dc.re - 0.1).abs() < 1e-8 && dc.im.abs() < 1e-8, "G_0(j0) = {dc}");
//! assert!(htf.g(1, 3.0)?.norm() > 1e-3);
//! # Ok::<(), htfid_api::Error>(())
//! ```

use htfid_estimate::{DataSpec, FromDataError, PeriodChoice, PeriodicRecord};
use htfid_theory::HarmonicTransferFunction;

pub use htfid_diagnose::{
    diagnose_model, DiagnoseError, ModelCause, ModelDiagnosis, ModelFitOptions, TimeSeries,
};
pub use htfid_estimate::{Alpha, HtfEstimate, HtfRow};
pub use htfid_experiment::{ExperimentError, Input, Rhythmic};
pub use htfid_hybrid::Options as IntegratorOptions;
/// The traits a model written in Rust implements to take the whole path (see
/// `crates/experiment/tests/own_model.rs` for a worked example): its charts, vector fields,
/// guards and resets ([`HybridSystem`]), its input and outputs ([`InputOutput`]), its named
/// parameters ([`Parametric`]) and its limit cycle ([`Rhythmic`], usually
/// [`find_limit_cycle`] on the system with its input off).
pub use htfid_hybrid::{Crossing, HybridSystem};
pub use htfid_identify::Parametric;
pub use htfid_lang::Model;
pub use htfid_ltp::InputOutput;
pub use htfid_model::{DamperLaw, Effects, Hopper, HopperParams};
pub use htfid_orbit::find_limit_cycle;
pub use htfid_orbit::{LimitCycle, ShootingOptions};
pub use htfid_theory::LinearisedHtf;
pub use htfid_theory::{HtfGrid, HtfMethod};
pub use num_complex::Complex64;

/// Why a step of the common path failed; each variant wraps the error of the crate that
/// failed, which carries the numbers.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The hopper's parameters or its limit cycle.
    #[error(transparent)]
    Hopper(#[from] htfid_model::ModelError),
    /// A model file, or a model-language model's limit cycle.
    #[error(transparent)]
    Model(#[from] htfid_lang::ModelError),
    /// The linearisation or the HTFs.
    #[error(transparent)]
    Theory(#[from] htfid_theory::TheoryError),
    /// A simulation.
    #[error(transparent)]
    Simulation(#[from] htfid_hybrid::HybridError),
    /// The estimation.
    #[error(transparent)]
    Estimate(#[from] htfid_estimate::Error),
    /// What a record cannot give: too few periods, a band beyond its Nyquist frequency, a
    /// period its data contradict, ...
    #[error(transparent)]
    FromData(#[from] htfid_estimate::FromDataError),
    /// Any other step of an experiment (`htfid-experiment`).
    #[error(transparent)]
    Experiment(htfid_experiment::ExperimentError),
    /// An argument of this crate's functions out of its domain: `name` and why.
    #[error("{name}: {reason}")]
    Argument {
        /// The argument, as the function's documentation names it.
        name: &'static str,
        /// What is wrong and what is expected.
        reason: String,
    },
}

/// [`Error::Argument`] unless `value` is finite (and positive where `positive`).
fn check_number(name: &'static str, value: f64, positive: bool) -> Result<(), Error> {
    if !value.is_finite() || (positive && value <= 0.0) {
        let expected = if positive {
            "a finite number > 0"
        } else {
            "a finite number"
        };
        return Err(Error::Argument {
            name,
            reason: format!("{value} is not {expected}"),
        });
    }
    Ok(())
}

impl From<htfid_experiment::ExperimentError> for Error {
    fn from(e: htfid_experiment::ExperimentError) -> Self {
        use htfid_experiment::ExperimentError as X;
        match e {
            X::Hopper(e) => Error::Hopper(e),
            X::Model(e) => Error::Model(e),
            X::Theory(e) => Error::Theory(e),
            X::Simulation(e) => Error::Simulation(e),
            other => Error::Experiment(other),
        }
    }
}

/// Options of [`Htf::with_options`]: Newton shooting for the limit cycle, and the integrator
/// (its tolerances also bound the error of the HTFs computed along the orbit).
#[derive(Debug, Clone, Default)]
pub struct HtfOptions {
    /// Settling and Newton shooting onto the limit cycle.
    pub shooting: ShootingOptions,
    /// The event-accurate integrator.
    pub integrator: IntegratorOptions,
}

/// The exact HTFs of a system linearised about its limit cycle, every output.
#[derive(Debug)]
pub struct Htf<'a, S: Rhythmic> {
    system: &'a S,
    cycle: LimitCycle<S::Mode>,
    htf: LinearisedHtf<'a, S>,
    integrator: IntegratorOptions,
}

impl<'a, S: Rhythmic> Htf<'a, S> {
    /// Limit cycle, linearisation and exact HTFs of `system`, with the default options.
    ///
    /// # Errors
    /// No stable limit cycle ([`Error::Hopper`] for the hopper, [`Error::Model`] for a model
    /// file, [`Error::Experiment`] for a model written in Rust), an orbit the linearisation does
    /// not cover, such as sliding ([`Error::Theory`]).
    pub fn of(system: &'a S) -> Result<Self, Error> {
        Self::with_options(system, &HtfOptions::default())
    }

    /// As [`Htf::of`], with `options`.
    ///
    /// # Errors
    /// As [`Htf::of`].
    pub fn with_options(system: &'a S, options: &HtfOptions) -> Result<Self, Error> {
        let cycle = system.limit_cycle(&options.shooting, &options.integrator)?;
        let htf = LinearisedHtf::new(system, &cycle, &options.integrator)?;
        Ok(Htf {
            system,
            cycle,
            htf,
            integrator: options.integrator.clone(),
        })
    }

    /// `G_n(j omega)` of the first output (`omega` in rad/s, the output frequency).
    ///
    /// # Errors
    /// [`Error::Theory`] for a system without outputs.
    pub fn g(&self, n: i32, omega: f64) -> Result<Complex64, Error> {
        self.g_of(0, n, omega)
    }

    /// `G_n(j omega)` of output `output`.
    ///
    /// # Errors
    /// [`Error::Theory`] when `output` is out of range; [`Error::Argument`] when `omega` is not
    /// finite.
    pub fn g_of(&self, output: usize, n: i32, omega: f64) -> Result<Complex64, Error> {
        check_number("omega", omega, false)?;
        Ok(self.htf.channel(output)?.g(n, omega))
    }

    /// `G_n(jw)` on `omegas x harmonics`, one grid per output.
    ///
    /// # Errors
    /// [`Error::Theory`] when the periodic-response integration fails; [`Error::Argument`]
    /// when an entry of `omegas` is not finite.
    pub fn grids(&self, harmonics: &[i32], omegas: &[f64]) -> Result<Vec<HtfGrid>, Error> {
        for &w in omegas {
            check_number("omegas", w, false)?;
        }
        Ok(self.htf.grids(harmonics, omegas)?)
    }

    /// The limit cycle (input off) the system was linearised about.
    pub fn limit_cycle(&self) -> &LimitCycle<S::Mode> {
        &self.cycle
    }

    /// The orbit's period `T` (s); the pumping frequency is `2 pi / T`.
    pub fn period(&self) -> f64 {
        self.cycle.period
    }

    /// How the HTFs are computed (closed form when the linearisation is constant per mode).
    pub fn method(&self) -> HtfMethod {
        self.htf.method()
    }

    /// The underlying [`LinearisedHtf`], for everything else `htfid-theory` offers.
    pub fn linearised(&self) -> &LinearisedHtf<'a, S> {
        &self.htf
    }

    /// The options the integrator used.
    pub fn integrator(&self) -> &IntegratorOptions {
        &self.integrator
    }
}

/// Simulates the system of `htf` driven by `input` from its orbit at `t = 0` and samples every
/// output at `times` (non-decreasing, from 0 s): one vector per output. A record made this way
/// stands in for a measurement in examples and tests.
///
/// # Errors
/// [`Error::Argument`] when `times` is not finite, non-decreasing and from 0;
/// [`Error::Simulation`] when the integrator cannot proceed.
pub fn simulate<S: Rhythmic>(
    htf: &Htf<'_, S>,
    input: Input,
    times: &[f64],
) -> Result<Vec<Vec<f64>>, Error> {
    let mut before = 0.0;
    for (k, &t) in times.iter().enumerate() {
        if !(t.is_finite() && t >= before) {
            return Err(Error::Argument {
                name: "times",
                reason: if k == 0 {
                    format!("times[0] = {t}: the grid starts at 0 s or later (finite)")
                } else {
                    format!(
                        "times[{k}] = {t} after times[{}] = {before}: the grid must be finite \
                         and non-decreasing",
                        k - 1
                    )
                },
            });
        }
        before = t;
    }
    Ok(htfid_experiment::drive(
        htf.system,
        htf.limit_cycle(),
        Some(input),
        times,
        htf.integrator(),
    )?
    .outputs)
}

/// Options of [`estimate`].
#[derive(Debug, Clone)]
pub struct EstimateOptions {
    /// The harmonics `n` of `G_n` to estimate.
    pub harmonics: Vec<i32>,
    /// Output frequencies `(lo, hi)` in rad/s, edges included.
    pub band: (f64, f64),
    /// Smoothness weight of Siddiqi's estimator (dimensionless), or generalised cross-validation.
    pub alpha: Alpha,
    /// Harmonics of the period average kept as the orbit of the input (the output keeps twice
    /// as many); the split removes every multiple of the pumping frequency regardless.
    pub orbit_harmonics: usize,
}

impl Default for EstimateOptions {
    /// `G_-3 .. G_3` over 1-40 rad/s, `alpha = 1`.
    fn default() -> Self {
        EstimateOptions {
            harmonics: (-3..=3).collect(),
            band: (1.0, 40.0),
            alpha: Alpha::Fixed(1.0),
            orbit_harmonics: 5,
        }
    }
}

/// HTFs of one output estimated from a record: `u` and `y` sampled every `dt` s from absolute
/// time `t0`, the system's period `period` s. The period must hold a whole number `M` of
/// samples: `period / dt` may miss one only by a drift of a hundredth of a sample over the
/// record (a step printed with few digits), and the step is then taken as `period / M`;
/// resample a record whose sampling is not locked to the period. The record is cut to a whole
/// number of periods, its period average (the orbit) removed from input and output, and
/// Siddiqi's estimator run on the deviations: `htfid_estimate::PeriodicRecord`, the same
/// steps as `htfid estimate`.
///
/// # Errors
/// [`Error::Argument`]: `t0`, `dt` or `period` not finite (the last two not positive), `u` and
/// `y` of unequal lengths, a period of no whole number of samples. [`Error::FromData`]: fewer
/// than 64 samples or two periods, a band and harmonics that read input beyond the Nyquist
/// frequency, a period the output's own orbit contradicts, an estimator that fails.
pub fn estimate(
    t0: f64,
    dt: f64,
    u: &[f64],
    y: &[f64],
    period: f64,
    options: &EstimateOptions,
) -> Result<HtfEstimate, Error> {
    check_number("t0", t0, false)?;
    check_number("dt", dt, true)?;
    check_number("period", period, true)?;
    if u.len() != y.len() {
        return Err(Error::Argument {
            name: "u, y",
            reason: format!(
                "{} input samples against {} output samples: one of each per time",
                u.len(),
                y.len()
            ),
        });
    }
    let spec = DataSpec {
        harmonics: options.harmonics.clone(),
        band: options.band,
        alpha: options.alpha,
        orbit_harmonics: options.orbit_harmonics,
        outer_harmonics: 0,
    };
    let given = PeriodChoice::Given(period);
    let plan = PeriodicRecord::plan(y, dt, given, &spec).map_err(|e| match e {
        FromDataError::PeriodNotWhole { per_period, .. } => Error::Argument {
            name: "period",
            reason: format!(
                "{period} s is {per_period:.4} samples of {dt} s, not a whole number: resample \
                 the record so that a period holds a whole number of samples (the period \
                 average and the estimator need N dt = P T)"
            ),
        },
        other => Error::FromData(other),
    })?;
    let mut found = plan.estimate(t0, u, &[y], &spec)?;
    Ok(found.outputs.swap_remove(0).estimate)
}
