//! Evidence a scientist reads: where in the state and in the forcing cycle the model's error
//! sits, and how the held-out error falls from the configured model to the final one.
//!
//! - [`binned_means`]: the mean of a residual in bins of position, velocity or forcing phase,
//!   with the standard error of each bin mean. Samples close in time are correlated (the
//!   smoother alone spans several samples), so the standard error treats blocks of
//!   consecutive samples as the independent units (a cluster-robust variance): each block's
//!   samples in a bin contribute their summed deviation from the bin mean.
//! - [`amplitude_spectrum`]: where in frequency a residual's error sits.
//! - [`period_average`]: a signal folded over the forcing period, with the standard error of
//!   each phase bin's mean across the periods.

use serde::{Deserialize, Serialize};

/// The mean of a residual over the samples whose explanatory variable falls in `[lo, hi)`
/// (the last bin includes `hi`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Bin {
    /// Lower edge of the bin.
    pub lo: f64,
    /// Upper edge of the bin.
    pub hi: f64,
    /// Mean of the explanatory variable over the bin's samples (where the mean is plotted).
    pub centre: f64,
    /// Samples in the bin.
    pub count: usize,
    /// Blocks (independent units of the standard error) with samples in the bin.
    pub blocks: usize,
    /// Mean of the residual over the bin's samples.
    pub mean: f64,
    /// Standard error of `mean`, blocks of consecutive samples taken as independent
    /// (cluster-robust, with the small-sample factor `G / (G - 1)` for `G` blocks); NaN
    /// (`null` in JSON) with fewer than [`MIN_BLOCKS`] blocks.
    pub stderr: f64,
}

/// Fewest blocks a bin's standard error is computed from. The cluster-robust variance from `G`
/// blocks has `G - 1` degrees of freedom: from 2 blocks the mean of a residual without
/// structure stands more than 637 of its standard errors from zero one time in a thousand
/// (Student's t with one degree of freedom), from 10 blocks more than 4.8, near the 3.3 of
/// many blocks. With fewer the bin has its mean but no standard error.
pub const MIN_BLOCKS: usize = 10;

/// Means of `y` in `bins` equal bins of `x` over `range`, each with its standard error; samples
/// outside `range` or not finite are left out, and so are bins without samples. `block[i]` is
/// the block (the independent unit of the standard error) of sample `i`: consecutive samples
/// whose residuals are correlated share a block. With every sample its own block the standard
/// error is the textbook `s / sqrt(n)`.
///
/// # Panics
///
/// When `x`, `y` and `block` differ in length (a broken contract of the caller).
pub fn binned_means(
    x: &[f64],
    y: &[f64],
    block: &[usize],
    bins: usize,
    range: (f64, f64),
) -> Vec<Bin> {
    assert!(
        x.len() == y.len() && x.len() == block.len(),
        "binned_means: x, y and block must have one entry per sample"
    );
    let (lo, hi) = range;
    if bins == 0 || !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return Vec::new();
    }
    let width = (hi - lo) / bins as f64;
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); bins];
    for (i, (&xi, &yi)) in x.iter().zip(y).enumerate() {
        if !(xi.is_finite() && yi.is_finite()) || xi < lo || xi > hi {
            continue;
        }
        let k = (((xi - lo) / width) as usize).min(bins - 1);
        members[k].push(i);
    }
    members
        .iter()
        .enumerate()
        .filter(|(_, m)| !m.is_empty())
        .map(|(k, m)| {
            let n = m.len() as f64;
            let mean = m.iter().map(|&i| y[i]).sum::<f64>() / n;
            let centre = m.iter().map(|&i| x[i]).sum::<f64>() / n;
            // Summed deviation per block, blocks in order of first appearance.
            let mut sums: Vec<(usize, f64)> = Vec::new();
            for &i in m {
                let d = y[i] - mean;
                match sums.iter_mut().find(|(b, _)| *b == block[i]) {
                    Some(s) => s.1 += d,
                    None => sums.push((block[i], d)),
                }
            }
            let g = sums.len();
            let stderr = if g >= MIN_BLOCKS {
                let ss: f64 = sums.iter().map(|(_, s)| s * s).sum();
                (g as f64 / (g as f64 - 1.0) * ss).sqrt() / n
            } else {
                f64::NAN
            };
            Bin {
                lo: lo + k as f64 * width,
                hi: lo + (k + 1) as f64 * width,
                centre,
                count: m.len(),
                blocks: g,
                mean,
                stderr,
            }
        })
        .collect()
}

