//! The hopper's LTP model about its limit cycle, checked against independent truth: the
//! saltation identity, finite differences of the hybrid simulation, Liouville's formula, an
//! independent brute-force HTF computation (tests/oracle, Python), and a small-amplitude
//! simulation of the nonlinear hybrid system itself.

use htfid_hybrid::{simulate, Options};
use htfid_ltp::{linearise, Floquet};
use htfid_model::{DamperLaw, Effects, Hopper, HopperParams};
use htfid_orbit::ShootingOptions;
use htfid_theory::{ExactHtf, HarmonicTransferFunction, TruncatedHtf};
use num_complex::Complex64;

fn tight() -> Options {
    Options {
        rtol: 1e-12,
        atol: 1e-14,
        ..Options::default()
    }
}

fn period_map_fd(hopper: &Hopper, x0: &[f64], period: f64, h: f64) -> [[f64; 2]; 2] {
    let opts = Options {
        rtol: 1e-13,
        atol: 1e-15,
        ..Options::default()
    };
    let flow = |x: &[f64]| {
        simulate(hopper, hopper.mode_of(x[1]), 0.0, x, period, &[], &opts)
            .unwrap()
            .final_state
    };
    let mut m = [[0.0; 2]; 2];
    for j in 0..2 {
        let (mut xp, mut xm) = (x0.to_vec(), x0.to_vec());
        xp[j] += h;
        xm[j] -= h;
        let (fp, fm) = (flow(&xp), flow(&xm));
        for i in 0..2 {
            m[i][j] = (fp[i] - fm[i]) / (2.0 * h);
        }
    }
    m
}

#[test]
fn hopper_saltation_is_identity_and_monodromy_matches_simulation() {
    let hopper = Hopper::new(HopperParams::paper()).unwrap();
    let orbit = hopper
        .limit_cycle(&ShootingOptions::default(), &tight())
        .unwrap();
    let lin = linearise(&hopper, &orbit.cycle, 64, &tight()).unwrap();
    assert_eq!(lin.switches.len(), 2);
    for s in &lin.switches {
        // The damper force c x' vanishes on x' = 0: S = I up to the round-off of the formula.
        let dev = (&s.saltation - nalgebra::DMatrix::identity(2, 2)).amax();
        assert!(dev < 1e-12, "saltation deviates from I by {dev}");
    }
    assert!(!lin.piecewise.has_jumps());
    // Monodromy of the piecewise-LTI model from phase 0 against finite differences of the
    // hybrid simulation's period map (h = 1e-6: see tests/limit_cycle.rs for the error budget).
    let mono = lin.piecewise.monodromy_from(0.0);
    let fd = period_map_fd(&hopper, &orbit.cycle.state0, 1.0, 1e-6);
    for i in 0..2 {
        for j in 0..2 {
            assert!(
                (mono[(i, j)] - fd[i][j]).abs() < 1e-6 * 8.3,
                "M[{i}][{j}] {} vs {}",
                mono[(i, j)],
                fd[i][j]
            );
        }
    }
    // Floquet multipliers of the LTP model equal those of the orbit (issue: 1e-6).
    let floquet = Floquet::new(&lin.piecewise);
    for (a, b) in floquet.multipliers().iter().zip(&orbit.cycle.multipliers) {
        assert!((a - b).norm() < 1e-9, "{a} vs {b}");
    }
    // Liouville: det = exp(-c/m * duty * T).
    let det = mono.determinant();
    assert!((det - (-2.0 * orbit.duty).exp()).abs() < 1e-12);
}

