//! Simulation of a model driven by the measured force.

use std::cell::Cell;
use std::sync::Arc;

use htfid_hybrid::{Crossing, FixedStepLane, HybridSystem, Method, Options};
use htfid_model::{DamperLaw, Effects, Hopper, HopperMode, HopperParams, InputFn, ModelError};
use serde::{Deserialize, Serialize};

use crate::interp::{Interpolation, LaggedSignal, SampledSignal};

/// Most sub-steps per sample.
const MAX_SUBSTEPS: usize = 256;

/// How much more coarsely a fit's forward sensitivities resolve an oscillation than its
/// residuals do (`Context::jacobian_stepping`): `omega h <= 2 max_rate_step`, 0.4 by default,
/// well inside RK4's stability bound (2.8). The Jacobian only steers the iteration and
/// scales the standard errors; the residuals, hence the optimum, its cost and every test,
/// keep the full step. The columns then differ from the full step's by RK4's error at the
/// coarser step, about `(omega h)^4 / 120 = 2e-4` per radian of the motion's memory (a test
/// bounds it), and a Jacobian costs half the simulation.
pub(crate) const JACOBIAN_COARSENING: f64 = 2.0;

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
        Self::resolve_coarsened(method, p, e, extent, dt, 1.0)
    }

    /// [`Stepping::resolve`] with an oscillation resolved `coarsening` times more coarsely
    /// and a decay as finely.
    pub(crate) fn resolve_coarsened(
        method: SimMethod,
        p: &HopperParams,
        e: &Effects,
        extent: &Extent,
        dt: f64,
        coarsening: f64,
    ) -> Stepping {
        match method {
            SimMethod::FixedStep { max_rate_step } => {
                let (omega, decay) = rates(p, e, extent);
                // Oscillation needs `omega h <= max_rate_step`; a pure decay (damping, lag) is
                // resolved well enough at ten times that.
                let s = (omega * dt / (coarsening * max_rate_step))
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

    /// The measured force at time `t`, read between samples as the simulation reads it.
    pub(crate) fn at(&self, t: f64) -> f64 {
        self.signal.eval(t)
    }

    /// The model driven by the measured force.
    ///
    /// An actuator lag acts on the input alone, so it is applied to the interpolated force
    /// exactly ([`LaggedSignal`], from the first sample with `F = f`) and the model is
    /// simulated with `tau = 0` and the lagged force: the dynamics of the model's lag state,
    /// without a stiff third state that would need sub-steps shorter than `tau`. A delay then
    /// shifts the lagged force, which equals lagging the delayed one.
    pub(crate) fn drive(
        &self,
        params: HopperParams,
        damper: DamperLaw,
        effects: Effects,
    ) -> Result<Hopper, ModelError> {
        self.drive_with(params, damper, effects).map(|(h, _)| h)
    }

    /// [`MeasuredForce::drive`], and the force the model reads as a concrete signal, which
    /// the simulation reads directly (the same values as the hopper's input function).
    pub(crate) fn drive_with(
        &self,
        params: HopperParams,
        damper: DamperLaw,
        effects: Effects,
    ) -> Result<(Hopper, Force), ModelError> {
        let force = if effects.tau > 0.0 {
            Force::Lagged(Arc::new(LaggedSignal::new(
                Arc::clone(&self.signal),
                effects.tau,
            )))
        } else {
            Force::Sampled(Arc::clone(&self.signal))
        };
        let read = force.clone();
        let f: InputFn = Arc::new(move |t| read.eval(t));
        let effects = Effects {
            tau: 0.0,
            ..effects
        };
        let hopper = Hopper::with_effects(params, damper, effects)?;
        Ok((hopper.with_input(Some(f)), force))
    }
}

/// The input of a model driven by the measured force: the interpolated samples, or the same
/// passed through an actuator lag.
#[derive(Debug, Clone)]
pub(crate) enum Force {
    Sampled(Arc<SampledSignal>),
    Lagged(Arc<LaggedSignal>),
}

impl Force {
    #[inline]
    pub(crate) fn eval(&self, t: f64) -> f64 {
        match self {
            Force::Sampled(s) => s.eval(t),
            Force::Lagged(l) => l.eval(t),
        }
    }

    /// Its time derivative at `t`.
    #[inline]
    pub(crate) fn rate(&self, t: f64) -> f64 {
        match self {
            Force::Sampled(s) => s.rate(t),
            Force::Lagged(l) => l.rate(t),
        }
    }

    /// Its derivative at `t` by the actuator lag's time constant; without a lag the
    /// derivative from above, `-f'` (a lag `tau` reads `f - tau f'` to first order).
    #[inline]
    pub(crate) fn tau_derivative(&self, t: f64) -> f64 {
        match self {
            Force::Sampled(s) => -s.rate(t),
            Force::Lagged(l) => l.tau_derivative(t),
        }
    }
}

/// The model with its non-smooth points made visible to the integrator: besides the damper's
/// switching guard, a guard at the contact position of a hard stop (where the force's slope
/// jumps) and, with an always-on damper, at `x' = 0` for Coulomb friction (where the force
/// jumps). Their resets are the identity in the same chart: stepping to them and restarting
/// there keeps the simulated output a smooth function of the parameters, which finite
/// differences need (a kink stepped over leaves an error of `O(h^2)` that jitters with the
/// parameters).
///
/// Given the force the hopper reads ([`Force`]), the vector field reads it directly, without
/// the hopper's input function, and reads it once for the two stages of a Runge-Kutta step
/// at the same time: the same values, fewer calls.
struct Located<'a> {
    hopper: &'a Hopper,
    extra: Option<&'a ExtraForce>,
    force: Option<&'a Force>,
    /// The hopper's acceleration, its coefficients gathered for the direct path.
    field: Field,
    /// The last time the force was read at and its value there.
    last: Cell<(f64, f64)>,
    base: [usize; 2],
    contact: Option<f64>,
    friction: bool,
}

impl<'a> Located<'a> {
    fn new(hopper: &'a Hopper, extra: Option<&'a ExtraForce>, force: Option<&'a Force>) -> Self {
        let e = hopper.effects();
        Located {
            hopper,
            extra,
            // A lag state of the hopper's own (never present when driven by the measured
            // force) reads the force in its own equation: the hopper's field then.
            force: force.filter(|_| !e.has_lag()),
            field: Field::new(hopper),
            last: Cell::new((f64::NAN, 0.0)),
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

    /// The commanded force at `t` (the delay applied), reading `force` once for the two
    /// stages of a Runge-Kutta step at the same time.
    #[inline(always)]
    fn commanded(&self, force: &Force, t: f64) -> f64 {
        let h = self.hopper;
        let td = t - h.effects().delay;
        let (t_last, u_last) = self.last.get();
        let u = if td.to_bits() == t_last.to_bits() {
            u_last
        } else {
            let u = force.eval(td);
            self.last.set((td, u));
            u
        };
        h.commanded_force_with(td, u)
    }

    fn base(&self, mode: HopperMode) -> usize {
        match mode {
            HopperMode::Damped => self.base[0],
            HopperMode::Free => self.base[1],
        }
    }

    /// The hopper's own vector field (with a lag state of its own) at the first `n` entries
    /// of `x`.
    #[inline(never)]
    fn hopper_field(&self, mode: HopperMode, t: f64, x: [f64; 3], n: usize) -> [f64; 3] {
        let mut d = [0.0; 3];
        self.hopper.vector_field(mode, t, &x[..n], &mut d[..n]);
        d
    }

    /// The extra force's acceleration.
    #[inline(never)]
    fn extra_acceleration(&self, t: f64, pos: f64, vel: f64) -> f64 {
        self.extra
            .map_or(0.0, |extra| extra(t, pos, vel) / self.hopper.params().m)
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

    // Inlined into the integrator's stages, which then keep the state in registers; the
    // rarer paths are functions of their own.
    #[inline(always)]
    fn vector_field(&self, mode: HopperMode, t: f64, x: &[f64], dxdt: &mut [f64]) {
        match self.force {
            // `Hopper::vector_field` without a lag state, reading the force directly.
            Some(force) => {
                let f = self.commanded(force, t);
                // Written as one pair: the integrator reads the derivative back whole.
                let d = [x[1], self.field.acceleration(mode, x[0], x[1], f)];
                dxdt[..2].copy_from_slice(&d);
            }
            None => {
                // By value: a state or derivative whose address reached a call could not stay
                // in registers on the direct path either.
                let mut state = [0.0; 3];
                let n = x.len().min(3);
                state[..n].copy_from_slice(&x[..n]);
                let d = self.hopper_field(mode, t, state, n);
                let n = dxdt.len().min(3);
                dxdt[..n].copy_from_slice(&d[..n]);
            }
        }
        if self.extra.is_some() {
            dxdt[1] += self.extra_acceleration(t, x[0], x[1]);
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

/// [`Hopper::acceleration`] with its coefficients gathered and its terms summed as a shallow
/// tree, then multiplied by `1 / m`: the same force law (equal to rounding), with a short
/// chain of dependent operations from the state to the acceleration, which is what a
/// Runge-Kutta step waits on.
#[derive(Debug, Clone, Copy)]
struct Field {
    x0: f64,
    inv_m: f64,
    weight: f64,
    k: f64,
    k3: f64,
    mu: f64,
    /// Linear damping in the damped and the free chart: `c` and `c_f`.
    c_damped: f64,
    c_free: f64,
    c2: f64,
    /// Friction's sign from the chart (the switching damper) rather than from the velocity.
    sign_from_chart: bool,
    stop: Option<(f64, f64)>,
}

impl Field {
    fn new(hopper: &Hopper) -> Self {
        let p = hopper.params();
        let e = hopper.effects();
        Field {
            x0: p.x0,
            inv_m: 1.0 / p.m,
            weight: p.m * p.g,
            k: p.k,
            k3: e.k3,
            mu: e.mu,
            c_damped: p.c,
            c_free: e.c_f,
            c2: e.c2,
            sign_from_chart: hopper.damper() == DamperLaw::Switching,
            stop: e.hard_stop.map(|h| (h.x_stop, h.k_stop)),
        }
    }

    #[inline]
    fn acceleration(&self, mode: HopperMode, pos: f64, vel: f64, force: f64) -> f64 {
        let t = self.terms(mode, pos, vel);
        let contact = match self.stop {
            Some((x_stop, k_stop)) if pos < x_stop => k_stop * (pos - x_stop),
            _ => 0.0,
        };
        ((force - self.weight - self.mu * t.sign) - (t.damping + (t.spring + contact))) * self.inv_m
    }

    /// The spring's and the dampers' forces at a state, and the friction's sign, as
    /// [`Field::acceleration`] and [`Field::derivatives`] both sum them.
    #[inline(always)]
    fn terms(&self, mode: HopperMode, pos: f64, vel: f64) -> Terms {
        let damped = mode == HopperMode::Damped;
        let dx = pos - self.x0;
        let c_lin = if damped { self.c_damped } else { self.c_free };
        let sign = match (self.sign_from_chart, damped) {
            (true, true) => 1.0,
            (true, false) => -1.0,
            (false, _) => vel.signum(),
        };
        Terms {
            damped,
            dx,
            spring: (self.k + self.k3 * (dx * dx)) * dx,
            c_lin,
            damping: (c_lin + self.c2 * vel.abs()) * vel,
            sign,
        }
    }
}

/// What [`Field::terms`] gives.
struct Terms {
    damped: bool,
    dx: f64,
    spring: f64,
    c_lin: f64,
    damping: f64,
    sign: f64,
}

impl Field {
    /// The acceleration, its derivatives by position and velocity, and its derivative by
    /// every [`Param`] (indexed by `Param as usize`): the same force law as
    /// [`Field::acceleration`], differentiated by hand term by term.
    ///
    /// `inside` says on which side of a contact's edge the derivatives are taken: at the
    /// edge itself (the start or end of a step split there) the position cannot tell.
    #[inline(always)]
    fn derivatives(
        &self,
        mode: HopperMode,
        inside: bool,
        pos: f64,
        vel: f64,
        force: f64,
    ) -> (f64, f64, f64, [f64; PARAMS]) {
        let Terms {
            damped,
            dx,
            spring,
            c_lin,
            damping,
            sign,
        } = self.terms(mode, pos, vel);
        let stiffness = self.k + 3.0 * self.k3 * dx * dx;
        let (contact, k_contact, into) = match self.stop {
            Some((x_stop, k_stop)) if inside => (k_stop * (pos - x_stop), k_stop, pos - x_stop),
            _ => (0.0, 0.0, 0.0),
        };
        // Every force but the weight: `a = net / m - g`, so `da/dm = -net / m^2`.
        let net = (force - self.mu * sign) - (damping + (spring + contact));
        let a = (net - self.weight) * self.inv_m;
        let a_x = -(stiffness + k_contact) * self.inv_m;
        let a_v = -(c_lin + 2.0 * self.c2 * vel.abs()) * self.inv_m;
        let (on, off) = if damped { (-vel, 0.0) } else { (0.0, -vel) };
        let forces = [
            -net * self.inv_m, // M
            -dx,               // K
            on,                // C
            off,               // CF
            stiffness,         // X0
            1.0,               // InputOffset
            -dx * dx * dx,     // K3
            -vel * vel.abs(),  // C2
            k_contact,         // XStop
            -into,             // KStop
            0.0,               // Position
            0.0,               // Velocity
        ];
        (a, a_x, a_v, forces.map(|f| f * self.inv_m))
    }
}

/// The number of [`Param`]s.
const PARAMS: usize = 12;

/// A number the position's derivative is integrated for ([`simulate_sensitivities`]): a
/// parameter of the force law, or the starting position or velocity.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub(crate) enum Param {
    M,
    K,
    C,
    CF,
    X0,
    InputOffset,
    K3,
    C2,
    XStop,
    KStop,
    Position,
    Velocity,
    /// The delay of the force: its column's forcing is `-(forcing' + f') / m` at the delayed
    /// time.
    Delay,
    /// The actuator lag's time constant: its column's forcing is `(dF/dtau) / m`.
    Tau,
}

/// [`Param::Delay`] and [`Param::Tau`] as the columns of [`Sensitive`] index them (beyond
/// [`Field::derivatives`]' own).
const DELAY: usize = Param::Delay as usize;
const TAU: usize = Param::Tau as usize;

/// Most columns of [`simulate_sensitivities`] integrated together. Beyond eight (a state of
/// 18 numbers) a column costs more: on 65 000 samples of the Silverbox model at 6 sub-steps,
/// 54 ms for eight columns, 84-95 ms for nine or ten in one simulation (the plain simulation
/// 24 ms). More are integrated in two halves, on two threads where one is free (ten: 61 ms).
const SPLIT_SENSITIVITIES: usize = 8;

/// Most columns of [`simulate_sensitivities`].
pub(crate) const MAX_SENSITIVITIES: usize = 15;

/// The chart of [`Sensitive`]: the hopper's, and whether the mass is inside a contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Chart {
    hopper: HopperMode,
    inside: bool,
}

/// The located model with the sensitivities of its state to `M` numbers appended (`N = 2 + 2
/// M` entries): `[x, v, dx/dp_1..M, dv/dp_1..M]`, following `d(dx/dp)/dt = dv/dp` and
/// `d(dv/dp)/dt = a_x dx/dp + a_v dv/dp + da/dp`.
///
/// Built only for a model whose force is continuous across every guard it crosses (no
/// Coulomb friction, no damper threshold: the damper's force `c x'` vanishes at its switch
/// `x' = 0`, and the contact's force at its edge). The crossing time then moves the
/// sensitivities by the jump in the field times that move, which is zero: every saltation
/// matrix is the identity, the resets pass the sensitivities unchanged, and no motion slides
/// along a switch (both sides' fields are equal there).
///
/// The force's derivatives do jump at a contact's edge, and a step split there starts and
/// ends on it, where the position cannot say which side a stage belongs to: taken from the
/// wrong side for one stage, the contact's stiffness enters a step's sensitivities with
/// weight `h / 6` at every crossing, an error of first order in the step (measured: 5e-4 of
/// the derivatives at 16 sub-steps per sample). The side is therefore part of the chart,
/// switched at the contact's guard.
struct Sensitive<'a, const M: usize> {
    located: Located<'a>,
    force: &'a Force,
    /// Which derivative of [`Field::derivatives`] each column reads, or [`DELAY`], [`TAU`].
    params: [usize; M],
    /// Whether a column is the delay's, which reads the force's rate.
    reads_rate: bool,
    /// Whether a column is the lag's, which reads the force's derivative by its time
    /// constant.
    reads_tau: bool,
}

impl<const M: usize> Sensitive<'_, M> {
    /// Whether guard `index` of `mode` is the contact's edge.
    fn is_contact(&self, mode: HopperMode, index: usize) -> bool {
        self.located.contact.is_some() && index == self.located.base(mode)
    }
}

impl<const M: usize> HybridSystem for Sensitive<'_, M> {
    type Mode = Chart;

    fn dim(&self) -> usize {
        2 * (1 + M)
    }

    #[inline(always)]
    fn vector_field(&self, mode: Chart, t: f64, x: &[f64], dxdt: &mut [f64]) {
        let f = self.located.commanded(self.force, t);
        let (a, a_x, a_v, a_p) =
            self.located
                .field
                .derivatives(mode.hopper, mode.inside, x[0], x[1], f);
        let sx: &[f64; M] = x[2..2 + M].try_into().expect("M columns");
        let sv: &[f64; M] = x[2 + M..2 + 2 * M].try_into().expect("M columns");
        // The force's derivatives by the delay and the lag, at the delayed time; `a_p` of the
        // input offset is the acceleration per unit force, `1 / m`.
        let (mut by_delay, mut by_tau) = (0.0, 0.0);
        if self.reads_rate || self.reads_tau {
            let hopper = self.located.hopper;
            let td = t - hopper.effects().delay;
            let per_force = a_p[Param::InputOffset as usize];
            if self.reads_rate {
                let p = hopper.params();
                // Measured data carry the forcing in their input: no sine without one.
                let forcing_rate = if p.forcing_amplitude == 0.0 {
                    0.0
                } else {
                    let w = p.pump_frequency();
                    -p.forcing_amplitude * w * (w * td).sin()
                };
                by_delay = -(forcing_rate + self.force.rate(td)) * per_force;
            }
            if self.reads_tau {
                by_tau = self.force.tau_derivative(td) * per_force;
            }
        }
        let mut d = [0.0; M];
        for j in 0..M {
            let forcing = match self.params[j] {
                DELAY => by_delay,
                TAU => by_tau,
                p => a_p[p],
            };
            d[j] = a_x * sx[j] + a_v * sv[j] + forcing;
        }
        dxdt[0] = x[1];
        dxdt[1] = a;
        dxdt[2..2 + M].copy_from_slice(sv);
        dxdt[2 + M..2 + 2 * M].copy_from_slice(&d);
    }

    fn num_guards(&self, mode: Chart) -> usize {
        self.located.num_guards(mode.hopper)
    }

    fn guard(&self, mode: Chart, index: usize, t: f64, x: &[f64]) -> f64 {
        self.located.guard(mode.hopper, index, t, &x[..2])
    }

    fn guard_direction(&self, mode: Chart, index: usize) -> Crossing {
        self.located.guard_direction(mode.hopper, index)
    }

    fn transition(&self, mode: Chart, index: usize, t: f64, x: &mut [f64]) -> Chart {
        if self.is_contact(mode.hopper, index) {
            return Chart {
                inside: !mode.inside,
                ..mode
            };
        }
        Chart {
            hopper: self.located.transition(mode.hopper, index, t, &mut x[..2]),
            ..mode
        }
    }
}

/// Whether [`simulate_sensitivities`] holds for a model with these effects: its force
/// continuous across every guard (no Coulomb friction, no damper threshold) and no lag state.
pub(crate) fn sensitivities_hold(e: &Effects) -> bool {
    e.mu == 0.0 && e.v_th == 0.0 && !e.has_lag()
}

/// [`simulate_positions`] on fixed steps, with the positions' derivatives by `params`
/// integrated beside them (forward sensitivities through the same Runge-Kutta steps and
/// located crossings): `columns[j * n + i]` is the derivative of position `i` by `params[j]`,
/// `n = positions.len()`. For a model where [`sensitivities_hold`]; at most
/// [`MAX_SENSITIVITIES`] columns.
#[allow(clippy::too_many_arguments)] // reason: the model, its input, the grid and the outputs
pub(crate) fn simulate_sensitivities(
    hopper: &Hopper,
    force: &Force,
    t0: f64,
    xv0: [f64; 2],
    dt: f64,
    substeps: usize,
    params: &[Param],
    positions: &mut [f64],
    columns: &mut [f64],
) -> Result<(), SimFailure> {
    let (n, m) = (positions.len(), params.len());
    if !sensitivities_hold(hopper.effects()) || columns.len() != n * m {
        return Err(SimFailure {
            time: t0,
            reason: "forward sensitivities do not hold for this model".to_string(),
        });
    }
    if m > SPLIT_SENSITIVITIES {
        // Two halves, each with the state: on two threads where one is free, and in about
        // the time of all columns at once where none is.
        let half = m / 2;
        let (first, second) = columns.split_at_mut(n * half);
        let mut again = vec![0.0; n];
        let run = |params: &[Param], positions: &mut [f64], columns: &mut [f64]| {
            simulate_sensitivities(
                hopper, force, t0, xv0, dt, substeps, params, positions, columns,
            )
        };
        let (a, b) = rayon::join(
            || run(&params[..half], positions, first),
            || run(&params[half..], &mut again, second),
        );
        return a.and(b);
    }
    let run = Sensitivities {
        hopper,
        force,
        t0,
        xv0,
        dt,
        substeps,
        params,
    };
    // One copy per column count, each with its state in arrays of exactly its length.
    macro_rules! columns {
        ($(($m:literal, $n:literal))*) => {
            match m {
                $($m => run.run::<$m, $n>(positions, columns),)*
                _ => Err(SimFailure {
                    time: t0,
                    reason: format!("{m} sensitivities asked for, at most {MAX_SENSITIVITIES}"),
                }),
            }
        };
    }
    columns!(
        (1, 4)(2, 6)(3, 8)(4, 10)(5, 12)(6, 14)(7, 16)(8, 18)(9, 20)(10, 22)(11, 24)(12, 26)(
            13, 28
        )(14, 30)(15, 32)
    )
}

/// The arguments of [`simulate_sensitivities`].
struct Sensitivities<'a> {
    hopper: &'a Hopper,
    force: &'a Force,
    t0: f64,
    xv0: [f64; 2],
    dt: f64,
    substeps: usize,
    params: &'a [Param],
}

impl Sensitivities<'_> {
    /// With `M` columns and `N = 2 + 2 M` entries of state.
    fn run<const M: usize, const N: usize>(
        &self,
        positions: &mut [f64],
        columns: &mut [f64],
    ) -> Result<(), SimFailure> {
        let n = positions.len();
        let sys = Sensitive::<M> {
            located: Located::new(self.hopper, None, Some(self.force)),
            force: self.force,
            params: std::array::from_fn(|j| self.params[j] as usize),
            reads_rate: self.params.contains(&Param::Delay),
            reads_tau: self.params.contains(&Param::Tau),
        };
        let mut x0 = [0.0; N];
        x0[..2].copy_from_slice(&self.xv0);
        for (j, p) in self.params.iter().enumerate() {
            match p {
                Param::Position => x0[2 + j] = 1.0,
                Param::Velocity => x0[2 + M + j] = 1.0,
                _ => {}
            }
        }
        let chart = Chart {
            hopper: self.hopper.mode_of(self.xv0[1]),
            inside: sys
                .located
                .contact
                .is_some_and(|x_stop| self.xv0[0] < x_stop),
        };
        htfid_hybrid::simulate_fixed_step_states::<_, N>(
            &sys,
            chart,
            self.t0,
            &x0,
            self.dt,
            self.substeps,
            n,
            |i, x| {
                positions[i] = x[0];
                for j in 0..M {
                    columns[j * n + i] = x[2 + j];
                }
            },
        )
        .map_err(|e| SimFailure {
            time: self.t0,
            reason: e.to_string(),
        })
    }
}

