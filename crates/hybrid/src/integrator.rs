use std::collections::VecDeque;
use std::fmt;

use crate::rk::{self, Work};
use crate::roots::{self, SQRT_EPS};
use crate::sliding::{self, Filippov};
use crate::{
    Crossing, Event, EventKind, HybridError, HybridSystem, Method, Options, SlidingInterval, Stats,
    Trajectory,
};

/// Why [`Integrator::step_until`] returned.
#[derive(Debug, Clone)]
pub enum StopReason<M> {
    /// One step was accepted and nothing happened in it.
    InternalStep,
    /// An event. Events found in one step are returned one per call, in time order, before
    /// the next step is taken; `event.time <= Integrator::t()`.
    Event(Event<M>),
    /// `t() == t_stop`.
    TStopReached,
}

/// Validity range of the dense output: the last accepted step `[t_old, t_old + h]`, cut at
/// `t_end` when an event ended it early.
#[derive(Debug, Clone, Copy)]
struct Dense {
    t_old: f64,
    h: f64,
    t_end: f64,
}

/// What refining a guard extremum found.
enum Refined {
    Nothing,
    Graze(f64),
    Crossing(f64),
}

/// Step-size controller constants of Hairer's codes.
struct Controller {
    safe: f64,
    /// Smallest and largest step ratio `h_new / h`.
    fac_min: f64,
    fac_max: f64,
    /// Lund stabilisation exponent.
    beta: f64,
    expo: f64,
}

impl Controller {
    fn for_method(method: Method) -> Self {
        match method {
            Method::Dopri5 => Controller {
                safe: 0.9,
                fac_min: 0.2,
                fac_max: 10.0,
                beta: 0.04,
                expo: 0.2 - 0.04 * 0.75,
            },
            Method::Dop853 => Controller {
                safe: 0.9,
                fac_min: 0.333,
                fac_max: 6.0,
                beta: 0.0,
                expo: 1.0 / 8.0,
            },
        }
    }
}

/// The stepping integrator that [`simulate`] is built on.
///
/// All buffers are allocated in [`Integrator::new`]; a step allocates only when it reports an
/// event (the event's state vector) or when a chart has more guards than any chart before it.
pub struct Integrator<'a, S: HybridSystem + ?Sized> {
    sys: &'a S,
    opts: Options,
    method: Method,
    ctrl: Controller,
    n: usize,
    mode: S::Mode,
    t: f64,
    x: Vec<f64>,
    /// Stages; row 0 is `f(t, x)`.
    k: Vec<f64>,
    xnew: Vec<f64>,
    ytmp: Vec<f64>,
    incr: Vec<f64>,
    acc: Vec<f64>,
    cont: Vec<f64>,
    dense: Option<Dense>,
    /// Proposed next step (before clipping to `t_stop`).
    h: f64,
    facold: f64,
    last_rejected: bool,
    /// Guard values at `t` in the current chart.
    g_start: Vec<f64>,
    /// Time derivatives of the guards at `t` where known, else NaN.
    d_start: Vec<f64>,
    /// Guard samples of the current step, `num_guards x (guard_samples + 2)`.
    gv: Vec<f64>,
    d_end: Vec<f64>,
    xs: Vec<f64>,
    /// Time of the last restart (initial time or transition) while no step has been accepted
    /// since.
    restart: Option<f64>,
    grazes: Vec<(f64, usize)>,
    pending: VecDeque<Event<S::Mode>>,
    recent: VecDeque<f64>,
    /// The sliding motion, while the state slides along a switching surface.
    slide: Option<Filippov<'a, S>>,
    stats: Stats,
}

impl<S: HybridSystem + ?Sized> fmt::Debug for Integrator<'_, S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Integrator")
            .field("method", &self.method)
            .field("t", &self.t)
            .field("mode", &self.mode)
            .field("state", &self.x)
            .field("h", &self.h)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

fn non_finite_guard(time: f64, guard: usize, value: f64) -> HybridError {
    HybridError::NonFiniteGuard { time, guard, value }
}

/// `Some(s)` when `g` lies strictly on a pre-crossing side of `dir`, `s` being that side's sign.
#[inline]
fn before_side(dir: Crossing, g: f64) -> Option<f64> {
    match dir {
        Crossing::Rising if g < 0.0 => Some(-1.0),
        Crossing::Falling if g > 0.0 => Some(1.0),
        Crossing::Either if g > 0.0 => Some(1.0),
        Crossing::Either if g < 0.0 => Some(-1.0),
        _ => None,
    }
}

