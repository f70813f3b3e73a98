//! The two explicit Runge-Kutta pairs: one trial step with its error norm, the dense-output
//! coefficients of an accepted step, evaluation of the interpolant, and the starting step.
//!
//! Stage values live in one flat buffer `k`, stage `s` at `k[s * n..(s + 1) * n]`. Row 0 always
//! holds `f(t, y)` at the start of the step (FSAL: copied from the last stage after an accepted
//! step, re-evaluated after an event).

use crate::tableau::{dop853, dopri5};
use crate::{HybridSystem, Method};

/// Stage rows the `k` buffer needs.
pub(crate) fn stage_rows(method: Method) -> usize {
    match method {
        Method::Dopri5 => 7,
        Method::Dop853 => 16,
    }
}

/// Rows of dense-output coefficients.
pub(crate) fn dense_rows(method: Method) -> usize {
    match method {
        Method::Dopri5 => 5,
        Method::Dop853 => 8,
    }
}

/// Row of `k` holding `f(t + h, y_new)` after a trial step.
pub(crate) fn fsal_row(method: Method) -> usize {
    match method {
        Method::Dopri5 => 6,
        Method::Dop853 => 12,
    }
}

/// Evaluates stage `s`: `k_s = f(t + c h, y + h sum_j a_j k_j)`.
#[inline]
fn stage<S: HybridSystem>(
    sys: &S,
    mode: S::Mode,
    t: f64,
    h: f64,
    c: f64,
    a: &[f64],
    y: &[f64],
    k: &mut [f64],
    s: usize,
    ytmp: &mut [f64],
) {
    let n = y.len();
    let (done, rest) = k.split_at_mut(s * n);
    for i in 0..n {
        let mut acc = 0.0;
        for (j, &aj) in a.iter().enumerate() {
            acc += aj * done[j * n + i];
        }
        ytmp[i] = y[i] + h * acc;
    }
    sys.vector_field(mode, t + c * h, ytmp, &mut rest[..n]);
}

/// Scratch vectors of a trial step.
pub(crate) struct Work<'w> {
    pub k: &'w mut [f64],
    pub ynew: &'w mut [f64],
    pub ytmp: &'w mut [f64],
    pub incr: &'w mut [f64],
}

/// One trial step of size `h` from `(t, y)`; `k` row 0 must hold `f(t, y)`.
/// Writes `ynew` and the stages (including the FSAL row) and returns the scaled error norm
/// (accept when `<= 1`), `INFINITY` when anything is not finite. Returns the number of
/// vector-field evaluations alongside.
pub(crate) fn trial_step<S: HybridSystem>(
    method: Method,
    sys: &S,
    mode: S::Mode,
    t: f64,
    h: f64,
    y: &[f64],
    w: &mut Work<'_>,
    rtol: f64,
    atol: f64,
) -> (f64, u64) {
    let n = y.len();
    let (err, evals) = match method {
        Method::Dopri5 => {
            for s in 1..6 {
                stage(sys, mode, t, h, dopri5::C[s], dopri5::A[s], y, w.k, s, w.ytmp);
            }
            let b = dopri5::A[6];
            for i in 0..n {
                let mut acc = 0.0;
                for (j, &bj) in b.iter().enumerate() {
                    acc += bj * w.k[j * n + i];
                }
                w.ynew[i] = y[i] + h * acc;
            }
            let (_, rest) = w.k.split_at_mut(6 * n);
            sys.vector_field(mode, t + h, w.ynew, &mut rest[..n]);
            let mut sum = 0.0;
            for i in 0..n {
                let mut e = 0.0;
                for (j, &ej) in dopri5::E.iter().enumerate() {
                    e += ej * w.k[j * n + i];
                }
                let sk = atol + rtol * y[i].abs().max(w.ynew[i].abs());
                let r = h * e / sk;
                sum += r * r;
            }
            ((sum / n as f64).sqrt(), 6)
        }
        Method::Dop853 => {
            for s in 1..12 {
                stage(sys, mode, t, h, dop853::C[s], dop853::A[s], y, w.k, s, w.ytmp);
            }
            let b = dop853::A[12];
            for i in 0..n {
                let mut acc = 0.0;
                for (j, &bj) in b.iter().enumerate() {
                    acc += bj * w.k[j * n + i];
                }
                w.incr[i] = acc;
                w.ynew[i] = y[i] + h * acc;
            }
            let (_, rest) = w.k.split_at_mut(12 * n);
            sys.vector_field(mode, t + h, w.ynew, &mut rest[..n]);
            let (mut e5sum, mut e3sum) = (0.0, 0.0);
            for i in 0..n {
                let mut e5 = 0.0;
                for (j, &ej) in dop853::E5.iter().enumerate() {
                    e5 += ej * w.k[j * n + i];
                }
                let e3 = w.incr[i]
                    - dop853::BHH0 * w.k[i]
                    - dop853::BHH8 * w.k[8 * n + i]
                    - dop853::BHH11 * w.k[11 * n + i];
                let sk = atol + rtol * y[i].abs().max(w.ynew[i].abs());
                e5sum += (e5 / sk) * (e5 / sk);
                e3sum += (e3 / sk) * (e3 / sk);
            }
            // Hairer's combination: the 5th-order estimate, damped by the 3rd-order one where
            // the two disagree, which keeps the controller honest at crude tolerances.
            let mut deno = e5sum + 0.01 * e3sum;
            if deno <= 0.0 {
                deno = 1.0;
            }
            (h.abs() * e5sum / (n as f64 * deno).sqrt(), 12)
        }
    };
    let finite = err.is_finite()
        && w.ynew.iter().all(|v| v.is_finite())
        && w.k[fsal_row(method) * n..(fsal_row(method) + 1) * n]
            .iter()
            .all(|v| v.is_finite());
    (if finite { err } else { f64::INFINITY }, evals)
}