#[test]
fn threshold_damper_has_a_saltation_jump_that_the_ltp_model_needs() {
    // The damper engages at x' > v_th: its force c v_th jumps at the switch, so S != I.
    let effects = Effects {
        v_th: 0.01,
        ..Effects::default()
    };
    let hopper =
        Hopper::with_effects(HopperParams::paper(), DamperLaw::Switching, effects).unwrap();
    let orbit = hopper
        .limit_cycle(&ShootingOptions::default(), &tight())
        .unwrap();
    let lin = linearise(&hopper, &orbit.cycle, 64, &tight()).unwrap();
    assert!(lin.piecewise.has_jumps());
    let fd = period_map_fd(&hopper, &orbit.cycle.state0, 1.0, 1e-6);
    let with_jumps = lin.piecewise.monodromy_from(0.0);
    let err = (0..2)
        .flat_map(|i| (0..2).map(move |j| (i, j)))
        .map(|(i, j)| (with_jumps[(i, j)] - fd[i][j]).abs())
        .fold(0.0, f64::max);
    assert!(
        err < 1e-5,
        "monodromy with saltation jumps vs finite differences: {err}"
    );
    // Dropping the jumps gives a visibly wrong monodromy: the saltation is not cosmetic.
    let pieces: Vec<_> = lin
        .piecewise
        .pieces()
        .iter()
        .map(|p| {
            htfid_ltp::Piece::new(
                p.duration(),
                p.a().clone(),
                p.b().clone(),
                p.c().clone(),
                p.d().clone(),
            )
        })
        .collect();
    let no_jumps = htfid_ltp::PiecewiseLti::new(1.0, lin.piecewise.start(), pieces)
        .unwrap()
        .monodromy_from(0.0);
    let err_no = (0..2)
        .flat_map(|i| (0..2).map(move |j| (i, j)))
        .map(|(i, j)| (no_jumps[(i, j)] - fd[i][j]).abs())
        .fold(0.0, f64::max);
    assert!(err_no > 100.0 * err.max(1e-6), "without jumps: {err_no}");
}

fn paper_htf() -> (ExactHtf, htfid_ltp::PiecewiseLti) {
    let hopper = Hopper::new(HopperParams::paper()).unwrap();
    let orbit = hopper
        .limit_cycle(&ShootingOptions::default(), &tight())
        .unwrap();
    let lin = linearise(&hopper, &orbit.cycle, 16, &tight()).unwrap();
    (ExactHtf::new(&lin.piecewise).unwrap(), lin.piecewise)
}

#[test]
fn exact_htf_matches_independent_brute_force_reference() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../tests/oracle/hopper_reference.json"
    ))
    .unwrap();
    let reference: serde_json::Value = serde_json::from_str(&text).unwrap();
    let (htf, _) = paper_htf();
    let rows = reference["htf"].as_array().unwrap();
    let max_g = rows
        .iter()
        .map(|r| Complex64::new(r["re"].as_f64().unwrap(), r["im"].as_f64().unwrap()).norm())
        .fold(0.0, f64::max);
    assert!(rows.len() >= 70);
    for r in rows {
        let (w, n) = (
            r["omega"].as_f64().unwrap(),
            r["n"].as_i64().unwrap() as i32,
        );
        let want = Complex64::new(r["re"].as_f64().unwrap(), r["im"].as_f64().unwrap());
        let got = htf.g(n, w);
        // Issue: within 1e-7 of max|G| of an independent computation. The reference is good to
        // ~1e-10 of max|G| and our orbit's switch phases to ~1e-12 s.
        assert!(
            (got - want).norm() < 1e-7 * max_g,
            "G_{n}({w}): {got} vs {want}"
        );
    }
    // The slow decay at 13.5 rad/s, harmonics -10..10.
    for r in reference["htf_n10_at_13_5"].as_array().unwrap() {
        let (w, n) = (
            r["omega"].as_f64().unwrap(),
            r["n"].as_i64().unwrap() as i32,
        );
        let want = Complex64::new(r["re"].as_f64().unwrap(), r["im"].as_f64().unwrap());
        assert!((htf.g(n, w) - want).norm() < 1e-7 * max_g, "G_{n}({w})");
    }
}

