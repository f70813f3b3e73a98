//! The benchmark workloads: vector fields with their Jacobians, as expression text and written
//! by hand in Rust (the floor). Shared with the comparison against other crates, which lives
//! outside the workspace (see docs/expressions.md).

use std::f64::consts::PI;

use htfid_expr::{parse, Expr};

/// A vector field over `states` (first in `vars`), plus parameters and time.
pub struct Workload {
    pub name: &'static str,
    pub vars: &'static [&'static str],
    pub states: &'static [&'static str],
    pub field: &'static [&'static str],
    /// Field then Jacobian, row-major, written by hand.
    pub hand: fn(&[f64], &mut [f64]),
    pub point: &'static [f64],
}

impl Workload {
    /// The field's components followed by the Jacobian `d f_i / d state_j`, row-major.
    pub fn exprs(&self) -> Vec<Expr> {
        let f: Vec<Expr> = self.field.iter().map(|s| parse(s).unwrap()).collect();
        let mut all = f.clone();
        for fi in &f {
            for s in self.states {
                all.push(fi.derivative(s));
            }
        }
        all
    }

    /// Index of time `t` in `vars`, varied from call to call.
    pub fn time_slot(&self) -> usize {
        self.vars.iter().position(|v| *v == "t").unwrap()
    }
}

pub fn all() -> [Workload; 2] {
    [
        Workload {
            name: "hopper (2 states, 6 outputs)",
            vars: &["x", "v", "t", "m", "g", "c", "k", "x0", "a", "T", "u"],
            states: &["x", "v"],
            field: &["v", "(-m*g - c*v - k*(x - x0) + a*cos(2*pi*t/T) + u)/m"],
            hand: hopper,
            point: &[0.1, -0.4, 0.3, 80.0, 9.81, 120.0, 2e4, 0.05, 30.0, 1.1, 5.0],
        },
        Workload {
            name: "2-DOF cubic springs (4 states, 20 outputs)",
            vars: &[
                "x1", "v1", "x2", "v2", "t", "m1", "m2", "k1", "k2", "k3", "c1", "c2", "a", "w",
            ],
            states: &["x1", "v1", "x2", "v2"],
            field: &[
                "v1",
                "(-k1*x1 - k3*x1^3 - c1*v1 + k2*(x2 - x1) + c2*(v2 - v1) + a*sin(w*t))/m1",
                "v2",
                "(-k2*(x2 - x1) - k3*(x2 - x1)^3 - c2*(v2 - v1))/m2",
            ],
            hand: two_dof,
            point: &[
                0.02, 0.1, -0.01, 0.3, 0.7, 2.0, 1.5, 100.0, 50.0, 1e4, 0.8, 0.4, 3.0, 12.0,
            ],
        },
    ]
}

fn hopper(p: &[f64], out: &mut [f64]) {
    let [x, v, t, m, g, c, k, x0, a, tt, u] = p[..11] else {
        return;
    };
    out[0] = v;
    out[1] = (-m * g - c * v - k * (x - x0) + a * (2.0 * PI * t / tt).cos() + u) / m;
    out[2] = 0.0;
    out[3] = 1.0;
    out[4] = -k / m;
    out[5] = -c / m;
}

fn two_dof(p: &[f64], out: &mut [f64]) {
    let [x1, v1, x2, v2, t, m1, m2, k1, k2, k3, c1, c2, a, w] = p[..14] else {
        return;
    };
    let d = x2 - x1;
    out[0] = v1;
    out[1] =
        (-k1 * x1 - k3 * x1 * x1 * x1 - c1 * v1 + k2 * d + c2 * (v2 - v1) + a * (w * t).sin()) / m1;
    out[2] = v2;
    out[3] = (-k2 * d - k3 * d * d * d - c2 * (v2 - v1)) / m2;
    // Jacobian rows: d f0, d f1, d f2, d f3 over (x1, v1, x2, v2).
    out[4..8].copy_from_slice(&[0.0, 1.0, 0.0, 0.0]);
    out[8] = (-k1 - 3.0 * k3 * x1 * x1 - k2) / m1;
    out[9] = (-c1 - c2) / m1;
    out[10] = k2 / m1;
    out[11] = c2 / m1;
    out[12..16].copy_from_slice(&[0.0, 0.0, 0.0, 1.0]);
    let s = (k2 + 3.0 * k3 * d * d) / m2;
    out[16] = s;
    out[17] = c2 / m2;
    out[18] = -s;
    out[19] = -c2 / m2;
}

/// Best of `rounds` rounds of `iters` calls, in nanoseconds per call. `call(i)` gets the call
/// number so that inputs can change from call to call.
pub fn best_ns(rounds: usize, iters: usize, mut call: impl FnMut(usize)) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..rounds {
        let start = std::time::Instant::now();
        for i in 0..iters {
            call(i);
        }
        best = best.min(start.elapsed().as_nanos() as f64 / iters as f64);
    }
    best
}
