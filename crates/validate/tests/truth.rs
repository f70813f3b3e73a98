//! The validation statistics against truth they did not produce: the rate at which white
//! noise of a known seed leaves the bounds, the autocorrelation `0.5^k` of an AR(1) series,
//! and Ljung-Box statistics and chi-square tails computed once with numpy and scipy
//! (`tests/reference/ljung_box.py`).

use approx::assert_relative_eq;
use htfid_validate::{autocorrelation, chi_square_sf, resid, Z_99};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

fn white(seed: u64, n: usize) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n).map(|_| StandardNormal.sample(&mut rng)).collect()
}

#[test]
fn white_noise_stays_inside_the_bounds_at_the_stated_rate() {
    // 40 records of 2000 samples, 25 lags each: 1000 autocorrelation lags and 1040
    // cross-correlation lags (0..=25) against an independent white input. Under the null
    // about 1 % leave the 99 % bounds: 10 of 1000 expected, standard deviation about 3.2.
    // Accepting 2..=25 is more than 4 standard deviations either side.
    let (mut outside_acf, mut tested_acf) = (0, 0);
    let (mut outside_ccf, mut tested_ccf) = (0, 0);
    let mut rejected = 0;
    for seed in 0..40 {
        let e = white(seed, 2000);
        let u = white(1000 + seed, 2000);
        let r = resid(&e, &u, 25).unwrap();
        outside_acf += r.whiteness.outside;
        tested_acf += r.whiteness.tested;
        outside_ccf += r.independence.outside;
        tested_ccf += r.independence.tested;
        rejected += usize::from(!r.whiteness.passed) + usize::from(!r.independence.passed);
    }
    assert_eq!((tested_acf, tested_ccf), (1000, 1040));
    assert!(
        (2..=25).contains(&outside_acf),
        "{outside_acf} of 1000 outside"
    );
    assert!(
        (2..=26).contains(&outside_ccf),
        "{outside_ccf} of 1040 outside"
    );
    // 80 tests at the 1 % level: 0.8 rejections expected; 4 or more has probability < 1 %.
    assert!(
        rejected <= 3,
        "{rejected} of 80 Ljung-Box tests rejected white noise"
    );
}

#[test]
fn ar1_autocorrelation_is_a_power_of_its_coefficient() {
    // x_t = 0.5 x_{t-1} + w_t has r(k) = 0.5^k. Bartlett's formula gives a standard error of
    // about sqrt((1 + 0.25) / (1 - 0.25) / N) = 0.0029 at N = 200 000; 0.015 is five of them.
    let w = white(7, 200_000);
    let mut x = Vec::with_capacity(w.len());
    let mut prev = 0.0;
    for v in w {
        prev = 0.5 * prev + v;
        x.push(prev);
    }
    let r = autocorrelation(&x, 8).unwrap();
    for (k, rk) in r.iter().enumerate() {
        let truth = 0.5f64.powi(k as i32);
        assert!((rk - truth).abs() < 0.015, "r({k}) = {rk}, truth {truth}");
    }
    // And the whiteness test rejects it outright.
    let u = white(8, 200_000);
    let res = resid(&x, &u, 25).unwrap();
    assert!(!res.whiteness.passed && res.whiteness.outside >= 5);
}

#[test]
fn ljung_box_matches_the_reference_computation() {
    // Values from tests/reference/ljung_box.py; the sums differ only by rounding order,
    // hence 1e-12 relative on Q and r, and 1e-9 relative on p-values as small as 1e-189
    // (the tail is computed in logarithms, so its relative error stays small).
    let n = 200;
    let series = |a: f64| -> Vec<f64> {
        (0..n)
            .map(|i| a * (0.37 * i as f64).sin() + ((i * 7919) % 113) as f64 / 113.0)
            .collect()
    };
    let u: Vec<f64> = white(3, n);
    for (a, r123, q, p) in [
        (
            1.0,
            [0.8772010627373543, 0.6564429634336827, 0.3619107462985509],
            912.1516511326529,
            1.5436182471209914e-189,
        ),
        (
            0.1,
            [0.5888075325254719, 0.2390247796678325, -0.04738829197798672],
            291.3775908044429,
            1.0319503437552377e-56,
        ),
    ] {
        let r = resid(&series(a), &u, 10).unwrap();
        for k in 0..3 {
            assert_relative_eq!(r.autocorrelation[k + 1], r123[k], max_relative = 1e-12);
        }
        assert_relative_eq!(r.whiteness.statistic, q, max_relative = 1e-12);
        assert_eq!(r.whiteness.dof, 10);
        assert_relative_eq!(r.whiteness.p_value, p, max_relative = 1e-9);
        assert_relative_eq!(
            r.whiteness.bound,
            Z_99 / (n as f64).sqrt(),
            max_relative = 1e-15
        );
    }
}

#[test]
fn chi_square_tail_matches_scipy_at_odd_and_even_dof() {
    // scipy.stats.chi2.sf, from tests/reference/ljung_box.py; 1e-10 relative is the series
    // and continued fraction's accuracy with margin.
    for (x, k, p) in [
        (3.0, 1, 0.08326451666355042),
        (7.5, 5, 0.186029833602867),
        (30.0, 25, 0.22428900483440378),
        (40.0, 25, 0.02916439562315211),
        (12.3, 11, 0.3415208582761478),
    ] {
        assert_relative_eq!(chi_square_sf(x, k), p, max_relative = 1e-10);
    }
}
