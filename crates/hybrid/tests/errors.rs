//! Every error path: step-size underflow at a finite-time blow-up, invalid options (exact
//! messages), invalid grids and time spans, dimension mismatch, non-finite values, the step cap.

mod problems;

use htfid_hybrid::{simulate, HybridError, HybridSystem, Integrator, Options};
use problems::{Blowup, Oscillator, METHODS};

#[test]
fn blow_up_is_step_size_too_small_near_one() {
    // x' = x^2, x(0) = 1: x = 1 / (1 - t) blows up at t = 1. Near the pole the controller's
    // step shrinks like a fixed fraction of 1 - t, so it crosses h_min = 1e-14 within about
    // 1e-11 of t = 1 (the numerical pole itself differs from 1 by the accumulated relative
    // error, ~1e-11 here). The error must name that time, not panic and not run on.
    for method in METHODS {
        let err = simulate(
            &Blowup,
            (),
            0.0,
            &[1.0],
            2.0,
            &[],
            &Options {
                method,
                ..Options::default()
            },
        )
        .unwrap_err();
        match err {
            HybridError::StepSizeTooSmall { time, step } => {
                assert!((time - 1.0).abs() < 1e-9, "{method:?}: t = {time}");
                assert!(step < 1e-14, "{method:?}: step {step}");
                let msg = err.to_string();
                assert!(msg.contains(&format!("t = {time}")), "{msg}");
            }
            other => panic!("{method:?}: expected StepSizeTooSmall, got {other}"),
        }
    }
}

fn option_error(opts: Options) -> (&'static str, String) {
    match opts.validate() {
        Err(HybridError::InvalidOptions { field, reason }) => (field, reason),
        other => panic!("expected InvalidOptions, got {other:?}"),
    }
}

#[test]
fn invalid_options_name_field_and_value() {
    let d = Options::default;
    let cases: Vec<(Options, &str, &str)> = vec![
        (
            Options { rtol: -1.0, ..d() },
            "rtol",
            "must be > 0 and finite (got -1)",
        ),
        (
            Options { rtol: 0.0, ..d() },
            "rtol",
            "must be > 0 and finite (got 0)",
        ),
        (
            Options {
                rtol: f64::NAN,
                ..d()
            },
            "rtol",
            "must be > 0 and finite (got NaN)",
        ),
        (
            Options { atol: -1e-3, ..d() },
            "atol",
            "must be >= 0 and finite (got -0.001)",
        ),
        (
            Options {
                h_init: Some(0.0),
                ..d()
            },
            "h_init",
            "must be > 0 and finite (got 0)",
        ),
        (
            Options { h_max: 0.0, ..d() },
            "h_max",
            "must be > 0 (got 0)",
        ),
        (
            Options {
                h_min: 1.0,
                h_max: 0.5,
                ..d()
            },
            "h_min",
            "must be smaller than h_max = 0.5 (got 1)",
        ),
        (
            Options {
                max_steps: 0,
                ..d()
            },
            "max_steps",
            "must be >= 1 (got 0)",
        ),
        (
            Options {
                event_tol: f64::INFINITY,
                ..d()
            },
            "event_tol",
            "must be > 0 and finite (got inf)",
        ),
        (
            Options {
                graze_tol: -1.0,
                ..d()
            },
            "graze_tol",
            "must be >= 0 and finite (got -1)",
        ),
        (
            Options {
                zeno_window: 0.0,
                ..d()
            },
            "zeno_window",
            "must be > 0 and finite (got 0)",
        ),
        (
            Options {
                zeno_max_events: 0,
                ..d()
            },
            "zeno_max_events",
            "must be >= 1 (got 0)",
        ),
    ];
    for (opts, field, reason) in cases {
        assert_eq!(option_error(opts.clone()), (field, reason.to_string()));
        // The constructor and `simulate` validate too, with the same error.
        let err = Integrator::new(&Oscillator, (), 0.0, &[1.0, 0.0], &opts).unwrap_err();
        assert_eq!(
            err.to_string(),
            format!("invalid option `{field}`: {reason}")
        );
        let err = simulate(&Oscillator, (), 0.0, &[1.0, 0.0], 1.0, &[], &opts).unwrap_err();
        assert!(matches!(err, HybridError::InvalidOptions { .. }), "{err}");
    }
    assert!(Options::default().validate().is_ok());
}

