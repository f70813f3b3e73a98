use std::fmt;
use std::sync::Arc;

use htfid_hybrid::{Crossing, HybridSystem};

use crate::{Effects, HopperParams, ModelError};

/// A time-varying input `u(t)` added to the forcing (N). Absolute time, s.
pub type InputFn = Arc<dyn Fn(f64) -> f64 + Send + Sync>;

/// The hopper's charts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
pub enum HopperMode {
    /// Damper on (`x' > v_th`; `s = 1`).
    Damped,
    /// Damper off (`s = 0`).
    Free,
}

impl HopperMode {
    /// The damping switch `s`: 1 when damped.
    #[inline]
    pub fn switch(self) -> f64 {
        match self {
            HopperMode::Damped => 1.0,
            HopperMode::Free => 0.0,
        }
    }
}

/// When the damper acts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DamperLaw {
    /// On only while the mass moves up (the hybrid hopper).
    #[default]
    Switching,
    /// Always on (a plain spring-mass-damper; one chart, no switching).
    AlwaysOn,
}

/// The hopper as a hybrid system. State `[x, x']`, plus the applied force `F` when the
/// actuator lag effect is present.
#[derive(Clone)]
pub struct Hopper {
    params: HopperParams,
    damper: DamperLaw,
    effects: Effects,
    input: Option<InputFn>,
}

impl fmt::Debug for Hopper {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Hopper")
            .field("params", &self.params)
            .field("damper", &self.damper)
            .field("effects", &self.effects)
            .field("input", &self.input.as_ref().map(|_| "<fn>"))
            .finish()
    }
}

impl Hopper {
    /// The nominal switching hopper without input.
    pub fn new(params: HopperParams) -> Result<Self, ModelError> {
        Self::with_effects(params, DamperLaw::Switching, Effects::default())
    }

    /// A hopper with a damper law and extra physical terms.
    pub fn with_effects(
        params: HopperParams,
        damper: DamperLaw,
        effects: Effects,
    ) -> Result<Self, ModelError> {
        params.validate()?;
        effects.validate()?;
        Ok(Hopper {
            params,
            damper,
            effects,
            input: None,
        })
    }

    /// The same model driven by `u(t)` on top of the forcing.
    pub fn with_input(&self, input: Option<InputFn>) -> Self {
        Hopper {
            input,
            ..self.clone()
        }
    }

    /// Parameters.
    #[inline]
    pub fn params(&self) -> &HopperParams {
        &self.params
    }

    /// Extra terms.
    #[inline]
    pub fn effects(&self) -> &Effects {
        &self.effects
    }

    /// Damper law.
    #[inline]
    pub fn damper(&self) -> DamperLaw {
        self.damper
    }

    /// The forcing `A cos(2 pi t / T)` (N).
    #[inline]
    pub fn forcing(&self, t: f64) -> f64 {
        let a = self.params.forcing_amplitude;
        // Measured data carry the forcing in their input: skip the cosine when there is none.
        if a == 0.0 {
            return 0.0;
        }
        a * htfid_trig::cos(self.params.pump_frequency() * t)
    }

    /// The commanded force `f(t) = A cos(2 pi t/T) + u(t) + offset`, before delay and lag.
    #[inline]
    pub fn commanded_force(&self, t: f64) -> f64 {
        let u = self.input.as_ref().map_or(0.0, |u| u(t));
        self.commanded_force_with(t, u)
    }

    /// The commanded force at `t` with the input's value `u` there given: for a caller that
    /// reads the input itself (a sampled signal, without the indirection of [`InputFn`]).
    #[inline]
    pub fn commanded_force_with(&self, t: f64, u: f64) -> f64 {
        self.forcing(t) + u + self.effects.input_offset
    }

    /// The chart a state belongs to.
    pub fn mode_of(&self, xd: f64) -> HopperMode {
        match self.damper {
            DamperLaw::AlwaysOn => HopperMode::Damped,
            DamperLaw::Switching if xd > self.effects.v_th => HopperMode::Damped,
            DamperLaw::Switching => HopperMode::Free,
        }
    }

