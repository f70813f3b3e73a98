//! Slow, obvious oracles shared by the integration tests.
#![allow(dead_code)]

use num_complex::Complex64;
use std::f64::consts::TAU;

/// Naive DFT `X[c] = sum_k x_k exp(-j 2 pi c k / N)` at the requested bins
/// (any sign). Twiddles come from a table indexed by `c k mod N`, so large
/// products lose no accuracy.
pub struct NaiveDft {
    n: usize,
    table: Vec<Complex64>,
}

impl NaiveDft {
    pub fn new(n: usize) -> Self {
        let table = (0..n)
            .map(|m| Complex64::from_polar(1.0, -TAU * m as f64 / n as f64))
            .collect();
        Self { n, table }
    }

    pub fn bin(&self, x: &[f64], c: i64) -> Complex64 {
        assert_eq!(x.len(), self.n);
        let c = c.rem_euclid(self.n as i64) as usize;
        let mut acc = Complex64::new(0.0, 0.0);
        for (k, &v) in x.iter().enumerate() {
            acc += self.table[(c * k) % self.n] * v;
        }
        acc
    }
}

/// Largest |u| on a grid of `per_cycle` samples per cycle of the fastest line.
pub fn brute_peak(u: &dyn htfid_excite::Signal, period: f64, max_bin: u64, per_cycle: u64) -> f64 {
    let n = (max_bin * per_cycle) as usize;
    (0..n)
        .map(|i| u.value(i as f64 * period / n as f64).abs())
        .fold(0.0, f64::max)
}
