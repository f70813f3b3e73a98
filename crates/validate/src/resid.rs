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

/// Eigenvalues of the cross-correlation's covariance below this share of the largest are left
/// out of the independence test (with their degrees of freedom): a strongly oversampled input
/// makes neighbouring lags nearly collinear, and directions its sample autocorrelation cannot
/// resolve would only amplify noise.
const MIN_EIGEN_SHARE: f64 = 1e-6;

impl CorrelationTest {
    /// The test of the cross-correlation `r` at `lags` (consecutive, from 0) of a residual
    /// with autocorrelation `acf_e` (`None`: a white residual) against an input with
    /// autocorrelation `acf_u` (at lags `0..`, at least `2 max_lag` of them), under the
    /// hypothesis that the two are independent. Then `sqrt(N) r` is asymptotically normal
    /// with covariance `P_kl = sum_tau rho_e(tau) rho_u(tau + k - l)` (Bartlett's formula;
    /// `P = ` the input's autocorrelation matrix when the residual is white), and
    /// `Q = N r' P^-1 r` is chi-square with one degree of freedom per direction of `P` kept
    /// (see [`MIN_EIGEN_SHARE`]). A coloured
    /// input correlates neighbouring lags, so the Ljung-Box sum of squares, which assumes them
    /// independent, would reject an exact model (and its bounds hold only lag by lag).
    fn independence(
        samples: usize,
        lags: &[i64],
        r: &[f64],
        acf_e: Option<&[f64]>,
        acf_u: &[f64],
    ) -> Self {
        let n = samples as f64;
        let m = r.len();
        let rho_u = |k: i64| acf_u.get(k.unsigned_abs() as usize).copied().unwrap_or(0.0);
        let p = nalgebra::DMatrix::from_fn(m, m, |k, l| {
            let d = k as i64 - l as i64;
            match acf_e {
                None => rho_u(d),
                Some(acf_e) => {
                    let window = acf_e.len() as i64 - 1;
                    (-window..=window)
                        .map(|tau| {
                            // Bartlett's weights keep the estimated covariance positive.
                            let w = 1.0 - tau.unsigned_abs() as f64 / (window + 1) as f64;
                            w * acf_e[tau.unsigned_abs() as usize] * rho_u(tau + d)
                        })
                        .sum()
                }
            }
        });
        let bound = Z_99 * (p[(0, 0)].max(0.0) / n).sqrt();
        let eig = nalgebra::SymmetricEigen::new(p);
        let largest = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
        let rv = nalgebra::DVector::from_column_slice(r);
        let (mut statistic, mut dof) = (0.0, 0);
        for (i, &lambda) in eig.eigenvalues.iter().enumerate() {
            if lambda > MIN_EIGEN_SHARE * largest {
                let proj = eig.eigenvectors.column(i).dot(&rv);
                statistic += n * proj * proj / lambda;
                dof += 1;
            }
        }
        Self::with(samples, lags, r, bound, statistic, dof)
    }

    fn new(samples: usize, lags: &[i64], r: &[f64]) -> Self {
        let n = samples as f64;
        let bound = Z_99 / n.sqrt();
        let statistic = n
            * (n + 2.0)
            * lags
                .iter()
                .zip(r)
                .map(|(&k, v)| v * v / (n - k.unsigned_abs() as f64))
                .sum::<f64>();
        Self::with(samples, lags, r, bound, statistic, r.len())
    }

    /// The test of correlations `r` at `lags` with the bound `bound` and the statistic
    /// `statistic`, chi-square with `dof` degrees of freedom under the hypothesis.
    fn with(
        samples: usize,
        lags: &[i64],
        r: &[f64],
        bound: f64,
        statistic: f64,
        dof: usize,
    ) -> Self {
        let outside = r.iter().filter(|v| v.abs() > bound).count();
        let p_value = chi_square_sf(statistic, dof.max(1));
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
            dof,
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
    /// are non-zero under feedback without the model being wrong). Its statistic is
    /// `N r' P^-1 r` with `P` the covariance of the lags under independence (the input's
    /// autocorrelation matrix for a white residual, Bartlett's formula for a coloured one),
    /// not the Ljung-Box sum, which holds only for a white input; its bound is
    /// `Z_99 sqrt(P_00 / N)`.
    pub independence: CorrelationTest,
}

/// Residual analysis of residual `e` against input `u` (same instants) up to `max_lag` samples.
///
/// The whiteness bounds and its Ljung-Box test assume the null hypothesis of a white residual;
/// under it `sqrt(N) r(k)` is asymptotically standard normal at every lag `k != 0`. The
/// independence test assumes a residual independent of the input, each with its own colour
/// (see [`Resid::independence`]).
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
                          // The input's autocorrelation over twice the lags (the covariance of the cross-correlation
                          // reaches that far); the residual's own only where it is not white.
    let acf_u = autocorrelation(u, (2 * max_lag).min(n.saturating_sub(1) / 2))?;
    let independence = CorrelationTest::independence(
        n,
        &cross_lags[causal..],
        &ccf[causal..],
        (!whiteness.passed).then_some(&acf[..]),
        &acf_u,
    );
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
