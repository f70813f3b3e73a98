//! Sliding along a switching surface: a mass on a moving belt (stick-slip), against its
//! closed-form solution.
//!
//! `m x'' = -k x - F sign(x' - v)`: a mass on a spring (anchored at `x = 0`) rests on a belt
//! moving at speed `v`, with Coulomb friction of magnitude `F` (static = kinetic). The
//! switching surface is the relative velocity `w = x' - v = 0`. Charts: `Behind` (`w < 0`,
//! friction `+F`) and `Ahead` (`w > 0`, friction `-F`). On `w = 0` the fields point into the
//! surface from both sides while `|k x| < F`: the mass sticks to the belt, `x' = v`, and `x`
//! grows linearly until `k x = F`, where it slips back (the field of `Behind` leaves the
//! surface).
//!
//! With `w = sqrt(k / m)`, every phase is a harmonic oscillation about `+-F / k` or a straight
//! line, so each switching time and state is written below from these formulas (inverse sine
//! and cosine), independent of the integrator.
//!
//! Tolerances: event times are located to `event_tol = 1e-12` on the dense output, and the
//! state carries the integration error of `rtol = 1e-10` over a few oscillations; the crossing
//! and exit speeds are of order 1 (`|w'| = |k x -+ F| / m`, exit slope `k v / m = 0.8`), so a
//! state error of 1e-10 moves an event by about 1e-10. `1e-9` on times and states leaves a
//! factor of ten.

use approx::assert_abs_diff_eq;
use htfid_hybrid::{simulate, Crossing, EventKind, HybridSystem, Method, Options};

const M: f64 = 1.0;
const K: f64 = 4.0;
const F: f64 = 1.0;
const V: f64 = 0.2;
const TOL: f64 = 1e-9;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Belt {
    Behind,
    Ahead,
}

/// The belt system; `gradient` switches the exact guard gradient on, so that both ways of
/// computing the sliding field (exact, finite differences) are exercised.
struct Stick {
    gradient: bool,
    /// Amplitude (N) and angular frequency (rad/s) of an extra force `A sin(W t)`; zero in
    /// the closed-form tests.
    forcing: (f64, f64),
}

impl HybridSystem for Stick {
    type Mode = Belt;
    fn dim(&self) -> usize {
        2
    }
    fn vector_field(&self, mode: Belt, t: f64, x: &[f64], dx: &mut [f64]) {
        let friction = match mode {
            Belt::Behind => F,
            Belt::Ahead => -F,
        };
        dx[0] = x[1];
        let (amp, freq) = self.forcing;
        dx[1] = (-K * x[0] + friction + amp * (freq * t).sin()) / M;
    }
    fn num_guards(&self, _: Belt) -> usize {
        1
    }
    fn guard(&self, _: Belt, _: usize, _t: f64, x: &[f64]) -> f64 {
        x[1] - V
    }
    fn guard_direction(&self, mode: Belt, _: usize) -> Crossing {
        match mode {
            Belt::Behind => Crossing::Rising,
            Belt::Ahead => Crossing::Falling,
        }
    }
    fn transition(&self, mode: Belt, _: usize, _t: f64, _x: &mut [f64]) -> Belt {
        other(mode)
    }
    fn sliding_chart(&self, mode: Belt, _: usize) -> Option<Belt> {
        Some(other(mode))
    }
    fn guard_gradient(&self, _: Belt, _: usize, _t: f64, _x: &[f64], g: &mut [f64]) -> bool {
        if self.gradient {
            g[0] = 0.0;
            g[1] = 1.0;
        }
        self.gradient
    }
}

fn other(mode: Belt) -> Belt {
    match mode {
        Belt::Behind => Belt::Ahead,
        Belt::Ahead => Belt::Behind,
    }
}

fn omega() -> f64 {
    (K / M).sqrt()
}

