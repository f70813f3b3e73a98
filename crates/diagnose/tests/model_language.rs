//! Diagnosis of a model-language model on records from the independent truth generator
//! (`htfid-truth`: its own integrator and equations, sharing no code with the models).

use std::path::Path;

use htfid_diagnose::{diagnose_model, ModelCause, ModelFitOptions, TimeSeries};
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

fn record(scenario: &Scenario) -> TimeSeries {
    let r = generate(scenario).unwrap();
    TimeSeries::new(r.t, r.f, r.x, "generator").unwrap()
}

fn options() -> ModelFitOptions {
    ModelFitOptions {
        free: vec!["k".into(), "c".into()],
        ..ModelFitOptions::default()
    }
}

/// 90 s of the paper's protocol from the truth generator with `effects` and parameter
/// `errors`, and 2e-6 m of position noise.
fn protocol(effects: Vec<htfid_truth::Effect>, errors: ParameterErrors) -> Scenario {
    Scenario {
        effects,
        parameter_errors: errors,
        noise: htfid_truth::Noise {
            sigma_x: 2e-6,
            sigma_f: 0.0,
        },
        record_s: 90.0,
        ..Scenario::default()
    }
}

/// The diagnosis of a record of [`protocol`] with one `effect`.
fn diagnose_single(effect: htfid_truth::Effect) -> htfid_diagnose::ModelDiagnosis {
    let scenario = protocol(vec![effect], ParameterErrors::default());
    diagnose_model(&hopper(), &record(&scenario), None, &options()).unwrap()
}

/// Whether the diagnosis names `effect`: as its cause, or among an `ambiguous` answer's rivals.
fn names(d: &htfid_diagnose::ModelDiagnosis, effect: &str) -> bool {
    match &d.cause {
        ModelCause::Effect(e) => e == effect,
        ModelCause::Ambiguous => d.alternatives.iter().any(|a| a == effect),
        _ => false,
    }
}

/// A parameter of the final fit (`extended`), NaN when there is none or it lacks it.
fn final_value(d: &htfid_diagnose::ModelDiagnosis, name: &str) -> f64 {
    d.extended
        .as_ref()
        .and_then(|e| e.parameters.get(name).copied())
        .unwrap_or(f64::NAN)
}

/// The causes' names, strongest first; checks on the way that their shares of the explained
/// error lie in [0, 1], add up to 1 (to rounding) and fall from the first to the last.
fn effects(d: &htfid_diagnose::ModelDiagnosis) -> Vec<&str> {
    let shares: Vec<f64> = d.causes.iter().map(|c| c.gain_share).collect();
    if !shares.is_empty() {
        assert!(
            (shares.iter().sum::<f64>() - 1.0).abs() < 1e-12
                && shares.iter().all(|s| (0.0..=1.0).contains(s))
                && shares.windows(2).all(|w| w[0] >= w[1]),
            "shares {shares:?}"
        );
    }
    d.causes.iter().map(|c| c.effect.as_str()).collect()
}

/// `names` in alphabetical order.
fn sorted(mut names: Vec<&str>) -> Vec<&str> {
    names.sort_unstable();
    names
}

