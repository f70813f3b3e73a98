//! The public contract: input validation with exact messages, JSON keys, the simulated outputs
//! of the report, and options.

// Fit and validation stretches are lists of sample-index ranges; a list of one is not a
// mistaken attempt to list the indices.
#![allow(clippy::single_range_in_vec_init)]

mod common;

use common::{generate, Protocol};
use htfid_diagnose::{
    diagnose, DiagnoseError, DiagnoseOptions, Effect, NominalModel, NominalParam, TimeSeries,
};
use htfid_model::{DamperLaw, Effects, HopperParams};

fn uniform(n: usize) -> Vec<f64> {
    (0..n).map(|k| k as f64 * 0.01).collect()
}

#[test]
fn records_are_validated_with_exact_messages() {
    // The record type checks its own invariants where it is built, naming the source.
    let err = TimeSeries::new(uniform(40), vec![0.0; 39], vec![0.0; 40], "rec").unwrap_err();
    assert_eq!(
        err.to_string(),
        "rec: column \"input\" has 39 values, the time vector has 40"
    );
    let mut x = vec![0.0; 40];
    x[7] = f64::NAN;
    let err = TimeSeries::new(uniform(40), vec![0.0; 40], x, "rec").unwrap_err();
    assert_eq!(
        err.to_string(),
        "rec: row 7: column \"output\": value \"NaN\" is not a finite number"
    );
    let mut t = uniform(40);
    t[20] += 0.005;
    let err = TimeSeries::new(t, vec![0.0; 40], vec![0.0; 40], "rec").unwrap_err();
    assert!(err.to_string().starts_with("rec: row 20: "), "{err}");
    // The diagnosis needs more samples than a record's minimum of two.
    let record = TimeSeries::new(uniform(10), vec![0.0; 10], vec![1e-3; 10], "rec").unwrap();
    let nominal = NominalModel::hopper(HopperParams::paper()).unwrap();
    let err = diagnose(&record, &nominal, &DiagnoseOptions::default()).unwrap_err();
    assert!(matches!(
        err,
        DiagnoseError::TooShort { min: 32, found: 10 }
    ));
    assert_eq!(
        err.to_string(),
        "a record needs at least 32 samples (got 10)"
    );
}

#[test]
fn options_and_ranges_are_validated() {
    let x: Vec<f64> = (0..400).map(|k| 1e-4 * k as f64).collect();
    let record = TimeSeries::new(uniform(400), vec![0.0; 400], x, "test").unwrap();
    let nominal = NominalModel::hopper(HopperParams::paper()).unwrap();
    let run = |opts: DiagnoseOptions| diagnose(&record, &nominal, &opts).unwrap_err().to_string();
    assert_eq!(
        run(DiagnoseOptions {
            significance_sigma: 0.0,
            ..Default::default()
        }),
        "significance_sigma must be > 0 and finite (got 0)"
    );
    assert_eq!(
        run(DiagnoseOptions {
            min_gain: 1.0,
            ..Default::default()
        }),
        "min_gain must be in [0, 1) (got 1)"
    );
    assert_eq!(
        run(DiagnoseOptions {
            candidates: vec![Effect::HardStop, Effect::HardStop],
            ..Default::default()
        }),
        "candidate effect hard_stop is listed twice"
    );
    assert_eq!(
        run(DiagnoseOptions {
            fit: vec![0..300],
            validation: vec![250..400],
            ..Default::default()
        }),
        "validation range 250..400 overlaps fit range 0..300; held-out data must not be fitted"
    );
    assert_eq!(
        run(DiagnoseOptions {
            fit: vec![0..500],
            ..Default::default()
        }),
        "fit range 0..500 is empty or leaves the record of 400 samples"
    );
    assert_eq!(
        run(DiagnoseOptions {
            burn_in_s: Some(2.0),
            ..Default::default()
        }),
        "validation range 280..400 keeps 0 samples after the 2 s burn-in; at least 16 are needed"
    );
    let err = NominalModel::new(
        HopperParams::paper(),
        DamperLaw::Switching,
        Effects::default(),
        vec![NominalParam::K, NominalParam::K],
    )
    .unwrap_err();
    assert_eq!(
        err.to_string(),
        "nominal parameter k is listed twice in `free`"
    );
    let bad = HopperParams {
        m: -1.0,
        ..HopperParams::paper()
    };
    assert_eq!(
        NominalModel::hopper(bad).unwrap_err().to_string(),
        "m must be > 0 and finite (got -1)"
    );
}

