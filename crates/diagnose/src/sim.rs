//! Simulation of a model driven by the measured force.

use std::sync::Arc;

use htfid_hybrid::{Crossing, HybridSystem, Method, Options};
use htfid_model::{DamperLaw, Effects, Hopper, HopperMode, HopperParams, InputFn, ModelError};
use serde::{Deserialize, Serialize};

use crate::interp::{Interpolation, LaggedSignal, SampledSignal};

/// Most sub-steps per sample.
const MAX_SUBSTEPS: usize = 256;

/// How a model is simulated on the record.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SimMethod {
    /// Classical fourth-order Runge-Kutta on the sample grid with `s` equal sub-steps per
    /// sample, `s` the smallest integer with `omega * dt / s <= max_rate_step` and
    /// `decay * dt / s <= 10 max_rate_step`, where `omega` is the fastest natural frequency of
    /// the model linearised over the data (including cubic and contact stiffness) and `decay`
    /// the fastest damping rate (damping over mass). Damper switches are located on
    /// the cubic Hermite interpolant of the sub-step and the step is split there, so the
    /// simulated output is a smooth function of the parameters. Where Coulomb friction holds
    /// the mass at the switch, it sticks: the state slides on the switch with Filippov's
    /// field, as in `htfid-hybrid`'s adaptive method. Fast; its error against the adaptive
    /// integrator and against the independent truth generator through sticks is checked in
    /// the tests.
    FixedStep {
        /// Largest `omega * h` (dimensionless), `> 0`; the default 0.2 keeps the local error
        /// of a sub-step near `0.2^5 / 120 = 3e-6` relative (on the silverbox record the
        /// simulated output then differs from DOP853 at `rtol = 1e-10` by 3 % of the noise).
        max_rate_step: f64,
    },
    /// `htfid-hybrid`'s DOP853 with `h_max = dt` and event location (slower; the reference).
    Adaptive {
        /// Relative tolerance, `> 0`.
        rtol: f64,
    },
}

impl Default for SimMethod {
    fn default() -> Self {
        SimMethod::FixedStep { max_rate_step: 0.2 }
    }
}

/// A simulation that could not be completed.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SimFailure {
    pub time: f64,
    pub reason: String,
}

/// The integrator with its resolution fixed for one fit.
#[derive(Debug, Clone)]
pub(crate) enum Stepping {
    Fixed { substeps: usize },
    Adaptive(Options),
}

/// Extent of the data, used to bound the model's fastest rate.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Extent {
    pub x_min: f64,
    pub x_max: f64,
    pub v_max: f64,
}

impl Stepping {
    pub(crate) fn resolve(
        method: SimMethod,
        p: &HopperParams,
        e: &Effects,
        extent: &Extent,
        dt: f64,
    ) -> Stepping {
        match method {
            SimMethod::FixedStep { max_rate_step } => {
                let (omega, decay) = rates(p, e, extent);
                // Oscillation needs `omega h <= max_rate_step`; a pure decay (damping, lag) is
                // resolved well enough at ten times that.
                let s = (omega * dt / max_rate_step)
                    .max(decay * dt / (10.0 * max_rate_step))
                    .ceil();
                let substeps = if s.is_finite() {
                    (s as usize).clamp(1, MAX_SUBSTEPS)
                } else {
                    MAX_SUBSTEPS
                };
                Stepping::Fixed { substeps }
            }
            SimMethod::Adaptive { rtol } => Stepping::Adaptive(Options {
                method: Method::Dop853,
                rtol,
                h_max: dt,
                ..Options::default()
            }),
        }
    }

    /// Whether this resolution is at least as fine as `other` needs.
    pub(crate) fn covers(&self, other: &Stepping) -> bool {
        match (self, other) {
            (Stepping::Fixed { substeps: a }, Stepping::Fixed { substeps: b }) => a >= b,
            _ => true,
        }
    }
}

