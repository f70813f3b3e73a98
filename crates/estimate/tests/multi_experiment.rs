//! The multi-experiment estimator against known harmonic transfer functions.

mod common;

use std::f64::consts::PI;

use common::{c_at, max_rel_err, random_spectrum, synth_record, with_noise, Grid, Rational, Truth};
use htfid_estimate::{
    deviation_record, multi_experiment, Alpha, Error, Leakage, MultiOptions, Regularisation,
    TimeSeries,
};
use num_complex::Complex64;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const PERIOD: f64 = 1.0;
const GRID: Grid = Grid {
    n: 800,
    dt: 0.01,
    period: PERIOD,
};
const BAND: (f64, f64) = (0.5, 30.0);
/// Input bins reach the band's top bin (38) plus three pumping shifts (3 x 8).
const KMAX: i64 = 62;

/// `K` records of the periodic input delayed by `r T / K`, each starting at an absolute time
/// that is not a whole number of periods.
fn phase_shifted(
    k: usize,
    truth: &dyn Truth,
    seed: u64,
) -> (Vec<TimeSeries>, Vec<Complex64>, Vec<f64>) {
    let c = random_spectrum(KMAX, seed);
    let taus: Vec<f64> = (0..k).map(|r| r as f64 * PERIOD / k as f64).collect();
    let records = taus
        .iter()
        .enumerate()
        .map(|(r, &tau)| synth_record(GRID, &c, tau, 100.37 + 9.13 * r as f64, truth))
        .collect();
    (records, c, taus)
}

fn harmonics(nmax: i32) -> Vec<i32> {
    (-nmax..=nmax).collect()
}

#[test]
fn recovers_rational_htfs_noise_free() {
    let truth = Rational::standard(3);
    let (records, c, _) = phase_shifted(9, &truth, 1);
    let hs = harmonics(3);
    let est = multi_experiment(&records, PERIOD, &hs, BAND, &MultiOptions::default()).unwrap();
    let p = GRID.p();
    for &n in &hs {
        let s = est.harmonic(n).unwrap();
        let want: Vec<Complex64> = s.omegas.iter().map(|&w| truth.g(n, w)).collect();
        // Exact data, cond <= 3 (|C| in [0.5, 1.5]); DFT and inverse DFT round to ~1e-13.
        let err = max_rel_err(s.values, &want);
        assert!(err < 1e-10, "G_{n}: relative error {err:e}");
    }
    // With delays r T / K the bin matrix is diag(phase) F diag(C[k - nP]) with F a partial DFT
    // matrix with orthogonal columns, so its condition number is max|C| / min|C| over the
    // harmonic-shifted bins.
    let cond = est.cond().unwrap();
    let omegas = est.harmonic(0).unwrap().omegas;
    for (kb, &w) in omegas.iter().enumerate() {
        let k = (w / GRID.dw()).round() as i64;
        let mags: Vec<f64> = hs
            .iter()
            .map(|&n| c_at(&c, k - i64::from(n) * p).norm())
            .collect();
        let expect = mags.iter().copied().fold(0.0, f64::max)
            / mags.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(
            (cond[kb] - expect).abs() < 1e-8 * expect,
            "bin {kb}: {} vs {expect}",
            cond[kb]
        );
    }
}

