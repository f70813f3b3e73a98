//! The diagnosis (`diagnose_model` on `models/hopper.toml`, `k` and `c` free) on the core
//! cells of the independent truth generator's catalogue (`htfid-truth`): a measurement of how
//! the diagnosis does on data from equations and an integrator it shares no code with.
//!
//! Ignored (about 20 minutes on 2 cores, the records diagnosed side by side; in `just test`);
//! run with
//! `cargo test --release -p htfid-diagnose --test model_language_sweep -- --ignored --nocapture`
//! (`HTFID_MODEL_SWEEP_N` records, the catalogue's core cells by default; from record
//! `HTFID_MODEL_SWEEP_FROM`, 0 by default; `HTFID_MODEL_SWEEP_PROTOCOL=configured` for the
//! protocol with nothing refitted and `m`, `k`, `c` the candidate
//! `parameter_error`, with floors of its own). It prints one line
//! per record and a score per group, and holds the floors measured when it was written.
//!
//! The generator names its effects in its own words; the library's terms sit at the sites the
//! file offers (drag, Coulomb friction, a stiffness law and a hard stop on either side on `v'`,
//! damping per mode, the moved switching surface) and on its boundary (input offset, delay and
//! lag; sensor offset and gain, sensor lag). Asymmetric friction is its Coulomb friction beside
//! a constant force (the same force law). The generator's own out-of-library effects are out of
//! its library too. The judgement:
//! - clean: `none`;
//! - effects in its library: each named (as a cause, or among an `ambiguous` answer's names),
//!   by the engine's name for it or an equivalent on this protocol (a constant shift of the
//!   position is an input offset, a sensor offset or a parameter error alike);
//! - anything else: not claimed with confidence (`unexplained` or `ambiguous`).

use std::path::Path;

use htfid_diagnose::{diagnose_model, ModelCause, ModelDiagnosis, ModelFitOptions, TimeSeries};
use htfid_lang::Model;
use htfid_truth::{catalogue, generate, EffectLabel, LabelClass, Scenario};
use rayon::prelude::*;

fn hopper() -> Model {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/hopper.toml");
    Model::from_file(&path)
        .unwrap()
        .with_parameters(&[("a", 0.0)])
        .unwrap()
}

/// The engine's acceptable names for a labelled effect of a record labelled `all`, or `None`
/// when the effect is outside the model file's library.
fn accepted(e: &EffectLabel) -> Option<Vec<&'static str>> {
    let shift = ["input_offset", "sensor_offset_gain", "parameter_error"];
    Some(match e.name.as_str() {
        "cubic_stiffness" => vec!["nonlinear_stiffness"],
        "flight_damping" => vec!["mode_damping(v, free)"],
        "quadratic_drag" => vec!["quadratic_drag"],
        "actuator_lag" => vec!["actuator_lag"],
        "input_delay" => vec!["input_delay"],
        "switch_threshold" => vec!["guard_shift"],
        "coulomb_friction" | "asymmetric_friction" => vec!["coulomb_friction"],
        "hard_stop" => vec!["hard_stop"],
        "sensor_lag" => vec!["sensor_lag"],
        "input_offset" | "sensor_offset_gain" => shift.to_vec(),
        "parameter_error" => {
            // Errors of k and c are the refit's; of g, x0 (a shift) or m (with k and c free,
            // a scaled force) its boundary's or the refit's.
            shift.to_vec()
        }
        _ => return None,
    })
}

/// Every name the diagnosis gives: its causes, its cause, an `ambiguous` answer's names.
fn names_of(d: &ModelDiagnosis) -> Vec<String> {
    let mut v: Vec<String> = d.causes.iter().map(|c| c.effect.clone()).collect();
    match &d.cause {
        ModelCause::Effect(e) => v.push(e.clone()),
        ModelCause::ParameterError => v.push("parameter_error".into()),
        _ => {}
    }
    v.extend(d.alternatives.iter().cloned());
    v
}

fn judge(s: &Scenario, d: &ModelDiagnosis) -> Result<(), String> {
    let label = s.label();
    let named = names_of(d);
    let cause = d.cause.name();
    let unsure = matches!(d.cause, ModelCause::Unexplained | ModelCause::Ambiguous);
    if label.class == LabelClass::Clean {
        return (cause == "none")
            .then_some(())
            .ok_or_else(|| format!("clean record named {cause}"));
    }
    let wanted: Option<Vec<Vec<&str>>> = if label.class == LabelClass::InLibrary {
        label.effects.iter().map(accepted).collect()
    } else {
        None
    };
    match wanted {
        Some(wanted) => {
            let missing: Vec<String> = wanted
                .iter()
                .zip(&label.effects)
                .filter(|(names, _)| !names.iter().any(|w| named.iter().any(|n| n.starts_with(w))))
                .map(|(_, e)| e.name.clone())
                .collect();
            if missing.is_empty() {
                Ok(())
            } else {
                Err(format!("missed {missing:?}: cause {cause} names {named:?}"))
            }
        }
        None if unsure => Ok(()),
        None => Err(format!("claimed {cause} (names {named:?}) with confidence")),
    }
}

