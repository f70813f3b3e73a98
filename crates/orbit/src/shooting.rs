//! Settling and Newton shooting onto the forced periodic orbit.

use htfid_hybrid::{simulate, Event, HybridSystem, Options, SlidingInterval, Stats};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

use crate::{OrbitError, Variational};

/// How the limit cycle is searched for.
#[derive(Debug, Clone)]
pub struct ShootingOptions {
    /// Periods simulated before Newton shooting starts (the paper uses 30).
    pub settle_periods: usize,
    /// Newton stops when `|P(x) - x|_inf <= newton_tol * max(1, |x|_inf)`, or when a step no
    /// longer lowers that residual and it lies within `1e3 newton_tol` or `10 rtol` (the
    /// integrator's tolerance) of `max(1, |x|_inf)`: the period map's own error.
    pub newton_tol: f64,
    /// At most this many Newton iterations.
    pub max_newton: usize,
    /// The orbit counts as asymptotically stable when every Floquet multiplier has modulus
    /// below `1 - stability_margin`.
    pub stability_margin: f64,
}

impl Default for ShootingOptions {
    fn default() -> Self {
        ShootingOptions {
            settle_periods: 30,
            newton_tol: 1e-13,
            max_newton: 30,
            stability_margin: 1e-6,
        }
    }
}

impl ShootingOptions {
    fn validate(&self) -> Result<(), OrbitError> {
        if !(self.newton_tol.is_finite() && self.newton_tol > 0.0) {
            return Err(OrbitError::InvalidOptions {
                field: "newton_tol",
                reason: format!("must be > 0 and finite (got {})", self.newton_tol),
            });
        }
        if self.max_newton == 0 {
            return Err(OrbitError::InvalidOptions {
                field: "max_newton",
                reason: "must be at least 1 (got 0)".into(),
            });
        }
        if !(self.stability_margin.is_finite() && (0.0..1.0).contains(&self.stability_margin)) {
            return Err(OrbitError::InvalidOptions {
                field: "stability_margin",
                reason: format!("must be in [0, 1) (got {})", self.stability_margin),
            });
        }
        Ok(())
    }
}

/// One application of the period map with its Jacobian.
#[derive(Debug, Clone)]
pub struct PeriodMap<M> {
    /// `P(x) = phi(t0 + T; t0, x)`.
    pub state: Vec<f64>,
    /// The chart at `t0 + T`.
    pub mode: M,
    /// `DP(x)`, saltations included. When the motion slides during the period, central
    /// differences of the period map instead (see [`period_map`]).
    pub jacobian: DMatrix<f64>,
    /// Transitions during the period (states before the reset, without the sensitivity part).
    pub events: Vec<Event<M>>,
    /// Intervals spent sliding along a switching surface during the period.
    pub sliding: Vec<SlidingInterval<M>>,
    /// Integrator work.
    pub stats: Stats,
}

/// Integrates the variational system over one period from `(t0, x0, mode0)`.
///
/// When the motion slides along a switching surface during the period, the variational
/// equations do not give the flow's Jacobian (the saltation matrices of the sliding start and
/// end and the derivative of the Filippov coefficient are not implemented), so the Jacobian is
/// taken by central differences of the period map instead: `2 n` further integrations, with
/// steps of `1e-4 max(1, |x_j|)`, whose error is dominated by the integration error divided
/// by the step (about `1e-6` relative at the default tolerances).
pub fn period_map<S: HybridSystem>(
    sys: &S,
    mode0: S::Mode,
    t0: f64,
    x0: &[f64],
    period: f64,
    opts: &Options,
) -> Result<PeriodMap<S::Mode>, OrbitError> {
    if !(period.is_finite() && period > 0.0) {
        return Err(OrbitError::InvalidPeriod(period));
    }
    let n = sys.dim();
    let var = Variational::new(sys);
    let z0 = var.initial_state(x0);
    let traj = simulate(&var, mode0, t0, &z0, t0 + period, &[], opts)?;
    let jacobian = if traj.sliding.is_empty() {
        DMatrix::from_row_slice(n, n, &traj.final_state[n..])
    } else {
        difference_jacobian(sys, mode0, t0, x0, period, opts)?
    };
    let events = traj
        .events
        .into_iter()
        .map(|mut e| {
            e.state.truncate(n);
            e
        })
        .collect();
    Ok(PeriodMap {
        state: traj.final_state[..n].to_vec(),
        mode: traj.final_mode,
        jacobian,
        events,
        sliding: traj.sliding,
        stats: traj.stats,
    })
}