fn systems() -> [(Stick, Method); 4] {
    [
        (
            Stick {
                gradient: true,
                forcing: (0.0, 0.0),
            },
            Method::Dop853,
        ),
        (
            Stick {
                gradient: true,
                forcing: (0.0, 0.0),
            },
            Method::Dopri5,
        ),
        (
            Stick {
                gradient: false,
                forcing: (0.0, 0.0),
            },
            Method::Dop853,
        ),
        (
            Stick {
                gradient: false,
                forcing: (0.0, 0.0),
            },
            Method::Dopri5,
        ),
    ]
}

/// The state on the slip phase after the stick ends at `t2` at `x = F / k`, `x' = v`:
/// `x = F/k + (v/w) sin(w (t - t2))` in chart `Behind`.
fn after_stick(t2: f64, t: f64) -> [f64; 2] {
    let w = omega();
    [
        F / K + V / w * (w * (t - t2)).sin(),
        V * (w * (t - t2)).cos(),
    ]
}

/// From rest in `Behind`: slip `x = F/k (1 - cos wt)` until `x' = v` at `t1` (state `x1`),
/// stuck `x = x1 + v (t - t1)` until `k x = F` at `t2`, then [`after_stick`].
struct FromRest {
    t1: f64,
    x1: f64,
    t2: f64,
}

impl FromRest {
    fn new() -> Self {
        let w = omega();
        let t1 = (V * K / (F * w)).asin() / w;
        let x1 = F / K * (1.0 - (w * t1).cos());
        FromRest {
            t1,
            x1,
            t2: t1 + (F / K - x1) / V,
        }
    }

    fn state(&self, t: f64) -> [f64; 2] {
        let w = omega();
        if t < self.t1 {
            [F / K * (1.0 - (w * t).cos()), F / K * w * (w * t).sin()]
        } else if t < self.t2 {
            [self.x1 + V * (t - self.t1), V]
        } else {
            after_stick(self.t2, t)
        }
    }
}

/// From `x = 0`, `x' = v + u0` in `Ahead`: slip `x = -F/k + (F/k) cos wt + ((v + u0)/w) sin wt`
/// until `x' = v` at `t1`, stuck until `k x = F` at `t2`, then [`after_stick`] in `Behind`.
struct FromAhead {
    /// `F w / k` and `v + u0`: the slip's velocity is `-a sin wt + b cos wt`.
    a: f64,
    b: f64,
    t1: f64,
    x1: f64,
    t2: f64,
}

impl FromAhead {
    fn new(u0: f64) -> Self {
        let w = omega();
        let (a, b) = (F * w / K, V + u0);
        let (r, phi) = (a.hypot(b), a.atan2(b));
        let t1 = ((V / r).acos() - phi) / w;
        let x1 = -F / K + F / K * (w * t1).cos() + b / w * (w * t1).sin();
        FromAhead {
            a,
            b,
            t1,
            x1,
            t2: t1 + (F / K - x1) / V,
        }
    }

    fn state(&self, t: f64) -> [f64; 2] {
        let w = omega();
        let (a, b) = (self.a, self.b);
        if t < self.t1 {
            [
                -F / K + F / K * (w * t).cos() + b / w * (w * t).sin(),
                -a * (w * t).sin() + b * (w * t).cos(),
            ]
        } else if t < self.t2 {
            [self.x1 + V * (t - self.t1), V]
        } else {
            after_stick(self.t2, t)
        }
    }
}