fn group(s: &Scenario) -> &'static str {
    let label = s.label();
    match label.class {
        LabelClass::Clean => "clean",
        LabelClass::InLibrary if label.effects.iter().all(|e| accepted(e).is_some()) => {
            if label.effects.len() == 1 {
                "single, in its library"
            } else {
                "pair, in its library"
            }
        }
        _ => "outside its library",
    }
}

#[test]
#[ignore = "minutes: a measurement over the independent generator's catalogue"]
fn the_model_file_diagnosis_on_the_independent_catalogue() {
    let n = std::env::var("HTFID_MODEL_SWEEP_N")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(htfid_truth::core_size);
    // `HTFID_MODEL_SWEEP_FROM` skips the records before it (the random pairs after the core
    // cells: `HTFID_MODEL_SWEEP_N=200 HTFID_MODEL_SWEEP_FROM=77`).
    let from: usize = std::env::var("HTFID_MODEL_SWEEP_FROM")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    // `HTFID_MODEL_SWEEP_PROTOCOL=configured`: nothing
    // refitted with every candidate and an error of `m`, `k` or `c` a candidate effect of its
    // own (`parameter_error`); by default `k` and `c` are refitted with every candidate.
    let configured = std::env::var("HTFID_MODEL_SWEEP_PROTOCOL").is_ok_and(|p| p == "configured");
    let options = if configured {
        ModelFitOptions {
            parameter_error: vec!["m".into(), "k".into(), "c".into()],
            ..ModelFitOptions::default()
        }
    } else {
        ModelFitOptions {
            free: vec!["k".into(), "c".into()],
            ..ModelFitOptions::default()
        }
    };
    let model = hopper();
    let scenarios: Vec<Scenario> = catalogue(2026, n).into_iter().skip(from).collect();
    // The records are diagnosed side by side, each on its own (every diagnosis is
    // deterministic), and each line is printed as its record ends.
    let verdicts: Vec<Result<(), String>> = scenarios
        .par_iter()
        .map(|s| {
            let r = generate(s).expect("the generator runs");
            let record = TimeSeries::new(r.t, r.f, r.x, "generator").expect("a record");
            let verdict = diagnose_model(&model, &record, None, &options)
                .map_err(|e| format!("diagnose: {e}"))
                .and_then(|d| judge(s, &d));
            eprintln!(
                "{:<40} {:<24} {}",
                s.name,
                group(s),
                verdict
                    .as_ref()
                    .err()
                    .map_or("ok".into(), |e| format!("FAIL {e}"))
            );
            verdict
        })
        .collect();
    let mut scores: std::collections::BTreeMap<&str, (usize, usize)> = Default::default();
    for (s, verdict) in scenarios.iter().zip(&verdicts) {
        let entry = scores.entry(group(s)).or_default();
        entry.1 += 1;
        if verdict.is_ok() {
            entry.0 += 1;
        }
    }
    for (g, (ok, all)) in &scores {
        eprintln!("{g}: {ok} of {all}");
    }
    let total: usize = scores.values().map(|s| s.1).sum();
    assert!(total > 0, "no record was diagnosed");
    if n == htfid_truth::core_size() && from == 0 {
        // The floors measured on the core cells at seed 2026 (`FLOORS`, or
        // `FLOORS_CONFIGURED` for the protocol with nothing refitted): a change that loses a
        // record in any group fails here.
        let floors = if configured {
            FLOORS_CONFIGURED
        } else {
            FLOORS
        };
        for (g, floor) in floors {
            let (ok, all) = scores.get(g).copied().unwrap_or_default();
            assert!(
                ok >= floor,
                "{g}: {ok} of {all}, below the measured {floor}"
            );
        }
    }
}

/// Records judged right per group on the core cells (seed 2026), as measured with the terms'
/// fits started from the better of zero and the equation error's estimate (2026-11-29,
/// afternoon): 75 of 77, the same records (two halves side by side, other diagnoses beside
/// them). Before it, with the runner-up of the first round tried as a first effect too: 75 of 77
/// (the records in two halves side by side on the project's 2-core machine, 1363 s and 590 s).
/// Before it, with the stiffness law about the rest point of the model's own spring: 74 of 77
/// (10, 47, 7, 10; 3228 s, the pairs' sweep and the workspace's tests beside it). Before that,
/// with the second round's wider first effects, the backward pass's refits and the parameter
/// error beside effects (2026-11-28, night): 72 of 77 (10, 46, 6, 10); before those, 71 (10,
/// 46, 5, 10).
const FLOORS: [(&str, usize); 4] = [
    ("clean", 10),
    ("single, in its library", 47),
    ("pair, in its library", 8),
    ("outside its library", 10),
];

/// Records judged right per group on the core cells (seed 2026) with nothing refitted and `m`,
/// `k`, `c` the candidate `parameter_error` (`HTFID_MODEL_SWEEP_PROTOCOL=configured`), as
/// measured with the terms' fits started from the better of zero and the equation error's
/// estimate (2026-11-29, afternoon): 75 of 77 (905 s, clippy beside it). Before it, with a term
/// that only re-expresses a change of those parameters marked so: 74 of 77 (790 s, the records
/// side by side on 2 cores). Without that check, 70 (10, 42, 8, 10): the four damper errors were
/// named damping in the damper's own mode.
const FLOORS_CONFIGURED: [(&str, usize); 4] = [
    ("clean", 10),
    ("single, in its library", 47),
    ("pair, in its library", 8),
    ("outside its library", 10),
];
