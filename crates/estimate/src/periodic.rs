//! The orbit from data alone: the pumping period of a record, and its split into the periodic
//! part (the period average, the limit cycle as measured) and the deviation from it that the
//! HTF estimators take.

use std::f64::consts::PI;

use num_complex::Complex64;
use rustfft::FftPlanner;

use crate::smooth::golden_min;
use crate::{Error, Result};

/// Largest drift, in samples over the whole record, of a period against a whole number of
/// samples that is still read as the sampling locked to the period: timestamps printed with
/// few digits (float32) give a step off by a few parts in 1e8, which drifts by a few 1e-5
/// samples over 300 periods; a pumping clock not locked to the sampling drifts by samples.
pub const LOCKED_DRIFT_SAMPLES: f64 = 0.01;

/// The sample step with which `period` holds a whole number `M` of samples, for a record of
/// `samples` samples `dt` apart: `period / M` where `period / dt` misses `M` by a drift of at
/// most [`LOCKED_DRIFT_SAMPLES`] over the record, `None` otherwise (the sampling is not locked
/// to the period: resample). [`split_periodic`] and the estimators need `N dt = P T` exactly.
pub fn locked_step(period: f64, dt: f64, samples: usize) -> Option<f64> {
    let per = period / dt;
    let whole = per.round();
    let drift = (per - whole).abs() * samples as f64 / per;
    (whole >= 1.0 && drift <= LOCKED_DRIFT_SAMPLES).then(|| period / whole)
}

/// A record split into its `T`-periodic part and the rest.
#[derive(Debug, Clone)]
pub struct PeriodicSplit {
    /// The record minus its periodic part (what the estimators take as output).
    pub deviation: Vec<f64>,
    /// Complex Fourier coefficients `c_k`, `k = 0..`, of the periodic part in absolute time:
    /// `y_periodic(t) = c_0 + 2 Re sum_{k>=1} c_k exp(j k wp t)`.
    pub harmonics: Vec<Complex64>,
    /// Whole periods in the record.
    pub periods: usize,
}

/// Splits `y` (uniform samples `dt` apart, the first at absolute time `t_start`) into its
/// periodic part at `period` and the deviation from it. The record must hold a whole number
/// of periods (`N dt = P T` to within `1e-6` periods, as for a record read by the estimators); the periodic
/// part is then exactly the DFT bins at multiples of `P`, i.e. the average over the `P`
/// periods at each phase, and removing it leaves every other bin untouched. `max_harmonic`
/// limits the coefficients reported (not the split, which removes every multiple up to
/// Nyquist).
///
/// # Errors
/// [`Error::NotWholePeriods`], [`Error::TooShort`], [`Error::InvalidPeriod`].
pub fn split_periodic(
    y: &[f64],
    dt: f64,
    t_start: f64,
    period: f64,
    max_harmonic: usize,
) -> Result<PeriodicSplit> {
    if !(period.is_finite() && period > 0.0) {
        return Err(Error::InvalidPeriod { period });
    }
    let n = y.len();
    if n < 4 {
        return Err(Error::TooShort {
            samples: n,
            minimum: 4,
        });
    }
    let periods_f = n as f64 * dt / period;
    let periods = periods_f.round();
    if periods < 1.0 || (periods_f - periods).abs() > 1e-6 {
        return Err(Error::NotWholePeriods {
            duration: n as f64 * dt,
            period,
            ratio: periods_f,
        });
    }
    let p = periods as usize;
    let mut buf: Vec<Complex64> = y.iter().map(|&v| Complex64::new(v, 0.0)).collect();
    let mut planner = FftPlanner::new();
    planner.plan_fft_forward(n).process(&mut buf);
    let wp = 2.0 * PI / period;
    let mut harmonics = Vec::new();
    let mut k = 0;
    while k * p <= n / 2 {
        let bin = k * p;
        if k <= max_harmonic {
            // Bin phases refer to t_start; rotate to absolute time.
            let rot = Complex64::from_polar(1.0, -(k as f64) * wp * t_start);
            harmonics.push(buf[bin] / n as f64 * rot.conj());
        }
        buf[bin] = Complex64::new(0.0, 0.0);
        if bin != 0 && n - bin != bin {
            buf[n - bin] = Complex64::new(0.0, 0.0);
        }
        k += 1;
    }
    planner.plan_fft_inverse(n).process(&mut buf);
    let deviation = buf.iter().map(|z| z.re / n as f64).collect();
    Ok(PeriodicSplit {
        deviation,
        harmonics,
        periods: p,
    })
}

/// The period found in a record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PeriodEstimate {
    /// The estimated period (s).
    pub period: f64,
    /// Harmonics of the fundamental used in the refinement.
    pub harmonics_used: usize,
    /// Share of the record's variance (mean removed) at the fundamental and its harmonics:
    /// near 1 for a record dominated by its orbit.
    pub periodic_share: f64,
}

