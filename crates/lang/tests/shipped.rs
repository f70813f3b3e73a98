//! Every shipped model compiles and has a stable forced orbit.

use std::path::Path;

use htfid_hybrid::Options;
use htfid_lang::Model;
use htfid_orbit::ShootingOptions;

fn load(name: &str) -> Model {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../models/{name}.toml"));
    Model::from_file(&path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn every_shipped_model_has_a_stable_orbit() {
    for name in [
        "hopper",
        "bouncing-ball",
        "flight-hopper",
        "two-dof",
        "closed-loop-friction",
    ] {
        let model = load(name);
        let shooting = ShootingOptions {
            settle_periods: 200,
            ..ShootingOptions::default()
        };
        let cycle = model
            .limit_cycle(&shooting, &Options::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let radius = cycle
            .multipliers
            .iter()
            .map(|z| z.norm())
            .fold(0.0, f64::max);
        assert!(radius < 1.0);
    }
}

/// The period-1 orbit of a ball on a table `A sin(w t)` is known in closed form: the flight
/// lasts one period, so the ball leaves with `v+ = g T / 2` and meets the table again at the
/// same phase, where `cos(w t_i) = g T (1 - e) / (2 (1 + e) A w)`. The stable orbit is the
/// one with the table decelerating (`sin(w t_i) > 0`).
#[test]
fn bouncing_ball_orbit_matches_closed_form() {
    let model = load("bouncing-ball");
    let (g, e, a, period) = (9.81, 0.8, 0.01, 0.25);
    let w = 2.0 * std::f64::consts::PI / period;
    let cycle = model
        .limit_cycle(&ShootingOptions::default(), &Options::default())
        .unwrap();
    let impact = &cycle.events[0];
    let phase = (g * period * (1.0 - e) / (2.0 * (1.0 + e) * a * w)).acos() / w;
    // Event location to 1e-12 s; the orbit itself to Newton's 1e-13 relative.
    assert!(
        (impact.time.rem_euclid(period) - phase).abs() < 1e-10,
        "{}",
        impact.time
    );
    // State before the reset: at the table, falling at -g T / 2.
    assert!((impact.state[0] - a * (w * phase).sin()).abs() < 1e-10);
    assert!((impact.state[1] + g * period / 2.0).abs() < 1e-9);
    // At phase 0 the ball is in flight since t_i - T with v+ = g T / 2.
    let since = period - phase;
    let v0 = g * period / 2.0 - g * since;
    let y0 = a * (w * phase).sin() + g * period / 2.0 * since - 0.5 * g * since * since;
    assert!((cycle.state0[1] - v0).abs() < 1e-9 && (cycle.state0[0] - y0).abs() < 1e-10);
}

/// The ball's reset reads the table's velocity, so it moves with time: `dR/dt` is taken
/// symbolically, `(0, -(1 + e) A w^2 sin(w t))`, and the guard's `dh/dt = -A w cos(w t)`.
#[test]
fn bouncing_ball_time_derivatives_are_exact() {
    use htfid_hybrid::HybridSystem;
    let model = load("bouncing-ball");
    let (e, a) = (0.8, 0.01);
    let w = 2.0 * std::f64::consts::PI / 0.25;
    let mode = model.initial_mode();
    let (t, x) = (0.0371, [0.004, -1.2]);
    let mut out = [f64::NAN; 2];
    assert!(model.reset_time_derivative(mode, 0, t, &x, &mut out));
    let want = -(1.0 + e) * a * w * w * (w * t).sin();
    assert!(out[0].abs() < 1e-15 && (out[1] - want).abs() < 1e-12 * want.abs());
    let dhdt = model.guard_time_derivative(mode, 0, t, &x).unwrap();
    assert!((dhdt + a * w * (w * t).cos()).abs() < 1e-13);
}
