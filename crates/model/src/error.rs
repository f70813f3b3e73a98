use htfid_orbit::OrbitError;

/// Errors of the hopper model.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// A parameter is out of range.
    #[error("{name} must be {expected} (got {value})")]
    InvalidParameter {
        /// Parameter name as in configs.
        name: &'static str,
        /// What was expected.
        expected: &'static str,
        /// The value given.
        value: f64,
    },
    /// The limit cycle could not be found.
    #[error(transparent)]
    Orbit(#[from] OrbitError),
    /// Integration failed.
    #[error(transparent)]
    Integration(#[from] htfid_hybrid::HybridError),
    /// The orbit does not switch the damper exactly once on and once off per period.
    #[error(
        "the periodic orbit switches the damper on {on} and off {off} times per period; \
         expected exactly one of each"
    )]
    UnexpectedSwitching {
        /// Number of switch-on events per period.
        on: usize,
        /// Number of switch-off events per period.
        off: usize,
    },
}
