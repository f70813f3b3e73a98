use htfid_hybrid::HybridError;
use num_complex::Complex64;

/// Errors of periodic-orbit computations.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum OrbitError {
    /// The underlying hybrid integration failed.
    #[error("integration failed: {0}")]
    Integration(#[from] HybridError),
    /// The period must be positive and finite.
    #[error("period must be positive and finite (got {0})")]
    InvalidPeriod(f64),
    /// Newton shooting did not converge.
    #[error(
        "Newton shooting did not converge to a periodic orbit after {iterations} iterations \
         (periodicity residual {residual:.3e}, tolerance {tolerance:.1e})"
    )]
    NoConvergence {
        /// Iterations used.
        iterations: usize,
        /// Final residual `|P(x) - x|`.
        residual: f64,
        /// Requested tolerance.
        tolerance: f64,
    },
    /// `DP - I` is singular: a Floquet multiplier equals 1, the orbit is not isolated.
    #[error(
        "the period-map Jacobian has a Floquet multiplier at 1; the periodic orbit is not isolated"
    )]
    SingularJacobian,
    /// The periodic orbit exists but is not asymptotically stable.
    #[error(
        "no stable period-{period} orbit: the largest Floquet multiplier has modulus {max_modulus:.9} \
         (needs < 1 - {margin:.0e}); multipliers: {}", format_multipliers(multipliers)
    )]
    NotStable {
        /// The period.
        period: f64,
        /// Largest multiplier modulus.
        max_modulus: f64,
        /// Required margin below 1.
        margin: f64,
        /// All multipliers.
        multipliers: Vec<Complex64>,
    },
    /// The motion slides along a switching surface through the whole period (a mass stuck
    /// by friction that the forcing never breaks loose): every state near it on the surface
    /// is periodic too, so there is no isolated orbit to refine.
    #[error(
        "the motion slides along guard {guard} through the whole period {period} s from \
         t = {start} s (stuck at {state:?}); the periodic orbit is not isolated"
    )]
    SlidesThroughout {
        /// The surface: guard index in the chart the motion slides in.
        guard: usize,
        /// The period.
        period: f64,
        /// Start of the period examined.
        start: f64,
        /// The state at its start.
        state: Vec<f64>,
    },
    /// The shooting options are out of range.
    #[error("invalid shooting option {field}: {reason}")]
    InvalidOptions {
        /// The offending field.
        field: &'static str,
        /// What was expected.
        reason: String,
    },
}

fn format_multipliers(m: &[Complex64]) -> String {
    m.iter()
        .map(|z| format!("{:.6}{:+.6}j", z.re, z.im))
        .collect::<Vec<_>>()
        .join(", ")
}
