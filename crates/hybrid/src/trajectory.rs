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
    /// Chart at each grid time (post-transition at a transition time).
    pub modes: Vec<M>,
    /// Every event, in time order.
    pub events: Vec<Event<M>>,
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

    /// Transitions only (grazes left out).
    pub fn transitions(&self) -> impl Iterator<Item = &Event<M>> {
        self.events
            .iter()
            .filter(|e| e.kind == EventKind::Transition)
    }
}