impl<'a, S: HybridSystem + ?Sized> Integrator<'a, S> {
    /// Starts at `(t0, x0)` in chart `mode0`. Validates the options, the dimension and
    /// finiteness, evaluates `f(t0, x0)` and the guards, and picks the first step. On a
    /// declared switching surface ([`HybridSystem::sliding_chart`]) the start may take the
    /// chart of the state's side or start sliding at once (crate docs, "Sliding").
    pub fn new(
        sys: &'a S,
        mode0: S::Mode,
        t0: f64,
        x0: &[f64],
        opts: &Options,
    ) -> Result<Self, HybridError> {
        opts.validate()?;
        let n = sys.dim();
        if x0.len() != n {
            return Err(HybridError::DimensionMismatch {
                expected: n,
                found: x0.len(),
            });
        }
        if !t0.is_finite() {
            return Err(HybridError::InvalidTimeSpan { t0, t_end: t0 });
        }
        if x0.iter().any(|v| !v.is_finite()) {
            return Err(HybridError::NonFiniteState { time: t0 });
        }
        let method = opts.method;
        let mut integ = Integrator {
            sys,
            opts: opts.clone(),
            method,
            ctrl: Controller::for_method(method),
            n,
            mode: mode0,
            t: t0,
            x: x0.to_vec(),
            k: vec![0.0; rk::stage_rows(method) * n],
            xnew: vec![0.0; n],
            ytmp: vec![0.0; n],
            incr: vec![0.0; n],
            acc: vec![0.0; n],
            cont: vec![0.0; rk::dense_rows(method) * n],
            dense: None,
            h: 0.0,
            facold: 1e-4,
            last_rejected: false,
            g_start: Vec::new(),
            d_start: Vec::new(),
            gv: Vec::new(),
            d_end: Vec::new(),
            xs: vec![0.0; n],
            restart: None,
            grazes: Vec::with_capacity(8),
            pending: VecDeque::with_capacity(8),
            recent: VecDeque::with_capacity(opts.zeno_max_events + 2),
            slide: None,
            stats: Stats::default(),
        };
        integ.eval_f0()?;
        integ.h = match opts.h_init {
            Some(h) => h.min(opts.h_max),
            None => {
                let (head, tail) = integ.k.split_at_mut(n);
                let (h, evals) = rk::initial_step(
                    method,
                    sys,
                    mode0,
                    t0,
                    &integ.x,
                    head,
                    &mut integ.ytmp,
                    &mut tail[..n],
                    opts.rtol,
                    opts.atol,
                    opts.h_max,
                );
                integ.stats.rhs_evals += evals;
                h
            }
        };
        integ.restart_guards()?;
        integ.start_on_surfaces()?;
        Ok(integ)
    }

    /// Current time (s).
    pub fn t(&self) -> f64 {
        self.t
    }

    /// Current state (after the reset if the last step ended in a transition).
    pub fn state(&self) -> &[f64] {
        &self.x
    }

    /// Current chart.
    pub fn mode(&self) -> S::Mode {
        self.mode
    }

    /// Work counters so far.
    pub fn stats(&self) -> Stats {
        self.stats
    }

    /// While the state slides along a switching surface: the surface's guard index in the
    /// current chart, and the chart on its far side.
    pub fn sliding(&self) -> Option<(usize, S::Mode)> {
        self.slide.as_ref().map(|s| (s.guard, s.to))
    }

    /// The step size the controller proposes next (s).
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// Time range `[start, end]` covered by [`Integrator::interpolate`]: the last accepted step,
    /// cut at the event time when an event ended it. `None` before the first step.
    pub fn dense_range(&self) -> Option<(f64, f64)> {
        self.dense.map(|d| (d.t_old, d.t_end))
    }

    /// Dense output of the last accepted step at time `t` into `out` (the pre-reset trajectory
    /// when the step ended in a transition). Returns `false`, leaving `out` untouched, when `t`
    /// lies outside [`Integrator::dense_range`] or `out` has the wrong length.
    pub fn interpolate(&self, t: f64, out: &mut [f64]) -> bool {
        if out.len() != self.n {
            return false;
        }
        match self.dense {
            Some(d) if t >= d.t_old && t <= d.t_end => {
                rk::eval_dense(self.method, &self.cont, (t - d.t_old) / d.h, out);
                true
            }
            _ => false,
        }
    }

    fn eval_f0(&mut self) -> Result<(), HybridError> {
        let n = self.n;
        match &self.slide {
            None => self
                .sys
                .vector_field(self.mode, self.t, &self.x, &mut self.k[..n]),
            Some(fl) => fl.vector_field(self.mode, self.t, &self.x, &mut self.k[..n]),
        }
        self.stats.rhs_evals += 1;
        self.collect_sliding_counts();
        if self.k[..n].iter().any(|v| !v.is_finite()) {
            return Err(HybridError::NonFiniteState { time: self.t });
        }
        Ok(())
    }

    /// Finite-difference step for guard time derivatives: a small fraction of the step, but
    /// not more than that fraction of the time scale (the proposed step can be huge on
    /// polynomial flows) and not below the resolution of `t`.
    fn fd_delta(&self, h: f64) -> f64 {
        let scale = self.t.abs().max(1.0);
        (SQRT_EPS * h.abs().min(scale)).max(64.0 * f64::EPSILON * scale)
    }

    /// Evaluates the current chart's guards at a restart (initial time or after a transition),
    /// with their time derivatives along the flow by a forward difference.
    fn restart_guards(&mut self) -> Result<(), HybridError> {
        let ng = self.num_guards();
        self.g_start.clear();
        self.d_start.clear();
        let delta = self.fd_delta(self.h.min(self.opts.h_max));
        let n = self.n;
        for i in 0..n {
            self.xs[i] = self.x[i] + delta * self.k[i];
        }
        for i in 0..ng {
            let g0 = self.guard_at(i, self.t, &self.x);
            if !g0.is_finite() {
                return Err(non_finite_guard(self.t, i, g0));
            }
            let g1 = self.guard_at(i, self.t + delta, &self.xs);
            self.stats.guard_evals += 2;
            self.g_start.push(g0);
            self.d_start.push(if g1.is_finite() {
                (g1 - g0) / delta
            } else {
                f64::NAN
            });
        }
        self.restart = Some(self.t);
        self.collect_sliding_counts();
        Ok(())
    }