#[test]
fn truncated_htf_converges_to_the_exact_one() {
    let (exact, lti) = paper_htf();
    let omegas = [3.0, 9.0, 13.5, 20.0];
    let harmonics: Vec<i32> = (-3..=3).collect();
    let max_g = exact.grid(&harmonics, &omegas).max_abs();
    let err = |n_trunc: usize| {
        let t = TruncatedHtf::new(&lti, n_trunc).unwrap();
        let mut e: f64 = 0.0;
        for &w in &omegas {
            for &n in &harmonics {
                e = e.max((t.g(n, w) - exact.g(n, w)).norm());
            }
        }
        e / max_g
    };
    let (e10, e20, e40) = (err(10), err(20), err(40));
    // Issue: within 1e-4 of max|G| at N = 10, converging as N grows (the square wave's 1/n
    // coefficients give roughly N^-3 for the position output).
    assert!(e10 < 1e-4, "N = 10: {e10}");
    assert!(e20 < e10 / 4.0 && e40 < e20 / 4.0, "{e10} {e20} {e40}");
}

/// The nonlinear hybrid hopper, driven by a small cosine, against the HTF of its linearisation.
#[test]
fn small_signal_response_of_the_hybrid_system_matches_the_htf() {
    let p = HopperParams::paper();
    let hopper = Hopper::new(p).unwrap();
    let opts = tight();
    let orbit = hopper
        .limit_cycle(&ShootingOptions::default(), &opts)
        .unwrap();
    let (htf, _) = paper_htf();
    let wp = p.pump_frequency();
    // w0 = 2.25 wp: the response repeats every 4 T, and 2 w0 is not a multiple of wp, so
    // second-order products do not land on the bins of the linear response.
    let w0 = 2.25 * wp;
    let eps = 1e-5;
    let input: htfid_model::InputFn = std::sync::Arc::new(move |t: f64| eps * (w0 * t).cos());
    let driven = hopper.with_input(Some(input));
    // Settle 40 periods (|mu| = 0.6 per period: 0.6^40 ~ 1e-9), then record 8 T.
    let (settle, window, samples) = (40.0, 8.0, 8 * 512);
    let grid: Vec<f64> = (0..samples)
        .map(|i| settle + window * i as f64 / samples as f64)
        .collect();
    let forced = simulate(
        &driven,
        orbit.cycle.mode0,
        0.0,
        &orbit.cycle.state0,
        settle + window,
        &grid,
        &opts,
    )
    .unwrap();
    let free = simulate(
        &hopper,
        orbit.cycle.mode0,
        0.0,
        &orbit.cycle.state0,
        settle + window,
        &grid,
        &opts,
    )
    .unwrap();
    let max_g = htf
        .grid(
            &[-3, -2, -1, 0, 1, 2, 3],
            &[w0 - 3.0 * wp, w0, w0 + 3.0 * wp],
        )
        .max_abs();
    for n in -3..=3 {
        let w = w0 + n as f64 * wp;
        // DFT of the deviation at frequency w over whole periods of the response (exact for
        // a periodic signal sampled finely: 512 samples per period resolve the damper switch's
        // kink well enough for the tolerance below).
        let mut acc = Complex64::new(0.0, 0.0);
        for (i, &t) in grid.iter().enumerate() {
            let dy = forced.state(i)[0] - free.state(i)[0];
            acc += dy * Complex64::from_polar(1.0, -w * t);
        }
        let measured = acc / samples as f64 * 2.0 / eps;
        let predicted = htf.g(n, w);
        // Second-order effects are ~eps * |G|^2 / |x| ~ 1e-8 relative; the rectangle-rule DFT
        // of the kinked response adds ~1e-7.
        assert!(
            (measured - predicted).norm() < 2e-6 * max_g,
            "n = {n}: simulated {measured} vs HTF {predicted} (max |G| {max_g})"
        );
    }
}