/// The period average of `y` sampled at times `t` (s): its means in `bins` equal bins of the
/// phase `t mod period` over `[0, period)`, each with its standard error across the periods
/// (every period one block of [`binned_means`]: the samples of one pass through a phase are
/// correlated, the passes of different periods are taken as independent). Samples that are
/// not finite are left out, and so are bins without samples.
///
/// # Panics
///
/// When `t` and `y` differ in length (a broken contract of the caller).
pub fn period_average(t: &[f64], y: &[f64], period: f64, bins: usize) -> Vec<Bin> {
    assert_eq!(t.len(), y.len(), "period_average: one time per sample");
    if !(period.is_finite() && period > 0.0) {
        return Vec::new();
    }
    let phase: Vec<f64> = t.iter().map(|ti| ti.rem_euclid(period)).collect();
    let block: Vec<usize> = t
        .iter()
        .map(|ti| (ti / period).floor().max(0.0) as usize)
        .collect();
    binned_means(&phase, y, &block, bins, (0.0, period))
}

/// How far a set of bin means stands from zero, in their own standard errors.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Structure {
    /// `sum (mean / stderr)^2` over the bins with a standard error: chi-square with `bins`
    /// degrees of freedom for a residual with no structure and zero mean.
    pub chi_square: f64,
    /// Bins counted in `chi_square`.
    pub bins: usize,
    /// The largest `|mean| / stderr`.
    pub max_abs_z: f64,
    /// Smallest bin mean (of every bin, with a standard error or not).
    pub min_mean: f64,
    /// Largest bin mean.
    pub max_mean: f64,
}

impl Structure {
    /// The structure of `bins`: the test statistics over the bins with a standard error (zeros
    /// when none has one), the extreme means over all of them.
    pub fn of(bins: &[Bin]) -> Structure {
        let with_se: Vec<&Bin> = bins
            .iter()
            .filter(|b| b.stderr.is_finite() && b.stderr > 0.0)
            .collect();
        let z = |b: &&Bin| b.mean / b.stderr;
        Structure {
            chi_square: with_se.iter().map(|b| z(b).powi(2)).sum(),
            bins: with_se.len(),
            max_abs_z: with_se.iter().map(|b| z(b).abs()).fold(0.0, f64::max),
            min_mean: bins.iter().map(|b| b.mean).fold(f64::INFINITY, f64::min),
            max_mean: bins
                .iter()
                .map(|b| b.mean)
                .fold(f64::NEG_INFINITY, f64::max),
        }
    }
}

/// The residual acceleration of a model at the scored samples of a record.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ResidualSamples {
    /// Time of each sample (s).
    pub t: Vec<f64>,
    /// Smoothed position (output units; the sensor's offset and gain undone).
    pub x: Vec<f64>,
    /// Smoothed velocity (output units per s).
    pub v: Vec<f64>,
    /// Measured minus model acceleration (output units per s^2).
    pub residual: Vec<f64>,
}

/// Binned residual acceleration against position, velocity and (with a forcing period) the
/// forcing phase, for one model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BinnedResidual {
    /// Samples binned.
    pub samples: usize,
    /// Length of the blocks taken as independent in the standard errors (s).
    pub block_s: f64,
    /// Bins of position.
    pub by_position: Vec<Bin>,
    /// Bins of velocity.
    pub by_velocity: Vec<Bin>,
    /// Bins of the forcing phase, as time into the period `t mod T` (s); empty without a
    /// forcing period.
    pub by_phase: Vec<Bin>,
}

