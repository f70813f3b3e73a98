//! Simulation of a model driven by the measured force.

use std::sync::Arc;

use htfid_hybrid::{Crossing, HybridSystem, Method, Options};
use htfid_model::{DamperLaw, Effects, Hopper, HopperMode, HopperParams, InputFn, ModelError};
use serde::{Deserialize, Serialize};

use crate::interp::{Interpolation, LaggedSignal, SampledSignal};

/// Largest state dimension the fixed-step integrator handles (position, velocity, lag state).
const MAX_DIM: usize = 4;
/// Switches allowed within one sub-step before the motion counts as chattering.
const MAX_EVENTS_PER_STEP: usize = 8;
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
    /// simulated output is a smooth function of the parameters. Fast; its error against the
    /// adaptive integrator is checked in the tests.
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
    base: [usize; 2],
    contact: Option<f64>,
    friction: bool,
}

impl<'a> Located<'a> {
    fn new(hopper: &'a Hopper) -> Self {
        let e = hopper.effects();
        Located {
            hopper,
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
}

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
    let mut state = vec![xv0[0], xv0[1]];
    if hopper.effects().has_lag() {
        state.push(hopper.commanded_force(t0 - hopper.effects().delay));
    }
    let mode0 = hopper.mode_of(xv0[1]);
    let sys = Located::new(hopper);
    match stepping {
        Stepping::Fixed { substeps } => rk4_hybrid(&sys, mode0, t0, &state, dt, *substeps, out),
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

/// Classical RK4 on a uniform grid of `out.len()` samples with `substeps` per sample, for any
/// hybrid system of dimension at most 4. A guard crossing in its direction within a sub-step is
/// located on the cubic Hermite interpolant of the sub-step; the sub-step is then redone up to
/// the crossing, the reset applied, and the rest of the sub-step taken in the new chart.
/// Writes the first state component at each sample.
pub(crate) fn rk4_hybrid<S: HybridSystem>(
    sys: &S,
    mode0: S::Mode,
    t0: f64,
    x0: &[f64],
    dt: f64,
    substeps: usize,
    out: &mut [f64],
) -> Result<(), SimFailure> {
    let n = sys.dim();
    if n > MAX_DIM || x0.len() != n || n == 0 {
        return Err(SimFailure {
            time: t0,
            reason: format!(
                "state dimension {n} (initial state of length {}) is not supported",
                x0.len()
            ),
        });
    }
    let mut st = Stepper {
        sys,
        n,
        mode: mode0,
        x: [0.0; MAX_DIM],
        f: [0.0; MAX_DIM],
    };
    st.x[..n].copy_from_slice(x0);
    sys.vector_field(mode0, t0, &st.x[..n], &mut st.f[..n]);
    let Some((first, rest)) = out.split_first_mut() else {
        return Ok(());
    };
    *first = st.x[0];
    let substeps = substeps.max(1);
    let h = dt / substeps as f64;
    let mut j = 0usize;
    for slot in rest {
        for _ in 0..substeps {
            // Times from the step count, so they do not drift over a long record.
            let ta = t0 + j as f64 * h;
            j += 1;
            let tb = t0 + j as f64 * h;
            st.advance(ta, tb)?;
        }
        *slot = st.x[0];
    }
    Ok(())
}

struct Stepper<'a, S: HybridSystem> {
    sys: &'a S,
    n: usize,
    mode: S::Mode,
    x: [f64; MAX_DIM],
    /// Vector field at `x` in `mode`.
    f: [f64; MAX_DIM],
}

impl<S: HybridSystem> Stepper<'_, S> {
    fn advance(&mut self, ta: f64, tb: f64) -> Result<(), SimFailure> {
        let n = self.n;
        let mut t = ta;
        // The guard that just fired sits at zero at the restart; it is not watched again within
        // the same sub-step (a guard with either crossing direction would otherwise fire again
        // at once).
        let mut fired: Option<usize> = None;
        for _ in 0..=MAX_EVENTS_PER_STEP {
            let h = tb - t;
            let mut xb = [0.0; MAX_DIM];
            rk4_step(self.sys, self.mode, t, &self.x, &self.f, h, n, &mut xb);
            if !xb[..n].iter().all(|v| v.is_finite()) {
                return Err(SimFailure {
                    time: tb,
                    reason: "the state became non-finite".to_string(),
                });
            }
            let mut fb = [0.0; MAX_DIM];
            self.sys.vector_field(self.mode, tb, &xb[..n], &mut fb[..n]);
            let mut first: Option<(f64, usize)> = None;
            for g in 0..self.sys.num_guards(self.mode) {
                if fired == Some(g) {
                    continue;
                }
                let ga = self.sys.guard(self.mode, g, t, &self.x[..n]);
                let gb = self.sys.guard(self.mode, g, tb, &xb[..n]);
                if !self.sys.guard_direction(self.mode, g).accepts(ga, gb) {
                    continue;
                }
                let (xa, fa) = (&self.x, &self.f);
                let mut buf = [0.0; MAX_DIM];
                let theta = locate(
                    |th| {
                        hermite(xa, fa, &xb, &fb, h, th, n, &mut buf);
                        self.sys.guard(self.mode, g, t + th * h, &buf[..n])
                    },
                    ga,
                    gb,
                );
                if first.map_or(true, |(th0, _)| theta < th0) {
                    first = Some((theta, g));
                }
            }
            let Some((theta, guard)) = first else {
                self.x = xb;
                self.f = fb;
                return Ok(());
            };
            let te = t + theta * h;
            let mut xe = [0.0; MAX_DIM];
            rk4_step(self.sys, self.mode, t, &self.x, &self.f, te - t, n, &mut xe);
            self.mode = self.sys.transition(self.mode, guard, te, &mut xe[..n]);
            fired = Some(guard);
            self.x = xe;
            self.sys
                .vector_field(self.mode, te, &self.x[..n], &mut self.f[..n]);
            t = te;
        }
        Err(SimFailure {
            time: t,
            reason: format!(
                "more than {MAX_EVENTS_PER_STEP} switches within one integration step (chattering)"
            ),
        })
    }
}

#[inline]
fn rk4_step<S: HybridSystem>(
    sys: &S,
    mode: S::Mode,
    t: f64,
    x: &[f64; MAX_DIM],
    f0: &[f64; MAX_DIM],
    h: f64,
    n: usize,
    out: &mut [f64; MAX_DIM],
) {
    let mut tmp = [0.0; MAX_DIM];
    let mut k2 = [0.0; MAX_DIM];
    let mut k3 = [0.0; MAX_DIM];
    let mut k4 = [0.0; MAX_DIM];
    let half = 0.5 * h;
    for i in 0..n {
        tmp[i] = x[i] + half * f0[i];
    }
    sys.vector_field(mode, t + half, &tmp[..n], &mut k2[..n]);
    for i in 0..n {
        tmp[i] = x[i] + half * k2[i];
    }
    sys.vector_field(mode, t + half, &tmp[..n], &mut k3[..n]);
    for i in 0..n {
        tmp[i] = x[i] + h * k3[i];
    }
    sys.vector_field(mode, t + h, &tmp[..n], &mut k4[..n]);
    let sixth = h / 6.0;
    for i in 0..n {
        out[i] = x[i] + sixth * (f0[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
    }
}

/// Cubic Hermite interpolant of a step of length `h` at fraction `th`.
#[inline]
fn hermite(
    xa: &[f64; MAX_DIM],
    fa: &[f64; MAX_DIM],
    xb: &[f64; MAX_DIM],
    fb: &[f64; MAX_DIM],
    h: f64,
    th: f64,
    n: usize,
    out: &mut [f64; MAX_DIM],
) {
    let s = 1.0 - th;
    let h00 = (1.0 + 2.0 * th) * s * s;
    let h10 = th * s * s;
    let h01 = th * th * (3.0 - 2.0 * th);
    let h11 = -th * th * s;
    for i in 0..n {
        out[i] = h00 * xa[i] + h10 * h * fa[i] + h01 * xb[i] + h11 * h * fb[i];
    }
}

/// Root of `g` on `[0, 1]` given `g(0) = ga` and `g(1) = gb` of opposite signs (or `gb`
/// zero): Illinois false position to `1e-14`.
fn locate(mut g: impl FnMut(f64) -> f64, ga: f64, gb: f64) -> f64 {
    let (mut a, mut fa, mut b, mut fb) = (0.0_f64, ga, 1.0_f64, gb);
    if fb.is_nan() || fb.abs() <= 0.0 {
        return 1.0;
    }
    let mut side = 0i8;
    let mut c = 1.0;
    for _ in 0..100 {
        if b - a <= 1e-14 {
            return b;
        }
        let mut next = (a * fb - b * fa) / (fb - fa);
        if !(next > a && next < b) {
            next = 0.5 * (a + b);
        }
        let converged = (next - c).abs() <= 1e-15;
        c = next;
        let fc = g(c);
        if converged || fc.is_nan() || fc.abs() <= 0.0 {
            return c;
        }
        if (fc > 0.0) == (fb > 0.0) {
            b = c;
            fb = fc;
            if side == -1 {
                fa *= 0.5;
            }
            side = -1;
        } else {
            a = c;
            fa = fc;
            if side == 1 {
                fb *= 0.5;
            }
            side = 1;
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;
    use htfid_hybrid::Crossing;

    /// A bouncing ball: x'' = -g, velocity reversed with restitution at x = 0.
    struct Ball;
    impl HybridSystem for Ball {
        type Mode = ();
        fn dim(&self) -> usize {
            2
        }
        fn vector_field(&self, _m: (), _t: f64, _x: &[f64], d: &mut [f64]) {
            d[0] = _x[1];
            d[1] = -9.81;
        }
        fn num_guards(&self, _m: ()) -> usize {
            1
        }
        fn guard(&self, _m: (), _i: usize, _t: f64, x: &[f64]) -> f64 {
            x[0]
        }
        fn guard_direction(&self, _m: (), _i: usize) -> Crossing {
            Crossing::Falling
        }
        fn transition(&self, m: (), _i: usize, _t: f64, x: &mut [f64]) -> Self::Mode {
            x[1] *= -0.8;
            m
        }
    }

    #[test]
    fn bouncing_ball_matches_the_closed_form() {
        // Dropped from 1 m: impact at t1 = sqrt(2/9.81), rebound speed 0.8 * 9.81 * t1.
        // Between events the motion is a parabola, which RK4 integrates exactly, and the
        // Hermite interpolant of a parabola is exact, so only root finding (1e-14) and rounding
        // remain: 1e-10 m is generous.
        let g: f64 = 9.81;
        let t1 = (2.0 / g).sqrt();
        let v1 = 0.8 * g * t1;
        let dt = 0.01;
        let mut out = vec![0.0; 60];
        rk4_hybrid(&Ball, (), 0.0, &[1.0, 0.0], dt, 1, &mut out).unwrap();
        for (i, &x) in out.iter().enumerate() {
            let t = i as f64 * dt;
            let exact = if t < t1 {
                1.0 - 0.5 * g * t * t
            } else {
                let s = t - t1;
                v1 * s - 0.5 * g * s * s
            };
            assert_abs_diff_eq!(x, exact, epsilon = 1e-10);
        }
    }

    #[test]
    fn root_finder_finds_a_simple_root() {
        let r = locate(|t| t * t - 0.3, -0.3, 0.7);
        assert_abs_diff_eq!(r, 0.3f64.sqrt(), epsilon = 1e-13);
    }
}
