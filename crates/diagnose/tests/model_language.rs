//! Diagnosis of a model-language model on records from the independent truth generator
//! (`htfid-truth`: its own integrator and equations, sharing no code with the models).

use std::path::Path;

use htfid_diagnose::{diagnose_model, ModelCause, ModelFitOptions, ModelRecord};
use htfid_lang::Model;
use htfid_truth::{generate, ParameterErrors, Scenario};

/// The hopper file with its forcing amplitude at zero: the record's input column is the total
/// applied force, forcing included.
fn hopper() -> Model {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/hopper.toml");
    Model::from_file(&path)
        .unwrap()
        .with_parameters(&[("a", 0.0)])
        .unwrap()
}

fn record(scenario: &Scenario) -> ModelRecord {
    let r = generate(scenario).unwrap();
    ModelRecord {
        t: r.t.clone(),
        u: r.f.clone(),
        y: vec![r.x.clone()],
    }
}

fn options() -> ModelFitOptions {
    ModelFitOptions {
        free: vec!["k".into(), "c".into()],
        ..ModelFitOptions::default()
    }
}

/// A spring 3 % stiffer than configured is found: the configured simulation is the baseline,
/// so the refit of k is itself the finding, with k within 0.5 % of the truth (206) and c
/// unmoved.
#[test]
fn a_stiffer_spring_is_a_parameter_error() {
    let scenario = Scenario {
        parameter_errors: ParameterErrors {
            k: 0.03,
            ..ParameterErrors::default()
        },
        record_s: 90.0,
        ..Scenario::default()
    };
    let d = diagnose_model(&hopper(), &record(&scenario), None, &options()).unwrap();
    assert_eq!(d.cause, ModelCause::ParameterError, "{d:?}");
    let k = &d.parameters[0];
    assert!((k.fitted / 206.0 - 1.0).abs() < 5e-3, "{k:?}");
    assert!(k.z.abs() > 5.0);
    assert!(d.gain > 0.5, "{}", d.gain);
    let c = &d.parameters[1];
    assert!((c.fitted / 2.0 - 1.0).abs() < 0.02, "{c:?}");
}

/// A record of the nominal hopper names nothing: every refitted parameter stays within its
/// significance (5 standard errors) and within 1 % of the configured value.
#[test]
fn the_nominal_hopper_gives_none() {
    let scenario = Scenario {
        record_s: 90.0,
        ..Scenario::default()
    };
    let d = diagnose_model(&hopper(), &record(&scenario), None, &options()).unwrap();
    assert_eq!(d.cause, ModelCause::None, "{d:?}");
    for p in &d.parameters {
        assert!(
            p.z.abs() < 5.0 && (p.fitted / p.configured - 1.0).abs() < 1e-2,
            "{p:?}"
        );
    }
}