/// Power of `y` (Hann-windowed, mean removed) at frequency `f` (Hz), by a direct DTFT.
fn power_at(y: &[f64], window: &[f64], dt: f64, f: f64) -> f64 {
    let w = 2.0 * PI * f * dt;
    let (mut re, mut im) = (0.0, 0.0);
    let step = Complex64::from_polar(1.0, -w);
    let mut z = Complex64::new(1.0, 0.0);
    for (i, (&v, &h)) in y.iter().zip(window).enumerate() {
        if i % 1024 == 0 {
            // Re-anchor the recurrence to keep its phase error at round-off.
            z = Complex64::from_polar(1.0, -w * i as f64);
        }
        re += v * h * z.re;
        im += v * h * z.im;
        z *= step;
    }
    re * re + im * im
}

/// Estimates the fundamental period of the strongest periodic component of `y` (uniform
/// samples `dt` apart): the largest spectral peak, moved down to a sub-multiple when that
/// carries at least a tenth of the peak's amplitude (a fundamental weaker than its
/// harmonics), then refined by maximising the power summed over the fundamental and its
/// harmonics up to Nyquist (at most 10) with a golden-section search within one DFT bin.
///
/// # Errors
/// [`Error::TooShort`] below 64 samples; [`Error::NoPeriodicComponent`] when no spectral
/// peak stands 30 times above the median (a flat spectrum).
pub fn estimate_period(y: &[f64], dt: f64) -> Result<PeriodEstimate> {
    let n = y.len();
    if n < 64 {
        return Err(Error::TooShort {
            samples: n,
            minimum: 64,
        });
    }
    let mean = y.iter().sum::<f64>() / n as f64;
    let centred: Vec<f64> = y.iter().map(|v| v - mean).collect();
    let window: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / (n - 1) as f64).cos())
        .collect();
    // Zero-padded spectrum, 4x, for the coarse peak.
    let m = (4 * n).next_power_of_two();
    let mut buf = vec![Complex64::new(0.0, 0.0); m];
    for i in 0..n {
        buf[i] = Complex64::new(centred[i] * window[i], 0.0);
    }
    FftPlanner::new().plan_fft_forward(m).process(&mut buf);
    let mag: Vec<f64> = buf[..m / 2].iter().map(|z| z.norm()).collect();
    let df = 1.0 / (m as f64 * dt);
    // Skip the window's main lobe around DC (4 padded bins per DFT bin, 2 DFT bins wide).
    let first = 8.min(m / 4);
    let (k_peak, peak) = mag
        .iter()
        .enumerate()
        .skip(first)
        .fold((first, 0.0), |a, (k, &v)| if v > a.1 { (k, v) } else { a });
    let median = {
        let mut s: Vec<f64> = mag[first..].to_vec();
        s.sort_by(f64::total_cmp);
        s[s.len() / 2]
    };
    if peak.is_nan() || peak <= 0.0 || peak < 30.0 * median {
        return Err(Error::NoPeriodicComponent);
    }
    let mut k_fund = k_peak as f64;
    for div in (2..=6).rev() {
        let k = k_peak as f64 / div as f64;
        if k < first as f64 {
            continue;
        }
        let lo = (k - 3.0).max(0.0) as usize;
        let hi = ((k + 3.0) as usize).min(mag.len() - 1);
        let local = mag[lo..=hi].iter().copied().fold(0.0, f64::max);
        if local >= 0.1 * peak {
            k_fund = k;
            break;
        }
    }
    let f0 = k_fund * df;
    let nyquist = 0.5 / dt;
    let harmonics = ((nyquist / f0).floor() as usize).clamp(1, 10);
    let score = |f: f64| -> f64 {
        (1..=harmonics)
            .map(|h| power_at(&centred, &window, dt, h as f64 * f))
            .sum()
    };
    // Golden-section search within one DFT bin of the record around the coarse estimate.
    let bin = 1.0 / (n as f64 * dt);
    let (f, _) = golden_min(|f| -score(f), f0 - bin, f0 + bin, 1e-12 * f0);
    // Share of the variance at the harmonics: a sinusoid of amplitude A has windowed DTFT
    // magnitude A sum(w) / 2 at its frequency and variance A^2 / 2.
    let gain: f64 = window.iter().sum();
    let variance = centred.iter().map(|v| v * v).sum::<f64>() / n as f64;
    let periodic = 2.0 * score(f) / (gain * gain);
    Ok(PeriodEstimate {
        period: 1.0 / f,
        harmonics_used: harmonics,
        periodic_share: if variance > 0.0 {
            (periodic / variance).min(1.0)
        } else {
            0.0
        },
    })
}
