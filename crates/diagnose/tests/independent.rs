//! The diagnosis on records it was never tuned to: the catalogue of the independent truth
//! generator (`htfid-truth`, its own equations and integrator, written from the effect
//! definitions alone and sharing no code with `htfid-model` or `htfid-diagnose`).
//!
//! The nominal model is the paper's hopper as configured (m = 1, k = 200, c = 2, g = 9.81,
//! x0 = 0.2, switching damper) with nothing refitted: the configured simulation is the
//! baseline, so a parameter error is a finding. Each record is judged against its label:
//! - clean: the cause must be `none`;
//! - one in-library effect: it must be named (alone, or as one of the names of an `ambiguous`
//!   answer when the data cannot separate it from its rival; see `acceptable`);
//! - compound pairs: both effects among the causes;
//! - out of library: not claimed with confidence (`unexplained`, `ambiguous` or `discovered`).
//!
//! The quick set (`cargo test`) checks one record per group; the wide sweep (ignored, run in
//! CI by `just sweep`) runs 200 records and prints the score of each group.

use htfid_diagnose::{
    diagnose, diagnose_with_progress, DiagnoseOptions, Diagnosis, Effect, NominalModel, TimeSeries,
};
use htfid_model::{DamperLaw, Effects, HopperParams};
use htfid_truth::{catalogue, generate, EffectLabel, LabelClass, Scenario};

fn nominal() -> NominalModel {
    NominalModel::new(
        HopperParams::paper(),
        DamperLaw::Switching,
        Effects::default(),
        Vec::new(),
    )
    .expect("valid nominal")
}

/// Whether a labelled effect is a constant shift of the position: an input offset (a constant
/// force), a sensor offset without gain error, an error of gravity or of the rest length. The
/// hopper's spring is always engaged and its dynamics are translation-invariant except for the
/// equilibrium, so these are one observable on this protocol.
fn is_shift(e: &EffectLabel) -> bool {
    match e.name.as_str() {
        "input_offset" => true,
        "sensor_offset_gain" => e
            .params
            .get("gain")
            .is_some_and(|g| (g - 1.0).abs() < 1e-12),
        "parameter_error" => e.params.keys().all(|k| k == "g" || k == "x0"),
        _ => false,
    }
}

/// Names that are the same observable on this protocol as the labelled effect `e` of a record
/// labelled `all`. A constant shift of the position is an input offset, a sensor offset, an
/// error of the rest length or of gravity alike ([`is_shift`]). Coulomb friction `mu` beside a
/// constant force `d` is exactly asymmetric friction (`mu_pos = mu - d`, `mu_neg = mu + d` is the
/// same force law, sticking band included), so asymmetric friction names both the friction and
/// the shift of such a record, and Coulomb friction names asymmetric friction beside a shift.
fn equivalents(e: &EffectLabel, all: &[EffectLabel]) -> Vec<&'static str> {
    let friction = all
        .iter()
        .any(|o| o.name == "asymmetric_friction" || o.name == "coulomb_friction");
    if is_shift(e) {
        let mut v = vec!["input_offset", "sensor_offset_gain"];
        if friction {
            v.push("asymmetric_friction");
        }
        return v;
    }
    match e.name.as_str() {
        "coulomb_friction" if all.iter().any(is_shift) => vec!["asymmetric_friction"],
        // And back: asymmetric friction beside a constant force is Coulomb friction beside
        // another constant force.
        "asymmetric_friction" if all.iter().any(is_shift) => vec!["coulomb_friction"],
        // The hopper is piecewise linear with its switch at a velocity of zero, so a reading
        // scaled by g is the position of a hopper with m, k and c scaled by 1 / g and a
        // constant force added: the same records, told apart only by the configured mass.
        "sensor_offset_gain" => vec!["parameter_error"],
        _ => Vec::new(),
    }
}

fn names_of(d: &Diagnosis) -> Vec<String> {
    let mut v: Vec<String> = d.causes.iter().map(|c| c.effect.clone()).collect();
    if v.is_empty() && !["none", "unexplained", "ambiguous", "model_mismatch"].contains(&&*d.cause)
    {
        v.push(d.cause.clone());
    }
    v.extend(d.alternatives.iter().cloned());
    v
}

