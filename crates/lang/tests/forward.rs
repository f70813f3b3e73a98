//! Forward sensitivities of the simulated outputs against central differences of plain
//! simulations (the model recompiled with each parameter, or started from each initial state,
//! moved up and down), on the shipped models with every kind of guard: a switching damper
//! without reset (hopper, two-dof), touchdown and liftoff guards whose expressions hold
//! parameters (flight hopper), and an impact with restitution on a moving table (bouncing
//! ball: a time-dependent guard and reset, non-identity saltation).

use std::path::Path;
use std::sync::Arc;

use htfid_hybrid::{simulate, Options};
use htfid_lang::{output_sensitivities, InputFn, Model};

fn load(name: &str) -> Model {
    if name == "two-dof-shifted" {
        return shifted();
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../models/{name}.toml"));
    Model::from_file(&path).unwrap()
}

/// The two-dof model with its damper switching at `v1 = s` instead of 0: the field jumps at
/// the switch, on a surface along which the motion could slide.
fn shifted() -> Model {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/two-dof.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let text = text
        .replace("when = \"v1\"", "when = \"v1 - s\"")
        .replace("[parameters]", "[parameters]\ns = { value = 0.05 }");
    Model::parse(&text).unwrap()
}

fn tight() -> Options {
    Options {
        rtol: 1e-12,
        atol: 1e-14,
        ..Options::default()
    }
}

/// The outputs of a plain simulation on `grid`, and the times of its transitions.
fn outputs(model: &Model, x0: &[f64], grid: &[f64]) -> (Vec<Vec<f64>>, Vec<f64>) {
    let mode = model.start_mode(model.initial_mode(), grid[0], x0);
    let end = *grid.last().unwrap();
    let traj = simulate(model, mode, grid[0], x0, end, grid, &tight()).unwrap();
    let p = model.outputs().len();
    let mut out = vec![vec![0.0; grid.len()]; p];
    let mut y = vec![0.0; p];
    for (i, &t) in grid.iter().enumerate() {
        model.eval_outputs(
            traj.modes[i],
            t,
            traj.state(i),
            model.input_value(t),
            &mut y,
        );
        for o in 0..p {
            out[o][i] = y[o];
        }
    }
    (out, traj.events.iter().map(|e| e.time).collect())
}

/// Every column of the exact sensitivities against a central difference with relative step
/// `step` (of at least `0.1` for a state), at `rtol = 1e-12`. Samples between a transition of
/// the two moved runs are skipped (with `1e-4` s to spare): a difference straddling a crossing
/// there sees the moved event, not the derivative. The step depends on the guards:
///
/// - Where the field is continuous across a switch (a damper switching at zero velocity) the
///   outputs are once but not twice differentiable in the parameters (the field's Jacobian
///   jumps), so a central difference is only first-order accurate: `1e-5`, whose error is
///   then about `1e-5` of a column.
/// - Where the field or the state jumps (a touchdown, an impact), the crossing is located to
///   about `1e-12` s, which moves the output by the jump (up to 30 m/s^2) times that: over a
///   step of `1e-5` that noise would reach `1e-5` of a column, so the step is `1e-4`
///   (truncation about `1e-8`, noise about `1e-6`).
///
/// `2e-5` of the column's largest value bounds either with room, while a missing saltation
/// term or a wrong sign is off by the column's own size.
fn check(name: &str, params: &[&str], step: f64, span: f64, min_events: usize) {
    let input: InputFn = Arc::new(|t: f64| 0.3 * (3.1 * t).sin());
    let model = load(name).with_input(Some(input));
    let x0 = model.initial_state().to_vec();
    let n = x0.len();
    let grid: Vec<f64> = (0..=400).map(|i| span * i as f64 / 400.0).collect();
    let mode = model.start_mode(model.initial_mode(), 0.0, &x0);
    let exact =
        output_sensitivities(&model, params, true, mode, 0.0, &x0, &grid, &tight()).unwrap();
    let (plain, events) = outputs(&model, &x0, &grid);
    let events = events.len();
    assert!(
        events >= min_events,
        "{name}: {events} transitions, the test needs at least {min_events}"
    );
    // The sensitivity run's outputs are the plain run's, to the tolerance.
    for (a, b) in exact.outputs.iter().zip(&plain) {
        let size = b.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        for (x, y) in a.iter().zip(b) {
            assert!(
                (x - y).abs() <= 1e-9 * size.max(1e-3),
                "{name}: outputs {x} vs {y}"
            );
        }
    }
    let columns = params.len() + n;
    for j in 0..columns {
        let (up, down, h, what) = if j < params.len() {
            let v = model.parameter(params[j]).unwrap();
            let h = step * v.abs().max(1e-3);
            let up = model.with_parameters(&[(params[j], v + h)]).unwrap();
            let down = model.with_parameters(&[(params[j], v - h)]).unwrap();
            (
                outputs(&up, &x0, &grid),
                outputs(&down, &x0, &grid),
                h,
                params[j].to_string(),
            )
        } else {
            let s = j - params.len();
            let h = step * x0[s].abs().max(0.1);
            let (mut a, mut b) = (x0.clone(), x0.clone());
            a[s] += h;
            b[s] -= h;
            (
                outputs(&model, &a, &grid),
                outputs(&model, &b, &grid),
                h,
                format!("initial state {s}"),
            )
        };
        let ((up, up_events), (down, down_events)) = (up, down);
        // Between a transition of the run moved up and the same transition of the run moved
        // down (and 1e-4 s around), the difference straddles the crossing.
        let near_event = |t: f64| {
            up_events
                .iter()
                .zip(&down_events)
                .any(|(&a, &b)| t > a.min(b) - 1e-4 && t < a.max(b) + 1e-4)
        };
        for o in 0..plain.len() {
            let col = &exact.columns[j][o];
            let size = col.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            assert!(size > 0.0, "{name}: d y{o} / d {what} vanishes everywhere");
            for i in 0..grid.len() {
                if near_event(grid[i]) {
                    continue;
                }
                let fd = (up[o][i] - down[o][i]) / (2.0 * h);
                assert!(
                    (col[i] - fd).abs() <= 2e-5 * size,
                    "{name}: d y{o} / d {what} at t = {}: exact {} vs difference {fd}",
                    grid[i],
                    col[i]
                );
            }
        }
    }
}

#[test]
fn the_hoppers_sensitivities_cross_its_damper_switches() {
    check("hopper", &["k", "c", "m", "x0"], 1e-5, 6.0, 8);
}

#[test]
fn the_flight_hoppers_sensitivities_cross_touchdown_and_liftoff() {
    check("flight-hopper", &["k", "c", "L0", "a"], 1e-4, 3.0, 6);
}

#[test]
fn the_bouncing_balls_sensitivities_cross_impacts_on_the_moving_table() {
    check("bouncing-ball", &["e", "A", "g"], 1e-4, 2.0, 4);
}

#[test]
fn the_two_dof_sensitivities_with_two_outputs() {
    check("two-dof", &["k1", "k2", "k3", "c1", "c2"], 1e-5, 5.0, 6);
}

#[test]
fn the_sensitivities_cross_a_moved_switch_where_the_field_jumps() {
    check("two-dof-shifted", &["s", "k2", "c1"], 1e-4, 5.0, 6);
}

/// Columns along the input's directions against closed forms: an integrator `x' = u` driven
/// by `u(t) = sin(t - d)` has `dx/dd = -(sin(t - d) - sin(-d))` (the direction `-cos(t - d)`
/// integrated), and with an output `y = x + 2 u` reading the input the output's column adds
/// `2 w(t)`; an input offset (direction 1) gives `t` and `t + 2`. A guard `x - 0.5 = 0` with
/// a reset `x -> x - u` (both through the input) moves the crossing: after it, the column of
/// a constant input change `w` is `w t - w` from the reset's `-u` (the crossing time's shift
/// cancels in the integrator, whose field `u` is the same on both sides: the saltation
/// carries `dx/dd` through unchanged). Tolerance: 1e-9, the integrator's `rtol = 1e-12`
/// over values of order one.
#[test]
fn input_directions_give_the_closed_form_derivatives() {
    let d = 0.3;
    let model = Model::parse(
        r#"
        states = ["x"]
        parameters = { k = 1.0 }
        flow = { x = "u" }
        outputs = { y = "x + 2*u" }
        initial = { x = 0.0 }
        "#,
    )
    .unwrap()
    .with_input(Some(Arc::new(move |t: f64| (t - d).sin())));
    let grid: Vec<f64> = (0..=200).map(|i| 0.025 * i as f64).collect();
    let delay: InputFn = Arc::new(move |t: f64| -(t - d).cos());
    let offset: InputFn = Arc::new(|_| 1.0);
    // The outputs' columns along `directions`, from `x = 0` at `t = 0`.
    let along = |model: &Model, directions: &[InputFn]| {
        htfid_lang::output_sensitivities_with_input(
            model,
            &[],
            directions,
            false,
            model.initial_mode(),
            0.0,
            &[0.0],
            &grid,
            &tight(),
        )
        .unwrap()
    };
    let s = along(&model, &[delay, offset]);
    assert_eq!(s.columns.len(), 2);
    for (i, &t) in grid.iter().enumerate() {
        let by_delay = -((t - d).sin() - (-d).sin()) + 2.0 * -(t - d).cos();
        let by_offset = t + 2.0;
        assert!((s.columns[0][0][i] - by_delay).abs() < 1e-9, "t {t}");
        assert!((s.columns[1][0][i] - by_offset).abs() < 1e-9, "t {t}");
    }

    // A constant input 1 reaches the guard at t = 0.5 and the reset takes u off.
    let model = Model::parse(
        r#"
        states = ["x"]
        parameters = { k = 1.0 }

        [modes.before]
        x = "u"

        [modes.after]
        x = "u"

        [[guards]]
        name = "half"
        from = "before"
        to = "after"
        when = "x - 0.5"
        direction = "rising"
        reset = { x = "x - u" }

        [outputs]
        y = "x"

        [initial]
        mode = "before"
        x = 0.0
        "#,
    )
    .unwrap();
    let model = model.with_input(Some(Arc::new(|_t: f64| 1.0)));
    let offset: InputFn = Arc::new(|_| 1.0);
    let s = along(&model, &[offset]);
    for (i, &t) in grid.iter().enumerate() {
        let exact = if t < 0.5 { t } else { t - 1.0 };
        if (t - 0.5).abs() > 1e-9 {
            assert!(
                (s.columns[0][0][i] - exact).abs() < 1e-9,
                "t {t}: {}",
                s.columns[0][0][i]
            );
        }
    }
}
