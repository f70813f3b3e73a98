//! The band-wide significance level of an estimate's values, against simulated noise.

use htfid_estimate::{band_level, HarmonicSeries};
use num_complex::Complex64;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// Noise alone, circular with `E|e|^2 = 1`, passes the level at any of 200 frequencies in
/// about 5 % of bands. Exactly, `1 - (1 - 0.05 / 200)^200 = 4.88 %` (the level's tail
/// `exp(-t^2)` is exact for circular Gaussian noise); 20 000 simulated bands give it within
/// 0.15 % (one binomial standard deviation), so [4.3 %, 5.5 %] is four of them.
#[test]
fn noise_alone_passes_the_band_level_in_five_percent_of_bands() {
    let points = 200;
    let level = band_level(points, 0.05);
    let exact = 1.0 - (1.0 - 0.05 / points as f64).powi(points as i32);
    assert!((exact - 0.0488).abs() < 1e-4, "{exact}");
    let half = Normal::new(0.0, 0.5f64.sqrt()).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let bands = 20_000;
    let mut passed = 0;
    let stderr = vec![1.0; points];
    let mut values = vec![Complex64::new(0.0, 0.0); points];
    for _ in 0..bands {
        for v in values.iter_mut() {
            *v = Complex64::new(half.sample(&mut rng), half.sample(&mut rng));
        }
        let series = HarmonicSeries {
            n: 0,
            omegas: &[],
            values: &values,
            stderr: &stderr,
        };
        if series.largest_significant(0.05).is_some() {
            passed += 1;
        }
        // The level is the one the series uses.
        let above = values.iter().any(|v| v.norm() > level);
        assert_eq!(above, series.largest_significant(0.05).is_some());
    }
    let share = f64::from(passed) / f64::from(bands);
    assert!((0.043..=0.055).contains(&share), "{share}");
}

/// The largest value above the level is reported, not a larger one buried in its own noise,
/// and nothing when no value stands out; the level never falls below 2 standard errors.
#[test]
fn the_largest_significant_value_ignores_values_within_their_noise() {
    assert!((band_level(1, 0.5) - 2.0).abs() < 1e-15);
    let level = band_level(4, 0.05);
    assert!((level - (80.0f64).ln().sqrt()).abs() < 1e-15);
    let values = [
        Complex64::new(3.0, 4.0),  // 5, stderr 1: stands out
        Complex64::new(0.0, 9.0),  // 9, stderr 5: within its noise
        Complex64::new(1.0, 0.0),  // 1, stderr 0.1: stands out
        Complex64::new(20.0, 0.0), // stderr NaN: no noise estimate, not counted
    ];
    let stderr = [1.0, 5.0, 0.1, f64::NAN];
    let series = HarmonicSeries {
        n: 1,
        omegas: &[],
        values: &values,
        stderr: &stderr,
    };
    assert_eq!(
        series.largest_significant(0.05).map(f64::to_bits),
        Some(5.0f64.to_bits())
    );
    let quiet = HarmonicSeries {
        stderr: &[10.0, 10.0, 10.0, 10.0],
        ..series
    };
    assert_eq!(quiet.largest_significant(0.05), None);
}
