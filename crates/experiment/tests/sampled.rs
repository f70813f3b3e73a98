//! `drive_sampled` against `drive`: given the input's values at the grid, the same run bit for
//! bit; given a wrong count of them, an error that says so.

use std::sync::Arc;

use htfid_experiment::{drive, drive_sampled, ExperimentError, Input, Rhythmic};
use htfid_hybrid::Options;
use htfid_model::{Hopper, HopperParams};
use htfid_orbit::ShootingOptions;

fn setup() -> (
    Hopper,
    htfid_orbit::LimitCycle<htfid_model::HopperMode>,
    Vec<f64>,
    Input,
) {
    let hopper = Hopper::new(HopperParams::paper()).unwrap();
    let cycle =
        Rhythmic::limit_cycle(&hopper, &ShootingOptions::default(), &Options::default()).unwrap();
    let times: Vec<f64> = (0..400).map(|i| 0.01 * f64::from(i)).collect();
    let input: Input = Arc::new(|t: f64| 0.01 * (7.0 * t * t).sin());
    (hopper, cycle, times, input)
}

#[test]
fn given_samples_give_the_same_run_bit_for_bit() {
    let (hopper, cycle, times, input) = setup();
    let opts = Options::default();
    let plain = drive(&hopper, &cycle, Some(input.clone()), &times, &opts).unwrap();
    let samples: Vec<f64> = times.iter().map(|&t| input(t)).collect();
    let given = drive_sampled(&hopper, &cycle, Some(input), &times, &opts, || samples).unwrap();
    assert_eq!(plain.trajectory.times, given.trajectory.times);
    for (a, b) in plain.outputs.iter().zip(&given.outputs) {
        assert!(a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
    }
    // The input moved the mass: the comparison is not of two orbits.
    let unforced = drive(&hopper, &cycle, None, &times, &opts).unwrap();
    let moved = plain.outputs[0]
        .iter()
        .zip(&unforced.outputs[0])
        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(moved > 1e-6, "the input moved the mass by {moved}");
}

#[test]
fn a_wrong_count_of_samples_is_an_error() {
    let (hopper, cycle, times, input) = setup();
    let err = drive_sampled(
        &hopper,
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