#[test]
fn standard_errors_match_monte_carlo_scatter() {
    let truth = Rational::standard(3);
    let (clean, _, _) = phase_shifted(9, &truth, 2);
    let hs = harmonics(3);
    let opts = MultiOptions::default();
    let sigma = 0.05;
    let trials = 200;
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let first = multi_experiment(&clean, PERIOD, &hs, BAND, &opts).unwrap();
    let m = first.harmonic(0).unwrap().omegas.len();
    let h = hs.len();
    let mut sum = vec![Complex64::new(0.0, 0.0); h * m];
    let mut sum_sq = vec![0.0; h * m];
    let mut reported_var = vec![0.0; h * m];
    for _ in 0..trials {
        let noisy: Vec<TimeSeries> = clean
            .iter()
            .map(|r| with_noise(r, sigma, &mut rng))
            .collect();
        let est = multi_experiment(&noisy, PERIOD, &hs, BAND, &opts).unwrap();
        for (i, &n) in hs.iter().enumerate() {
            let s = est.harmonic(n).unwrap();
            for kb in 0..m {
                sum[i * m + kb] += s.values[kb];
                sum_sq[i * m + kb] += s.values[kb].norm_sqr();
                reported_var[i * m + kb] += s.stderr[kb] * s.stderr[kb];
            }
        }
    }
    // Per harmonic, over all bins: observed variance of the complex estimate versus the mean
    // reported variance. One bin's observed variance from 200 trials has a relative spread of
    // about 1/sqrt(200) = 7% and the reported variance (pooled over 22 complex degrees of
    // freedom) is unbiased, so summing ~38 bins leaves ~1-2% scatter: 0.8..1.25 on the standard
    // deviation ratio is a > 10 sigma band that still catches a wrong factor of 2 or sqrt(2).
    for (i, &n) in hs.iter().enumerate() {
        let (mut obs, mut rep) = (0.0, 0.0);
        for kb in 0..m {
            let mean = sum[i * m + kb] / trials as f64;
            obs += (sum_sq[i * m + kb] / trials as f64 - mean.norm_sqr()) * trials as f64
                / (trials - 1) as f64;
            rep += reported_var[i * m + kb] / trials as f64;
        }
        let ratio = (obs / rep).sqrt();
        assert!(
            (0.8..1.25).contains(&ratio),
            "G_{n}: observed/reported = {ratio}"
        );
    }
    // Pooling over 11 bins with K - H = 2 each; the band edges pool 6 bins.
    assert!((first.dof().unwrap() - 12.0).abs() < 1e-12);
}

#[test]
fn harmonics_k_apart_alias_with_k_phase_shifts() {
    // Known limitation: with delays r T / 3, the column of harmonic n is proportional to that of
    // n - 3 in every bin, so G_2 (unmodelled) folds into G_{-1} and G_{-2} into G_1:
    // G_hat_{-1}[k] = G_{-1} + G_2 C[k - 2P] / C[k + P], exactly, and the residual is zero.
    let truth = Rational::standard(2);
    let (records, c, _) = phase_shifted(3, &truth, 3);
    let hs = harmonics(1);
    let est = multi_experiment(&records, PERIOD, &hs, BAND, &MultiOptions::default()).unwrap();
    let p = GRID.p();
    let mut leak = 0.0f64;
    for (n, alias) in [(-1i32, 2i32), (0, 3), (1, -2)] {
        let s = est.harmonic(n).unwrap();
        let want: Vec<Complex64> = s
            .omegas
            .iter()
            .map(|&w| {
                let k = (w / GRID.dw()).round() as i64;
                let fold = if alias.abs() <= truth.nmax() {
                    truth.g(alias, w) * c_at(&c, k - i64::from(alias) * p)
                        / c_at(&c, k - i64::from(n) * p)
                } else {
                    Complex64::new(0.0, 0.0)
                };
                truth.g(n, w) + fold
            })
            .collect();
        let err = max_rel_err(s.values, &want);
        assert!(err < 1e-10, "G_{n}: {err:e}");
        let plain: Vec<Complex64> = s.omegas.iter().map(|&w| truth.g(n, w)).collect();
        leak = leak.max(max_rel_err(s.values, &plain));
    }
    // The aliasing is not small: the estimates are visibly wrong against the true G_n.
    assert!(leak > 0.1, "leak {leak}");
}

/// `y(t) = p(t) u(t)` with `p(t) = 1 + 0.4 cos(wp t) + 0.2 sin(2 wp t)`: `G_0 = 1`,
/// `G_{+-1} = 0.2`, `G_{+-2} = -+0.1j`, at every frequency. Multiplying by `exp(j n wp t)` shifts
/// the DFT of a P-period record by exactly `nP` bins, so this holds for any sampled input,
/// periodic or not.
fn memoryless(t: f64, u: f64) -> f64 {
    let wp = 2.0 * PI / PERIOD;
    (1.0 + 0.4 * (wp * t).cos() + 0.2 * (2.0 * wp * t).sin()) * u
}

fn memoryless_truth(n: i32) -> Complex64 {
    match n {
        0 => Complex64::new(1.0, 0.0),
        1 | -1 => Complex64::new(0.2, 0.0),
        2 => Complex64::new(0.0, -0.1),
        -2 => Complex64::new(0.0, 0.1),
        _ => Complex64::new(0.0, 0.0),
    }
}