/// Bins of position and velocity, between their 0.5 % and 99.5 % quantiles (so that a few
/// extreme samples do not leave most bins empty).
pub const STATE_BINS: usize = 24;
/// Bins of the forcing phase over one period.
pub const PHASE_BINS: usize = 20;

impl BinnedResidual {
    /// Bins `samples` (a residual acceleration at each scored sample) in blocks of `block_s`
    /// seconds, by phase of `period` when it is given and positive. The state bins span `x_range` and `v_range`
    /// when given (so that two models share their bins), else the samples' own quantiles.
    pub fn new(
        samples: &ResidualSamples,
        block_s: f64,
        period: Option<f64>,
        x_range: Option<(f64, f64)>,
        v_range: Option<(f64, f64)>,
    ) -> BinnedResidual {
        let t0 = samples.t.first().copied().unwrap_or(0.0);
        let block: Vec<usize> = samples
            .t
            .iter()
            .map(|&t| {
                if block_s > 0.0 {
                    ((t - t0) / block_s).floor().max(0.0) as usize
                } else {
                    0
                }
            })
            .collect();
        let r = &samples.residual;
        let xr = x_range.unwrap_or_else(|| quantile_range(&samples.x));
        let vr = v_range.unwrap_or_else(|| quantile_range(&samples.v));
        let by_phase = match period {
            Some(p) if p > 0.0 && p.is_finite() => {
                let phase: Vec<f64> = samples.t.iter().map(|t| t.rem_euclid(p)).collect();
                binned_means(&phase, r, &block, PHASE_BINS, (0.0, p))
            }
            _ => Vec::new(),
        };
        BinnedResidual {
            samples: r.len(),
            block_s,
            by_position: binned_means(&samples.x, r, &block, STATE_BINS, xr),
            by_velocity: binned_means(&samples.v, r, &block, STATE_BINS, vr),
            by_phase,
        }
    }
}

/// The 0.5 % and 99.5 % quantiles of the finite values.
pub fn quantile_range(v: &[f64]) -> (f64, f64) {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return (f64::NAN, f64::NAN);
    }
    s.sort_by(f64::total_cmp);
    let at = |q: f64| s[((q * (s.len() - 1) as f64).round() as usize).min(s.len() - 1)];
    (at(0.005), at(0.995))
}

/// One step of the held-out error, from `before` to `after` (RMSE, output units).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ErrorStep {
    /// `configured`, `refitted`, an effect's name, or `final`.
    pub step: String,
    /// Held-out RMSE before the step (equal to `after` for `configured` and `final`, which
    /// are levels, not steps).
    pub before: f64,
    /// Held-out RMSE after it.
    pub after: f64,
}

