//! Observed order of convergence with fixed steps on `x' = -2 t x^2`, `x(0) = 1`
//! (`x = 1 / (1 + t^2)`), over `[0, 2]`.
//!
//! Fixed steps: `h_init = h_max = h` and tolerances so loose that every step passes the error
//! test (the test asserts no rejection and exactly `2 / h` steps). The global error at `t = 2`
//! must shrink like `h^p` (p = 5 for Dopri5, 8 for DOP853); the dense output, sampled inside
//! every step, like `h^(q+1)` with the interpolant order q = 4 resp. 7 (its local error is
//! `O(h^(q+1))`, and the global error it inherits is `O(h^p)` with p = q + 1 for both pairs).

mod problems;

use htfid_hybrid::{Integrator, Method, Options, StopReason};
use problems::Decay;

const T_END: f64 = 2.0;

/// Global error at `T_END` and largest dense-output error at quarter points of every step.
fn errors(method: Method, steps: usize) -> (f64, f64) {
    let h = T_END / steps as f64;
    let opts = Options {
        method,
        rtol: 1e3,
        atol: 1e3,
        h_init: Some(h),
        h_max: h,
        ..Options::default()
    };
    let mut integ = Integrator::new(&Decay, (), 0.0, &[1.0], &opts).unwrap();
    let mut dense = 0.0f64;
    let mut out = [0.0];
    loop {
        let reason = integ.step_until(T_END).unwrap();
        let (a, b) = integ.dense_range().unwrap();
        for q in [0.25, 0.5, 0.75] {
            let t = a + q * (b - a);
            assert!(integ.interpolate(t, &mut out));
            dense = dense.max((out[0] - Decay::exact(t)).abs());
        }
        if matches!(reason, StopReason::TStopReached) {
            break;
        }
    }
    let s = integ.stats();
    assert_eq!(
        s.rejected, 0,
        "{method:?}, {steps} steps: fixed-step run rejected a step"
    );
    assert_eq!(s.steps, steps as u64, "{method:?}: step count");
    ((integ.state()[0] - Decay::exact(T_END)).abs(), dense)
}

/// Least-squares slope of `log(err)` against `log(h)`.
fn slope(steps: &[usize], errs: &[f64]) -> f64 {
    let xs: Vec<f64> = steps.iter().map(|&n| (T_END / n as f64).ln()).collect();
    let ys: Vec<f64> = errs.iter().map(|e| e.ln()).collect();
    let mx = xs.iter().sum::<f64>() / xs.len() as f64;
    let my = ys.iter().sum::<f64>() / ys.len() as f64;
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

fn check(method: Method, steps: &[usize], order: f64, dense_order: f64) {
    let (global, dense): (Vec<f64>, Vec<f64>) = steps.iter().map(|&n| errors(method, n)).unzip();
    let p = slope(steps, &global);
    let q = slope(steps, &dense);
    // +-0.5 as asked for: wide enough for the pre-asymptotic bend of a least-squares fit over
    // a factor 2-4 in h, narrow enough to tell 5 from 4 or 6 and 8 from 7.
    assert!(
        (p - order).abs() <= 0.5,
        "{method:?}: observed order {p:.2}, errors {global:?}"
    );
    assert!(
        (q - dense_order).abs() <= 0.5,
        "{method:?}: observed dense-output order {q:.2}, errors {dense:?}"
    );
}

#[test]
fn dopri5_is_fifth_order() {
    // Global errors from 1.6e-11 down to 1.4e-13, above rounding and in the asymptotic range
    // (observed fits: 5.19 global, 5.00 dense).
    check(Method::Dopri5, &[64, 96, 128, 160], 5.0, 5.0);
}

#[test]
fn dop853_is_eighth_order() {
    // Global errors from 3e-12 down to 1e-14; at 40 steps the error reaches rounding level
    // (observed fits: 8.26 global, 8.14 dense).
    check(Method::Dop853, &[10, 12, 16, 20], 8.0, 8.0);
}
