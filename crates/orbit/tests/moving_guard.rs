//! Saltation through a guard and a reset that move in time: a ball hitting a vibrating table.
//! Truth: central finite differences of the hybrid flow map, which know nothing of saltation.

use htfid_hybrid::{simulate, Crossing, HybridSystem, Options};
use htfid_orbit::{guard_gradient, saltation, Variational};

/// A ball `[y, v]` above a table at height `A sin(w t)`; impacts reverse the velocity relative
/// to the table with restitution `e`.
struct Table {
    amplitude: f64,
    omega: f64,
    restitution: f64,
    exact_dhdt: bool,
}

impl Table {
    fn table_velocity(&self, t: f64) -> f64 {
        self.amplitude * self.omega * (self.omega * t).cos()
    }
}

impl HybridSystem for Table {
    type Mode = ();
    fn dim(&self) -> usize {
        2
    }
    fn vector_field(&self, _: (), _t: f64, x: &[f64], dx: &mut [f64]) {
        dx[0] = x[1];
        dx[1] = -9.81;
    }
    fn num_guards(&self, _: ()) -> usize {
        1
    }
    fn guard(&self, _: (), _: usize, t: f64, x: &[f64]) -> f64 {
        x[0] - self.amplitude * (self.omega * t).sin()
    }
    fn guard_time_derivative(&self, _: (), _: usize, t: f64, _x: &[f64]) -> Option<f64> {
        self.exact_dhdt.then(|| -self.table_velocity(t))
    }
    fn guard_direction(&self, _: (), _: usize) -> Crossing {
        Crossing::Falling
    }
    fn transition(&self, _: (), _: usize, t: f64, x: &mut [f64]) {
        let s = self.table_velocity(t);
        x[1] = s - self.restitution * (x[1] - s);
    }
}

fn table(exact_dhdt: bool) -> Table {
    Table {
        amplitude: 0.01,
        omega: 31.4,
        restitution: 0.8,
        exact_dhdt,
    }
}

fn tight() -> Options {
    Options {
        rtol: 1e-13,
        atol: 1e-15,
        ..Options::default()
    }
}

#[test]
fn guard_time_derivative_is_used_when_supplied() {
    let (t, x): (f64, _) = (0.123, [0.02, -1.0]);
    let want = -0.01 * 31.4 * (31.4 * t).cos();
    let (grad, dhdt) = guard_gradient(&table(true), (), 0, t, &x);
    assert!(
        (dhdt - want).abs() <= 1e-16 * want.abs(),
        "{dhdt} vs {want}"
    );
    assert!((grad[0] - 1.0).abs() < 1e-9 && grad[1].abs() < 1e-12);
    // The finite-difference fallback (step h = 6e-6 in t) is off by (w h)^2 / 6 = 6e-9
    // relative at w = 31.4 rad/s, and measurably so: the supplied derivative is what is used.
    let (_, fd) = guard_gradient(&table(false), (), 0, t, &x);
    let rel = (fd - want).abs() / want.abs();
    assert!(rel < 1e-8 && rel > 1e-10, "{fd} vs {want}: {rel:e}");
}

#[test]
fn saltation_of_a_moving_guard_and_reset_matches_the_flow() {
    let (t_end, x0) = (0.2, [0.1, 0.0]);
    for exact in [true, false] {
        let sys = table(exact);
        let var = Variational::new(&sys);
        let traj = simulate(&var, (), 0.0, &var.initial_state(&x0), t_end, &[], &tight()).unwrap();
        assert_eq!(traj.transitions().count(), 1);
        let phi = &traj.final_state[2..];
        // Central differences of the flow map; h = 1e-5 balances the integrator's ~1e-13 error
        // (1e-8 after dividing by h) against the h^2 truncation (the flow is smooth in x0 while
        // the impact stays transversal).
        let h = 1e-5;
        let flow = |x: &[f64]| {
            simulate(&sys, (), 0.0, x, t_end, &[], &tight())
                .unwrap()
                .final_state
        };
        let mut worst: f64 = 0.0;
        let event = &traj.events[0];
        let (s, ()) = saltation(&sys, (), 0, event.time, &event.state[..2]);
        for j in 0..2 {
            let (mut xp, mut xm) = (x0.to_vec(), x0.to_vec());
            xp[j] += h;
            xm[j] -= h;
            let (fp, fm) = (flow(&xp), flow(&xm));
            for i in 0..2 {
                let fd = (fp[i] - fm[i]) / (2.0 * h);
                worst = worst.max((phi[i * 2 + j] - fd).abs());
            }
        }
        assert!(
            worst < 1e-6,
            "exact dh/dt {exact}: Phi vs finite differences {worst}"
        );
        // By hand: the reset's time derivative (the table's acceleration a) adds
        // -(0, (1 + e) a) grad(h)^T / (grad(h) . f- + dh/dt) to the saltation matrix.
        let (te, v_minus) = (event.time, event.state[1]);
        let (w, amp, e) = (31.4_f64, 0.01, 0.8);
        let table_v = amp * w * (w * te).cos();
        let table_a = -amp * w * w * (w * te).sin();
        let v_plus = (1.0 + e) * table_v - e * v_minus;
        let denom = v_minus - table_v;
        let naive = (-9.81 - (-e) * -9.81) / denom;
        let full = naive - (1.0 + e) * table_a / denom;
        assert!(
            (s[(0, 0)] - (1.0 + (v_plus - v_minus) / denom)).abs() < 1e-8,
            "{s}"
        );
        assert!(
            (s[(1, 0)] - full).abs() < 1e-6 * full.abs(),
            "{s} vs {full}"
        );
        assert!(
            (full - naive).abs() > 1.0,
            "the dR/dt term matters: {full} vs {naive}"
        );
    }
}