#[test]
fn mass_from_rest_sticks_to_the_belt_and_slips_back_at_the_friction_bound() {
    let w = omega();
    let exact = FromRest::new();
    let (t1, x1, t2) = (exact.t1, exact.x1, exact.t2);
    // Stop before the slip phase returns tangentially to w = 0 at t2 + 2 pi / w (where
    // k x = F exactly: a degenerate touch of the stick boundary).
    let t_end = t2 + 1.5 * std::f64::consts::PI / w;
    let grid: Vec<f64> = (0..=400).map(|i| t_end * i as f64 / 400.0).collect();
    for (sys, method) in systems() {
        let opts = Options {
            method,
            ..Options::default()
        };
        let traj = simulate(&sys, Belt::Behind, 0.0, &[0.0, 0.0], t_end, &grid, &opts).unwrap();
        let label = format!("{method:?}, gradient {}", sys.gradient);
        let kinds: Vec<EventKind> = traj.events.iter().map(|e| e.kind).collect();
        assert_eq!(
            kinds,
            [EventKind::SlideStart, EventKind::SlideEnd],
            "{label}"
        );
        let (start, end) = (&traj.events[0], &traj.events[1]);
        assert_abs_diff_eq!(start.time, t1, epsilon = TOL);
        assert_abs_diff_eq!(start.state[0], x1, epsilon = TOL);
        assert_abs_diff_eq!(start.state[1], V, epsilon = TOL);
        assert_eq!((start.from, start.to), (Belt::Behind, Belt::Behind));
        assert_abs_diff_eq!(end.time, t2, epsilon = TOL);
        assert_abs_diff_eq!(end.state[0], F / K, epsilon = TOL);
        assert_eq!((end.from, end.to), (Belt::Behind, Belt::Behind), "{label}");
        assert_eq!(traj.sliding.len(), 1);
        let stick = traj.sliding[0];
        assert_eq!(
            (stick.guard, stick.chart, stick.exit),
            (0, Belt::Behind, Some(Belt::Behind))
        );
        assert_abs_diff_eq!(stick.start, t1, epsilon = TOL);
        assert_abs_diff_eq!(stick.end, t2, epsilon = TOL);
        let mut worst = 0.0_f64;
        for (i, &t) in grid.iter().enumerate() {
            let exact = exact.state(t);
            let x = traj.state(i);
            worst = worst.max((x[0] - exact[0]).abs().max((x[1] - exact[1]).abs()));
        }
        eprintln!("{label}: worst state error {worst:e}");
        assert!(worst < TOL, "{label}: worst state error {worst:e}");
        traj.check_charts(&sys, 1e-9).unwrap();
    }
}

#[test]
fn mass_faster_than_the_belt_sticks_and_leaves_into_the_other_chart() {
    let u0 = 0.3;
    // The slip's x' = -(F w / k) sin wt + (v + u0) cos wt = R cos(wt + phi) reaches v first
    // at t1.
    let exact = FromAhead::new(u0);
    let (t1, x1, t2) = (exact.t1, exact.x1, exact.t2);
    assert!((K * x1).abs() < F, "the scenario must stick at t1");
    let t_end = t2 + 1.0;
    let grid: Vec<f64> = (0..=300).map(|i| t_end * i as f64 / 300.0).collect();
    for (sys, method) in systems() {
        let opts = Options {
            method,
            ..Options::default()
        };
        let traj = simulate(&sys, Belt::Ahead, 0.0, &[0.0, V + u0], t_end, &grid, &opts).unwrap();
        let label = format!("{method:?}, gradient {}", sys.gradient);
        assert_eq!(traj.events.len(), 2, "{label}: {:?}", traj.events);
        let (start, end) = (&traj.events[0], &traj.events[1]);
        assert_eq!(start.kind, EventKind::SlideStart);
        assert_abs_diff_eq!(start.time, t1, epsilon = TOL);
        assert_abs_diff_eq!(start.state[0], x1, epsilon = TOL);
        // Arrived from `Ahead`, leaves into the far side's chart `Behind` where its field
        // stops pushing into the surface (k x = F).
        assert_eq!(end.kind, EventKind::SlideEnd);
        assert_eq!((end.from, end.to), (Belt::Ahead, Belt::Behind), "{label}");
        assert_abs_diff_eq!(end.time, t2, epsilon = TOL);
        assert_eq!(traj.final_mode, Belt::Behind);
        let mut worst = 0.0_f64;
        for (i, &t) in grid.iter().enumerate() {
            let exact = exact.state(t);
            let x = traj.state(i);
            worst = worst.max((x[0] - exact[0]).abs().max((x[1] - exact[1]).abs()));
            // The chart while stuck is the arrival chart; the velocity is the belt's.
            if t > t1 && t < t2 {
                assert_eq!(traj.modes[i], Belt::Ahead);
                assert!(traj.sliding_at(t).is_some());
            }
        }
        eprintln!("{label}: worst state error {worst:e}");
        assert!(worst < TOL, "{label}: worst state error {worst:e}");
        traj.check_charts(&sys, 1e-9).unwrap();
    }
}

