//! The hopper with Coulomb friction `mu` sticks where `|spring + gravity + forcing| < mu` at
//! `x' = 0`. Checked against `htfid-truth`, an independent generator written from the
//! equations with its own Dormand-Prince integrator and its own Filippov stick handling (it
//! shares no code with `htfid-model` or `htfid-hybrid`).
//!
//! Tolerances: the truth integrates with tolerance 1e-12 and locates its switches to 1e-14 s;
//! htfid runs at `rtol = 1e-12, atol = 1e-14` here. Each is accurate to about 1e-12 in the
//! state over the runs below (the orbit contracts, multipliers 0.07 and 0, so errors do not
//! grow), and a stick start or end moves by the state error divided by the rate at which the
//! deciding quantity changes (the acceleration, about 10 m/s^2, at a stick start; the force
//! rate `2 pi A` or `k |x'|`, of order 1 to 10 N/s, at an end). Measured: 2e-13 m, 2e-12 m/s
//! and 3e-12 s. `1e-10` leaves a factor of 50 for the difference of two integrators.

use htfid_hybrid::{simulate, EventKind, Options};
use htfid_model::{DamperLaw, Effects, Hopper, HopperMode, HopperParams};
use htfid_orbit::ShootingOptions;
use htfid_truth::{Effect, Excitation, Friction, Plant, Scenario, SimOptions, State};

const TOL: f64 = 1e-10;

fn hopper(mu: f64) -> Hopper {
    Hopper::with_effects(
        HopperParams::paper(),
        DamperLaw::Switching,
        Effects {
            mu,
            ..Effects::default()
        },
    )
    .unwrap()
}

fn tight() -> Options {
    Options {
        rtol: 1e-12,
        atol: 1e-14,
        ..Options::default()
    }
}

fn truth_plant(mu: f64) -> Plant {
    Plant::new(&Scenario {
        effects: vec![Effect::CoulombFriction { mu }],
        excitation: Excitation::ForcingOnly,
        ..Scenario::default()
    })
    .unwrap()
}

/// Truth start state: at rest at the static equilibrium (the truth's own protocol).
fn truth_start(plant: &Plant) -> State {
    let mut y: State = [0.0; htfid_truth::NX];
    y[htfid_truth::X] = plant.x0 - plant.m * plant.g / plant.k;
    y
}

/// `(start, end)` of every stick interval of a truth run.
fn truth_sticks(events: &[htfid_truth::Event]) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut open = None;
    for e in events {
        if e.to.friction == Friction::Stick && e.from.friction != Friction::Stick {
            open = Some(e.t);
        }
        if e.from.friction == Friction::Stick && e.to.friction != Friction::Stick {
            if let Some(s) = open.take() {
                out.push((s, e.t));
            }
        }
    }
    out
}

#[test]
fn sticking_hopper_matches_the_independent_truth_over_ten_seconds() {
    let mu = 0.5;
    let plant = truth_plant(mu);
    let y0 = truth_start(&plant);
    let grid: Vec<f64> = (0..=2000).map(|i| i as f64 * 0.005).collect();
    let truth = plant
        .simulate(0.0, y0, &grid, &SimOptions::default())
        .unwrap();
    let h = hopper(mu);
    let x0 = [y0[htfid_truth::X], 0.0];
    let traj = simulate(&h, h.mode_of(0.0), 0.0, &x0, 10.0, &grid, &tight()).unwrap();

    let mut worst = (0.0_f64, 0.0_f64);
    for (i, s) in truth.states.iter().enumerate() {
        let x = traj.state(i);
        worst.0 = worst.0.max((x[0] - s[htfid_truth::X]).abs());
        worst.1 = worst.1.max((x[1] - s[htfid_truth::V]).abs());
    }
    eprintln!(
        "position error {:e} m, velocity error {:e} m/s",
        worst.0, worst.1
    );
    assert!(worst.0 < TOL && worst.1 < TOL, "{worst:?}");

    let expected = truth_sticks(&truth.events);
    let found: Vec<(f64, f64)> = traj
        .sliding
        .iter()
        .filter(|s| s.exit.is_some())
        .map(|s| (s.start, s.end))
        .collect();
    assert!(
        expected.len() >= 15,
        "the run sticks twice per period: {expected:?}"
    );
    assert_eq!(found.len(), expected.len(), "{found:?} vs {expected:?}");
    let mut worst_t = 0.0_f64;
    for (f, e) in found.iter().zip(&expected) {
        worst_t = worst_t.max((f.0 - e.0).abs()).max((f.1 - e.1).abs());
    }
    eprintln!(
        "{} stick intervals, worst start/end difference {worst_t:e} s",
        found.len()
    );
    assert!(worst_t < TOL, "{worst_t:e}");

    // Off the stick intervals the chart is the sign of the velocity.
    traj.check_charts(&h, 1e-9).unwrap();
}

