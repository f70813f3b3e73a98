//! `OrbitHtf::derivatives` (the HTFs' derivatives integrated along the orbit, with the orbit's
//! sensitivity, the changed linearisation, the moved switches and their changed saltation)
//! against `ExactHtf::derivatives` (the closed form along the piecewise linearisation's
//! tangents), on the shipped models whose linearisation is constant within each mode, where
//! both apply: two methods with no code in common past the model's own derivatives.

use std::path::Path;

use htfid_hybrid::Options;
use htfid_lang::Model;
use htfid_orbit::ShootingOptions;
use htfid_theory::{HtfChannel, LinearisedHtf, OrbitHtf};
use num_complex::Complex64;

fn shipped(name: &str) -> Model {
    Model::from_file(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../models/{name}.toml")),
    )
    .expect("the shipped model reads")
}

fn opts() -> Options {
    Options {
        rtol: 1e-11,
        atol: 1e-13,
        ..Options::default()
    }
}

/// The largest difference against the largest derivative, over every direction and point.
fn compare(name: &str, params: &[&str], period: f64) -> f64 {
    let model = shipped(name);
    let cycle = model
        .limit_cycle(&ShootingOptions::default(), &opts())
        .unwrap();
    let wp = std::f64::consts::TAU / period;
    let points: Vec<(i32, f64)> = (-2..=2)
        .flat_map(|k| [0.23, 0.61, 1.37, 2.9].map(|r| (k, r * wp)))
        .collect();

    let htf = LinearisedHtf::new(&model, &cycle, &opts()).unwrap();
    let lin = htf.linearisation().expect("closed form for this model");
    let tangents = model
        .piecewise_tangents(params, &cycle, lin, &opts())
        .unwrap()
        .expect("a piecewise-constant model gives its tangents");
    let HtfChannel::Exact(exact) = htf.channel(0).unwrap() else {
        panic!("closed form expected");
    };
    let channel: Vec<_> = tangents.iter().map(|t| t.channel(0, 0)).collect();
    let want = exact.derivatives(&channel, &points).unwrap();

    let orbit = OrbitHtf::new(&model, &cycle, &opts()).unwrap();
    let along = model
        .orbit_tangents(params, &cycle, &opts())
        .unwrap()
        .expect("no parameter here sets the period");
    let got = orbit.derivatives(&along, &points).unwrap().swap_remove(0);

    let scale = want.iter().flatten().map(|v| v.norm()).fold(0.0, f64::max);
    let mut worst = 0.0_f64;
    for (j, (g, w)) in got.iter().zip(&want).enumerate() {
        let err = g
            .iter()
            .zip(w)
            .map(|(a, b): (&Complex64, &Complex64)| (a - b).norm())
            .fold(0.0, f64::max)
            / scale;
        eprintln!(
            "{name}, d/d{}: {err:e} of the largest derivative",
            params[j]
        );
        worst = worst.max(err);
    }
    worst
}

/// Both methods are exact up to the integrator (rtol 1e-11 here, on the orbit, its
/// sensitivity and the response). Measured: 5e-11 of the largest derivative at most (the
/// mass and the table's amplitude; most directions 1e-12 to 1e-14). 1e-9 leaves twenty times
/// that, while a missing term (a jump's change, a moved switch) is of the order of the
/// derivative itself.
const TOLERANCE: f64 = 1e-9;

#[test]
fn along_the_orbit_matches_the_closed_form_on_the_hopper() {
    let err = compare("hopper", &["k", "c", "m", "a"], 1.0);
    assert!(err < TOLERANCE, "{err:e}");
}

/// Impacts on a moving table: resets, a guard that moves in time, saltations that change with
/// every parameter.
#[test]
fn along_the_orbit_matches_the_closed_form_on_the_bouncing_ball() {
    let err = compare("bouncing-ball", &["e", "g", "A"], 0.25);
    assert!(err < TOLERANCE, "{err:e}");
}

/// Touchdown and liftoff, a non-identity saltation at touchdown, a liftoff guard that reads
/// the thrust of time.
#[test]
fn along_the_orbit_matches_the_closed_form_on_the_flight_hopper() {
    let err = compare("flight-hopper", &["k", "c", "m", "L0", "a"], 0.5);
    assert!(err < TOLERANCE, "{err:e}");
}
