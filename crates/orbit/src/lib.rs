//! Periodic orbits of clock-driven hybrid systems.
//!
//! Given any [`HybridSystem`](htfid_hybrid::HybridSystem) whose inputs repeat with a known
//! period `T` (a forced, clock-driven oscillator), this crate
//!
//! - integrates the **variational equations** `Phi' = Df(t, x) Phi` alongside the state, with
//!   the **saltation matrix** applied at every transition ([`saltation`], [`Variational`]);
//! - evaluates the **period map** `P(x) = phi(t0 + T; t0, x)` and its Jacobian ([`period_map`]);
//! - finds the limit cycle by settling followed by **Newton shooting** on `P(x) - x = 0`
//!   ([`find_limit_cycle`]), and reports its Floquet multipliers (the eigenvalues of `DP`) and
//!   the periodicity residual, refusing orbits that are not asymptotically stable.
//!
//! # Saltation
//!
//! At a transition from chart `a` to chart `b` at time `t*`, guard `h(t, x) = 0`, reset `R`,
//! a perturbation `dx` just before the event maps to `S dx` just after it, where
//!
//! ```text
//! S = DR + (f_b(x+) - DR f_a(x-) - dR/dt) grad(h)^T / (grad(h) . f_a(x-) + dh/dt)
//! ```
//!
//! `dh/dt` and `dR/dt` are partial derivatives in time at fixed `x`: zero unless the guard or
//! the reset moves with time (a ball hitting a vibrating table `h = y - A sin(w t)`, whose reset
//! reads the table's velocity). `dh/dt` comes from
//! [`HybridSystem::guard_time_derivative`](htfid_hybrid::HybridSystem::guard_time_derivative)
//! where the system supplies it, `dR/dt` and every other missing derivative from central
//! finite differences ([`guard_gradient`], [`reset_jacobian`]).
//!
//! With the identity reset and a vector field that is continuous across the switching surface
//! (the hopper's damper force `c xd` vanishes on `xd = 0`), `f_b = f_a` there and `S = I`.
//!
//! # Orbits that slide
//!
//! Where the motion slides along a switching surface
//! ([`HybridSystem::sliding_chart`](htfid_hybrid::HybridSystem::sliding_chart), for instance a
//! mass stuck by Coulomb friction), the saltation matrices of the start and end of sliding
//! and the variation of the Filippov field are not implemented. [`period_map`] then takes the
//! Jacobian by central differences of the period map (relative accuracy about `1e-6`), so
//! Newton shooting and the Floquet multipliers still work; [`LimitCycle::sliding`] lists the
//! intervals. A motion that slides through the whole period (stuck for good) has no isolated
//! orbit: [`OrbitError::SlidesThroughout`].
//!
//! # Example
//!
//! ```
//! use htfid_hybrid::{HybridSystem, Options};
//! use htfid_orbit::{find_limit_cycle, ShootingOptions};
//!
//! /// x' = -x + cos(t): one chart, a stable 2*pi-periodic orbit with multiplier exp(-2*pi).
//! struct Forced;
//! impl HybridSystem for Forced {
//!     type Mode = ();
//!     fn dim(&self) -> usize { 1 }
//!     fn vector_field(&self, _: (), t: f64, x: &[f64], dx: &mut [f64]) { dx[0] = -x[0] + t.cos(); }
//! }
//! let period = 2.0 * std::f64::consts::PI;
//! let cycle = find_limit_cycle(&Forced, (), 0.0, &[0.0], period, &ShootingOptions::default(),
//!     &Options::default()).unwrap();
//! // The periodic solution is (cos t + sin t)/2, so x(0) = 1/2.
//! assert!((cycle.state0[0] - 0.5).abs() < 1e-9);
//! assert!((cycle.multipliers[0].re - (-period).exp()).abs() < 1e-9);
//! ```

mod error;
mod shooting;
mod variational;

pub use error::OrbitError;
pub use shooting::{find_limit_cycle, period_map, LimitCycle, PeriodMap, ShootingOptions};
pub use variational::{
    guard_gradient, reset_jacobian, saltation, transition_jump, vector_field_jacobian,
    TransitionJump, Variational,
};
