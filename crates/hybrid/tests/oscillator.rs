//! The harmonic oscillator `x'' = -x` from `x = 1, x' = 0`: `x = cos t`, `x' = -sin t`.
//! Checks accuracy over 100 periods against the closed form, energy drift, the dense output on
//! a grid, and the work counters (so that a regression in effort shows).

mod problems;

use std::f64::consts::PI;

use htfid_hybrid::{simulate, Method, Options, Stats};
use problems::{Oscillator, METHODS};

const PERIODS: f64 = 100.0;

fn run(method: Method, rtol: f64, grid: &[f64]) -> htfid_hybrid::Trajectory<()> {
    let opts = Options {
        method,
        rtol,
        atol: rtol * 1e-2,
        ..Options::default()
    };
    simulate(
        &Oscillator,
        (),
        0.0,
        &[1.0, 0.0],
        2.0 * PI * PERIODS,
        grid,
        &opts,
    )
    .expect("the oscillator integrates")
}

/// Amplitude error, phase error (rad) and energy error of a state at time `t`.
fn errors(t: f64, s: &[f64]) -> (f64, f64, f64) {
    let amp = s[0].hypot(s[1]);
    let phase = (-s[1]).atan2(s[0]);
    let exact_phase = (t + PI).rem_euclid(2.0 * PI) - PI;
    let mut dphase = phase - exact_phase;
    if dphase > PI {
        dphase -= 2.0 * PI;
    } else if dphase < -PI {
        dphase += 2.0 * PI;
    }
    let energy = 0.5 * (s[0] * s[0] + s[1] * s[1]);
    (amp - 1.0, dphase, energy - 0.5)
}

#[test]
fn hundred_periods_error_scales_with_tolerance() {
    for method in METHODS {
        for rtol in [1e-6, 1e-8, 1e-10] {
            let tr = run(method, rtol, &[]);
            let (da, dp, de) = errors(tr.final_time, &tr.final_state);
            // The controller bounds each step's local error by about rtol (relative, the state
            // has unit size), and on this neutrally stable problem local errors add up roughly
            // linearly per period. Observed constants are below 0.6 for both pairs at all three
            // tolerances; the bound 2 * rtol * periods fails on a four-fold regression.
            let bound = 2.0 * rtol * PERIODS;
            assert!(
                da.abs() <= bound && dp.abs() <= bound,
                "{method:?} rtol {rtol:e}: amplitude error {da:e}, phase error {dp:e}, bound {bound:e}"
            );
            // Energy 0.5 (x^2 + x'^2) drifts by amplitude error to first order.
            assert!(
                de.abs() <= bound,
                "{method:?} rtol {rtol:e}: energy drift {de:e}, bound {bound:e}"
            );
        }
    }
}

#[test]
fn dense_output_on_a_grid_matches_closed_form() {
    let t_end = 2.0 * PI * PERIODS;
    let grid: Vec<f64> = (0..=1000).map(|i| t_end * i as f64 / 1000.0).collect();
    for method in METHODS {
        let rtol = 1e-10;
        let tr = run(method, rtol, &grid);
        assert_eq!(tr.times.len(), grid.len());
        assert_eq!(tr.states.len(), 2 * grid.len());
        for (i, &t) in grid.iter().enumerate() {
            let s = tr.state(i);
            // Same bound as the final state: the interpolant's own error (O(h^5) resp. O(h^8)
            // locally) is below the accumulated global error at this tolerance.
            let bound = 2.0 * rtol * PERIODS;
            assert!(
                (s[0] - t.cos()).abs() <= bound && (s[1] + t.sin()).abs() <= bound,
                "{method:?} at t = {t}: {s:?} vs [{}, {}]",
                t.cos(),
                -t.sin()
            );
        }
        // The last grid point is t_end itself, which must carry the exact step end.
        let last = tr.state(grid.len() - 1);
        approx::assert_abs_diff_eq!(last[0], tr.final_state[0], epsilon = 0.0);
        approx::assert_abs_diff_eq!(last[1], tr.final_state[1], epsilon = 0.0);
    }
}

/// Per attempted step: 6 evaluations for Dopri5 (FSAL), 12 for DOP853 plus 3 dense-output
/// stages per accepted step; plus `f(t0)` and the starting-step estimate.
fn expected_rhs_evals(method: Method, s: &Stats) -> u64 {
    match method {
        Method::Dopri5 => 6 * (s.steps + s.rejected) + 2,
        Method::Dop853 => 12 * (s.steps + s.rejected) + 3 * s.steps + 2,
    }
}

#[test]
fn work_counters_stay_in_band() {
    // Recorded with the defaults (rtol 1e-10, atol 1e-12) over 100 periods:
    //   Dopri5: 20955 steps, 130 rejected;   DOP853: 1960 steps, 0 rejected.
    // The bands (+-5 %) let harmless changes through and catch an effort regression.
    let bands = [
        (Method::Dopri5, 19_900..=22_000, 0..=300),
        (Method::Dop853, 1_860..=2_060, 0..=20),
    ];
    for (method, steps, rejected) in bands {
        let tr = run(method, 1e-10, &[]);
        let s = tr.stats;
        assert!(
            steps.contains(&s.steps) && rejected.contains(&s.rejected),
            "{method:?}: {s:?} outside steps {steps:?}, rejected {rejected:?}"
        );
        assert_eq!(
            s.rhs_evals,
            expected_rhs_evals(method, &s),
            "{method:?}: {s:?}"
        );
        assert_eq!(s.events, 0);
        assert_eq!(s.guard_evals, 0, "no guards, no guard evaluations");
    }
}
