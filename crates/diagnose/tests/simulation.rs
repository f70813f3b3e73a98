//! The simulation with the measured force against independent references: a closed-form
//! solution, and the model's own vector field (with its lag state) integrated by the adaptive
//! DOP853 of `htfid-hybrid` from the continuous force.

mod common;

use common::{generate, Protocol};
use htfid_diagnose::{simulate_record, FittedModel, Interpolation, Sensor, SimMethod, TimeSeries};
use htfid_model::{DamperLaw, Effects, HardStop, Hopper, HopperParams};

fn rms(a: &[f64], b: &[f64]) -> f64 {
    (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / a.len() as f64).sqrt()
}

fn max_abs(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn linear_oscillator_matches_its_closed_form_solution() {
    // m x'' + c x' + k x = F0 sin(w t) + offset from rest at x = 0, x' = 0 (silverbox-like
    // scales: m = 5e-6, resonance 70 Hz, 610 Hz sampling, forcing at 40 Hz). Closed form:
    // steady state X sin(w t - phi) plus offset / k, plus the damped transient that matches the
    // initial state.
    let (m, c, k, f0, offset): (f64, f64, f64, f64, f64) = (5e-6, 2e-4, 0.97, 0.02, -5e-3);
    let w = 2.0 * std::f64::consts::PI * 40.0;
    let fs = 1e7 / 16384.0;
    let n = 4000;
    let (wn, zeta) = ((k / m).sqrt(), c / (2.0 * (k * m).sqrt()));
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    let (re, im) = (k - m * w * w, c * w);
    let amp = f0 / (re * re + im * im).sqrt();
    let phi = im.atan2(re);
    let xs = |t: f64| amp * (w * t - phi).sin() + offset / k;
    let vs = |t: f64| amp * w * (w * t - phi).cos();
    // Transient e^{-zeta wn t} (A cos wd t + B sin wd t) with x(0) = 0, x'(0) = 0.
    let a = -xs(0.0);
    let b = (-vs(0.0) + zeta * wn * a) / wd;
    let exact: Vec<f64> = (0..n)
        .map(|i| {
            let t = i as f64 / fs;
            xs(t) + (-zeta * wn * t).exp() * (a * (wd * t).cos() + b * (wd * t).sin())
        })
        .collect();
    let f: Vec<f64> = (0..n).map(|i| f0 * (w * i as f64 / fs).sin()).collect();
    let record = TimeSeries::from_sample_rate(fs, 0.0, f, exact.clone(), "test").unwrap();
    let model = FittedModel {
        params: HopperParams {
            m,
            k,
            c,
            g: 0.0,
            x0: 0.0,
            forcing_amplitude: 0.0,
            period: 1.0,
        },
        damper: DamperLaw::AlwaysOn,
        effects: Effects {
            input_offset: offset,
            ..Effects::default()
        },
        sensor: Sensor::default(),
    };
    let amplitude = amp;
    // The spline reads a 40 Hz sine sampled at 610 Hz with relative error about
    // (5/384) (w dt)^4 = 3e-4 (w dt = 0.41), which passes to the response; RK4 adds about
    // 1e-5 relative at the default step. 1e-3 of the amplitude is a few times their sum.
    let y = simulate_record(
        &record,
        &model,
        0..n,
        Some([0.0, 0.0]),
        Interpolation::CubicSpline,
        SimMethod::default(),
    )
    .unwrap();
    assert!(
        max_abs(&y, &exact) < 1e-3 * amplitude,
        "{}",
        max_abs(&y, &exact) / amplitude
    );
    // Linear interpolation errs by (w dt)^2 / 8 = 2 % at the peaks: 3 % of the amplitude.
    let y = simulate_record(
        &record,
        &model,
        0..n,
        Some([0.0, 0.0]),
        Interpolation::Linear,
        SimMethod::default(),
    )
    .unwrap();
    assert!(max_abs(&y, &exact) < 3e-2 * amplitude);
}

#[test]
fn fixed_step_and_adaptive_agree_with_the_models_own_hybrid_simulation() {
    // Every effect of the library at once, on the paper's hopper under the test protocol,
    // noise free. The reference integrates the model's own vector field (lag as a third state,
    // delay inside the commanded force) with the continuous force by DOP853 at rtol 1e-10. The
    // diagnosis sees 100 Hz samples of the force, reads them by a spline, applies the lag to the
    // force exactly and integrates by RK4 (or DOP853): the remaining differences are the
    // spline's (about 1e-4 N at 7 Hz, so about 1e-7 m after the hopper's gain) and RK4's. The
    // position noise of the tests is 2e-6 m; 2e-7 m is a tenth of it.
    let effects = Effects {
        k3: 300.0,
        mu: 0.003,
        c_f: 0.05,
        c2: 1.0,
        tau: 0.005,
        delay: 0.004,
        v_th: 0.005,
        hard_stop: Some(HardStop {
            x_stop: 0.1437,
            k_stop: 1000.0,
        }),
        input_offset: 0.0,
    };
    let protocol = Protocol {
        noise_x: 0.0,
        noise_f: 0.0,
        ..Protocol::default()
    };
    let params = HopperParams::paper();
    let record = generate(&protocol, params, effects, None, 0);
    let n = record.len();
    let truth = Hopper::with_effects(params, DamperLaw::Switching, effects)
        .unwrap()
        .initial_guess();
    let model = FittedModel {
        params: HopperParams {
            forcing_amplitude: 0.0,
            ..params
        },
        damper: DamperLaw::Switching,
        effects,
        sensor: Sensor::default(),
    };
    for sim in [SimMethod::default(), SimMethod::Adaptive { rtol: 1e-10 }] {
        let y = simulate_record(
            &record,
            &model,
            0..n,
            Some([truth[0], truth[1]]),
            Interpolation::CubicSpline,
            sim,
        )
        .unwrap();
        let err = max_abs(&y, record.output());
        assert!(err < 2e-7, "{sim:?}: max error {err}");
    }
    // Started from the state estimated from the data instead, the estimate's error (a local
    // cubic over +-4 samples) decays with the damping (time constant 2 s): after 10 s the RMS
    // error is about 3e-9 m; 2e-8 m allows for it.
    let y = simulate_record(
        &record,
        &model,
        0..n,
        None,
        Interpolation::CubicSpline,
        SimMethod::default(),
    )
    .unwrap();
    assert!(rms(&y[1000..], &record.output()[1000..]) < 2e-8);
}

#[test]
fn the_fixed_step_simulation_sticks_with_coulomb_friction_as_the_independent_truth() {
    // Coulomb friction of 0.5 N on the paper's hopper: at the turning points the spring,
    // gravity and forcing stay inside the friction band for a while and the mass sticks. The
    // truth is `htfid-truth` (its own equations, Dormand-Prince at 1e-12 with Filippov
    // sticking, written without this crate's code), noise free at 100 Hz, 20 s after 10 s of
    // settling. The diagnosis reads the force by a spline and steps RK4 with located switches
    // and sliding: as in the test above, the spline's error (about 1e-7 m after the hopper's
    // gain) dominates; 2e-7 m is a tenth of the tests' position noise.
    use htfid_truth::{
        generate, simulate_scenario, Effect, Excitation, Friction, Scenario, SimOptions,
    };
    let scenario = Scenario {
        effects: vec![Effect::CoulombFriction { mu: 0.5 }],
        excitation: Excitation::PaperChirps,
        settle_s: 10.0,
        record_s: 20.0,
        ..Scenario::default()
    };
    let (_, traj) = simulate_scenario(&scenario, &SimOptions::default()).unwrap();
    let sticks = traj
        .events
        .iter()
        .filter(|e| e.to.friction == Friction::Stick)
        .count();
    assert!(sticks >= 10, "the scenario must stick ({sticks} sticks)");
    let truth = generate(&scenario).unwrap();
    let record = TimeSeries::new(truth.t, truth.f, truth.x, "test").unwrap();
    let n = record.len();
    let model = FittedModel {
        params: HopperParams {
            forcing_amplitude: 0.0,
            ..HopperParams::paper()
        },
        damper: DamperLaw::Switching,
        effects: Effects {
            mu: 0.5,
            ..Effects::default()
        },
        sensor: Sensor::default(),
    };
    let start = [traj.states[0][0], traj.states[0][1]];
    let y = simulate_record(
        &record,
        &model,
        0..n,
        Some(start),
        Interpolation::CubicSpline,
        SimMethod::default(),
    )
    .unwrap();
    let err = max_abs(&y, record.output());
    eprintln!("max error against the truth through {sticks} sticks: {err:e} m");
    assert!(err < 2e-7, "max error {err}");
}
