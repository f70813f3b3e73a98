//! Mistakes in a model are reported with the file, the line, the column and the key.

use std::path::Path;

use htfid_lang::Model;

const GOOD: &str = r#"states = ["x", "v"]

[parameters]
k = 4.0
c = { value = 0.5, min = 0.0 }

[forcing]
period = 2.0
signals = { f = "cos(pi*t)" }

[flow]
x = "v"
v = "-k*x - c*v + f + u"
"#;

fn error(text: &str) -> String {
    Model::from_document(text, Some(Path::new("m.toml")), &[])
        .unwrap_err()
        .to_string()
}

#[test]
fn the_reference_model_compiles() {
    Model::parse(GOOD).unwrap();
}

#[test]
fn unknown_name_in_an_expression_points_at_its_column() {
    let text = GOOD.replace("-k*x - c*v", "-kk*x - c*v");
    assert_eq!(
        error(&text),
        "m.toml:13:7: flow.v: unknown name `kk` (did you mean `k`?)"
    );
}

#[test]
fn syntax_error_in_an_expression_points_at_its_column() {
    let text = GOOD.replace("-k*x - c*v + f + u", "-k*x - c*v + (f + u");
    let msg = error(&text);
    assert!(msg.starts_with("m.toml:13:"), "{msg}");
    assert!(msg.contains("flow.v"), "{msg}");
}

#[test]
fn unknown_top_level_key_is_named_with_a_suggestion() {
    let text = GOOD.replace("[flow]", "[flwo]");
    assert_eq!(
        error(&text),
        "m.toml:11:1: flwo: unknown key (did you mean `flow`?); allowed here: name, description, \
         states, parameters, input, forcing, definitions, flow, modes, guards, outputs, initial"
    );
}

#[test]
fn a_state_without_equation_is_named() {
    let text = GOOD.replace("x = \"v\"\n", "");
    let msg = error(&text);
    assert!(msg.contains("no equation for state `x`"), "{msg}");
}

#[test]
fn parameter_out_of_bounds_is_rejected() {
    let text = GOOD.replace("value = 0.5, min = 0.0", "value = -0.5, min = 0.0");
    assert_eq!(
        error(&text),
        "m.toml:5:5: parameters.c: value -0.5 is outside its bounds [0, inf]"
    );
}

#[test]
fn time_is_not_allowed_in_the_period() {
    let text = GOOD.replace("period = 2.0", "period = \"2 + t\"");
    assert_eq!(
        error(&text),
        "m.toml:8:15: forcing.period: `t` (time) is not allowed here"
    );
}

#[test]
fn a_signal_that_is_not_periodic_is_rejected() {
    let text = GOOD.replace("cos(pi*t)", "cos(2*t)");
    let msg = error(&text);
    assert!(
        msg.starts_with(
            "m.toml:9:18: forcing.signals.f: is not periodic with the forcing period 2"
        ),
        "{msg}"
    );
}

#[test]
fn guard_errors_name_the_guard() {
    let text = format!("{GOOD}\n[[guards]]\nwhen = \"x\"\ndirection = \"down\"\n");
    assert_eq!(
        error(&text),
        "m.toml:17:13: guards[0].direction: must be \"rising\", \"falling\" or \"either\" (got \"down\")"
    );
    let text = format!("{GOOD}\n[[guards]]\nwhen = \"x\"\nto = \"flight\"\n");
    let msg = error(&text);
    assert!(msg.contains("guards[0].to: no mode `flight`"), "{msg}");
}

#[test]
fn reserved_and_duplicate_names_are_rejected() {
    let text = GOOD.replace("k = 4.0", "t = 4.0");
    assert!(error(&text).contains("`t` is reserved"));
    let text = GOOD.replace("k = 4.0", "x = 4.0");
    assert!(error(&text).contains("`x` is already a state"));
}

#[test]
fn invalid_toml_is_located() {
    let text = GOOD.replace("k = 4.0", "k = = 4.0");
    let msg = error(&text);
    assert!(msg.starts_with("m.toml:4:"), "{msg}");
}
