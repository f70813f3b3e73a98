//! Timing of the diagnosis on the paper's protocol: a 300 s record at 100 Hz (30 s settling,
//! then nine 30 s chirps 0 to 7 Hz of amplitude 0.004 N with phases spread over the period),
//! with a hidden cubic spring, and again with a cubic spring and quadratic drag, each diagnosed
//! over the whole library; plus single simulations, and the silverbox record when present. Run
//! with `cargo bench -p htfid-diagnose`.

// Fit and validation stretches are lists of sample-index ranges; a list of one is not a
// mistaken attempt to list the indices.
#![allow(clippy::single_range_in_vec_init)]

use std::f64::consts::PI;
use std::sync::Arc;
use std::time::{Duration, Instant};

use htfid_data::{read_csv, CsvSpec};
use htfid_diagnose::{
    diagnose, simulate_record, DiagnoseOptions, FittedModel, Interpolation, NominalModel, Sensor,
    SimMethod, TimeSeries,
};
use htfid_hybrid::{simulate, Options};
use htfid_model::{DamperLaw, Effects, Hopper, HopperParams, InputFn};

fn chirp(t: f64) -> f64 {
    if t < 30.0 {
        return 0.0;
    }
    let s = t - 30.0;
    let j = (s / 30.0).floor();
    let tau = s - 30.0 * j;
    0.004 * (14.0 * PI * tau * tau / 30.0 + 2.0 * PI * j / 9.0).sin()
}

fn paper_record(effects: Effects) -> TimeSeries {
    let params = HopperParams::paper();
    let u: InputFn = Arc::new(chirp);
    let hopper = Hopper::with_effects(params, DamperLaw::Switching, effects)
        .expect("valid")
        .with_input(Some(u));
    let n = 30_000;
    let grid: Vec<f64> = (0..n).map(|i| i as f64 * 0.01).collect();
    let x0 = hopper.initial_guess();
    let opts = Options {
        rtol: 1e-10,
        atol: 1e-12,
        ..Options::default()
    };
    let traj = simulate(
        &hopper,
        hopper.mode_of(x0[1]),
        0.0,
        &x0,
        grid[n - 1],
        &grid,
        &opts,
    )
    .expect("simulates");
    // Deterministic pseudo-noise (a fixed LCG) keeps the bench free of test dependencies.
    let mut state = 12345u64;
    let mut noise = |scale: f64| {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        scale * (((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5) * 3.46
    };
    let f: Vec<f64> = grid
        .iter()
        .map(|&t| (2.0 * PI * t).cos() + chirp(t) + noise(1e-4))
        .collect();
    let x: Vec<f64> = (0..n).map(|i| traj.state(i)[0] + noise(2e-6)).collect();
    TimeSeries::new(grid, f, x, "test").expect("valid record")
}

fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> (Duration, T) {
    let mut best = Duration::MAX;
    let mut out = None;
    for _ in 0..runs {
        let t = Instant::now();
        let v = f();
        best = best.min(t.elapsed());
        out = Some(v);
    }
    (best, out.expect("runs >= 1"))
}

fn main() {
    let effects = Effects {
        k3: 300.0,
        ..Effects::default()
    };
    let record = paper_record(effects);
    let model = FittedModel {
        params: HopperParams {
            forcing_amplitude: 0.0,
            ..HopperParams::paper()
        },
        damper: DamperLaw::Switching,
        effects,
        sensor: Sensor::default(),
    };
    let n = record.len();
    for sim in [SimMethod::default(), SimMethod::Adaptive { rtol: 1e-8 }] {
        let (t, _) = best_of(5, || {
            simulate_record(&record, &model, 0..n, None, Interpolation::CubicSpline, sim)
                .expect("simulates")
        });
        println!("simulate 300 s at 100 Hz, {sim:?}: {t:.2?}");
    }
    let nominal = NominalModel::hopper(HopperParams::paper()).expect("valid");
    let (t, report) = best_of(3, || {
        diagnose(&record, &nominal, &DiagnoseOptions::default()).expect("diagnoses")
    });
    println!(
        "diagnose 300 s paper protocol, whole library ({} threads): {t:.2?}, {} fit-range simulations, cause {}, k3 = {:.1}",
        rayon::current_num_threads(),
        report.evaluations,
        report.diagnosis.cause,
        report.diagnosis.parameters.get("k3").copied().unwrap_or(f64::NAN)
    );
    // Two effects at once: forward selection adds both, and the backward pass keeps both.
    let compound = paper_record(Effects {
        k3: 300.0,
        c2: 20.0,
        ..Effects::default()
    });
    let (t, report) = best_of(3, || {
        diagnose(&compound, &nominal, &DiagnoseOptions::default()).expect("diagnoses")
    });
    let found: Vec<&str> = report
        .diagnosis
        .causes
        .iter()
        .map(|c| c.effect.as_str())
        .collect();
    println!(
        "diagnose 300 s paper protocol with a cubic spring and quadratic drag, whole library: {t:.2?}, {} fit-range simulations, causes {found:?}, k3 = {:.1}, c2 = {:.2}",
        report.evaluations,
        report.diagnosis.parameters.get("k3").copied().unwrap_or(f64::NAN),
        report.diagnosis.parameters.get("c2").copied().unwrap_or(f64::NAN)
    );

    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/silverbox/SNLS80mV.csv"
    );
    let spec = CsvSpec::default()
        .with_columns("V1", "V2")
        .with_sample_rate(1e7 / 16384.0, 0.0);
    match read_csv(path, &spec) {
        Ok(series) => {
            let record = series;
            let model = FittedModel {
                params: HopperParams {
                    m: 5.373e-6,
                    k: 0.9902,
                    c: 2.2515e-4,
                    g: 0.0,
                    x0: 0.0,
                    forcing_amplitude: 0.0,
                    period: 1.0,
                },
                damper: DamperLaw::AlwaysOn,
                effects: Effects {
                    k3: 3.912,
                    input_offset: -5.345e-3,
                    ..Effects::default()
                },
                sensor: Sensor::default(),
            };
            let n = record.len();
            let (t, _) = best_of(5, || {
                simulate_record(
                    &record,
                    &model,
                    0..n,
                    None,
                    Interpolation::CubicSpline,
                    SimMethod::default(),
                )
                .expect("simulates")
            });
            println!("simulate silverbox, 131072 samples at 610 Hz: {t:.2?}");
            let nominal = NominalModel::linear_spring_mass_damper(1e-5, 2.0, 1e-3).expect("valid");
            let opts = DiagnoseOptions {
                fit: vec![40650..105712],
                validation: vec![105712..127400],
                ..DiagnoseOptions::default()
            };
            let (t, report) = best_of(1, || diagnose(&record, &nominal, &opts).expect("diagnoses"));
            println!(
                "diagnose silverbox, whole library: {t:.2?}, {} fit-range simulations, cause {}",
                report.evaluations, report.diagnosis.cause
            );
        }
        Err(e) => println!("silverbox skipped: {e}"),
    }
}