/// Whether the diagnosis is right for the scenario, and why not.
fn judge(s: &Scenario, d: &Diagnosis) -> Result<(), String> {
    let label = s.label();
    let named = names_of(d);
    // Coulomb friction named beside a constant force or a sensor offset (whose offset takes up
    // the force's static deflection, whatever its gain) is asymmetric friction's force law:
    // `mu_pos = mu - d`, `mu_neg = mu + d`.
    let offset_named = named
        .iter()
        .any(|n| n == "input_offset" || n == "sensor_offset_gain");
    let has = |want: &EffectLabel| {
        named.contains(&want.name)
            || equivalents(want, &label.effects)
                .iter()
                .any(|e| named.iter().any(|n| n == e))
            || (want.name == "asymmetric_friction"
                && offset_named
                && named.iter().any(|n| n == "coulomb_friction"))
    };
    match label.class {
        LabelClass::Clean => (d.cause == "none")
            .then_some(())
            .ok_or_else(|| format!("clean record named {}", d.cause)),
        LabelClass::InLibrary => {
            let missing: Vec<&str> = label
                .effects
                .iter()
                .filter(|e| !has(e))
                .map(|e| e.name.as_str())
                .collect();
            if missing.is_empty() {
                Ok(())
            } else {
                Err(format!(
                    "missed {missing:?}: cause {} names {named:?}",
                    d.cause
                ))
            }
        }
        LabelClass::OutOfLibrary | LabelClass::Mixed => {
            if ["unexplained", "ambiguous"].contains(&&*d.cause) {
                Ok(())
            } else {
                Err(format!(
                    "claimed {} (names {named:?}) with confidence",
                    d.cause
                ))
            }
        }
    }
}

/// Largest relative error of a fitted parameter of a single effect that counts as found.
const PARAMETER_TOLERANCE: f64 = 0.1;

/// For a record with one in-library effect named by its own name: whether every labelled
/// parameter was fitted within [`PARAMETER_TOLERANCE`] of its true value (for
/// `parameter_error`, of the true fractional error of `m`, `k` and `c`). `None` where the
/// record has no such single effect or the diagnosis named it by an equivalent.
fn parameters_within(s: &Scenario, d: &Diagnosis) -> Option<Result<(), String>> {
    let label = s.label();
    let [want] = label.effects.as_slice() else {
        return None;
    };
    if label.class != LabelClass::InLibrary {
        return None;
    }
    let cause = d.causes.iter().find(|c| c.effect == want.name)?;
    let nominal = HopperParams::paper();
    let mut bad = Vec::new();
    for (name, &truth) in &want.params {
        let (fitted, truth) = match (want.name.as_str(), name.as_str()) {
            ("parameter_error", p @ ("m" | "k" | "c")) => {
                let base = match p {
                    "m" => nominal.m,
                    "k" => nominal.k,
                    _ => nominal.c,
                };
                let Some(v) = cause.parameters.get(p) else {
                    bad.push(format!("{p} not fitted (true error {truth:+.3})"));
                    continue;
                };
                (v / base - 1.0, truth)
            }
            // g and x0 errors are a shift of the position, not fitted as such.
            ("parameter_error", _) => continue,
            (_, p) => {
                // The diagnosis's names for the generator's `offset` and `gain`.
                let ours = match p {
                    "offset" => "input_offset",
                    "gain" => "g",
                    p => p,
                };
                // A parameter the diagnosis does not report counts as off.
                (
                    cause.parameters.get(ours).copied().unwrap_or(f64::NAN),
                    truth,
                )
            }
        };
        if truth == 0.0 {
            // No scale for a relative error (the offset of a pure gain error).
            continue;
        }
        // A NaN fit is off, so the comparison is written to be false for it.
        let close = (fitted - truth).abs() <= PARAMETER_TOLERANCE * truth.abs();
        if !close {
            bad.push(format!("{name} = {fitted:.4e}, true {truth:.4e}"));
        }
    }
    Some(if bad.is_empty() {
        Ok(())
    } else {
        Err(bad.join(", "))
    })
}

/// The judgement of a record, and of its fitted parameters where [`parameters_within`] applies.
type Outcome = (Result<(), String>, Option<Result<(), String>>);

fn run(s: &Scenario) -> Outcome {
    let r = match generate(s) {
        Ok(r) => r,
        Err(e) => return (Err(format!("generator: {e}")), None),
    };
    let diagnosed = TimeSeries::new(r.t, r.f, r.x, "test")
        .map_err(|e| format!("record: {e}"))
        .and_then(|record| {
            diagnose(&record, &nominal(), &DiagnoseOptions::default())
                .map_err(|e| format!("diagnose: {e}"))
        });
    let report = match diagnosed {
        Ok(r) => r,
        Err(e) => return (Err(e), None),
    };
    let verdict = judge(s, &report.diagnosis).map_err(|e| {
        format!(
            "{e}\n    evidence: {}",
            report.diagnosis.evidence.join("\n    evidence: ")
        )
    });
    (verdict, parameters_within(s, &report.diagnosis))
}