    /// A starting state near the orbit: the particular solution of the linear system with the
    /// damper on half the time, plus the actuator state where present.
    pub fn initial_guess(&self) -> Vec<f64> {
        let p = &self.params;
        let w = p.pump_frequency();
        let c_eff = match self.damper {
            DamperLaw::AlwaysOn => p.c,
            DamperLaw::Switching => 0.5 * p.c,
        };
        // X = A / (k - m w^2 + j w c_eff); x = x_eq + Re(X e^{j w t}).
        let (re, im) = (p.k - p.m * w * w, w * c_eff);
        let den = re * re + im * im;
        let (xr, xi) = (
            p.forcing_amplitude * re / den,
            -p.forcing_amplitude * im / den,
        );
        let mut state = vec![p.equilibrium() + xr, -w * xi];
        if self.effects.has_lag() {
            state.push(self.commanded_force(0.0));
        }
        state
    }

    /// The applied force at `(t, state)`: the lag state when present, else the (delayed)
    /// commanded force.
    #[inline]
    fn applied_force(&self, t: f64, x: &[f64]) -> f64 {
        if self.effects.has_lag() {
            x[2]
        } else {
            self.commanded_force(t - self.effects.delay)
        }
    }

    /// Acceleration of the mass at position `pos`, velocity `vel` and applied force `force` in
    /// chart `mode` (the second component of the vector field).
    #[inline]
    pub fn acceleration(&self, mode: HopperMode, pos: f64, vel: f64, force: f64) -> f64 {
        let p = &self.params;
        let e = &self.effects;
        let s = mode.switch();
        let dx = pos - p.x0;
        let friction_sign = match self.damper {
            // On the hybrid hopper with v_th = 0 the sign of x' is the chart, exactly, also at
            // the switching instant.
            DamperLaw::Switching => 2.0 * s - 1.0,
            DamperLaw::AlwaysOn => vel.signum(),
        };
        let mut force_sum = -p.m * p.g - p.c * s * vel - p.k * dx + force;
        force_sum -= e.k3 * dx * dx * dx;
        force_sum -= e.mu * friction_sign;
        force_sum -= e.c_f * (1.0 - s) * vel;
        force_sum -= e.c2 * vel * vel.abs();
        if let Some(stop) = e.hard_stop {
            if pos < stop.x_stop {
                force_sum -= stop.k_stop * (pos - stop.x_stop);
            }
        }
        force_sum / p.m
    }
}

impl HybridSystem for Hopper {
    type Mode = HopperMode;

    fn dim(&self) -> usize {
        if self.effects.has_lag() {
            3
        } else {
            2
        }
    }

    fn vector_field(&self, mode: HopperMode, t: f64, x: &[f64], dxdt: &mut [f64]) {
        let force = self.applied_force(t, x);
        dxdt[0] = x[1];
        dxdt[1] = self.acceleration(mode, x[0], x[1], force);
        if self.effects.has_lag() {
            dxdt[2] = (self.commanded_force(t - self.effects.delay) - x[2]) / self.effects.tau;
        }
    }

    fn num_guards(&self, _mode: HopperMode) -> usize {
        match self.damper {
            DamperLaw::Switching => 1,
            DamperLaw::AlwaysOn => 0,
        }
    }

    fn guard(&self, _mode: HopperMode, _index: usize, _t: f64, x: &[f64]) -> f64 {
        x[1] - self.effects.v_th
    }

    fn guard_direction(&self, mode: HopperMode, _index: usize) -> Crossing {
        match mode {
            HopperMode::Damped => Crossing::Falling,
            HopperMode::Free => Crossing::Rising,
        }
    }

    fn transition(&self, mode: HopperMode, _index: usize, _t: f64, _x: &mut [f64]) -> HopperMode {
        match mode {
            HopperMode::Damped => HopperMode::Free,
            HopperMode::Free => HopperMode::Damped,
        }
    }

