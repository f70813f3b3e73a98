//! Non-parametric estimation of harmonic transfer functions (HTFs) of linear time-periodic (LTP)
//! systems, and Levenberg-Marquardt least squares for parametric fits.
//!
//! # Estimators
//!
//! - [`siddiqi`]: one record, least squares with a second-difference (curvature) penalty across
//!   frequency bins, weight fixed or chosen by generalised cross-validation ([`Alpha`]). Banded
//!   normal equations: time and memory linear in the number of bins.
//! - [`multi_experiment`]: `K` records (phase-shifted segments), one `K x H` least squares per
//!   output bin, with condition numbers, pooled standard errors, optional ridge or smoothness
//!   regularisation ([`Regularisation`]) and optional local polynomial transient suppression
//!   ([`Leakage`]).
//! - [`periodic_lines`] and [`periodic_lines_paired`]: ratios at the lines of a periodic
//!   multisine, averaged over periods, optionally from a `+u` / `-u` pair.
//! - [`levenberg_marquardt`]: nonlinear least squares with a finite-difference Jacobian, returning
//!   the covariance and why it stopped ([`LmStop`]).
//! - [`uncertainty_budget`]: the error of fitted parameters split into noise, the known bias of
//!   the estimates and model-structure error ([`UncertaintyBudget`]).
//!
//! # Bias
//!
//! Standard errors cover noise only. Where an estimator has a known systematic error it says so
//! ([`HtfEstimate::bias`], [`BiasSource`]): the regularised estimators attach an estimate of
//! their smoothing bias. The odd-order distortion that a `+u` / `-u` pairing leaves
//! cannot be seen in one pair of records (it does not change sign with the input); the `htfid`
//! binary estimates it by re-running the experiment, without noise, on the fitted model.
//!
//! All estimators return an [`HtfEstimate`]; [`HtfEstimate::rows`] yields
//! `(omega, n, G, stderr)` rows.
//!
//! # Conventions
//!
//! - The system has period `T` and pumping frequency `wp = 2 pi / T`. Time is absolute and
//!   `t = 0` is phase 0 of the orbit, so DFT phases and HTF phases share one origin.
//! - Estimation convention (the paper's output equation):
//!   `Y(jw) = sum_n G_n(jw) U(jw - j n wp)`. `G_n` is indexed by the **output** frequency `w`:
//!   input at `w - n wp` appears at `w` with gain `G_n(jw)`. All frequencies are in rad/s and the
//!   `band` arguments select output frequencies, edges included.
//! - A record is htfid's one record type, a [`TimeSeries`] with one output (build one from
//!   deviations with [`deviation_record`]), uniformly sampled with interval `dt`, its first
//!   sample at absolute time `t_start`. Its length must be a whole number of system periods, `N dt = P T` with `P` an
//!   integer (to within `1e-6` periods), so that `wp` is exactly `P` DFT bins; otherwise
//!   [`Error::NotWholePeriods`].
//! - DFT scaling and phase ([`dft`]): `X[k] = dt * sum_i x_i exp(-j w_k (t_start + i dt))`,
//!   `w_k = 2 pi k / (N dt)`. For an `N dt`-periodic signal with Fourier coefficients `c_k` this
//!   is `N dt c_k`, independent of `t_start`. The ratios that define `G_n` do not depend on the
//!   scaling.
//! - Outputs are deviations from the limit cycle: the caller subtracts the orbit.
//! - For real signals `G_n(-jw) = conj(G_{-n}(jw))`; the estimators do not impose it.
//! - Standard errors are `sqrt(E|G_hat - E G_hat|^2)` for the complex estimate (each part has
//!   about `stderr / sqrt(2)`); `NaN` when no residual degrees of freedom remain.
//!
//! # Regularisation weight
//!
//! A weight `alpha` is dimensionless: the penalty enters the normal equations as
//! `alpha_eff = alpha * s`, where `s` is the mean diagonal of the data Gram matrices,
//! `s = sum_{k, r, n} |U_r[k - nP]|^2 / (M H)` over the `M` band bins, `K` records and `H`
//! harmonics (for one record, the mean of `|U|^2` over the shifted band). `alpha = 1` weighs one
//! bin's curvature like one bin's data. Second differences are taken in bins, so a fixed `alpha`
//! smooths over a fixed number of bins, a narrower band in rad/s as records lengthen; GCV adapts.
//! Both values are reported ([`HtfEstimate::alpha`], [`HtfEstimate::alpha_effective`]).
//! The trace of the influence matrix needed by GCV comes from the exact diagonal blocks of the
//! inverse banded normal matrix (selected inversion), not from a stochastic estimator.
//! An L-curve criterion is not implemented.
//!
//! # Example
//!
//! A memoryless LTP system `y(t) = (2 + 0.5 cos(wp t)) u(t)` has `G_0 = 2`, `G_{+-1} = 0.25` at
//! every frequency. A multisine with period 8 T on lines 1, 2 and 3 identifies them:
//!
//! ```
//! use std::f64::consts::PI;
//! use htfid_estimate::{deviation_record, periodic_lines, LineSpec};
//!
//! let (t_sys, dt, tm) = (1.0, 0.01, 8.0);
//! let wp = 2.0 * PI / t_sys;
//! let lines = [1usize, 2, 3];
//! let n = 2 * 800; // two multisine periods
//! let t: Vec<f64> = (0..n).map(|i| 3.0 + i as f64 * dt).collect();
//! let u: Vec<f64> = t
//!     .iter()
//!     .map(|&t| lines.iter().map(|&b| (2.0 * PI * b as f64 * t / tm + b as f64).cos()).sum())
//!     .collect();
//! let y: Vec<f64> = t.iter().zip(&u).map(|(&t, &u)| (2.0 + 0.5 * (wp * t).cos()) * u).collect();
//! let record = deviation_record(u, y, dt, t[0])?;
//! let est = periodic_lines(&record, t_sys, &LineSpec::new(tm, lines.to_vec())?, &[-1, 0, 1])?;
//! for row in est.rows() {
//!     let truth = if row.n == 0 { 2.0 } else { 0.25 };
//!     assert!((row.value.re - truth).abs() < 1e-9 && row.value.im.abs() < 1e-9);
//! }
//! # Ok::<(), htfid_estimate::Error>(())
//! ```

