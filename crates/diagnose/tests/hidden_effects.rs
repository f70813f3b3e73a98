//! Data generated from a truth hopper with one hidden effect: the diagnosis must name it and
//! recover its parameter; without an effect it must say `none`; with an effect outside the
//! library it must not claim one.
//!
//! The truth is the paper's hopper (m = 1, k = 200, c = 2, g = 9.81, x0 = 0.2, forcing
//! cos(2 pi t)) integrated by `htfid-hybrid`'s DOP853 with event location and the continuous
//! input; the diagnosis sees only 100 Hz samples of the force (with noise 1e-4 N) and of the
//! position (noise 2e-6 m), and simulates with its own fixed-step scheme and spline input.
//! Protocol: 80 s, 5 s settling, then 15 s chirps 0 to 7 Hz of amplitude 0.05 N with five
//! phases (1 s cosine tapers keep the force smooth). The nominal model refits k and c.
//!
//! Detectable sizes. Each range below was chosen so that the nominal fit's held-out RMSE is
//! about 3 to 100 times the noise (measured while calibrating; the effect changes the output by
//! a few noise levels at its small end), and for the lag and the delay so that the two are
//! still told apart (they agree to first order in `omega tau`; below about 3 ms their fits
//! differ by less than the BIC margin and the diagnosis rightly refuses to choose):
//!
//! | effect | parameter | range | nominal RMSE / noise |
//! |---|---|---|---|
//! | cubic_stiffness | k3 | 100 to 1000 N/m^3 | 8 to 80 |
//! | coulomb_friction | mu | 0.002 to 0.01 N | 7 to 33 |
//! | flight_damping | c_f | 0.05 to 0.25 N s/m | 6 to 30 |
//! | quadratic_drag | c2 | 1 to 5 N s^2/m^2 | 6 to 28 |
//! | actuator_lag | tau | 3 to 15 ms | 40 to 200 |
//! | input_delay | delay | 3 to 15 ms | 40 to 200 |
//! | switch_threshold | v_th | +-(6 to 15) mm/s | 3 to 20 |
//! | hard_stop | x_stop, k_stop | 0.3 to 1.5 mm into the orbit's lowest point, 500 to 3000 N/m | 10 to 300 |
//! | parameter_error | m | 1 +- (0.005 to 0.03) kg | 11 to 66 |

mod common;

use std::f64::consts::PI;
use std::sync::Arc;

use common::{generate, ExtraForce, Protocol};
use htfid_diagnose::{diagnose, DiagnoseOptions, Diagnosis, Effect, NominalModel};
use htfid_model::{Effects, HardStop, HopperParams};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Lowest position of the nominal orbit under the test protocol (m), measured on a
/// noise-free record; the hard stop's contact position is drawn just above it.
const ORBIT_MIN: f64 = 0.143_03;

/// One hidden effect and its true parameters.
#[derive(Debug, Clone)]
struct Hidden {
    effect: Effect,
    params: HopperParams,
    effects: Effects,
}

fn log_uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    (lo.ln() + rng.gen::<f64>() * (hi.ln() - lo.ln())).exp()
}

fn sign(rng: &mut ChaCha8Rng) -> f64 {
    if rng.gen::<bool>() {
        1.0
    } else {
        -1.0
    }
}

