//! Local polynomial (Savitzky-Golay) smoothing and differentiation of the measured position,
//! and a zero-phase spectral low-pass with exact derivatives.

use nalgebra::DMatrix;

/// Position, velocity and acceleration of a local polynomial fit at one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Kinematics {
    pub x: f64,
    pub v: f64,
    pub a: f64,
}

/// Savitzky-Golay filter of half-width `half` and degree `degree`: smoothed value, first and
/// second derivative at every sample of `x[lo..hi]` whose full window lies inside `x`; other
/// samples are left out. Returns the sample indices with their kinematics.
pub(crate) fn savitzky_golay(
    x: &[f64],
    lo: usize,
    hi: usize,
    dt: f64,
    half: usize,
    degree: usize,
) -> Vec<(usize, Kinematics)> {
    let w = 2 * half + 1;
    let p = degree + 1;
    if w <= p {
        return Vec::new();
    }
    let vander = DMatrix::from_fn(w, p, |i, j| (i as f64 - half as f64).powi(j as i32));
    // Rows 0, 1, 2 of the pseudo-inverse give the smoothed value and the derivatives at the
    // centre, in sample units.
    let Ok(pinv) = vander.pseudo_inverse(1e-12) else {
        return Vec::new();
    };
    let c0: Vec<f64> = (0..w).map(|i| pinv[(0, i)]).collect();
    let c1: Vec<f64> = (0..w).map(|i| pinv[(1, i)] / dt).collect();
    let c2: Vec<f64> = (0..w)
        .map(|i| {
            if p > 2 {
                2.0 * pinv[(2, i)] / (dt * dt)
            } else {
                0.0
            }
        })
        .collect();
    let start = lo.max(half);
    let end = hi.min(x.len().saturating_sub(half));
    (start..end)
        .map(|k| {
            let win = &x[k - half..=k + half];
            let dot = |c: &[f64]| c.iter().zip(win).map(|(a, b)| a * b).sum::<f64>();
            (
                k,
                Kinematics {
                    x: dot(&c0),
                    v: dot(&c1),
                    a: dot(&c2),
                },
            )
        })
        .collect()
}

/// Half-width of a degree-4 Savitzky-Golay window whose pass band reaches about twice the
/// natural frequency `f_n` (Hz) at sample step `dt` (Schafer's cut-off rule
/// `f_c ~ (d + 1) / (3.2 w - 4.6)` cycles per sample for window length `w`).
pub(crate) fn window_half_width(f_n: f64, dt: f64) -> usize {
    let fc = (2.0 * f_n * dt).clamp(1e-4, 0.45);
    let w = (5.0 / fc + 4.6) / 3.2;
    ((w - 1.0) / 2.0).round().clamp(3.0, 200.0) as usize
}

/// The weights `w` (sum 1, offsets `-half..=half`) with which the Savitzky-Golay second
/// derivative of a position sequence equals `sum_m w_m x''(t + m dt)` up to `O(dt^2)`: the
/// derivative filter `c` annihilates constants and lines, so `c = D2 w / dt^2` with `D2` the
/// second difference, and `w` is the double running sum of `c dt^2`. Smoothing the model's
/// acceleration with `w` makes it comparable with the measured one at every frequency, not only
/// inside the smoother's pass band.
pub(crate) fn acceleration_kernel(half: usize, dt: f64) -> Vec<f64> {
    let len = 2 * half + 1;
    let c: Vec<f64> = (0..len)
        .map(|i| {
            let mut e = vec![0.0; len];
            e[i] = 1.0;
            savitzky_golay(&e, half, half + 1, dt, half, 4)
                .first()
                .map_or(0.0, |(_, k)| k.a * dt * dt)
        })
        .collect();
    let mut s1 = 0.0;
    let mut s2 = 0.0;
    let mut w = vec![0.0; len];
    for (i, &ci) in c.iter().enumerate().take(len - 1) {
        s1 += ci;
        s2 += s1;
        w[i + 1] = s2;
    }
    w
}