/// The fastest oscillation (rad/s) and decay (1/s) rates of the model linearised anywhere over
/// the data's extent.
fn rates(p: &HopperParams, e: &Effects, extent: &Extent) -> (f64, f64) {
    let dx = (extent.x_max - p.x0).abs().max((extent.x_min - p.x0).abs()) * 1.2;
    let k_stop = e.hard_stop.map_or(0.0, |h| h.k_stop.max(0.0));
    let k_eff = p.k + 3.0 * e.k3.abs() * dx * dx + k_stop;
    let c_eff = p.c + e.c_f.abs() + 2.0 * e.c2.abs() * extent.v_max * 1.2;
    // A lag is applied to the input exactly (see `MeasuredForce::drive`) and sets no rate.
    ((k_eff / p.m).sqrt(), c_eff / p.m)
}

/// The measured force, read between samples.
#[derive(Debug, Clone)]
pub(crate) struct MeasuredForce {
    signal: Arc<SampledSignal>,
}

impl MeasuredForce {
    pub(crate) fn new(t0: f64, dt: f64, samples: &[f64], kind: Interpolation) -> Self {
        MeasuredForce {
            signal: Arc::new(SampledSignal::new(t0, dt, samples, kind)),
        }
    }

    /// The model driven by the measured force.
    ///
    /// An actuator lag acts on the input alone, so it is applied to the interpolated force
    /// exactly ([`LaggedSignal`], from the first sample with `F = f`) and the model is
    /// simulated with `tau = 0` and the lagged force: the dynamics of the model's lag state,
    /// without a stiff third state that would need sub-steps shorter than `tau`. A delay then
    /// shifts the lagged force, which equals lagging the delayed one.
    /// The measured force at time `t`, read between samples as the simulation reads it.
    pub(crate) fn at(&self, t: f64) -> f64 {
        self.signal.eval(t)
    }

    pub(crate) fn drive(
        &self,
        params: HopperParams,
        damper: DamperLaw,
        effects: Effects,
    ) -> Result<Hopper, ModelError> {
        let f: InputFn = if effects.tau > 0.0 {
            let lagged = LaggedSignal::new(Arc::clone(&self.signal), effects.tau);
            Arc::new(move |t| lagged.eval(t))
        } else {
            let signal = Arc::clone(&self.signal);
            Arc::new(move |t| signal.eval(t))
        };
        let effects = Effects {
            tau: 0.0,
            ..effects
        };
        let hopper = Hopper::with_effects(params, damper, effects)?;
        Ok(hopper.with_input(Some(f)))
    }
}

/// The model with its non-smooth points made visible to the integrator: besides the damper's
/// switching guard, a guard at the contact position of a hard stop (where the force's slope
/// jumps) and, with an always-on damper, at `x' = 0` for Coulomb friction (where the force
/// jumps). Their resets are the identity in the same chart: stepping to them and restarting
/// there keeps the simulated output a smooth function of the parameters, which finite
/// differences need (a kink stepped over leaves an error of `O(h^2)` that jitters with the
/// parameters).
struct Located<'a> {
    hopper: &'a Hopper,
    extra: Option<&'a ExtraForce>,
    base: [usize; 2],
    contact: Option<f64>,
    friction: bool,
}

impl<'a> Located<'a> {
    fn new(hopper: &'a Hopper, extra: Option<&'a ExtraForce>) -> Self {
        let e = hopper.effects();
        Located {
            hopper,
            extra,
            base: [
                hopper.num_guards(HopperMode::Damped),
                hopper.num_guards(HopperMode::Free),
            ],
            contact: e
                .hard_stop
                .filter(|h| h.k_stop.abs() > 0.0)
                .map(|h| h.x_stop),
            friction: hopper.damper() == DamperLaw::AlwaysOn && e.mu.abs() > 0.0,
        }
    }

    fn base(&self, mode: HopperMode) -> usize {
        match mode {
            HopperMode::Damped => self.base[0],
            HopperMode::Free => self.base[1],
        }
    }

    /// The extra guard's value: contact first, then friction.
    fn extra(&self, k: usize, x: &[f64]) -> f64 {
        match (k, self.contact) {
            (0, Some(x_stop)) => x[0] - x_stop,
            _ => x[1],
        }
    }
}

