//! Fourier coefficients of periodic matrix functions.
//!
//! Convention: `M(t) = sum_n M_n exp(j n wp t)`,
//! `M_n = (1/T) int_0^T M(t) exp(-j n wp t) dt`, `wp = 2 pi / T`.

use crate::piecewise::{LtpError, PiecewiseLti, SystemMatrix};
use nalgebra::DMatrix;
use num_complex::Complex64;
use rustfft::FftPlanner;
use std::f64::consts::TAU;

/// `sin(x) / x`, equal to 1 at 0.
fn sinc(x: f64) -> f64 {
    if x.abs() < 1e-4 {
        // Two Taylor terms: the next one, x^4/120, is below 1e-18.
        1.0 - x * x / 6.0
    } else {
        x.sin() / x
    }
}

/// Fourier coefficient `n` of the indicator of `[t0, t0 + duration)` repeated
/// with period `period`, for `0 <= duration <= period`.
///
/// Written as `(h/T) exp(-j n wp (t0 + h/2)) sinc(n wp h / 2)`: this is the
/// closed form `(exp(-j n wp t1) - exp(-j n wp t0)) / (-j n wp T)` without its
/// cancellation at small `n wp h`.
pub(crate) fn interval_fourier(t0: f64, duration: f64, period: f64, n: i32) -> Complex64 {
    let wp = TAU / period;
    let theta = f64::from(n) * wp;
    let centre = t0 + 0.5 * duration;
    // Reduce the phase argument so large times do not lose digits.
    let phase = -(theta * centre).rem_euclid(TAU);
    Complex64::from_polar(duration / period * sinc(0.5 * theta * duration), phase)
}

/// Fourier coefficient `s_n` of the square wave `s(t) = 1` for
/// `t mod T` in `[t_on, t_off)` and 0 otherwise, in closed form.
///
/// The on-interval may wrap through `t = 0` (`t_off < t_on`). Its length is
/// `t_off - t_on` when that lies in `[0, T]` (so `t_on = 0, t_off = T` is the
/// constant 1), and `(t_off - t_on) mod T` otherwise. Returns NaN when
/// `period` is not finite and positive or a time is not finite.
///
/// `s_n = (exp(-j n wp t_off) - exp(-j n wp t_on)) / (-j n wp T)` for
/// `n != 0`, `s_0 = duty cycle`; `|s_n| <= 1 / (pi |n|)`.
pub fn square_wave_fourier(t_on: f64, t_off: f64, period: f64, n: i32) -> Complex64 {
    if !(period.is_finite() && period > 0.0 && t_on.is_finite() && t_off.is_finite()) {
        return Complex64::new(f64::NAN, f64::NAN);
    }
    let span = t_off - t_on;
    let duration = if (0.0..=period).contains(&span) {
        span
    } else {
        span.rem_euclid(period)
    };
    interval_fourier(t_on, duration, period, n)
}

impl PiecewiseLti {
    /// Fourier coefficient `n` of the piecewise-constant matrix function
    /// selected by `which` (for example `A(t)`), in closed form:
    /// `M_n = sum_i M_i (exp(-j n wp tau_{i+1}) - exp(-j n wp tau_i)) / (-j n wp T)`.
    ///
    /// Jump matrices are not part of `A(t)` and are ignored here.
    pub fn fourier_coefficient(&self, which: SystemMatrix, n: i32) -> DMatrix<Complex64> {
        let first = self.pieces()[0].matrix(which);
        let mut out = DMatrix::<Complex64>::zeros(first.nrows(), first.ncols());
        for (i, piece) in self.pieces().iter().enumerate() {
            let w = interval_fourier(self.piece_start(i), piece.duration(), self.period(), n);
            let m = piece.matrix(which);
            out.zip_apply(m, |o, v| *o += w * v);
        }
        out
    }
}

/// Fourier coefficients `M_n`, `|n| <= max_harmonic`, of a periodic matrix
/// function, as produced by [`fft_fourier`].
#[derive(Debug, Clone, PartialEq)]
pub struct MatrixFourierSeries {
    period: f64,
    max_harmonic: usize,
    /// `coeffs[n + max_harmonic] = M_n`.
    coeffs: Vec<DMatrix<Complex64>>,
}

