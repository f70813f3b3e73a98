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

// Speed: state dimensions in this workspace are small (2 to 6). With `n` unknown, index
// arithmetic, bounds checks and loop overhead cost more than the arithmetic, so the public
// entry points dispatch on `n` and call `#[inline(always)]` bodies with `n` a literal for
// n <= 4: the compiler then unrolls every component loop. Larger `n` takes the same code with
// `n` at run time.
macro_rules! dispatch_dim {
    ($n:expr, $f:ident($($arg:expr),* $(,)?)) => {
        match $n {
            1 => $f(1, $($arg),*),
            2 => $f(2, $($arg),*),
            3 => $f(3, $($arg),*),
            4 => $f(4, $($arg),*),
            n => $f(n, $($arg),*),
        }
    };
}

/// `out = sum_j w_j k_j` over the first `w.len()` stage rows (`k_j = k[j n..(j + 1) n]`).
/// Zero weights (DOP853 has many) are skipped for larger states, where that saves a row of
/// work; for small ones the test costs as much as the arithmetic.
#[inline(always)]
fn weighted(n: usize, w: &[f64], k: &[f64], out: &mut [f64]) {
    let out = &mut out[..n];
    out.fill(0.0);
    for (j, &wj) in w.iter().enumerate() {
        if n > 4 && wj == 0.0 {
            continue;
        }
        let kj = &k[j * n..j * n + n];
        for i in 0..n {
            out[i] += wj * kj[i];
        }
    }
}

/// `out = y + h sum_j a_j k_j`; `acc` is scratch. The increment is summed before it is added
/// to `y`, which keeps the rounding relative to the increment.
#[inline(always)]
fn combine(n: usize, y: &[f64], h: f64, a: &[f64], k: &[f64], acc: &mut [f64], out: &mut [f64]) {
    weighted(n, a, k, acc);
    let (y, acc, out) = (&y[..n], &acc[..n], &mut out[..n]);
    for i in 0..n {
        out[i] = y[i] + h * acc[i];
    }
}

/// Evaluates stage `s`: `k_s = f(t + c h, y + h sum_j a_j k_j)`.
#[inline(always)]
fn stage<S: HybridSystem + ?Sized>(
    n: usize,
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
    acc: &mut [f64],
) {
    let (done, rest) = k.split_at_mut(s * n);
    combine(n, y, h, a, done, acc, ytmp);
    sys.vector_field(mode, t + c * h, ytmp, &mut rest[..n]);
}

/// Scratch vectors of a trial step.
pub(crate) struct Work<'w> {
    pub k: &'w mut [f64],
    pub ynew: &'w mut [f64],
    pub ytmp: &'w mut [f64],
    /// Weighted stage sums (`n`).
    pub incr: &'w mut [f64],
    /// A second scratch vector (`n`).
    pub acc: &'w mut [f64],
}

/// One trial step of size `h` from `(t, y)`; `k` row 0 must hold `f(t, y)`.
/// Writes `ynew` and the stages (including the FSAL row) and returns the scaled error norm
/// (accept when `<= 1`), `INFINITY` when anything is not finite, with the number of
/// vector-field evaluations.
pub(crate) fn trial_step<S: HybridSystem + ?Sized>(
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
    dispatch_dim!(
        y.len(),
        trial_step_n(method, sys, mode, t, h, y, w, rtol, atol)
    )
}

