//! End to end: a known linear time-periodic system plus a quadratic term,
//! driven by a designed multisine; the HTFs read off the designed bins must
//! equal the analytic ones wherever the design says they are protected.

mod common;

use std::f64::consts::TAU;

use common::NaiveDft;
use htfid_excite::{
    design_htf_multisine, Amplitude, Block, Branch, Design, DesignSpec, EvenOrder, PhaseRule,
    Signal,
};
use num_complex::Complex64;

const WP: f64 = TAU; // T = 1 s
const POLE: f64 = 5.0; // rad/s
const QUAD: f64 = 0.3;
const QUAD_HARMONICS: i32 = 8;

/// Fourier coefficients p_n, n = 0..=3, of the periodic gain (p_{-n} = conj p_n).
/// p_3 lies beyond the estimated harmonics: it must not leak into them.
fn p_coef(n: i32) -> Complex64 {
    let c = [
        Complex64::new(1.0, 0.0),
        Complex64::new(0.3, 0.2),
        Complex64::new(-0.1, 0.05),
        Complex64::new(0.02, -0.03),
    ];
    let k = n.unsigned_abs() as usize;
    if k >= c.len() {
        return Complex64::new(0.0, 0.0);
    }
    if n < 0 {
        c[k].conj()
    } else {
        c[k]
    }
}

fn lowpass(w: f64) -> Complex64 {
    Complex64::new(1.0, 0.0) / Complex64::new(1.0, w / POLE)
}

/// Truth in the paper's convention `Y(jw) = sum_n G_n(jw) U(jw - j n wp)`:
/// for `y = p(t) (h * u)(t)`, `G_n(jw) = p_n H(j(w - n wp))`.
fn g_true(n: i32, w: f64) -> Complex64 {
    p_coef(n) * lowpass(w - f64::from(n) * WP)
}

/// Periodic coefficient of the quadratic term, harmonics 0..=QUAD_HARMONICS.
/// A constant coefficient would only produce products `+-b_i +- b_j`; the
/// periodic one shifts them by multiples of P as a limit-cycle system does,
/// which is what the residue argument of the design protects against.
fn quad_gain(t: f64) -> f64 {
    QUAD * (1.0
        + (1..=QUAD_HARMONICS)
            .map(|m| 0.7_f64.powi(m) * (f64::from(m) * (WP * t + 1.0)).cos())
            .sum::<f64>())
}

fn spec(even_order: EvenOrder) -> DesignSpec {
    DesignSpec {
        period: 1.0,
        max_harmonic: 2,
        omega_lo: 0.5,
        omega_hi: 12.0,
        spacing: 0.8,
        amplitude: Amplitude::Rms(1.0),
        phases: PhaseRule::Schroeder,
        even_order,
        settle: 0.0,
        start: 0.0,
        max_record: 1e5,
    }
}

/// Input and output samples of one measured window in periodic steady state.
/// `u` comes from the design's input signal; the filtered state is computed
/// analytically from the design's line list, so the two must agree for the
/// estimates to come out right.
fn window(d: &Design, b: &Block, n: usize) -> (Vec<f64>, Vec<f64>) {
    let tm = d.multisine_period();
    let dt = tm / n as f64;
    let u = d.input().sample_uniform(b.measure_start, dt, n);
    let s = b.polarity.sign();
    let y = (0..n)
        .map(|k| {
            let tau = k as f64 * dt;
            let t = b.measure_start + tau;
            let x: f64 = d
                .lines()
                .iter()
                .map(|l| {
                    s * (lowpass(l.omega)
                        * Complex64::from_polar(l.amplitude, l.omega * tau + l.phase))
                    .re
                })
                .sum();
            let p: f64 = p_coef(0).re
                + (1..=3)
                    .map(|m| {
                        2.0 * (p_coef(m) * Complex64::from_polar(1.0, f64::from(m) * WP * t)).re
                    })
                    .sum::<f64>();
            p * x + quad_gain(t) * u[k] * u[k]
        })
        .collect();
    (u, y)
}

/// Largest |G_est - G_true| over every in-band point of every |n| <= H.
fn max_error(d: &Design, u: &[f64], y: &[f64]) -> f64 {
    let dft = NaiveDft::new(u.len());
    let h = d.spec().max_harmonic as i32;
    let (lo, hi) = (d.spec().omega_lo, d.spec().omega_hi);
    let mut worst: f64 = 0.0;
    let mut count = 0;
    for n in -h..=h {
        for q in d.htf_points(n) {
            if q.omega < lo || q.omega > hi {
                continue;
            }
            let ub = dft.bin(u, d.lines()[q.line].bin as i64);
            let yc = dft.bin(y, q.output_bin);
            let g = match q.branch {
                Branch::Direct => yc / ub,
                Branch::Mirror => yc / ub.conj(),
            };
            worst = worst.max((g - g_true(n, q.omega)).norm());
            count += 1;
        }
    }
    assert!(count > 50, "too few points: {count}");
    worst
}

fn samples_for(d: &Design) -> usize {
    // Highest output bin: b_max + 3P from the periodic gain, 2 b_max + 8P
    // from the quadratic term; sampling above twice that avoids aliasing.
    let b_max = d.lines().last().unwrap().bin as usize;
    let p = d.periods_per_multisine() as usize;
    2 * (2 * b_max + QUAD_HARMONICS as usize * p) + 64
}

#[test]
fn guarded_design_recovers_htfs_despite_a_quadratic_term() {
    let d = design_htf_multisine(spec(EvenOrder::QuadraticGuard)).unwrap();
    let (u, y) = window(&d, &d.blocks()[0], samples_for(&d));
    let err = max_error(&d, &u, &y);
    // |G| <= 1.4 and the DFT of ~2000 O(1) samples rounds at ~1e-13
    // relative; 1e-9 leaves room yet would catch any leak (the quadratic
    // term alone is ~0.1 on exposed bins, see below).
    assert!(err < 1e-9, "max error {err}");
}

#[test]
fn unprotected_design_is_biased_by_the_quadratic_term() {
    let d = design_htf_multisine(spec(EvenOrder::Unprotected)).unwrap();
    assert!(d.report().second_order_exposed_lines > 0);
    let (u, y) = window(&d, &d.blocks()[0], samples_for(&d));
    let err = max_error(&d, &u, &y);
    assert!(err > 1e-3, "expected visible bias, got {err}");
}

#[test]
fn sign_reversal_cancels_the_quadratic_term() {
    let d = design_htf_multisine(spec(EvenOrder::SignReversal)).unwrap();
    let n = samples_for(&d);
    let (u_plus, y_plus) = window(&d, &d.blocks()[0], n);
    let (u_minus, y_minus) = window(&d, &d.blocks()[1], n);
    for (a, b) in u_plus.iter().zip(&u_minus) {
        // Unit-RMS multisine; both blocks evaluate the same window-local time.
        approx::assert_abs_diff_eq!(*a, -*b, epsilon = 1e-11);
    }
    // One block alone still carries the even-order term...
    assert!(max_error(&d, &u_plus, &y_plus) > 1e-3);
    // ...which (y(+u) - y(-u)) / 2 removes.
    let y_odd: Vec<f64> = y_plus
        .iter()
        .zip(&y_minus)
        .map(|(a, b)| 0.5 * (a - b))
        .collect();
    let err = max_error(&d, &u_plus, &y_odd);
    assert!(err < 1e-9, "max error {err}");
}
