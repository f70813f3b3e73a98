//! The periodic-line estimator against known harmonic transfer functions.

mod common;

use std::f64::consts::PI;

use common::{inverse, record_spectra, with_noise, Grid, Rational, Truth};
use htfid_estimate::{
    deviation_record, periodic_lines, periodic_lines_paired, Error, LineSpec, TimeSeries,
};
use num_complex::Complex64;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const PERIOD: f64 = 1.0;
const DT: f64 = 0.01;
/// Multisine period: eight system periods, 800 samples.
const TM: f64 = 8.0;
const ONE: Grid = Grid {
    n: 800,
    dt: DT,
    period: PERIOD,
};

/// Lines in residues 1, 2, 3 modulo 8 and 56 bins apart: seven harmonics (a span of 48 bins)
/// never bring two lines, or a line and a mirror (residues 5, 6, 7), onto one bin.
fn lines() -> Vec<usize> {
    [0usize, 56, 112]
        .iter()
        .flat_map(|&o| [o + 1, o + 2, o + 3])
        .collect()
}

/// The multisine spectrum on one period, unit magnitudes and random phases, Hermitian.
fn multisine(lines: &[usize], seed: u64) -> Vec<Complex64> {
    let kmax = *lines.iter().max().unwrap() as i64;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut c = vec![Complex64::new(0.0, 0.0); 2 * kmax as usize + 1];
    for &b in lines {
        let v = Complex64::from_polar(1.0, rng.gen_range(0.0..2.0 * PI));
        c[(kmax + b as i64) as usize] = v;
        c[(kmax - b as i64) as usize] = v.conj();
    }
    c
}

/// `periods` whole multisine periods of the steady-state response, from `t0`, with input
/// `sign * u` and output `sign * y_linear + beta * u^2`.
fn record(
    c: &[Complex64],
    truth: &dyn Truth,
    t0: f64,
    periods: usize,
    sign: f64,
    beta: f64,
) -> TimeSeries {
    let (us, ys) = record_spectra(ONE, c, 0.0, truth);
    let u1 = inverse(ONE, t0, &us);
    let y1 = inverse(ONE, t0, &ys);
    let u: Vec<f64> = (0..periods)
        .flat_map(|_| u1.iter().map(|v| sign * v))
        .collect();
    let y: Vec<f64> = (0..periods)
        .flat_map(|_| u1.iter().zip(&y1).map(|(a, b)| sign * b + beta * a * a))
        .collect();
    deviation_record(u, y, DT, t0).unwrap()
}

#[test]
fn recovers_rational_htfs_and_their_mirrors_exactly() {
    let truth = Rational::standard(3);
    let c = multisine(&lines(), 1);
    let rec = record(&c, &truth, 4.56, 3, 1.0, 0.0);
    let hs: Vec<i32> = (-3..=3).collect();
    let spec = LineSpec::new(TM, lines()).unwrap();
    let est = periodic_lines(&rec, PERIOD, &spec, &hs).unwrap();
    for &n in &hs {
        let s = est.harmonic(n).unwrap();
        // Each line reaches one bin per harmonic, and so does its mirror.
        assert_eq!(s.omegas.len(), 2 * lines().len());
        assert!(s.omegas.windows(2).all(|w| w[0] < w[1]));
        for (w, g) in s.omegas.iter().zip(s.values) {
            let want = truth.g(n, *w);
            // Exact data: rounding of the synthesis and the DFT, relative to |G|.
            assert!(
                (g - want).norm() < 1e-10 * want.norm(),
                "G_{n}({w}) = {g}, want {want}"
            );
        }
        // Steady state: every period is identical, so the scatter vanishes.
        assert!(s.stderr.iter().all(|&e| e < 1e-10));
    }
    assert!((est.dof().unwrap() - 2.0).abs() < 1e-12);
}

#[test]
fn paired_records_cancel_even_order_nonlinearity() {
    // y = linear + beta u^2. The square puts power at sums and differences of lines (1 + 2 = 3,
    // 57 - 56 = 1, ...), on top of the linear response; with -u the square is unchanged, so
    // (y+ - y-) / 2 is exactly linear.
    let truth = Rational::standard(1);
    let ls: Vec<usize> = [0usize, 24, 48]
        .iter()
        .flat_map(|&o| [o + 1, o + 2, o + 3])
        .collect();
    let c = multisine(&ls, 2);
    let beta = 0.3;
    let plus = record(&c, &truth, 2.0, 2, 1.0, beta);
    // The -u experiment runs later, a whole number of multisine periods on.
    let minus = record(&c, &truth, 2.0 + 10.0 * TM, 2, -1.0, beta);
    let hs = [-1, 0, 1];
    let spec = LineSpec::new(TM, ls).unwrap();
    let paired = periodic_lines_paired(&plus, &minus, PERIOD, &spec, &hs).unwrap();
    let single = periodic_lines(&plus, PERIOD, &spec, &hs).unwrap();
    let mut single_err = 0.0f64;
    for (a, b) in paired.rows().zip(single.rows()) {
        let want = truth.g(a.n, a.omega);
        assert!((a.value - want).norm() < 1e-10 * want.norm(), "{a:?}");
        single_err = single_err.max((b.value - want).norm() / want.norm());
    }
    // Without the pair the quadratic term biases the estimate badly.
    assert!(single_err > 0.1, "single-record error {single_err}");
}