mod banded;
mod error;
mod estimate;
mod experiment;
mod from_data;
mod lines;
mod lm;
mod multi;
mod periodic;
mod record;
mod siddiqi;
mod size;
mod smallls;
mod smooth;
mod uncertainty;

pub use error::{Error, Result};
pub use estimate::{band_level, BiasSource, HarmonicSeries, HtfEstimate, HtfRow, Method};
pub use experiment::{
    estimate_experiment, Design, Estimator, Layout, LineWindows, Request, Sampled,
};
pub use from_data::{
    excited_band, periodic_value, DataEstimate, DataSpec, FromDataError, HarmonicSummary,
    OutputEstimate, PeriodChoice, PeriodicRecord, Signal, BAND_FALSE_ALARM, MIN_PERIODS,
    MIN_SAMPLES, OUTER_SIGNIFICANT_SHARE, UNEXCITED_SHARE,
};
pub use htfid_data::TimeSeries;
pub use lines::{periodic_lines, periodic_lines_paired, LineSpec};
pub use lm::{
    levenberg_marquardt, levenberg_marquardt_batch, levenberg_marquardt_parallel,
    levenberg_marquardt_with_jacobian, FdScheme, LmFit, LmOptions, LmStop, EXTEND_FROM, EXTEND_MAX,
};
pub use multi::{multi_experiment, Leakage, MultiOptions, Regularisation};
pub use periodic::{
    estimate_period, locked_step, split_periodic, PeriodEstimate, PeriodicSplit,
    LOCKED_DRIFT_SAMPLES,
};
pub use record::{deviation_record, dft};
pub use siddiqi::{outer_harmonics, siddiqi, OuterHarmonic, SiddiqiDesign};
pub use size::estimator_bytes;
pub use smooth::{golden_min, Alpha};
pub use uncertainty::{
    contiguous_clusters, uncertainty_budget, ErrorSource, FitBias, FitBudgetInput, ParameterBudget,
    UncertaintyBudget,
};
