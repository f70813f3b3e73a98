//! The stepping API: `step_until` never passes `t_stop`, stopping at many intermediate times
//! does not ruin the step size, the dense output window, and every state dimension (the
//! kernels are specialised for dimensions up to 4 and generic above).

mod problems;

use htfid_hybrid::{simulate, HybridSystem, Integrator, Options, StopReason};
use problems::{Oscillator, METHODS};

#[test]
fn never_steps_past_t_stop_and_keeps_its_step_size() {
    for method in METHODS {
        let opts = Options {
            method,
            ..Options::default()
        };
        let t_end = 20.0;
        let single = simulate(&Oscillator, (), 0.0, &[1.0, 0.0], t_end, &[], &opts).unwrap();

        let mut integ = Integrator::new(&Oscillator, (), 0.0, &[1.0, 0.0], &opts).unwrap();
        let mut out = [0.0; 2];
        assert!(
            !integ.interpolate(0.0, &mut out),
            "no dense output before the first step"
        );
        let stops: Vec<f64> = (1..=100).map(|i| 0.2 * i as f64).collect();
        for &stop in &stops {
            loop {
                let reason = integ.step_until(stop).unwrap();
                assert!(
                    integ.t() <= stop,
                    "{method:?}: t = {} past {stop}",
                    integ.t()
                );
                if matches!(reason, StopReason::TStopReached) {
                    approx::assert_abs_diff_eq!(integ.t(), stop, epsilon = 0.0);
                    break;
                }
            }
            // At t_stop, asking again does nothing.
            let before = integ.stats();
            assert!(matches!(
                integ.step_until(stop).unwrap(),
                StopReason::TStopReached
            ));
            assert_eq!(integ.stats(), before);
            // Accuracy as for a free run (see tests/oscillator.rs: about rtol per period).
            let s = integ.state();
            assert!((s[0] - stop.cos()).abs() < 1e-9 && (s[1] + stop.sin()).abs() < 1e-9);
        }
        // A stop shortens one step; the next one resumes the step size the controller wanted,
        // so 100 stops cost at most about 100 extra steps.
        let steps = integ.stats().steps;
        assert!(
            steps <= single.stats.steps + stops.len() as u64 + 5,
            "{method:?}: {steps} steps with stops vs {} without",
            single.stats.steps
        );
        // The dense output covers exactly the last step.
        let (a, b) = integ.dense_range().unwrap();
        approx::assert_abs_diff_eq!(b, t_end, epsilon = 0.0);
        assert!(a < b);
        assert!(integ.interpolate(0.5 * (a + b), &mut out));
        assert!((out[0] - (0.5 * (a + b)).cos()).abs() < 1e-9);
        assert!(!integ.interpolate(a - 1e-3, &mut out));
        assert!(!integ.interpolate(b + 1e-3, &mut out));
        assert!(!integ.interpolate(a, &mut [0.0; 3]), "wrong output length");
    }
}

/// `copies` uncoupled oscillators `[x, v]` plus, for odd `dim`, a decaying `z' = -z`.
#[derive(Debug)]
struct Stacked {
    dim: usize,
}

impl HybridSystem for Stacked {
    type Mode = ();
    fn dim(&self) -> usize {
        self.dim
    }
    fn vector_field(&self, _: (), _t: f64, x: &[f64], dxdt: &mut [f64]) {
        for c in 0..self.dim / 2 {
            dxdt[2 * c] = x[2 * c + 1];
            dxdt[2 * c + 1] = -x[2 * c];
        }
        if self.dim % 2 == 1 {
            dxdt[self.dim - 1] = -x[self.dim - 1];
        }
    }
}

#[test]
fn every_dimension_matches_closed_form() {
    let t_end = 10.0;
    for method in METHODS {
        for dim in 1..=7 {
            let sys = Stacked { dim };
            // Oscillator c starts at amplitude c + 1: x = (c + 1) cos t.
            let mut x0 = vec![0.0; dim];
            for c in 0..dim / 2 {
                x0[2 * c] = (c + 1) as f64;
            }
            if dim % 2 == 1 {
                x0[dim - 1] = 1.0;
            }
            let opts = Options {
                method,
                ..Options::default()
            };
            let tr = simulate(&sys, (), 0.0, &x0, t_end, &[5.0], &opts).unwrap();
            for (t, s) in [(5.0f64, tr.state(0)), (t_end, &tr.final_state[..])] {
                for c in 0..dim / 2 {
                    let amp = (c + 1) as f64;
                    // rtol 1e-10 relative to amplitudes up to 3, over under two periods.
                    assert!(
                        (s[2 * c] - amp * t.cos()).abs() < 1e-9 * amp,
                        "{method:?} dim {dim} comp {c} at {t}: {}",
                        s[2 * c]
                    );
                    assert!((s[2 * c + 1] + amp * t.sin()).abs() < 1e-9 * amp);
                }
                if dim % 2 == 1 {
                    // Each accepted step commits a local error of at most about rtol relative
                    // (z stays far above atol = 1e-12), and on this contracting equation the
                    // relative errors at most add up: the bound is steps * rtol.
                    let z = (-t).exp();
                    let bound = tr.stats.steps as f64 * opts.rtol * z;
                    assert!(
                        (s[dim - 1] - z).abs() < bound,
                        "{method:?} dim {dim}: {} vs {z}",
                        s[dim - 1]
                    );
                }
            }
        }
    }
}

#[test]
fn trait_objects_are_accepted() {
    // Callers holding `&dyn HybridSystem` (e.g. a model chosen at run time) integrate the same.
    let sys: &dyn HybridSystem<Mode = ()> = &Oscillator;
    let opts = Options::default();
    let dynamic = simulate(sys, (), 0.0, &[1.0, 0.0], 3.0, &[1.5], &opts).unwrap();
    let concrete = simulate(&Oscillator, (), 0.0, &[1.0, 0.0], 3.0, &[1.5], &opts).unwrap();
    assert_eq!(dynamic.states, concrete.states);
    assert_eq!(dynamic.stats, concrete.stats);
}
