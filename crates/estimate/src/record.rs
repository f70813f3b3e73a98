//! Records, the absolute-time DFT and the bin grid shared by the estimators.

use std::f64::consts::PI;
use std::sync::Arc;

use htfid_data::TimeSeries;
use num_complex::Complex64;
use rustfft::{Fft, FftPlanner};

use crate::error::{Error, Result};

/// Shortest record accepted (a few samples, so that a DFT has more than a DC bin).
const MIN_SAMPLES: usize = 4;

/// How far `N dt / T` may be from an integer, in periods. Sample intervals such as 0.01 s are not
/// exact in binary, so a 270 s record at 100 Hz is 270.00000000000003 periods of 1 s; a phase error
/// of `2 pi 1e-6` per period is far below anything the estimators resolve.
const WHOLE_PERIOD_TOL: f64 = 1e-6;

/// Checks a record the estimators read: one output (a deviation from the limit cycle, the
/// caller subtracts the orbit) and at least 4 samples, so that a DFT has more than a DC bin.
/// The estimators read `input()[i]` and `output()[i]` at absolute time `time()[0] + i dt()`.
pub(crate) fn check_record(r: &TimeSeries) -> Result<()> {
    if r.outputs().len() != 1 {
        return Err(Error::SeveralOutputs {
            outputs: r.outputs().len(),
        });
    }
    if r.len() < MIN_SAMPLES {
        return Err(Error::TooShort {
            samples: r.len(),
            minimum: MIN_SAMPLES,
        });
    }
    Ok(())
}

/// A record of deviations `u`, `y` sampled every `dt` from `t_start`, for the estimators.
pub fn deviation_record(u: Vec<f64>, y: Vec<f64>, dt: f64, t_start: f64) -> Result<TimeSeries> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(Error::InvalidTimeStep { dt });
    }
    let r = TimeSeries::from_step(t_start, dt, u, vec![y], "deviations from the orbit").map_err(
        |e| Error::Record {
            reason: e.to_string(),
        },
    )?;
    check_record(&r)?;
    Ok(r)
}

fn check_finite(signal: &'static str, x: &[f64]) -> Result<()> {
    match x.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(Error::NonFiniteSample {
            signal,
            index,
            value: x[index],
        }),
        None => Ok(()),
    }
}

/// DFT with phase referenced to absolute time:
/// `X[k] = dt * sum_i x[i] exp(-j w_k (t_start + i dt))`, `w_k = 2 pi k / (N dt)`.
///
/// Returns the `N` bins in FFT order (`k = 0..N/2` then the negative frequencies
/// `k = -(N - N/2 - 1)..-1`). For an `N dt`-periodic signal with Fourier coefficients `c_k`
/// (`x(t) = sum_k c_k exp(j w_k t)`), `X[k] = N dt c_k` whatever `t_start` is.
pub fn dft(x: &[f64], dt: f64, t_start: f64) -> Result<Vec<Complex64>> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(Error::InvalidTimeStep { dt });
    }
    if !t_start.is_finite() {
        return Err(Error::InvalidStartTime { t_start });
    }
    check_finite("input", x)?;
    if x.is_empty() {
        return Err(Error::TooShort {
            samples: 0,
            minimum: 1,
        });
    }
    let fft = FftPlanner::new().plan_fft_forward(x.len());
    Ok(Spectrum::new(x, dt, t_start, &fft).bins)
}

/// Bins between phase factors of [`Spectrum::new`] computed from their own phase; the bins
/// between take the previous bin's factor times one bin's, each multiplication adding about
/// one rounding (so at most about `32 * 1.1e-16` relative, below the error of the exact phase
/// itself for bins beyond 32, `|k| * 1.1e-16` turns).
const ANCHOR_EVERY: usize = 32;

/// A full DFT indexed by signed bin number.
#[derive(Debug, Clone)]
pub(crate) struct Spectrum {
    bins: Vec<Complex64>,
}