#[inline(always)]
fn trial_step_n<S: HybridSystem + ?Sized>(
    n: usize,
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
    let y = &y[..n];
    let (err, evals) = match method {
        Method::Dopri5 => {
            for s in 1..6 {
                let (c, a) = (dopri5::C[s], dopri5::A[s]);
                stage(n, sys, mode, t, h, c, a, y, w.k, s, w.ytmp, w.acc);
            }
            combine(n, y, h, dopri5::A[6], w.k, w.acc, w.ynew);
            let (_, rest) = w.k.split_at_mut(6 * n);
            sys.vector_field(mode, t + h, w.ynew, &mut rest[..n]);
            weighted(n, &dopri5::E, w.k, w.incr);
            let (ynew, e) = (&w.ynew[..n], &w.incr[..n]);
            let mut sum = 0.0;
            for i in 0..n {
                let sk = atol + rtol * y[i].abs().max(ynew[i].abs());
                let r = h * e[i] / sk;
                sum += r * r;
            }
            ((sum / n as f64).sqrt(), 6)
        }
        Method::Dop853 => {
            for s in 1..12 {
                let (c, a) = (dop853::C[s], dop853::A[s]);
                stage(n, sys, mode, t, h, c, a, y, w.k, s, w.ytmp, w.acc);
            }
            // The 8th-order increment, kept for the 3rd-order error estimate.
            weighted(n, dop853::A[12], w.k, w.incr);
            for i in 0..n {
                w.ynew[i] = y[i] + h * w.incr[i];
            }
            let (_, rest) = w.k.split_at_mut(12 * n);
            sys.vector_field(mode, t + h, w.ynew, &mut rest[..n]);
            weighted(n, &dop853::E5, w.k, w.acc);
            let (k0, k8, k11) = (&w.k[..n], &w.k[8 * n..9 * n], &w.k[11 * n..12 * n]);
            let (ynew, incr, e5) = (&w.ynew[..n], &w.incr[..n], &w.acc[..n]);
            let (mut e5sum, mut e3sum) = (0.0, 0.0);
            for i in 0..n {
                let e3 =
                    incr[i] - dop853::BHH0 * k0[i] - dop853::BHH8 * k8[i] - dop853::BHH11 * k11[i];
                let inv = 1.0 / (atol + rtol * y[i].abs().max(ynew[i].abs()));
                let (e5, e3) = (e5[i] * inv, e3 * inv);
                e5sum += e5 * e5;
                e3sum += e3 * e3;
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
    let fsal = fsal_row(method) * n;
    let finite = err.is_finite()
        && w.ynew[..n].iter().all(|v| v.is_finite())
        && w.k[fsal..fsal + n].iter().all(|v| v.is_finite());
    (if finite { err } else { f64::INFINITY }, evals)
}

/// Fills `cont` with the interpolant of the accepted step `(t, y) -> (t + h, ynew)`. For DOP853
/// this evaluates the three extra stages. Returns the number of vector-field evaluations.
pub(crate) fn build_dense<S: HybridSystem + ?Sized>(
    method: Method,
    sys: &S,
    mode: S::Mode,
    t: f64,
    h: f64,
    y: &[f64],
    ynew: &[f64],
    k: &mut [f64],
    ytmp: &mut [f64],
    acc: &mut [f64],
    cont: &mut [f64],
) -> u64 {
    dispatch_dim!(
        y.len(),
        build_dense_n(method, sys, mode, t, h, y, ynew, k, ytmp, acc, cont)
    )
}

#[inline(always)]
fn build_dense_n<S: HybridSystem + ?Sized>(
    n: usize,
    method: Method,
    sys: &S,
    mode: S::Mode,
    t: f64,
    h: f64,
    y: &[f64],
    ynew: &[f64],
    k: &mut [f64],
    ytmp: &mut [f64],
    acc: &mut [f64],
    cont: &mut [f64],
) -> u64 {
    let evals = match method {
        Method::Dopri5 => 0,
        Method::Dop853 => {
            for s in 13..16 {
                let (c, a) = (dop853::C[s], dop853::A[s]);
                stage(n, sys, mode, t, h, c, a, y, k, s, ytmp, acc);
            }
            3
        }
    };
    let (y, ynew) = (&y[..n], &ynew[..n]);
    let fsal = fsal_row(method) * n;
    let (k0, kf) = (&k[..n], &k[fsal..fsal + n]);
    let (c_low, c_high) = cont.split_at_mut(4 * n);
    for i in 0..n {
        let dy = ynew[i] - y[i];
        let bspl = h * k0[i] - dy;
        c_low[i] = y[i];
        c_low[n + i] = dy;
        c_low[2 * n + i] = bspl;
        // Equals `2 dy - h (f_new + f_old)`: the cubic Hermite term.
        c_low[3 * n + i] = dy - h * kf[i] - bspl;
    }
    let rows: &[&[f64]] = match method {
        Method::Dopri5 => &[&dopri5::D],
        Method::Dop853 => &[&dop853::D[0], &dop853::D[1], &dop853::D[2], &dop853::D[3]],
    };
    for (row, out) in rows.iter().zip(c_high.chunks_exact_mut(n)) {
        weighted(n, row, k, acc);
        for i in 0..n {
            out[i] = h * acc[i];
        }
    }
    evals
}

/// Evaluates the interpolant at `theta = (t - t_old) / h` into `out`.
#[inline]
pub(crate) fn eval_dense(method: Method, cont: &[f64], theta: f64, out: &mut [f64]) {
    dispatch_dim!(out.len(), eval_dense_n(method, cont, theta, out))
}

#[inline(always)]
fn eval_dense_n(n: usize, method: Method, cont: &[f64], theta: f64, out: &mut [f64]) {
    let s = theta;
    let s1 = 1.0 - theta;
    let r = |row: usize| &cont[row * n..(row + 1) * n];
    let out = &mut out[..n];
    match method {
        Method::Dopri5 => {
            let (c0, c1, c2, c3, c4) = (r(0), r(1), r(2), r(3), r(4));
            for i in 0..n {
                out[i] = c0[i] + s * (c1[i] + s1 * (c2[i] + s * (c3[i] + s1 * c4[i])));
            }
        }
        Method::Dop853 => {
            let (c0, c1, c2, c3) = (r(0), r(1), r(2), r(3));
            let (c4, c5, c6, c7) = (r(4), r(5), r(6), r(7));
            for i in 0..n {
                let inner = c4[i] + s * (c5[i] + s1 * (c6[i] + s * c7[i]));
                out[i] = c0[i] + s * (c1[i] + s1 * (c2[i] + s * (c3[i] + s1 * inner)));
            }
        }
    }
}

/// Hairer's starting-step estimate (`hinit` in `dopri5`/`dop853`): a step whose explicit-Euler
/// error, judged from a second derivative estimate, matches the tolerance at the method's order.
/// `f0 = f(t, y)`; `ytmp`, `f1` are scratch. Returns the step and 1 (its vector-field evaluation).
pub(crate) fn initial_step<S: HybridSystem + ?Sized>(
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
