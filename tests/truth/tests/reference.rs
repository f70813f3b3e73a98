//! The generator against answers worked out by hand: closed-form linear responses, switch
//! times of the piecewise-linear hopper, the length of a Coulomb stick, step-size convergence
//! and determinism.

use std::f64::consts::PI;

use htfid_truth::{
    generate, generate_with, simulate_scenario, Damper, Effect, Excitation, Friction, Lash, Noise,
    Plant, Scenario, SimOptions, State, Stop, NX, V, X,
};

/// Solution of `m x'' + c x' + k x = f0 + a cos(w t)` through `(xa, va)` at `ta`
/// (underdamped or undamped), returned as a closure giving `(x, v)` at `t`.
fn linear(
    m: f64,
    c: f64,
    k: f64,
    f0: f64,
    a: f64,
    w: f64,
    ta: f64,
    xa: f64,
    va: f64,
) -> impl Fn(f64) -> (f64, f64) {
    // Particular solution x_p = f0/k + re(z e^{i w t}), z = a / (k - m w^2 + i c w).
    let (dr, di) = (k - m * w * w, c * w);
    let den = dr * dr + di * di;
    let (zr, zi) = (a * dr / den, -a * di / den);
    let xp = move |t: f64| f0 / k + zr * (w * t).cos() - zi * (w * t).sin();
    let vp = move |t: f64| -w * zr * (w * t).sin() - w * zi * (w * t).cos();
    let alpha = c / (2.0 * m);
    let wd = (k / m - alpha * alpha).sqrt();
    let c1 = xa - xp(ta);
    let c2 = (va - vp(ta) + alpha * c1) / wd;
    move |t: f64| {
        let tau = t - ta;
        let e = (-alpha * tau).exp();
        let (s, co) = (wd * tau).sin_cos();
        let xh = e * (c1 * co + c2 * s);
        let vh = e * (-alpha * (c1 * co + c2 * s) + wd * (-c1 * s + c2 * co));
        (xp(t) + xh, vp(t) + vh)
    }
}

/// First zero of `g` after `t0` (scanning in 1 ms steps, then bisecting to the last bit).
fn first_zero(g: impl Fn(f64) -> f64, t0: f64) -> f64 {
    let mut a = t0 + 1e-6;
    let ga = g(a);
    let mut b = a;
    loop {
        b += 1e-3;
        if (g(b) > 0.0) != (ga > 0.0) {
            break;
        }
        a = b;
    }
    let sa = g(a) > 0.0;
    for _ in 0..200 {
        let mid = 0.5 * (a + b);
        if mid <= a || mid >= b {
            break;
        }
        if (g(mid) > 0.0) == sa {
            a = mid;
        } else {
            b = mid;
        }
    }
    0.5 * (a + b)
}

fn forcing_only(effects: Vec<Effect>) -> Scenario {
    Scenario {
        effects,
        excitation: Excitation::ForcingOnly,
        settle_s: 0.0,
        record_s: 20.0,
        ..Scenario::default()
    }
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).abs())
        .fold(0.0, f64::max)
}

/// With the damper never switching the hopper is a linear oscillator (damped or undamped).
#[test]
fn no_switch_matches_closed_form_linear_response() {
    for (v_th, c) in [(-1000.0, 2.0), (1000.0, 0.0)] {
        let s = forcing_only(vec![Effect::SwitchThreshold { v_th }]);
        let rec = generate(&s).unwrap();
        let p = Plant::new(&s).unwrap();
        let exact = linear(
            p.m,
            c,
            p.k,
            p.k * p.x0 - p.m * p.g,
            1.0,
            2.0 * PI,
            0.0,
            p.x_eq(),
            0.0,
        );
        let x_exact: Vec<f64> = rec.t.iter().map(|&t| exact(t).0).collect();
        let err = max_abs_diff(&rec.x, &x_exact);
        eprintln!("no switch, v_th = {v_th}: max |x - closed form| = {err:e} m");
        assert!(err < 1e-11, "v_th = {v_th}: max error {err:e} m");
    }
}