fn white_records(k: usize, seed: u64) -> Vec<TimeSeries> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let normal = Normal::new(0.0, 1.0).unwrap();
    (0..k)
        .map(|r| {
            let t0 = 3.21 + 17.7 * r as f64;
            let u: Vec<f64> = (0..GRID.n).map(|_| normal.sample(&mut rng)).collect();
            let y = u
                .iter()
                .enumerate()
                .map(|(i, &v)| memoryless(t0 + i as f64 * GRID.dt, v))
                .collect();
            deviation_record(u, y, GRID.dt, t0).unwrap()
        })
        .collect()
}

#[test]
fn memoryless_modulation_with_white_noise_inputs_is_exact() {
    // Time-domain truth, no frequency-domain synthesis: a second, independent path.
    let records = white_records(9, 4);
    let hs = harmonics(2);
    let est = multi_experiment(&records, PERIOD, &hs, BAND, &MultiOptions::default()).unwrap();
    for row in est.rows() {
        // Random 9 x 5 bin matrices have cond up to ~1e2; rounding stays below 1e-12.
        assert!(
            (row.value - memoryless_truth(row.n)).norm() < 1e-10,
            "n = {} at {}: {}",
            row.n,
            row.omega,
            row.value
        );
        assert!(row.stderr < 1e-10);
    }
}

#[test]
fn smoothness_and_ridge_regularisation_agree_with_the_plain_solution_when_tiny() {
    let truth = Rational::standard(3);
    let (records, _, _) = phase_shifted(9, &truth, 5);
    let hs = harmonics(3);
    let plain = multi_experiment(&records, PERIOD, &hs, BAND, &MultiOptions::default()).unwrap();
    for reg in [
        Regularisation::Smoothness(Alpha::Fixed(1e-9)),
        Regularisation::Ridge(1e-9),
    ] {
        let opts = MultiOptions {
            regularisation: reg,
            ..MultiOptions::default()
        };
        let est = multi_experiment(&records, PERIOD, &hs, BAND, &opts).unwrap();
        for &n in &hs {
            let a = est.harmonic(n).unwrap().values;
            let b = plain.harmonic(n).unwrap().values;
            // The penalty perturbs the exact solution by O(alpha * cond^2) ~ 1e-8.
            let err = max_rel_err(a, b);
            assert!(err < 1e-6, "{reg:?} G_{n}: {err:e}");
        }
        assert!(est.alpha().is_some() && est.cond().is_some());
    }
}

#[test]
fn fewer_records_than_harmonics_needs_regularisation() {
    let truth = Rational::standard(3);
    let (records, _, _) = phase_shifted(3, &truth, 6);
    let hs = harmonics(3);
    let err = multi_experiment(&records, PERIOD, &hs, BAND, &MultiOptions::default()).unwrap_err();
    assert!(matches!(
        err,
        Error::TooFewRecords {
            records: 3,
            harmonics: 7
        }
    ));
    let opts = MultiOptions {
        regularisation: Regularisation::Smoothness(Alpha::Fixed(1e-2)),
        ..MultiOptions::default()
    };
    let est = multi_experiment(&records, PERIOD, &hs, BAND, &opts).unwrap();
    assert!(est.cond().unwrap().iter().all(|c| c.is_infinite()));
}

#[test]
fn records_must_be_whole_periods_and_share_a_grid() {
    let u = vec![0.0; 150];
    let r = deviation_record(u.clone(), u, 0.01, 0.0).unwrap();
    let e = multi_experiment(&[r], PERIOD, &[0], BAND, &MultiOptions::default()).unwrap_err();
    assert!(matches!(e, Error::NotWholePeriods { .. }));
    assert!(e.to_string().contains("1.5 periods"), "{e}");
    let records = white_records(2, 7);
    let short = deviation_record(vec![0.0; 400], vec![0.0; 400], 0.01, 0.0).unwrap();
    let e = multi_experiment(
        &[records[0].clone(), short],
        PERIOD,
        &[0],
        BAND,
        &MultiOptions::default(),
    )
    .unwrap_err();
    assert!(matches!(e, Error::RecordsDiffer { index: 1, .. }));
    // A band whose shifted input bins reach Nyquist (50 Hz = 314 rad/s).
    let e = multi_experiment(
        &records,
        PERIOD,
        &[-2, 0],
        (1.0, 305.0),
        &MultiOptions::default(),
    )
    .unwrap_err();
    assert!(matches!(e, Error::BeyondNyquist { n: -2, .. }), "{e}");
}

