//! Synthetic LTP data with known harmonic transfer functions, built exactly on the DFT grid of
//! periodic inputs (so there is no leakage) and brought to time by a naive inverse DFT that is
//! independent of the crate's transform.
#![allow(dead_code)]

use std::f64::consts::PI;

use htfid_estimate::{deviation_record, TimeSeries};
use num_complex::Complex64;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A truth `G_n(jw)` for `n` in `-nmax..=nmax`, satisfying `G_n(-jw) = conj(G_{-n}(jw))` so that
/// real inputs give real outputs.
pub trait Truth {
    fn nmax(&self) -> i32;
    fn g(&self, n: i32, w: f64) -> Complex64;
}

/// `G_n(s) = a_n / (s^2 + b_n s + c_n)`, `a_{-n} = conj(a_n)`, `b`, `c` shared by `+-n`.
#[derive(Debug, Clone)]
pub struct Rational {
    /// `(a_n, b_n, c_n)` for `n = 0..=nmax`.
    pub coef: Vec<(Complex64, f64, f64)>,
}

impl Rational {
    /// Resonances at 10, 12, 8 and 16 rad/s with damping ratios 0.1 to 0.16.
    pub fn standard(nmax: i32) -> Self {
        let all = [
            (Complex64::new(100.0, 0.0), 2.0, 100.0),
            (Complex64::new(30.0, 20.0), 3.0, 150.0),
            (Complex64::new(10.0, -5.0), 2.5, 64.0),
            (Complex64::new(3.0, 3.0), 5.0, 250.0),
        ];
        Self {
            coef: all[..=nmax as usize].to_vec(),
        }
    }

    /// Same shapes, but with damping scaled by `f` (broader, smoother resonances for f > 1).
    pub fn damped(nmax: i32, f: f64) -> Self {
        let mut r = Self::standard(nmax);
        for c in &mut r.coef {
            c.1 *= f;
        }
        r
    }
}

impl Truth for Rational {
    fn nmax(&self) -> i32 {
        self.coef.len() as i32 - 1
    }
    fn g(&self, n: i32, w: f64) -> Complex64 {
        let (a, b, c) = self.coef[n.unsigned_abs() as usize];
        let a = if n < 0 { a.conj() } else { a };
        let s = Complex64::new(0.0, w);
        a / (s * s + s * b + c)
    }
}

/// `G_n(jw) = a_n + b_n w` with `a_{-n} = conj(a_n)`, `b_{-n} = -conj(b_n)` (`a_0` must be real
/// and `b_0` imaginary).
#[derive(Debug, Clone)]
pub struct Affine {
    pub coef: Vec<(Complex64, Complex64)>,
}

impl Truth for Affine {
    fn nmax(&self) -> i32 {
        self.coef.len() as i32 - 1
    }
    fn g(&self, n: i32, w: f64) -> Complex64 {
        let (a, b) = self.coef[n.unsigned_abs() as usize];
        if n < 0 {
            a.conj() - b.conj() * w
        } else {
            a + b * w
        }
    }
}

/// A truth with one harmonic switched off or rescaled, keeping the conjugate symmetry.
pub struct Masked<'a, T: Truth> {
    pub inner: &'a T,
    pub keep: fn(i32) -> bool,
}

impl<T: Truth> Truth for Masked<'_, T> {
    fn nmax(&self) -> i32 {
        self.inner.nmax()
    }
    fn g(&self, n: i32, w: f64) -> Complex64 {
        if (self.keep)(n) {
            self.inner.g(n, w)
        } else {
            Complex64::new(0.0, 0.0)
        }
    }
}

/// A grid: `n` samples of `dt`, `p` system periods of `period`.
#[derive(Debug, Clone, Copy)]
pub struct Grid {
    pub n: usize,
    pub dt: f64,
    pub period: f64,
}

impl Grid {
    pub fn p(&self) -> i64 {
        (self.n as f64 * self.dt / self.period).round() as i64
    }
    pub fn dw(&self) -> f64 {
        2.0 * PI / (self.n as f64 * self.dt)
    }
}

/// A Hermitian input spectrum `C[k]` (one multisine period = the record), nonzero for
/// `|k| <= kmax`, magnitudes in `[0.5, 1.5]`, random phases.
pub fn random_spectrum(kmax: i64, seed: u64) -> Vec<Complex64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut c = vec![Complex64::new(0.0, 0.0); 2 * kmax as usize + 1];
    c[kmax as usize] = Complex64::new(rng.gen_range(0.5..1.5), 0.0);
    for k in 1..=kmax {
        let v = Complex64::from_polar(rng.gen_range(0.5..1.5), rng.gen_range(0.0..2.0 * PI));
        c[(kmax + k) as usize] = v;
        c[(kmax - k) as usize] = v.conj();
    }
    c
}