#[test]
fn a_start_on_the_surface_inside_the_stick_region_sticks_at_once() {
    // x(0) = 0, x'(0) = v: |k x| = 0 < F, so the mass rides the belt from t = 0 until
    // k x = F at t = F / (k v).
    let t2 = F / (K * V);
    let t_end = t2 + 0.5;
    let grid = [0.0, 0.5 * t2, t_end];
    for (sys, method) in systems() {
        let opts = Options {
            method,
            ..Options::default()
        };
        for mode0 in [Belt::Behind, Belt::Ahead] {
            let traj = simulate(&sys, mode0, 0.0, &[0.0, V], t_end, &grid, &opts).unwrap();
            assert_eq!(traj.sliding.len(), 1, "{method:?} {mode0:?}");
            assert_abs_diff_eq!(traj.sliding[0].start, 0.0);
            assert_abs_diff_eq!(traj.sliding[0].end, t2, epsilon = TOL);
            assert_abs_diff_eq!(traj.state(1)[0], 0.5 * t2 * V, epsilon = TOL);
            let exact = after_stick(t2, t_end);
            assert_abs_diff_eq!(traj.state(2)[0], exact[0], epsilon = TOL);
            assert_abs_diff_eq!(traj.state(2)[1], exact[1], epsilon = TOL);
        }
    }
}

#[test]
fn a_start_on_the_far_side_of_the_surface_takes_that_sides_chart() {
    // x' = v + 0.1 labelled `Behind` (whose side is w < 0): the state belongs to `Ahead`.
    let sys = Stick {
        gradient: true,
        forcing: (0.0, 0.0),
    };
    let traj = simulate(
        &sys,
        Belt::Behind,
        0.0,
        &[0.0, V + 0.1],
        0.01,
        &[0.0, 0.01],
        &Options::default(),
    )
    .unwrap();
    assert_eq!(traj.modes, [Belt::Ahead, Belt::Ahead]);
    // Ahead's field from x = 0, x' = u: x' = -(F w / k) sin wt + u cos wt.
    let (w, u) = (omega(), V + 0.1);
    let exact = -F * w / K * (w * 0.01).sin() + u * (w * 0.01).cos();
    assert_abs_diff_eq!(traj.state(1)[1], exact, epsilon = TOL);
}

#[test]
fn an_impact_guard_is_never_slid_along() {
    /// A ball whose impact guard keeps the default `sliding_chart` (`None`): it bounces as
    /// before.
    struct Ball;
    impl HybridSystem for Ball {
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
        fn guard(&self, _: (), _: usize, _t: f64, x: &[f64]) -> f64 {
            x[0]
        }
        fn guard_direction(&self, _: (), _: usize) -> Crossing {
            Crossing::Falling
        }
        fn transition(&self, _: (), _: usize, _t: f64, x: &mut [f64]) {
            x[1] *= -0.9;
        }
    }
    // Impacts at 0.4515 s and 0.4515 + 2 (0.9 * 4.429) / 9.81 = 1.264 s.
    let traj = simulate(&Ball, (), 0.0, &[1.0, 0.0], 1.5, &[], &Options::default()).unwrap();
    assert!(traj.sliding.is_empty());
    assert_eq!(traj.transitions().count(), 2);
}

