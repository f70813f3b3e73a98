//! Small-signal simulation: a driven nonlinear hybrid system with the projections
//! `(1/W) int x_o(t) exp(-j w t) dt` of its first states on some frequencies integrated beside
//! it, so that they see every located event.

use std::f64::consts::TAU;

use htfid_hybrid::{Crossing, HybridSystem};
use num_complex::Complex64;

/// `inner` with the projections of its first `projected` states on `omegas` over a window
/// `window` long: state `[x, then per frequency i and state o the (Re, Im) at
/// dim + 2 (i projected + o)]`.
pub struct Projected<'a, S> {
    pub inner: &'a S,
    pub projected: usize,
    pub omegas: &'a [f64],
    pub window: f64,
}

impl<S: HybridSystem> HybridSystem for Projected<'_, S> {
    type Mode = S::Mode;
    fn dim(&self) -> usize {
        self.inner.dim() + 2 * self.projected * self.omegas.len()
    }
    fn vector_field(&self, mode: S::Mode, t: f64, z: &[f64], dz: &mut [f64]) {
        let n = self.inner.dim();
        self.inner.vector_field(mode, t, &z[..n], &mut dz[..n]);
        for (i, &w) in self.omegas.iter().enumerate() {
            let e = Complex64::from_polar(1.0 / self.window, -(w * t).rem_euclid(TAU));
            for o in 0..self.projected {
                let v = e * z[o];
                let at = n + 2 * (i * self.projected + o);
                dz[at] = v.re;
                dz[at + 1] = v.im;
            }
        }
    }
    fn num_guards(&self, mode: S::Mode) -> usize {
        self.inner.num_guards(mode)
    }
    fn guard(&self, mode: S::Mode, i: usize, t: f64, z: &[f64]) -> f64 {
        self.inner.guard(mode, i, t, &z[..self.inner.dim()])
    }
    fn guard_direction(&self, mode: S::Mode, i: usize) -> Crossing {
        self.inner.guard_direction(mode, i)
    }
    fn transition(&self, mode: S::Mode, i: usize, t: f64, z: &mut [f64]) -> S::Mode {
        let n = self.inner.dim();
        self.inner.transition(mode, i, t, &mut z[..n])
    }
}