/// A force `F(t, x, v)` added to the model's (terms found outside the library by the term
/// search of `discover`); smooth, so it needs no guard of its own.
pub(crate) type ExtraForce = dyn Fn(f64, f64, f64) -> f64 + Send + Sync;

/// Simulates `out.len()` samples from `t0` (step `dt`) starting at position and velocity
/// `xv0`, writing positions. A lag state starts at the commanded force.
/// `force`, when given, is the force the hopper's input function reads (see
/// [`MeasuredForce::drive_with`]).
pub(crate) fn simulate_positions(
    hopper: &Hopper,
    force: Option<&Force>,
    t0: f64,
    xv0: [f64; 2],
    dt: f64,
    stepping: &Stepping,
    out: &mut [f64],
) -> Result<(), SimFailure> {
    simulate_positions_with(hopper, force, None, t0, xv0, dt, stepping, out)
}

/// [`simulate_positions`] with an extra force in the vector field.
#[allow(clippy::too_many_arguments)] // reason: the model, its input and the grid, each needed
pub(crate) fn simulate_positions_with(
    hopper: &Hopper,
    force: Option<&Force>,
    extra: Option<&ExtraForce>,
    t0: f64,
    xv0: [f64; 2],
    dt: f64,
    stepping: &Stepping,
    out: &mut [f64],
) -> Result<(), SimFailure> {
    let state = initial_state(hopper, t0, xv0);
    let mode0 = hopper.mode_of(xv0[1]);
    let sys = Located::new(hopper, extra, force);
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

/// The state at `t0` from position and velocity `xv0`: a lag state starts at the commanded
/// force.
fn initial_state(hopper: &Hopper, t0: f64, xv0: [f64; 2]) -> Vec<f64> {
    let mut state = vec![xv0[0], xv0[1]];
    if hopper.effects().has_lag() {
        state.push(hopper.commanded_force(t0 - hopper.effects().delay));
    }
    state
}

/// One simulation of a batch ([`simulate_positions_batch`]): the arguments of
/// [`simulate_positions_with`] that differ between lanes.
pub(crate) struct SimLane<'a> {
    pub hopper: &'a Hopper,
    pub force: Option<&'a Force>,
    pub extra: Option<&'a ExtraForce>,
    pub xv0: [f64; 2],
    pub out: &'a mut [f64],
}

