mod common;
use common::*;
use htfid_diagnose::*;
use htfid_model::{DamperLaw, Effects, HopperParams};

#[test]
#[ignore = "exploration"]
fn explore_sim() {
    let mut p = Protocol::default();
    p.noise_x = 0.0;
    p.noise_f = 0.0;
    let rec = generate(&p, HopperParams::paper(), Effects::default(), None, 1);
    let model = FittedModel {
        params: HopperParams::paper(),
        damper: DamperLaw::Switching,
        effects: Effects::default(),
    };
    let n = rec.len();
    let truth_init = {
        let h = htfid_model::Hopper::new(HopperParams::paper()).unwrap();
        let g = h.initial_guess();
        [g[0], g[1]]
    };
    for (name, sim, init) in [
        ("fixed data-init", SimMethod::default(), None),
        ("fixed true-init", SimMethod::default(), Some(truth_init)),
        (
            "fixed fine true-init",
            SimMethod::FixedStep {
                max_rate_step: 0.01,
            },
            Some(truth_init),
        ),
        (
            "adaptive true-init",
            SimMethod::Adaptive { rtol: 1e-10 },
            Some(truth_init),
        ),
        (
            "adaptive data-init",
            SimMethod::Adaptive { rtol: 1e-10 },
            None,
        ),
    ] {
        let t = std::time::Instant::now();
        let y = simulate_record(&rec, &model, 0..n, init, Interpolation::CubicSpline, sim).unwrap();
        let el = t.elapsed();
        let err: Vec<f64> = y.iter().zip(rec.x()).map(|(a, b)| a - b).collect();
        let rms = |r: &[f64]| (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt();
        println!(
            "{name:24} {el:?} rms all {:.3e} first 5s {:.3e} 10-20s {:.3e} last 20s {:.3e}",
            rms(&err),
            rms(&err[..500]),
            rms(&err[1000..2000]),
            rms(&err[n - 2000..])
        );
    }
}