    /// The damper switch `x' = v_th` is a switching surface: the state is continuous across
    /// it and only the force jumps (the damper, and with `mu > 0` the Coulomb friction, whose
    /// sign is the chart). Where both sides push into it (`|spring + gravity + forcing| < mu`
    /// at `x' = 0`) the mass sticks: the integrator slides along `x' = v_th`.
    fn sliding_chart(&self, mode: HopperMode, _index: usize) -> Option<HopperMode> {
        match self.damper {
            DamperLaw::Switching => Some(match mode {
                HopperMode::Damped => HopperMode::Free,
                HopperMode::Free => HopperMode::Damped,
            }),
            DamperLaw::AlwaysOn => None,
        }
    }

    fn jacobian(&self, mode: HopperMode, _t: f64, x: &[f64], jac: &mut [f64]) -> bool {
        let p = &self.params;
        let e = &self.effects;
        let n = self.dim();
        let s = mode.switch();
        let dx = x[0] - p.x0;
        let mut dpos = -p.k - 3.0 * e.k3 * dx * dx;
        if let Some(stop) = e.hard_stop {
            if x[0] < stop.x_stop {
                dpos -= stop.k_stop;
            }
        }
        let dvel = -p.c * s - e.c_f * (1.0 - s) - 2.0 * e.c2 * x[1].abs();
        jac.iter_mut().for_each(|v| *v = 0.0);
        jac[1] = 1.0;
        jac[n] = dpos / p.m;
        jac[n + 1] = dvel / p.m;
        if n == 3 {
            jac[n + 2] = 1.0 / p.m;
            jac[2 * n + 2] = -1.0 / e.tau;
        }
        true
    }

    fn guard_gradient(
        &self,
        _mode: HopperMode,
        _index: usize,
        _t: f64,
        _x: &[f64],
        grad: &mut [f64],
    ) -> bool {
        grad.iter_mut().for_each(|v| *v = 0.0);
        grad[1] = 1.0;
        true
    }

    fn reset_jacobian(
        &self,
        _mode: HopperMode,
        _index: usize,
        _t: f64,
        _x: &[f64],
        jac: &mut [f64],
    ) -> bool {
        let n = self.dim();
        jac.iter_mut().for_each(|v| *v = 0.0);
        for i in 0..n {
            jac[i * n + i] = 1.0;
        }
        true
    }
}

impl htfid_ltp::InputOutput for Hopper {
    /// The input enters as a force: `B = [0, 1/m]`, or `[0, 0, 1/tau]` through the actuator lag.
    /// An input delay is not representable in a finite-dimensional LTP model and is ignored
    /// here.
    fn input_gain(&self, _mode: HopperMode, _t: f64, _x: &[f64], b: &mut [f64]) {
        b.iter_mut().for_each(|v| *v = 0.0);
        if self.effects.has_lag() {
            b[2] = 1.0 / self.effects.tau;
        } else {
            b[1] = 1.0 / self.params.m;
        }
    }

    /// The hopper's `A` is constant within each chart unless a term makes it depend on the
    /// state there: a cubic spring, quadratic drag, a one-sided contact (no chart of its own),
    /// or Coulomb friction (its sticking is a sliding mode). Flight damping, an actuator lag,
    /// a shifted switching threshold and an input offset keep it constant.
    fn is_piecewise_constant(&self) -> bool {
        let e = &self.effects;
        e.k3 == 0.0 && e.c2 == 0.0 && e.mu == 0.0 && e.hard_stop.is_none()
    }

    /// One output, the position: `C = [1, 0]` (or `[1, 0, 0]`).
    fn output_gain(&self, _mode: HopperMode, _t: f64, _x: &[f64], c: &mut [f64]) {
        c.iter_mut().for_each(|v| *v = 0.0);
        c[0] = 1.0;
    }
}