/// A Newton step that no longer lowers the periodicity residual ends the search when the
/// residual is within this many times `newton_tol` (round-off of the period map) ...
const STALL_TOL_FACTOR: f64 = 1e3;
/// ... or within this many times the integrator's `rtol` (where the adaptive step sizes change
/// with the start, the period map is only as smooth as the integrator's error: a residual of
/// 1.9e-9 at rtol 1e-8 on a stiff Hertz contact, where `newton_tol` asks for 1e-13).
const STALL_RTOL_FACTOR: f64 = 10.0;

/// Relative step of the central differences of the period map: large enough that the
/// integration error (about `rtol` relative) divided by the step stays near `1e-6`, small
/// enough that the truncation error (step squared) does too.
const PERIOD_MAP_FD_REL: f64 = 1e-4;

/// `DP(x)` by central differences of the period map of `sys` (without variational equations).
fn difference_jacobian<S: HybridSystem>(
    sys: &S,
    mode0: S::Mode,
    t0: f64,
    x0: &[f64],
    period: f64,
    opts: &Options,
) -> Result<DMatrix<f64>, OrbitError> {
    let n = x0.len();
    let mut jac = DMatrix::zeros(n, n);
    let mut x = x0.to_vec();
    for j in 0..n {
        let h = PERIOD_MAP_FD_REL * x0[j].abs().max(1.0);
        x[j] = x0[j] + h;
        let plus = simulate(sys, mode0, t0, &x, t0 + period, &[], opts)?.final_state;
        x[j] = x0[j] - h;
        let minus = simulate(sys, mode0, t0, &x, t0 + period, &[], opts)?.final_state;
        x[j] = x0[j];
        for i in 0..n {
            jac[(i, j)] = (plus[i] - minus[i]) / (2.0 * h);
        }
    }
    Ok(jac)
}

/// A stable periodic orbit of a clock-driven hybrid system.
#[derive(Debug, Clone)]
pub struct LimitCycle<M> {
    /// Its period (the forcing period).
    pub period: f64,
    /// The phase origin: `state0` is the state at times `t0 + j * period`.
    pub t0: f64,
    /// The state on the orbit at phase `t0`.
    pub state0: Vec<f64>,
    /// The chart at phase `t0`.
    pub mode0: M,
    /// The period-map Jacobian (monodromy matrix, saltations included) at `state0`.
    pub jacobian: DMatrix<f64>,
    /// Its eigenvalues, the Floquet multipliers, largest modulus first.
    pub multipliers: Vec<Complex64>,
    /// `|P(state0) - state0|_inf` after the last Newton step.
    pub residual: f64,
    /// The transitions over one period starting at `t0`.
    pub events: Vec<Event<M>>,
    /// The intervals spent sliding along a switching surface over one period starting at
    /// `t0` (empty for an orbit that only crosses its surfaces). The linearisation about an
    /// orbit with sliding is not implemented: `htfid-ltp` and `htfid-theory` refuse it.
    pub sliding: Vec<SlidingInterval<M>>,
    /// Newton iterations used.
    pub newton_iterations: usize,
    /// Integrator work of the final period map.
    pub stats: Stats,
}

