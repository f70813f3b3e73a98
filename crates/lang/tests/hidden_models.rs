//! Models written by someone else from `docs/models.md` alone (an impact oscillator with
//! restitution, a forced Duffing oscillator with an acceleration output, a system whose
//! stiffness and damping switch on a guard in time only), with their orbits, Floquet
//! multipliers and HTFs computed by that person's own program (`tests/oracle/hidden_models`:
//! numpy/scipy; closed form or Hill's method, each value checked against the integrated
//! variational equations and a brute-force simulation of the nonlinear model). Nothing of
//! either side was written with the other in view.
//!
//! A second round (`tests/oracle/hidden_models_2`, same layout, by another hand): an actuator
//! with a third state and a brake whose field jumps at its guards (non-identity saltation,
//! `tanh`), a spring between two clearance stops (three modes, six crossings a period, `min`,
//! `max`, `abs`, `exp`, two outputs), and a ball on a paddle moved by a non-sinusoidal motion
//! whose impact reset depends on both bodies, the restitution and time.
//!
//! A third round (`tests/oracle/hidden_models_3`, its own layout: each JSON holds the oracle at
//! the model file's values, `nominal`, and at the values that generated its record, `truth`):
//! an oscillator under a hysteretic relay (guards at `x = +-delta`, the field jumping at both),
//! and two masses with a one-sided contact between them, Hertzian (`kc pos(d)^1.5`) and
//! linear, with contact damping (four crossings a period, two outputs). The same person
//! simulated measured records from them, which the diagnosis tests in `tests/cli.rs` read.

mod common;

use std::path::{Path, PathBuf};

use htfid_hybrid::Options;
use htfid_lang::Model;
use htfid_orbit::ShootingOptions;
use htfid_theory::{HarmonicTransferFunction, LinearisedHtf};
use num_complex::Complex64;
use serde_json::Value;

/// The oracle's directory of a round of hidden models (`hidden_models`, `hidden_models_2`).
fn dir(round: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/oracle")
        .join(round)
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// Floquet multipliers written as `[re, im]` pairs.
fn multipliers(v: &Value) -> Vec<Complex64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|z| {
            let z = floats(z);
            Complex64::new(z[0], z[1])
        })
        .collect()
}

fn check(name: &str) {
    check_in("hidden_models", name, 1e-9);
}

/// One output's HTF in an oracle: its name, the scale of its tolerance, its values
/// `(n, omega, G)`.
type HtfTable = (String, f64, Vec<(i32, f64, Complex64)>);

/// What an oracle states about a model: its period, the mode and state at phase 0, the Floquet
/// multipliers, and per output (in the model's order) its HTF values `(n, omega, G)` with the
/// scale the tolerance is relative to (the largest |G| over the oracle's grid).
struct Reference {
    period: f64,
    mode: Option<String>,
    state0: Vec<f64>,
    multipliers: Vec<Complex64>,
    htf: Vec<HtfTable>,
}

/// The oracle of `name` in `dir`, as written.
fn oracle(dir: &Path, name: &str) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join(format!("{name}.json"))).unwrap())
        .unwrap()
}

/// The layout of rounds one and two.
fn rounds_one_two(oracle: &Value) -> Reference {
    let htf = oracle["outputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| {
            let output = o.as_str().unwrap().to_string();
            let table = &oracle["htf"][&output];
            let rows = table["values"]
                .as_array()
                .unwrap()
                .iter()
                .map(|row| {
                    (
                        row["n"].as_i64().unwrap() as i32,
                        row["omega"].as_f64().unwrap(),
                        Complex64::new(row["re"].as_f64().unwrap(), row["im"].as_f64().unwrap()),
                    )
                })
                .collect();
            (output, table["max_abs_over_grid"].as_f64().unwrap(), rows)
        })
        .collect();
    Reference {
        period: oracle["period"].as_f64().unwrap(),
        mode: oracle["mode_phase0"].as_str().map(str::to_string),
        state0: floats(&oracle["orbit_state_phase0"]),
        multipliers: multipliers(&oracle["floquet_multipliers"]),
        htf,
    }
}

