//! The crate's single error type.

/// Everything that can go wrong when building a signal or a design.
///
/// Variants carry the numbers that explain them, so a message can be acted
/// on without reading the source.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ExciteError {
    /// A scalar parameter is out of its range.
    #[error("{name} must be {requirement} (got {value})")]
    InvalidParameter {
        /// Parameter name as it appears in the API.
        name: &'static str,
        /// The range it must lie in, in words.
        requirement: &'static str,
        /// The offending value.
        value: f64,
    },
    /// A multisine was asked for with no lines.
    #[error("a multisine needs at least one line (got none)")]
    NoLines,
    /// Bin 0 is DC, which is not a sinusoidal line.
    #[error("multisine bins must be >= 1 (got bin 0, which is DC)")]
    ZeroBin,
    /// Two lines share one bin.
    #[error("multisine bin {bin} appears more than once")]
    DuplicateBin {
        /// The repeated bin.
        bin: u64,
    },
    /// A frequency band selects no bin of the multisine grid.
    #[error(
        "band {lo_hz}..={hi_hz} Hz holds no bin of a {period} s multisine \
         (bins are {} Hz apart)", 1.0 / period
    )]
    EmptyBand {
        /// Lower band edge, Hz.
        lo_hz: f64,
        /// Upper band edge, Hz.
        hi_hz: f64,
        /// Multisine period, s.
        period: f64,
    },
    /// The record would not start at forcing phase 0.
    #[error(
        "start {start} s is not a whole number of forcing periods T = {period} s; \
         measured windows must begin at forcing phase 0"
    )]
    StartOffPeriod {
        /// Requested start time, s.
        start: f64,
        /// Forcing period, s.
        period: f64,
    },
    /// The smallest multisine that meets the spectral targets does not fit the record.
    #[error(
        "infeasible design: needs P >= {needed_p} (Tm = {multisine_period} s), \
         record {record} s > max {max_record} s"
    )]
    RecordTooLong {
        /// Smallest number of forcing periods per multisine period that meets
        /// spacing, coverage and residue capacity.
        needed_p: u64,
        /// The multisine period that P implies, s.
        multisine_period: f64,
        /// Total record length that P implies (all blocks and settling), s.
        record: f64,
        /// The allowed maximum, s.
        max_record: f64,
    },
    /// The search for P gave up (targets far too fine for the band).
    #[error("no design found with P up to {searched_up_to} forcing periods per multisine period")]
    NoDesign {
        /// Largest P tried.
        searched_up_to: u64,
    },
    /// Two harmonics asked for are indistinguishable with K phase-shifted copies.
    #[error(
        "harmonics {first} and {second} cannot be told apart with {copies} phase-shifted \
         copies (they differ by a multiple of {copies})"
    )]
    HarmonicsAlias {
        /// First harmonic index.
        first: i32,
        /// Second harmonic index.
        second: i32,
        /// Number of phase-shifted copies K.
        copies: usize,
    },
    /// A design was built but one harmonic misses the spacing target (a broken
    /// internal contract reported instead of panicking).
    #[error(
        "design misses the spacing target for harmonic {harmonic}: \
         largest gap {max_gap} rad/s > target {target} rad/s"
    )]
    CoverageNotMet {
        /// Harmonic index n.
        harmonic: i32,
        /// Largest gap between estimate points bracketing the band, rad/s.
        max_gap: f64,
        /// Target spacing, rad/s.
        target: f64,
    },
}

pub(crate) fn finite(name: &'static str, value: f64) -> Result<f64, ExciteError> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(ExciteError::InvalidParameter {
            name,
            requirement: "finite",
            value,
        })
    }
}

pub(crate) fn positive(name: &'static str, value: f64) -> Result<f64, ExciteError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(ExciteError::InvalidParameter {
            name,
            requirement: "finite and > 0",
            value,
        })
    }
}

pub(crate) fn non_negative(name: &'static str, value: f64) -> Result<f64, ExciteError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(ExciteError::InvalidParameter {
            name,
            requirement: "finite and >= 0",
            value,
        })
    }
}