#[test]
fn invalid_grid_and_time_span() {
    let opts = Options::default();
    let run = |t0: f64, t_end: f64, grid: &[f64]| {
        simulate(&Oscillator, (), t0, &[1.0, 0.0], t_end, grid, &opts).unwrap_err()
    };
    let msg = run(0.0, 1.0, &[0.0, 0.5, 0.4]).to_string();
    assert_eq!(
        msg,
        "invalid output grid: grid must be non-decreasing, but grid[2] = 0.4 < grid[1] = 0.5"
    );
    let msg = run(0.0, 1.0, &[0.5, 1.5]).to_string();
    assert_eq!(
        msg,
        "invalid output grid: grid[1] = 1.5 lies outside [t0, t_end] = [0, 1]"
    );
    let msg = run(0.0, 1.0, &[-0.1]).to_string();
    assert_eq!(
        msg,
        "invalid output grid: grid[0] = -0.1 lies outside [t0, t_end] = [0, 1]"
    );
    assert!(matches!(
        run(0.0, 1.0, &[f64::NAN]),
        HybridError::InvalidGrid { .. }
    ));
    assert!(matches!(
        run(1.0, 0.0, &[]),
        HybridError::InvalidTimeSpan { t0, t_end } if t0 > t_end
    ));
    assert!(matches!(
        run(0.0, f64::INFINITY, &[]),
        HybridError::InvalidTimeSpan { .. }
    ));
    // Repeated grid times and t0 == t_end are fine.
    let tr = simulate(&Oscillator, (), 0.0, &[1.0, 0.0], 0.0, &[0.0, 0.0], &opts).unwrap();
    assert_eq!(tr.states, vec![1.0, 0.0, 1.0, 0.0]);
}

#[test]
fn dimension_mismatch_and_non_finite_start() {
    let opts = Options::default();
    let err = simulate(&Oscillator, (), 0.0, &[1.0], 1.0, &[], &opts).unwrap_err();
    assert!(matches!(
        err,
        HybridError::DimensionMismatch {
            expected: 2,
            found: 1
        }
    ));
    assert_eq!(
        err.to_string(),
        "state has dimension 1, the system has dimension 2"
    );
    let err = simulate(&Oscillator, (), 0.0, &[f64::NAN, 0.0], 1.0, &[], &opts).unwrap_err();
    assert!(matches!(err, HybridError::NonFiniteState { time } if time == 0.0));
}

/// A vector field that turns NaN after t = 0.5, and a guard that is NaN after t = 0.25.
#[derive(Debug)]
struct Poisoned {
    field: bool,
}

impl HybridSystem for Poisoned {
    type Mode = ();
    fn dim(&self) -> usize {
        1
    }
    fn vector_field(&self, _: (), t: f64, _x: &[f64], dxdt: &mut [f64]) {
        dxdt[0] = if self.field && t > 0.5 { f64::NAN } else { 1.0 };
    }
    fn num_guards(&self, _: ()) -> usize {
        usize::from(!self.field)
    }
    fn guard(&self, _: (), _: usize, t: f64, _x: &[f64]) -> f64 {
        if t > 0.25 {
            f64::NAN
        } else {
            -1.0
        }
    }
}

#[test]
fn non_finite_field_and_guard() {
    for method in METHODS {
        let opts = Options {
            method,
            ..Options::default()
        };
        // A NaN field makes every step fail the error test until the step underflows; the
        // error then says why.
        let err =
            simulate(&Poisoned { field: true }, (), 0.0, &[0.0], 1.0, &[], &opts).unwrap_err();
        match err {
            HybridError::NonFiniteState { time } => {
                assert!(time > 0.49 && time <= 0.5, "{method:?}: t = {time}")
            }
            other => panic!("{method:?}: expected NonFiniteState, got {other}"),
        }
        let err =
            simulate(&Poisoned { field: false }, (), 0.0, &[0.0], 1.0, &[], &opts).unwrap_err();
        assert!(
            matches!(err, HybridError::NonFiniteGuard { guard: 0, time, value } if time > 0.25 && value.is_nan()),
            "{method:?}: {err}"
        );
    }
}

#[test]
fn step_cap() {
    let opts = Options {
        max_steps: 10,
        ..Options::default()
    };
    let err = simulate(&Oscillator, (), 0.0, &[1.0, 0.0], 100.0, &[], &opts).unwrap_err();
    match err {
        HybridError::MaxStepsExceeded { time, steps } => {
            assert_eq!(steps, 10);
            assert!(time > 0.0 && time < 100.0);
        }
        other => panic!("expected MaxStepsExceeded, got {other}"),
    }
}

#[test]
fn defaults_are_the_documented_ones() {
    let o = Options::default();
    assert_eq!(o.method, htfid_hybrid::Method::Dop853);
    approx::assert_relative_eq!(o.rtol, 1e-10);
    approx::assert_relative_eq!(o.atol, 1e-12);
    assert!(o.h_init.is_none());
    assert!(o.h_max.is_infinite());
    approx::assert_relative_eq!(o.h_min, 1e-14);
    assert_eq!(o.max_steps, 10_000_000);
    approx::assert_relative_eq!(o.event_tol, 1e-12);
    assert_eq!(o.guard_samples, 4);
    approx::assert_relative_eq!(o.graze_tol, 1e-8);
    approx::assert_relative_eq!(o.zeno_window, 1e-3);
    assert_eq!(o.zeno_max_events, 100);
}
