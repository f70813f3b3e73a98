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
    let r = diagnose_with_progress(&rec, &nominal, &opts, &|s| println!("  {s}")).unwrap();
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
