//! What a simulation will cost, known before it runs: callers refuse a request that cannot fit
//! in memory or under [`Options::max_steps`](crate::Options::max_steps) before any work.

/// Bytes of a [`Trajectory`](crate::Trajectory) of a `dim`-dimensional system sampled at
/// `samples` grid times, with charts of `mode_bytes` bytes each: the grid, the row-major
/// states and the charts (events and the final state are negligible beside them). The caller's
/// grid itself is not counted. Saturates instead of overflowing.
pub fn trajectory_bytes(dim: usize, samples: u64, mode_bytes: usize) -> u64 {
    let per_sample = 8 * (1 + dim as u64) + mode_bytes as u64;
    samples.saturating_mul(per_sample)
}

/// Smallest number of accepted steps that integrate `span` seconds of a system forced with
/// period `period` s: [`MIN_STEPS_PER_PERIOD`] per period. An estimate from below, so a
/// request it puts above [`Options::max_steps`](crate::Options::max_steps) certainly fails
/// there; a request below it may still need more. Returns infinity for a non-positive or
/// non-finite period.
pub fn min_steps(span: f64, period: f64) -> f64 {
    if !(period.is_finite() && period > 0.0) {
        return f64::INFINITY;
    }
    (span.max(0.0) / period) * MIN_STEPS_PER_PERIOD
}

/// Accepted steps per forcing period that no accurate run goes below: an embedded pair
/// resolves a sinusoid with steps of at most about a quarter of its period, and a forced
/// hybrid orbit adds its transitions (each ends a step). The shipped hopper takes about 50
/// at the default tolerances.
pub const MIN_STEPS_PER_PERIOD: f64 = 4.0;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trajectory_bytes_counts_grid_states_and_modes() {
        // 10 samples of a 2-state system with 1-byte charts: 10 * (8 + 16 + 1).
        assert_eq!(trajectory_bytes(2, 10, 1), 250);
        assert_eq!(trajectory_bytes(2, u64::MAX, 8), u64::MAX);
    }

    #[test]
    fn min_steps_scales_with_periods() {
        assert!((min_steps(100.0, 0.5) - 800.0).abs() < 1e-9);
        assert!(min_steps(1.0, 0.0).is_infinite());
        assert!(min_steps(-1.0, 1.0).abs() < 1e-12);
    }
}
