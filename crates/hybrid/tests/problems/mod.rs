//! Reference problems with closed-form solutions, shared by the integration tests.
//!
//! Each test binary uses a subset of these problems.
#![allow(dead_code)]

use htfid_hybrid::{Crossing, HybridSystem, Method};

/// Both Runge-Kutta pairs; every reference problem runs against each.
pub const METHODS: [Method; 2] = [Method::Dopri5, Method::Dop853];

/// `x'' = -x` as `[x, v]`: `x = cos t`, `v = -sin t` from `[1, 0]`.
#[derive(Debug)]
pub struct Oscillator;

impl HybridSystem for Oscillator {
    type Mode = ();
    fn dim(&self) -> usize {
        2
    }
    fn vector_field(&self, _: (), _t: f64, x: &[f64], dxdt: &mut [f64]) {
        dxdt[0] = x[1];
        dxdt[1] = -x[0];
    }
}

/// The oscillator with one guard `x - level` in direction `dir` and an identity reset that
/// stays in the same chart: every crossing is logged and nothing else changes.
#[derive(Debug)]
pub struct LevelCounter {
    pub level: f64,
    pub dir: Crossing,
}

impl HybridSystem for LevelCounter {
    type Mode = ();
    fn dim(&self) -> usize {
        2
    }
    fn vector_field(&self, _: (), _t: f64, x: &[f64], dxdt: &mut [f64]) {
        dxdt[0] = x[1];
        dxdt[1] = -x[0];
    }
    fn num_guards(&self, _: ()) -> usize {
        1
    }
    fn guard(&self, _: (), _: usize, _t: f64, x: &[f64]) -> f64 {
        x[0] - self.level
    }
    fn guard_direction(&self, _: (), _: usize) -> Crossing {
        self.dir
    }
}

/// A ball `[height, velocity]` under gravity `g` bouncing on the floor `height = 0` with
/// restitution `e` (reset `v -> -e v`).
#[derive(Debug)]
pub struct Ball {
    pub g: f64,
    pub e: f64,
}

impl HybridSystem for Ball {
    type Mode = ();
    fn dim(&self) -> usize {
        2
    }
    fn vector_field(&self, _: (), _t: f64, x: &[f64], dxdt: &mut [f64]) {
        dxdt[0] = x[1];
        dxdt[1] = -self.g;
    }
    fn num_guards(&self, _: ()) -> usize {
        1
    }
    fn guard(&self, _: (), _: usize, _t: f64, x: &[f64]) -> f64 {
        x[0]
    }
    fn guard_direction(&self, _: (), _: usize) -> Crossing {
        Crossing::Falling
    }
    fn transition(&self, _: (), _: usize, _t: f64, x: &mut [f64]) {
        x[1] *= -self.e;
    }
}

/// Charts of [`Sawtooth`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Saw {
    Up,
    Down,
}

/// `x' = 1` in `Up` until `x = 1`, then `x' = -2` in `Down` until `x = 0`, and so on: from
/// `x(0) = 0` the switches fall at `t = 1, 1.5, 2.5, 3, 4, ...` (period 1.5 s).
#[derive(Debug)]
pub struct Sawtooth;

impl HybridSystem for Sawtooth {
    type Mode = Saw;
    fn dim(&self) -> usize {
        1
    }
    fn vector_field(&self, mode: Saw, _t: f64, _x: &[f64], dxdt: &mut [f64]) {
        dxdt[0] = match mode {
            Saw::Up => 1.0,
            Saw::Down => -2.0,
        };
    }
    fn num_guards(&self, _: Saw) -> usize {
        1
    }
    fn guard(&self, mode: Saw, _: usize, _t: f64, x: &[f64]) -> f64 {
        match mode {
            Saw::Up => x[0] - 1.0,
            Saw::Down => x[0],
        }
    }
    fn guard_direction(&self, mode: Saw, _: usize) -> Crossing {
        match mode {
            Saw::Up => Crossing::Rising,
            Saw::Down => Crossing::Falling,
        }
    }
    fn transition(&self, mode: Saw, _: usize, _t: f64, _x: &mut [f64]) -> Saw {
        match mode {
            Saw::Up => Saw::Down,
            Saw::Down => Saw::Up,
        }
    }
}

