//! Model validation on held-out data, as MATLAB's `compare` and `resid` give it.
//!
//! - [`fit_percent`]: `100 (1 - NRMSE)` of a simulation against the measurement.
//! - [`autocorrelation`] and [`cross_correlation`]: sample correlations over lags.
//! - [`resid`]: both correlations of a residual with their 99 % bounds (`+- 2.576 / sqrt(N)`
//!   for a white residual), the share of lags outside them, and a portmanteau test of each at
//!   the 1 % level ([`CorrelationTest`]); [`chi_square_sf`] gives its p-value.
//!
//! # Conventions
//! - Correlations use the biased estimator (divide by `N` at every lag) of the mean-removed
//!   series, so the autocorrelation at lag 0 is 1 and every value lies in `[-1, 1]`.
//! - In the cross-correlation a positive lag `k` pairs the residual with the input `k` samples
//!   earlier. Whiteness is tested on lags `1..=M`, independence on lags `0..=M`.
//! - Ljung-Box (whiteness): `Q = N (N + 2) sum_k r(k)^2 / (N - |k|)`, compared with a
//!   chi-square distribution with as many degrees of freedom as lags tested (no parameters are
//!   subtracted: the residual of a simulation is not that of a fitted ARMA model).
//! - Independence: `Q = N r' P^-1 r` over lags `0..=M`, `P` the lags' covariance when residual
//!   and input are independent (Bartlett: `P_kl = sum_tau rho_e(tau) rho_u(tau + k - l)`,
//!   the input's autocorrelation matrix for a white residual), chi-square with one degree per
//!   lag (directions of `P` below `1e-6` of its largest eigenvalue left out). A band-limited
//!   input correlates neighbouring lags: the Ljung-Box sum would reject an exact model.
//! - Nothing here panics on data: short, constant or non-finite series are [`Error`]s.
//!
//! # Example
//! ```
//! use htfid_validate::{resid, LEVEL};
//!
//! // A residual that follows the input one sample late is neither white nor independent.
//! let u: Vec<f64> = (0..500).map(|i| ((i * 37) % 17) as f64 - 8.0).collect();
//! let e: Vec<f64> = (0..500).map(|i| if i > 0 { u[i - 1] } else { 0.0 }).collect();
//! let r = resid(&e, &u, 25)?;
//! assert!(!r.independence.passed && r.independence.p_value < LEVEL);
//! # Ok::<(), htfid_validate::Error>(())
//! ```

mod chi_square;
mod correlation;
mod error;
mod resid;

pub use chi_square::chi_square_sf;
pub use correlation::{autocorrelation, cross_correlation};
pub use error::{Error, Result};
pub use resid::{fit_percent, resid, CorrelationTest, Resid, DEFAULT_LAGS, LEVEL, Z_99};