    /// Takes at most one step toward `t_stop`, never past it, and says why it returned.
    ///
    /// Pending events from the previous step are returned first, without stepping. A step is
    /// retried with smaller sizes until the error test passes; rejected attempts do not return.
    pub fn step_until(&mut self, t_stop: f64) -> Result<StopReason<S::Mode>, HybridError> {
        if let Some(ev) = self.pending.pop_front() {
            return Ok(StopReason::Event(ev));
        }
        if t_stop.is_nan() {
            return Err(HybridError::InvalidTimeSpan {
                t0: self.t,
                t_end: t_stop,
            });
        }
        if t_stop <= self.t {
            return Ok(StopReason::TStopReached);
        }
        let (t0, h, t1) = self.accept_step(t_stop)?;
        self.stats.steps += 1;
        self.stats.rhs_evals += match &self.slide {
            None => rk::build_dense(
                self.method,
                self.sys,
                self.mode,
                t0,
                h,
                &self.x,
                &self.xnew,
                &mut self.k,
                &mut self.ytmp,
                &mut self.acc,
                &mut self.cont,
            ),
            Some(fl) => rk::build_dense(
                self.method,
                fl,
                self.mode,
                t0,
                h,
                &self.x,
                &self.xnew,
                &mut self.k,
                &mut self.ytmp,
                &mut self.acc,
                &mut self.cont,
            ),
        };
        self.dense = Some(Dense {
            t_old: t0,
            h,
            t_end: t1,
        });

        self.grazes.clear();
        let transition = if self.g_start.is_empty() {
            None
        } else {
            self.detect(t0, t1)?
        };
        let t_cut = transition.map_or(f64::INFINITY, |(te, _)| te);
        self.grazes.retain(|&(tg, _)| tg < t_cut);
        self.grazes
            .sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        for idx in 0..self.grazes.len() {
            let (tg, guard) = self.grazes[idx];
            let state = self.dense_state(tg);
            let guard = self
                .slide
                .as_ref()
                .map_or(guard, |fl| fl.reported_guard(guard));
            self.pending.push_back(Event {
                time: tg,
                from: self.mode,
                to: self.mode,
                guard,
                state,
                kind: EventKind::Grazing,
            });
            self.stats.events += 1;
        }

        match transition {
            Some((te, guard)) => self.apply_transition(te, guard)?,
            None => {
                self.t = t1;
                std::mem::swap(&mut self.x, &mut self.xnew);
                let n = self.n;
                let fsal = rk::fsal_row(self.method) * n;
                self.k.copy_within(fsal..fsal + n, 0);
                let ns = self.opts.guard_samples + 2;
                for i in 0..self.g_start.len() {
                    self.g_start[i] = self.gv[i * ns + ns - 1];
                    self.d_start[i] = self.d_end[i];
                }
                self.restart = None;
            }
        }

        self.collect_sliding_counts();
        Ok(match self.pending.pop_front() {
            Some(ev) => StopReason::Event(ev),
            None if self.t >= t_stop => StopReason::TStopReached,
            None => StopReason::InternalStep,
        })
    }

    fn dense_state(&mut self, t: f64) -> Vec<f64> {
        let mut out = vec![0.0; self.n];
        if let Some(d) = self.dense {
            rk::eval_dense(self.method, &self.cont, (t - d.t_old) / d.h, &mut out);
        }
        out
    }

