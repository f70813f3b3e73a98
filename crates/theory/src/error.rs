//! The crate's error type.

use htfid_ltp::LtpError;

/// Errors of the HTF theory layer.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TheoryError {
    /// The underlying LTP model was rejected.
    #[error(transparent)]
    Ltp(#[from] LtpError),
    /// HTFs here are single-input single-output; select a channel first
    /// (`PiecewiseLti::channel`).
    #[error(
        "expected a single-input single-output system, got {inputs} inputs and {outputs} outputs"
    )]
    NotSiso {
        /// Number of inputs of the given system.
        inputs: usize,
        /// Number of outputs of the given system.
        outputs: usize,
    },
    /// State jumps have no place in the Fourier-series (harmonic state space)
    /// form; use the exact HTF instead.
    #[error("piece {piece} has a jump matrix other than the identity, which the truncated harmonic state space cannot represent")]
    JumpNotRepresentable {
        /// First piece with a non-identity jump.
        piece: usize,
    },
    /// The modal method was requested for a piece whose state matrix is not
    /// (well-conditioned) diagonalisable.
    #[error("piece {piece}: state matrix is not safely diagonalisable (eigenvector condition {condition:e}, relative residual {residual:e})")]
    NotDiagonalisable {
        /// Index of the offending piece.
        piece: usize,
        /// Condition number of the eigenvector matrix.
        condition: f64,
        /// `||A V - V diag(lambda)|| / ||A||` of the computed decomposition.
        residual: f64,
    },
    /// A guard or reset on the orbit reads the input and the tangents do not give the change
    /// of its jump per unit input.
    #[error("derivatives of the HTFs along the orbit need the change of the state's jump per unit input where a guard or reset reads the input, and the system's tangents do not give it")]
    InputAtCrossing,
    /// A Fourier-coefficient provider returned a matrix of the wrong shape.
    #[error("coefficient {matrix:?}_{harmonic} is {found_rows}x{found_cols}, expected {expected_rows}x{expected_cols}")]
    CoefficientShape {
        /// Which system matrix.
        matrix: htfid_ltp::SystemMatrix,
        /// Harmonic index of the coefficient.
        harmonic: i32,
        /// Expected number of rows.
        expected_rows: usize,
        /// Expected number of columns.
        expected_cols: usize,
        /// Actual number of rows.
        found_rows: usize,
        /// Actual number of columns.
        found_cols: usize,
    },
    /// A Fourier-coefficient provider returned a NaN or infinite entry.
    #[error("coefficient {matrix:?}_{harmonic} has a non-finite entry")]
    NonFiniteCoefficient {
        /// Which system matrix.
        matrix: htfid_ltp::SystemMatrix,
        /// Harmonic index of the coefficient.
        harmonic: i32,
    },
    /// The period must be finite and strictly positive.
    #[error("period must be finite and > 0 (got {period})")]
    InvalidPeriod {
        /// The rejected period.
        period: f64,
    },
    /// Fourier series describing one system must share one period.
    #[error("Fourier series periods disagree: {first} vs {second}")]
    PeriodMismatch {
        /// Period of the `A` series.
        first: f64,
        /// The disagreeing period.
        second: f64,
    },
    /// The limit cycle's state has the wrong length for the system.
    #[error("the cycle's state has {found} entries, the system {expected} states")]
    StateDimension {
        /// The system's state dimension.
        expected: usize,
        /// Length of the cycle's state.
        found: usize,
    },
    /// HTFs need at least one output.
    #[error("the system has no outputs")]
    NoOutputs,
    /// A requested output does not exist.
    #[error("output {output} out of range for a system with {n_outputs} outputs")]
    OutputOutOfRange {
        /// Requested output index.
        output: usize,
        /// Number of outputs of the system.
        n_outputs: usize,
    },
    /// Integrating the variational equations over the limit cycle failed.
    #[error("integration over the limit cycle failed: {0}")]
    Orbit(String),
    /// The limit cycle does not return to its start under the HTF's integrator options.
    #[error("the cycle is not a periodic orbit of this system: |P(x0) - x0| = {residual:e} exceeds {tolerance:e} (a cycle of another system, or computed with the input on?)")]
    NotPeriodic {
        /// `|P(x0) - x0|_inf` over one period.
        residual: f64,
        /// The accepted residual.
        tolerance: f64,
    },
    /// A frequency must be finite.
    #[error("frequency must be finite (got {w})")]
    InvalidFrequency {
        /// The rejected frequency (rad per time unit).
        w: f64,
    },
    /// Integrating the steady-state response to one input frequency failed.
    #[error("integration of the response to input frequency {w_in} failed: {reason}")]
    Integration {
        /// Input frequency (rad per time unit).
        w_in: f64,
        /// The integrator's message.
        reason: String,
    },
    /// The truncation order is too large to build the harmonic state space.
    #[error("truncation order {harmonics} is too large (harmonic state space of size {size} exceeds {max})")]
    TruncationTooLarge {
        /// Requested truncation order N.
        harmonics: usize,
        /// Resulting matrix size (2N + 1) n.
        size: usize,
        /// Largest accepted size.
        max: usize,
    },
}
