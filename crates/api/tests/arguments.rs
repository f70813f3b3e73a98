//! Arguments out of their domain are named errors, never a hang, a panic or a NaN result.

use htfid_api::{estimate, simulate, Error, EstimateOptions, Hopper, HopperParams, Htf, Input};

fn argument(e: Result<impl std::fmt::Debug, Error>) -> (&'static str, String) {
    match e {
        Err(Error::Argument { name, reason }) => (name, reason),
        other => panic!("expected an argument error, got {other:?}"),
    }
}

#[test]
fn estimate_refuses_a_bad_step_period_or_length_by_name() {
    let u: Vec<f64> = (0..1000).map(|i| (0.37 * f64::from(i)).sin()).collect();
    let y = u.clone();
    let opts = EstimateOptions::default();
    // A NaN step used to spin without end.
    for (dt, name) in [
        (f64::NAN, "dt"),
        (0.0, "dt"),
        (-0.01, "dt"),
        (f64::INFINITY, "dt"),
    ] {
        assert_eq!(
            argument(estimate(0.0, dt, &u, &y, 1.0, &opts)).0,
            name,
            "dt {dt}"
        );
    }
    assert_eq!(
        argument(estimate(f64::NAN, 0.01, &u, &y, 1.0, &opts)).0,
        "t0"
    );
    assert_eq!(
        argument(estimate(0.0, 0.01, &u, &y, -1.0, &opts)).0,
        "period"
    );
    let (name, reason) = argument(estimate(0.0, 0.01, &u, &y[..999], 1.0, &opts));
    assert_eq!(name, "u, y");
    assert!(
        reason.contains("1000") && reason.contains("999"),
        "{reason}"
    );
    // 76.54 samples per period: not a whole number.
    let (name, reason) = argument(estimate(0.0, 0.01, &u, &y, 0.7654, &opts));
    assert_eq!(name, "period");
    assert!(reason.contains("76.5400 samples"), "{reason}");
}

#[test]
fn the_htf_and_the_simulation_refuse_frequencies_and_grids_that_are_not_numbers() {
    let hopper = Hopper::new(HopperParams::paper()).unwrap();
    let htf = Htf::of(&hopper).unwrap();
    for w in [f64::NAN, f64::INFINITY] {
        assert_eq!(argument(htf.g(0, w)).0, "omega");
        assert_eq!(argument(htf.grids(&[0], &[1.0, w])).0, "omegas");
    }
    let input: Input = std::sync::Arc::new(|_t: f64| 0.0);
    let (name, reason) = argument(simulate(&htf, input.clone(), &[1.0, 0.5]));
    assert_eq!(name, "times");
    assert!(
        reason.contains("times[1] = 0.5 after times[0] = 1"),
        "{reason}"
    );
    assert_eq!(argument(simulate(&htf, input, &[-1.0])).0, "times");
}