    /// Runs trial steps until one passes the error test; leaves the new state in `xnew` and
    /// returns `(t0, h, t1)`.
    fn accept_step(&mut self, t_stop: f64) -> Result<(f64, f64, f64), HybridError> {
        loop {
            let attempts = self.stats.steps + self.stats.rejected;
            if attempts >= self.opts.max_steps {
                return Err(HybridError::MaxStepsExceeded {
                    time: self.t,
                    steps: attempts,
                });
            }
            let h_ctrl = self.h.min(self.opts.h_max);
            if h_ctrl < self.opts.h_min || self.t + h_ctrl <= self.t {
                return Err(HybridError::StepSizeTooSmall {
                    time: self.t,
                    step: h_ctrl,
                });
            }
            let remaining = t_stop - self.t;
            // Stretch a step by up to 1 % (even past h_max) rather than leave a sliver before
            // t_stop, as Hairer's codes do.
            let (h, t1) = if remaining <= 1.01 * h_ctrl {
                (remaining, t_stop)
            } else {
                (h_ctrl, self.t + h_ctrl)
            };
            let mut work = Work {
                k: &mut self.k,
                ynew: &mut self.xnew,
                ytmp: &mut self.ytmp,
                incr: &mut self.incr,
                acc: &mut self.acc,
            };
            let (err, evals) = match &self.slide {
                None => rk::trial_step(
                    self.method,
                    self.sys,
                    self.mode,
                    self.t,
                    h,
                    &self.x,
                    &mut work,
                    self.opts.rtol,
                    self.opts.atol,
                ),
                Some(fl) => rk::trial_step(
                    self.method,
                    fl,
                    self.mode,
                    self.t,
                    h,
                    &self.x,
                    &mut work,
                    self.opts.rtol,
                    self.opts.atol,
                ),
            };
            self.stats.rhs_evals += evals;
            let c = &self.ctrl;
            let fac11 = match self.method {
                // err^(1/8) without the cost of powf.
                Method::Dop853 => err.sqrt().sqrt().sqrt(),
                Method::Dopri5 => err.powf(c.expo),
            };
            if err <= 1.0 {
                let fac = if c.beta > 0.0 {
                    fac11 / self.facold.powf(c.beta)
                } else {
                    fac11
                };
                let fac = (fac / c.safe).clamp(1.0 / c.fac_max, 1.0 / c.fac_min);
                let mut h_new = h / fac;
                self.facold = err.max(1e-4);
                if self.last_rejected {
                    h_new = h_new.min(h);
                }
                self.last_rejected = false;
                if h < h_ctrl {
                    // Shortened to land on t_stop: the error of the short step says nothing
                    // against the step the controller wanted.
                    h_new = h_new.max(h_ctrl);
                }
                // Error-free steps (polynomial flows) grow h sixfold each time; keep it finite.
                self.h = h_new.min(self.opts.h_max).min(f64::MAX);
                return Ok((self.t, h, t1));
            }
            self.stats.rejected += 1;
            self.last_rejected = true;
            self.h = h / (1.0 / c.fac_min).min(fac11 / c.safe);
            if !err.is_finite() && self.h < self.opts.h_min {
                return Err(HybridError::NonFiniteState { time: self.t });
            }
        }
    }

    /// Guard value at `t` inside the last step, from the dense output.
    fn guard_dense(&mut self, guard: usize, t: f64) -> Result<f64, HybridError> {
        let d = self
            .dense
            .expect("dense output exists during event detection");
        rk::eval_dense(self.method, &self.cont, (t - d.t_old) / d.h, &mut self.xs);
        let g = self.guard_at(guard, t, &self.xs);
        self.stats.guard_evals += 1;
        if g.is_finite() {
            Ok(g)
        } else {
            Err(non_finite_guard(t, guard, g))
        }
    }

    /// Samples every guard over the accepted step `[t0, t1]` and returns the first transition
    /// `(time, guard)`, lowest guard index first on ties. Grazes go to `self.grazes`.
    fn detect(&mut self, t0: f64, t1: f64) -> Result<Option<(f64, usize)>, HybridError> {
        let ng = self.g_start.len();
        let m = self.opts.guard_samples;
        let ns = m + 2;
        if self.gv.len() < ng * ns {
            self.gv.resize(ng * ns, 0.0);
        }
        if self.d_end.len() != ng {
            self.d_end.resize(ng, f64::NAN);
        }
        self.d_end.fill(f64::NAN);
        for i in 0..ng {
            self.gv[i * ns] = self.g_start[i];
        }
        let h = t1 - t0;
        let d = self
            .dense
            .expect("dense output exists during event detection");
        for j in 1..=m {
            let tau = t0 + h * (j as f64 / (m + 1) as f64);
            rk::eval_dense(self.method, &self.cont, (tau - d.t_old) / d.h, &mut self.xs);
            for i in 0..ng {
                let g = self.guard_at(i, tau, &self.xs);
                if !g.is_finite() {
                    return Err(non_finite_guard(tau, i, g));
                }
                self.gv[i * ns + j] = g;
            }
        }
        for i in 0..ng {
            let g = self.guard_at(i, t1, &self.xnew);
            if !g.is_finite() {
                return Err(non_finite_guard(t1, i, g));
            }
            self.gv[i * ns + ns - 1] = g;
        }
        self.stats.guard_evals += (ng * (m + 1)) as u64;

        let mut best: Option<(f64, usize)> = None;
        for i in 0..ng {
            if let Some(te) = self.scan_guard(i, t0, t1, ns)? {
                if best.map_or(true, |(tb, _)| te < tb) {
                    best = Some((te, i));
                }
            }
        }
        Ok(best)
    }

    /// Whether a located transition must be ignored: it lies within `event_tol` after a restart,
    /// i.e. the guard is only leaving the zero it sat on.
    /// While sliding, the exit conditions (guards 0 and 1) start strictly positive, so an
    /// early crossing of theirs is a genuine exit and never suppressed.
    fn suppressed(&self, i: usize, te: f64) -> bool {
        self.restart
            .is_some_and(|tr| te <= tr + self.opts.event_tol)
            && !(self.slide.is_some() && i < 2)
    }

