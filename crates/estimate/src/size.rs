//! Memory of an estimate, known before it runs.

use std::f64::consts::TAU;

/// Bytes of the largest arrays [`siddiqi`](crate::siddiqi) (one record) or
/// [`multi_experiment`](crate::multi_experiment) (`records` records) hold for records of
/// `samples` samples at interval `dt`, `harmonics` harmonics and an output `band` in rad/s:
/// the complex DFTs of input and output, the per-bin regression rows (`M K H` entries for the
/// `M` band bins), the banded normal matrix (`M H` unknowns, half-bandwidth `2 H`), and the
/// estimates with their standard errors. The periodic-line estimators hold only the DFTs, so
/// this bounds them too. An estimate within a small factor, for refusing a request that cannot
/// fit before the transforms start; saturates instead of overflowing.
pub fn estimator_bytes(
    records: usize,
    samples: u64,
    dt: f64,
    harmonics: usize,
    band: (f64, f64),
) -> u64 {
    const C: u64 = 16; // one complex double
    let (k, h) = (records as u64, harmonics as u64);
    let span = samples as f64 * dt;
    // Band bins at spacing 2 pi / (N dt), never more than the record's own bins.
    let m = if span.is_finite() && span > 0.0 && band.1 > band.0 {
        (((band.1 - band.0) * span / TAU).floor() + 1.0).min(samples as f64) as u64
    } else {
        samples
    };
    let dfts = k
        .saturating_mul(2)
        .saturating_mul(samples)
        .saturating_mul(C);
    let rows = m.saturating_mul(k).saturating_mul(h + 1).saturating_mul(C);
    let unknowns = m.saturating_mul(h);
    let normal = unknowns.saturating_mul(2 * h + 1).saturating_mul(C);
    let results = unknowns.saturating_mul(C + 8 + 8);
    dfts.saturating_add(rows)
        .saturating_add(normal)
        .saturating_add(results)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grows_with_samples_and_saturates() {
        // One 100 s record at 100 Hz, 7 harmonics, 1..40 rad/s: 621 band bins.
        let b = estimator_bytes(1, 10_000, 0.01, 7, (1.0, 40.0));
        let m = 621u64;
        let expected = 2 * 10_000 * 16 + m * 8 * 16 + m * 7 * 15 * 16 + m * 7 * 32;
        assert_eq!(b, expected);
        assert!(estimator_bytes(1, 20_000, 0.01, 7, (1.0, 40.0)) > 2 * b - 1000);
        assert_eq!(estimator_bytes(9, u64::MAX, 0.01, 7, (1.0, 40.0)), u64::MAX);
    }
}
