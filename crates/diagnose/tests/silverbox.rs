//! Real data: the Silverbox benchmark (an electronic Duffing oscillator, see
//! ../shared/data/silverbox/README.md). The nominal linear spring-mass-damper must be found
//! wanting and the cause named `cubic_stiffness`, with a simulation error on the test data near
//! the published grey-box figure. Fails, not skips, when the file is missing.

// Fit and validation stretches are lists of sample-index ranges; a list of one is not a
// mistaken attempt to list the indices.
#![allow(clippy::single_range_in_vec_init)]

use htfid_data::{read_csv, CsvSpec};
use htfid_diagnose::{
    diagnose, simulate_record, DiagnoseOptions, Interpolation, NominalModel, SimMethod,
};

const FILE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../../shared/data/silverbox/SNLS80mV.csv"
);

#[test]
fn silverbox_is_diagnosed_as_a_cubic_spring() {
    let spec = CsvSpec::default()
        .with_columns("V1", "V2")
        .with_sample_rate(1e7 / 16384.0, 0.0);
    let series = read_csv(FILE, &spec)
        .unwrap_or_else(|e| panic!("the silverbox data must be present at {FILE}: {e}"));
    let record = series;
    assert_eq!(record.len(), 131_072);
    // Rough starting values (resonance 71 Hz, damping ratio 0.11): the published values are
    // within a factor of 2 (mass, stiffness) and 5 (damping); the fit must find them.
    let nominal = NominalModel::linear_spring_mass_damper(1e-5, 2.0, 1e-3).unwrap();
    let opts = DiagnoseOptions {
        fit: vec![40650..105712],
        validation: vec![105712..127400],
        ..DiagnoseOptions::default()
    };
    let report = diagnose(&record, &nominal, &opts).unwrap();
    let d = &report.diagnosis;
    let summary = format!("{d:#?}");
    assert_eq!(d.cause, "cubic_stiffness", "{summary}");
    // Published simulation errors on the multisine test data (output RMS 54 mV): a linear
    // second-order model about 7 mV, a Duffing model fitted by output error about 1 mV.
    assert!(
        d.nominal.rmse > 5e-3 && d.nominal.rmse < 9e-3,
        "nominal {}",
        d.nominal.rmse
    );
    assert!(d.extended.rmse < 1.2e-3, "extended {}", d.extended.rmse);
    assert!(d.gain > 0.8, "gain {}", d.gain);
    // The published Duffing fit y'' = -a y' - b y - c y^3 + g (u - u0): a = 41.0 1/s,
    // b = 1.850e5 1/s^2, c = 7.47e5 1/(V^2 s^2), g = 1.947e5 1/s^2, u0 = 5.4 mV, from a fit by
    // another method; agreement to 10 % (these are estimates, not exact truths) with the
    // diagnosis's own Duffing model, the cubic spring of the first round beside the refitted
    // nominal. The selection may add effects beyond it (the device's asymmetry); they must not
    // make the held-out error worse.
    let duffing = d
        .candidates
        .iter()
        .find(|c| c.effect == "cubic_stiffness")
        .expect("the cubic spring among the first round's candidates");
    assert!(
        d.extended.rmse <= duffing.rmse_validation * (1.0 + 1e-9),
        "extended {} against the Duffing model's {}",
        d.extended.rmse,
        duffing.rmse_validation
    );
    let p = &duffing.parameters;
    let m = p["m"];
    for (name, got, published) in [
        ("a = c/m", p["c"] / m, 41.0),
        ("b = k/m", p["k"] / m, 1.850e5),
        ("c = k3/m", p["k3"] / m, 7.47e5),
        ("g = 1/m", 1.0 / m, 1.947e5),
        ("u0 = -input_offset", -p["input_offset"], 5.4e-3),
    ] {
        assert!(
            (got / published - 1.0).abs() < 0.1,
            "{name}: {got} vs published {published}\n{summary}"
        );
    }
    // The arrow (filtered noise of rising amplitude, never fitted): the extended model keeps
    // its accuracy there (published: about 1 mV for the Duffing model, 14 mV for a linear one
    // over the arrow including its extrapolation tail). A 0.33 s burn-in (200 samples) covers
    // the start-up transient (decay time 2 m / c = 0.05 s).
    let arrow = 100..32100;
    let skip = 200;
    let mut rmse = Vec::new();
    for model in [&report.nominal_model, &report.extended_model] {
        let y = simulate_record(
            &record,
            model,
            arrow.clone(),
            None,
            Interpolation::CubicSpline,
            SimMethod::default(),
        )
        .unwrap();
        let x = &record.output()[arrow.start + skip..arrow.end];
        let e = (y[skip..]
            .iter()
            .zip(x)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            / x.len() as f64)
            .sqrt();
        rmse.push(e);
    }
    assert!(rmse[0] > 4e-3, "nominal on the arrow {}", rmse[0]);
    assert!(rmse[1] < 1.2e-3, "extended on the arrow {}", rmse[1]);
    println!(
        "silverbox: nominal {:.3e} V, extended {:.3e} V on the test multisines; arrow {:.3e} / {:.3e} V; parameters {:?}",
        d.nominal.rmse, d.extended.rmse, rmse[0], rmse[1], d.parameters
    );
}