/// Charts of [`Clock`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Half {
    Low,
    High,
}

/// A time-dependent guard: `x' = 1` (`x` is a clock) in both charts; `Low` switches to `High`
/// when `sin t - 0.5` rises through zero, `High` back to `Low` when it falls through zero.
/// Switches at `t = pi/6 + 2 pi k` and `5 pi/6 + 2 pi k`.
#[derive(Debug)]
pub struct Clock;

impl HybridSystem for Clock {
    type Mode = Half;
    fn dim(&self) -> usize {
        1
    }
    fn vector_field(&self, _: Half, _t: f64, _x: &[f64], dxdt: &mut [f64]) {
        dxdt[0] = 1.0;
    }
    fn num_guards(&self, _: Half) -> usize {
        1
    }
    fn guard(&self, _: Half, _: usize, t: f64, _x: &[f64]) -> f64 {
        t.sin() - 0.5
    }
    fn guard_direction(&self, mode: Half, _: usize) -> Crossing {
        match mode {
            Half::Low => Crossing::Rising,
            Half::High => Crossing::Falling,
        }
    }
    fn transition(&self, mode: Half, _: usize, _t: f64, _x: &mut [f64]) -> Half {
        match mode {
            Half::Low => Half::High,
            Half::High => Half::Low,
        }
    }
}

/// `x' = x^2`, `x(0) = 1`: `x = 1 / (1 - t)`, blowing up at `t = 1`.
#[derive(Debug)]
pub struct Blowup;

impl HybridSystem for Blowup {
    type Mode = ();
    fn dim(&self) -> usize {
        1
    }
    fn vector_field(&self, _: (), _t: f64, x: &[f64], dxdt: &mut [f64]) {
        dxdt[0] = x[0] * x[0];
    }
}

/// A smooth nonlinear non-autonomous problem, `x' = -2 t x^2`, `x(0) = 1`: `x = 1 / (1 + t^2)`.
#[derive(Debug)]
pub struct Decay;

impl Decay {
    pub fn exact(t: f64) -> f64 {
        1.0 / (1.0 + t * t)
    }
}

impl HybridSystem for Decay {
    type Mode = ();
    fn dim(&self) -> usize {
        1
    }
    fn vector_field(&self, _: (), t: f64, x: &[f64], dxdt: &mut [f64]) {
        dxdt[0] = -2.0 * t * x[0] * x[0];
    }
}

/// `x'' = -1` as `[x, v]` from `[0, 1]`: `x = t - t^2 / 2`, peaking at `x = 1/2` at `t = 1`.
/// One guard `x - level` in direction `dir`, identity reset in the same chart. Both pairs
/// reproduce the parabola (and their interpolants it) to rounding with any step, so event
/// times can be checked to the location tolerance even when one step spans both crossings,
/// at `1 -+ sqrt(1 - 2 level)`.
#[derive(Debug)]
pub struct Projectile {
    pub level: f64,
    pub dir: Crossing,
}

impl Projectile {
    pub fn crossings(&self) -> (f64, f64) {
        let d = (1.0 - 2.0 * self.level).sqrt();
        (1.0 - d, 1.0 + d)
    }
}

impl HybridSystem for Projectile {
    type Mode = ();
    fn dim(&self) -> usize {
        2
    }
    fn vector_field(&self, _: (), _t: f64, x: &[f64], dxdt: &mut [f64]) {
        dxdt[0] = x[1];
        dxdt[1] = -1.0;
    }
    fn num_guards(&self, _: ()) -> usize {
        1
    }
    fn guard(&self, _: (), _: usize, _t: f64, x: &[f64]) -> f64 {
        x[0] - self.level
    }
    fn guard_direction(&self, _: (), _: usize) -> Crossing {
        self.dir
    }
}
