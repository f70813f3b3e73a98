//! Siddiqi's single-record estimator: least squares with a curvature penalty across bins.

use crate::error::Result;
use crate::estimate::{BiasSource, HtfEstimate, Method};
use crate::record::{Prepared, Record};
use crate::smooth::{self, Alpha, BinSystem};

/// Second differences need at least three bins.
const MIN_BINS: usize = 3;

/// Estimates `G_n` for `n` in `harmonics` at the output bins of `band` (rad/s, inclusive) from a
/// single record, by minimising
///
/// ```text
/// sum_k |Y[k] - sum_n G_n[k] U[k - nP]|^2 + alpha_eff sum_n sum_k |G_n[k+1] - 2 G_n[k] + G_n[k-1]|^2
/// ```
///
/// with `alpha_eff = alpha * mean_{k, n} |U[k - nP]|^2` over the band. The normal equations are
/// banded (half-bandwidth `2H`) and solved by a banded Cholesky factorisation in `O(M H^3)` time
/// and `O(M H^2)` memory for `M` bins; [`Alpha::Gcv`] needs the diagonal blocks of the inverse,
/// obtained exactly by selected inversion at the same cost.
///
/// Standard errors are `sqrt(sigma^2 [N^{-1}]_ii)` with `sigma^2 = RSS / (M - tr S)` and `S` the
/// influence matrix: the posterior spread of a Gaussian smoothness prior. They ignore the bias
/// that the penalty introduces where `G_n` curves, and they bound the frequentist spread
/// `sigma^2 [N^{-1} A^H A N^{-1}]_ii` from above. The bias itself is estimated to first order and
/// attached ([`HtfEstimate::bias`], [`BiasSource::Smoothing`]): the penalised solution has mean
/// `G - N^{-1} R G` (`N` the normal matrix, `R` the penalty), so `-N^{-1} R G_hat`, the
/// estimate's curvature weighed by the smoother's kernel, is the bias with the estimate in place
/// of the truth. It underestimates where the penalty flattens much of the curvature (the
/// estimate's own curvature is shrunk by the same factor).
pub fn siddiqi(
    record: &Record,
    period: f64,
    harmonics: &[i32],
    band: (f64, f64),
    alpha: Alpha,
) -> Result<HtfEstimate> {
    let prep = Prepared::new(
        std::slice::from_ref(record),
        period,
        harmonics,
        band,
        0,
        MIN_BINS,
    )?;
    let sys = BinSystem::new(&prep);
    let res = smooth::estimate(&sys, alpha, 0.0)?;
    let omegas = prep.omegas();
    Ok(HtfEstimate::new(
        Method::Siddiqi,
        harmonics.to_vec(),
        vec![omegas; harmonics.len()],
        res.values,
        res.stderr,
    )?
    .with_bias(BiasSource::Smoothing, res.bias)?
    .with_alpha(res.alpha, res.alpha_effective)
    .with_dof(res.dof))
}