fn class_name(c: LabelClass) -> &'static str {
    match c {
        LabelClass::Clean => "clean",
        LabelClass::InLibrary => "in library",
        LabelClass::OutOfLibrary => "out of library",
        LabelClass::Mixed => "mixed",
    }
}

fn sweep(n: usize, seed: u64) -> Vec<(Scenario, Outcome)> {
    catalogue(seed, n)
        .into_iter()
        .map(with_sweep_length)
        .map(|s| {
            let outcome = run(&s);
            let parameters = match &outcome.1 {
                None | Some(Ok(())) => String::new(),
                Some(Err(e)) => format!(" (parameters off: {e})"),
            };
            eprintln!(
                "{:<40} {}{parameters}",
                s.name,
                match &outcome.0 {
                    Ok(()) => "ok".to_string(),
                    Err(e) => format!("FAIL {e}"),
                }
            );
            (s, outcome)
        })
        .collect()
}

/// The catalogue's seed: 2026, or `HTFID_SWEEP_SEED` to draw records this project has not
/// seen (the floors below were measured at 2026).
fn sweep_seed() -> u64 {
    std::env::var("HTFID_SWEEP_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(2026)
}

/// The scenario recorded for `HTFID_SWEEP_RECORD_S` seconds where that is set (the floors
/// were measured on the generator's 270 s).
fn with_sweep_length(s: Scenario) -> Scenario {
    let record_s: Option<f64> = std::env::var("HTFID_SWEEP_RECORD_S")
        .ok()
        .and_then(|v| v.parse().ok());
    Scenario {
        record_s: record_s.unwrap_or(s.record_s),
        ..s
    }
}

/// The catalogue's core cell of this name (drawn with the sweep's seed).
fn cell(name: &str) -> Scenario {
    cell_among(name, htfid_truth::core_size())
}

/// The cell of this name among the sweep's first `n` records.
fn cell_among(name: &str, n: usize) -> Scenario {
    catalogue(sweep_seed(), n)
        .into_iter()
        .map(with_sweep_length)
        .find(|s| s.name.ends_with(name))
        .unwrap_or_else(|| panic!("no catalogue cell {name}"))
}

#[test]
fn a_single_effect_is_named() {
    let (verdict, parameters) = run(&cell("-coulomb_friction-large"));
    verdict.unwrap();
    parameters
        .expect("a single effect named by its own name")
        .unwrap();
}

/// The record `name` of the catalogue drawn with seed 7 (200 records).
fn seed_7(name: &str) -> Scenario {
    catalogue(7, 200)
        .into_iter()
        .find(|s| s.name == name)
        .unwrap_or_else(|| panic!("seed 7 has no record {name}"))
}

/// A negative threshold among the speed's extremes (`v_th = -0.038 m/s`, reached in some
/// periods of a multisine record and not in others), whose whole-record error is rough in the
/// threshold: minima a twentieth of a percent wide. Seed 7's record 055, missed until the
/// threshold was searched on short windows (`Screening::threshold_on_windows`).
#[test]
fn a_threshold_among_the_speed_extremes_is_named() {
    let (verdict, parameters) = run(&seed_7("055-switch_threshold-large"));
    verdict.unwrap();
    parameters
        .expect("a single effect named by its own name")
        .unwrap();
}

/// Damping while the damper is off (`c_f = 0.11 N s/m`) beside a cubic spring: fitted alone
/// it sits on its bound at zero, pushed there by the unmodelled spring. Seed 7's record 146,
/// missed until a candidate held by a bound was tried again in later rounds.
#[test]
fn damping_in_flight_held_on_its_bound_is_tried_again() {
    run(&seed_7("146-random-pair")).0.unwrap();
}

/// A threshold among the speed's extremes (`v_th = -0.037 m/s`) beside a small input offset:
/// the threshold alone improves the fit data by a likelihood ratio of 34757, yet its whole
/// held-out simulation parts from the data (the offset still missing decides which periods
/// switch). Judged on held-out windows of two natural periods, it gains 76 %, and the offset
/// beside it 98 %. Seed 7's record 137.
#[test]
fn a_threshold_beside_an_offset_is_judged_on_windows() {
    let s = seed_7("137-random-pair");
    let r = generate(&s).expect("generator");
    let record = TimeSeries::new(r.t, r.f, r.x, "test").expect("record");
    let report = diagnose(&record, &nominal(), &DiagnoseOptions::default()).expect("diagnosis");
    let d = &report.diagnosis;
    judge(&s, d).unwrap();
    // The whole held-out simulation loses against the nominal (measured: -78 %); on the
    // windows the pair removes nearly all of the nominal's error (measured: 98.6 %, the
    // final error 1.3 times the noise of 1e-6 m). 90 % leaves room for another integrator
    // tolerance or window length, not for a missing effect.
    let w = d
        .held_out_on_windows
        .expect("the answer judged on held-out windows");
    assert!(w.gain > 0.9, "held-out windows: {w:?}");
}

#[test]
fn a_sensor_side_effect_is_named() {
    let (verdict, parameters) = run(&cell("-sensor_lag-large"));
    verdict.unwrap();
    parameters
        .expect("a single effect named by its own name")
        .unwrap();
}

#[test]
fn both_effects_of_a_pair_are_named() {
    run(&cell("-cubic_stiffness+coulomb_friction")).0.unwrap();
}

/// The diagnosis of the scenario's record with `opts`.
fn diagnosed(s: &Scenario, opts: &DiagnoseOptions) -> Diagnosis {
    let r = generate(s).expect("generator");
    let record = TimeSeries::new(r.t, r.f, r.x, "test").expect("record");
    diagnose(&record, &nominal(), opts)
        .expect("diagnosis")
        .diagnosis
}

/// A sensor gain beside a stiffness error, recorded for 90 s instead of 270 s: the refitted
/// parameters leave a constant offset, and once they are in the model five candidates reach
/// the noise floor held out. Ranked by their held-out noise, a weak contact came first and the
/// offset was never named; ranked on the fit data, the offset is.
#[test]
fn candidates_at_the_noise_floor_are_ranked_on_the_fit_data() {
    let s = Scenario {
        record_s: 90.0,
        ..cell("-sensor_gain+k")
    };
    let d = diagnosed(&s, &DiagnoseOptions::default());
    judge(&s, &d).unwrap();
    let names = names_of(&d);
    assert!(
        !names.iter().any(|n| n == "hard_stop")
            && d.evidence
                .iter()
                .any(|e| e.contains("reach the noise floor held out")),
        "cause {}, names {names:?}: {:#?}",
        d.cause,
        d.evidence
    );
}

/// The same record with only the refitted parameters and a contact to choose from: the contact
/// joins them in round 2, and without the parameters it fits as well only by moving above every
/// measured position (a stiffer spring). The backward pass keeps the parameters.
#[test]
fn the_backward_pass_keeps_what_another_effect_mimics_only_outside_the_data() {
    let s = Scenario {
        record_s: 90.0,
        ..cell("-sensor_gain+k")
    };
    let opts = DiagnoseOptions {
        candidates: vec![Effect::ParameterError, Effect::HardStop],
        ..DiagnoseOptions::default()
    };
    let d = diagnosed(&s, &opts);
    assert!(
        names_of(&d).iter().any(|n| n == "parameter_error"),
        "cause {}, names {:?}: {:#?}",
        d.cause,
        names_of(&d),
        d.evidence
    );
    assert!(
        d.evidence
            .iter()
            .any(|e| e.starts_with("backward pass: parameter_error kept")),
        "{:#?}",
        d.evidence
    );
}

#[test]
fn clean_data_give_none() {
    run(&cell("-clean-2e-5-200")).0.unwrap();
}

#[test]
fn an_effect_outside_the_library_is_not_claimed() {
    run(&cell("-second_mode-large")).0.unwrap();
}

/// White noise on the recorded force (not on the force applied), 1 % of the paper chirps'
/// RMS of 0.707 N: the simulation driven by the noisy force leaves the model's response to
/// it, 24 to 50 times the position's noise of 1e-6 m, which no effect explains.
const FORCE_NOISE: f64 = 0.00707;

/// `s` with [`FORCE_NOISE`] on its recorded force.
fn with_force_noise(s: &Scenario) -> Scenario {
    let mut s = s.clone();
    s.noise.sigma_f = FORCE_NOISE;
    s
}

/// A clean record whose recorded force carries white noise is still clean: the noise floor
/// holds the model's response to the force's noise, read from the force's spectrum. The
/// level read must be the generator's (within 10 %: the band's median over 13 segments
/// scatters by about 3 %).
#[test]
fn a_noisy_force_leaves_clean_data_clean() {
    let s = with_force_noise(&cell("-clean-1e-6-200"));
    let r = generate(&s).expect("generator");
    let record = TimeSeries::new(r.t, r.f, r.x, "test").expect("record");
    let report = diagnose(&record, &nominal(), &DiagnoseOptions::default()).expect("diagnosis");
    judge(&s, &report.diagnosis).unwrap();
    let noise = report.input_noise.expect("the force's noise read");
    assert!(
        (noise.sigma / FORCE_NOISE - 1.0).abs() < 0.1,
        "{noise:?} against {FORCE_NOISE}"
    );
    assert!(report.noise_floor.is_some_and(|f| f >= noise.propagated));
}

/// Data the model cannot describe at all are named as such, with the likely reason, and no
/// effect is claimed: the position column's sign flipped, and the position in mm instead of m.
#[test]
fn garbage_data_are_a_model_mismatch_with_the_reason() {
    let s = cell("-coulomb_friction-large");
    let r = generate(&s).unwrap();
    for (scale, reason) in [(-1.0, "sign:"), (1000.0, "scale:")] {
        let x: Vec<f64> = r.x.iter().map(|v| scale * v).collect();
        let record = TimeSeries::new(r.t.clone(), r.f.clone(), x, "test").unwrap();
        let d = diagnose(&record, &nominal(), &DiagnoseOptions::default())
            .unwrap()
            .diagnosis;
        assert_eq!(d.cause, "model_mismatch", "{scale}: {:?}", d.evidence);
        assert!(d.causes.is_empty(), "{:?}", d.causes);
        assert!(
            d.mismatch.iter().any(|m| m.starts_with(reason)),
            "{scale}: {:?}",
            d.mismatch
        );
    }
}

/// The sweep's groups: a record's class, with in-library records split into single effects
/// and compound ones.
fn group(s: &Scenario) -> &'static str {
    let label = s.label();
    match label.class {
        LabelClass::InLibrary if label.effects.len() == 1 => "single effect",
        LabelClass::InLibrary => "compound",
        c => class_name(c),
    }
}