/// The layout of round three, at the model file's values (`nominal`): HTF rows
/// `[omega, re, im]` by output and harmonic, in the order of `model`'s outputs.
fn round_three(all: &Value, model: &Model) -> Reference {
    let oracle = &all["nominal"];
    let tables = oracle["htf"].as_object().unwrap();
    assert_eq!(tables.len(), model.outputs().len(), "outputs");
    let htf = model
        .outputs()
        .iter()
        .map(|output| {
            let rows: Vec<(i32, f64, Complex64)> = tables[&output.name]
                .as_object()
                .unwrap()
                .iter()
                .flat_map(|(n, rows)| {
                    let n: i32 = n.parse().unwrap();
                    rows.as_array().unwrap().iter().map(move |r| {
                        let r = floats(r);
                        (n, r[0], Complex64::new(r[1], r[2]))
                    })
                })
                .collect();
            assert!(
                rows.len() >= 25,
                "output {}: {} values",
                output.name,
                rows.len()
            );
            let scale = rows.iter().map(|r| r.2.norm()).fold(0.0, f64::max);
            (output.name.clone(), scale, rows)
        })
        .collect();
    Reference {
        period: oracle["period"].as_f64().unwrap(),
        mode: Some(oracle["mode_phase0"].as_str().unwrap().to_string()),
        state0: floats(&oracle["state_phase0"]),
        multipliers: multipliers(&oracle["floquet_multipliers"]),
        htf,
    }
}

/// Checks `model` (`name`) against `reference` with the integrator `opts`: the period to 1e-12,
/// the orbit at phase 0 to 1e-9 of the state's scale, the multipliers to 1e-9, the HTFs of every
/// output to `htf_rel` of the reference's scale.
fn compare(name: &str, model: &Model, reference: &Reference, opts: &Options, htf_rel: f64) {
    let shooting = ShootingOptions {
        settle_periods: 100,
        ..ShootingOptions::default()
    };
    let cycle = model.limit_cycle(&shooting, opts).unwrap();
    assert!(
        (cycle.period - reference.period).abs() < 1e-12,
        "{name}: period"
    );

    // The orbit at phase 0: the first round's oracle (closed form and shooting) agrees with
    // itself to 3e-12; ours is limited by rtol 1e-10 along a period (measured 2.5e-10 of the
    // state's scale at worst).
    let scale = reference.state0.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
    for (a, b) in cycle.state0.iter().zip(&reference.state0) {
        assert!((a - b).abs() < 1e-9 * scale, "{name}: state0 {a} vs {b}");
    }
    if let Some(mode) = &reference.mode {
        assert_eq!(
            model.mode_name(cycle.mode0),
            mode,
            "{name}: mode at phase 0"
        );
    }

    // Floquet multipliers, as a set: measured agreement 1.3e-11 in the first round; a
    // monodromy known to about 1e-10 gives eigenvalues to 1e-9 unless they are nearly repeated
    // (they are not).
    common::assert_same_multipliers(name, &cycle.multipliers, &reference.multipliers, 1e-9);

    // HTFs of every output, as `htfid theory` computes them (exact piecewise where the
    // linearisation is constant within modes, the periodic response otherwise): measured
    // 4.7e-11 of the output's largest |G| at worst in the first round; the bound leaves room
    // for the integrator.
    let htf = LinearisedHtf::new(model, &cycle, opts).unwrap();
    assert_eq!(reference.htf.len(), htf.n_outputs(), "{name}: outputs");
    for (o, (output, scale, rows)) in reference.htf.iter().enumerate() {
        let channel = htf.channel(o).unwrap();
        let worst = rows
            .iter()
            .map(|&(n, w, want)| (channel.g(n, w) - want).norm())
            .fold(0.0, f64::max);
        assert!(
            worst < htf_rel * scale,
            "{name} output {output}: worst {worst:e} of max {scale:e}"
        );
    }
}

/// Checks `name` of `round` (one or two) against its oracle with the defaults of `htfid
/// theory` (DOP853, rtol 1e-10, atol 1e-12); the HTFs to `htf_rel`.
fn check_in(round: &str, name: &str, htf_rel: f64) {
    check_at(round, name, &Options::default(), htf_rel);
}

/// [`check_in`] with the integrator at `opts`.
fn check_at(round: &str, name: &str, opts: &Options, htf_rel: f64) {
    let dir = dir(round);
    let model = Model::from_file(&dir.join(format!("{name}.toml"))).unwrap();
    let reference = rounds_one_two(&oracle(&dir, name));
    compare(name, &model, &reference, opts, htf_rel);
}

#[test]
fn an_impact_oscillator_with_restitution_matches_its_oracle() {
    check("impact_oscillator");
}