/// Draws a detectable size of `effect` (see the module docs).
fn draw(effect: Effect, rng: &mut ChaCha8Rng) -> Hidden {
    let mut params = HopperParams::paper();
    let mut e = Effects::default();
    match effect {
        Effect::CubicStiffness => e.k3 = log_uniform(rng, 100.0, 1000.0),
        Effect::CoulombFriction => e.mu = log_uniform(rng, 0.002, 0.01),
        Effect::FlightDamping => e.c_f = log_uniform(rng, 0.05, 0.25),
        Effect::QuadraticDrag => e.c2 = log_uniform(rng, 1.0, 5.0),
        Effect::ActuatorLag => e.tau = log_uniform(rng, 0.003, 0.015),
        Effect::InputDelay => e.delay = log_uniform(rng, 0.003, 0.015),
        Effect::SwitchThreshold => e.v_th = sign(rng) * log_uniform(rng, 0.006, 0.015),
        Effect::HardStop => {
            e.hard_stop = Some(HardStop {
                x_stop: ORBIT_MIN + log_uniform(rng, 3e-4, 1.5e-3),
                k_stop: log_uniform(rng, 500.0, 3000.0),
            })
        }
        Effect::ParameterError => params.m = 1.0 + sign(rng) * log_uniform(rng, 0.005, 0.03),
    }
    Hidden {
        effect,
        params,
        effects: e,
    }
}

/// The true values the diagnosis must recover, with the allowed error of each: 10 % of the
/// value, except a contact position (10 % of its depth below the free orbit's lowest point,
/// since its absolute value says nothing) and a mass error (10 % of the deviation from the
/// nominal mass, since the mass itself is known to far better than 10 %).
fn targets(h: &Hidden) -> Vec<(&'static str, f64, f64)> {
    let e = &h.effects;
    let ten = |name, v: f64| (name, v, 0.1 * v.abs());
    match h.effect {
        Effect::CubicStiffness => vec![ten("k3", e.k3)],
        Effect::CoulombFriction => vec![ten("mu", e.mu)],
        Effect::FlightDamping => vec![ten("c_f", e.c_f)],
        Effect::QuadraticDrag => vec![ten("c2", e.c2)],
        Effect::ActuatorLag => vec![ten("tau", e.tau)],
        Effect::InputDelay => vec![ten("delay", e.delay)],
        Effect::SwitchThreshold => vec![ten("v_th", e.v_th)],
        Effect::HardStop => {
            let s = e.hard_stop.expect("drawn");
            vec![
                ("x_stop", s.x_stop, 0.1 * (s.x_stop - ORBIT_MIN)),
                ten("k_stop", s.k_stop),
            ]
        }
        Effect::ParameterError => vec![("m", h.params.m, 0.1 * (h.params.m - 1.0).abs())],
    }
}

fn nominal() -> NominalModel {
    NominalModel::hopper(HopperParams::paper()).expect("valid nominal")
}

fn summary(d: &Diagnosis) -> String {
    format!(
        "cause {} params {:?}\n{}",
        d.cause,
        d.parameters,
        d.evidence.join("\n")
    )
}

/// Generates, diagnoses and checks one case; returns a failure description.
fn check_hidden(h: &Hidden, seed: u64) -> Result<(), String> {
    let record = generate(&Protocol::default(), h.params, h.effects, None, seed);
    let report = diagnose(&record, &nominal(), &DiagnoseOptions::default())
        .map_err(|e| format!("{h:?}: diagnose failed: {e}"))?;
    let d = &report.diagnosis;
    if d.cause != h.effect.name() {
        return Err(format!("{h:?}: named {}\n{}", d.cause, summary(d)));
    }
    for (name, truth, tol) in targets(h) {
        let got = d.parameters.get(name).copied().unwrap_or(f64::NAN);
        if got.is_nan() || (got - truth).abs() > tol {
            return Err(format!(
                "{h:?}: {name} = {got}, truth {truth}, allowed error {tol}\n{}",
                summary(d)
            ));
        }
    }
    // The extended model must predict held-out data clearly better (the gain the decision
    // rule demands).
    if d.gain.is_nan() || d.gain < 0.05 {
        return Err(format!("{h:?}: gain {}\n{}", d.gain, summary(d)));
    }
    Ok(())
}