#[test]
fn options_deserialise_with_defaults_and_reject_unknown_keys() {
    let opts: DiagnoseOptions = serde_json::from_str(
        r#"{"candidates": ["cubic_stiffness", "input_delay"], "min_gain": 0.1}"#,
    )
    .unwrap();
    assert_eq!(
        opts.candidates,
        vec![Effect::CubicStiffness, Effect::InputDelay]
    );
    assert!((opts.min_gain - 0.1).abs() < 1e-15);
    assert!((opts.significance_sigma - 5.0).abs() < 1e-15);
    let err = serde_json::from_str::<DiagnoseOptions>(r#"{"min_gian": 0.1}"#).unwrap_err();
    assert!(
        err.to_string().starts_with("unknown field `min_gian`"),
        "{err}"
    );
    let err = serde_json::from_str::<DiagnoseOptions>(r#"{"candidates": ["cubic"]}"#).unwrap_err();
    assert!(err.to_string().contains("unknown variant `cubic`"), "{err}");
}

#[test]
fn report_carries_the_json_contract_and_consistent_outputs() {
    let effects = Effects {
        k3: 500.0,
        ..Effects::default()
    };
    let record = generate(
        &Protocol::default(),
        HopperParams::paper(),
        effects,
        None,
        5,
    );
    let nominal = NominalModel::hopper(HopperParams::paper()).unwrap();
    let opts = DiagnoseOptions {
        candidates: vec![Effect::CubicStiffness, Effect::FlightDamping],
        ..DiagnoseOptions::default()
    };
    let report = diagnose(&record, &nominal, &opts).unwrap();
    let json = serde_json::to_value(&report.diagnosis).unwrap();
    // serde_json's map is ordered by key.
    let keys =
        |v: &serde_json::Value| -> Vec<String> { v.as_object().unwrap().keys().cloned().collect() };
    let sorted = |names: &[&str]| -> Vec<String> {
        let mut v: Vec<String> = names.iter().map(|s| s.to_string()).collect();
        v.sort();
        v
    };
    assert_eq!(
        keys(&json),
        sorted(&[
            "cause",
            "parameters",
            "stderr",
            "nominal",
            "extended",
            "gain",
            "candidates",
            "evidence",
            "causes",
            "alternatives",
            "configured",
            "gain_vs_configured",
            "mismatch"
        ])
    );
    assert_eq!(json["cause"], "cubic_stiffness");
    assert_eq!(
        keys(&json["causes"][0]),
        sorted(&["effect", "parameters", "stderr", "gain_share"])
    );
    assert_eq!(json["causes"][0]["effect"], "cubic_stiffness");
    assert_eq!(json["causes"].as_array().unwrap().len(), 1);
    assert_eq!(keys(&json["configured"]), sorted(&["nrmse", "rmse"]));
    assert_eq!(keys(&json["nominal"]), sorted(&["nrmse", "rmse"]));
    assert_eq!(keys(&json["extended"]), sorted(&["nrmse", "rmse"]));
    assert_eq!(
        keys(&json["candidates"][0]),
        sorted(&[
            "effect",
            "parameters",
            "stderr",
            "nrmse_validation",
            "rmse_validation",
            "bic",
            "significant",
            "note",
            "starts",
            "best_start"
        ])
    );
    assert_eq!(json["candidates"][0]["effect"], "cubic_stiffness");
    assert_eq!(keys(&json["parameters"]), sorted(&["c", "k", "k3"]));
    assert_eq!(keys(&json["stderr"]), sorted(&["c", "k", "k3"]));

    // The plotted outputs reproduce the reported held-out scores (computed independently here
    // from the outputs and the data), and are NaN only outside the simulated ranges.
    let d = &report.diagnosis;
    let n = record.len();
    assert_eq!(report.nominal_output.len(), n);
    assert_eq!(report.extended_output.len(), n);
    let skip = (report.burn_in_s / record.dt()).round() as usize;
    let val = &report.validation_ranges[0];
    for (out, score) in [
        (&report.nominal_output, d.nominal),
        (&report.extended_output, d.extended),
    ] {
        assert!(
            out.iter().all(|v| v.is_finite()),
            "default ranges cover the record"
        );
        let scored = val.start + skip..val.end;
        let x = &record.output()[scored.clone()];
        let y = &out[scored];
        let rmse =
            (y.iter().zip(x).map(|(a, b)| (a - b).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
        assert!(
            (rmse / score.rmse - 1.0).abs() < 1e-9,
            "{rmse} vs {}",
            score.rmse
        );
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        let sd = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (x.len() - 1) as f64).sqrt();
        assert!((score.nrmse - rmse / sd).abs() < 1e-9 * score.nrmse);
    }
    assert!((d.gain - (1.0 - d.extended.rmse / d.nominal.rmse)).abs() < 1e-12);
}

#[test]
fn fitted_initial_states_and_explicit_ranges_work() {
    // Two fit ranges and one validation range between them, with the initial states taken from
    // the data (not the default) and a 3 s burn-in: the diagnosis is unchanged (k3 = 500
    // recovered within 2 %; its standard error is about 0.1 %).
    let effects = Effects {
        k3: 500.0,
        ..Effects::default()
    };
    let record = generate(
        &Protocol::default(),
        HopperParams::paper(),
        effects,
        None,
        6,
    );
    let nominal = NominalModel::hopper(HopperParams::paper()).unwrap();
    let opts = DiagnoseOptions {
        fit: vec![0..3000, 5500..8000],
        validation: vec![3000..5500],
        candidates: vec![Effect::CubicStiffness, Effect::CoulombFriction],
        fit_initial_state: false,
        burn_in_s: Some(3.0),
        ..DiagnoseOptions::default()
    };
    let report = diagnose(&record, &nominal, &opts).unwrap();
    let d = &report.diagnosis;
    assert_eq!(d.cause, "cubic_stiffness", "{d:#?}");
    assert!(
        (d.parameters["k3"] / 500.0 - 1.0).abs() < 0.02,
        "{:?}",
        d.parameters
    );
    // Outside the ranges nothing is simulated.
    assert!(report.nominal_output.iter().all(|v| v.is_finite()));
    let short = DiagnoseOptions {
        fit: vec![0..3000],
        validation: vec![3000..5500],
        ..opts
    };
    let report = diagnose(&record, &nominal, &short).unwrap();
    assert!(report.extended_output[5500..].iter().all(|v| v.is_nan()));
    assert!(report.extended_output[..5500].iter().all(|v| v.is_finite()));
}

#[test]
fn degenerate_records_are_refused_or_claim_no_effect() {
    // Records the diagnosis cannot do much with. Too short: refused, naming the range. No
    // motion at all: refused, since every normalised error divides by zero. Signals unrelated
    // to the model (a sine against another sine, pure noise): no physical effect may be
    // claimed; the model does not describe the data.
    let nominal = NominalModel::hopper(HopperParams::paper()).unwrap();
    let short = uniform(64);
    let e = diagnose(
        &TimeSeries::new(
            short.clone(),
            vec![0.0; 64],
            (0..64).map(|k| 0.15 + 1e-4 * k as f64).collect(),
            "test",
        )
        .unwrap(),
        &nominal,
        &DiagnoseOptions::default(),
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            DiagnoseError::RangeTooShort {
                which: "validation",
                min: 16,
                ..
            }
        ),
        "{e:?}"
    );
    let n = 3000;
    let t = uniform(n);
    let e = diagnose(
        &TimeSeries::new(t.clone(), vec![0.0; n], vec![0.15; n], "test").unwrap(),
        &nominal,
        &DiagnoseOptions::default(),
    )
    .unwrap_err();
    assert!(
        matches!(e, DiagnoseError::ConstantOutput { value, .. } if value.to_bits() == 0.15f64.to_bits()),
        "{e:?}"
    );
    let unrelated: Vec<(Vec<f64>, Vec<f64>)> = vec![
        (
            t.iter().map(|t| (6.0 * t).sin()).collect(),
            t.iter().map(|t| 0.15 + 1e-3 * (7.0 * t).cos()).collect(),
        ),
        (
            (0..n)
                .map(|k| ((k * 7919) % 101) as f64 / 101.0 - 0.5)
                .collect(),
            (0..n).map(|k| ((k * 104729) % 97) as f64 * 1e-4).collect(),
        ),
    ];
    for (f, x) in unrelated {
        let record = TimeSeries::new(t.clone(), f, x, "test").unwrap();
        let report = diagnose(&record, &nominal, &DiagnoseOptions::default()).unwrap();
        let cause = report.diagnosis.cause.as_str();
        assert!(
            cause == "model_mismatch" || cause == "unexplained",
            "{cause}: {:?}",
            report.diagnosis.evidence
        );
    }
}
