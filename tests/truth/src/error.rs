//! The crate's one error type.
//!
//! `thiserror` is not among this crate's allowed dependencies, so `Display` is written by hand.

use std::fmt;
use std::path::PathBuf;

/// Everything that can go wrong while checking a scenario, simulating it or writing a record.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// A scenario parameter is outside its allowed range.
    InvalidParameter {
        /// Dotted name, e.g. `effects[2].k3` or `parameter_errors.k`.
        name: String,
        /// What the value must satisfy, e.g. `> 0`.
        requirement: &'static str,
        /// The value found.
        value: f64,
    },
    /// The same effect is listed twice, or two effects that define the same force are combined.
    ConflictingEffects {
        /// The effect names involved.
        first: &'static str,
        /// The second name (equal to `first` for a duplicate).
        second: &'static str,
    },
    /// A sample rate other than 50, 100, 200 or 1000 Hz.
    UnsupportedSampleRate {
        /// The rate asked for, Hz.
        hz: u32,
    },
    /// The adaptive step fell below the smallest allowed step.
    StepSizeTooSmall {
        /// Simulation time at which it happened, s.
        time: f64,
        /// The step that was rejected, s.
        step: f64,
    },
    /// No combination of discrete modes is consistent with the state (a broken Filippov case).
    NoConsistentMode {
        /// Simulation time, s.
        time: f64,
        /// Position and velocity at that time.
        x: f64,
        /// Velocity, m/s.
        v: f64,
    },
    /// The state became non-finite or ran away (an unstable true system, e.g. strongly
    /// softening cubic stiffness).
    Diverged {
        /// Simulation time, s.
        time: f64,
    },
    /// Events kept firing at one instant without time advancing (Zeno or chattering).
    EventStorm {
        /// Simulation time, s.
        time: f64,
        /// Events counted at that instant.
        count: usize,
    },
    /// Reading or writing a file failed.
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// Encoding the manifest failed.
    Json(serde_json::Error),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::InvalidParameter {
                name,
                requirement,
                value,
            } => write!(f, "{name} must be {requirement} (got {value})"),
            Error::ConflictingEffects { first, second } if first == second => {
                write!(f, "effect {first} is listed twice")
            }
            Error::ConflictingEffects { first, second } => {
                write!(f, "effects {first} and {second} cannot be combined")
            }
            Error::UnsupportedSampleRate { hz } => write!(
                f,
                "sample rate must be one of 50, 100, 200, 1000 Hz (got {hz})"
            ),
            Error::StepSizeTooSmall { time, step } => {
                write!(f, "step size {step:e} s too small at t = {time} s")
            }
            Error::NoConsistentMode { time, x, v } => write!(
                f,
                "no consistent discrete mode at t = {time} s (x = {x} m, v = {v} m/s)"
            ),
            Error::Diverged { time } => {
                write!(f, "the true system diverged at t = {time} s")
            }
            Error::EventStorm { time, count } => {
                write!(f, "{count} events at t = {time} s without time advancing")
            }
            Error::Io { path, source } => write!(f, "{}: {source}", path.display()),
            Error::Json(e) => write!(f, "manifest encoding failed: {e}"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io { source, .. } => Some(source),
            Error::Json(e) => Some(e),
            _ => None,
        }
    }
}
