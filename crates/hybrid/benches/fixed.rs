//! Timing of the fixed-step integrator: a Duffing oscillator driven by a sampled force (a
//! cubic spring and light damping, near the Silverbox circuit's numbers), 65 000 samples at
//! 610 Hz with 6 sub-steps, simulated one lane after another and in lockstep batches of 2 to 4
//! lanes. Run with `cargo bench -p htfid-hybrid --bench fixed`.

use std::time::{Duration, Instant};

use htfid_hybrid::{simulate_fixed_step, simulate_fixed_step_batch, FixedStepLane, HybridSystem};

/// `m x'' + c x' + k x + k3 x^3 = u(t)`, `u` read linearly between samples.
struct Duffing {
    k: f64,
    k3: f64,
    c: f64,
    inv_m: f64,
    rate: f64,
    u: Vec<f64>,
}

impl HybridSystem for Duffing {
    type Mode = ();
    fn dim(&self) -> usize {
        2
    }
    fn vector_field(&self, _m: (), t: f64, x: &[f64], d: &mut [f64]) {
        let s = t * self.rate;
        let i = (s as usize).min(self.u.len() - 2);
        let a = s - i as f64;
        let f = (1.0 - a) * self.u[i] + a * self.u[i + 1];
        let spring = (self.k + self.k3 * x[0] * x[0]) * x[0];
        d[0] = x[1];
        d[1] = (f - spring - self.c * x[1]) * self.inv_m;
    }
}

fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> Duration {
    (0..runs)
        .map(|_| {
            let t = Instant::now();
            std::hint::black_box(f());
            t.elapsed()
        })
        .min()
        .unwrap_or_default()
}

fn main() {
    let n = 65_000;
    let rate = 1e7 / 16384.0;
    let dt = 1.0 / rate;
    let u: Vec<f64> = (0..n + 2)
        .map(|i| 0.1 * (0.37 * i as f64).sin() + 0.05 * (0.11 * i as f64).cos())
        .collect();
    let systems: Vec<Duffing> = (0..4)
        .map(|l| Duffing {
            k: 0.99 * (1.0 + 1e-7 * l as f64),
            k3: 3.9,
            c: 2.25e-4,
            inv_m: 1.0 / 5.37e-6,
            rate,
            u: u.clone(),
        })
        .collect();
    let x0 = [0.0, 0.0];
    for lanes in 1..=4 {
        let mut outs = vec![vec![0.0; n]; lanes];
        let serial = best_of(5, || {
            for (s, o) in systems.iter().zip(outs.iter_mut()) {
                simulate_fixed_step(s, (), 0.0, &x0, dt, 6, 0, o).expect("simulates");
            }
        });
        let batch = best_of(5, || {
            let mut l: Vec<FixedStepLane<'_, Duffing>> = systems
                .iter()
                .zip(outs.iter_mut())
                .map(|(system, out)| FixedStepLane {
                    system,
                    mode0: (),
                    x0: &x0,
                    out,
                })
                .collect();
            simulate_fixed_step_batch(&mut l, 0.0, dt, 6, 0)
        });
        println!(
            "{lanes} lane(s) of 65 000 samples x 6 sub-steps: one by one {serial:.2?}, in lockstep {batch:.2?} ({:.2?} per lane)",
            batch / lanes as u32
        );
    }
}
