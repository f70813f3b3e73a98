//! A Rust user's own model through the whole pipeline: written in code (the traits
//! `HybridSystem`, `InputOutput`, `Parametric`, `Rhythmic`; `support/oscillator.rs`), driven from its limit cycle, its
//! HTFs estimated from the record and its stiffness and damping fitted, against the analytic
//! truth of a forced linear oscillator `m x'' + c x' + k x = a cos(2 pi t / T) + u`, whose only
//! HTF is `G_0(jw) = 1 / (k - m w^2 + j c w)`.

use std::sync::Arc;

use htfid_estimate::{estimate_experiment, Alpha, Estimator, Layout, Request, Sampled};
use htfid_experiment::{drive, orbit_deviation, Input, Rhythmic};
use htfid_hybrid::Options;
use htfid_identify::{fit_to_htf, HtfFitSpec};
use htfid_orbit::ShootingOptions;
use htfid_theory::{HarmonicTransferFunction, LinearisedHtf};
use num_complex::Complex64;

#[path = "support/oscillator.rs"]
mod oscillator;

use oscillator::{Oscillator, PERIOD};

fn opts() -> Options {
    Options {
        rtol: 1e-10,
        atol: 1e-12,
        ..Options::default()
    }
}

#[test]
fn a_users_own_model_is_simulated_estimated_and_fitted() {
    let truth = Oscillator::new(1.0, 5.0, 0.5);
    let cycle = truth
        .limit_cycle(&ShootingOptions::default(), &opts())
        .unwrap();

    // The exact HTF of the linearisation is the analytic one: the linearisation of a linear
    // system is itself, to the integrator's tolerance (1e-10 relative; 1e-7 allowed).
    let htf = LinearisedHtf::new(&truth, &cycle, &opts()).unwrap();
    let g0 = htf.channel(0).unwrap();
    for w in [0.5, 2.0, 2.236, 4.0] {
        let analytic = Complex64::new(truth.k - truth.m * w * w, truth.c * w).inv();
        let rel = (g0.g(0, w) - analytic).norm() / analytic.norm();
        assert!(rel < 1e-7, "G_0({w}): {} vs {analytic}", g0.g(0, w));
        assert!(g0.g(1, w).norm() < 1e-7 * analytic.norm(), "G_1({w})");
    }

    // A broadband input, 400 s at 20 Hz: 150 sines on the record's DFT grid (every third bin
    // up to 7.1 rad/s; the pumping frequency, bin 200, and its multiples are not among them),
    // so nothing leaks and the estimator's smoothing bridges two empty bins at most.
    let input: Input = Arc::new(|t: f64| {
        (1..=150)
            .map(|i| {
                let w = 2.0 * std::f64::consts::PI * f64::from(3 * i) / 400.0;
                0.002 * (w * t + 0.7 * f64::from(i * i)).sin()
            })
            .sum()
    });
    let dt = 0.05;
    let times: Vec<f64> = (0..8000).map(|i| f64::from(i) * dt).collect();
    let run = drive(&truth, &cycle, Some(input.clone()), &times, &opts()).unwrap();
    let deviation = orbit_deviation(&truth, &cycle, &times, &run.outputs, &opts()).unwrap();
    let u: Vec<f64> = times.iter().map(|&t| input(t)).collect();
    let estimate = estimate_experiment(
        &Sampled {
            u: &u,
            y: &deviation[0],
            dt,
            t_start: 0.0,
        },
        &Layout::default(),
        &Request {
            period: PERIOD,
            harmonics: &[-1, 0, 1],
            band: (0.5, 7.0),
        },
        &Estimator::Siddiqi(Alpha::Fixed(1.0)),
    )
    .unwrap();

    // Fitted from 20 % off: the estimate is noise free, so only the estimator's smoothing
    // bias at the resonance separates the fit from the truth (measured 0.15 % on k and 1.5 %
    // on c, the damping widening as the smoothing widens the peak); 0.5 % and 5 % allowed.
    let start = Oscillator {
        k: 4.0,
        c: 0.6,
        ..truth.clone()
    };
    let start_cycle = start
        .limit_cycle(&ShootingOptions::default(), &opts())
        .unwrap();
    let spec = HtfFitSpec::new(vec!["k".into(), "c".into()], vec![0], (0.5, 7.0));
    let fit = fit_to_htf(&start, &start_cycle, &[(0, &estimate)], &spec, &opts()).unwrap();
    assert!(
        (fit.values[0] / 5.0 - 1.0).abs() < 5e-3,
        "k = {}",
        fit.values[0]
    );
    assert!(
        (fit.values[1] / 0.5 - 1.0).abs() < 5e-2,
        "c = {}",
        fit.values[1]
    );
}
