//! The orbit from data: period estimation and the periodic split, against signals whose parts
//! are known in closed form.

use std::f64::consts::PI;

use htfid_estimate::{estimate_period, split_periodic, Error};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// A periodic part with known coefficients plus an aperiodic sinusoid on a DFT bin that is no
/// multiple of the pumping frequency: the split returns the sinusoid and the coefficients to
/// round-off (1e-12 of the signal), with the phase referred to absolute time.
#[test]
fn split_returns_the_periodic_part_and_the_rest() {
    let (period, dt, t_start, periods) = (0.8, 0.01, 3.2, 25);
    let n = (periods as f64 * period / dt).round() as usize;
    let wp = 2.0 * PI / period;
    // c_1 = 0.3 - 0.1j, c_3 = 0.05j, c_0 = 0.2.
    let periodic = |t: f64| {
        0.2 + 2.0 * (0.3 * (wp * t).cos() + 0.1 * (wp * t).sin())
            + 2.0 * (-0.05 * (3.0 * wp * t).sin())
    };
    let w_other = 2.0 * PI * 37.0 / (n as f64 * dt); // bin 37, not a multiple of 25
    let other = |t: f64| 0.01 * (w_other * t + 0.4).cos();
    let t: Vec<f64> = (0..n).map(|i| t_start + i as f64 * dt).collect();
    let y: Vec<f64> = t.iter().map(|&t| periodic(t) + other(t)).collect();
    let split = split_periodic(&y, dt, t_start, period, 4).unwrap();
    assert_eq!(split.periods, periods);
    for (i, &ti) in t.iter().enumerate() {
        assert!((split.deviation[i] - other(ti)).abs() < 1e-12, "{i}");
    }
    let want = [(0.2, 0.0), (0.3, -0.1), (0.0, 0.0), (0.0, 0.05), (0.0, 0.0)];
    for (k, (re, im)) in want.iter().enumerate() {
        let c = split.harmonics[k];
        assert!(
            (c.re - re).abs() < 1e-12 && (c.im - im).abs() < 1e-12,
            "c_{k} = {c}"
        );
    }
    // Not a whole number of periods: refused.
    assert!(matches!(
        split_periodic(&y[..n - 3], dt, t_start, period, 4),
        Err(Error::NotWholePeriods { .. })
    ));
}

/// A fundamental weaker than its second harmonic, with noise: the period is found to 1e-6
/// (a strong periodic component over 150 periods is located far better than one DFT bin,
/// 1/150 of the frequency).
#[test]
fn period_is_found_through_a_weak_fundamental() {
    let (period, dt) = (0.731, 0.004);
    let n = 150 * 183;
    let wp = 2.0 * PI / period;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let y: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 * dt;
            0.3 * (wp * t).cos()
                + 1.0 * (2.0 * wp * t + 1.0).cos()
                + 0.2 * (3.0 * wp * t).sin()
                + noise.sample(&mut rng)
        })
        .collect();
    let est = estimate_period(&y, dt).unwrap();
    assert!((est.period / period - 1.0).abs() < 1e-6, "{}", est.period);
    assert!(est.periodic_share > 0.9, "{}", est.periodic_share);
}

#[test]
fn white_noise_has_no_period() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let noise = Normal::new(0.0, 1.0).unwrap();
    let y: Vec<f64> = (0..20_000).map(|_| noise.sample(&mut rng)).collect();
    assert!(matches!(
        estimate_period(&y, 0.01),
        Err(Error::NoPeriodicComponent)
    ));
}
