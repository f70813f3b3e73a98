use htfid_data::{read_csv, CsvSpec};
use htfid_diagnose::*;

#[test]
#[ignore = "exploration"]
fn explore_silverbox() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/silverbox/SNLS80mV.csv"
    );
    let spec = CsvSpec::default()
        .with_columns("V1", "V2")
        .with_sample_rate(1e7 / 16384.0, 0.0);
    let series = read_csv(path, &spec).unwrap();
    let rec = Record::from_series(&series).unwrap();
    let nominal = NominalModel::linear_spring_mass_damper(1e-5, 2.0, 1e-3).unwrap();
    let mut opts = DiagnoseOptions {
        fit: vec![40650..105712],
        validation: vec![105712..127400],
        ..DiagnoseOptions::default()
    };
    if std::env::var("LIN").is_ok() {
        opts.interpolation = Interpolation::Linear;
    }
    if let Ok(v) = std::env::var("MRS") {
        opts.sim = SimMethod::FixedStep {
            max_rate_step: v.parse().unwrap(),
        };
    }
    if let Ok(v) = std::env::var("ONLY") {
        opts.candidates = v.split(',').map(|s| s.parse().unwrap()).collect();
    }
    let t = std::time::Instant::now();
    let r = diagnose_with_progress(&rec, &nominal, &opts, &|s| {
        println!("  {:?} {s}", t.elapsed())
    })
    .unwrap();
    println!(
        "diagnosed in {:?}, evaluations {}",
        t.elapsed(),
        r.evaluations
    );
    let d = &r.diagnosis;
    println!(
        "cause {} nominal {:.4e} extended {:.4e} gain {:.3} noise {:?} burn {}",
        d.cause, d.nominal.rmse, d.extended.rmse, d.gain, r.noise_floor, r.burn_in_s
    );
    println!("params {:?}", d.parameters);
    for c in &d.candidates {
        println!(
            "  {:18} rmse {:.3e} bic {:.1} sig {} :: {:?} | {}",
            c.effect, c.rmse_validation, c.bic, c.significant, c.parameters, c.note
        );
    }
    for e in &d.evidence {
        println!("  * {e}");
    }
    // arrow
    for (name, m) in [
        ("nominal", &r.nominal_model),
        ("extended", &r.extended_model),
    ] {
        let y = simulate_record(&rec, m, 100..32100, None, opts.interpolation, opts.sim).unwrap();
        let skip = 200;
        let e: Vec<f64> = y[skip..]
            .iter()
            .zip(&rec.x()[100 + skip..32100])
            .map(|(a, b)| a - b)
            .collect();
        println!(
            "arrow {name}: rmse {:.4e}",
            (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt()
        );
    }
}

#[test]
#[ignore = "exploration"]
fn explore_silverbox_sim() {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/data/silverbox/SNLS80mV.csv"
    );
    let spec = CsvSpec::default()
        .with_columns("V1", "V2")
        .with_sample_rate(1e7 / 16384.0, 0.0);
    let series = read_csv(path, &spec).unwrap();
    let rec = Record::from_series(&series).unwrap();
    let m = 5.3732921495507545e-6;
    let model = FittedModel {
        params: htfid_model::HopperParams {
            m,
            k: 0.9901556904245938,
            c: 0.00022515087020722984,
            g: 0.0,
            x0: 0.0,
            forcing_amplitude: 0.0,
            period: 1e12,
        },
        damper: htfid_model::DamperLaw::AlwaysOn,
        effects: htfid_model::Effects {
            k3: 3.912448481237227,
            input_offset: -0.0053454413975863035,
            ..Default::default()
        },
    };
    let n = rec.len();
    let reference = simulate_record(
        &rec,
        &model,
        0..n,
        None,
        Interpolation::CubicSpline,
        SimMethod::Adaptive { rtol: 1e-10 },
    )
    .unwrap();
    for sim in [
        SimMethod::FixedStep {
            max_rate_step: 0.05,
        },
        SimMethod::FixedStep { max_rate_step: 0.1 },
        SimMethod::FixedStep { max_rate_step: 0.2 },
        SimMethod::FixedStep { max_rate_step: 0.3 },
        SimMethod::Adaptive { rtol: 1e-8 },
    ] {
        let t = std::time::Instant::now();
        let y = simulate_record(&rec, &model, 0..n, None, Interpolation::CubicSpline, sim).unwrap();
        let el = t.elapsed();
        let d = (y
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            / n as f64)
            .sqrt();
        let e = (y[105712..127400]
            .iter()
            .zip(&rec.x()[105712..127400])
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            / 21688.0)
            .sqrt();
        println!("{sim:?}: {el:?}, rms vs reference {d:.3e}, test rmse {e:.4e}");
    }
}
