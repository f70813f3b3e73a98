//! Test harness: records generated from a truth hopper by the adaptive integrator of
//! `htfid-hybrid` (an independent method from the diagnosis's fixed-step RK4 and spline input).
#![allow(dead_code)]

use std::f64::consts::PI;
use std::sync::Arc;

use htfid_diagnose::TimeSeries;
use htfid_hybrid::{simulate, Crossing, HybridSystem, Options};
use htfid_model::{DamperLaw, Effects, Hopper, HopperMode, HopperParams, InputFn};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// The protocol of a synthetic experiment.
#[derive(Debug, Clone)]
pub struct Protocol {
    /// TimeSeries length (s).
    pub duration: f64,
    /// Sample rate (Hz).
    pub rate: f64,
    /// Settling time before the chirps (s).
    pub settle: f64,
    /// Length of one chirp (s); each sweeps 0 to `f_max` Hz linearly.
    pub chirp_len: f64,
    /// Top chirp frequency (Hz).
    pub f_max: f64,
    /// Chirp amplitude (N).
    pub amplitude: f64,
    /// Number of phase-shifted copies (phases `2 pi j / copies`).
    pub copies: usize,
    /// Standard deviation of the position noise (m).
    pub noise_x: f64,
    /// Standard deviation of the force-measurement noise (N).
    pub noise_f: f64,
}

impl Default for Protocol {
    fn default() -> Self {
        Protocol {
            duration: 80.0,
            rate: 100.0,
            settle: 5.0,
            chirp_len: 15.0,
            f_max: 7.0,
            amplitude: 0.05,
            copies: 5,
            noise_x: 2e-6,
            noise_f: 1e-4,
        }
    }
}

impl Protocol {
    /// The chirp train `u(t)` added to the forcing.
    pub fn chirp(&self) -> impl Fn(f64) -> f64 + Send + Sync + Clone + 'static {
        let p = self.clone();
        move |t: f64| {
            if t < p.settle {
                return 0.0;
            }
            let s = t - p.settle;
            let j = (s / p.chirp_len).floor();
            let tau = s - j * p.chirp_len;
            let phase = 2.0 * PI * (j as usize % p.copies) as f64 / p.copies as f64;
            // Cosine ramps of 1 s at both ends keep the force smooth across chirps (a jump
            // between samples could not be reconstructed from any sampled record).
            let ramp = |s: f64| {
                if s >= 1.0 {
                    1.0
                } else {
                    0.5 - 0.5 * (PI * s).cos()
                }
            };
            let taper = ramp(tau) * ramp(p.chirp_len - tau);
            taper * p.amplitude * (PI * p.f_max * tau * tau / p.chirp_len + phase).sin()
        }
    }
}

/// An extra force `g(t, x, x')` (N) outside the library, unknown to the measured force.
pub type ExtraForce = Arc<dyn Fn(f64, f64, f64) -> f64 + Send + Sync>;

/// The hopper with an extra force added to its acceleration.
struct WithExtra {
    hopper: Hopper,
    extra: Option<ExtraForce>,
    m: f64,
}

impl HybridSystem for WithExtra {
    type Mode = HopperMode;
    fn dim(&self) -> usize {
        self.hopper.dim()
    }
    fn vector_field(&self, mode: HopperMode, t: f64, x: &[f64], d: &mut [f64]) {
        self.hopper.vector_field(mode, t, x, d);
        if let Some(g) = &self.extra {
            d[1] += g(t, x[0], x[1]) / self.m;
        }
    }
    fn num_guards(&self, mode: HopperMode) -> usize {
        self.hopper.num_guards(mode)
    }
    fn guard(&self, mode: HopperMode, i: usize, t: f64, x: &[f64]) -> f64 {
        self.hopper.guard(mode, i, t, x)
    }
    fn guard_direction(&self, mode: HopperMode, i: usize) -> Crossing {
        self.hopper.guard_direction(mode, i)
    }
    fn transition(&self, mode: HopperMode, i: usize, t: f64, x: &mut [f64]) -> HopperMode {
        self.hopper.transition(mode, i, t, x)
    }
}

/// A record of the hopper with `params` and `effects`, forcing `A cos(2 pi t / T)` plus the
/// chirp train, integrated by DOP853 (`rtol = 1e-10`) with event location; `extra` is a force
/// the measured `f` does not contain (an effect outside the library). Position and force noise
/// are seeded.
pub fn generate(
    protocol: &Protocol,
    params: HopperParams,
    effects: Effects,
    extra: Option<ExtraForce>,
    seed: u64,
) -> TimeSeries {
    let chirp = protocol.chirp();
    let u: InputFn = Arc::new(chirp);
    let hopper = WithExtra {
        hopper: Hopper::with_effects(params, DamperLaw::Switching, effects)
            .unwrap()
            .with_input(Some(u)),
        extra,
        m: params.m,
    };
    let n = (protocol.duration * protocol.rate).round() as usize;
    let dt = 1.0 / protocol.rate;
    let grid: Vec<f64> = (0..n).map(|i| i as f64 * dt).collect();
    let x0 = hopper.hopper.initial_guess();
    let mode0 = hopper.hopper.mode_of(x0[1]);
    let opts = Options {
        rtol: 1e-10,
        atol: 1e-12,
        ..Options::default()
    };
    let traj = simulate(&hopper, mode0, 0.0, &x0, grid[n - 1], &grid, &opts).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let nx = Normal::new(0.0, protocol.noise_x.max(1e-300)).unwrap();
    let nf = Normal::new(0.0, protocol.noise_f.max(1e-300)).unwrap();
    let chirp = protocol.chirp();
    let mut f = Vec::with_capacity(n);
    let mut x = Vec::with_capacity(n);
    for (i, &t) in grid.iter().enumerate() {
        // The measured force: forcing and chirp, without the extra force.
        let applied = params.forcing_amplitude * (2.0 * PI * t / params.period).cos() + chirp(t);
        f.push(applied + nf.sample(&mut rng));
        x.push(traj.state(i)[0] + nx.sample(&mut rng));
    }
    TimeSeries::new(grid, f, x, "test").unwrap()
}
