use thiserror::Error;

/// Everything that can go wrong while integrating a hybrid system.
///
/// Every variant carries the time (s) and the numbers that explain it.
#[non_exhaustive]
#[derive(Debug, Error)]
pub enum HybridError {
    /// The step-size controller asked for a step shorter than `Options::h_min` (or too short to
    /// advance `t` in floating point). Typical causes: finite-time blow-up, a discontinuity the
    /// model does not declare as a guard, or a stiff chart.
    #[error("step size {step:e} s fell below the minimum at t = {time} s")]
    StepSizeTooSmall {
        /// Time at which the step was attempted (s).
        time: f64,
        /// The rejected step size (s).
        step: f64,
    },
    /// More than `Options::max_steps` steps (accepted plus rejected) were attempted.
    #[error("{steps} steps attempted without reaching the end; stopped at t = {time} s")]
    MaxStepsExceeded {
        /// Time reached (s).
        time: f64,
        /// Steps attempted (accepted plus rejected).
        steps: u64,
    },
    /// The state or the vector field stopped being finite and shrinking the step did not help.
    #[error("state or vector field not finite at t = {time} s")]
    NonFiniteState {
        /// Time at which the non-finite value appeared (s).
        time: f64,
    },
    /// A guard function returned NaN or an infinity.
    #[error("guard {guard} returned a non-finite value ({value}) at t = {time} s")]
    NonFiniteGuard {
        /// Time of the evaluation (s).
        time: f64,
        /// Guard index in the current chart.
        guard: usize,
        /// The value returned.
        value: f64,
    },
    /// The events accumulate: more than `Options::zeno_max_events` transitions happened within
    /// `Options::zeno_window` seconds, or, right after a transition, a guard sitting on zero
    /// heads back toward its pre-crossing side by less than can be resolved (the accumulation
    /// point has been reached numerically, as for a bouncing ball whose bounces shrink below the
    /// event resolution).
    /// Sliding starts and ends along a switching surface count as transitions here, so a
    /// motion that keeps entering and leaving a surface (chattering) ends here too.
    #[error(
        "Zeno behaviour at t = {time} s: {events} transitions within the last {window} s \
         (the last through guard {guard}); the events accumulate and cannot be resolved"
    )]
    Zeno {
        /// Time of the transition that exceeded the cap or after which the guard stuck (s).
        time: f64,
        /// The guard of the last transition (index in the chart it left).
        guard: usize,
        /// Transitions within the window ending at `time`.
        events: usize,
        /// The window length (s).
        window: f64,
    },
    /// More transitions within one fixed step than the fixed-step integrator resolves: the
    /// motion chatters between charts (a sliding mode, or a step far too long).
    #[error("chattering at t = {time} s: {events} transitions within one fixed step")]
    Chattering {
        /// Time of the last transition (s).
        time: f64,
        /// Transitions within the step.
        events: usize,
    },
    /// A state vector does not have the system's dimension.
    #[error("state has dimension {found}, the system has dimension {expected}")]
    DimensionMismatch {
        /// `HybridSystem::dim`.
        expected: usize,
        /// Length of the vector supplied.
        found: usize,
    },
    /// An option is out of range.
    #[error("invalid option `{field}`: {reason}")]
    InvalidOptions {
        /// The field of `Options`.
        field: &'static str,
        /// What is wrong, including the offending value.
        reason: String,
    },
    /// The output grid is not non-decreasing or leaves `[t0, t_end]`.
    #[error("invalid output grid: {reason}")]
    InvalidGrid {
        /// What is wrong, including the offending index and value.
        reason: String,
    },
    /// The time span is not finite or runs backwards.
    #[error("invalid time span: t0 = {t0} s, t_end = {t_end} s (need finite t0 <= t_end)")]
    InvalidTimeSpan {
        /// Start time (s).
        t0: f64,
        /// End time (s).
        t_end: f64,
    },
    /// A trajectory's chart disagrees with the side of one of its guards
    /// ([`Trajectory::check_charts`](crate::Trajectory::check_charts)).
    #[error(
        "at t = {time} s the chart is {chart} but its guard {guard} is {value:e}, past zero by \
         more than {tol:e}: a crossing was not taken"
    )]
    ChartMismatch {
        /// Grid time (s).
        time: f64,
        /// The chart, as `Debug` prints it.
        chart: String,
        /// Guard index in that chart.
        guard: usize,
        /// The guard's value there.
        value: f64,
        /// The tolerance allowed.
        tol: f64,
    },
    /// The bracketing root finder did not reach `Options::event_tol`.
    #[error("event location did not converge near t = {time} s")]
    EventLocationFailed {
        /// Best estimate of the event time (s).
        time: f64,
    },
}