impl MatrixFourierSeries {
    /// The period `T`.
    pub fn period(&self) -> f64 {
        self.period
    }

    /// Largest harmonic index held.
    pub fn max_harmonic(&self) -> usize {
        self.max_harmonic
    }

    /// Shape (rows, columns) of the matrix function.
    pub fn shape(&self) -> (usize, usize) {
        self.coeffs[0].shape()
    }

    /// Coefficient `M_n`, or `None` when `|n| > max_harmonic`.
    pub fn coefficient(&self, n: i32) -> Option<&DMatrix<Complex64>> {
        let idx = i64::from(n) + self.max_harmonic as i64;
        usize::try_from(idx).ok().and_then(|i| self.coeffs.get(i))
    }

    /// The truncated series `sum_{|n| <= max} M_n exp(j n wp t)` at time `t`.
    pub fn evaluate(&self, t: f64) -> DMatrix<Complex64> {
        let (r, c) = self.shape();
        let mut out = DMatrix::<Complex64>::zeros(r, c);
        let wp = TAU / self.period;
        let max = self.max_harmonic as i64;
        for (k, m) in self.coeffs.iter().enumerate() {
            let n = k as i64 - max;
            let e = Complex64::from_polar(1.0, (n as f64 * wp * t).rem_euclid(TAU));
            out.zip_apply(m, |o, v| *o += e * v);
        }
        out
    }
}

/// Fourier coefficients of a `period`-periodic matrix function from `K`
/// equally spaced samples `samples[k] = M(k T / K)`, by FFT.
///
/// Returns `M_n` for `|n| <= (K - 1) / 2` (the Nyquist bin of an even `K`
/// is dropped since it mixes `n = +K/2` and `-K/2`). The DFT coefficient is
/// the aliased sum `sum_l M_{n + l K}`: for smooth `M` the error decays
/// faster than any power of `K`; for piecewise-constant `M` (a square wave)
/// it is `O(1/K)`, because `|M_n|` only decays like `1/n` and the sample
/// grid cannot see where in a sample interval a switch happens.
pub fn fft_fourier(period: f64, samples: &[DMatrix<f64>]) -> Result<MatrixFourierSeries, LtpError> {
    if !(period.is_finite() && period > 0.0) {
        return Err(LtpError::InvalidPeriod { period });
    }
    let count = samples.len();
    let first = samples.first().ok_or(LtpError::TooFewSamples { count })?;
    let (rows, cols) = first.shape();
    for (index, s) in samples.iter().enumerate() {
        if s.shape() != (rows, cols) {
            return Err(LtpError::SampleShapeMismatch {
                index,
                expected_rows: rows,
                expected_cols: cols,
                found_rows: s.nrows(),
                found_cols: s.ncols(),
            });
        }
        if let Some(pos) = s.iter().position(|v| !v.is_finite()) {
            return Err(LtpError::NonFiniteSample {
                index,
                row: pos % rows,
                col: pos / rows,
            });
        }
    }
    let max_harmonic = (count - 1) / 2;
    let mut coeffs = vec![DMatrix::<Complex64>::zeros(rows, cols); 2 * max_harmonic + 1];
    let fft = FftPlanner::<f64>::new().plan_fft_forward(count);
    let mut buffer = vec![Complex64::new(0.0, 0.0); count];
    let mut scratch = vec![Complex64::new(0.0, 0.0); fft.get_inplace_scratch_len()];
    let scale = 1.0 / count as f64;
    for c in 0..cols {
        for r in 0..rows {
            for (b, s) in buffer.iter_mut().zip(samples) {
                *b = Complex64::new(s[(r, c)], 0.0);
            }
            fft.process_with_scratch(&mut buffer, &mut scratch);
            for n in -(max_harmonic as i64)..=(max_harmonic as i64) {
                let bin = n.rem_euclid(count as i64) as usize;
                coeffs[(n + max_harmonic as i64) as usize][(r, c)] = buffer[bin] * scale;
            }
        }
    }
    Ok(MatrixFourierSeries {
        period,
        max_harmonic,
        coeffs,
    })
}