/// Switch times of the nominal hopper under the forcing alone, phase by phase in closed form.
#[test]
fn damper_switch_times_match_piecewise_closed_form() {
    let s = forcing_only(vec![]);
    let p = Plant::new(&s).unwrap();
    let traj = p
        .simulate(0.0, p.rest_state(0.0), &[3.0], &SimOptions::default())
        .unwrap();
    let switches: Vec<_> = traj
        .events
        .iter()
        .filter(|e| e.from.damper != e.to.damper)
        .collect();
    assert!(switches.len() >= 8, "{} switches", switches.len());

    // At t = 0 the forcing is at its maximum, so v becomes positive: damper on first.
    let (mut t, mut x, mut v, mut on) = (0.0, p.x_eq(), 0.0, true);
    for (i, event) in switches.iter().take(8).enumerate() {
        let t_sim = event.t;
        let c = if on { p.c } else { 0.0 };
        let phase = linear(p.m, c, p.k, p.k * p.x0 - p.m * p.g, 1.0, 2.0 * PI, t, x, v);
        let t_next = first_zero(|tt| phase(tt).1, t);
        eprintln!(
            "switch {i}: t = {t_sim}, closed form - simulated = {:e} s",
            t_next - t_sim
        );
        assert!(
            (t_next - t_sim).abs() < 1e-10,
            "switch {i}: closed form {t_next}, simulated {t_sim}, diff {:e}",
            t_next - t_sim
        );
        let expected_to = if on { Damper::Off } else { Damper::On };
        assert_eq!(event.to.damper, expected_to);
        (x, v) = phase(t_next);
        t = t_next;
        on = !on;
    }
}

/// Start stuck where the spring balances gravity plus the forcing's maximum: the other forces
/// are `A (cos(2 pi t) - 1)`, which leave the band `|F| <= mu` at `cos(2 pi t) = 1 - mu / A`.
/// With `mu = A / 2` that is `t = 1/6 s`; meanwhile x must not move at all.
#[test]
fn coulomb_stick_from_rest_lasts_one_sixth_period() {
    let s = forcing_only(vec![Effect::CoulombFriction { mu: 0.5 }]);
    let p = Plant::new(&s).unwrap();
    let mut y0: State = [0.0; NX];
    y0[X] = p.x_eq() + 1.0 / p.k;
    let traj = p
        .simulate(0.0, y0, &[0.05, 0.1, 0.16, 0.2], &SimOptions::default())
        .unwrap();
    let first = traj.events[0];
    assert_eq!(first.from.friction, Friction::Stick);
    assert_eq!(first.to.friction, Friction::Neg);
    eprintln!("stick from rest: end - 1/6 = {:e} s", first.t - 1.0 / 6.0);
    assert!(
        (first.t - 1.0 / 6.0).abs() < 1e-10,
        "{:e}",
        first.t - 1.0 / 6.0
    );
    for y in &traj.states[..3] {
        assert!((y[X] - y0[X]).abs() < 1e-15 && y[V].abs() < 1e-15);
    }
    assert!(traj.states[3][V] < 0.0);
}

/// With strong friction the hopper sticks repeatedly. While stuck at `x_s` the other forces
/// are `-m g - k (x_s - x0) + A cos(2 pi t)`, so each stick ends where that reaches `+mu`
/// or `-mu`; every simulated stick is checked against this hand analysis.
#[test]
fn coulomb_sticks_end_where_hand_analysis_says() {
    let mu = 0.6;
    let s = forcing_only(vec![Effect::CoulombFriction { mu }]);
    let p = Plant::new(&s).unwrap();
    let traj = p
        .simulate(0.0, p.rest_state(0.0), &[10.0], &SimOptions::default())
        .unwrap();
    let ev = &traj.events;
    let mut checked = 0;
    for (i, e) in ev.iter().enumerate() {
        if e.to.friction != Friction::Stick {
            continue;
        }
        let Some(end) = ev[i + 1..]
            .iter()
            .find(|e2| e2.from.friction == Friction::Stick)
        else {
            continue;
        };
        // Position while stuck: re-simulate to the middle of the stick.
        let mid = 0.5 * (e.t + end.t);
        let y = p
            .simulate(0.0, p.rest_state(0.0), &[mid], &SimOptions::default())
            .unwrap()
            .states[0];
        let other = |t: f64| -p.m * p.g - p.k * (y[X] - p.x0) + (2.0 * PI * t).cos();
        assert!(other(mid).abs() < mu);
        let expected_end = first_zero(|t| mu - other(t).abs(), e.t);
        eprintln!(
            "stick {:.6}..{:.6} s: end - hand analysis = {:e} s",
            e.t,
            end.t,
            end.t - expected_end
        );
        assert!(
            (expected_end - end.t).abs() < 1e-10,
            "stick from {} ended at {}, hand analysis {}",
            e.t,
            end.t,
            expected_end
        );
        let expected_dir = if other(end.t) > 0.0 {
            Friction::Pos
        } else {
            Friction::Neg
        };
        assert_eq!(end.to.friction, expected_dir);
        checked += 1;
    }
    assert!(checked >= 5, "only {checked} sticks");
}

