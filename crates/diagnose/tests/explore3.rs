mod common;
use common::*;
use htfid_diagnose::*;
use htfid_model::{DamperLaw, Effects, HopperParams};

#[test]
#[ignore = "exploration"]
fn explore_lag() {
    let mut p = Protocol::default();
    p.noise_x = 0.0;
    p.noise_f = 0.0;
    let e = Effects {
        tau: 0.002,
        ..Effects::default()
    };
    let rec = generate(&p, HopperParams::paper(), e, None, 1);
    let n = rec.len();
    for (name, eff) in [
        ("lag", e),
        (
            "delay",
            Effects {
                delay: 0.002,
                ..Effects::default()
            },
        ),
        ("none", Effects::default()),
    ] {
        let model = FittedModel {
            params: HopperParams::paper(),
            damper: DamperLaw::Switching,
            effects: eff,
        };
        for sim in [SimMethod::default(), SimMethod::Adaptive { rtol: 1e-10 }] {
            let y =
                simulate_record(&rec, &model, 0..n, None, Interpolation::CubicSpline, sim).unwrap();
            let err: Vec<f64> = y.iter().zip(rec.x()).map(|(a, b)| a - b).collect();
            let rms = |r: &[f64]| (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt();
            println!(
                "{name:8} {sim:?} rms all {:.3e} first 5s {:.3e} 10-20s {:.3e} last 20s {:.3e}",
                rms(&err),
                rms(&err[..500]),
                rms(&err[1000..2000]),
                rms(&err[n - 2000..])
            );
        }
    }
}
