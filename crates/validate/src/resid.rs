//! Residual analysis: correlations with their bounds and the portmanteau verdicts.

use serde::Serialize;

use crate::chi_square::chi_square_sf;
use crate::correlation::{autocorrelation, cross_correlation};
use crate::error::{Error, Result};

/// Significance level of the bounds and of the portmanteau tests: 1 %, i.e. 99 % bounds.
pub const LEVEL: f64 = 0.01;
/// Two-sided 99 % quantile of the standard normal distribution: the bounds are `+- Z_99 / sqrt(N)`.
pub const Z_99: f64 = 2.575_829_303_548_901;
/// Default largest lag, as MATLAB's `resid`.
pub const DEFAULT_LAGS: usize = 25;

/// One correlation test: how many lags leave the 99 % bounds, and a Ljung-Box portmanteau
/// statistic with its chi-square p-value.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CorrelationTest {
    /// Samples the correlations were computed from.
    pub samples: usize,
    /// First and last lag tested (inclusive).
    pub lags: [i64; 2],
    /// Half-width of the bounds, `Z_99 / sqrt(N)`.
    pub bound: f64,
    /// Confidence of the bounds (0.99).
    pub confidence: f64,
    /// Lags tested.
    pub tested: usize,
    /// Lags whose correlation lies outside the bounds.
    pub outside: usize,
    /// `outside / tested`; about 1 % for a white residual independent of the input.
    pub outside_share: f64,
    /// Ljung-Box statistic `Q = N (N + 2) sum_k r(k)^2 / (N - |k|)` over the tested lags.
    pub statistic: f64,
    /// Its degrees of freedom (the number of lags tested).
    pub dof: usize,
    /// `P(chi2_dof > Q)`.
    pub p_value: f64,
    /// Level of the test (0.01).
    pub level: f64,
    /// `p_value >= level`: no evidence against the hypothesis at that level.
    pub passed: bool,
}

impl CorrelationTest {
    fn new(samples: usize, lags: &[i64], r: &[f64]) -> Self {
        let n = samples as f64;
        let bound = Z_99 / n.sqrt();
        let outside = r.iter().filter(|v| v.abs() > bound).count();
        let statistic = n
            * (n + 2.0)
            * lags
                .iter()
                .zip(r)
                .map(|(&k, v)| v * v / (n - k.unsigned_abs() as f64))
                .sum::<f64>();
        let p_value = chi_square_sf(statistic, r.len());
        Self {
            samples,
            lags: [
                lags.first().copied().unwrap_or(0),
                lags.last().copied().unwrap_or(0),
            ],
            bound,
            confidence: 1.0 - LEVEL,
            tested: r.len(),
            outside,
            outside_share: outside as f64 / r.len().max(1) as f64,
            statistic,
            dof: r.len(),
            p_value,
            level: LEVEL,
            passed: p_value >= LEVEL,
        }
    }
}

/// Residual analysis of one output, as MATLAB's `resid`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Resid {
    /// Autocorrelation of the residual at lags `0..=max_lag`.
    #[serde(skip)]
    pub autocorrelation: Vec<f64>,
    /// Lags `-max_lag..=max_lag` of [`Resid::cross_correlation`].
    #[serde(skip)]
    pub cross_lags: Vec<i64>,
    /// Cross-correlation of residual and input (see [`cross_correlation`]).
    #[serde(skip)]
    pub cross_correlation: Vec<f64>,
    /// Whiteness: the autocorrelation at lags `1..=max_lag`.
    pub whiteness: CorrelationTest,
    /// Independence of the input: the cross-correlation at lags `0..=max_lag` (the residual
    /// against present and past inputs; negative lags are drawn but not tested, since they
    /// are non-zero under feedback without the model being wrong).
    pub independence: CorrelationTest,
}