#[test]
fn every_library_effect_is_named_and_recovered() {
    // One seeded draw per effect: the quick set of the normal suite.
    let failures: Vec<String> = Effect::ALL
        .iter()
        .enumerate()
        .filter_map(|(i, &effect)| {
            let mut rng = ChaCha8Rng::seed_from_u64(1000 + i as u64);
            let h = draw(effect, &mut rng);
            check_hidden(&h, 2000 + i as u64).err()
        })
        .collect();
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn data_without_an_effect_give_none() {
    for seed in [11, 12] {
        let record = generate(
            &Protocol::default(),
            HopperParams::paper(),
            Effects::default(),
            None,
            seed,
        );
        let report = diagnose(&record, &nominal(), &DiagnoseOptions::default()).unwrap();
        let d = &report.diagnosis;
        assert_eq!(d.cause, "none", "{}", summary(d));
        assert!(d.candidates.iter().all(|c| !c.significant));
        // k and c refitted to the truth: their standard errors are about 1e-4 relative, so
        // 1e-3 is many of them.
        assert!(
            (d.parameters["k"] / 200.0 - 1.0).abs() < 1e-3,
            "{:?}",
            d.parameters
        );
        assert!(
            (d.parameters["c"] / 2.0 - 1.0).abs() < 1e-3,
            "{:?}",
            d.parameters
        );
        // The noise floor estimate sees the true position noise, 2e-6 m, to within 15 %
        // (about 8 % spread from 47 Welch segments plus the force noise passed through).
        let floor = report.noise_floor.expect("long enough");
        assert!((floor / 2e-6 - 1.0).abs() < 0.15, "noise floor {floor}");
        assert!(d.gain.abs() < 1e-12);
    }
}

#[test]
fn effects_outside_the_library_are_not_claimed() {
    // A sinusoidal force at 3.3 Hz (incommensurate with the forcing), a damping that grows with
    // the compression, and a spring that stiffens over the record: none is a library term, and
    // each changes the output by 4 to 100 noise levels. The diagnosis must not name a library
    // effect (`unexplained`, or `none` if it saw nothing).
    let extras: Vec<(&str, ExtraForce)> = vec![
        (
            "sinusoidal disturbance 0.004 N at 3.3 Hz",
            Arc::new(|t: f64, _x: f64, _v: f64| 0.004 * (2.0 * PI * 3.3 * t).sin()),
        ),
        (
            "position-dependent damping 100 (x - 0.151) x'",
            Arc::new(|_t: f64, x: f64, v: f64| -100.0 * (x - 0.151) * v),
        ),
        (
            "stiffness drifting by 2 N/m over the record",
            Arc::new(|t: f64, x: f64, _v: f64| -2.0 * t / 80.0 * (x - 0.2)),
        ),
    ];
    for (i, (name, extra)) in extras.into_iter().enumerate() {
        let record = generate(
            &Protocol::default(),
            HopperParams::paper(),
            Effects::default(),
            Some(extra),
            40 + i as u64,
        );
        let report = diagnose(&record, &nominal(), &DiagnoseOptions::default()).unwrap();
        let d = &report.diagnosis;
        assert!(
            d.cause == "unexplained" || d.cause == "none",
            "{name}: {}",
            summary(d)
        );
    }
}

#[test]
#[ignore = "wide sweep: run with --ignored"]
fn wide_sweep_over_many_seeds() {
    // 90 seeded draws (effect and size), 10 per effect on average, plus 10 without an effect.
    let mut failures = Vec::new();
    for seed in 0..90u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let effect = Effect::ALL[rng.gen_range(0..Effect::ALL.len())];
        let h = draw(effect, &mut rng);
        if let Err(e) = check_hidden(&h, 10_000 + seed) {
            failures.push(e);
        }
    }
    for seed in 0..10u64 {
        let record = generate(
            &Protocol::default(),
            HopperParams::paper(),
            Effects::default(),
            None,
            20_000 + seed,
        );
        let report = diagnose(&record, &nominal(), &DiagnoseOptions::default()).unwrap();
        if report.diagnosis.cause != "none" {
            failures.push(format!(
                "no effect, seed {seed}: {}",
                summary(&report.diagnosis)
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n\n")
    );
}
