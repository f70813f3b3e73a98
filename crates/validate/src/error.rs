//! Errors of the validation computations.

/// Why a validation quantity cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Two series that must be sampled at the same instants differ in length.
    #[error("series lengths differ: {expected} against {found}")]
    LengthMismatch {
        /// Length of the first series.
        expected: usize,
        /// Length of the second series.
        found: usize,
    },
    /// Too few samples for the lags asked for.
    #[error("{found} samples are too few for {lags} lags (need at least {min})")]
    TooShort {
        /// Samples needed.
        min: usize,
        /// Samples given.
        found: usize,
        /// Largest lag asked for.
        lags: usize,
    },
    /// A sample is NaN or infinite.
    #[error("sample {index} is not finite ({value})")]
    NotFinite {
        /// Index of the first non-finite sample.
        index: usize,
        /// Its value.
        value: f64,
    },
    /// The series does not vary, so its correlations are undefined.
    #[error("the series is constant (standard deviation {std:e})")]
    Constant {
        /// Its standard deviation.
        std: f64,
    },
    /// A significance level outside (0, 1).
    #[error("significance level must be in (0, 1) (got {level})")]
    Level {
        /// The level given.
        level: f64,
    },
}

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
