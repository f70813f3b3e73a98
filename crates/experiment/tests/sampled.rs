//! `drive_sampled`: the outputs read the input's values the caller gives, one per grid time, and
//! the run is otherwise `drive`'s; a wrong count of values is an error that says so.
//!
//! The model is the shipped hopper file with a second output that reads the input itself
//! (`force = u`), so the values an output was given can be seen in the record.

use std::sync::Arc;

use htfid_experiment::{drive, drive_sampled, ExperimentError, Input, Rhythmic};
use htfid_hybrid::Options;
use htfid_lang::Model;
use htfid_orbit::{LimitCycle, ShootingOptions};

fn setup() -> (Model, LimitCycle<htfid_lang::Mode>, Vec<f64>, Input) {
    let text = include_str!("../../../models/hopper.toml").replace(
        r#"x = { expr = "x", unit = "m" }"#,
        "x = { expr = \"x\", unit = \"m\" }\nforce = { expr = \"u\", unit = \"N\" }",
    );
    let model = Model::parse(&text).unwrap();
    assert_eq!(model.outputs().len(), 2, "the input output was added");
    let cycle =
        Rhythmic::limit_cycle(&model, &ShootingOptions::default(), &Options::default()).unwrap();
    let times: Vec<f64> = (0..400).map(|i| 0.01 * f64::from(i)).collect();
    let input: Input = Arc::new(|t: f64| 0.01 * (7.0 * t * t).sin());
    (model, cycle, times, input)
}

#[test]
fn the_outputs_read_the_values_given_and_the_run_is_drives() {
    let (model, cycle, times, input) = setup();
    let opts = Options::default();
    let plain = drive(&model, &cycle, Some(input.clone()), &times, &opts).unwrap();
    // Values the input function never takes: twice its own.
    let given: Vec<f64> = times.iter().map(|&t| 2.0 * input(t)).collect();
    let expected = given.clone();
    let run = drive_sampled(&model, &cycle, Some(input.clone()), &times, &opts, || given).unwrap();
    // The output that reads the input holds exactly the values given...
    assert!(run.outputs[1]
        .iter()
        .zip(&expected)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    // ...and `drive` the input's own values at the grid.
    assert!(plain.outputs[1]
        .iter()
        .zip(&times)
        .all(|(a, &t)| a.to_bits() == input(t).to_bits()));
    // The trajectory is integrated through the input function either way: the same positions.
    assert_eq!(plain.trajectory.times, run.trajectory.times);
    assert!(plain.outputs[0]
        .iter()
        .zip(&run.outputs[0])
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    // The input moved the mass: the positions compared are not two copies of the orbit.
    let unforced = drive(&model, &cycle, None, &times, &opts).unwrap();
    let moved = plain.outputs[0]
        .iter()
        .zip(&unforced.outputs[0])
        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(moved > 1e-6, "the input moved the mass by {moved}");
}

#[test]
fn a_wrong_count_of_samples_is_an_error() {
    let (model, cycle, times, input) = setup();
    let err = drive_sampled(
        &model,
        &cycle,
        Some(input),
        &times,
        &Options::default(),
        || vec![0.0; 399],
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            ExperimentError::InputSamples {
                expected: 400,
                found: 399
            }
        ),
        "{err}"
    );
    assert_eq!(err.to_string(), "399 input values for a grid of 400 times");
}
