//! The term search outside the library, on records of the independent truth generator
//! (`htfid-truth`: its own equations and integrator), against the paper's hopper as configured
//! with nothing refitted. 90 s records keep each test short.

use htfid_diagnose::{diagnose, DiagnoseOptions, Diagnosis, NominalModel, TimeSeries};
use htfid_model::{DamperLaw, Effects, HopperParams};
use htfid_truth::{generate, Effect, Noise, Scenario};

fn nominal() -> NominalModel {
    NominalModel::new(
        HopperParams::paper(),
        DamperLaw::Switching,
        Effects::default(),
        Vec::new(),
    )
    .expect("valid nominal")
}

fn diagnosis(effects: Vec<Effect>) -> Diagnosis {
    let s = Scenario {
        effects,
        noise: Noise {
            sigma_x: 2e-5,
            sigma_f: 0.0,
        },
        seed: 7,
        record_s: 90.0,
        ..Scenario::default()
    };
    let r = generate(&s).expect("generator");
    let record = TimeSeries::new(r.t, r.f, r.x, "test").expect("record");
    diagnose(&record, &nominal(), &DiagnoseOptions::default())
        .expect("diagnosis")
        .diagnosis
}

#[test]
fn a_position_velocity_force_is_found_as_a_formula() {
    // Force -a (x - x_eq) v with a = 100 N s/m^2, outside the library.
    let a = 100.0;
    let d = diagnosis(vec![Effect::PosVelForce { a }]);
    eprintln!("{}", d.evidence.join("\n"));
    let found = d.discovered.as_ref().expect("a discovered formula");
    eprintln!("{}: {:?}", found.formula, found.terms);
    let term = found
        .terms
        .iter()
        .find(|t| t.term == "(x - x_eq) v")
        .expect("the (x - x_eq) v term");
    // 20 %: the output-error refit is unbiased, but the rest of the model is held at the
    // selection's fit (library effects that partly mimicked the term keep their share) and the
    // formula may carry a companion term correlated with (x - x_eq) v on this orbit.
    assert!(
        (term.coefficient / -a - 1.0).abs() < 0.2,
        "coefficient {} against {}",
        term.coefficient,
        -a
    );
    assert!(found.gain >= 0.05, "gain {}", found.gain);
    // A hint, not a cause: the library's answer is unchanged in kind.
    assert_ne!(d.cause, "pos_vel_force");
}

#[test]
fn a_clean_record_gives_no_formula() {
    let d = diagnosis(Vec::new());
    assert_eq!(d.cause, "none", "{}", d.evidence.join("\n"));
    assert!(d.discovered.is_none(), "{:?}", d.discovered);
}
