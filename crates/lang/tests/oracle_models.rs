//! The shipped models against `tests/oracle/models`: orbits, Floquet multipliers and HTFs
//! computed by a separately written Python program (numpy/scipy/mpmath, two methods each)
//! from the model equations alone.

mod common;

use std::path::{Path, PathBuf};

use htfid_hybrid::{EventKind, Options};
use htfid_lang::Model;
use htfid_orbit::ShootingOptions;
use htfid_theory::{HarmonicTransferFunction, OrbitHtf};
use num_complex::Complex64;
use serde_json::Value;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn check(model_file: &str, oracle_file: &str) {
    let model = Model::from_file(&root().join("models").join(model_file)).unwrap();
    let text =
        std::fs::read_to_string(root().join("tests/oracle/models").join(oracle_file)).unwrap();
    let oracle: Value = serde_json::from_str(&text).unwrap();
    let opts = Options::default(); // DOP853, rtol 1e-10, atol 1e-12
    let shooting = ShootingOptions {
        settle_periods: 100,
        ..ShootingOptions::default()
    };
    let cycle = model.limit_cycle(&shooting, &opts).unwrap();

    // Orbit: the oracle agrees with itself (two methods) to about 1e-12; ours is limited by
    // rtol 1e-10 along one period, so 1e-9 of the state's scale.
    let state0: Vec<f64> = oracle["orbit"]["state0"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let scale = state0.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
    for (a, b) in cycle.state0.iter().zip(&state0) {
        assert!(
            (a - b).abs() < 1e-9 * scale,
            "{model_file}: state0 {a} vs {b}"
        );
    }
    let ours: Vec<f64> = cycle
        .events
        .iter()
        .filter(|e| e.kind == EventKind::Transition)
        .map(|e| e.time.rem_euclid(cycle.period))
        .collect();
    let theirs: Vec<f64> = oracle["orbit"]["events"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["time"].as_f64().unwrap())
        .collect();
    assert_eq!(
        ours.len(),
        theirs.len(),
        "{model_file}: number of crossings"
    );
    for t in &theirs {
        // Event location is 1e-12 s; the orbit error moves crossings by about 1e-11 s.
        assert!(
            ours.iter().any(|o| (o - t).abs() < 1e-9),
            "{model_file}: crossing at {t} not found in {ours:?}"
        );
    }

    // Floquet multipliers: eigenvalues of a monodromy known to about 1e-10.
    let theirs: Vec<Complex64> = oracle["floquet"]
        .as_array()
        .unwrap()
        .iter()
        .map(|z| Complex64::new(z["re"].as_f64().unwrap(), z["im"].as_f64().unwrap()))
        .collect();
    common::assert_same_multipliers(model_file, &cycle.multipliers, &theirs, 1e-7);

    // HTFs, every output: the general periodic-response HTF against the oracle's
    // periodic solution of the same LTP system (checked there by small-signal simulation of
    // the nonlinear model). Both are exact up to integrator error: 1e-7 of max |G| per output.
    let htf = OrbitHtf::new(&model, &cycle, &opts).unwrap();
    let rows = oracle["htf"].as_array().unwrap();
    let outputs = rows
        .iter()
        .map(|r| r["output"].as_u64().unwrap() as usize)
        .max()
        .unwrap()
        + 1;
    assert_eq!(outputs, htf.n_outputs(), "{model_file}: outputs");
    for o in 0..outputs {
        let channel = htf.channel(o).unwrap();
        let mine: Vec<(Complex64, Complex64)> = rows
            .iter()
            .filter(|r| r["output"].as_u64().unwrap() as usize == o)
            .map(|r| {
                let (w, n) = (r["omega"].as_f64().unwrap(), r["n"].as_i64().unwrap());
                let want = Complex64::new(r["re"].as_f64().unwrap(), r["im"].as_f64().unwrap());
                (channel.g(n as i32, w), want)
            })
            .collect();
        let scale = mine.iter().map(|(_, w)| w.norm()).fold(0.0, f64::max);
        let worst = mine.iter().map(|(a, b)| (a - b).norm()).fold(0.0, f64::max);
        assert!(
            worst < 1e-7 * scale,
            "{model_file} output {o}: worst {worst:e} of max {scale:e}"
        );
    }
}

#[test]
fn bouncing_ball_matches_oracle() {
    check("bouncing-ball.toml", "bouncing_ball.json");
}

#[test]
fn flight_hopper_matches_oracle() {
    check("flight-hopper.toml", "flight_hopper.json");
}

#[test]
fn two_dof_matches_oracle() {
    check("two-dof.toml", "two_dof.json");
}

#[test]
fn closed_loop_friction_matches_oracle() {
    check("closed-loop-friction.toml", "closed_loop_friction.json");
}