/// Halving the tolerance and the step cap changes no record by more than 1e-10 m, for the
/// paper protocol and for a record with every kind of event (stick, contact, backlash).
#[test]
fn halving_tolerance_changes_records_by_less_than_1e_10() {
    let heavy = Scenario {
        effects: vec![
            Effect::CoulombFriction { mu: 0.2 },
            Effect::HardStop {
                k_stop: 5000.0,
                x_stop: 0.1465,
            },
            Effect::Backlash { gap: 0.1 },
            Effect::ActuatorLag { tau: 0.01 },
            Effect::SwitchThreshold { v_th: 0.01 },
            Effect::FlightDamping { c_f: 0.5 },
        ],
        record_s: 60.0,
        ..Scenario::default()
    };
    let (_, traj) = simulate_scenario(&heavy, &SimOptions::default()).unwrap();
    let ev = &traj.events;
    assert!(ev.iter().any(|e| e.to.friction == Friction::Stick));
    assert!(ev.iter().any(|e| e.to.stop == Stop::Contact));
    assert!(ev.iter().any(|e| e.to.lash == Lash::Up));
    assert!(ev.iter().any(|e| e.to.lash == Lash::Down));
    for s in [Scenario::default(), heavy] {
        let a = generate_with(&s, &SimOptions::default()).unwrap();
        // The 2 ms step cap binds for the nominal hopper, so halve it too: otherwise the
        // steps would not change at all.
        let d0 = SimOptions::default();
        let opts = SimOptions {
            tol: d0.tol / 2.0,
            h_max: d0.h_max / 2.0,
        };
        let b = generate_with(&s, &opts).unwrap();
        let d = max_abs_diff(&a.x, &b.x);
        eprintln!(
            "{} effects: tol and h_max halved: max |dx| = {d:e} m",
            s.effects.len()
        );
        assert!(d < 1e-10, "{:?}: {d:e}", s.effects);
    }
}

#[test]
fn same_seed_same_record_other_seed_other_noise() {
    let s = Scenario {
        effects: vec![Effect::CubicStiffness { k3: 2000.0 }],
        noise: Noise {
            sigma_x: 2e-5,
            sigma_f: 1e-4,
        },
        seed: 42,
        record_s: 30.0,
        ..Scenario::default()
    };
    let a = generate(&s).unwrap();
    let b = generate(&s).unwrap();
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a.x), bits(&b.x));
    assert_eq!(bits(&a.f), bits(&b.f));
    let c = generate(&Scenario {
        seed: 43,
        ..s.clone()
    })
    .unwrap();
    assert!(max_abs_diff(&a.x, &c.x) > 1e-5);
    // Noise-free parts agree: the difference is noise of the right size.
    let diff: Vec<f64> = a.x.iter().zip(&c.x).map(|(p, q)| p - q).collect();
    let rms = (diff.iter().map(|d| d * d).sum::<f64>() / diff.len() as f64).sqrt();
    assert!((rms / (2e-5 * 2f64.sqrt()) - 1.0).abs() < 0.05, "{rms}");
}

/// With `v_th > 0` the damping force jumps by `c v_th` at `v = v_th`, and where the other
/// forces lie inside that jump the flow slides along `v = v_th` (Filippov): `x' = v_th`,
/// `v' = 0`. Started on the surface in the middle of the band, the slide ends when the other
/// forces `F_o(t) = -m g - k (x_s + v_th t - x0) + cos(2 pi t)` reach 0 (then it leaves
/// downward, damper off).
#[test]
fn filippov_slide_on_damper_surface_matches_hand_analysis() {
    let v_th = 0.05;
    let s = forcing_only(vec![Effect::SwitchThreshold { v_th }]);
    let p = Plant::new(&s).unwrap();
    let band = p.c * v_th;
    let mut y0: State = [0.0; NX];
    // -m g - k (x_s - x0) + 1 = band / 2.
    y0[X] = p.x0 + (1.0 - p.m * p.g - band / 2.0) / p.k;
    y0[V] = v_th;
    let traj = p
        .simulate(0.0, y0, &[0.002, 0.05], &SimOptions::default())
        .unwrap();
    let first = traj.events[0];
    assert_eq!(first.from.damper, Damper::Slide);
    assert_eq!(first.to.damper, Damper::Off);
    let f_o = |t: f64| -p.m * p.g - p.k * (y0[X] + v_th * t - p.x0) + (2.0 * PI * t).cos();
    let expected = first_zero(f_o, 0.0);
    eprintln!("slide end - hand analysis = {:e} s", first.t - expected);
    assert!(
        (first.t - expected).abs() < 1e-10,
        "slide ended at {}, hand analysis {expected}",
        first.t
    );
    let y = traj.states[0];
    assert!((y[X] - (y0[X] + v_th * 0.002)).abs() < 1e-13);
    assert!((y[V] - v_th).abs() < 1e-15);
}