#[test]
fn standard_errors_match_monte_carlo_scatter() {
    let truth = Rational::standard(1);
    let ls: Vec<usize> = [0usize, 24, 48]
        .iter()
        .flat_map(|&o| [o + 1, o + 2, o + 3])
        .collect();
    let c = multisine(&ls, 3);
    let clean = record(&c, &truth, 1.0, 8, 1.0, 0.0);
    let spec = LineSpec::new(TM, ls).unwrap();
    let hs = [-1, 0, 1];
    let mut rng = ChaCha8Rng::seed_from_u64(33);
    let trials = 200;
    let rows = periodic_lines(&clean, PERIOD, &spec, &hs)
        .unwrap()
        .rows()
        .count();
    let mut sum = vec![Complex64::new(0.0, 0.0); rows];
    let mut sum_sq = vec![0.0; rows];
    let mut rep = vec![0.0; rows];
    for _ in 0..trials {
        let noisy = with_noise(&clean, 0.02, &mut rng);
        let est = periodic_lines(&noisy, PERIOD, &spec, &hs).unwrap();
        for (i, r) in est.rows().enumerate() {
            sum[i] += r.value;
            sum_sq[i] += r.value.norm_sqr();
            rep[i] += r.stderr * r.stderr;
        }
    }
    // Observed variance across 200 trials against the mean reported variance (unbiased, from
    // 7 complex degrees of freedom per trial), summed over the 18 rows of each harmonic: the
    // ratio of standard deviations scatters by ~2%, so 0.8..1.25 is a wide but discriminating
    // band.
    let per_h = rows / hs.len();
    for h in 0..hs.len() {
        let (mut obs, mut reported) = (0.0, 0.0);
        for i in h * per_h..(h + 1) * per_h {
            let mean = sum[i] / trials as f64;
            obs +=
                (sum_sq[i] / trials as f64 - mean.norm_sqr()) * trials as f64 / (trials - 1) as f64;
            reported += rep[i] / trials as f64;
        }
        let ratio = (obs / reported).sqrt();
        assert!((0.8..1.25).contains(&ratio), "harmonic {}: {ratio}", hs[h]);
    }
}

#[test]
fn colliding_lines_and_bad_records_are_rejected() {
    let truth = Rational::standard(1);
    let c = multisine(&[1, 9], 4);
    let rec = record(&c, &truth, 0.0, 2, 1.0, 0.0);
    // Line 9 through harmonic -1 lands on bin 1, where line 1 arrives through harmonic 0 (the
    // first of several collisions: 1 + 8 = 9 + 0 as well).
    let spec = LineSpec::new(TM, vec![1, 9]).unwrap();
    let e = periodic_lines(&rec, PERIOD, &spec, &[-1, 0, 1]).unwrap_err();
    assert!(
        matches!(
            e,
            Error::LineCollision {
                bin: 1,
                line_a: 1,
                n_a: 0,
                line_b: 9,
                n_b: -1
            }
        ),
        "{e}"
    );
    // One period only: the estimate is still exact (no noise here) and the standard error,
    // taken from the bins no line reaches, is finite.
    let short = record(&c, &truth, 0.0, 1, 1.0, 0.0);
    let spec = LineSpec::new(TM, vec![1]).unwrap();
    let one = periodic_lines(&short, PERIOD, &spec, &[0]).unwrap();
    assert!(one.rows().all(|r| r.stderr.is_finite()));
    // A multisine period that is not a whole number of system periods.
    let spec = LineSpec::new(7.5, vec![1]).unwrap();
    let e = periodic_lines(&rec, PERIOD, &spec, &[0]).unwrap_err();
    assert!(matches!(e, Error::MultisineNotWholePeriods { .. }));
    // A line that the input does not excite.
    let spec = LineSpec::new(TM, vec![2]).unwrap();
    let e = periodic_lines(&rec, PERIOD, &spec, &[0]).unwrap_err();
    assert!(matches!(e, Error::LineNotExcited { line: 2, .. }), "{e}");
    assert!(matches!(
        LineSpec::new(TM, vec![3, 3]),
        Err(Error::DuplicateLine { line: 3 })
    ));
}
