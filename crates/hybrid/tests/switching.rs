//! Systems whose switch times are known in closed form: a piecewise-linear sawtooth with
//! state-dependent guards, and a clock with a time-dependent guard `sin t - 0.5`.

mod problems;

use std::f64::consts::PI;

use htfid_hybrid::{simulate, EventKind, Options};
use problems::{Clock, Half, Saw, Sawtooth, METHODS};

/// An event is located to `event_tol = 1e-12` s on an exact solution (both fields are
/// polynomials of degree <= 1, which both pairs reproduce to rounding); the reported time is the
/// post-crossing end of the final bracket, so it lies in `[t*, t* + 1e-12]`. Another 1e-12
/// covers rounding in `t` over 30 s.
const SWITCH_TOL: f64 = 2e-12;

/// Sawtooth from `x(0) = 0` in `Up`: `x' = 1` until `x = 1`, then `x' = -2` until `x = 0`:
/// switches at `1.5 k + 1` (Up -> Down) and `1.5 (k + 1)` (Down -> Up).
fn sawtooth_exact(t: f64) -> (f64, Saw) {
    let phase = t.rem_euclid(1.5);
    if phase < 1.0 {
        (phase, Saw::Up)
    } else {
        (1.0 - 2.0 * (phase - 1.0), Saw::Down)
    }
}

#[test]
fn sawtooth_switch_times_and_states() {
    // Not a multiple of 1.5: a switch exactly at t_end would be a coin toss of rounding.
    let t_end = 29.9;
    // Grid points offset from the switch instants, so the chart there is unambiguous.
    let grid: Vec<f64> = (0..2990).map(|i| 0.0037 + 0.01 * i as f64).collect();
    for method in METHODS {
        let opts = Options {
            method,
            ..Options::default()
        };
        let tr = simulate(&Sawtooth, Saw::Up, 0.0, &[0.0], t_end, &grid, &opts).unwrap();
        // Every grid state lies on its chart's side of the guards (grid times are 0.3 ms or
        // more from the switches, so no tolerance is needed beyond rounding).
        tr.check_charts(&Sawtooth, 1e-12).unwrap();
        // 20 switches at 1.5 k + 1 and 19 at 1.5 (k + 1) before 29.9 s.
        assert_eq!(tr.events.len(), 39, "{method:?}");
        let mut prev_time = 0.0;
        let mut prev_x = 0.0;
        for (k, ev) in tr.events.iter().enumerate() {
            // Each switch is located relative to where the previous one left the state: the
            // lateness of one location (<= event_tol) moves the start of the next leg.
            let (gap, from, to, x) = if k % 2 == 0 {
                (1.0 - prev_x, Saw::Up, Saw::Down, 1.0)
            } else {
                (prev_x / 2.0, Saw::Down, Saw::Up, 0.0)
            };
            let exact = prev_time + gap;
            assert_eq!(ev.kind, EventKind::Transition);
            assert_eq!((ev.from, ev.to), (from, to), "{method:?} event {k}");
            assert!(
                ev.time >= exact - 1e-13 && ev.time <= exact + SWITCH_TOL,
                "{method:?} event {k}: {} vs {exact}",
                ev.time
            );
            // The state is interpolated to the event time, not left at the step end: it sits
            // on the switching surface within slope (<= 2) times the lateness.
            assert!(
                (ev.state[0] - x).abs() <= 2.0 * SWITCH_TOL,
                "{method:?}: {:?}",
                ev.state
            );
            // Against the closed form from t = 0 the latenesses add up: per 1.5 s period at
            // most 4.5 event_tol (the Up overshoot delays the Down leg by half of itself, the
            // Down overshoot the Up leg by twice itself).
            let closed_form = 1.5 * (k / 2) as f64 + if k % 2 == 0 { 1.0 } else { 1.5 };
            let drift = 4.5 * SWITCH_TOL * (k / 2 + 1) as f64;
            assert!(
                (ev.time - closed_form).abs() <= drift,
                "{method:?} event {k}: {} vs closed form {closed_form}",
                ev.time
            );
            prev_time = ev.time;
            prev_x = ev.state[0];
        }
        for (i, &t) in grid.iter().enumerate() {
            let (x, mode) = sawtooth_exact(t);
            assert_eq!(tr.modes[i], mode, "{method:?} at t = {t}");
            // The state error is the accumulated drift times the slope (<= 2).
            assert!(
                (tr.state(i)[0] - x).abs() <= 2.0 * 4.5 * SWITCH_TOL * 21.0,
                "{method:?} at t = {t}: {} vs {x}",
                tr.state(i)[0]
            );
        }
        assert_eq!(tr.final_mode, sawtooth_exact(t_end).1);
    }
}

