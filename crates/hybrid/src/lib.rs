//! Event-accurate integration of hybrid systems with explicit Runge-Kutta pairs.
//!
//! A hybrid system ([`HybridSystem`]) is a set of charts (modes), each with a smooth vector
//! field `x' = f_mode(t, x)` and guard functions `g_i(t, x)`; when a guard crosses zero in its
//! [`Crossing`] direction, its reset map ([`HybridSystem::transition`]) is applied and the flow
//! continues in the chart it returns. [`simulate`] integrates from `(t0, x0, mode0)` to `t_end`
//! and returns a [`Trajectory`]: the states on a requested grid (from the dense output), every
//! [`Event`], and work counters ([`Stats`]). [`simulate_fixed_step`] is the fixed-step
//! alternative (RK4 on a uniform sample grid with located events), for fits whose cost must vary
//! smoothly with the parameters; [`simulate_fixed_step_states`] takes the same steps and hands
//! over the whole state at every sample (a state with its sensitivities appended, say).
//! [`Integrator`] is the stepping API underneath: each
//! call to [`Integrator::step_until`] takes at most one step and says why it stopped
//! ([`StopReason`]). [`Options`] holds tolerances and event settings; errors are
//! [`HybridError`]. A guard that a system declares a switching surface
//! ([`HybridSystem::sliding_chart`]) may be slid along (Filippov sliding, for instance a mass
//! stuck by Coulomb friction); the [`Trajectory`] lists those intervals ([`SlidingInterval`]).
//!
//! ```
//! use htfid_hybrid::{simulate, Crossing, EventKind, HybridSystem, Options};
//!
//! /// A ball `[height, velocity]` bouncing with restitution 0.9.
//! struct Ball;
//!
//! impl HybridSystem for Ball {
//!     type Mode = ();
//!     fn dim(&self) -> usize {
//!         2
//!     }
//!     fn vector_field(&self, _: (), _t: f64, x: &[f64], dxdt: &mut [f64]) {
//!         dxdt[0] = x[1];
//!         dxdt[1] = -9.81;
//!     }
//!     fn num_guards(&self, _: ()) -> usize {
//!         1
//!     }
//!     fn guard(&self, _: (), _: usize, _t: f64, x: &[f64]) -> f64 {
//!         x[0]
//!     }
//!     fn guard_direction(&self, _: (), _: usize) -> Crossing {
//!         Crossing::Falling
//!     }
//!     fn transition(&self, _: (), _: usize, _t: f64, x: &mut [f64]) {
//!         x[1] *= -0.9;
//!     }
//! }
//!
//! let grid = [0.0, 0.25, 0.5, 0.75, 1.0];
//! let traj = simulate(&Ball, (), 0.0, &[1.0, 0.0], 1.0, &grid, &Options::default()).unwrap();
//! // Dropped from 1 m, the ball lands at sqrt(2 / 9.81) = 0.4515 s.
//! let impact = &traj.events[0];
//! assert_eq!(impact.kind, EventKind::Transition);
//! assert!((impact.time - (2.0f64 / 9.81).sqrt()).abs() < 1e-11);
//! assert!(impact.state[1] < 0.0); // the state before the reset
//! assert!(traj.state(2)[1] > 0.0); // at t = 0.5 s it is on its way up
//! ```
//!
//! # Conventions
//!
//! - Time is in the unit the system uses for `t` (seconds throughout this workspace); every
//!   time-valued option (`h_*`, `event_tol`, `zeno_window`) is in that unit.
//! - States are `&[f64]` of length [`HybridSystem::dim`], the same in every chart;
//!   [`Trajectory::states`] is row-major, one row per grid time.
//! - Guards: [`Crossing::Rising`] fires when the guard goes from `< 0` to `>= 0`,
//!   [`Crossing::Falling`] from `> 0` to `<= 0`, [`Crossing::Either`] on both. The side a guard
//!   must start on ("pre-crossing side") is therefore strictly nonzero: a guard sitting exactly
//!   on zero has to leave it before it can fire.
//! - An [`Event`] records the time, the charts before and after, the guard index (in the chart
//!   before) and the state interpolated to the event time *before* the reset. Its time is the
//!   end of the final root bracket on the post-crossing side, within `event_tol` after the root.
//! - A grid time equal to a transition time receives the post-reset state and chart.
//!
//! # Methods
//!
//! [`Method::Dopri5`] is the Dormand-Prince 5(4) pair (6 evaluations per step thanks to FSAL,
//! "first same as last") with Shampine's 4th-order dense output. [`Method::Dop853`] (the
//! default) is Hairer's 8th-order pair with the combined 5th/3rd-order error estimator of his
//! `dop853` code (12 evaluations per step with FSAL) and its 7th-order dense output (3 more
//! evaluations per accepted step). The error norm is the root mean square of
//! `err_i / (atol + rtol * max(|x_i(t)|, |x_i(t + h)|))`; a step passes when it is `<= 1`. Step
//! sizes follow Hairer's controller (safety factor 0.9; ratio limits 0.2 to 10 for Dopri5 with
//! a PI term `beta = 0.04`, 1/3 to 6 for DOP853), and the first step comes from Hairer's
//! starting-step estimate unless `Options::h_init` is given. A step is stretched by up to 1 %
//! (possibly past `h_max`) to land on `t_stop` instead of leaving a sliver. After an event `f`
//! is re-evaluated: there is no FSAL across a reset.
//!
//! # Event algorithm
//!
//! After every accepted step `[t0, t1]` of length `h`, each guard of the current chart is
//! sampled at `t1` (from the new state) and at `m = guard_samples` interior times
//! `t0 + j h / (m + 1)` (from the dense output); the value at `t0` is carried over from the
//! previous step. Per guard, the sample intervals are scanned in time order:
//!
//! 1. **Sign change.** The first interval whose end values cross in the guard's direction is a
//!    bracket. The root is located on the dense output by the Illinois variant of regula falsi
//!    (with a bisection step whenever two iterations fail to halve the bracket) until the
//!    bracket is narrower than `event_tol`.
//! 2. **Extremum refinement.** A guard can cross and come back between two samples. Where the
//!    samples on the pre-crossing side show a local minimum of `|g|` (a sample strictly closer to
//!    zero than the one before and no farther than the one after), the minimum of `|g|` over the
//!    two adjacent intervals is refined by Brent's method on the dense output. Near the ends of
//!    the step the same is done when the time derivative of the guard along the flow (a finite
//!    difference of the guard along `f`) shows it turning between `t0` and the first sample, or
//!    between the last sample and `t1`. Turns too shallow to get near zero are skipped: the
//!    refinement runs only if the closest sample is within (the quadratic coefficient of the
//!    parabola through the samples, or through the end samples and the derivative, which bounds
//!    that parabola's dip) plus `graze_tol` of zero. If the refined guard value reaches the
//!    post-crossing side, the pair of crossings is real and the first one is bracketed and
//!    located as in 1.; if it stays within `graze_tol` of zero, a [`EventKind::Grazing`] event is
//!    recorded.
//!
//! The earliest transition over all guards wins (the lowest guard index on a tie). The step is
//! cut there: the state is interpolated to the event time, the reset is applied, the event is
//! logged and the integrator restarts in the new chart from the event time (`f` and all guards
//! re-evaluated). Grazes before the transition are reported too, in time order; each
//! [`Integrator::step_until`] call returns one event. A graze is only reported, the state
//! continues unchanged.
//!
//! **Restarts.** Right after a restart (the initial time or a transition) a guard that sits on
//! zero must not fire again at once: a crossing located within `event_tol` after the restart
//! is ignored, since it only says that the guard is leaving the surface. The exception is a
//! guard that starts on (or just past) zero, heads into its pre-crossing side and is back past
//! zero at the first sample: it left and returned within the first sample interval (a bounce
//! shorter than the sampling). Probing `t0 + 2^-k (t_1st sample - t0)` finds a point on the
//! pre-crossing side for any such excursion down to the resolution of `t`, and the return
//! crossing fires even if it is closer than `event_tol`. If no such point exists although the
//! guard sits within `graze_tol` of zero just after a transition, the events have accumulated
//! beyond resolution and the integration stops with [`HybridError::Zeno`].
//!
//! **Zeno.** More than `zeno_max_events` transitions within any `zeno_window` is
//! [`HybridError::Zeno`], which names the time, the guard of the last transition and the count.
//! Grazes do not count; the starts and ends of sliding do, so a motion that keeps sticking and
//! breaking loose faster than that (chattering) stops there too.
//!
//! # Sliding (Filippov)
//!
//! A switching surface is a guard `g` of chart `A` across which the state is continuous and
//! only the vector field jumps: [`HybridSystem::sliding_chart`] returns the chart `B` on its
//! far side (default `None`: an ordinary guard, for instance an impact with a reset). Write
//! `a = dg/dt` along `f_A` and `b = dg/dt` along `f_B` (the normal speeds, from
//! [`HybridSystem::guard_gradient`] and [`HybridSystem::guard_time_derivative`] where the
//! system supplies them, else central differences along each field).
//!
//! - **Start.** At a located crossing of such a guard, if `a` and `b` have opposite signs
//!   (the field of `B` points back into the surface, so the flow would cross again at once),
//!   the motion slides instead of crossing: the state is moved onto `g = 0` along the gradient
//!   (it was located within `event_tol` past it), an [`EventKind::SlideStart`] is logged, and
//!   the chart stays `A`. Otherwise the transition happens as usual.
//! - **Motion.** While sliding the integrator steps Filippov's convex combination
//!   `f_s = (1 - alpha) f_A + alpha f_B` with `alpha = a / (a - b)`, for which `dg/dt = 0`: the
//!   state moves along the surface (for friction at zero velocity, `x' = 0` is held). The
//!   error control, dense output and step-size controller are those of any chart.
//! - **End.** Sliding lasts while `alpha` stays in `(0, 1)`, i.e. while `a` and `b` keep their
//!   signs. The two exit conditions (`alpha` reaching 0: the field of `A` leaves the surface;
//!   1: that of `B` does) are guards of the sliding motion, sampled and located by the event
//!   algorithm above like any crossing (an early exit is never suppressed by the restart
//!   rule). At the exit an [`EventKind::SlideEnd`] event is logged (its `to` is the chart the
//!   motion leaves into) and the integration restarts there. The other guards of `A` stay
//!   active while sliding; if one fires, sliding ends and its transition follows at once.
//! - **Initial state.** At `t0`, a state on the far side of a declared surface (for a rising
//!   or falling guard) starts in the chart of that side; a state within `graze_tol` of the
//!   surface whose chart's field heads across starts sliding if the far side's field points
//!   back, and starts in the far side's chart otherwise. So a simulation restarted from the
//!   end of another, even mid-stick, continues as it would have.
//! - **Reports.** [`Trajectory::sliding`] lists the intervals (start, end, guard, the chart
//!   the motion arrived in, the chart it left into); [`Trajectory::sliding_at`] finds the one
//!   containing a time. On the grid the chart while sliding is the arrival chart.
//!
//! The sensitivity of the flow through sliding (saltation at the start and end, and the
//! derivative of `alpha`) is not implemented: `htfid-orbit` takes the period-map Jacobian of an
//! orbit with sliding by differences, and the linearisations of `htfid-ltp` and `htfid-theory`
//! refuse such orbits.
//!
//! # Guarantees and limits
//!
//! - Every sign change between consecutive samples is found, in the allowed direction, and the
//!   first one in time wins. Samples are at most `h / (guard_samples + 1)` apart, and `h` is at
//!   most `h_max`.
//! - An even number of crossings between two consecutive samples is found only when the
//!   samples bracket it by a local extremum on the pre-crossing side, deep enough by the test
//!   above. A guard that crosses and returns between two samples while the samples around it
//!   are monotone, or whose dip is much sharper than the parabola through the samples (for
//!   instance several oscillations of the guard within one sample interval), is undetectable.
//!   Bound `h_max`, or raise `guard_samples`, to resolve the fastest guard motion.
//! - Grazing times are located to about `1.5e-8` times the refined interval: near a touch the
//!   guard is flat to second order, so the time of its extremum is not better defined in
//!   floating point.
//! - Two guards crossing at the same instant: the lower index fires; the other, if still
//!   present in the new chart and within `event_tol` of its crossing, falls under the restart
//!   rule and is ignored.
//! - A crossing at exactly `t0` (a start on the surface) is not reported (for declared
//!   switching surfaces the start rule of the sliding section decides the chart instead).
//! - Sliding: the exit times are located to `event_tol` like crossings; the state stays on
//!   the surface to rounding when the system supplies the guard gradient (the coefficient
//!   `alpha` is then exact), and to the finite-difference error (about `1e-10` relative)
//!   otherwise. Measured on a stick-slip belt with a closed-form solution
//!   (`tests/sliding.rs`): stick start and end times and states within `1e-10`.
//! - A surface the system does not declare is crossed as before: where the far side's field
//!   points back, the motion chatters (ending in [`HybridError::Zeno`]) or, if the return
//!   crossing comes within `event_tol` of the first, passes through the surface in the wrong
//!   chart. Declare every surface that can slide.
//! - Invariant: outside the sliding intervals, every guard of the chart at a grid time lies on
//!   its pre-crossing side (within the event tolerance); [`Trajectory::check_charts`] checks
//!   it, and the test suites run it on their simulations.
//! - [`simulate_fixed_step`] slides the same way, with RK4 on the Filippov field and the exit
//!   conditions located on the step's Hermite interpolant; on the belt, RK4 with
//!   `h = 2.5 ms` stays within `1e-9` of the closed form through a stick.
//! - Failures never panic: step-size underflow ([`HybridError::StepSizeTooSmall`], naming the
//!   time), non-finite states or guards, the step cap and Zeno behaviour are errors.
//! - Cost is known up front: [`trajectory_bytes`] is the memory of a sampled trajectory and
//!   [`min_steps`] a lower bound on the steps of a forced run, so a caller can refuse a request
//!   that cannot fit, or cannot finish under `max_steps`, before integrating.
//!
//! # Performance
//!
//! Every buffer is allocated once in [`Integrator::new`]; a step allocates only when it reports
//! an event (the event's state vector) or starts sliding. Sliding costs two vector-field
//! evaluations per stage (one per side) and one more per exit-guard sample; event-free stepping
//! outside sliding is unchanged (one branch per step selects the field). For small state dimensions (up to 4) the stage loops are
//! specialised so that they unroll. Figures from `cargo run --release -p htfid-hybrid --example
//! bench_events` are recorded in that example's documentation.

mod error;
mod fixed;
mod integrator;
mod options;
mod rk;
mod roots;
mod size;
mod sliding;
mod system;
mod tableau;
mod trajectory;

pub use error::HybridError;
pub use fixed::{
    simulate_fixed_step, simulate_fixed_step_batch, simulate_fixed_step_states, FixedStepLane,
    FIXED_STEP_MAX_DIM,
};
pub use integrator::{simulate, Integrator, StopReason};
pub use options::{Method, Options};
pub use size::{min_steps, trajectory_bytes, MIN_STEPS_PER_PERIOD};
pub use system::{Crossing, HybridSystem};
pub use trajectory::{Event, EventKind, SlidingInterval, Stats, Trajectory};