    /// The first transition of guard `i` within the step, if any.
    fn scan_guard(
        &mut self,
        i: usize,
        t0: f64,
        t1: f64,
        ns: usize,
    ) -> Result<Option<f64>, HybridError> {
        let dir = self.direction(i);
        let base = i * ns;
        let graze_tol = self.opts.graze_tol;
        let tau = |j: usize| {
            if j == ns - 1 {
                t1
            } else {
                t0 + (t1 - t0) * (j as f64 / (ns - 1) as f64)
            }
        };

        // Right after a restart a guard may sit on zero (or just past it) and head back into
        // its pre-crossing side; if the next sample is already past zero again, the guard left
        // and returned within the first sample interval (a bounce shorter than the sample
        // spacing). Look for a point on the pre-crossing side, then bracket the return.
        if self.restart.is_some() {
            let (g0, g1, d0) = (self.gv[base], self.gv[base + 1], self.d_start[i]);
            if before_side(dir, g0).is_none() && d0.is_finite() {
                if let Some(s) = before_side(dir, d0) {
                    if s * g1 <= 0.0 {
                        match self.find_excursion(i, tau(0), tau(1), s)? {
                            Some((tp, gp)) => {
                                // The guard was seen strictly on its pre-crossing side, so the
                                // return is a genuine crossing even if it follows the restart
                                // within event_tol (a Zeno accumulation, which the Zeno cap
                                // catches); suppressing it would let the state slip through.
                                return Ok(Some(self.locate(i, tp, gp, tau(1), g1)?));
                            }
                            None if g0.abs() <= self.opts.graze_tol
                                && self.recent.back().is_some_and(|&te| te >= t0) =>
                            {
                                // Just after a transition the guard sits on zero and heads back
                                // toward its pre-crossing side, but the excursion is too small
                                // to resolve: the events have accumulated (a bouncing ball
                                // whose bounce height fell below the event resolution).
                                // Continuing would let the state slip through the guard.
                                return Err(HybridError::Zeno {
                                    time: t0,
                                    guard: self.slide.as_ref().map_or(i, |fl| fl.reported_guard(i)),
                                    events: self.recent.len(),
                                    window: self.opts.zeno_window,
                                });
                            }
                            None => {}
                        }
                    }
                }
            }
        }

        for j in 0..ns - 1 {
            let (a, b) = (self.gv[base + j], self.gv[base + j + 1]);
            // The three extremum tests below refine only dips that could reach within
            // graze_tol of zero: with `u = s g` and the quadratic through the two samples and the
            // slope (or the three samples), the dip below the closest sample is at most its
            // quadratic coefficient, so a closest sample farther from zero than that coefficient
            // (plus graze_tol) marks a shallow turn far from the guard surface.
            // Extremum near the start: approaching zero at t0 but farther away at the first
            // sample, so the closest approach lies inside the first interval.
            if j == 0 {
                let d0 = self.d_start[i];
                if let Some(s) = before_side(dir, a) {
                    let slope = -s * d0 * (tau(1) - tau(0));
                    if d0.is_finite()
                        && slope > 0.0
                        && s * b > s * a
                        && s * a <= (s * b - s * a) + slope + graze_tol
                    {
                        if let Some(te) = self.refine_outcome(i, tau(0), a, tau(1), None, s)? {
                            return Ok(Some(te));
                        }
                    }
                }
            }
            // Interior discrete minimum of |g| on the pre-crossing side.
            if j >= 1 {
                if let Some(s) = before_side(dir, a) {
                    let prev = self.gv[base + j - 1];
                    let curvature = s * prev - 2.0 * s * a + s * b;
                    if s * prev > s * a && s * b >= s * a && s * a <= curvature + graze_tol {
                        let centre = Some(s * a);
                        if let Some(te) =
                            self.refine_outcome(i, tau(j - 1), prev, tau(j + 1), centre, s)?
                        {
                            return Ok(Some(te));
                        }
                    }
                }
            }
            // Extremum near the end: still approaching at the last sample but receding at t1
            // (derivative by a backward difference along the flow).
            if j == ns - 2 {
                if let Some(s) = before_side(dir, b) {
                    if s * a > s * b {
                        let d1 = self.end_derivative(i, t1, b)?;
                        self.d_end[i] = d1;
                        let slope = s * d1 * (t1 - tau(j));
                        if slope >= 0.0 && s * b <= (s * a - s * b) + slope + graze_tol {
                            if let Some(te) = self.refine_outcome(i, tau(j), a, t1, None, s)? {
                                return Ok(Some(te));
                            }
                        }
                    }
                }
            }
            if dir.accepts(a, b) {
                let te = self.locate(i, tau(j), a, tau(j + 1), b)?;
                if !self.suppressed(i, te) {
                    return Ok(Some(te));
                }
            }
        }
        Ok(None)
    }

    /// A point in `(lo, hi)` where `s * g > 0`, for a guard that starts at (or just past) zero
    /// at `lo` heading to side `s` and is back past zero at `hi`. Probes `lo + 2^-k (hi - lo)`
    /// first, which finds any single excursion that starts at `lo` whatever its length, down to
    /// the resolution of `t`; then Brent's method on `-s g` for an excursion that starts later.
    fn find_excursion(
        &mut self,
        i: usize,
        lo: f64,
        hi: f64,
        s: f64,
    ) -> Result<Option<(f64, f64)>, HybridError> {
        let width = hi - lo;
        let mut frac = 0.5;
        for _ in 0..64 {
            let t = lo + frac * width;
            if t <= lo {
                break;
            }
            let g = self.guard_dense(i, t)?;
            if s * g > 0.0 {
                return Ok(Some((t, g)));
            }
            frac *= 0.5;
        }
        let tol = (self.opts.event_tol / width).max(1e-15);
        let mut f = |theta: f64| {
            let t = lo + theta * width;
            self.guard_dense(i, t).map(|g| -s * g)
        };
        let found = roots::minimize(&mut f, roots::GOLDEN_START, None, tol, -f64::MIN_POSITIVE)?;
        Ok(found.stopped.then(|| (lo + found.x * width, -s * found.fx)))
    }