/// One-sided amplitude spectrum of `x` sampled every `dt` s, its mean removed, through a Hann
/// window: `(omega, amplitude)` for the bins `1..n/2`, `omega` in rad/s and `amplitude = 4
/// |X_k| / n` (a sine of amplitude `a` on a bin reads `a`). Empty below 16 samples.
pub fn amplitude_spectrum(x: &[f64], dt: f64) -> (Vec<f64>, Vec<f64>) {
    use rustfft::{num_complex::Complex64, FftPlanner};
    let n = x.len();
    if n < 16 {
        return (Vec::new(), Vec::new());
    }
    let mean = x.iter().sum::<f64>() / n as f64;
    let mut buf: Vec<Complex64> = x
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let w = 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos();
            Complex64::new((v - mean) * w, 0.0)
        })
        .collect();
    FftPlanner::new().plan_fft_forward(n).process(&mut buf);
    let dw = 2.0 * std::f64::consts::PI / (n as f64 * dt);
    (1..n / 2)
        .map(|k| (k as f64 * dw, 4.0 * buf[k].norm() / n as f64))
        .unzip()
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    /// A sine on a bin reads its amplitude at its frequency (the Hann window's coherent gain
    /// of one half is undone), and a constant does not show.
    #[test]
    fn a_sine_on_a_bin_reads_its_amplitude() {
        let (n, dt) = (1024, 0.01);
        let w0 = 2.0 * std::f64::consts::PI * 37.0 / (n as f64 * dt);
        let x: Vec<f64> = (0..n)
            .map(|i| 5.0 + 0.3 * (w0 * i as f64 * dt + 0.4).sin())
            .collect();
        let (w, a) = amplitude_spectrum(&x, dt);
        assert_eq!(w.len(), n / 2 - 1);
        let k = a
            .iter()
            .enumerate()
            .max_by(|p, q| p.1.total_cmp(q.1))
            .map(|(k, _)| k)
            .unwrap();
        assert!((w[k] - w0).abs() < 1e-9, "peak at {} rad/s, not {w0}", w[k]);
        assert!((a[k] - 0.3).abs() < 1e-12, "amplitude {}", a[k]);
        assert!(
            a[0] < 1e-12,
            "the constant leaks into the first bin: {}",
            a[0]
        );
        assert!(amplitude_spectrum(&x[..15], dt).0.is_empty());
    }

    /// A sine of period `T` folded over `T`: each of 10 bins holds the mean of the sine over
    /// its phases, `(cos a - cos b) / (b - a)` for a bin from `a` to `b` rad (the samples'
    /// midpoint rule differs from the integral by about `h^2 f'' / 24`, 2e-6 at 1000 samples
    /// a period: 1e-5 allowed). White noise of 0.1 added (seeded) over 400 periods: each bin's
    /// standard error across the periods is `0.1 / sqrt(n)` for its `n` samples, within 20 %
    /// (400 blocks estimate it to about 4 %).
    #[test]
    fn a_folded_sine_reads_its_bin_averages_and_noise_its_standard_error() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        use std::f64::consts::PI;
        let (period, per, periods) = (0.8, 1000, 400);
        let dt = period / per as f64;
        let t: Vec<f64> = (0..per * periods).map(|i| (i as f64 + 0.5) * dt).collect();
        let y: Vec<f64> = t.iter().map(|ti| (2.0 * PI * ti / period).sin()).collect();
        let bins = period_average(&t, &y, period, 10);
        assert_eq!(bins.len(), 10);
        for (k, b) in bins.iter().enumerate() {
            let (a, c) = (2.0 * PI * k as f64 / 10.0, 2.0 * PI * (k + 1) as f64 / 10.0);
            let exact = (a.cos() - c.cos()) / (c - a);
            assert_abs_diff_eq!(b.mean, exact, epsilon = 1e-5);
            assert_eq!((b.count, b.blocks), (100 * periods, periods));
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let normal = Normal::new(0.0, 0.1).unwrap();
        let noisy: Vec<f64> = y.iter().map(|v| v + normal.sample(&mut rng)).collect();
        for b in period_average(&t, &noisy, period, 10) {
            let expected = 0.1 / (b.count as f64).sqrt();
            assert!(
                (b.stderr / expected - 1.0).abs() < 0.2,
                "stderr {} against {expected}",
                b.stderr
            );
        }
        assert!(period_average(&t, &y, 0.0, 10).is_empty());
    }

    #[test]
    fn bin_means_and_standard_errors_by_hand() {
        // Bin [0, 1): y = 1, 2, ..., 20 at x = 0.025, 0.05, ..., 0.5, mean 10.5. Each sample
        // its own block: sample variance 35, stderr sqrt(35 / 20) = sqrt(7/4).
        // Blocks of two, {1, 2}, {3, 4}, ...: summed deviations -18, -14, ..., 18 (ten blocks,
        // sum of squares 1320), stderr sqrt(10 / 9 * 1320) / 20 = sqrt(4400 / 3) / 20.
        // Blocks of four: five blocks, too few for a standard error. Bin [1, 2): one sample,
        // no standard error.
        let mut x: Vec<f64> = (1..=20).map(|i| 0.025 * f64::from(i)).collect();
        let mut y: Vec<f64> = (1..=20).map(f64::from).collect();
        x.push(1.5);
        y.push(10.0);
        let own: Vec<usize> = (0..21).collect();
        let bins = binned_means(&x, &y, &own, 2, (0.0, 2.0));
        assert_eq!(bins.len(), 2);
        assert_abs_diff_eq!(bins[0].mean, 10.5, epsilon = 1e-12);
        assert_abs_diff_eq!(bins[0].centre, 0.2625, epsilon = 1e-12);
        assert_abs_diff_eq!(bins[0].stderr, (7.0f64 / 4.0).sqrt(), epsilon = 1e-12);
        assert_eq!((bins[0].count, bins[0].blocks), (20, 20));
        assert_abs_diff_eq!(bins[1].mean, 10.0, epsilon = 1e-12);
        assert!(bins[1].stderr.is_nan());
        let pairs: Vec<usize> = (0..21).map(|i| i / 2).collect();
        let blocked = binned_means(&x, &y, &pairs, 2, (0.0, 2.0));
        assert_abs_diff_eq!(
            blocked[0].stderr,
            (4400.0f64 / 3.0).sqrt() / 20.0,
            epsilon = 1e-12
        );
        assert_eq!(blocked[0].blocks, MIN_BLOCKS);
        let fours: Vec<usize> = (0..21).map(|i| i / 4).collect();
        let few = binned_means(&x, &y, &fours, 2, (0.0, 2.0));
        assert_eq!(few[0].blocks, 5);
        assert!(few[0].stderr.is_nan(), "{}", few[0].stderr);
        // Outside the range, not finite, or no bins: left out.
        let none = binned_means(&[5.0, f64::NAN], &[1.0, 1.0], &[0, 1], 3, (0.0, 1.0));
        assert!(none.is_empty());
        assert!(binned_means(&x, &y, &[0; 21], 0, (0.0, 1.0)).is_empty());
        // The upper edge belongs to the last bin.
        let edge = binned_means(&[1.0], &[3.0], &[0], 4, (0.0, 1.0));
        assert_abs_diff_eq!(edge[0].lo, 0.75, epsilon = 1e-12);
    }

    #[test]
    fn a_residual_known_in_position_comes_back_in_the_bins() {
        // y = 3 x^2 on a fine uniform grid of x in [-1, 1]: the mean over a bin of width
        // w = 0.25 centred at c is 3 (c^2 + w^2 / 12), up to the grid's discreteness.
        let n = 40_001;
        let x: Vec<f64> = (0..n)
            .map(|i| -1.0 + 2.0 * i as f64 / (n - 1) as f64)
            .collect();
        let y: Vec<f64> = x.iter().map(|v| 3.0 * v * v).collect();
        let block: Vec<usize> = (0..n).map(|i| i / 100).collect();
        let bins = binned_means(&x, &y, &block, 8, (-1.0, 1.0));
        assert_eq!(bins.len(), 8);
        for b in &bins {
            let c = 0.5 * (b.lo + b.hi);
            assert_abs_diff_eq!(
                b.mean,
                3.0 * (c * c + 0.25f64.powi(2) / 12.0),
                epsilon = 1e-3
            );
            assert_abs_diff_eq!(b.centre, c, epsilon = 1e-4);
        }
        let s = Structure::of(&bins);
        assert_eq!(s.bins, 8);
        assert!(s.max_abs_z > 10.0);
        assert_abs_diff_eq!(
            s.max_mean,
            3.0 * (0.875f64.powi(2) + 0.25f64.powi(2) / 12.0),
            epsilon = 1e-3
        );
    }
}