/// Every candidate's name, score, parameters and note, a line each (for failure messages).
fn candidate_table(d: &htfid_diagnose::ModelDiagnosis) -> String {
    d.candidates
        .iter()
        .map(|c| {
            format!(
                "{} {:.4e} {:?} {}",
                c.effect, c.nrmse_validation, c.parameters, c.note
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
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
    assert_eq!(d.cause, ModelCause::ParameterError, "{:?}", d.candidates);
    // Named as a cause, as the candidate `parameter_error` is with nothing refitted.
    assert_eq!(effects(&d), ["parameter_error"]);
    let k = &d.refit_parameters[0];
    assert!((k.fitted / 206.0 - 1.0).abs() < 5e-3, "{k:?}");
    assert!(k.z.abs() > 5.0);
    assert!(d.refit_gain > 0.5, "{}", d.refit_gain);
    let c = &d.refit_parameters[1];
    assert!((c.fitted / 2.0 - 1.0).abs() < 0.02, "{c:?}");
    // The cause holds the moved parameters as refitted, and all of the explained error.
    let cause = &d.causes[0];
    // (Copies of one value: equal to the bit.)
    assert_eq!(
        cause.parameters["k"].to_bits(),
        k.fitted.to_bits(),
        "{cause:?}"
    );
    assert_eq!(cause.gain_share.to_bits(), 1f64.to_bits());
    // No effect: the final model is the refit, its parameters the refit's, no gain beyond.
    assert_eq!(d.parameters["k"].to_bits(), k.fitted.to_bits());
    assert_eq!(d.stderr["c"].to_bits(), c.stderr.to_bits());
    assert_eq!(d.gain.to_bits(), 0f64.to_bits());
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
    assert_eq!(d.cause, ModelCause::None, "{:?}", d.candidates);
    assert!(d.causes.is_empty(), "{:?}", d.causes);
    for p in &d.refit_parameters {
        assert!(
            p.z.abs() < 5.0 && (p.fitted / p.configured - 1.0).abs() < 1e-2,
            "{p:?}"
        );
    }
}

/// A record of the nominal hopper whose recorded force carries white noise (0.007 N, 1 % of
/// the paper chirps' RMS; 2e-6 m on the position) still names nothing: the noise floor holds
/// the refitted model's response to the force's noise, read from the force's spectrum, which
/// must be the generator's level within 10 % (the band's median over a few segments scatters
/// by a few percent).
#[test]
fn a_noisy_input_leaves_the_nominal_hopper_at_none() {
    let scenario = Scenario {
        noise: htfid_truth::Noise {
            sigma_x: 2e-6,
            sigma_f: 0.007,
        },
        record_s: 90.0,
        ..Scenario::default()
    };
    let d = diagnose_model(&hopper(), &record(&scenario), None, &options()).unwrap();
    assert_eq!(d.cause, ModelCause::None, "{}", candidate_table(&d));
    let noise = d.input_noise.expect("the force's noise read");
    assert!((noise.sigma / 0.007 - 1.0).abs() < 0.1, "{noise:?}");
    assert!(
        d.noise_floor >= noise.propagated,
        "{} {noise:?}",
        d.noise_floor
    );
}

/// Effects on the boundary of a model file, on records of the independent truth generator
/// (90 s of the paper's protocol, 2e-6 m of noise): the effect is named (alone, or among the
/// names of an `ambiguous` answer where an input-side and an output-side lag fit equally well)
/// with its parameter within 10 % of the truth, and k and c stay within 1 % of the configured
/// (true) values. 10 % is the accuracy the diagnosis promises for a single effect; these
/// effects change the output by 50 to 300 times the noise, so their parameters are determined
/// far more closely than that.
#[test]
fn effects_on_the_boundary_of_a_model_file_are_named_with_their_parameters() {
    use htfid_truth::Effect;
    let cases = [
        (
            Effect::SensorLag { tau_s: 0.01 },
            "sensor_lag",
            "tau_s",
            0.01,
        ),
        (
            Effect::InputDelay { delay: 0.02 },
            "input_delay",
            "delay",
            0.02,
        ),
        (
            Effect::InputOffset { offset: 0.12 },
            "input_offset",
            "input_offset",
            0.12,
        ),
    ];
    for (effect, name, parameter, truth) in cases {
        let d = diagnose_single(effect);
        let named = names(&d, name);
        let table = candidate_table(&d);
        assert!(
            named,
            "{name}: cause {} ({:?}); refit {:.4e}\n{}",
            d.cause.name(),
            d.alternatives,
            d.refitted.validation(),
            table
        );
        let c = d
            .candidates
            .iter()
            .find(|c| c.effect == name)
            .expect("every effect is tried");
        assert!(c.significant, "{name}: {}", c.note);
        let fitted = c.parameters[parameter];
        assert!(
            (fitted / truth - 1.0).abs() < 0.1,
            "{name}: {parameter} = {fitted}, true {truth}"
        );
        for (p, configured) in [("k", 200.0), ("c", 2.0)] {
            let v = c.parameters[p];
            assert!((v / configured - 1.0).abs() < 0.01, "{name}: {p} = {v}");
        }
    }
}

/// Effects inside the equations of a model file, proposed by the library at the sites the
/// hopper file offers (drag and a stiffness law on `v' `, damping in each mode, the moved
/// switching surface `v = shift`), on records of the independent truth generator (90 s of
/// the paper's protocol, 2e-6 m of noise). The terms are per unit mass and `m = 1`, so each
/// fitted parameter is the truth's own. Each effect is named (alone, or among the names of an
/// `ambiguous` answer) with its parameter within 10 % of the truth: the accuracy the diagnosis
/// promises for a single effect.
#[test]
fn effects_inside_the_equations_of_a_model_file_are_named_with_their_parameters() {
    use htfid_truth::Effect;
    let cases = [
        (
            Effect::QuadraticDrag { c2: 20.0 },
            "quadratic_drag(v)",
            "drag_v",
            20.0,
        ),
        (
            Effect::FlightDamping { c_f: 1.0 },
            "mode_damping(v, free)",
            "damping_v_free",
            1.0,
        ),
        (
            Effect::SwitchThreshold { v_th: 0.02 },
            "guard_shift(v)",
            "shift_1",
            0.02,
        ),
        (
            Effect::SwitchThreshold { v_th: -0.02 },
            "guard_shift(v)",
            "shift_1",
            -0.02,
        ),
    ];
    let mut failures = Vec::new();
    for (effect, name, parameter, truth) in cases {
        let d = diagnose_single(effect);
        let named = names(&d, name);
        let table = candidate_table(&d);
        let fitted = d
            .candidates
            .iter()
            .find(|c| c.effect == name)
            .map_or(f64::NAN, |c| c.parameters[parameter]);
        if !named || (fitted / truth - 1.0).abs() >= 0.1 {
            failures.push(format!(
                "{name}: cause {} ({:?}), {parameter} = {fitted} (true {truth}); refit {:.4e}\n{}",
                d.cause.name(),
                d.alternatives,
                d.refitted.validation(),
                table
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// The library's discontinuous effects on the same records: Coulomb friction of 0.1 N (the
/// truth sticks at the switch; the library's friction is smoothed over a thousandth of the
/// velocity's spread) and a contact spring of 5000 N/m below 0.147 m (the truth's own contact,
/// located exactly by its integrator). Each is named with its parameters: the friction and the
/// contact's stiffness within 10 % of the truth (the promise for a single effect), the
/// contact's position within 0.1 mm, 2.5 % of the motion's spread (4 mm RMS): a position is
/// judged against how far the motion reaches, not against its distance from zero.
#[test]
fn friction_and_a_hard_stop_in_a_model_file_are_named_with_their_parameters() {
    use htfid_truth::Effect;
    let mut failures = Vec::new();
    let d = diagnose_single(Effect::CoulombFriction { mu: 0.1 });
    let fitted = d
        .candidates
        .iter()
        .find(|c| c.effect == "coulomb_friction(v)")
        .map_or(f64::NAN, |c| c.parameters["friction_v"]);
    eprintln!(
        "friction: cause {} friction_v {fitted}\n{}",
        d.cause.name(),
        candidate_table(&d)
    );
    if !names(&d, "coulomb_friction(v)") || (fitted / 0.1 - 1.0).abs() >= 0.1 {
        failures.push(format!(
            "friction: cause {} ({:?}), friction_v = {fitted} (true 0.1)\n{}",
            d.cause.name(),
            d.alternatives,
            candidate_table(&d)
        ));
    }
    let d = diagnose_single(Effect::HardStop {
        k_stop: 5000.0,
        x_stop: 0.147,
    });
    let stop = d
        .candidates
        .iter()
        .find(|c| c.effect == "hard_stop(x, below)");
    let (floor, k) = stop.map_or((f64::NAN, f64::NAN), |c| {
        (c.parameters["floor_x"], c.parameters["k_floor_x"])
    });
    eprintln!(
        "stop: cause {} floor {floor} k {k}\n{}",
        d.cause.name(),
        candidate_table(&d)
    );
    if !names(&d, "hard_stop(x, below)")
        || (k / 5000.0 - 1.0).abs() >= 0.1
        || (floor - 0.147).abs() >= 1e-4
    {
        failures.push(format!(
            "hard stop: cause {} ({:?}), floor_x = {floor}, k_floor_x = {k} (true 0.147, 5000)\n{}",
            d.cause.name(),
            d.alternatives,
            candidate_table(&d)
        ));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// The record of a cubic spring about the rest length, `-k3 (x - x0)^3` with `k3` = -2000
/// N/m^3 (the catalogue's large cubic), of [`protocol`].
fn large_cubic() -> TimeSeries {
    record(&protocol(
        vec![htfid_truth::Effect::CubicStiffness { k3: -2000.0 }],
        ParameterErrors::default(),
    ))
}

/// On the hopper the stiffness law sits at the rest point of the model's own spring, `x0`,
/// where a real spring's nonlinearity is, so a cubic spring (the catalogue's large one) is
/// named alone, with the truth's coefficient: `k3_x` within 10 % of -2000 (the promise for
/// a single effect) and `k` within 0.5 % of 200, nothing beside them. About the motion's mean
/// the cubic carries a constant force (`k3 d^3`, `d` = -0.05 m from the mean to the rest
/// length) that a law about the mean leaves to a sensor's offset.
#[test]
fn a_cubic_spring_is_named_alone_with_its_coefficient_about_the_rest_point() {
    let d = diagnose_model(&hopper(), &large_cubic(), None, &options()).unwrap();
    let (k3, k) = (final_value(&d, "k3_x"), final_value(&d, "k"));
    eprintln!("causes {:?}: k3_x {k3}, k {k}", d.causes);
    assert!(
        effects(&d) == ["nonlinear_stiffness(x)"]
            && (k3 / -2000.0 - 1.0).abs() < 0.1
            && (k / 200.0 - 1.0).abs() < 5e-3,
        "causes {:?}, k3_x {k3}, k {k}\n{}",
        d.causes,
        candidate_table(&d)
    );
}

/// A cubic spring beside a spring 3 % softer than configured (the catalogue's `124` on
/// [`protocol`]): about the rest point the law's slope on the motion is its own, so the
/// refitted `k` beside it is the model's error and is named: the law and `parameter_error`,
/// `k3_x` within 10 % of -2000 and `k` within 0.5 % of 193.4.
#[test]
fn a_stiffness_error_beside_a_cubic_spring_is_named_with_it() {
    let scenario = protocol(
        vec![htfid_truth::Effect::CubicStiffness { k3: -2000.0 }],
        ParameterErrors {
            k: -0.033,
            ..ParameterErrors::default()
        },
    );
    let d = diagnose_model(&hopper(), &record(&scenario), None, &options()).unwrap();
    let (k3, k) = (final_value(&d, "k3_x"), final_value(&d, "k"));
    eprintln!("causes {:?}: k3_x {k3}, k {k}", d.causes);
    assert!(
        sorted(effects(&d)) == ["nonlinear_stiffness(x)", "parameter_error"]
            && (k3 / -2000.0 - 1.0).abs() < 0.1
            && (k / (200.0 * 0.967) - 1.0).abs() < 5e-3,
        "causes {:?}, k3_x {k3}, k {k}, beside {:?}\n{}",
        d.causes,
        d.parameters_beside,
        candidate_table(&d)
    );
}

/// A model whose own spring is not linear in the position (here the hopper with a quadratic
/// term of zero size) has no rest point to read, and the stiffness law is written about the
/// motion's mean. On the same large cubic the law is named, and the refitted `k`, which then
/// takes the law's linear part about the mean (`3 k3 d^2`: 7 %), is excused, not named a
/// parameter error. Only that rule is checked: about the mean the law leaves the cubic's
/// constant force to a sensor's offset and gain, named beside it.
#[test]
fn beside_a_stiffness_law_its_linear_part_is_not_a_parameter_error() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/hopper.toml");
    let text = std::fs::read_to_string(path)
        .unwrap()
        .replace(
            "spring = \"-k * (x - x0)\"",
            "spring = \"-k * (x - x0) - kq * (x - x0)^2\"",
        )
        .replace(
            "x0 = { value = 0.2,   unit = \"m\" }",
            "x0 = { value = 0.2,   unit = \"m\" }\nkq = { value = 0.0, unit = \"N/m^2\" }",
        );
    assert!(text.contains("kq * (x - x0)^2") && text.contains("kq = {"));
    let model = Model::parse(&text)
        .unwrap()
        .with_parameters(&[("a", 0.0)])
        .unwrap();
    let diagnosis = diagnose_model(&model, &large_cubic(), None, &options()).unwrap();
    let beside = diagnosis.parameters_beside.as_ref();
    eprintln!(
        "cause {} causes {:?}; beside {beside:?}",
        diagnosis.cause.name(),
        diagnosis.causes
    );
    assert!(
        diagnosis
            .causes
            .iter()
            .any(|c| c.effect == "nonlinear_stiffness(x)")
            && !effects(&diagnosis).contains(&"parameter_error")
            && beside.is_some_and(|p| {
                p.moved.is_empty()
                    && p.excused
                        .iter()
                        .any(|c| c.name == "k" && (c.fitted / 200.0 - 1.0).abs() > 0.03)
            }),
        "causes {:?}, beside {beside:?}",
        diagnosis.causes
    );
}

/// An actuator lag of 20.3 ms beside a constant force of -0.122 N (the catalogue's `005` on
/// this protocol). Alone, a sensor lag fits the record a little better than the actuator lag
/// (a near tie of look-alikes), and beside it the input offset passes too, short of the noise
/// floor. Both lags are tried first in the second round, so the pair that reaches the floor is
/// named: the actuator lag and the input offset, each within 10 % of the truth.
#[test]
fn an_actuator_lag_beside_a_constant_force_is_named_as_such() {
    use htfid_truth::Effect;
    let (tau, offset) = (0.0203, -0.122);
    let scenario = protocol(
        vec![Effect::ActuatorLag { tau }, Effect::InputOffset { offset }],
        ParameterErrors::default(),
    );
    let d = diagnose_model(&hopper(), &record(&scenario), None, &options()).unwrap();
    let fitted = d.extended.as_ref().map(|e| &e.parameters);
    let value = |k: &str| fitted.and_then(|p| p.get(k)).copied().unwrap_or(f64::NAN);
    let (tau_fit, offset_fit) = (value("tau"), value("input_offset"));
    let pairs: Vec<String> = d
        .pairs
        .iter()
        .map(|c| format!("{} {:.4e}", c.effect, c.nrmse_validation))
        .collect();
    eprintln!(
        "cause {} causes {:?}: tau {tau_fit} ({tau}), input_offset {offset_fit} ({offset})\n{}",
        d.cause.name(),
        d.causes,
        pairs.join("\n")
    );
    assert!(
        sorted(effects(&d)) == sorted(vec!["actuator_lag", "input_offset"])
            && (tau_fit / tau - 1.0).abs() < 0.1
            && (offset_fit / offset - 1.0).abs() < 0.1,
        "cause {} causes {:?}: tau = {tau_fit} (true {tau}), input_offset = {offset_fit} (true \
         {offset})\npairs:\n{}",
        d.cause.name(),
        d.causes,
        pairs.join("\n")
    );
}

/// Damping in flight (1.03 N s/m) beside a switch moved to 0.0309 m/s (the catalogue's `009`
/// on this protocol). Alone, quadratic drag fits best: it stands in for both, and beside it
/// neither passes, while the damping in flight alone is the runner-up and the moved switch
/// alone does nothing (the refitted `c` takes its part). The runner-up is tried as a first
/// effect too, and beside it the switch reaches the noise floor: both are named, each within
/// 2 % of the truth, with no drag.
#[test]
fn damping_in_flight_beside_a_moved_switch_is_named_not_drag() {
    use htfid_truth::Effect;
    let (v_th, c_f) = (0.030894, 1.0298);
    let scenario = protocol(
        vec![
            Effect::SwitchThreshold { v_th },
            Effect::FlightDamping { c_f },
        ],
        ParameterErrors::default(),
    );
    let d = diagnose_model(&hopper(), &record(&scenario), None, &options()).unwrap();
    let (shift, damping) = (
        final_value(&d, "shift_1"),
        final_value(&d, "damping_v_free"),
    );
    eprintln!(
        "cause {} causes {:?}: shift_1 {shift} ({v_th}), damping_v_free {damping} ({c_f})",
        d.cause.name(),
        d.causes,
    );
    assert!(
        sorted(effects(&d)) == sorted(vec!["mode_damping(v, free)", "guard_shift(v)"])
            && (shift / v_th - 1.0).abs() < 0.02
            && (damping / c_f - 1.0).abs() < 0.02,
        "cause {} causes {:?}: shift_1 = {shift} (true {v_th}), damping_v_free = {damping} \
         (true {c_f})",
        d.cause.name(),
        d.causes,
    );
}

/// A damper 11.5 % stronger than configured beside a switch moved to -0.0346 m/s (the
/// catalogue's `029` on this protocol). The moved switch is named, and beside it the
/// parameter error: `c` as fitted with the switch is 2.2305 (the truth's 2 x 1.1152), and set
/// back to its configured 2 it costs most of the held-out accuracy. In the first round the
/// switch's fit alone stalled; beside the stiffness law it was found, and the backward pass,
/// refitting the switch alone from that fit, drops the law, which then does nothing.
#[test]
fn a_damping_error_beside_a_moved_switch_is_named_with_it() {
    use htfid_truth::Effect;
    let (v_th, c_error) = (-0.03457, 0.11524);
    let scenario = protocol(
        vec![Effect::SwitchThreshold { v_th }],
        ParameterErrors {
            c: c_error,
            ..ParameterErrors::default()
        },
    );
    let d = diagnose_model(&hopper(), &record(&scenario), None, &options()).unwrap();
    let fitted = d.extended.as_ref().map(|e| &e.parameters);
    let value = |k: &str| fitted.and_then(|p| p.get(k)).copied().unwrap_or(f64::NAN);
    let (shift, c) = (value("shift_1"), value("c"));
    let c_true = 2.0 * (1.0 + c_error);
    let beside = d.parameters_beside.as_ref();
    eprintln!(
        "cause {} causes {:?}: shift_1 {shift} ({v_th}), c {c} ({c_true}); beside {beside:?}\n{}",
        d.cause.name(),
        d.causes,
        candidate_table(&d)
    );
    assert!(
        sorted(effects(&d)) == sorted(vec!["guard_shift(v)", "parameter_error"])
            && (shift / v_th - 1.0).abs() < 0.1
            && (c / c_true - 1.0).abs() < 0.01
            && beside.is_some_and(|p| p.named && p.moved.iter().any(|m| m.name == "c")),
        "cause {} causes {:?}: shift_1 = {shift} (true {v_th}), c = {c} (true {c_true}); \
         beside {beside:?}\n{}",
        d.cause.name(),
        d.causes,
        candidate_table(&d)
    );
}

/// A model parameter that has the name of a boundary effect's parameter (here the hopper's
/// damping renamed `tau`, as the actuator lag's time constant is called) keeps its name; the
/// effect's parameter takes the next free one, `tau_2`. Both are fitted and reported apart:
/// on a record with a 10 ms actuator lag, the lag is named with `tau_2` within 10 % of the
/// truth and the damping `tau` within 1 % of its configured 2 N s/m.
#[test]
fn an_effect_parameter_named_like_a_model_parameter_takes_the_next_free_name() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/hopper.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let renamed = text
        .replace("c  = { value = 2.0", "tau = { value = 2.0")
        .replace("- c*v", "- tau*v");
    assert_ne!(renamed, text);
    let model = Model::parse(&renamed)
        .unwrap()
        .with_parameters(&[("a", 0.0)])
        .unwrap();
    let scenario = Scenario {
        effects: vec![htfid_truth::Effect::ActuatorLag { tau: 0.01 }],
        noise: htfid_truth::Noise {
            sigma_x: 2e-6,
            sigma_f: 0.0,
        },
        record_s: 90.0,
        ..Scenario::default()
    };
    let opts = ModelFitOptions {
        free: vec!["k".into(), "tau".into()],
        ..ModelFitOptions::default()
    };
    let d = diagnose_model(&model, &record(&scenario), None, &opts).unwrap();
    assert!(names(&d, "actuator_lag"), "{}", candidate_table(&d));
    let c = d
        .candidates
        .iter()
        .find(|c| c.effect == "actuator_lag")
        .expect("every effect is tried");
    let lag = c.parameters["tau_2"];
    let damping = c.parameters["tau"];
    assert!((lag / 0.01 - 1.0).abs() < 0.1, "lag {lag}");
    assert!((damping / 2.0 - 1.0).abs() < 0.01, "damping {damping}");
}

/// A record whose output was recorded with its sign flipped, or in centimetres against a model
/// in metres, is refused before any fit, naming the check: a refit would only hide either
/// behind absurd parameters (and ran for minutes on the flipped one). The same record as
/// recorded, and ones whose configured stiffness is a quarter or twice the truth's (a refit's
/// business; the quarter moves 13 times as much), are diagnosed.
#[test]
fn a_flipped_sign_or_a_unit_slip_is_refused_before_any_fit() {
    let scenario = Scenario {
        noise: htfid_truth::Noise {
            sigma_x: 2e-6,
            sigma_f: 0.0,
        },
        record_s: 60.0,
        ..Scenario::default()
    };
    let r = generate(&scenario).unwrap();
    let edited = |f: fn(f64) -> f64| {
        let x: Vec<f64> = r.x.iter().map(|&v| f(v)).collect();
        TimeSeries::new(r.t.clone(), r.f.clone(), x, "generator").unwrap()
    };
    for (rec, check) in [(edited(|v| -v), "sign:"), (edited(|v| 1e2 * v), "units:")] {
        match diagnose_model(&hopper(), &rec, None, &options()) {
            Err(htfid_diagnose::DiagnoseError::ModelMismatch { reasons }) => {
                assert!(reasons.iter().any(|r| r.starts_with(check)), "{reasons:?}");
            }
            other => panic!(
                "{check} expected a refusal, got {:?}",
                other.map(|d| d.cause)
            ),
        }
    }
    assert!(diagnose_model(&hopper(), &edited(|v| v), None, &options()).is_ok());
    for k in [50.0, 400.0] {
        let off = hopper().with_parameters(&[("k", k)]).unwrap();
        let d = diagnose_model(&off, &edited(|v| v), None, &options());
        assert!(d.is_ok(), "k = {k}: {:?}", d.map(|_| ()));
    }
}

/// Nothing refitted with every candidate, `m`, `k` and `c` the candidate `parameter_error`.
fn nothing_refitted() -> ModelFitOptions {
    ModelFitOptions {
        parameter_error: vec!["m".into(), "k".into(), "c".into()],
        ..ModelFitOptions::default()
    }
}

/// With nothing refitted, a spring 3 % stiffer than configured (truth 206 N/m) is the
/// candidate `parameter_error`, chosen against every library effect: its fit holds `k`
/// within 0.5 % of the truth (the refit's own test above asks the same), and `m` and `c`
/// within 1 % of their configured 1 and 2 (the record's noise is 2e-6 m against a motion of
/// centimetres; 1 % leaves room for a trade between them over 90 s).
#[test]
fn nothing_refitted_a_stiffer_spring_is_the_candidate_parameter_error() {
    let scenario = protocol(
        Vec::new(),
        ParameterErrors {
            k: 0.03,
            ..ParameterErrors::default()
        },
    );
    let d = diagnose_model(&hopper(), &record(&scenario), None, &nothing_refitted()).unwrap();
    let (m, k, c) = (
        final_value(&d, "m"),
        final_value(&d, "k"),
        final_value(&d, "c"),
    );
    assert!(
        d.cause == ModelCause::ParameterError
            && effects(&d) == ["parameter_error"]
            && (k / 206.0 - 1.0).abs() < 5e-3
            && (m - 1.0).abs() < 0.01
            && (c / 2.0 - 1.0).abs() < 0.01,
        "cause {} causes {:?}: m {m}, k {k}, c {c}\n{}",
        d.cause.name(),
        d.causes,
        candidate_table(&d)
    );
}

/// With nothing refitted, the nominal hopper's record names nothing: the candidate
/// `parameter_error` is tried (it is in `candidates`) and does not pass.
#[test]
fn nothing_refitted_the_nominal_hopper_gives_none() {
    let scenario = protocol(Vec::new(), ParameterErrors::default());
    let d = diagnose_model(&hopper(), &record(&scenario), None, &nothing_refitted()).unwrap();
    let tried = d.candidates.iter().find(|c| c.effect == "parameter_error");
    assert!(
        d.cause == ModelCause::None && tried.is_some_and(|c| !c.significant),
        "cause {} causes {:?}\n{}",
        d.cause.name(),
        d.causes,
        candidate_table(&d)
    );
}

/// The candidate's parameters must be the model's, not free, each once: each mistake is
/// refused before any fit.
#[test]
fn a_parameter_error_list_must_name_held_parameters_once() {
    let scenario = protocol(Vec::new(), ParameterErrors::default());
    let rec = record(&scenario);
    for (list, free) in [
        (vec!["spring"], vec![]),
        (vec!["k"], vec!["k"]),
        (vec!["m", "m"], vec![]),
    ] {
        let opts = ModelFitOptions {
            parameter_error: list.iter().map(|s| s.to_string()).collect(),
            free: free.iter().map(|s| s.to_string()).collect(),
            ..ModelFitOptions::default()
        };
        let e = diagnose_model(&hopper(), &rec, None, &opts).unwrap_err();
        assert!(
            matches!(
                e,
                htfid_diagnose::DiagnoseError::InvalidParameterName {
                    option: "parameter_error",
                    ..
                }
            ),
            "{list:?} beside free {free:?}: {e}"
        );
    }
}

/// With nothing refitted, a damper 10 % stronger than configured (truth 2.2 N s/m) is the
/// candidate `parameter_error`, not extra damping in the mode where the damper acts: that term
/// only re-expresses a change of `c` (its derivatives are `c`'s times `m`), fits exactly as
/// well with one parameter instead of three, and is marked so. `c` within 0.5 % of the truth.
#[test]
fn nothing_refitted_a_stronger_damper_is_a_parameter_error_not_damping_in_its_mode() {
    let scenario = protocol(
        Vec::new(),
        ParameterErrors {
            c: 0.1,
            ..ParameterErrors::default()
        },
    );
    let d = diagnose_model(&hopper(), &record(&scenario), None, &nothing_refitted()).unwrap();
    let c = final_value(&d, "c");
    let alias = d
        .candidates
        .iter()
        .find(|c| c.effect == "mode_damping(v, damped)");
    assert!(
        d.cause == ModelCause::ParameterError
            && effects(&d) == ["parameter_error"]
            && (c / 2.2 - 1.0).abs() < 5e-3
            && alias.is_some_and(|a| !a.significant && a.note.contains("re-expresses")),
        "cause {} causes {:?}: c {c}\n{}",
        d.cause.name(),
        d.causes,
        candidate_table(&d)
    );
}

/// Where the equations miss the data, against the force the generator added: a record with
/// Coulomb friction `mu` = 0.1 N on the 1 kg mass, diagnosed with nothing refitted (the model
/// as configured is the generator's but for the friction). The refitted model's binned
/// residual acceleration against velocity is then `-mu sign(v) / m`: each bin of speed above a
/// third of the largest within 10 % of `mu` plus three standard errors of its mean (the 10 %
/// for the smoothing, which spreads the step at zero speed over its window, and the bins
/// nearest the third reach into it). The final model, with the friction named, leaves every
/// such bin within 5 % of `mu` plus three standard errors of zero. The position has no pair
/// but the hopper's `(x, v)`, so there is one pair and its output is `x`.
#[test]
fn the_binned_residual_acceleration_shows_the_missing_friction_as_its_step() {
    let mu = 0.1;
    let scenario = protocol(
        vec![htfid_truth::Effect::CoulombFriction { mu }],
        ParameterErrors::default(),
    );
    let opts = ModelFitOptions {
        free: Vec::new(),
        ..ModelFitOptions::default()
    };
    let d = diagnose_model(&hopper(), &record(&scenario), None, &opts).unwrap();
    assert_eq!(d.residual_bins.len(), 1);
    let pair = &d.residual_bins[0];
    assert_eq!(
        (
            pair.output.as_str(),
            pair.position.as_str(),
            pair.velocity.as_str()
        ),
        ("x", "x", "v")
    );
    let top = pair
        .nominal
        .by_velocity
        .iter()
        .map(|b| b.centre.abs())
        .fold(0.0, f64::max);
    let mut checked = 0;
    for b in pair
        .nominal
        .by_velocity
        .iter()
        .filter(|b| b.centre.abs() > top / 3.0)
    {
        let want = -mu * b.centre.signum();
        assert!(
            (b.mean - want).abs() < 0.1 * mu + 3.0 * b.stderr,
            "bin at v = {}: mean {} against {want} (stderr {})",
            b.centre,
            b.mean,
            b.stderr
        );
        checked += 1;
    }
    assert!(checked >= 8, "only {checked} bins of speed");
    assert!(names(&d, "coulomb_friction(v)"), "{}", candidate_table(&d));
    let ext = pair.extended.as_ref().expect("the final model's bins");
    for b in ext
        .by_velocity
        .iter()
        .filter(|b| b.centre.abs() > top / 3.0)
    {
        assert!(
            b.mean.abs() < 0.05 * mu + 3.0 * b.stderr,
            "with friction, bin at v = {}: mean {} (stderr {})",
            b.centre,
            b.mean,
            b.stderr
        );
    }
}

/// A separate held-out record shorter than the estimation record: the check that the
/// configured model describes the data reads the estimation record's own simulation (it read
/// the held-out one's, past whose end it indexed). The nominal hopper's record, split 70/30
/// into two records, names nothing.
#[test]
fn a_shorter_held_out_record_is_diagnosed() {
    let scenario = Scenario {
        record_s: 90.0,
        ..Scenario::default()
    };
    let r = generate(&scenario).unwrap();
    let cut = r.t.len() * 7 / 10;
    let part = |range: std::ops::Range<usize>, name: &str| {
        TimeSeries::new(
            r.t[range.clone()].to_vec(),
            r.f[range.clone()].to_vec(),
            r.x[range].to_vec(),
            name,
        )
        .unwrap()
    };
    let est = part(0..cut, "estimation");
    let val = part(cut..r.t.len(), "validation");
    assert!(val.len() < est.len());
    let d = diagnose_model(&hopper(), &est, Some(&val), &options()).unwrap();
    assert_eq!(d.cause, ModelCause::None, "{}", candidate_table(&d));
    // The held-out simulations are the validation record's.
    assert_eq!(d.simulated[0].len(), val.len());
}
