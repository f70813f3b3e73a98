//! Brute-force reference: fixed-step RK4 simulation of a two-state LTP
//! system driven by `u = exp(j w0 t)`, written independently of the crate
//! (no Fourier series, no matrix exponentials, no closed forms).

#![allow(dead_code)]

use nalgebra::{Matrix2, RowVector2, Vector2};
use num_complex::Complex64;
use std::f64::consts::TAU;

pub type CVec2 = Vector2<Complex64>;

/// Matrices `(A, B, C, D)` on one segment at time `t`.
pub type SegmentFn<'a> =
    dyn Fn(usize, f64) -> (Matrix2<f64>, Vector2<f64>, RowVector2<f64>, f64) + 'a;

/// A two-state LTP system on `[0, T)`, split into segments
/// `[bounds[k], bounds[k+1])` (`bounds[0] = 0`, last = `T`). The matrices are
/// given per segment so that a right-end stage time never reads the next
/// segment; `jumps[k]` acts at the start of segment `k`.
pub struct BruteLtp<'a> {
    pub period: f64,
    pub bounds: Vec<f64>,
    pub jumps: Vec<Matrix2<f64>>,
    pub matrices: &'a SegmentFn<'a>,
}

fn to_c(m: &Matrix2<f64>) -> Matrix2<Complex64> {
    m.map(|x| Complex64::new(x, 0.0))
}

impl BruteLtp<'_> {
    fn steps(&self, k: usize, h_max: f64) -> usize {
        let len = self.bounds[k + 1] - self.bounds[k];
        let n = (len / h_max).ceil() as usize;
        // Even, for composite Simpson.
        n + n % 2
    }

    /// One period from `x(0-)`, jumps included, optionally forced by
    /// `exp(j w0 t)`. `visit(t, segment, x)` sees every grid state.
    fn period_map(
        &self,
        x0: CVec2,
        forcing: Option<f64>,
        h_max: f64,
        mut visit: impl FnMut(usize, usize, f64, &CVec2),
    ) -> CVec2 {
        let mut x = x0;
        for k in 0..self.bounds.len() - 1 {
            x = to_c(&self.jumps[k]) * x;
            let t0 = self.bounds[k];
            let steps = self.steps(k, h_max);
            let h = (self.bounds[k + 1] - t0) / steps as f64;
            let f = |t: f64, x: &CVec2| -> CVec2 {
                let (a, b, _, _) = (self.matrices)(k, t);
                let mut dx = to_c(&a) * x;
                if let Some(w0) = forcing {
                    let u = Complex64::from_polar(1.0, w0 * t);
                    dx += b.map(|v| Complex64::new(v, 0.0)) * u;
                }
                dx
            };
            visit(k, 0, t0, &x);
            for i in 0..steps {
                let t = t0 + i as f64 * h;
                let k1 = f(t, &x);
                let k2 = f(t + 0.5 * h, &(x + k1 * Complex64::new(0.5 * h, 0.0)));
                let k3 = f(t + 0.5 * h, &(x + k2 * Complex64::new(0.5 * h, 0.0)));
                let k4 = f(t + h, &(x + k3 * Complex64::new(h, 0.0)));
                let two = Complex64::new(2.0, 0.0);
                x += (k1 + k2 * two + k3 * two + k4) * Complex64::new(h / 6.0, 0.0);
                visit(k, i + 1, t0 + (i + 1) as f64 * h, &x);
            }
        }
        x
    }

    /// Monodromy matrix `x(0-) -> x(T-)` by RK4 propagation of the identity.
    pub fn monodromy(&self, h_max: f64) -> Matrix2<f64> {
        let mut m = Matrix2::zeros();
        for col in 0..2 {
            let mut e = CVec2::zeros();
            e[col] = Complex64::new(1.0, 0.0);
            let x = self.period_map(e, None, h_max, |_, _, _, _| {});
            for row in 0..2 {
                m[(row, col)] = x[row].re;
            }
        }
        m
    }

    /// Steady-state output harmonics `Y_k` (`y = sum_k Y_k exp(j (w0 + k wp) t)`)
    /// for `u = exp(j w0 t)`: periodic initial state from the RK4 period map,
    /// then composite Simpson per segment of `y(t) exp(-j (w0 + k wp) t) / T`.
    pub fn harmonics(&self, w0: f64, ks: &[i32], h_max: f64) -> Vec<Complex64> {
        let wp = TAU / self.period;
        let m = self.monodromy(h_max).map(|x| Complex64::new(x, 0.0));
        let r = self.period_map(CVec2::zeros(), Some(w0), h_max, |_, _, _, _| {});
        // x(T-) = exp(j w0 T) x(0-) for x = exp(j w0 t) p(t), p periodic.
        let lhs = Matrix2::identity() * Complex64::from_polar(1.0, w0 * self.period) - m;
        let x0 = lhs
            .lu()
            .solve(&r)
            .expect("no Floquet multiplier on exp(j w0 T)");
        let mut acc = vec![Complex64::new(0.0, 0.0); ks.len()];
        let mut weights_h = Vec::new();
        for k in 0..self.bounds.len() - 1 {
            let steps = self.steps(k, h_max);
            weights_h.push(((self.bounds[k + 1] - self.bounds[k]) / steps as f64, steps));
        }
        self.period_map(x0, Some(w0), h_max, |seg, i, t, x| {
            let (_, _, c, d) = (self.matrices)(seg, t);
            let u = Complex64::from_polar(1.0, w0 * t);
            let y = c[0] * x[0] + c[1] * x[1] + u * d;
            let (h, steps) = weights_h[seg];
            let w = if i == 0 || i == steps {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            for (a, &kk) in acc.iter_mut().zip(ks) {
                let rot = Complex64::from_polar(1.0, -(w0 + f64::from(kk) * wp) * t);
                *a += y * rot * (w * h / 3.0);
            }
        });
        acc.into_iter().map(|a| a / self.period).collect()
    }
}

/// Hopper-like matrices: `A = [[0, 1], [-k, -c s]]`, `B = [0, 1]`, `C = [1, 0]`.
pub fn hopper_matrices(
    k: f64,
    c: f64,
    damper_on: bool,
) -> (Matrix2<f64>, Vector2<f64>, RowVector2<f64>, f64) {
    let damping = if damper_on { c } else { 0.0 };
    (
        Matrix2::new(0.0, 1.0, -k, -damping),
        Vector2::new(0.0, 1.0),
        RowVector2::new(1.0, 0.0),
        0.0,
    )
}