/// Samples `f` at `count` equally spaced times `k T / count` and returns
/// [`fft_fourier`] of the samples.
pub fn fft_fourier_fn<F>(period: f64, count: usize, f: F) -> Result<MatrixFourierSeries, LtpError>
where
    F: FnMut(f64) -> DMatrix<f64>,
{
    if !(period.is_finite() && period > 0.0) {
        return Err(LtpError::InvalidPeriod { period });
    }
    let dt = period / count as f64;
    let samples: Vec<_> = (0..count).map(|k| k as f64 * dt).map(f).collect();
    fft_fourier(period, &samples)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::piecewise::Piece;
    use nalgebra::dmatrix;

    /// The textbook closed form, written independently of `interval_fourier`.
    fn textbook(t_on: f64, t_off: f64, period: f64, n: i32) -> Complex64 {
        if n == 0 {
            return Complex64::new((t_off - t_on) / period, 0.0);
        }
        let wn = f64::from(n) * TAU / period;
        let e = |t: f64| Complex64::from_polar(1.0, -wn * t);
        (e(t_off) - e(t_on)) / Complex64::new(0.0, -wn * period)
    }

    #[test]
    fn square_wave_matches_textbook_formula() {
        for n in -12..=12 {
            let got = square_wave_fourier(0.23, 0.71, 1.0, n);
            let want = textbook(0.23, 0.71, 1.0, n);
            assert!((got - want).norm() < 1e-15, "n={n}");
            // Wrapping on-interval [0.9, 1.2) mod 2 = [0.9, 1.2).
            let got = square_wave_fourier(1.7, 0.3, 2.0, n);
            let want = textbook(1.7, 2.3, 2.0, n);
            assert!((got - want).norm() < 1e-15, "n={n}");
            // Bound |s_n| <= 1 / (pi |n|).
            if n != 0 {
                assert!(got.norm() <= 1.0 / (std::f64::consts::PI * f64::from(n.abs())) + 1e-15);
            }
        }
        // Full period is the constant 1; empty interval is 0.
        assert!((square_wave_fourier(0.0, 1.0, 1.0, 0) - 1.0).norm() < 1e-15);
        assert!(square_wave_fourier(0.0, 1.0, 1.0, 3).norm() < 1e-15);
        assert!(square_wave_fourier(0.4, 0.4, 1.0, 0).norm() < 1e-15);
        assert!(square_wave_fourier(0.0, 1.0, -1.0, 1).re.is_nan());
    }

    #[test]
    fn piecewise_coefficients_are_weighted_square_waves() {
        // A(t) = A_off + (A_on - A_off) s(t) with s the damper indicator.
        let on = dmatrix![0.0, 1.0; -200.0, -2.0];
        let off = dmatrix![0.0, 1.0; -200.0, 0.0];
        let b = dmatrix![0.0; 1.0];
        let c = dmatrix![1.0, 0.0];
        let d = dmatrix![0.0];
        let lti = PiecewiseLti::new(
            1.0,
            0.23,
            vec![
                Piece::new(0.48, on.clone(), b.clone(), c.clone(), d.clone()),
                Piece::new(0.52, off.clone(), b.clone(), c.clone(), d.clone()),
            ],
        )
        .unwrap();
        for n in -8..=8 {
            let s = textbook(0.23, 0.71, 1.0, n);
            let delta = if n == 0 { 1.0 } else { 0.0 };
            let want = off.map(|x| Complex64::new(x * delta, 0.0)) + (&on - &off).map(|x| s * x);
            let got = lti.fourier_coefficient(SystemMatrix::A, n);
            assert!((got - want).norm() < 1e-13, "n={n}");
            let gb = lti.fourier_coefficient(SystemMatrix::B, n);
            assert!((gb[(1, 0)] - delta).norm() < 1e-15);
        }
    }

    #[test]
    fn fft_of_square_wave_shows_first_order_error() {
        // Sampling a discontinuous function aliases the 1/n tail and misplaces
        // each switch by up to one sample: the coefficient error is O(1/K),
        // and must shrink by ~4x when K grows 4x (not faster, not slower).
        let (t_on, t_off) = (0.23, 0.71);
        let err = |k: usize| {
            let series = fft_fourier_fn(1.0, k, |t| {
                let on = (t_on..t_off).contains(&t);
                dmatrix![if on { 1.0 } else { 0.0 }]
            })
            .unwrap();
            (-10..=10)
                .map(|n| {
                    (series.coefficient(n).unwrap()[(0, 0)] - textbook(t_on, t_off, 1.0, n)).norm()
                })
                .fold(0.0, f64::max)
        };
        let errs: Vec<f64> = [100, 400, 1600, 6400].iter().map(|&k| err(k)).collect();
        for (i, &k) in [100.0, 400.0, 1600.0, 6400.0].iter().enumerate() {
            // Two switches, each misplaced by < 1/K: |error| <= 2/K.
            assert!(errs[i] <= 2.0 / k, "K={k}: {:e}", errs[i]);
            assert!(
                errs[i] > 0.01 / k,
                "K={k}: suspiciously exact {:e}",
                errs[i]
            );
        }
        for w in errs.windows(2) {
            let ratio = w[0] / w[1];
            assert!((2.0..8.0).contains(&ratio), "ratio {ratio}");
        }
    }

    #[test]
    fn fft_of_smooth_function_is_spectrally_accurate() {
        // exp(cos(wp t)) has coefficients I_n(1) (modified Bessel),
        // sum_m (1/2)^(2m+|n|) / (m! (m+|n|)!); 32 samples alias only terms
        // below I_32(1) ~ 1e-45, so agreement is to rounding.
        let bessel_i = |n: i32| {
            let n = n.unsigned_abs() as i32;
            let mut term = 0.5_f64.powi(n) / (1..=n).map(f64::from).product::<f64>();
            let mut sum = 0.0;
            for m in 0..30 {
                sum += term;
                term *= 0.25 / (f64::from(m + 1) * f64::from(m + 1 + n));
            }
            sum
        };
        let period = 2.5;
        let series = fft_fourier_fn(
            period,
            32,
            |t| dmatrix![(TAU * t / period).cos().exp(), 0.0; 1.0, (TAU * t / period).sin()],
        )
        .unwrap();
        assert_eq!(series.max_harmonic(), 15);
        for n in -15..=15 {
            let c = series.coefficient(n).unwrap();
            assert!((c[(0, 0)] - bessel_i(n)).norm() < 1e-15, "n={n}");
            let want_const = if n == 0 { 1.0 } else { 0.0 };
            assert!((c[(1, 0)] - want_const).norm() < 1e-15);
            // sin = (e^{j} - e^{-j}) / 2j: coefficient -j/2 at n = 1.
            let want_sin = match n {
                1 => Complex64::new(0.0, -0.5),
                -1 => Complex64::new(0.0, 0.5),
                _ => Complex64::new(0.0, 0.0),
            };
            assert!((c[(1, 1)] - want_sin).norm() < 1e-15);
        }
        assert!(series.coefficient(16).is_none());
        // The series reproduces the function between samples.
        let t = 0.377;
        let v = series.evaluate(t);
        assert!((v[(0, 0)].re - (TAU * t / period).cos().exp()).abs() < 1e-14);
    }

    #[test]
    fn fft_rejects_bad_input() {
        assert_eq!(
            fft_fourier(1.0, &[]),
            Err(LtpError::TooFewSamples { count: 0 })
        );
        let mixed = [dmatrix![1.0], dmatrix![1.0, 2.0]];
        assert!(matches!(
            fft_fourier(1.0, &mixed),
            Err(LtpError::SampleShapeMismatch { index: 1, .. })
        ));
        assert!(matches!(
            fft_fourier(1.0, &[dmatrix![f64::INFINITY]]),
            Err(LtpError::NonFiniteSample {
                index: 0,
                row: 0,
                col: 0
            })
        ));
        assert!(matches!(
            fft_fourier(0.0, &[dmatrix![1.0]]),
            Err(LtpError::InvalidPeriod { .. })
        ));
    }
}