/// Floors of the wide sweep, each a little below the share measured on 2026-11-24 (see
/// `docs/diagnosis.md`), so a regression fails CI while a draw's luck does not. The last is
/// the share of single effects named by their own name whose parameters are all within 10 %.
const FLOORS: [(&str, f64); 6] = [
    ("clean", 0.9),
    ("single effect", 0.9),
    ("compound", 0.8),
    ("out of library", 0.8),
    ("mixed", 0.0),
    ("parameters within 10 %", 0.9),
];

#[test]
#[ignore = "wide sweep of 200 independent records, 20 to 65 minutes on 2 cores: run with --ignored"]
fn independent_catalogue_sweep() {
    // `HTFID_SWEEP_N` runs a prefix (the first 77 are the core cells: every group).
    let n = std::env::var("HTFID_SWEEP_N")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(200);
    let results = sweep(n, sweep_seed());
    let mut low = Vec::new();
    for (name, floor) in FLOORS {
        let (ok, of) = if name.starts_with("parameters") {
            let checked: Vec<_> = results.iter().filter_map(|(_, o)| o.1.as_ref()).collect();
            (checked.iter().filter(|r| r.is_ok()).count(), checked.len())
        } else {
            let of: Vec<_> = results.iter().filter(|(s, _)| group(s) == name).collect();
            (of.iter().filter(|(_, o)| o.0.is_ok()).count(), of.len())
        };
        eprintln!("{name}: {ok} of {of}");
        if of > 0 && (ok as f64) < floor * of as f64 {
            low.push(format!(
                "{name}: {ok} of {of} right, below the floor {floor}"
            ));
        }
    }
    assert!(low.is_empty(), "{}", low.join("; "));
}