#[test]
fn time_dependent_guard_switches_at_arcsine_points() {
    let t_end = 30.0;
    let grid: Vec<f64> = (0..=300).map(|i| 0.1 * i as f64).collect();
    for method in METHODS {
        let opts = Options {
            method,
            ..Options::default()
        };
        let tr = simulate(&Clock, Half::Low, 0.0, &[0.0], t_end, &grid, &opts).unwrap();
        // sin t = 1/2 at pi/6 + 2 pi k (rising) and 5 pi/6 + 2 pi k (falling).
        let mut exact = Vec::new();
        for k in 0..5 {
            let base = 2.0 * PI * k as f64;
            exact.push((base + PI / 6.0, Half::Low, Half::High));
            exact.push((base + 5.0 * PI / 6.0, Half::High, Half::Low));
        }
        exact.retain(|&(t, _, _)| t < t_end);
        assert_eq!(tr.events.len(), exact.len(), "{method:?}");
        for (ev, &(t, from, to)) in tr.events.iter().zip(&exact) {
            assert_eq!((ev.from, ev.to), (from, to));
            // The guard depends on t only, so the only error is the location tolerance.
            assert!(
                ev.time >= t - 1e-13 && ev.time <= t + SWITCH_TOL,
                "{method:?}: {} vs {t}",
                ev.time
            );
        }
        for (i, &t) in grid.iter().enumerate() {
            let expected = if t.sin() > 0.5 { Half::High } else { Half::Low };
            assert_eq!(tr.modes[i], expected, "{method:?} at t = {t}");
            // x' = 1 in both charts and the resets are the identity: x = t throughout.
            approx::assert_abs_diff_eq!(tr.state(i)[0], t, epsilon = 1e-12);
        }
    }
}

/// Charts of [`SwitchedDamper`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Damper {
    Off,
    On,
}

/// `x'' + s c x' + k x = 0` with the damper on (`s = 1`) while the mass moves up (`x' > 0`):
/// the hopper's switching structure, guard `x'` in both charts.
#[derive(Debug)]
struct SwitchedDamper {
    c: f64,
    k: f64,
}

impl htfid_hybrid::HybridSystem for SwitchedDamper {
    type Mode = Damper;
    fn dim(&self) -> usize {
        2
    }
    fn vector_field(&self, mode: Damper, _t: f64, x: &[f64], dxdt: &mut [f64]) {
        let s = if mode == Damper::On { 1.0 } else { 0.0 };
        dxdt[0] = x[1];
        dxdt[1] = -s * self.c * x[1] - self.k * x[0];
    }
    fn num_guards(&self, _: Damper) -> usize {
        1
    }
    fn guard(&self, _: Damper, _: usize, _t: f64, x: &[f64]) -> f64 {
        x[1]
    }
    fn guard_direction(&self, mode: Damper, _: usize) -> htfid_hybrid::Crossing {
        match mode {
            Damper::Off => htfid_hybrid::Crossing::Rising,
            Damper::On => htfid_hybrid::Crossing::Falling,
        }
    }
    fn transition(&self, mode: Damper, _: usize, _t: f64, _x: &mut [f64]) -> Damper {
        match mode {
            Damper::Off => Damper::On,
            Damper::On => Damper::Off,
        }
    }
}

#[test]
fn switched_damper_half_periods_and_decay() {
    // From the top (x = 1, x' = 0) the mass falls undamped for half a period pi / w0 to the
    // bottom x = -1; rising with damping ratio zeta it turns after pi / wd at the top
    // x = exp(-zeta w0 pi / wd) times the amplitude; and so on. The run starts on the guard
    // (x' = 0 exactly), which must not fire at t = 0.
    let (c, k) = (0.4, 4.0);
    let w0 = f64::sqrt(k);
    let zeta = c / (2.0 * w0);
    let wd = w0 * (1.0 - zeta * zeta).sqrt();
    let decay = (-zeta * w0 * std::f64::consts::PI / wd).exp();
    let sys = SwitchedDamper { c, k };
    for method in METHODS {
        let opts = Options {
            method,
            ..Options::default()
        };
        let tr = simulate(&sys, Damper::Off, 0.0, &[1.0, 0.0], 30.0, &[], &opts).unwrap();
        let (mut t, mut amp) = (0.0, 1.0);
        assert!(
            tr.events.len() >= 18,
            "{method:?}: {} events",
            tr.events.len()
        );
        for (i, ev) in tr.events.iter().enumerate() {
            let (from, to) = if i % 2 == 0 {
                t += std::f64::consts::PI / w0;
                (Damper::Off, Damper::On)
            } else {
                t += std::f64::consts::PI / wd;
                amp *= decay;
                (Damper::On, Damper::Off)
            };
            assert_eq!((ev.from, ev.to), (from, to), "{method:?} event {i}");
            // At a turning point the guard x' moves at |x''| = k |x| = 4 amp, so a state error
            // of ~rtol (1e-10) per half-period becomes a time error of a few 1e-11 per event;
            // 1e-9 covers 20 events.
            assert!(
                (ev.time - t).abs() <= 1e-9,
                "{method:?} event {i}: {} vs {t}",
                ev.time
            );
            let x = if i % 2 == 0 { -amp } else { amp };
            assert!(
                (ev.state[0] - x).abs() <= 1e-9,
                "{method:?} event {i}: {:?} vs {x}",
                ev.state
            );
        }
    }
}