impl Spectrum {
    /// Transforms `x` with the absolute-time convention of [`dft`]; `fft` must have length
    /// `x.len()`.
    pub(crate) fn new(x: &[f64], dt: f64, t_start: f64, fft: &Arc<dyn Fft<f64>>) -> Self {
        let n = x.len();
        let mut bins: Vec<Complex64> = x.iter().map(|&v| Complex64::new(v, 0.0)).collect();
        fft.process(&mut bins);
        // The phase of bin k is -2 pi k t_start / (N dt); it is formed from the fractional
        // number of turns so that large start times do not lose digits, exactly every
        // `ANCHOR_EVERY` bins and by one bin's factor in between.
        let turns_per_bin = t_start / (n as f64 * dt);
        let exact = |k: i64| {
            let turns = k as f64 * turns_per_bin;
            Complex64::from_polar(dt, -2.0 * PI * (turns - turns.round()))
        };
        let step = Complex64::from_polar(1.0, -2.0 * PI * (turns_per_bin - turns_per_bin.round()));
        let mut factor = Complex64::new(0.0, 0.0);
        let mut previous: Option<i64> = None;
        for (i, b) in bins.iter_mut().enumerate() {
            let k = signed_bin(i, n);
            factor = if i % ANCHOR_EVERY == 0 || previous != Some(k - 1) {
                exact(k)
            } else {
                factor * step
            };
            previous = Some(k);
            *b *= factor;
        }
        Self { bins }
    }

    /// `(self - other) / 2`, bin by bin (the odd part of a `+u` / `-u` pair).
    pub(crate) fn half_difference(&self, other: &Self) -> Self {
        Self {
            bins: self
                .bins
                .iter()
                .zip(&other.bins)
                .map(|(a, b)| (a - b) * 0.5)
                .collect(),
        }
    }

    /// Bin `k` (signed, `|k| < N/2` for meaningful values).
    #[inline]
    pub(crate) fn at(&self, k: i64) -> Complex64 {
        let n = self.bins.len() as i64;
        self.bins[k.rem_euclid(n) as usize]
    }
}

/// Signed bin number of FFT index `i` for length `n`.
fn signed_bin(i: usize, n: usize) -> i64 {
    if 2 * i <= n {
        i as i64
    } else {
        i as i64 - n as i64
    }
}

/// The DFT grid of a record length that is a whole number of system periods.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Grid {
    /// Samples per record.
    pub n: usize,
    /// Sample interval, s.
    pub dt: f64,
    /// System periods per record: the pumping frequency is `p` bins.
    pub p: i64,
    /// Bin spacing `2 pi / (N dt)`, rad/s.
    pub dw: f64,
}

impl Grid {
    pub(crate) fn new(n: usize, dt: f64, period: f64) -> Result<Self> {
        validate_period(period)?;
        let duration = n as f64 * dt;
        let ratio = duration / period;
        let p = ratio.round();
        if p < 1.0 || (ratio - p).abs() > WHOLE_PERIOD_TOL {
            return Err(Error::NotWholePeriods {
                duration,
                period,
                ratio,
            });
        }
        Ok(Self {
            n,
            dt,
            p: p as i64,
            dw: 2.0 * PI / duration,
        })
    }

    pub(crate) fn omega(&self, k: i64) -> f64 {
        k as f64 * self.dw
    }

    /// Strictly below Nyquist, where a bin of a real signal is unambiguous.
    pub(crate) fn below_nyquist(&self, k: i64) -> bool {
        2 * k.unsigned_abs() < self.n as u64
    }

    pub(crate) fn nyquist(&self) -> f64 {
        PI / self.dt
    }
}

pub(crate) fn validate_period(period: f64) -> Result<()> {
    if period.is_finite() && period > 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidPeriod { period })
    }
}

pub(crate) fn validate_harmonics(harmonics: &[i32]) -> Result<()> {
    if harmonics.is_empty() {
        return Err(Error::NoHarmonics);
    }
    for (i, &n) in harmonics.iter().enumerate() {
        if harmonics[..i].contains(&n) {
            return Err(Error::DuplicateHarmonic { n });
        }
    }
    Ok(())
}

/// Records transformed onto one grid, with the output bins of a band.
#[derive(Debug)]
pub(crate) struct Prepared {
    pub grid: Grid,
    pub harmonics: Vec<i32>,
    /// Bin shift of each harmonic, `n * P`.
    pub shifts: Vec<i64>,
    /// First output bin of the band.
    pub k_lo: i64,
    /// Number of output bins in the band.
    pub m: usize,
    pub u: Vec<Spectrum>,
    pub y: Vec<Spectrum>,
    /// Start time of each record, s.
    pub t_starts: Vec<f64>,
}

impl Prepared {
    /// Validates the records, harmonics and band, and transforms every record.
    ///
    /// `margin` extra bins on each side of the band must also stay below Nyquist (the local
    /// polynomial window reads them); `min_bins` is the smallest band accepted.
    pub(crate) fn new(
        records: &[TimeSeries],
        period: f64,
        harmonics: &[i32],
        band: (f64, f64),
        margin: usize,
        min_bins: usize,
    ) -> Result<Self> {
        let mut prepared = Self::inputs(records, period, harmonics, band, margin, min_bins)?;
        prepared.y = prepared.output_spectra(records);
        Ok(prepared)
    }