/// The core cells' clean records and single effects again, each with [`FORCE_NOISE`] on its
/// recorded force: the clean records must stay `none` and the single effects be named, each
/// group held to a floor below (see `docs/diagnosis.md` for what a noisy force hides).
#[test]
#[ignore = "57 records with a noisy force, a few minutes on 2 cores: run with --ignored"]
fn a_noisy_force_sweep() {
    let mut tally = [(0usize, 0usize); 2];
    for s in catalogue(sweep_seed(), htfid_truth::core_size()) {
        let g = match group(&s) {
            "clean" => 0,
            "single effect" => 1,
            _ => continue,
        };
        let s = with_force_noise(&s);
        let (verdict, _) = run(&s);
        eprintln!(
            "{:<40} {}",
            s.name,
            verdict
                .as_ref()
                .map_or_else(|e| format!("FAIL {e}"), |()| "ok".into())
        );
        tally[g].1 += 1;
        tally[g].0 += usize::from(verdict.is_ok());
    }
    let [clean, single] = tally;
    eprintln!(
        "clean: {} of {}; single effect: {} of {}",
        clean.0, clean.1, single.0, single.1
    );
    assert!(
        clean.0 as f64 >= NOISY_FORCE_CLEAN_FLOOR * clean.1 as f64,
        "clean records with a noisy force: {} of {} `none`",
        clean.0,
        clean.1
    );
    assert!(
        single.0 as f64 >= NOISY_FORCE_SINGLE_FLOOR * single.1 as f64,
        "single effects with a noisy force: {} of {}",
        single.0,
        single.1
    );
}