/// Settles onto the forced periodic orbit by simulation, then refines it by Newton shooting on
/// the period map. The system must be `period`-periodic in time (inputs off).
///
/// # Errors
/// [`OrbitError::NoConvergence`] when Newton fails, [`OrbitError::NotStable`] when the orbit found
/// has a Floquet multiplier of modulus `>= 1 - stability_margin` (for example an undamped
/// oscillator), [`OrbitError::Integration`] when the integrator cannot proceed.
pub fn find_limit_cycle<S: HybridSystem>(
    sys: &S,
    mode0: S::Mode,
    t0: f64,
    x0: &[f64],
    period: f64,
    shooting: &ShootingOptions,
    opts: &Options,
) -> Result<LimitCycle<S::Mode>, OrbitError> {
    if !(period.is_finite() && period > 0.0) {
        return Err(OrbitError::InvalidPeriod(period));
    }
    shooting.validate()?;
    let n = sys.dim();
    let (mut x, mut mode) = (x0.to_vec(), mode0);
    if shooting.settle_periods > 0 {
        let t_end = t0 + period * shooting.settle_periods as f64;
        let traj = simulate(sys, mode0, t0, x0, t_end, &[], opts)?;
        x = traj.final_state;
        mode = traj.final_mode;
    }
    let mut iterations = 0;
    let mut residual;
    let stall = (STALL_TOL_FACTOR * shooting.newton_tol).max(STALL_RTOL_FACTOR * opts.rtol);
    let mut map = period_map(sys, mode, t0, &x, period, opts)?;
    if let [only] = map.sliding.as_slice() {
        // Sliding from the start to the end of the period: stuck for good.
        if only.start <= t0 && only.exit.is_none() {
            return Err(OrbitError::SlidesThroughout {
                guard: only.guard,
                period,
                start: t0,
                state: x,
            });
        }
    }
    loop {
        let r = DVector::from_iterator(n, (0..n).map(|i| map.state[i] - x[i]));
        residual = r.amax();
        let scale = x.iter().fold(1.0_f64, |a, v| a.max(v.abs()));
        if residual <= shooting.newton_tol * scale {
            break;
        }
        if iterations >= shooting.max_newton {
            return Err(OrbitError::NoConvergence {
                iterations,
                residual,
                tolerance: shooting.newton_tol * scale,
            });
        }
        let jm = &map.jacobian - DMatrix::identity(n, n);
        let delta = jm.lu().solve(&(-r)).ok_or(OrbitError::SingularJacobian)?;
        if delta.iter().any(|d| !d.is_finite()) {
            return Err(OrbitError::SingularJacobian);
        }
        for i in 0..n {
            x[i] += delta[i];
        }
        iterations += 1;
        let previous = residual;
        map = period_map(sys, mode, t0, &x, period, opts)?;
        // Newton on a piecewise-smooth map stalls at the period map's own error: round-off,
        // or the integrator's tolerance where the step sizes it chooses change with the start
        // (a stiff contact law). Accept once the correction no longer reduces the residual and
        // it is within that error.
        let new_res = (0..n)
            .map(|i| (map.state[i] - x[i]).abs())
            .fold(0.0, f64::max);
        if new_res >= previous && new_res <= stall * scale {
            residual = new_res;
            break;
        }
    }
    let mut multipliers: Vec<Complex64> = map
        .jacobian
        .complex_eigenvalues()
        .iter()
        .map(|c| Complex64::new(c.re, c.im))
        .collect();
    multipliers.sort_by(|a, b| b.norm().total_cmp(&a.norm()).then(b.im.total_cmp(&a.im)));
    let max_modulus = multipliers.first().map_or(0.0, |m| m.norm());
    if max_modulus >= 1.0 - shooting.stability_margin {
        return Err(OrbitError::NotStable {
            period,
            max_modulus,
            margin: shooting.stability_margin,
            multipliers,
        });
    }
    Ok(LimitCycle {
        period,
        t0,
        state0: x,
        mode0: mode,
        jacobian: map.jacobian,
        multipliers,
        residual,
        events: map.events,
        sliding: map.sliding,
        newton_iterations: iterations,
        stats: map.stats,
    })
}