    /// Refines an extremum of guard `i` in `[lo, hi]` on side `s` (`g(lo) = g_lo`) and turns the
    /// result into a transition time, a recorded graze, or nothing.
    fn refine_outcome(
        &mut self,
        i: usize,
        lo: f64,
        g_lo: f64,
        hi: f64,
        centre: Option<f64>,
        s: f64,
    ) -> Result<Option<f64>, HybridError> {
        match self.refine(i, lo, g_lo, hi, centre, s)? {
            Refined::Crossing(te) if !self.suppressed(i, te) => Ok(Some(te)),
            Refined::Graze(tg) => {
                self.grazes.push((tg, i));
                Ok(None)
            }
            _ => Ok(None),
        }
    }

    /// Minimises `s * g` over `[lo, hi]`. A value at or below zero reveals a pair of crossings
    /// between samples; the first is bracketed in `[lo, t]` and located. A positive minimum
    /// within `graze_tol` is a graze.
    fn refine(
        &mut self,
        i: usize,
        lo: f64,
        g_lo: f64,
        hi: f64,
        centre: Option<f64>,
        s: f64,
    ) -> Result<Refined, HybridError> {
        let width = hi - lo;
        if width <= 0.0 {
            return Ok(Refined::Nothing);
        }
        let tol = (self.opts.event_tol / width).max(1e-15);
        let (x0, fx0) = match centre {
            Some(v) => (0.5, Some(v)),
            None => (roots::GOLDEN_START, None),
        };
        let mut f = |theta: f64| {
            let t = lo + theta * width;
            self.guard_dense(i, t).map(|g| s * g)
        };
        let found = roots::minimize(&mut f, x0, fx0, tol, 0.0)?;
        let t = lo + found.x * width;
        if found.stopped {
            let te = self.locate(i, lo, g_lo, t, s * found.fx)?;
            Ok(Refined::Crossing(te))
        } else if found.fx <= self.opts.graze_tol {
            Ok(Refined::Graze(t))
        } else {
            Ok(Refined::Nothing)
        }
    }

    /// Time derivative of guard `i` at the step end by a backward difference along the flow.
    fn end_derivative(&mut self, i: usize, t1: f64, g1: f64) -> Result<f64, HybridError> {
        let n = self.n;
        let fsal = rk::fsal_row(self.method) * n;
        let d = self
            .dense
            .expect("dense output exists during event detection");
        let delta = self.fd_delta(d.h);
        for c in 0..n {
            self.xs[c] = self.xnew[c] - delta * self.k[fsal + c];
        }
        let gb = self.guard_at(i, t1 - delta, &self.xs);
        self.stats.guard_evals += 1;
        if !gb.is_finite() {
            return Err(non_finite_guard(t1 - delta, i, gb));
        }
        Ok((g1 - gb) / delta)
    }

    fn locate(&mut self, i: usize, a: f64, ga: f64, b: f64, gb: f64) -> Result<f64, HybridError> {
        let tol = self.opts.event_tol;
        let mut g = |t: f64| self.guard_dense(i, t);
        roots::locate_root(&mut g, a, ga, b, gb, tol)
    }

    /// Guards of the current chart (the exit conditions and the other guards while sliding).
    #[inline]
    fn num_guards(&self) -> usize {
        match &self.slide {
            None => self.sys.num_guards(self.mode),
            Some(fl) => fl.num_guards(self.mode),
        }
    }

    #[inline]
    fn guard_at(&self, i: usize, t: f64, x: &[f64]) -> f64 {
        match &self.slide {
            None => self.sys.guard(self.mode, i, t, x),
            Some(fl) => fl.guard(self.mode, i, t, x),
        }
    }

    #[inline]
    fn direction(&self, i: usize) -> Crossing {
        match &self.slide {
            None => self.sys.guard_direction(self.mode, i),
            Some(fl) => fl.guard_direction(self.mode, i),
        }
    }

    /// Adds the evaluations made inside the sliding field's trait calls to the counters.
    fn collect_sliding_counts(&mut self) {
        if let Some(fl) = &self.slide {
            self.stats.rhs_evals += fl.rhs_evals.take();
            self.stats.guard_evals += fl.guard_evals.take();
        }
    }

    /// Logs a transition time for the Zeno test and fails when the cap is exceeded.
    fn count_transition(&mut self, te: f64, guard: usize) -> Result<(), HybridError> {
        while self
            .recent
            .front()
            .is_some_and(|&tr| tr < te - self.opts.zeno_window)
        {
            self.recent.pop_front();
        }
        self.recent.push_back(te);
        if self.recent.len() > self.opts.zeno_max_events {
            return Err(HybridError::Zeno {
                time: te,
                guard,
                events: self.recent.len(),
                window: self.opts.zeno_window,
            });
        }
        Ok(())
    }

