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

/// An input much slower than its sampling, `u_t = 0.95 u_{t-1} + w_t`: neighbouring lags of
/// its cross-correlation with anything are nearly equal, `rho_u(k) = 0.95^k`.
fn slow(seed: u64, n: usize) -> Vec<f64> {
    let mut prev = 0.0;
    white(seed, n)
        .into_iter()
        .map(|w| {
            prev = 0.95 * prev + w;
            prev
        })
        .collect()
}

#[test]
fn an_exact_model_driven_by_a_slow_input_passes_the_independence_test_at_its_level() {
    // A white residual independent of an AR(1) input with coefficient 0.95: the hypothesis
    // holds, so 1 % of tests should reject. 200 records of 4000 samples: 2 rejections
    // expected, standard deviation 1.4; 7 or more has probability below 0.5 %. Summing the
    // squared lags as if independent (Ljung-Box) makes Q a sum of 26 correlated squares with
    // the same mean and a far heavier tail: it rejects 28 of these 200 records (the test
    // itself: 1), which is why the test uses the lags' covariance.
    let (mut rejected, mut ljung_box_rejected) = (0, 0);
    for seed in 0..200 {
        let e = white(5000 + seed, 4000);
        let u = slow(9000 + seed, 4000);
        let r = resid(&e, &u, 25).unwrap();
        rejected += usize::from(!r.independence.passed);
        assert_eq!(r.independence.tested, 26);
        let (lags, ccf) = htfid_validate::cross_correlation(&e, &u, 25).unwrap();
        let n = 4000.0;
        let q: f64 = lags[25..]
            .iter()
            .zip(&ccf[25..])
            .map(|(&k, v)| v * v / (n - k as f64))
            .sum::<f64>()
            * n
            * (n + 2.0);
        ljung_box_rejected += usize::from(chi_square_sf(q, 26) < 0.01);
    }
    assert!(
        rejected <= 6,
        "{rejected} of 200 rejected an independent input"
    );
    assert!(
        ljung_box_rejected >= 20,
        "the Ljung-Box sum rejected only {ljung_box_rejected} of 200: the test above proves \
         nothing new"
    );
}

#[test]
fn a_residual_that_follows_a_slow_input_fails_the_independence_test() {
    // The residual holds 0.05 of the input two samples late beside white noise of unit
    // variance (the input's own variance is about 10): a missed dynamic the test must see.
    for seed in 0..20 {
        let u = slow(300 + seed, 4000);
        let w = white(600 + seed, 4000);
        let e: Vec<f64> = (0..4000)
            .map(|t| w[t] + if t >= 2 { 0.05 * u[t - 2] } else { 0.0 })
            .collect();
        let r = resid(&e, &u, 25).unwrap();
        assert!(
            !r.independence.passed,
            "seed {seed}: p = {}",
            r.independence.p_value
        );
    }
}