/// Shares of clean records left at `none` and of single effects named with [`FORCE_NOISE`] on
/// the recorded force, a little below the shares measured (10 of 10 and 44 of 47, see
/// `docs/diagnosis.md`), as the wide sweep's floors are.
const NOISY_FORCE_CLEAN_FLOOR: f64 = 0.9;
const NOISY_FORCE_SINGLE_FLOOR: f64 = 0.85;

/// The same record at 1 kHz, 200 Hz and 50 Hz gives the same cause, with its parameter within
/// 10 % at every rate: the rules' noise floor comes from the residual's spectrum relative to
/// each record's Nyquist frequency, and must not depend on how finely smooth data are sampled.
#[test]
#[ignore = "three diagnoses, one of a 270 000-sample record (a few minutes); run by `just sweep`"]
fn the_cause_does_not_depend_on_the_sample_rate() {
    use htfid_truth::SampleRate;
    for name in ["-coulomb_friction-large", "-cubic_stiffness-large"] {
        let base = cell(name);
        for rate in [SampleRate::Hz1000, SampleRate::Hz200, SampleRate::Hz50] {
            let s = Scenario {
                sample_rate: rate,
                ..base.clone()
            };
            let (verdict, parameters) = run(&s);
            let at = format!("{name} at {} Hz", rate.hz());
            verdict.unwrap_or_else(|e| panic!("{at}: {e}"));
            parameters
                .unwrap_or_else(|| panic!("{at}: not named by its own name"))
                .unwrap_or_else(|e| panic!("{at}: {e}"));
        }
    }
}

/// One record of the wide sweep by the end of its name, judged like the sweep judges it, with
/// its whole evidence and first-round table printed: the sweep's failures reproduced one at a
/// time (`HTFID_CELL=switch_threshold-large`); run by `just sweep` with its default record.
#[test]
#[ignore = "one record of the sweep (HTFID_CELL, by default a masked threshold): run with --ignored"]
fn one_cell() {
    // Without a name: the pair whose threshold stays hidden until the flight damping is
    // modelled (found only since masked thresholds are tried again).
    let name = std::env::var("HTFID_CELL")
        .unwrap_or_else(|_| "switch_threshold+flight_damping".to_string());
    let s = cell_among(&name, 200);
    let r = generate(&s).expect("generator");
    let record = TimeSeries::new(r.t, r.f, r.x, "test").expect("record");
    // Every round's candidates as the command's progress shows them.
    let report = diagnose_with_progress(&record, &nominal(), &DiagnoseOptions::default(), &|m| {
        eprintln!("  progress: {m}")
    })
    .expect("diagnosis");
    eprintln!("{}: label {:?}", s.name, s.label());
    eprintln!(
        "cause {} names {:?}",
        report.diagnosis.cause,
        names_of(&report.diagnosis)
    );
    for e in &report.diagnosis.evidence {
        eprintln!("  {e}");
    }
    for c in &report.diagnosis.candidates {
        eprintln!(
            "  first round: {:<22} held-out NRMSE {:.5} BIC {:.0} {:?} {}",
            c.effect, c.nrmse_validation, c.bic, c.parameters, c.note
        );
    }
    if let Err(e) = judge(&s, &report.diagnosis) {
        panic!("{}: {e}", s.name);
    }
}