    /// Ends the step at `te` where guard `guard` fired: a transition (the reset is applied
    /// and the integration restarts in the new chart), the start of sliding along a switching
    /// surface, or, while sliding, its end.
    fn apply_transition(&mut self, te: f64, guard: usize) -> Result<(), HybridError> {
        if self.slide.is_some() {
            return self.end_slide(te, guard);
        }
        self.count_transition(te, guard)?;
        let state = self.dense_state(te);
        if let Some(to) = self.sys.sliding_chart(self.mode, guard) {
            if self.try_slide(te, guard, to, &state, None)? {
                return Ok(());
            }
        }
        self.transition_at(te, guard, state)
    }

    /// Applies the reset of `guard` to `state` (the pre-event state at `te`), restarts in the
    /// new chart and logs the event.
    fn transition_at(&mut self, te: f64, guard: usize, state: Vec<f64>) -> Result<(), HybridError> {
        self.x.copy_from_slice(&state);
        let from = self.mode;
        let to = self.sys.transition(from, guard, te, &mut self.x);
        if let Some(d) = self.dense.as_mut() {
            d.t_end = te;
        }
        self.t = te;
        self.mode = to;
        if self.x.iter().any(|v| !v.is_finite()) {
            return Err(HybridError::NonFiniteState { time: te });
        }
        // No FSAL across an event: the vector field may change with the chart and the reset.
        self.eval_f0()?;
        self.restart_guards()?;
        self.pending.push_back(Event {
            time: te,
            from,
            to,
            guard,
            state,
            kind: EventKind::Transition,
        });
        self.stats.events += 1;
        Ok(())
    }

    /// At a crossing of switching surface `guard` toward chart `to` at `(te, state)`: starts
    /// sliding if the field of `to` points back into the surface (the normal speeds `a` of
    /// the current chart and `b` of `to` have opposite signs), after moving the state onto the
    /// surface. With `pre = Some(p)` (a start on the surface), the current chart's field must
    /// also head away from its own side `p`, else the surface repels and nothing slides.
    /// Returns whether it started sliding.
    fn try_slide(
        &mut self,
        te: f64,
        guard: usize,
        to: S::Mode,
        state: &[f64],
        pre: Option<f64>,
    ) -> Result<bool, HybridError> {
        let n = self.n;
        let mut x = state.to_vec();
        let (mut grad, mut xs) = (vec![0.0; n], vec![0.0; n]);
        self.stats.guard_evals +=
            sliding::project(self.sys, self.mode, guard, te, &mut x, &mut grad, &mut xs);
        let fl = Filippov::new(self.sys, self.mode, to, guard, 1.0);
        let (a, b) = fl.speeds(te, &x);
        self.stats.rhs_evals += fl.rhs_evals.take();
        self.stats.guard_evals += fl.guard_evals.take();
        if !(a.is_finite() && b.is_finite()) {
            return Err(non_finite_guard(
                te,
                guard,
                if a.is_finite() { b } else { a },
            ));
        }
        if a * b >= 0.0 || pre.is_some_and(|p| p * a >= 0.0) {
            return Ok(false);
        }
        if let Some(d) = self.dense.as_mut() {
            d.t_end = te;
        }
        self.t = te;
        self.x.copy_from_slice(&x);
        self.slide = Some(Filippov::new(self.sys, self.mode, to, guard, a.signum()));
        self.eval_f0()?;
        self.restart_guards()?;
        self.pending.push_back(Event {
            time: te,
            from: self.mode,
            to: self.mode,
            guard,
            state: x,
            kind: EventKind::SlideStart,
        });
        self.stats.events += 1;
        Ok(true)
    }

    /// Ends sliding at `te` because wrapper guard `k` fired: 0 leaves into the chart the
    /// motion arrived in, 1 into the chart on the far side, `k >= 2` is another guard of the
    /// arrival chart, whose transition follows at once.
    fn end_slide(&mut self, te: f64, k: usize) -> Result<(), HybridError> {
        let Some(fl) = self.slide.take() else {
            return Ok(());
        };
        self.stats.rhs_evals += fl.rhs_evals.take();
        self.stats.guard_evals += fl.guard_evals.take();
        self.count_transition(te, fl.guard)?;
        let state = self.dense_state(te);
        let exit = if k == 1 { fl.to } else { fl.from };
        debug_assert!(
            {
                let g = self.sys.guard(fl.from, fl.guard, te, &state);
                let scale = state.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
                g.abs() <= 1e-6 * scale
            },
            "sliding drifted off the surface of guard {} by t = {te}",
            fl.guard
        );
        self.pending.push_back(Event {
            time: te,
            from: fl.from,
            to: exit,
            guard: fl.guard,
            state: state.clone(),
            kind: EventKind::SlideEnd,
        });
        self.stats.events += 1;
        self.mode = exit;
        if k >= 2 {
            return self.transition_at(te, fl.inner_guard(k), state);
        }
        if let Some(d) = self.dense.as_mut() {
            d.t_end = te;
        }
        self.t = te;
        self.x.copy_from_slice(&state);
        self.eval_f0()?;
        self.restart_guards()
    }