/// Residual analysis of residual `e` against input `u` (same instants) up to `max_lag` samples.
///
/// The bounds and the Ljung-Box tests assume the null hypothesis of a white residual
/// independent of the input; under it `sqrt(N) r(k)` is asymptotically standard normal for
/// every lag `k != 0` of the autocorrelation and every lag of the cross-correlation.
///
/// # Errors
/// [`Error::LengthMismatch`], [`Error::NotFinite`], [`Error::TooShort`] (fewer than
/// `max(2 max_lag, 8)` samples), [`Error::Constant`] (a constant residual or input), and
/// [`Error::TooShort`] for `max_lag == 0`.
pub fn resid(e: &[f64], u: &[f64], max_lag: usize) -> Result<Resid> {
    if max_lag == 0 {
        return Err(Error::TooShort {
            min: 8,
            found: e.len(),
            lags: 0,
        });
    }
    let acf = autocorrelation(e, max_lag)?;
    let (cross_lags, ccf) = cross_correlation(e, u, max_lag)?;
    let n = e.len();
    let white_lags: Vec<i64> = (1..=max_lag as i64).collect();
    let whiteness = CorrelationTest::new(n, &white_lags, &acf[1..]);
    let causal = max_lag; // index of lag 0
    let independence = CorrelationTest::new(n, &cross_lags[causal..], &ccf[causal..]);
    Ok(Resid {
        autocorrelation: acf,
        cross_lags,
        cross_correlation: ccf,
        whiteness,
        independence,
    })
}

/// Fit in percent, `100 (1 - |y - y_sim| / |y - mean(y)|)`, as MATLAB's `compare` (NRMSE).
///
/// 100 is a perfect fit, 0 no better than the mean of the measurement, negative worse. Pairs
/// with a non-finite value on either side are left out.
///
/// # Errors
/// [`Error::LengthMismatch`]; [`Error::TooShort`] with fewer than 2 finite pairs;
/// [`Error::Constant`] when the measurement does not vary.
pub fn fit_percent(measured: &[f64], simulated: &[f64]) -> Result<f64> {
    if measured.len() != simulated.len() {
        return Err(Error::LengthMismatch {
            expected: measured.len(),
            found: simulated.len(),
        });
    }
    let pairs: Vec<(f64, f64)> = measured
        .iter()
        .zip(simulated)
        .filter(|(a, b)| a.is_finite() && b.is_finite())
        .map(|(a, b)| (*a, *b))
        .collect();
    if pairs.len() < 2 {
        return Err(Error::TooShort {
            min: 2,
            found: pairs.len(),
            lags: 0,
        });
    }
    let mean = pairs.iter().map(|p| p.0).sum::<f64>() / pairs.len() as f64;
    let spread = pairs
        .iter()
        .map(|p| (p.0 - mean).powi(2))
        .sum::<f64>()
        .sqrt();
    if spread == 0.0 {
        return Err(Error::Constant { std: 0.0 });
    }
    let error = pairs
        .iter()
        .map(|p| (p.0 - p.1).powi(2))
        .sum::<f64>()
        .sqrt();
    Ok(100.0 * (1.0 - error / spread))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn fit_percent_of_perfect_mean_and_half() {
        let y = [1.0, 3.0, 2.0, 6.0];
        assert_abs_diff_eq!(fit_percent(&y, &y).unwrap(), 100.0, epsilon = 1e-12);
        // The mean (3) as a simulation scores 0.
        assert_abs_diff_eq!(fit_percent(&y, &[3.0; 4]).unwrap(), 0.0, epsilon = 1e-12);
        // Half the deviation from the mean: error is half the spread, fit 50 %.
        let half: Vec<f64> = y.iter().map(|v| 3.0 + 0.5 * (v - 3.0)).collect();
        assert_abs_diff_eq!(fit_percent(&y, &half).unwrap(), 50.0, epsilon = 1e-12);
        assert!(fit_percent(&[2.0; 4], &y).is_err());
    }
}