#[test]
fn sticking_and_slipping_faster_than_the_zeno_cap_is_an_error_with_the_numbers() {
    // A force 1.5 sin(1e6 t) N on a mass stuck to the belt (F = 1 N): it breaks loose and
    // sticks again within forcing periods of 6.3 us, so slide starts, ends and transitions
    // come at more than 100 per millisecond, the default cap per `zeno_window = 1 ms`: the
    // motion is not resolved, and the error says so.
    let sys = Stick {
        gradient: true,
        forcing: (1.5, 1e6),
    };
    let err = simulate(
        &sys,
        Belt::Behind,
        0.0,
        &[0.0, V],
        0.01,
        &[],
        &Options::default(),
    )
    .unwrap_err();
    match err {
        htfid_hybrid::HybridError::Zeno {
            time,
            guard,
            events,
            window,
        } => {
            assert_eq!(guard, 0);
            assert_eq!(events, 101);
            assert_abs_diff_eq!(window, 1e-3);
            // The cap is exceeded within the first window.
            assert!(time > 0.0 && time < 1e-3, "stopped at {time}");
        }
        other => panic!("expected Zeno, got {other}"),
    }
}

#[test]
fn the_fixed_step_method_sticks_and_slips_with_the_closed_form() {
    // The scenario of `mass_from_rest_sticks_to_the_belt_and_slips_back_at_the_friction_bound`,
    // on the fixed-step method: RK4 with h = 2.5 ms. Its local error on the oscillation is about
    // (w h)^5 / 120 = 1.3e-12 of the amplitude per step, the stick phase (x' = v) is integrated
    // exactly, and the entry and exit are located on the Hermite interpolant, whose error of
    // order h^4 |x^(4)| = 6e-11 moves an event by about that over speeds of order 1: 1e-9
    // leaves a margin of more than ten.
    let exact = FromRest::new();
    let t_end = exact.t2 + 1.5 * std::f64::consts::PI / omega();
    let dt = 0.01;
    let samples = (t_end / dt) as usize;
    for gradient in [true, false] {
        let sys = Stick {
            gradient,
            forcing: (0.0, 0.0),
        };
        let (pos, vel) = fixed_step(&sys, Belt::Behind, [0.0, 0.0], dt, samples);
        let mut worst = 0.0_f64;
        let mut stuck = 0;
        for i in 0..samples {
            let t = i as f64 * dt;
            if t >= exact.t1 && t < exact.t2 {
                stuck += 1;
            }
            let exact = exact.state(t);
            worst = worst.max((pos[i] - exact[0]).abs().max((vel[i] - exact[1]).abs()));
        }
        eprintln!("fixed step, gradient {gradient}: worst state error {worst:e}");
        assert!(stuck > 10, "the scenario must stick for some samples");
        assert!(
            worst < TOL,
            "gradient {gradient}: worst state error {worst:e}"
        );
    }
}

#[test]
fn the_fixed_step_method_leaves_into_the_far_chart_as_the_closed_form() {
    // The scenario of `mass_faster_than_the_belt_sticks_and_leaves_into_the_other_chart`:
    // arrives from `Ahead`, sticks, leaves into `Behind`. Tolerance as above.
    let u0 = 0.3;
    let exact = FromAhead::new(u0);
    let dt = 0.01;
    let samples = ((exact.t2 + 1.0) / dt) as usize;
    let sys = Stick {
        gradient: true,
        forcing: (0.0, 0.0),
    };
    let (pos, vel) = fixed_step(&sys, Belt::Ahead, [0.0, V + u0], dt, samples);
    let mut worst = 0.0_f64;
    for i in 0..samples {
        let exact = exact.state(i as f64 * dt);
        worst = worst.max((pos[i] - exact[0]).abs().max((vel[i] - exact[1]).abs()));
    }
    eprintln!("fixed step, leaving into the far chart: worst state error {worst:e}");
    assert!(worst < TOL, "worst state error {worst:e}");
}

/// Position and velocity of the fixed-step method (4 sub-steps per sample) from `x0`.
fn fixed_step(
    sys: &Stick,
    mode: Belt,
    x0: [f64; 2],
    dt: f64,
    samples: usize,
) -> (Vec<f64>, Vec<f64>) {
    let mut pos = vec![0.0; samples];
    let mut vel = vec![0.0; samples];
    htfid_hybrid::simulate_fixed_step(sys, mode, 0.0, &x0, dt, 4, 0, &mut pos).unwrap();
    htfid_hybrid::simulate_fixed_step(sys, mode, 0.0, &x0, dt, 4, 1, &mut vel).unwrap();
    (pos, vel)
}
