//! The noise floor of a residual from the high-frequency band of its spectrum.

use rustfft::{num_complex::Complex64, FftPlanner};

/// Longest Welch segment.
const MAX_SEGMENT: usize = 1024;
/// Shortest Welch segment.
const MIN_SEGMENT: usize = 64;

/// Standard deviation of the white noise that would give the residuals' spectrum level in the
/// band `[lo, hi]` (fractions of the Nyquist frequency).
///
/// Welch's method: non-overlapping Hann-windowed segments of a power-of-two length `L` (the
/// largest up to 1024 that fits the shortest residual), periodograms normalised so that white
/// noise of variance `s^2` has mean `s^2` in every bin, averaged over the `K` segments. The
/// level is the median over the band's bins divided by the median of a `chi^2_{2K} / 2K`
/// variable (Wilson-Hilferty), so isolated spectral lines (harmonics of a model error) do not
/// raise it. `None` when no residual holds `MIN_SEGMENT` samples or the band holds no bin.
pub(crate) fn noise_floor(residuals: &[&[f64]], band: (f64, f64)) -> Option<f64> {
    let shortest = residuals.iter().map(|r| r.len()).filter(|&n| n > 0).min()?;
    let mut len = MAX_SEGMENT;
    while len > shortest {
        len /= 2;
    }
    if len < MIN_SEGMENT {
        return None;
    }
    let window: Vec<f64> = (0..len)
        .map(|i| {
            let s = (std::f64::consts::PI * (i as f64 + 0.5) / len as f64).sin();
            s * s
        })
        .collect();
    let norm: f64 = window.iter().map(|w| w * w).sum();
    let fft = FftPlanner::<f64>::new().plan_fft_forward(len);
    let lo = ((band.0 * (len / 2) as f64).ceil() as usize).max(1);
    let hi = ((band.1 * (len / 2) as f64).floor() as usize).min(len / 2 - 1);
    if hi < lo {
        return None;
    }
    let mut power = vec![0.0; hi - lo + 1];
    let mut buf = vec![Complex64::new(0.0, 0.0); len];
    let mut segments = 0usize;
    for r in residuals {
        for chunk in r.chunks_exact(len) {
            let mean = chunk.iter().sum::<f64>() / len as f64;
            for ((b, &v), &w) in buf.iter_mut().zip(chunk).zip(&window) {
                *b = Complex64::new((v - mean) * w, 0.0);
            }
            fft.process(&mut buf);
            for (p, b) in power.iter_mut().zip(&buf[lo..=hi]) {
                *p += b.norm_sqr() / norm;
            }
            segments += 1;
        }
    }
    if segments == 0 {
        return None;
    }
    for p in power.iter_mut() {
        *p /= segments as f64;
    }
    power.sort_by(f64::total_cmp);
    let median = power[power.len() / 2];
    let nu = 2.0 * segments as f64;
    let median_of_mean_one = (1.0 - 2.0 / (9.0 * nu)).powi(3);
    Some((median / median_of_mean_one).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn recovers_white_noise_level_under_a_strong_low_frequency_signal() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let normal = Normal::new(0.0, 0.01).unwrap();
        // A sinusoid 100 times the noise at 2 % of Nyquist plus a line inside the band: the
        // band's median ignores both. With 20000 samples (19 segments of 1024, about 150 bins)
        // the estimate's relative spread is about 2 %; 8 % is four of those.
        let r: Vec<f64> = (0..20000)
            .map(|k| {
                let t = k as f64;
                (0.01 * std::f64::consts::PI * t).sin()
                    + 0.05 * (0.8 * std::f64::consts::PI * t).sin()
                    + normal.sample(&mut rng)
            })
            .collect();
        let s = noise_floor(&[&r], (0.6, 0.95)).unwrap();
        assert_relative_eq!(s, 0.01, max_relative = 0.08);
    }
}
