//! The data's HTFs against a model's, on records of the independent truth generator
//! (`htfid-truth`, written without this crate's code): the true model stays within the
//! estimate's noise, a model whose stiffness is 50 % off does not.

use htfid_diagnose::{htf_comparison, FittedModel, HtfComparisonSpec, Sensor, TimeSeries};
use htfid_model::{DamperLaw, Effects, HopperParams};
use htfid_truth::{generate, Noise, Scenario};

fn model(k_factor: f64) -> FittedModel {
    let paper = HopperParams::paper();
    FittedModel {
        params: HopperParams {
            k: k_factor * paper.k,
            forcing_amplitude: 0.0,
            ..paper
        },
        damper: DamperLaw::Switching,
        effects: Effects::default(),
        sensor: Sensor::default(),
    }
}

#[test]
fn the_true_model_stays_within_the_noise_and_a_wrong_one_does_not() {
    let r = generate(&Scenario {
        noise: Noise {
            sigma_x: 1e-6,
            sigma_f: 0.0,
        },
        seed: 3,
        ..Scenario::default()
    })
    .expect("generator");
    let record = TimeSeries::new(r.t, r.f, r.x, "truth").expect("record");
    let paper = HopperParams::paper();
    let spec = HtfComparisonSpec {
        forcing_amplitude: paper.forcing_amplitude,
        period: paper.period,
        harmonics: vec![-1, 0, 1],
        band: (2.0, 30.0),
        alpha: 1.0,
        theory_omegas: vec![5.0, 10.0],
    };
    let cmp = htf_comparison(&record, &model(1.0), &model(1.5), &spec).expect("comparison");
    assert_eq!(cmp.differences.len(), 3);
    assert_eq!(cmp.nominal_theory[1].len(), 2);
    for d in &cmp.differences {
        // About 5 % of the bins of a right model lie beyond two standard errors by chance
        // (more where the estimator's smoothing bias adds to the noise): at most 15 %.
        assert!(
            d.nominal_outside() < 0.15,
            "G_{}: the true model misses {:.0} % of the bins",
            d.n,
            100.0 * d.nominal_outside()
        );
    }
    let g0 = cmp.differences.iter().find(|d| d.n == 0).expect("G_0");
    // The estimate's standard errors hold the switch's nonlinear distortion as well as the
    // sensor noise (here 10 to 100 times the true model's error), so only a clear error shows
    // beyond two of them: a stiffness 50 % off misses 22 % of the bins of G_0 on this record,
    // six times the true model's share.
    assert!(
        g0.extended_outside() > 0.15 && g0.extended_outside() > 3.0 * g0.nominal_outside(),
        "a stiffness 50 % off misses {:.0} % of the bins of G_0, the true model {:.0} %",
        100.0 * g0.extended_outside(),
        100.0 * g0.nominal_outside()
    );
    // Too short to estimate from: a clear refusal, not a figure of noise.
    let short = record.slice(0..record.len() / 40).expect("slice");
    let err = htf_comparison(&short, &model(1.0), &model(1.0), &spec).unwrap_err();
    assert!(
        err.to_string()
            .starts_with("the data's HTFs cannot be compared with the models': "),
        "{err}"
    );
}