impl HybridSystem for Located<'_> {
    type Mode = HopperMode;

    fn dim(&self) -> usize {
        self.hopper.dim()
    }

    fn vector_field(&self, mode: HopperMode, t: f64, x: &[f64], dxdt: &mut [f64]) {
        self.hopper.vector_field(mode, t, x, dxdt);
        if let Some(extra) = self.extra {
            dxdt[1] += extra(t, x[0], x[1]) / self.hopper.params().m;
        }
    }

    fn num_guards(&self, mode: HopperMode) -> usize {
        self.base(mode) + usize::from(self.contact.is_some()) + usize::from(self.friction)
    }

    fn guard(&self, mode: HopperMode, index: usize, t: f64, x: &[f64]) -> f64 {
        let b = self.base(mode);
        if index < b {
            self.hopper.guard(mode, index, t, x)
        } else {
            self.extra(index - b, x)
        }
    }

    fn guard_direction(&self, mode: HopperMode, index: usize) -> Crossing {
        if index < self.base(mode) {
            self.hopper.guard_direction(mode, index)
        } else {
            Crossing::Either
        }
    }

    fn transition(&self, mode: HopperMode, index: usize, t: f64, x: &mut [f64]) -> HopperMode {
        if index < self.base(mode) {
            self.hopper.transition(mode, index, t, x)
        } else {
            mode
        }
    }

    /// The model's switching surfaces (the damper switch, where Coulomb friction makes the
    /// mass stick); the located kinks are not.
    fn sliding_chart(&self, mode: HopperMode, index: usize) -> Option<HopperMode> {
        if index < self.base(mode) {
            self.hopper.sliding_chart(mode, index)
        } else {
            None
        }
    }

    fn guard_gradient(
        &self,
        mode: HopperMode,
        index: usize,
        t: f64,
        x: &[f64],
        grad: &mut [f64],
    ) -> bool {
        index < self.base(mode) && self.hopper.guard_gradient(mode, index, t, x, grad)
    }
}

/// A force `F(t, x, v)` added to the model's (terms found outside the library by the term
/// search of `discover`); smooth, so it needs no guard of its own.
pub(crate) type ExtraForce = dyn Fn(f64, f64, f64) -> f64 + Send + Sync;

/// Simulates `out.len()` samples from `t0` (step `dt`) starting at position and velocity
/// `xv0`, writing positions. A lag state starts at the commanded force.
pub(crate) fn simulate_positions(
    hopper: &Hopper,
    t0: f64,
    xv0: [f64; 2],
    dt: f64,
    stepping: &Stepping,
    out: &mut [f64],
) -> Result<(), SimFailure> {
    simulate_positions_with(hopper, None, t0, xv0, dt, stepping, out)
}

/// [`simulate_positions`] with an extra force in the vector field.
pub(crate) fn simulate_positions_with(
    hopper: &Hopper,
    extra: Option<&ExtraForce>,
    t0: f64,
    xv0: [f64; 2],
    dt: f64,
    stepping: &Stepping,
    out: &mut [f64],
) -> Result<(), SimFailure> {
    let mut state = vec![xv0[0], xv0[1]];
    if hopper.effects().has_lag() {
        state.push(hopper.commanded_force(t0 - hopper.effects().delay));
    }
    let mode0 = hopper.mode_of(xv0[1]);
    let sys = Located::new(hopper, extra);
    match stepping {
        Stepping::Fixed { substeps } => {
            htfid_hybrid::simulate_fixed_step(&sys, mode0, t0, &state, dt, *substeps, 0, out)
                .map_err(|e| SimFailure {
                    time: t0,
                    reason: e.to_string(),
                })
        }
        Stepping::Adaptive(opts) => {
            let n = out.len();
            let grid: Vec<f64> = (0..n).map(|i| t0 + i as f64 * dt).collect();
            let t_end = grid.last().copied().unwrap_or(t0);
            let traj = htfid_hybrid::simulate(&sys, mode0, t0, &state, t_end, &grid, opts)
                .map_err(|e| SimFailure {
                    time: t0,
                    reason: e.to_string(),
                })?;
            for (i, o) in out.iter_mut().enumerate() {
                *o = traj.state(i)[0];
            }
            Ok(())
        }
    }
}