/// `C[k]` from [`random_spectrum`] output, zero outside.
pub fn c_at(c: &[Complex64], k: i64) -> Complex64 {
    let kmax = (c.len() as i64 - 1) / 2;
    if k.abs() > kmax {
        Complex64::new(0.0, 0.0)
    } else {
        c[(kmax + k) as usize]
    }
}

/// Nonzero DFT bins as `(signed bin, value)`.
pub type Bins = Vec<(i64, Complex64)>;

/// Spectra of one record: input `U[k] = C[k] exp(-j w_k tau)` (the periodic input delayed by
/// `tau`) and output `Y[k] = sum_n G_n(w_k) U[k - nP]`, on bins `-kmax_out..=kmax_out`.
pub fn record_spectra(grid: Grid, c: &[Complex64], tau: f64, truth: &dyn Truth) -> (Bins, Bins) {
    let kmax = (c.len() as i64 - 1) / 2;
    let p = grid.p();
    let dw = grid.dw();
    let u = |k: i64| c_at(c, k) * Complex64::from_polar(1.0, -(k as f64) * dw * tau);
    let kout = kmax + i64::from(truth.nmax()) * p;
    assert!(2 * kout < grid.n as i64, "synthetic output reaches Nyquist");
    let us = (-kmax..=kmax).map(|k| (k, u(k))).collect();
    let ys = (-kout..=kout)
        .map(|k| {
            let y: Complex64 = (-truth.nmax()..=truth.nmax())
                .map(|n| truth.g(n, k as f64 * dw) * u(k - i64::from(n) * p))
                .sum();
            (k, y)
        })
        .collect();
    (us, ys)
}

/// Naive inverse of the absolute-time DFT:
/// `x_i = (1 / (N dt)) sum_k X[k] exp(j w_k (t_start + i dt))`; panics if the result is not real.
pub fn inverse(grid: Grid, t_start: f64, bins: &[(i64, Complex64)]) -> Vec<f64> {
    let dw = grid.dw();
    let len = grid.n as f64 * grid.dt;
    let mut out = Vec::with_capacity(grid.n);
    let scale: f64 = bins.iter().map(|b| b.1.norm()).sum::<f64>() / len;
    for i in 0..grid.n {
        let t = t_start + i as f64 * grid.dt;
        let x: Complex64 = bins
            .iter()
            .map(|&(k, v)| v * Complex64::from_polar(1.0, k as f64 * dw * t))
            .sum::<Complex64>()
            / len;
        assert!(x.im.abs() <= 1e-10 * scale.max(1e-300), "not real: {x}");
        out.push(x.re);
    }
    out
}

/// A noise-free record of the truth driven by the periodic input `C` delayed by `tau`, sampled
/// from `t_start`.
pub fn synth_record(
    grid: Grid,
    c: &[Complex64],
    tau: f64,
    t_start: f64,
    truth: &dyn Truth,
) -> TimeSeries {
    let (us, ys) = record_spectra(grid, c, tau, truth);
    deviation_record(
        inverse(grid, t_start, &us),
        inverse(grid, t_start, &ys),
        grid.dt,
        t_start,
    )
    .unwrap()
}

/// The same record with seeded white Gaussian noise of standard deviation `sigma` on the output.
pub fn with_noise(r: &TimeSeries, sigma: f64, rng: &mut ChaCha8Rng) -> TimeSeries {
    use rand_distr::{Distribution, Normal};
    let normal = Normal::new(0.0, sigma).unwrap();
    let y = r.output().iter().map(|v| v + normal.sample(rng)).collect();
    deviation_record(r.input().to_vec(), y, r.dt(), r.time()[0]).unwrap()
}

/// Largest `|a - b| / max|b|` over paired complex values.
pub fn max_rel_err(a: &[Complex64], b: &[Complex64]) -> f64 {
    let scale = b.iter().map(|v| v.norm()).fold(0.0, f64::max);
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).norm())
        .fold(0.0, f64::max)
        / scale
}

/// Root mean square of `|a - b|` over `rms(b)`.
pub fn rms_rel_err(a: &[Complex64], b: &[Complex64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y).norm_sqr()).sum();
    let den: f64 = b.iter().map(|y| y.norm_sqr()).sum();
    (num / den).sqrt()
}
