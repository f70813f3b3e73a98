//! The noise floor of a residual from the high-frequency band of its spectrum.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rustfft::{num_complex::Complex64, FftPlanner};

use crate::DiagnoseError;

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
    let (power, segments) = band_power(residuals, band)?;
    Some(level(&power, segments))
}

/// The Welch periodogram of `residuals` at the bins of `band` (see [`noise_floor`]), in order
/// of frequency, and the number of segments averaged.
fn band_power(residuals: &[&[f64]], band: (f64, f64)) -> Option<(Vec<f64>, usize)> {
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
    Some((power, segments))
}

/// The white-noise standard deviation whose averaged periodogram has the median of `power`
/// (averages of `segments` segments).
fn level(power: &[f64], segments: usize) -> f64 {
    let mut sorted = power.to_vec();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    let nu = 2.0 * segments as f64;
    let median_of_mean_one = (1.0 - 2.0 / (9.0 * nu)).powi(3);
    (median / median_of_mean_one).sqrt()
}

/// Sub-bands whose levels must agree for an input's band to be read as white noise.
const SUB_BANDS: usize = 4;
/// The default largest ratio of the highest to the lowest sub-band level of white noise
/// ([`crate::ModelFitOptions::input_noise_flatness`]). On the shortest records read (a few
/// segments, a few dozen bins per sub-band) the sub-band medians of white noise scatter by
/// about 5 % each; the tail of an excitation's spectrum falls by a factor 3 or more across
/// the band.
pub(crate) const WHITE_SPREAD: f64 = 1.5;

/// The white-noise level of a measured input, read from the same band of its spectrum as a
/// residual's floor ([`noise_floor`]), where it can be told from the input itself: the band
/// must be flat (its [`SUB_BANDS`] sub-bands' levels within a factor `flatness` of each other;
/// the tail of an excitation's spectrum falls across it), and white noise of that level must
/// carry at most `max_share` of the input's variance (an input with content up to its
/// Nyquist frequency, whose noise no spectrum separates). `None` otherwise, or when the parts
/// are too short.
pub(crate) fn input_noise_level(
    parts: &[&[f64]],
    band: (f64, f64),
    max_share: f64,
    flatness: f64,
) -> Option<f64> {
    if max_share <= 0.0 {
        return None;
    }
    let (power, segments) = band_power(parts, band)?;
    let per_band = power.len() / SUB_BANDS;
    if per_band < 4 {
        return None;
    }
    let levels: Vec<f64> = power
        .chunks(per_band)
        .take(SUB_BANDS)
        .map(|c| level(c, segments))
        .collect();
    let (lo, hi) = levels
        .iter()
        .fold((f64::INFINITY, 0.0_f64), |(a, b), &v| (a.min(v), b.max(v)));
    if !(lo > 0.0 && hi <= flatness * lo) {
        return None;
    }
    let level = level(&power, segments);
    let (mut sum, mut count) = (0.0, 0usize);
    for part in parts {
        let mean = part.iter().sum::<f64>() / part.len().max(1) as f64;
        sum += part.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>();
        count += part.len();
    }
    let variance = sum / count.max(1) as f64;
    (level > 0.0 && level * level <= max_share * variance).then_some(level)
}

/// Checks the settings of a noise reading shared by both diagnoses: the band `(lo, hi)` of
/// the spectrum, `0 < lo < hi <= 1`, and the flatness an input's band must have, `>= 1`.
pub(crate) fn check_reading(band: (f64, f64), flatness: f64) -> Result<(), DiagnoseError> {
    let bad = |name, expected, value| {
        Err(DiagnoseError::InvalidOption {
            name,
            expected,
            value,
        })
    };
    let (lo, hi) = band;
    if !(lo > 0.0 && lo < hi) {
        return bad("noise_band.0", "> 0 and below noise_band.1", lo);
    }
    if hi.is_nan() || hi > 1.0 {
        return bad("noise_band.1", "<= 1", hi);
    }
    if !(flatness.is_finite() && flatness >= 1.0) {
        return bad("input_noise_flatness", ">= 1 and finite", flatness);
    }
    Ok(())
}

/// Seed of the white noise [`with_white_noise`] adds (fixed, so a diagnosis is repeatable).
const INPUT_NOISE_SEED: u64 = 0x5EED;

/// `u` plus white Gaussian noise of standard deviation `sigma` from a fixed seed: the input a
/// model is driven with to measure its response to the input's noise. `None` for a `sigma`
/// that is not a finite non-negative number.
pub(crate) fn with_white_noise(u: &[f64], sigma: f64) -> Option<Vec<f64>> {
    let normal = Normal::new(0.0, sigma).ok()?;
    let mut rng = ChaCha8Rng::seed_from_u64(INPUT_NOISE_SEED);
    Some(u.iter().map(|v| v + normal.sample(&mut rng)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

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

    /// A band-limited input (a linear chirp to a fifth of the Nyquist frequency) with white
    /// noise of 1 % of its RMS: the level is the noise's (8 %, as above), and an input that
    /// is white noise up to its Nyquist frequency has no level that can be told from it.
    #[test]
    fn an_inputs_noise_is_read_only_where_the_input_leaves_room() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let n = 20000;
        let noise = Normal::new(0.0, 0.00707).unwrap();
        let chirp: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 / n as f64;
                // Frequency rising from 0 to 0.2 of Nyquist: phase pi * 0.2 * n * t^2 / 2.
                (std::f64::consts::PI * 0.1 * n as f64 * t * t).sin() + noise.sample(&mut rng)
            })
            .collect();
        let s = input_noise_level(&[&chirp], (0.6, 0.95), 0.1, WHITE_SPREAD).unwrap();
        assert_relative_eq!(s, 0.00707, max_relative = 0.08);
        let white = Normal::new(0.0, 1.0).unwrap();
        let broadband: Vec<f64> = (0..n).map(|_| white.sample(&mut rng)).collect();
        assert_eq!(
            input_noise_level(&[&broadband], (0.6, 0.95), 0.1, WHITE_SPREAD),
            None
        );
        // A tail of tones falling as the fourth power of frequency across the band (the
        // excitation's own high-frequency content, not noise) is not read as noise either.
        let tail: Vec<f64> = (0..n)
            .map(|k| {
                (0..200)
                    .map(|j| {
                        let w = std::f64::consts::PI * (0.5 + 0.0025 * j as f64);
                        (0.5 / (0.5 + 0.0025 * j as f64)).powi(4) * (w * k as f64 + j as f64).sin()
                    })
                    .sum::<f64>()
            })
            .collect();
        let with_tail: Vec<f64> = chirp.iter().zip(&tail).map(|(c, t)| c + 0.01 * t).collect();
        assert_eq!(
            input_noise_level(&[&with_tail], (0.6, 0.95), 0.1, WHITE_SPREAD),
            None
        );
        // A share of 0 never reads one.
        assert_eq!(
            input_noise_level(&[&chirp], (0.6, 0.95), 0.0, WHITE_SPREAD),
            None
        );
    }
}
