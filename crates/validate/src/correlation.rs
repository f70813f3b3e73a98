//! Sample auto- and cross-correlation.

use crate::error::{Error, Result};

/// Checks that every sample is finite and that there are enough samples for `lags`.
pub(crate) fn check(x: &[f64], lags: usize) -> Result<()> {
    if let Some((index, &value)) = x.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(Error::NotFinite { index, value });
    }
    // Twice the largest lag keeps every correlation an average over at least half the record.
    let min = (2 * lags).max(8);
    if x.len() < min {
        return Err(Error::TooShort {
            min,
            found: x.len(),
            lags,
        });
    }
    Ok(())
}

/// The series minus its mean, and its (biased, divide-by-N) standard deviation.
fn centred(x: &[f64]) -> Result<(Vec<f64>, f64)> {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let c: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let std = (c.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
    let scale = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    // Relative to the series' own size: a constant series leaves only rounding.
    if std <= 1e-14 * scale {
        return Err(Error::Constant { std });
    }
    Ok((c, std))
}

/// Sample autocorrelation `r(k)` for `k = 0..=max_lag` (so `r(0) = 1`).
///
/// `r(k) = sum_{t} (x_t - m)(x_{t+k} - m) / sum_t (x_t - m)^2`, the standard biased estimator
/// (divide by `N` at every lag), as in MATLAB's `resid`, statsmodels' `acf` and the Ljung-Box
/// statistic.
///
/// # Errors
/// [`Error::NotFinite`], [`Error::TooShort`] (fewer than `max(2 max_lag, 8)` samples),
/// [`Error::Constant`].
pub fn autocorrelation(x: &[f64], max_lag: usize) -> Result<Vec<f64>> {
    check(x, max_lag)?;
    let (c, std) = centred(x)?;
    let n = c.len();
    let c0 = std * std * n as f64;
    Ok((0..=max_lag)
        .map(|k| {
            c[..n - k]
                .iter()
                .zip(&c[k..])
                .map(|(a, b)| a * b)
                .sum::<f64>()
                / c0
        })
        .collect())
}

/// Sample cross-correlation between residual `e` and input `u` at lags `-max_lag..=max_lag`.
///
/// Returns `(lags, r)` with `r(k) = sum_t (e_{t+k} - m_e)(u_t - m_u) / (N s_e s_u)`: a positive
/// lag `k` correlates the residual with the input `k` samples earlier (a feedback-free model
/// that missed a dynamic shows there); a negative lag, with later inputs (feedback or a
/// non-causal effect).
///
/// # Errors
/// As [`autocorrelation`], and [`Error::LengthMismatch`].
pub fn cross_correlation(e: &[f64], u: &[f64], max_lag: usize) -> Result<(Vec<i64>, Vec<f64>)> {
    if e.len() != u.len() {
        return Err(Error::LengthMismatch {
            expected: e.len(),
            found: u.len(),
        });
    }
    check(e, max_lag)?;
    check(u, max_lag)?;
    let (ce, se) = centred(e)?;
    let (cu, su) = centred(u)?;
    let n = ce.len();
    let norm = n as f64 * se * su;
    let m = max_lag as i64;
    let lags: Vec<i64> = (-m..=m).collect();
    let r = lags
        .iter()
        .map(|&k| {
            let k_abs = k.unsigned_abs() as usize;
            let sum: f64 = if k >= 0 {
                ce[k_abs..]
                    .iter()
                    .zip(&cu[..n - k_abs])
                    .map(|(a, b)| a * b)
                    .sum()
            } else {
                ce[..n - k_abs]
                    .iter()
                    .zip(&cu[k_abs..])
                    .map(|(a, b)| a * b)
                    .sum()
            };
            sum / norm
        })
        .collect();
    Ok((lags, r))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn hand_computed_short_series() {
        // Eight samples is the minimum length; worked by hand below.
        let x = [1.0, 2.0, 3.0, 4.0, 1.0, 2.0, 3.0, 4.0];
        // mean 2.5, centred c = [-1.5,-.5,.5,1.5,-1.5,-.5,.5,1.5], sum c^2 = 10.
        // lag 1 products: .75,-.25,.75,-2.25,.75,-.25,.75 -> 0.25 -> 0.025
        // lag 4 products: 2.25,.25,.25,2.25 -> 5 -> 0.5
        let r = autocorrelation(&x, 4).unwrap();
        // Exact in binary floating point up to a few ulps of 1.
        assert_abs_diff_eq!(r[0], 1.0, epsilon = 1e-15);
        assert_abs_diff_eq!(r[1], 0.025, epsilon = 1e-15);
        assert_abs_diff_eq!(r[4], 0.5, epsilon = 1e-15);
    }

    #[test]
    fn cross_correlation_finds_a_delay_at_its_positive_lag() {
        // e is u delayed by 3 samples (circularly, so the statistics match exactly at lag 3
        // up to the wrapped ends): the peak is at k = +3.
        let u: Vec<f64> = (0..400).map(|i| ((i * 7919) % 101) as f64 - 50.0).collect();
        let e: Vec<f64> = (0..400).map(|i| u[(i + 400 - 3) % 400]).collect();
        let (lags, r) = cross_correlation(&e, &u, 10).unwrap();
        let (best, _) = r
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .unwrap();
        assert_eq!(lags[best], 3);
        // Three of 400 products wrap around: the peak is within 3/400 of 1.
        assert!(r[best] > 1.0 - 3.0 / 400.0 * 4.0);
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        assert!(matches!(
            autocorrelation(&[1.0; 20], 3),
            Err(Error::Constant { .. })
        ));
        assert!(matches!(
            autocorrelation(&[1.0, 2.0, 3.0], 3),
            Err(Error::TooShort { .. })
        ));
        let mut x: Vec<f64> = (0..20).map(f64::from).collect();
        x[5] = f64::NAN;
        assert!(matches!(
            autocorrelation(&x, 3),
            Err(Error::NotFinite { index: 5, .. })
        ));
        assert!(matches!(
            cross_correlation(&[1.0; 10], &[1.0; 11], 2),
            Err(Error::LengthMismatch { .. })
        ));
    }
}
