//! The scenario file format: defaults, unknown keys, range messages, labels.

use htfid_truth::{Effect, Excitation, LabelClass, ParameterErrors, Plant, SampleRate, Scenario};

fn parse(json: &str) -> Result<Scenario, serde_json::Error> {
    serde_json::from_str(json)
}

fn invalid(s: &Scenario) -> String {
    Plant::new(s).unwrap_err().to_string()
}

#[test]
fn empty_object_is_the_clean_paper_protocol() {
    let s = parse("{}").unwrap();
    assert_eq!(s, Scenario::default());
    assert_eq!(s.sample_rate, SampleRate::Hz100);
    assert_eq!(s.excitation, Excitation::PaperChirps);
    assert!((s.settle_s - 30.0).abs() < 1e-12 && (s.record_s - 270.0).abs() < 1e-12);
}

#[test]
fn full_scenario_round_trips() {
    let json = r#"{
        "name": "a",
        "effects": [
            {"effect": "cubic_stiffness", "k3": 2000.0},
            {"effect": "hard_stop", "k_stop": 5000.0, "x_stop": 0.147},
            {"effect": "second_mode", "m2": 0.2, "k2": 79.0, "c2": 0.4}
        ],
        "parameter_errors": {"k": 0.05},
        "noise": {"sigma_x": 2e-5},
        "sample_rate": 1000,
        "excitation": {"kind": "multisine", "phase_seed": 4},
        "seed": 9,
        "record_s": 60
    }"#;
    let s = parse(json).unwrap();
    assert_eq!(s.sample_rate, SampleRate::Hz1000);
    assert_eq!(
        s.effects[1],
        Effect::HardStop {
            k_stop: 5000.0,
            x_stop: 0.147
        }
    );
    let back = parse(&serde_json::to_string(&s).unwrap()).unwrap();
    assert_eq!(back, s);
}

#[test]
fn unknown_keys_and_names_fail() {
    for (json, needle) in [
        (r#"{"nosie": {}}"#, "unknown field `nosie`"),
        (r#"{"noise": {"sigma": 1}}"#, "unknown field `sigma`"),
        (
            r#"{"effects": [{"effect": "cubic_stiffness", "k4": 1}]}"#,
            "unknown field `k4`",
        ),
        (
            r#"{"effects": [{"effect": "cubic_spring", "k3": 1}]}"#,
            "unknown variant `cubic_spring`",
        ),
        (
            r#"{"parameter_errors": {"mass": 0.1}}"#,
            "unknown field `mass`",
        ),
        (
            r#"{"sample_rate": 123}"#,
            "sample rate must be one of 50, 100, 200, 1000 Hz (got 123)",
        ),
    ] {
        let err = parse(json).unwrap_err().to_string();
        assert!(err.contains(needle), "{json}: {err}");
    }
}

#[test]
fn range_errors_name_the_field_and_value() {
    let with = |effects: Vec<Effect>| Scenario {
        effects,
        ..Scenario::default()
    };
    assert_eq!(
        invalid(&with(vec![Effect::CoulombFriction { mu: -1.0 }])),
        "effects[0].mu must be >= 0 (got -1)"
    );
    assert_eq!(
        invalid(&with(vec![
            Effect::InputOffset { offset: 0.1 },
            Effect::ActuatorLag { tau: 0.0 }
        ])),
        "effects[1].tau must be > 0 (got 0)"
    );
    assert_eq!(
        invalid(&with(vec![
            Effect::InputOffset { offset: 0.1 },
            Effect::InputOffset { offset: 0.2 }
        ])),
        "effect input_offset is listed twice"
    );
    assert_eq!(
        invalid(&with(vec![
            Effect::CoulombFriction { mu: 0.1 },
            Effect::AsymmetricFriction {
                mu_pos: 0.1,
                mu_neg: 0.2
            }
        ])),
        "effects coulomb_friction and asymmetric_friction cannot be combined"
    );
    assert_eq!(
        invalid(&with(vec![Effect::SecondMode {
            m2: 0.95,
            k2: 100.0,
            c2: 0.1
        }])),
        "effects[0].m2 must be < 0.9 m (the true mass) (got 0.95)"
    );
    assert_eq!(
        invalid(&Scenario {
            parameter_errors: ParameterErrors {
                k: -0.7,
                ..ParameterErrors::default()
            },
            ..Scenario::default()
        }),
        "parameter_errors.k must be in (-0.5, 0.5) (got -0.7)"
    );
    assert_eq!(
        invalid(&Scenario {
            record_s: 0.0,
            ..Scenario::default()
        }),
        "record_s must be > 0 (got 0)"
    );
}

#[test]
fn labels_carry_names_parameters_and_class() {
    let s = Scenario {
        effects: vec![
            Effect::SwitchThreshold { v_th: -0.02 },
            Effect::Backlash { gap: 0.1 },
        ],
        parameter_errors: ParameterErrors {
            c: 0.05,
            ..ParameterErrors::default()
        },
        ..Scenario::default()
    };
    let l = s.label();
    assert_eq!(l.class, LabelClass::Mixed);
    let names: Vec<&str> = l.effects.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(names, ["switch_threshold", "backlash", "parameter_error"]);
    assert!((l.effects[0].params["v_th"] + 0.02).abs() < 1e-15);
    assert!(!l.effects[1].in_library);
    assert_eq!(l.effects[2].params.len(), 1);
    assert!((l.effects[2].params["c"] - 0.05).abs() < 1e-15);
    assert_eq!(Scenario::default().label().class, LabelClass::Clean);
    let out = Scenario {
        effects: vec![Effect::PosVelForce { a: 10.0 }],
        ..Scenario::default()
    };
    assert_eq!(out.label().class, LabelClass::OutOfLibrary);
}