#[test]
fn a_forced_duffing_oscillator_with_an_acceleration_output_matches_its_oracle() {
    check("forced_duffing");
}

#[test]
fn a_system_switched_by_a_guard_in_time_matches_its_oracle() {
    check("phase_switched");
}

#[test]
fn an_actuator_with_a_brake_whose_field_jumps_matches_its_oracle() {
    check_in("hidden_models_2", "actuator_brake", 1e-9);
}

/// The stops' force as an output is stiff at contact (an exponential stop of 300 N/m over
/// 5 cm): at the integrator's default rtol 1e-10 its HTF is off by 2.2e-9 of its largest |G|
/// (below 1e-9 at rtol 1e-12, so the integrator's, not the method's); the bound is 5e-9.
#[test]
fn a_spring_between_two_clearance_stops_matches_its_oracle() {
    check_in("hidden_models_2", "clearance_stops", 5e-9);
}

#[test]
fn a_ball_on_a_paddle_with_a_reset_of_both_bodies_matches_its_oracle() {
    check_in("hidden_models_2", "ball_on_paddle", 1e-9);
}

/// Checks `name` of the third round against its oracle at the model file's values (`nominal`)
/// with the integrator at `rtol`; the HTFs to `htf_rel`.
fn check_round_3(name: &str, rtol: f64, htf_rel: f64) {
    let dir = dir("hidden_models_3");
    let model = Model::from_file(&dir.join(format!("{name}.toml"))).unwrap();
    let reference = round_three(&oracle(&dir, name), &model);
    let opts = Options {
        rtol,
        ..Options::default()
    };
    compare(name, &model, &reference, &opts, htf_rel);
}

/// Measured against the oracle: orbit 3e-12, multipliers 7e-12, HTF 6e-13 of its largest |G|.
#[test]
fn an_oscillator_under_a_hysteretic_relay_matches_its_oracle() {
    check_round_3("relay_oscillator", 1e-10, 1e-9);
}

/// The Hertz law's stiffness grows without bound into the contact: at rtol 1e-10 the second
/// output's HTF is off by 1.1e-8 of its largest |G| (integrator-limited; 3e-11 at rtol 1e-12),
/// hence the tighter tolerance here.
#[test]
fn two_masses_with_a_hertz_contact_between_them_match_their_oracle() {
    check_round_3("contact_pair", 1e-12, 1e-9);
}

/// Measured: orbit 1.2e-11, multipliers 5e-11, HTF 1.7e-10 of the largest |G|.
#[test]
fn two_masses_with_a_linear_contact_between_them_match_their_oracle() {
    check_round_3("contact_pair_linear", 1e-10, 1e-9);
}

// A fourth round (`tests/oracle/hidden_models_4`, the layout of rounds one and two, by another
// hand from `docs/models.md` alone): a leaky integrate-and-fire neuron whose spike resets its
// own state (a one-dimensional saltation of 3.26, outputs that jump and one that reads the
// input), a rimless wheel whose heel strike moves its angle by `-2 alpha` (`sin`, a complex
// pair of multipliers, an output that jumps), and a pendulum between two damped stops (three
// modes, four crossings a period, the period an expression of a parameter, `pos` and `min`
// in an output). The oracle's HTFs of outputs that jump are the documented `C dx + D u` with
// the saltation applied, without the pulse a moved event adds to a measured signal.

#[test]
fn an_integrate_and_fire_neuron_whose_spike_resets_its_state_matches_its_oracle() {
    check_in("hidden_models_4", "lif_neuron", 1e-9);
}

/// The integrator at rtol 1e-12, atol 1e-14: at the default rtol 1e-10 the wheel's hip height
/// is off by 6.2e-9 of its largest |G| and the pendulum's stop torque (a stiff contact) by
/// 1.4e-9; at 1e-12 by 1.6e-10 and under 1e-10. The error shrinks with the tolerance, so it is
/// the integrator's, not the method's; the bound, 5e-10, is three times the larger.
fn tight() -> Options {
    Options {
        rtol: 1e-12,
        atol: 1e-14,
        ..Options::default()
    }
}

#[test]
fn a_rimless_wheel_whose_heel_strike_moves_its_angle_matches_its_oracle() {
    check_at("hidden_models_4", "rimless_wheel", &tight(), 5e-10);
}

#[test]
fn a_pendulum_between_two_damped_stops_matches_its_oracle() {
    check_at("hidden_models_4", "pendulum_stops", &tight(), 5e-10);
}
