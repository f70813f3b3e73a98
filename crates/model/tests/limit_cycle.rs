//! The hopper's limit cycle against independent truth: the closed-form piecewise solution
//! (each chart is linear with sinusoidal forcing), finite differences of the hybrid simulation,
//! and Liouville's formula.

#[path = "../../../tests/oracle/hopper_closed_form.rs"]
mod oracle;

use htfid_hybrid::{simulate, Options};
use htfid_model::{Hopper, HopperMode, HopperParams, ModelError};
use htfid_orbit::{OrbitError, ShootingOptions};

fn tight() -> Options {
    Options {
        rtol: 1e-12,
        atol: 1e-14,
        ..Options::default()
    }
}

fn check_against_oracle(p: HopperParams) {
    let hopper = Hopper::new(p).unwrap();
    let orbit = hopper
        .limit_cycle(&ShootingOptions::default(), &tight())
        .unwrap();
    let o = oracle::hopper_orbit(p.m, p.k, p.c, p.g, p.x0, p.forcing_amplitude, p.period);
    // Switch phases: the issue asks for 1e-9 s against the closed form; the integrator's event
    // location is good to ~1e-12 s at rtol 1e-12, so 1e-9 leaves margin for the orbit's own
    // sensitivity to the tolerance.
    assert!(
        (orbit.t_on - o.t_on).abs() < 1e-9,
        "t_on {} vs {}",
        orbit.t_on,
        o.t_on
    );
    assert!(
        (orbit.t_off - o.t_off).abs() < 1e-9,
        "t_off {} vs {}",
        orbit.t_off,
        o.t_off
    );
    let s0 = &orbit.cycle.state0;
    assert!(
        (s0[0] - o.x_phase0).abs() < 1e-10,
        "x(0) {} vs {}",
        s0[0],
        o.x_phase0
    );
    assert!(
        (s0[1] - o.v_phase0).abs() < 1e-9,
        "v(0) {} vs {}",
        s0[1],
        o.v_phase0
    );
    // Monodromy entries reach ~8 for the paper's parameters; variational equations at rtol 1e-12
    // give ~1e-10 relative.
    for i in 0..2 {
        for j in 0..2 {
            let (a, b) = (orbit.cycle.jacobian[(i, j)], o.monodromy[i][j]);
            assert!(
                (a - b).abs() < 1e-8 * (1.0 + b.abs()),
                "M[{i}][{j}] {a} vs {b}"
            );
        }
    }
    // Multipliers: the issue asks for 1e-6; we hold 1e-8.
    for (m, (re, im)) in orbit.cycle.multipliers.iter().zip(o.floquet.iter()) {
        assert!(
            (m.re - re).abs() < 1e-8 && (m.im - im).abs() < 1e-8,
            "{m} vs {re}+{im}j"
        );
    }
}

#[test]
fn paper_orbit_matches_closed_form() {
    check_against_oracle(HopperParams::paper());
}

#[test]
fn other_parameters_match_closed_form_including_mass_not_one() {
    // m != 1 exercises the physically consistent -m g in the flight chart (the paper prints -g).
    check_against_oracle(HopperParams {
        m: 2.0,
        k: 100.0,
        c: 2.0,
        forcing_amplitude: 0.5,
        period: 1.5,
        ..HopperParams::paper()
    });
    check_against_oracle(HopperParams {
        c: 5.0,
        period: 0.8,
        ..HopperParams::paper()
    });
}

#[test]
fn period_map_jacobian_matches_finite_differences_of_the_hybrid_simulation() {
    let p = HopperParams::paper();
    let hopper = Hopper::new(p).unwrap();
    let opts = Options {
        rtol: 1e-13,
        atol: 1e-15,
        ..Options::default()
    };
    let orbit = hopper
        .limit_cycle(&ShootingOptions::default(), &opts)
        .unwrap();
    let x0 = orbit.cycle.state0.clone();
    let flow = |x: &[f64]| {
        let mode = hopper.mode_of(x[1]);
        simulate(&hopper, mode, 0.0, x, p.period, &[], &opts)
            .unwrap()
            .final_state
    };
    // Central differences. The switch times depend on the state, so the period map is curved
    // (measured: the error is 2e-5 at h = 1e-5 and falls as h^2); at h = 1e-6 truncation is
    // ~2e-7 and rounding ~rtol * |x| / h ~ 2e-8, so 1e-6 of the largest entry (8.3) is honest.
    let h = 1e-6;
    let scale = orbit.cycle.jacobian.amax();
    for j in 0..2 {
        let (mut xp, mut xm) = (x0.clone(), x0.clone());
        xp[j] += h;
        xm[j] -= h;
        let (fp, fm) = (flow(&xp), flow(&xm));
        for i in 0..2 {
            let fd = (fp[i] - fm[i]) / (2.0 * h);
            let newton = orbit.cycle.jacobian[(i, j)];
            assert!(
                (fd - newton).abs() < 1e-6 * scale,
                "DP[{i}][{j}]: fd {fd} vs {newton}"
            );
        }
    }
}

#[test]
fn determinant_obeys_liouville() {
    let p = HopperParams::paper();
    let orbit = Hopper::new(p)
        .unwrap()
        .limit_cycle(&ShootingOptions::default(), &tight())
        .unwrap();
    // det M = exp(integral of trace A) = exp(-c/m * duty * T); trace A = -c s / m.
    let det = orbit.cycle.jacobian.determinant();
    let liouville = (-p.c / p.m * orbit.duty * p.period).exp();
    assert!((det - liouville).abs() < 1e-10, "{det} vs {liouville}");
    assert!(orbit.cycle.residual < 1e-12);
    assert_eq!(orbit.cycle.mode0, HopperMode::Damped);
}

#[test]
fn undamped_hopper_has_no_stable_orbit() {
    let p = HopperParams {
        c: 0.0,
        ..HopperParams::paper()
    };
    let err = Hopper::new(p)
        .unwrap()
        .limit_cycle(&ShootingOptions::default(), &Options::default())
        .unwrap_err();
    match &err {
        ModelError::Orbit(OrbitError::NotStable { max_modulus, .. }) => {
            // Undamped: the monodromy is a rotation, |mu| = 1.
            assert!((max_modulus - 1.0).abs() < 1e-6);
        }
        other => panic!("expected NotStable, got {other}"),
    }
    assert!(
        err.to_string().contains("no stable period-1 orbit"),
        "{err}"
    );
}

#[test]
fn invalid_parameters_are_named() {
    let err = Hopper::new(HopperParams {
        k: -3.0,
        ..HopperParams::paper()
    })
    .unwrap_err();
    // k = 0 is a free mass (an integrating plant); a negative stiffness is refused.
    assert_eq!(err.to_string(), "k must be >= 0 and finite (got -3)");
    let err = Hopper::new(HopperParams {
        m: f64::NAN,
        ..HopperParams::paper()
    })
    .unwrap_err();
    assert_eq!(err.to_string(), "m must be > 0 and finite (got NaN)");
    let err = Hopper::new(HopperParams {
        c: -1.0,
        ..HopperParams::paper()
    })
    .unwrap_err();
    assert_eq!(err.to_string(), "c must be >= 0 and finite (got -1)");
}