#[test]
fn sticking_limit_cycle_matches_the_settled_truth() {
    let mu = 0.5;
    let h = hopper(mu);
    let orbit = h
        .limit_cycle(&ShootingOptions::default(), &tight())
        .unwrap();
    // Settle the truth for 40 periods: the slowest multiplier is 0.07, so after 40 periods
    // the transient is far below 1e-12.
    let plant = truth_plant(mu);
    let truth = plant
        .simulate(
            0.0,
            truth_start(&plant),
            &[40.0, 40.25, 40.5, 40.75],
            &SimOptions::default(),
        )
        .unwrap();
    let sampled = h.sample_orbit(&orbit, 4, &tight()).unwrap();
    for (s, t) in sampled.iter().zip(&truth.states) {
        assert!(
            (s.x - t[htfid_truth::X]).abs() < TOL && (s.xd - t[htfid_truth::V]).abs() < TOL,
            "phase {}: htfid ({}, {}), truth ({}, {})",
            s.phase,
            s.x,
            s.xd,
            t[htfid_truth::X],
            t[htfid_truth::V]
        );
    }
    let expected: Vec<(f64, f64)> = truth_sticks(&truth.events)
        .into_iter()
        .filter(|(a, _)| *a >= 40.0)
        .map(|(a, b)| (a - 40.0, b - 40.0))
        .collect();
    let sticks = orbit.stick_intervals();
    assert_eq!(sticks.len(), 2, "{sticks:?}");
    assert_eq!(expected.len(), 2, "{expected:?}");
    for (s, e) in sticks.iter().zip(&expected) {
        assert!(
            (s.0 - e.0).abs() < TOL && (s.1 - e.1).abs() < TOL,
            "stick {s:?} vs truth {e:?}"
        );
    }
    // Two stick intervals per period, at the top (arriving damped, leaving free) and the
    // bottom (arriving free, leaving damped) of the stroke.
    let exits: Vec<Option<HopperMode>> = orbit.cycle.sliding.iter().map(|s| s.exit).collect();
    assert!(exits.contains(&Some(HopperMode::Free)) && exits.contains(&Some(HopperMode::Damped)));
    // The sticking orbit has one multiplier at zero (sticking forgets the velocity).
    let m = &orbit.cycle.multipliers;
    assert!(m[1].norm() < 1e-4, "{m:?}");
    assert!(orbit
        .cycle
        .events
        .iter()
        .any(|e| e.kind == EventKind::SlideStart));
}

#[test]
fn linearisations_refuse_an_orbit_that_sticks() {
    let h = hopper(0.5);
    let orbit = h
        .limit_cycle(&ShootingOptions::default(), &tight())
        .unwrap();
    let first = orbit.cycle.sliding[0];
    // Both ways to the HTF (the piecewise-LTI model and the periodic-response method) stop
    // with the first stick interval rather than give an HTF without the sticking.
    let err = htfid_ltp::linearise(&h, &orbit.cycle, 64, &tight()).unwrap_err();
    assert_eq!(
        err,
        htfid_ltp::LtpError::SlidingOrbit {
            guard: 0,
            start: first.start,
            end: first.end,
            intervals: 2,
        }
    );
    let err = htfid_theory::OrbitHtf::new(&h, &orbit.cycle, &tight()).unwrap_err();
    assert!(
        matches!(
            err,
            htfid_theory::TheoryError::Ltp(htfid_ltp::LtpError::SlidingOrbit { intervals: 2, .. })
        ),
        "{err}"
    );
}