    /// The transformed outputs of `records`: records of the length and sample interval of
    /// those the inputs were prepared from, whose inputs are those inputs.
    pub(crate) fn output_spectra(&self, records: &[TimeSeries]) -> Vec<Spectrum> {
        let fft = FftPlanner::new().plan_fft_forward(self.grid.n);
        records
            .iter()
            .map(|r| Spectrum::new(r.output(), r.dt(), r.time()[0], &fft))
            .collect()
    }

    /// As [`Prepared::new`], but the outputs are not transformed (`y` is left empty; see
    /// [`Prepared::output_spectra`]).
    pub(crate) fn inputs(
        records: &[TimeSeries],
        period: f64,
        harmonics: &[i32],
        band: (f64, f64),
        margin: usize,
        min_bins: usize,
    ) -> Result<Self> {
        let first = records.first().ok_or(Error::NoRecords)?;
        for r in records {
            check_record(r)?;
        }
        validate_harmonics(harmonics)?;
        for (index, r) in records.iter().enumerate().skip(1) {
            // Equal dt to rounding: records cut from one experiment share dt exactly.
            if r.len() != first.len() || (r.dt() - first.dt()).abs() > 1e-12 * first.dt() {
                return Err(Error::RecordsDiffer {
                    index,
                    samples: r.len(),
                    dt: r.dt(),
                    expected_samples: first.len(),
                    expected_dt: first.dt(),
                });
            }
        }
        let grid = Grid::new(first.len(), first.dt(), period)?;
        let (lo, hi) = band;
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(Error::InvalidBand { lo, hi });
        }
        // A band edge that lands on a bin to rounding includes that bin.
        let k_lo = (lo / grid.dw - 1e-9).ceil() as i64;
        let k_hi = (hi / grid.dw + 1e-9).floor() as i64;
        let bins = (k_hi - k_lo + 1).max(0) as usize;
        if bins < min_bins {
            return Err(Error::TooFewBins {
                lo,
                hi,
                bins,
                spacing: grid.dw,
                minimum: min_bins,
            });
        }
        let shifts: Vec<i64> = harmonics.iter().map(|&n| i64::from(n) * grid.p).collect();
        let margin = margin as i64;
        for (&n, &s) in harmonics.iter().zip(&shifts) {
            for (k_out, k_need) in [
                (k_lo, k_lo - margin),
                (k_hi, k_hi + margin),
                (k_lo, k_lo - margin - s),
                (k_hi, k_hi + margin - s),
            ] {
                if !grid.below_nyquist(k_need) {
                    return Err(Error::BeyondNyquist {
                        omega: grid.omega(k_out),
                        n,
                        needed: grid.omega(k_need),
                        nyquist: grid.nyquist(),
                    });
                }
            }
        }
        let fft = FftPlanner::new().plan_fft_forward(grid.n);
        let u = records
            .iter()
            .map(|r| Spectrum::new(r.input(), r.dt(), r.time()[0], &fft))
            .collect();
        Ok(Self {
            grid,
            harmonics: harmonics.to_vec(),
            shifts,
            k_lo,
            m: bins,
            u,
            y: Vec::new(),
            t_starts: records.iter().map(|r| r.time()[0]).collect(),
        })
    }

    pub(crate) fn records(&self) -> usize {
        self.u.len()
    }

    pub(crate) fn omegas(&self) -> Vec<f64> {
        (0..self.m as i64)
            .map(|kb| self.grid.omega(self.k_lo + kb))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// Slow, obvious DFT straight from the documented formula.
    fn naive(x: &[f64], dt: f64, t_start: f64) -> Vec<Complex64> {
        let n = x.len();
        (0..n)
            .map(|i| {
                let k = signed_bin(i, n) as f64;
                let w = 2.0 * PI * k / (n as f64 * dt);
                x.iter()
                    .enumerate()
                    .map(|(s, &v)| Complex64::from_polar(v * dt, -w * (t_start + s as f64 * dt)))
                    .sum()
            })
            .collect()
    }

    #[test]
    fn dft_matches_the_documented_formula() {
        // Odd and even lengths, a start time that is not a multiple of dt and a large one.
        for (n, t_start) in [(37usize, 0.123), (64, -5.5), (50, 1234.567)] {
            let x: Vec<f64> = (0..n)
                .map(|i| ((i * 7919) % 97) as f64 / 97.0 - 0.5)
                .collect();
            let fast = dft(&x, 0.02, t_start).unwrap();
            let slow = naive(&x, 0.02, t_start);
            // The naive sum accumulates phase error ~ w t eps ~ 1e-10 at t = 1234 s; 1e-9 of the
            // spectrum's scale leaves room for it.
            let scale: f64 = slow.iter().map(|c| c.norm()).fold(0.0, f64::max);
            for (a, b) in fast.iter().zip(&slow) {
                assert!((a - b).norm() <= 1e-9 * scale, "{a} vs {b}");
            }
        }
    }

    #[test]
    fn dft_phase_factors_between_anchors_are_exact_to_rounding() {
        // The DFT of a unit impulse at the first sample is `dt exp(-j w_k t_start)`: the phase
        // factors themselves. With dt, N and t_start powers of two apart, `k t_start / (N dt)`
        // is exact in f64, so the reference below is exact to one rounding of `from_polar`,
        // while the DFT reaches most bins through up to 31 multiplications by one bin's factor
        // (about two roundings each): 2e-14 of dt bounds both.
        let (n, dt, t_start) = (4096usize, 0.0625, 1234.5625);
        let mut x = vec![0.0; n];
        x[0] = 1.0;
        let s = dft(&x, dt, t_start).unwrap();
        let turns_per_bin = t_start / (n as f64 * dt);
        for (i, got) in s.iter().enumerate() {
            let k = signed_bin(i, n) as f64;
            let turns = k * turns_per_bin;
            let expect = Complex64::from_polar(dt, -2.0 * PI * (turns - turns.round()));
            assert!(
                (got - expect).norm() <= 2e-14 * dt,
                "bin {k}: {got} vs {expect}"
            );
        }
    }

    #[test]
    fn dft_of_a_periodic_cosine_is_independent_of_the_start_time() {
        // x(t) = cos(w1 t + 0.3) has c_1 = exp(0.3 j)/2, so X[1] = N dt c_1 for any t_start.
        let (n, dt) = (40usize, 0.05);
        let w1 = 2.0 * PI / (n as f64 * dt);
        for t_start in [0.0, 0.013, 17.3] {
            let x: Vec<f64> = (0..n)
                .map(|i| (w1 * (t_start + i as f64 * dt) + 0.3).cos())
                .collect();
            let s = dft(&x, dt, t_start).unwrap();
            let expect = Complex64::from_polar(n as f64 * dt / 2.0, 0.3);
            // Rounding only: 1e-12 relative.
            assert_relative_eq!(s[1].re, expect.re, epsilon = 1e-12);
            assert_relative_eq!(s[1].im, expect.im, epsilon = 1e-12);
        }
    }

    #[test]
    fn grid_rejects_fractional_periods_and_accepts_rounding() {
        assert!(matches!(
            Grid::new(150, 0.01, 1.0),
            Err(Error::NotWholePeriods { .. })
        ));
        let g = Grid::new(27_000, 0.01, 1.0).unwrap();
        assert_eq!(g.p, 270);
        assert!(matches!(
            Grid::new(100, 0.01, -1.0),
            Err(Error::InvalidPeriod { .. })
        ));
    }

    #[test]
    fn record_validation_messages() {
        let e = deviation_record(vec![0.0; 5], vec![0.0; 4], 0.1, 0.0).unwrap_err();
        assert_eq!(
            e.to_string(),
            "record: deviations from the orbit: column \"output\" has 4 values, the time vector \
             has 5"
        );
        let e = deviation_record(vec![0.0; 5], vec![0.0, 0.0, f64::NAN, 0.0, 0.0], 0.1, 0.0)
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "record: deviations from the orbit: row 2: column \"output\": value \"NaN\" is not a \
             finite number"
        );
        assert!(matches!(
            deviation_record(vec![0.0; 5], vec![0.0; 5], 0.0, 0.0),
            Err(Error::InvalidTimeStep { .. })
        ));
        assert!(matches!(
            deviation_record(vec![0.0; 3], vec![0.0; 3], 0.1, 0.0),
            Err(Error::TooShort {
                samples: 3,
                minimum: 4
            })
        ));
        let two = TimeSeries::with_outputs(
            vec![0.0, 0.1, 0.2, 0.3, 0.4],
            vec![0.0; 5],
            vec![vec![0.0; 5], vec![1.0; 5]],
            "two",
        )
        .unwrap();
        assert!(matches!(
            check_record(&two),
            Err(Error::SeveralOutputs { outputs: 2 })
        ));
    }
}
