//! The HTF comparison of a diagnosis (`estimated_comparison`) against an analytic
//! answer: a linear spring-mass-damper, recorded with a stiffness of 400 N/m and simulated by a
//! model with 440 N/m, both by this file's own Runge-Kutta integrator. A linear time-invariant
//! system has `G_0(jw) = H(jw)` and no other harmonic, so the data's HTF minus the model's is
//! `1/(k - m w^2 + j c w) - 1/(k' - m w^2 + j c w)` at `G_0` and zero elsewhere.

use std::f64::consts::PI;

use htfid_diagnose::{estimated_comparison, TimeSeries};
use num_complex::Complex64;

const M: f64 = 1.0;
const C: f64 = 2.0;
const K_TRUE: f64 = 400.0;
const K_MODEL: f64 = 440.0;
const DT: f64 = 0.005;
const SECONDS: f64 = 130.0;
const PERIOD: f64 = 1.0;

/// A deterministic generator: 64-bit LCG, uniform in [0, 1).
struct Lcg(u64);

impl Lcg {
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let (a, b) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * a.ln()).sqrt() * (2.0 * PI * b).cos()
    }
}

/// A multisine of 300 random-phase lines from 0.1 Hz to 8 Hz, 1 N RMS.
fn input(rng: &mut Lcg) -> impl Fn(f64) -> f64 {
    let lines: Vec<(f64, f64)> = (0..300)
        .map(|i| {
            let f = 0.1 + 7.9 * i as f64 / 299.0;
            (2.0 * PI * f, 2.0 * PI * rng.uniform())
        })
        .collect();
    let amplitude = (2.0 / lines.len() as f64).sqrt();
    move |t| {
        lines
            .iter()
            .map(|(w, p)| amplitude * (w * t + p).sin())
            .sum()
    }
}

/// `m x'' + c x' + k x = u(t)` from rest, classical RK4 with ten steps per sample, at every
/// sample.
fn simulate(k: f64, u: &dyn Fn(f64) -> f64, n: usize) -> Vec<f64> {
    let h = DT / 10.0;
    let f = |t: f64, s: [f64; 2]| [s[1], (u(t) - C * s[1] - k * s[0]) / M];
    let (mut s, mut t) = ([0.0, 0.0], 0.0);
    let mut x = Vec::with_capacity(n);
    for _ in 0..n {
        x.push(s[0]);
        for _ in 0..10 {
            let k1 = f(t, s);
            let k2 = f(
                t + h / 2.0,
                [s[0] + h / 2.0 * k1[0], s[1] + h / 2.0 * k1[1]],
            );
            let k3 = f(
                t + h / 2.0,
                [s[0] + h / 2.0 * k2[0], s[1] + h / 2.0 * k2[1]],
            );
            let k4 = f(t + h, [s[0] + h * k3[0], s[1] + h * k3[1]]);
            for j in 0..2 {
                s[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
            }
            t += h;
        }
    }
    x
}

fn h(k: f64, w: f64) -> Complex64 {
    Complex64::new(1.0, 0.0) / Complex64::new(k - M * w * w, C * w)
}

/// `G_0` of the difference follows the analytic one where it stands well above the noise
/// (ten standard errors: 109 points, 17.5 to 22.9 rad/s about the resonance at 20 rad/s):
/// within three standard errors plus 5 % (the estimator's smoothing across its frequency bins
/// bends the difference where it turns fastest; measured, the error reaches 0.63 of that
/// bound, 1 to 3 % of the difference near the resonance); the other harmonics, zero for a
/// linear system, exceed two standard errors at no more than 10 % of their points (4.6 % for
/// Gaussian noise; measured at most 1.3 %).
#[test]
fn the_estimated_difference_is_the_analytic_difference_of_two_linear_systems() {
    let mut rng = Lcg(2026);
    let u = input(&mut rng);
    let n = (SECONDS / DT).round() as usize;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * DT).collect();
    let f: Vec<f64> = t.iter().map(|&t| u(t)).collect();
    let truth = simulate(K_TRUE, &u, n);
    let model = simulate(K_MODEL, &u, n);
    let sigma = 1e-5;
    let measured: Vec<f64> = truth.iter().map(|x| x + sigma * rng.normal()).collect();
    let record = TimeSeries::new(t, f, measured, "two spring-mass-dampers").unwrap();
    // From 10 s on: the start-up transient (decay rate c / 2m = 1/s) is below 5e-5 of itself.
    let rows = (10.0 / DT) as usize..n;
    let cmp = estimated_comparison(&record, rows, PERIOD, &[model], None).unwrap();
    assert_eq!(cmp.len(), 1);
    let c = &cmp[0];
    assert_eq!(c.periods, 120);
    let mut checked = 0;
    for d in &c.differences {
        assert_eq!(
            d.nominal, d.extended,
            "no extended model: the same difference"
        );
        if d.n == 0 {
            for ((w, got), se) in d.omega.iter().zip(&d.nominal).zip(&d.stderr) {
                let want = h(K_TRUE, *w) - h(K_MODEL, *w);
                if want.norm() < 10.0 * se {
                    continue;
                }
                assert!(
                    (got - want).norm() < 3.0 * se + 0.05 * want.norm(),
                    "G_0 at {w} rad/s: {got} against {want} (stderr {se})"
                );
                checked += 1;
            }
        } else {
            let outside = d.nominal_outside();
            assert!(outside <= 0.10, "G_{}: {outside} outside the noise", d.n);
        }
    }
    assert!(checked > 80, "only {checked} points of G_0 checked");
}
