//! Siddiqi's single-record estimator: least squares with a curvature penalty across bins.

use crate::error::{Error, Result};
use crate::estimate::{BiasSource, HtfEstimate, Method};
use crate::record::Prepared;
use crate::smooth::{self, Alpha, AtWeight, BinSystem, SmoothResult};
use htfid_data::TimeSeries;

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
/// `sigma^2 [N^{-1} A^H A N^{-1}]_ii` from above. The bias itself is estimated and attached
/// ([`HtfEstimate::bias`], [`BiasSource::Smoothing`]): the penalised solution has mean
/// `G - N^{-1} R G` (`N` the normal matrix, `R` the penalty), so the bias is `-N^{-1} R G`, the
/// curvature of `G` weighed by the smoother's kernel. With `G = G_hat - bias` it is a fixed
/// point; two terms of its series are used, starting from `-N^{-1} R G_hat` (more would undo
/// the regularisation and bring back the noise it suppresses). On noise-free data where
/// smoothing dominates it accounts for 77 to 85 % of the error (`tests/siddiqi.rs`): it falls
/// short where the penalty flattens much of the curvature.
pub fn siddiqi(
    record: &TimeSeries,
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
    assemble(&prep, smooth::estimate(&sys, alpha, 0.0)?)
}

/// A harmonic outside an estimate's set, estimated beside it to see whether it carries the
/// response ([`outer_harmonics`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OuterHarmonic {
    /// The harmonic `n`.
    pub n: i32,
    /// Share of the band's bins where `|G_n|` exceeds twice its standard error (noise alone:
    /// about 2 %).
    pub significant_share: f64,
    /// Its largest magnitude over the band.
    pub max_abs: f64,
}

/// Estimates `record` again with `extra` more harmonics on each side of `harmonics` (those
/// `|n|` keeps within the record's Nyquist frequency over `band`) and reports each added one:
/// a harmonic the response carries but the estimate leaves out is absorbed by the harmonics
/// estimated, as a bias their standard errors do not show. The same weight choice `alpha` as
/// the estimate's.
///
/// # Errors
/// As [`siddiqi`] for the widened set.
pub fn outer_harmonics(
    record: &TimeSeries,
    period: f64,
    harmonics: &[i32],
    band: (f64, f64),
    alpha: Alpha,
    extra: i32,
) -> Result<Vec<OuterHarmonic>> {
    let (Some(&lo), Some(&hi)) = (harmonics.iter().min(), harmonics.iter().max()) else {
        return Ok(Vec::new());
    };
    let nyquist = std::f64::consts::PI / record.dt();
    let wp = std::f64::consts::TAU / period;
    let resolved =
        |n: i32| band.1 - f64::from(n) * wp <= nyquist && band.0 - f64::from(n) * wp >= -nyquist;
    let added: Vec<i32> = (lo - extra..=hi + extra)
        .filter(|n| !harmonics.contains(n) && resolved(*n))
        .collect();
    if added.is_empty() {
        return Ok(Vec::new());
    }
    let mut wide: Vec<i32> = harmonics
        .iter()
        .copied()
        .chain(added.iter().copied())
        .collect();
    wide.sort_unstable();
    let e = siddiqi(record, period, &wide, band, alpha)?;
    Ok(added
        .iter()
        .map(|&n| {
            let rows: Vec<_> = e.rows().filter(|r| r.n == n).collect();
            let significant = rows
                .iter()
                .filter(|r| r.stderr > 0.0 && r.value.norm() > 2.0 * r.stderr)
                .count();
            OuterHarmonic {
                n,
                significant_share: significant as f64 / rows.len().max(1) as f64,
                max_abs: rows.iter().map(|r| r.value.norm()).fold(0.0, f64::max),
            }
        })
        .collect())
}

/// The estimate of `prep`'s harmonics at its band's bins, with its bias, weight and degrees of
/// freedom.
fn assemble(prep: &Prepared, res: SmoothResult) -> Result<HtfEstimate> {
    let omegas = prep.omegas();
    Ok(HtfEstimate::new(
        Method::Siddiqi,
        prep.harmonics.clone(),
        vec![omegas; prep.harmonics.len()],
        res.values,
        res.stderr,
    )?
    .with_bias(BiasSource::Smoothing, res.bias)?
    .with_alpha(res.alpha, res.alpha_effective)
    .with_dof(res.dof))
}

/// Siddiqi's estimator at a fixed weight, prepared from a record's input before its output is
/// known: the normal matrix is built from the input alone, factored and inverted once, and
/// [`SiddiqiDesign::estimate`] then costs a transform of the output and three banded solves.
/// For any record with the same input, `SiddiqiDesign::new(..)?.estimate(record)` equals
/// [`siddiqi`] with [`Alpha::Fixed`], bit for bit. (A weight chosen by GCV depends on the
/// output and cannot be prepared.)
#[derive(Debug)]
pub struct SiddiqiDesign {
    prep: Prepared,
    sys: BinSystem,
    weight: AtWeight,
    input: Vec<f64>,
    dt: f64,
    t_start: f64,
}

impl SiddiqiDesign {
    /// Prepares the estimator from `record`'s input (its output is not read); the arguments
    /// are those of [`siddiqi`], with the dimensionless weight `alpha`.
    ///
    /// # Errors
    /// As [`siddiqi`].
    pub fn new(
        record: &TimeSeries,
        period: f64,
        harmonics: &[i32],
        band: (f64, f64),
        alpha: f64,
    ) -> Result<Self> {
        let prep = Prepared::inputs(
            std::slice::from_ref(record),
            period,
            harmonics,
            band,
            0,
            MIN_BINS,
        )?;
        let sys = BinSystem::inputs(&prep);
        let weight = AtWeight::new(&sys, alpha, 0.0)?;
        Ok(Self {
            prep,
            sys,
            weight,
            input: record.input().to_vec(),
            dt: record.dt(),
            t_start: record.time()[0],
        })
    }

    /// The `(n, omega)` of the estimate's rows, in the order of [`HtfEstimate::rows`], known
    /// before the output is.
    pub fn points(&self) -> Vec<(i32, f64)> {
        let omegas = self.prep.omegas();
        self.prep
            .harmonics
            .iter()
            .flat_map(|&n| omegas.iter().map(move |&w| (n, w)))
            .collect()
    }

    /// The estimate from `record`, whose input must be the one this was prepared from.
    ///
    /// # Errors
    /// [`Error::InputDiffers`] when the input, its sample interval or its start differ.
    pub fn estimate(&self, record: &TimeSeries) -> Result<HtfEstimate> {
        let input = record.input();
        // The same samples at the same times, bit for bit: the design is exact for its own
        // input only.
        let same_time = record.dt().to_bits() == self.dt.to_bits()
            && record.time().first().map(|t| t.to_bits()) == Some(self.t_start.to_bits());
        if input.len() != self.input.len() || !same_time {
            return Err(Error::InputDiffers {
                index: input.len().min(self.input.len()),
            });
        }
        if let Some(index) = input
            .iter()
            .zip(&self.input)
            .position(|(a, b)| a.to_bits() != b.to_bits())
        {
            return Err(Error::InputDiffers { index });
        }
        let y = self.prep.output_spectra(std::slice::from_ref(record));
        let mut sys = self.sys.clone();
        sys.set_outputs(&self.prep, &y);
        assemble(&self.prep, self.weight.estimate(&sys))
    }
}