/// Velocity and acceleration at sample `k` of `x` (sampled every `dt`) by five-point central
/// differences (`2 <= k < x.len() - 2`): error `O(dt^4)`, 0.3 % of the acceleration at a tenth
/// of the sampling rate, where a three-point second difference is 2 % low.
pub(crate) fn five_point(x: &[f64], k: usize, dt: f64) -> (f64, f64) {
    let v = (8.0 * (x[k + 1] - x[k - 1]) - (x[k + 2] - x[k - 2])) / (12.0 * dt);
    let a = (16.0 * (x[k + 1] + x[k - 1]) - (x[k + 2] + x[k - 2]) - 30.0 * x[k]) / (12.0 * dt * dt);
    (v, a)
}

/// `signal` smoothed by `kernel` (of `2 half + 1` weights, [`acceleration_kernel`]) about
/// sample `k` (`half <= k < signal.len() - half`).
pub(crate) fn smoothed_at(kernel: &[f64], signal: &[f64], k: usize) -> f64 {
    let half = kernel.len() / 2;
    kernel
        .iter()
        .enumerate()
        .map(|(i, w)| w * signal[k + i - half])
        .sum()
}

/// A zero-phase low-pass applied through the FFT of a whole record, with its exact
/// derivatives: gain 1 up to `pass` (Hz), a raised-cosine fall to 0 at `stop`. The
/// `order`-th derivative multiplies each line by `(j omega)^order` beside the gain, so for a
/// signal band-limited below `stop` it is the derivative of the filtered signal with no error
/// of a difference quotient (a five-point acceleration is 14 % low at a third of the sampling
/// rate). The line through the record's end points is taken out before the transform and its
/// part put back after, so the record is not read as jumping at its wrap-around; what is left
/// of that jump rings for a few periods of the transition band at either end.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SpectralLowPass {
    pub pass: f64,
    pub stop: f64,
}

impl SpectralLowPass {
    /// The filter's gain at `f` (Hz, `>= 0`).
    fn gain(&self, f: f64) -> f64 {
        if f <= self.pass {
            1.0
        } else if f >= self.stop {
            0.0
        } else {
            let s = (f - self.pass) / (self.stop - self.pass);
            0.5 * (1.0 + (std::f64::consts::PI * s).cos())
        }
    }

