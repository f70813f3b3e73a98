mod common;
use common::*;
use htfid_diagnose::*;
use htfid_model::{DamperLaw, Effects, HardStop, HopperParams};

#[test]
#[ignore = "exploration"]
fn explore_stop() {
    let p = Protocol::default();
    let truth = Effects {
        hard_stop: Some(HardStop {
            x_stop: 0.14337382440941052,
            k_stop: 909.7611245908741,
        }),
        ..Effects::default()
    };
    let rec = generate(&p, HopperParams::paper(), truth, None, 1);
    let n = rec.len();
    let split = (n as f64 * 0.7) as usize;
    let skip = 600;
    for (name, xs, ks) in [
        ("truth", 0.14337382440941052, 909.7611245908741),
        ("fitted", 0.1434281379876669, 708.4882465051497),
    ] {
        let mut params = HopperParams::paper();
        params.c = 2.0001579966586145;
        params.k = 200.0000923328975;
        if name == "truth" {
            params.c = 2.0;
            params.k = 200.0;
        }
        let model = FittedModel {
            params,
            damper: DamperLaw::Switching,
            effects: Effects {
                hard_stop: Some(HardStop {
                    x_stop: xs,
                    k_stop: ks,
                }),
                ..Effects::default()
            },
        };
        let y = simulate_record(
            &rec,
            &model,
            0..split,
            None,
            Interpolation::CubicSpline,
            SimMethod::default(),
        )
        .unwrap();
        let rss: f64 = y[skip..]
            .iter()
            .zip(&rec.x()[skip..split])
            .map(|(a, b)| (a - b).powi(2))
            .sum();
        let yv = simulate_record(
            &rec,
            &model,
            split..n,
            None,
            Interpolation::CubicSpline,
            SimMethod::default(),
        )
        .unwrap();
        let rv: f64 = yv[skip..]
            .iter()
            .zip(&rec.x()[split + skip..n])
            .map(|(a, b)| (a - b).powi(2))
            .sum();
        println!(
            "{name}: fit rss {rss:.4e} rms {:.3e}; val rms {:.3e}",
            (rss / (split - skip) as f64).sqrt(),
            (rv / (n - split - skip) as f64).sqrt()
        );
        // x min in fit/val
    }
    let xmin_fit = rec.x()[..split]
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    let xmin_val = rec.x()[split..]
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min);
    println!("xmin fit {xmin_fit} val {xmin_val}");
}