/// [`simulate_positions_with`] for several models on the same grid, one result per lane. With
/// fixed steps the lanes are stepped in lockstep ([`htfid_hybrid::simulate_fixed_step_batch`]):
/// each lane's samples are those of its own simulation, bit for bit, in about half the time
/// for three lanes or more.
pub(crate) fn simulate_positions_batch(
    lanes: &mut [SimLane<'_>],
    t0: f64,
    dt: f64,
    stepping: &Stepping,
) -> Vec<Result<(), SimFailure>> {
    let Stepping::Fixed { substeps } = stepping else {
        return lanes
            .iter_mut()
            .map(|l| {
                simulate_positions_with(l.hopper, l.force, l.extra, t0, l.xv0, dt, stepping, l.out)
            })
            .collect();
    };
    let states: Vec<Vec<f64>> = lanes
        .iter()
        .map(|l| initial_state(l.hopper, t0, l.xv0))
        .collect();
    let systems: Vec<Located<'_>> = lanes
        .iter()
        .map(|l| Located::new(l.hopper, l.extra, l.force))
        .collect();
    let mut fixed: Vec<FixedStepLane<'_, Located<'_>>> = lanes
        .iter_mut()
        .zip(&systems)
        .zip(&states)
        .map(|((l, system), x0)| FixedStepLane {
            system,
            mode0: l.hopper.mode_of(l.xv0[1]),
            x0,
            out: &mut *l.out,
        })
        .collect();
    htfid_hybrid::simulate_fixed_step_batch(&mut fixed, t0, dt, *substeps, 0)
        .into_iter()
        .map(|r| {
            r.map_err(|e| SimFailure {
                time: t0,
                reason: e.to_string(),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use htfid_hybrid::HybridSystem;
    use htfid_model::HardStop;

    /// The gathered acceleration and the direct read of the force agree with the hopper's
    /// own vector field (through its input function) to rounding, in both charts, on both
    /// sides of a contact, for every effect and both damper laws.
    #[test]
    fn the_direct_field_equals_the_hoppers_field() {
        let samples: Vec<f64> = (0..200).map(|i| (0.37 * i as f64).sin()).collect();
        let input = MeasuredForce::new(0.0, 0.01, &samples, Interpolation::CubicSpline);
        let params = HopperParams {
            m: 0.7,
            k: 3.0,
            c: 0.4,
            g: 9.81,
            x0: 0.05,
            forcing_amplitude: 0.3,
            period: 1.3,
        };
        let effects = Effects {
            k3: 40.0,
            mu: 0.2,
            c_f: 0.1,
            c2: 0.3,
            delay: 0.013,
            input_offset: 0.02,
            hard_stop: Some(HardStop {
                x_stop: -0.1,
                k_stop: 50.0,
            }),
            ..Effects::default()
        };
        for damper in [DamperLaw::Switching, DamperLaw::AlwaysOn] {
            for tau in [0.0, 0.05] {
                let (hopper, force) = input
                    .drive_with(params, damper, Effects { tau, ..effects })
                    .unwrap();
                let sys = Located::new(&hopper, None, Some(&force));
                for (i, (x, v)) in [(0.3, 1.2), (-0.2, -0.7), (0.0, 0.0), (-0.1, 2.0)]
                    .into_iter()
                    .enumerate()
                {
                    let t = 0.3 + 0.217 * i as f64;
                    for mode in [HopperMode::Damped, HopperMode::Free] {
                        let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
                        hopper.vector_field(mode, t, &[x, v], &mut a);
                        sys.vector_field(mode, t, &[x, v], &mut b);
                        assert_eq!(a[0].to_bits(), b[0].to_bits());
                        let scale = a[1].abs().max(1.0);
                        assert!(
                            (a[1] - b[1]).abs() <= 1e-14 * scale,
                            "{damper:?} tau {tau} {mode:?} ({x}, {v}): {} vs {}",
                            a[1],
                            b[1]
                        );
                    }
                }
            }
        }
    }

    /// Columns past [`SPLIT_SENSITIVITIES`] are integrated in two halves: each column and the
    /// positions come out the same, bit for bit, as from simulations of fewer columns (each
    /// column follows the state alone, and the crossings are located on the state).
    #[test]
    fn split_sensitivities_equal_unsplit_ones_bit_for_bit() {
        let dt = 0.01;
        let samples: Vec<f64> = (0..3000)
            .map(|i| 2.0 * (0.37 * i as f64 * dt * 10.0).sin())
            .collect();
        let input = MeasuredForce::new(0.0, dt, &samples, Interpolation::CubicSpline);
        let params = HopperParams {
            m: 0.7,
            k: 30.0,
            c: 0.4,
            g: 9.81,
            x0: 0.05,
            forcing_amplitude: 0.0,
            period: 1.3,
        };
        let effects = Effects {
            k3: 40.0,
            c2: 0.3,
            input_offset: 0.02,
            hard_stop: Some(HardStop {
                x_stop: -0.25,
                k_stop: 50.0,
            }),
            ..Effects::default()
        };
        let (hopper, force) = input
            .drive_with(params, DamperLaw::Switching, effects)
            .unwrap();
        let all = [
            Param::M,
            Param::K,
            Param::C,
            Param::CF,
            Param::InputOffset,
            Param::K3,
            Param::C2,
            Param::XStop,
            Param::KStop,
            Param::Position,
            Param::Velocity,
        ];
        assert!(all.len() > SPLIT_SENSITIVITIES);
        let n = samples.len();
        let run = |params: &[Param]| {
            let (mut positions, mut columns) = (vec![0.0; n], vec![0.0; n * params.len()]);
            simulate_sensitivities(
                &hopper,
                &force,
                0.0,
                [0.1, 0.0],
                dt,
                3,
                params,
                &mut positions,
                &mut columns,
            )
            .unwrap();
            (positions, columns)
        };
        let (positions, columns) = run(&all);
        let (head_positions, head) = run(&all[..SPLIT_SENSITIVITIES]);
        let (_, tail) = run(&all[SPLIT_SENSITIVITIES..]);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
        assert_eq!(bits(&positions), bits(&head_positions));
        assert_eq!(bits(&columns), bits(&[head, tail].concat()));
        // The record reaches the contact and the damper's switch.
        assert!(positions.iter().any(|&x| x < -0.25));
        assert!(positions.iter().any(|&x| x > 0.0));
    }
}
