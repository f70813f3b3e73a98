//! The hybrid-system trait: charts (modes), a vector field per chart, guards and resets.

use std::fmt::Debug;

/// Direction in which a guard function must cross zero to trigger its transition.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Crossing {
    /// From negative to positive.
    Rising,
    /// From positive to negative.
    Falling,
    /// Either direction.
    Either,
}

impl Crossing {
    /// Whether a sign change from `before` to `after` is a crossing in this direction.
    pub fn accepts(self, before: f64, after: f64) -> bool {
        match self {
            Crossing::Rising => before < 0.0 && after >= 0.0,
            Crossing::Falling => before > 0.0 && after <= 0.0,
            Crossing::Either => (before < 0.0 && after >= 0.0) || (before > 0.0 && after <= 0.0),
        }
    }
}

/// A hybrid dynamical system: a finite set of charts (modes), each with a smooth vector field
/// and guard functions whose zero crossings trigger transitions with reset maps.
///
/// Time-varying inputs enter through the vector field (it receives `t`). The state dimension is
/// the same in every chart.
///
/// Only [`HybridSystem::vector_field`] and [`HybridSystem::dim`] are required; a system with
/// no guards is an ordinary ODE. Jacobians are optional: where a system does not supply one,
/// callers that need it fall back to finite differences.
pub trait HybridSystem {
    /// The chart label. An enum for most models.
    type Mode: Copy + Eq + Debug + Send + Sync;

    /// State dimension.
    fn dim(&self) -> usize;

    /// `dxdt = f_mode(t, x)`.
    fn vector_field(&self, mode: Self::Mode, t: f64, x: &[f64], dxdt: &mut [f64]);

    /// Number of guard functions active in `mode`.
    fn num_guards(&self, _mode: Self::Mode) -> usize {
        0
    }

    /// Value of guard `index` of `mode` at `(t, x)`; the transition fires when it crosses zero
    /// in the direction given by [`HybridSystem::guard_direction`].
    fn guard(&self, _mode: Self::Mode, _index: usize, _t: f64, _x: &[f64]) -> f64 {
        1.0
    }

    /// Partial derivative `dh/dt` of guard `index` of `mode` with respect to time at fixed `x`,
    /// or `None` (the default) when the system does not provide it.
    ///
    /// It enters the saltation matrix through the crossing speed `grad(h) . f + dh/dt`
    /// (`htfid-orbit`), which falls back to a central finite difference in `t` when this returns
    /// `None`. Guards that do not depend on `t` make the difference exactly zero, so only guards
    /// that move in time need it, for example a vibrating table `h = y - A sin(w t)`, whose
    /// `dh/dt = -A w cos(w t)`: there the central difference (step `6e-6 max(1, |t|)`) is off by
    /// about `(w h)^2 / 6` relative, `6e-9` at `w = 31` rad/s, and the exact value by nothing.
    /// The integrator itself never calls it.
    fn guard_time_derivative(
        &self,
        _mode: Self::Mode,
        _index: usize,
        _t: f64,
        _x: &[f64],
    ) -> Option<f64> {
        None
    }

    /// Partial derivative `dR/dt` (at fixed `x`) of the reset map of guard `index` of `mode`,
    /// written into `out` (length `dim`). Returns `false` (the default) when not provided;
    /// `htfid-orbit` then takes a central difference in `t`, exactly zero for resets that do
    /// not read `t`. A reset that reads a moving surface's velocity (a ball hitting a vibrating
    /// table) needs it in its saltation matrix. The integrator itself never calls it.
    fn reset_time_derivative(
        &self,
        _mode: Self::Mode,
        _index: usize,
        _t: f64,
        _x: &[f64],
        _out: &mut [f64],
    ) -> bool {
        false
    }

    /// Crossing direction of guard `index` of `mode`.
    fn guard_direction(&self, _mode: Self::Mode, _index: usize) -> Crossing {
        Crossing::Either
    }

    /// Applies the reset map of guard `index` of `mode` to `x` in place and returns the new
    /// chart. The default is the identity reset staying in the same chart.
    fn transition(&self, mode: Self::Mode, _index: usize, _t: f64, _x: &mut [f64]) -> Self::Mode {
        mode
    }

    /// The chart on the other side of guard `index` of `mode` when that guard is a switching
    /// surface on which the motion can slide; `None` (the default) for every other guard.
    ///
    /// A switching surface is a guard across which the state is continuous (its
    /// [`HybridSystem::transition`] leaves the state unchanged and returns this chart) while
    /// the vector field jumps, as Coulomb friction does at zero velocity. Where, at a crossing,
    /// the field of the chart on the far side points back into the surface, the integrator
    /// slides along it with Filippov's convex combination instead of crossing (see the crate
    /// docs). Guards whose reset changes the state (impacts) must return `None`. The guard's
    /// value must not depend on the chart: guard `index` of `mode` is the surface seen from
    /// both sides.
    fn sliding_chart(&self, _mode: Self::Mode, _index: usize) -> Option<Self::Mode> {
        None
    }

    /// Jacobian `df/dx` of the vector field, row-major `dim x dim`, written into `jac`.
    /// Returns `false` (the default) when the system does not provide it.
    fn jacobian(&self, _mode: Self::Mode, _t: f64, _x: &[f64], _jac: &mut [f64]) -> bool {
        false
    }

    /// Gradient of guard `index` of `mode` with respect to `x`, written into `grad`.
    /// Returns `false` (the default) when the system does not provide it.
    fn guard_gradient(
        &self,
        _mode: Self::Mode,
        _index: usize,
        _t: f64,
        _x: &[f64],
        _grad: &mut [f64],
    ) -> bool {
        false
    }

    /// Jacobian of the reset map of guard `index` of `mode`, row-major `dim x dim`.
    /// Returns `false` (the default) when not provided; callers then use finite differences.
    fn reset_jacobian(
        &self,
        _mode: Self::Mode,
        _index: usize,
        _t: f64,
        _x: &[f64],
        _jac: &mut [f64],
    ) -> bool {
        false
    }
}