/// Fills `cont` with the interpolant of the accepted step `(t, y) -> (t + h, ynew)`. For DOP853
/// this evaluates the three extra stages. Returns the number of vector-field evaluations.
pub(crate) fn build_dense<S: HybridSystem>(
    method: Method,
    sys: &S,
    mode: S::Mode,
    t: f64,
    h: f64,
    y: &[f64],
    ynew: &[f64],
    k: &mut [f64],
    ytmp: &mut [f64],
    cont: &mut [f64],
) -> u64 {
    let n = y.len();
    match method {
        Method::Dopri5 => {
            for i in 0..n {
                let dy = ynew[i] - y[i];
                let bspl = h * k[i] - dy;
                let mut d = 0.0;
                for (j, &dj) in dopri5::D.iter().enumerate() {
                    d += dj * k[j * n + i];
                }
                cont[i] = y[i];
                cont[n + i] = dy;
                cont[2 * n + i] = bspl;
                cont[3 * n + i] = dy - h * k[6 * n + i] - bspl;
                cont[4 * n + i] = h * d;
            }
            0
        }
        Method::Dop853 => {
            for s in 13..16 {
                stage(sys, mode, t, h, dop853::C[s], dop853::A[s], y, k, s, ytmp);
            }
            for i in 0..n {
                let dy = ynew[i] - y[i];
                cont[i] = y[i];
                cont[n + i] = dy;
                cont[2 * n + i] = h * k[i] - dy;
                cont[3 * n + i] = 2.0 * dy - h * (k[12 * n + i] + k[i]);
                for (r, row) in dop853::D.iter().enumerate() {
                    let mut d = 0.0;
                    for (j, &dj) in row.iter().enumerate() {
                        d += dj * k[j * n + i];
                    }
                    cont[(4 + r) * n + i] = h * d;
                }
            }
            3
        }
    }
}

/// Evaluates the interpolant at `theta = (t - t_old) / h` into `out`.
#[inline]
pub(crate) fn eval_dense(method: Method, cont: &[f64], theta: f64, out: &mut [f64]) {
    let n = out.len();
    let s = theta;
    let s1 = 1.0 - theta;
    match method {
        Method::Dopri5 => {
            for i in 0..n {
                let c = |r: usize| cont[r * n + i];
                out[i] = c(0) + s * (c(1) + s1 * (c(2) + s * (c(3) + s1 * c(4))));
            }
        }
        Method::Dop853 => {
            for i in 0..n {
                let c = |r: usize| cont[r * n + i];
                let inner = c(4) + s * (c(5) + s1 * (c(6) + s * c(7)));
                out[i] = c(0) + s * (c(1) + s1 * (c(2) + s * (c(3) + s1 * inner)));
            }
        }
    }
}

/// Hairer's starting-step estimate (`hinit` in `dopri5`/`dop853`): a step whose explicit-Euler
/// error, judged from a second derivative estimate, matches the tolerance at the method's order.
/// `f0 = f(t, y)`; `ytmp`, `f1` are scratch. Returns the step and 1 (its vector-field evaluation).
pub(crate) fn initial_step<S: HybridSystem>(
    method: Method,
    sys: &S,
    mode: S::Mode,
    t: f64,
    y: &[f64],
    f0: &[f64],
    ytmp: &mut [f64],
    f1: &mut [f64],
    rtol: f64,
    atol: f64,
    h_max: f64,
) -> (f64, u64) {
    let n = y.len();
    let (mut dnf, mut dny) = (0.0, 0.0);
    for i in 0..n {
        let sk = atol + rtol * y[i].abs();
        dnf += (f0[i] / sk) * (f0[i] / sk);
        dny += (y[i] / sk) * (y[i] / sk);
    }
    let mut h = if dnf <= 1e-10 || dny <= 1e-10 {
        1e-6
    } else {
        (dny / dnf).sqrt() * 0.01
    };
    h = h.min(h_max);
    for i in 0..n {
        ytmp[i] = y[i] + h * f0[i];
    }
    sys.vector_field(mode, t + h, ytmp, f1);
    let mut der2 = 0.0;
    for i in 0..n {
        let sk = atol + rtol * y[i].abs();
        der2 += ((f1[i] - f0[i]) / sk) * ((f1[i] - f0[i]) / sk);
    }
    let der2 = der2.sqrt() / h;
    let der12 = der2.max(dnf.sqrt());
    let order = f64::from(method.order());
    let h1 = if !der12.is_finite() {
        h * 1e-3
    } else if der12 <= 1e-15 {
        (h * 1e-3).max(1e-6)
    } else {
        (0.01 / der12).powf(1.0 / order)
    };
    let h = (100.0 * h).min(h1).min(h_max);
    (h, 1)
}
