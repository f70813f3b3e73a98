//! `models/hopper.toml` against the closed-form oracle of `tests/oracle` (written from the
//! equations alone, sharing no code with the model language).

#[path = "../../../tests/oracle/hopper_closed_form.rs"]
mod oracle;

use std::path::Path;

use htfid_hybrid::{EventKind, HybridSystem, Options};
use htfid_lang::Model;
use htfid_orbit::ShootingOptions;

fn hopper() -> Model {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/hopper.toml");
    Model::from_file(&path).unwrap()
}

#[test]
fn hopper_file_orbit_matches_closed_form() {
    let model = hopper();
    let cycle = model
        .limit_cycle(&ShootingOptions::default(), &Options::default())
        .unwrap();
    let o = oracle::hopper_orbit(1.0, 200.0, 2.0, 9.81, 0.2, 1.0, 1.0);
    // Newton shooting converges to 1e-13; the integrator's rtol 1e-10 bounds the state error
    // along the orbit at about 1e-11 here (measured 2e-12).
    assert!(
        (cycle.state0[0] - o.x_phase0).abs() < 1e-10,
        "{:?}",
        cycle.state0
    );
    assert!((cycle.state0[1] - o.v_phase0).abs() < 1e-10);
    let times: Vec<(f64, &str)> = cycle
        .events
        .iter()
        .filter(|e| e.kind == EventKind::Transition)
        .map(|e| (e.time.rem_euclid(1.0), model.mode_name(e.to)))
        .collect();
    assert_eq!(times.len(), 2);
    for (t, to) in times {
        let expected = if to == "damped" { o.t_on } else { o.t_off };
        // Event location tolerance 1e-12 s plus the orbit's own error.
        assert!((t - expected).abs() < 1e-10, "{to}: {t} vs {expected}");
    }
    let mut mult: Vec<(f64, f64)> = cycle.multipliers.iter().map(|z| (z.re, z.im)).collect();
    mult.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut want = o.floquet.to_vec();
    want.sort_by(|a, b| b.1.total_cmp(&a.1));
    for (m, w) in mult.iter().zip(&want) {
        assert!(
            (m.0 - w.0).abs() < 1e-9 && (m.1 - w.1).abs() < 1e-9,
            "{m:?} vs {w:?}"
        );
    }
}

#[test]
fn hopper_file_is_piecewise_constant_with_exact_jacobians() {
    let model = hopper();
    assert!(model.is_piecewise_constant());
    let damped = model.mode("damped").unwrap();
    let mut jac = [0.0; 4];
    assert!(model.jacobian(damped, 0.3, &[0.1, 0.2], &mut jac));
    // Symbolic derivatives of integer-coefficient expressions are exact in floating point.
    approx::assert_abs_diff_eq!(jac.as_slice(), [0.0, 1.0, -200.0, -2.0].as_slice());
    let changed = model.with_parameters(&[("k", 150.0), ("c", 3.0)]).unwrap();
    assert!(changed.jacobian(damped, 0.3, &[0.1, 0.2], &mut jac));
    approx::assert_abs_diff_eq!(jac.as_slice(), [0.0, 1.0, -150.0, -3.0].as_slice());
    // The unchanged model is untouched.
    assert_eq!(model.parameter("k"), Some(200.0));
}

/// The hopper written in the model language gives the built-in hopper's orbit and exact HTFs
/// (the closed-form piecewise-LTI HTF of both linearisations) to 1e-10.
#[test]
fn hopper_file_matches_the_built_in_hopper() {
    use htfid_ltp::linearise;
    use htfid_model::{Hopper, HopperParams};
    use htfid_theory::{ExactHtf, HarmonicTransferFunction};

    let opts = Options::default();
    let shooting = ShootingOptions::default();
    let built_in = Hopper::new(HopperParams::paper()).unwrap();
    let orbit = built_in.limit_cycle(&shooting, &opts).unwrap();
    let model = hopper();
    let cycle = model.limit_cycle(&shooting, &opts).unwrap();
    for i in 0..2 {
        assert!((orbit.cycle.state0[i] - cycle.state0[i]).abs() < 1e-10);
    }
    for (a, b) in orbit.cycle.multipliers.iter().zip(&cycle.multipliers) {
        assert!((a - b).norm() < 1e-10, "{a} vs {b}");
    }
    let lin_a = linearise(&built_in, &orbit.cycle, 64, &opts).unwrap();
    let lin_b = linearise(&model, &cycle, 64, &opts).unwrap();
    let (ga, gb) = (
        ExactHtf::new(&lin_a.piecewise).unwrap(),
        ExactHtf::new(&lin_b.piecewise).unwrap(),
    );
    let omegas: Vec<f64> = (0..60).map(|i| 1.0 + 39.0 * i as f64 / 59.0).collect();
    let harmonics = [-3, -2, -1, 0, 1, 2, 3];
    let (a, b) = (ga.grid(&harmonics, &omegas), gb.grid(&harmonics, &omegas));
    let scale = a.max_abs();
    let worst = a
        .values
        .iter()
        .zip(&b.values)
        .map(|(x, y)| (x - y).norm())
        .fold(0.0, f64::max);
    assert!(worst < 1e-10 * scale, "worst {worst:e} of max {scale:e}");
}
