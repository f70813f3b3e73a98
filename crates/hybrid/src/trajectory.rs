use crate::{Crossing, HybridError, HybridSystem};

/// Work counters.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Accepted steps (a step cut short at an event counts once).
    pub steps: u64,
    /// Rejected step attempts.
    pub rejected: u64,
    /// Vector-field evaluations, including dense-output stages, the starting-step estimate and
    /// re-evaluations after events.
    pub rhs_evals: u64,
    /// Events reported (transitions and grazes).
    pub events: u64,
    /// Guard-function evaluations (samples, root finding, extremum refinement, derivative tests).
    pub guard_evals: u64,
}

/// What an [`Event`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EventKind {
    /// The guard crossed zero in its direction; the reset map was applied and the chart changed
    /// to `Event::to`.
    Transition,
    /// The guard came within `Options::graze_tol` of zero from its pre-crossing side and turned
    /// back without crossing. Reported only; no reset, `from == to`.
    Grazing,
    /// The guard, a switching surface ([`HybridSystem::sliding_chart`]), was reached and the
    /// field on its far side points back into it: the motion slides along the surface from
    /// here on. `from == to` is the chart the motion arrived in, which stays the current chart
    /// while sliding; `state` is on the surface.
    ///
    /// [`HybridSystem::sliding_chart`]: crate::HybridSystem::sliding_chart
    SlideStart,
    /// Sliding along the guard ended because the field of one side stopped pushing into the
    /// surface; the motion continues in `to` (either side's chart). For an exit forced by
    /// another guard of the chart, this event is followed by that guard's transition at the
    /// same time.
    SlideEnd,
}

/// One detected event.
#[derive(Debug, Clone)]
pub struct Event<M> {
    /// Event time (s). For a transition, the end of the final root bracket: the guard has
    /// already reached its post-crossing side here (within `Options::event_tol` of the root).
    /// For a graze, the located guard extremum.
    pub time: f64,
    /// Chart before the event.
    pub from: M,
    /// Chart after the event (equal to `from` for a graze).
    pub to: M,
    /// Index of the guard in chart `from`.
    pub guard: usize,
    /// State at `time` from the dense output, before the reset map.
    pub state: Vec<f64>,
    /// Transition or graze.
    pub kind: EventKind,
}

/// A time interval spent sliding along a switching surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlidingInterval<M> {
    /// Start (s): the time of the [`EventKind::SlideStart`] event.
    pub start: f64,
    /// End (s): the time of the [`EventKind::SlideEnd`] event, or the end of the simulation
    /// when it was still sliding then.
    pub end: f64,
    /// The surface: the guard index in chart `chart`.
    pub guard: usize,
    /// The chart the motion arrived in, reported as the current chart while sliding.
    pub chart: M,
    /// The chart the motion left into; `None` when it was still sliding at the end.
    pub exit: Option<M>,
}

impl<M> SlidingInterval<M> {
    /// Whether `t` lies in `[start, end)` (or is `start` for an interval of zero length).
    pub fn contains(&self, t: f64) -> bool {
        t >= self.start && (t < self.end || (self.end <= self.start && t <= self.start))
    }
}

/// Result of [`simulate`](crate::simulate).
#[derive(Debug, Clone)]
pub struct Trajectory<M> {
    /// State dimension.
    pub dim: usize,
    /// The requested output grid (s).
    pub times: Vec<f64>,
    /// Row-major `times.len() x dim` states on the grid. A grid time equal to a transition time
    /// holds the post-reset state.
    pub states: Vec<f64>,
    /// Chart at each grid time (post-transition at a transition time; while sliding, the chart
    /// the motion arrived in, see [`Trajectory::sliding`]).
    pub modes: Vec<M>,
    /// Every event, in time order.
    pub events: Vec<Event<M>>,
    /// Every interval spent sliding along a switching surface, in time order (from the
    /// [`EventKind::SlideStart`] and [`EventKind::SlideEnd`] events).
    pub sliding: Vec<SlidingInterval<M>>,
    /// `t_end` (s).
    pub final_time: f64,
    /// State at `t_end`.
    pub final_state: Vec<f64>,
    /// Chart at `t_end`.
    pub final_mode: M,
    /// Work counters.
    pub stats: Stats,
}

impl<M> Trajectory<M> {
    /// State at grid index `i`.
    ///
    /// # Panics
    /// If `i >= times.len()`.
    pub fn state(&self, i: usize) -> &[f64] {
        &self.states[i * self.dim..(i + 1) * self.dim]
    }

    /// Number of grid points.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// Whether the grid is empty.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// The sliding interval containing `t`, if any.
    pub fn sliding_at(&self, t: f64) -> Option<&SlidingInterval<M>> {
        self.sliding.iter().find(|s| s.contains(t))
    }

    /// Checks the invariant behind every chart label: at each grid time outside the sliding
    /// intervals, every guard of the chart lies on its pre-crossing side (a guard past zero
    /// would have fired), allowing `tol` (guard units) for grid times within the event
    /// tolerance of a crossing, where the guard sits on zero. Guards that fire in
    /// [`Crossing::Either`] direction mark no side and are not checked.
    ///
    /// A trajectory started in a chart its guards disagree with fails this check legitimately;
    /// for one started consistently, a failure means a crossing was passed through.
    ///
    /// # Errors
    /// [`HybridError::ChartMismatch`] at the first violation, with its time, chart guard and
    /// value.
    pub fn check_charts<S>(&self, sys: &S, tol: f64) -> Result<(), HybridError>
    where
        S: HybridSystem<Mode = M> + ?Sized,
        M: Copy + std::fmt::Debug,
    {
        for (i, (&t, &mode)) in self.times.iter().zip(&self.modes).enumerate() {
            if self.sliding_at(t).is_some() {
                continue;
            }
            let x = self.state(i);
            for g in 0..sys.num_guards(mode) {
                let value = sys.guard(mode, g, t, x);
                let wrong = match sys.guard_direction(mode, g) {
                    Crossing::Rising => value > tol,
                    Crossing::Falling => value < -tol,
                    Crossing::Either => false,
                };
                if wrong || !value.is_finite() {
                    return Err(HybridError::ChartMismatch {
                        time: t,
                        chart: format!("{mode:?}"),
                        guard: g,
                        value,
                        tol,
                    });
                }
            }
        }
        Ok(())
    }

    /// Transitions only (grazes and the starts and ends of sliding left out).
    pub fn transitions(&self) -> impl Iterator<Item = &Event<M>> {
        self.events
            .iter()
            .filter(|e| e.kind == EventKind::Transition)
    }

    /// Every switch of the motion: the transitions, and the ends of sliding that leave into
    /// the chart on the far side of the surface (a stuck mass that breaks loose upward after
    /// arriving from above switches there).
    pub fn switches(&self) -> impl Iterator<Item = &Event<M>>
    where
        M: PartialEq,
    {
        self.events.iter().filter(|e| {
            e.kind == EventKind::Transition || (e.kind == EventKind::SlideEnd && e.from != e.to)
        })
    }
}