    /// At the initial time, for every switching surface of the current chart: a state on the
    /// far side of it belongs to the chart there (the chart of a state is its side of the
    /// surface). A state on it (within `graze_tol`) whose chart's field heads to the far side
    /// starts sliding if the far side's field points back, and otherwise starts in the far
    /// side's chart, where both fields carry it.
    fn start_on_surfaces(&mut self) -> Result<(), HybridError> {
        // At most two passes: a chart change can put the state on a surface of the new chart.
        for _ in 0..2 {
            let ng = self.g_start.len();
            let mut changed = false;
            for i in 0..ng {
                let Some(to) = self.sys.sliding_chart(self.mode, i) else {
                    continue;
                };
                let g = self.g_start[i];
                let dir = self.sys.guard_direction(self.mode, i);
                if dir == Crossing::Either {
                    // Neither side is marked as this chart's, so neither test applies.
                    continue;
                }
                let pre = if dir == Crossing::Rising { -1.0 } else { 1.0 };
                if g.abs() <= self.opts.graze_tol {
                    let x = self.x.clone();
                    if self.try_slide(self.t, i, to, &x, Some(pre))? {
                        // The slide starts at t0: its event is reported like any other.
                        return Ok(());
                    }
                    let fl = Filippov::new(self.sys, self.mode, to, i, 1.0);
                    let (a, b) = fl.speeds(self.t, &x);
                    self.stats.rhs_evals += fl.rhs_evals.take();
                    self.stats.guard_evals += fl.guard_evals.take();
                    if !(pre * a < 0.0 && pre * b < 0.0) {
                        continue;
                    }
                } else if before_side(dir, g).is_some() {
                    continue;
                }
                self.mode = to;
                self.eval_f0()?;
                self.restart_guards()?;
                changed = true;
                break;
            }
            if !changed {
                break;
            }
        }
        Ok(())
    }
}

/// Integrates from `(t0, x0, mode0)` to `t_end` and samples the dense output on `grid`
/// (non-decreasing, inside `[t0, t_end]`). Grid times equal to a transition time get the
/// post-reset state and chart.
pub fn simulate<S: HybridSystem + ?Sized>(
    sys: &S,
    mode0: S::Mode,
    t0: f64,
    x0: &[f64],
    t_end: f64,
    grid: &[f64],
    opts: &Options,
) -> Result<Trajectory<S::Mode>, HybridError> {
    if !(t0.is_finite() && t_end.is_finite() && t0 <= t_end) {
        return Err(HybridError::InvalidTimeSpan { t0, t_end });
    }
    for (i, &g) in grid.iter().enumerate() {
        if !(g >= t0 && g <= t_end) {
            return Err(HybridError::InvalidGrid {
                reason: format!("grid[{i}] = {g} lies outside [t0, t_end] = [{t0}, {t_end}]"),
            });
        }
        if i > 0 && g < grid[i - 1] {
            return Err(HybridError::InvalidGrid {
                reason: format!(
                    "grid must be non-decreasing, but grid[{i}] = {g} < grid[{}] = {}",
                    i - 1,
                    grid[i - 1]
                ),
            });
        }
    }
    let mut integ = Integrator::new(sys, mode0, t0, x0, opts)?;
    let n = sys.dim();
    let mut states = Vec::with_capacity(grid.len() * n);
    let mut modes = Vec::with_capacity(grid.len());
    let mut events = Vec::new();
    let mut sliding: Vec<SlidingInterval<S::Mode>> = Vec::new();
    let mut buf = vec![0.0; n];
    let mut gi = 0;
    // The start may have moved to the chart of the state's side of a switching surface
    // (and onto it): record what the integrator starts from.
    while gi < grid.len() && grid[gi] <= t0 {
        states.extend_from_slice(integ.state());
        modes.push(integ.mode());
        gi += 1;
    }
    loop {
        let mode_before = integ.mode();
        let reason = integ.step_until(t_end)?;
        let t_now = integ.t();
        while gi < grid.len() && grid[gi] < t_now {
            if !integ.interpolate(grid[gi], &mut buf) {
                // Every grid time below t_now and above the previous step end lies in the last
                // step, so this is unreachable; fall back to the current state rather than panic.
                buf.copy_from_slice(integ.state());
            }
            states.extend_from_slice(&buf);
            modes.push(mode_before);
            gi += 1;
        }
        while gi < grid.len() && grid[gi] <= t_now {
            states.extend_from_slice(integ.state());
            modes.push(integ.mode());
            gi += 1;
        }
        match reason {
            StopReason::Event(e) => {
                match e.kind {
                    EventKind::SlideStart => sliding.push(SlidingInterval {
                        start: e.time,
                        end: e.time,
                        guard: e.guard,
                        chart: e.from,
                        exit: None,
                    }),
                    EventKind::SlideEnd => {
                        if let Some(last) = sliding.last_mut() {
                            last.end = e.time;
                            last.exit = Some(e.to);
                        }
                    }
                    _ => {}
                }
                events.push(e);
            }
            StopReason::TStopReached => break,
            StopReason::InternalStep => {}
        }
    }
    if let Some(last) = sliding.last_mut() {
        if last.exit.is_none() {
            last.end = integ.t();
        }
    }
    Ok(Trajectory {
        dim: n,
        times: grid.to_vec(),
        states,
        modes,
        events,
        sliding,
        final_time: integ.t(),
        final_state: integ.state().to_vec(),
        final_mode: integ.mode(),
        stats: integ.stats(),
    })
}