/// Discrete-time LTP system: `v = p(t) u` (memoryless modulation) then
/// `y[i+1] = phi y[i] + dt v[i]`, `phi = exp(-a dt)`. In periodic steady state
/// `G_n(w) = p_n H(w)` with `H(w) = dt exp(-j w dt) / (1 - phi exp(-j w dt))`; on a segment cut
/// from a long run the output also carries a transient (the state at the segment's start), a
/// smooth rational function of frequency: exactly the situation the local polynomial method
/// models.
fn lti_after_modulation(a: f64, dt: f64) -> impl Fn(i32, f64) -> Complex64 {
    move |n, w| {
        let phi = (-a * dt).exp();
        let z1 = Complex64::from_polar(1.0, -w * dt);
        memoryless_truth(n) * dt * z1 / (1.0 - z1 * phi)
    }
}

/// Plain and LPM (half-width 4, degree 2) RMS relative errors, worst harmonic, for nine
/// segments of `n` samples cut from one run of the system above.
fn segment_errors(n: usize) -> (f64, f64) {
    let (dt, a) = (0.01f64, 3.0f64);
    let k = 9;
    // Segment starts that are not whole records or periods apart, so the transient's phase
    // reference (the segment start) differs from the absolute-time DFT's.
    let starts: Vec<usize> = (0..k).map(|r| 500 + r * (n + 1237)).collect();
    let total = starts[k - 1] + n;
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let normal = Normal::new(0.0, 1.0).unwrap();
    let u: Vec<f64> = (0..total).map(|_| normal.sample(&mut rng)).collect();
    let phi = (-a * dt).exp();
    let mut y = vec![0.0; total];
    for i in 0..total - 1 {
        y[i + 1] = phi * y[i] + dt * memoryless(i as f64 * dt, u[i]);
    }
    let records: Vec<TimeSeries> = starts
        .iter()
        .map(|&s| {
            deviation_record(
                u[s..s + n].to_vec(),
                y[s..s + n].to_vec(),
                dt,
                s as f64 * dt,
            )
            .unwrap()
        })
        .collect();
    let hs = harmonics(2);
    let band = (1.0, 20.0);
    let truth = lti_after_modulation(a, dt);
    let error = |opts: &MultiOptions| -> f64 {
        let est = multi_experiment(&records, PERIOD, &hs, band, opts).unwrap();
        hs.iter()
            .map(|&n| {
                let s = est.harmonic(n).unwrap();
                let want: Vec<Complex64> = s.omegas.iter().map(|&w| truth(n, w)).collect();
                common::rms_rel_err(s.values, &want)
            })
            .fold(0.0, f64::max)
    };
    let plain = error(&MultiOptions::default());
    let lpm = error(&MultiOptions {
        leakage: Leakage::Lpm {
            half_width: 4,
            degree: 2,
        },
        ..MultiOptions::default()
    });
    (plain, lpm)
}

#[test]
fn local_polynomial_method_removes_segment_transients() {
    // Noise free, so what remains after LPM is the error of approximating G_n and the transient
    // by quadratics over 9 bins: it must fall like (bin spacing)^3, i.e. 8x when the segments
    // double in length (measured 7.6). The plain per-bin estimate, which ignores the transient,
    // is off by tens of percent (measured 41% and 38%).
    let (plain1, lpm1) = segment_errors(3200);
    let (plain2, lpm2) = segment_errors(6400);
    let rate = lpm1 / lpm2;
    assert!((6.0..11.0).contains(&rate), "convergence ratio {rate}");
    // Measured 3.4e-4 at 64 s segments; 1e-3 leaves a factor 3.
    assert!(lpm2 < 1e-3, "LPM error {lpm2:e}");
    assert!(
        plain1 > 100.0 * lpm1 && plain2 > 100.0 * lpm2,
        "{plain1:e} {plain2:e}"
    );
}

#[test]
fn lpm_rejects_an_underdetermined_window() {
    let records = white_records(2, 9);
    let opts = MultiOptions {
        leakage: Leakage::Lpm {
            half_width: 1,
            degree: 2,
        },
        ..MultiOptions::default()
    };
    let e = multi_experiment(&records, PERIOD, &harmonics(1), BAND, &opts).unwrap_err();
    assert!(matches!(
        e,
        Error::LpmUnderdetermined {
            equations: 0,
            unknowns: 9
        }
    ));
}
