//! Local polynomial (Savitzky-Golay) smoothing and differentiation of the measured position.

use nalgebra::{DMatrix, DVector};

/// Position, velocity and acceleration of a local polynomial fit at one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Kinematics {
    pub x: f64,
    pub v: f64,
    pub a: f64,
}

/// A least-squares polynomial of degree `degree` through the samples `x[lo..hi]` (step `dt`),
/// evaluated with its first two derivatives at sample `at`. `None` when the window has no more
/// samples than coefficients.
pub(crate) fn local_fit(
    x: &[f64],
    lo: usize,
    hi: usize,
    at: usize,
    dt: f64,
    degree: usize,
) -> Option<Kinematics> {
    let hi = hi.min(x.len());
    let m = hi.checked_sub(lo)?;
    let p = degree + 1;
    if m <= p {
        return None;
    }
    // Abscissae in samples relative to `at`, scaled to [-1, 1] for conditioning.
    let half = ((m as f64) / 2.0).max(1.0);
    let vander = DMatrix::from_fn(m, p, |i, j| {
        let s = ((lo + i) as f64 - at as f64) / half;
        s.powi(j as i32)
    });
    let y = DVector::from_iterator(m, x[lo..hi].iter().copied());
    // nalgebra's SVD panics on non-finite entries: such data have no derivative.
    if !y.iter().all(|v| v.is_finite()) {
        return None;
    }
    let coef = vander.svd(true, true).solve(&y, 1e-12).ok()?;
    let c1 = if p > 1 { coef[1] } else { 0.0 };
    let c2 = if p > 2 { coef[2] } else { 0.0 };
    let scale = half * dt;
    Some(Kinematics {
        x: coef[0],
        v: c1 / scale,
        a: 2.0 * c2 / (scale * scale),
    })
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
        let k = local_fit(&x, 0, 12, 0, dt, 3).unwrap();
        assert_abs_diff_eq!(k.x, 1.0, epsilon = 1e-10);
        assert_abs_diff_eq!(k.v, 2.0, epsilon = 1e-8);
        assert_abs_diff_eq!(k.a, -6.0, epsilon = 1e-6);
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
}