    /// The `order`-th derivative (0, 1 or 2) of `x` (sampled every `dt`) filtered.
    pub(crate) fn apply(&self, x: &[f64], dt: f64, order: u32) -> Vec<f64> {
        use rustfft::{num_complex::Complex64, FftPlanner};
        let n = x.len();
        if n < 2 {
            return vec![0.0; n];
        }
        let slope = (x[n - 1] - x[0]) / ((n - 1) as f64 * dt);
        let line = |k: usize| x[0] + slope * k as f64 * dt;
        let mut buf: Vec<Complex64> = (0..n)
            .map(|k| Complex64::new(x[k] - line(k), 0.0))
            .collect();
        let mut planner = FftPlanner::<f64>::new();
        planner.plan_fft_forward(n).process(&mut buf);
        let df = 1.0 / (n as f64 * dt);
        for (i, c) in buf.iter_mut().enumerate() {
            // The signed frequency of line i; the Nyquist line of an even length has no sign,
            // and its odd derivatives are not real: it is dropped.
            let signed = if 2 * i <= n {
                i as f64
            } else {
                i as f64 - n as f64
            };
            if 2 * i == n && order % 2 == 1 {
                *c = Complex64::new(0.0, 0.0);
                continue;
            }
            let f = signed * df;
            let jw = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f);
            *c *= jw.powu(order) * (self.gain(f.abs()) / n as f64);
        }
        planner.plan_fft_inverse(n).process(&mut buf);
        (0..n)
            .map(|k| {
                buf[k].re
                    + match order {
                        0 => line(k),
                        1 => slope,
                        _ => 0.0,
                    }
            })
            .collect()
    }

    /// Samples at either end of a record in which the wrap-around's ringing lasts: eight
    /// periods of the transition band's width.
    pub(crate) fn edge(&self, dt: f64) -> usize {
        (8.0 / ((self.stop - self.pass) * dt)).ceil() as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_abs_diff_eq;

    #[test]
    fn savitzky_golay_is_exact_for_polynomials_of_its_degree() {
        // x = 1 + 2 t - 3 t^2 + 0.5 t^3: a cubic lies in the span of a degree-4 fit, so
        // value and derivatives are exact up to rounding (1e-9 relative to the acceleration).
        let dt = 0.01;
        let x: Vec<f64> = (0..200)
            .map(|k| {
                let t = k as f64 * dt;
                1.0 + 2.0 * t - 3.0 * t * t + 0.5 * t * t * t
            })
            .collect();
        let out = savitzky_golay(&x, 0, 200, dt, 7, 4);
        assert_eq!(out.len(), 200 - 14);
        for (k, kin) in out {
            let t = k as f64 * dt;
            assert_abs_diff_eq!(kin.x, x[k], epsilon = 1e-10);
            assert_abs_diff_eq!(kin.v, 2.0 - 6.0 * t + 1.5 * t * t, epsilon = 1e-8);
            assert_abs_diff_eq!(kin.a, -6.0 + 3.0 * t, epsilon = 1e-6);
        }
    }

    #[test]
    fn the_acceleration_kernel_turns_the_derivative_filter_into_a_smoother() {
        // On x = sin(w t) the filter's second derivative must equal the kernel applied to
        // x'' = -w^2 sin(w t), up to the second difference's O((w dt)^2) error (w dt = 0.3:
        // under 1 % of the amplitude), and the kernel's weights must sum to 1.
        let (dt, half, w) = (0.01, 12, 30.0);
        let kernel = acceleration_kernel(half, dt);
        assert!((kernel.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        let x: Vec<f64> = (0..200).map(|i| (w * i as f64 * dt).sin()).collect();
        let a: Vec<f64> = x.iter().map(|v| -w * w * v).collect();
        for (k, kin) in savitzky_golay(&x, 0, x.len(), dt, half, 4) {
            let smoothed: f64 = (0..kernel.len()).map(|m| kernel[m] * a[k + m - half]).sum();
            assert!(
                (kin.a - smoothed).abs() < 0.01 * w * w,
                "{} {}",
                kin.a,
                smoothed
            );
        }
    }

    #[test]
    fn the_spectral_low_pass_differentiates_a_band_limited_signal_exactly() {
        // x = 0.3 + 0.2 t + sin(2 pi 3 t) + 0.5 cos(2 pi 11.3 t + 1) sampled at 100 Hz: both
        // lines lie inside the pass band (20 Hz), 11.3 Hz is a third of the way to Nyquist,
        // where a five-point acceleration is 3 % low. Away from the ends (the ringing of the
        // non-periodic record's wrap-around) value, velocity and acceleration must match
        // the analytic ones to 1e-3 of the acceleration's size (about 2.5e3), the level the
        // ringing leaves, and well inside the five-point error.
        let dt = 0.01;
        let n = 4000;
        let (w1, w2) = (
            2.0 * std::f64::consts::PI * 3.0,
            2.0 * std::f64::consts::PI * 11.3,
        );
        let t = |k: usize| k as f64 * dt;
        let x: Vec<f64> = (0..n)
            .map(|k| 0.3 + 0.2 * t(k) + (w1 * t(k)).sin() + 0.5 * (w2 * t(k) + 1.0).cos())
            .collect();
        let filter = SpectralLowPass {
            pass: 20.0,
            stop: 30.0,
        };
        let (x0, x1, x2) = (
            filter.apply(&x, dt, 0),
            filter.apply(&x, dt, 1),
            filter.apply(&x, dt, 2),
        );
        let edge = filter.edge(dt);
        assert!(edge < n / 4);
        let scale = 0.5 * w2 * w2;
        let mut worst = 0.0f64;
        for k in edge..n - edge {
            let v = 0.2 + w1 * (w1 * t(k)).cos() - 0.5 * w2 * (w2 * t(k) + 1.0).sin();
            let a = -w1 * w1 * (w1 * t(k)).sin() - 0.5 * w2 * w2 * (w2 * t(k) + 1.0).cos();
            worst = worst
                .max((x0[k] - x[k]).abs() * w2 * w2)
                .max((x1[k] - v).abs() * w2)
                .max((x2[k] - a).abs());
        }
        assert!(
            worst < 1e-3 * scale,
            "worst error {worst:e} against {scale:e}"
        );
        // The five-point acceleration at the same samples errs by more.
        let five = (edge..n - edge)
            .map(|k| {
                let a = -w1 * w1 * (w1 * t(k)).sin() - 0.5 * w2 * w2 * (w2 * t(k) + 1.0).cos();
                (five_point(&x, k, dt).1 - a).abs()
            })
            .fold(0.0, f64::max);
        assert!(
            five > 10.0 * worst,
            "five-point {five:e}, spectral {worst:e}"
        );
    }
}
