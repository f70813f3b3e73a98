//! `OrbitHtf` (the linearisation integrated along the orbit by the hybrid integrator) against
//! truth computed elsewhere: the closed-form piecewise HTF and the independent Python reference
//! for the paper's hopper, Wereley's harmonic state space for a Mathieu oscillator (smooth
//! `A(t)`), and small-signal simulation of a nonlinear hybrid oscillator whose switches have
//! non-identity saltation matrices on a guard that moves in time.

mod small_signal;

use htfid_hybrid::{simulate, Crossing, HybridSystem, Options};
use htfid_ltp::{fft_fourier_fn, linearise, InputOutput};
use htfid_model::{Hopper, HopperParams};
use htfid_orbit::{find_limit_cycle, LimitCycle, ShootingOptions};
use htfid_theory::{
    ExactHtf, FourierLtp, HarmonicTransferFunction, OrbitHtf, TheoryError, TruncatedHtf,
};
use nalgebra::dmatrix;
use num_complex::Complex64;
use small_signal::Projected;
use std::f64::consts::TAU;

fn tight() -> Options {
    Options {
        rtol: 1e-12,
        atol: 1e-14,
        ..Options::default()
    }
}

fn paper_hopper() -> (Hopper, LimitCycle<htfid_model::HopperMode>) {
    let hopper = Hopper::new(HopperParams::paper()).unwrap();
    let orbit = hopper
        .limit_cycle(&ShootingOptions::default(), &tight())
        .unwrap();
    (hopper, orbit.cycle)
}

#[test]
fn hopper_matches_the_closed_form_piecewise_htf() {
    let (hopper, cycle) = paper_hopper();
    let lin = linearise(&hopper, &cycle, 16, &tight()).unwrap();
    let exact = ExactHtf::new(&lin.piecewise).unwrap();
    let orbit = OrbitHtf::new(&hopper, &cycle, &tight()).unwrap();
    let harmonics: Vec<i32> = (-3..=3).collect();
    let omegas: Vec<f64> = (0..20).map(|i| 1.0 + 39.0 * f64::from(i) / 19.0).collect();
    let want = exact.grid(&harmonics, &omegas);
    let got = orbit.grid(&harmonics, &omegas);
    let max_g = want.max_abs();
    let err = got
        .values
        .iter()
        .zip(&want.values)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max)
        / max_g;
    println!("hopper: OrbitHtf vs ExactHtf, worst / max|G| = {err:.2e}");
    // The hopper's A is constant per chart and S = I, so the piecewise model is exact; what
    // remains is the integrator (rtol 1e-12) and the event times (event_tol 1e-12 s).
    assert!(err < 1e-9, "worst deviation {err:e} of max|G| {max_g:e}");
    // `g` and `grid` agree.
    assert!((orbit.g(2, omegas[7]) - got.get(7, 5).unwrap()).norm() < 1e-14 * max_g);
}

#[test]
fn hopper_matches_the_independent_python_reference() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../tests/oracle/hopper_reference.json"
    ))
    .unwrap();
    let reference: serde_json::Value = serde_json::from_str(&text).unwrap();
    let (hopper, cycle) = paper_hopper();
    let orbit = OrbitHtf::new(&hopper, &cycle, &tight()).unwrap();
    let parse = |r: &serde_json::Value| {
        (
            r["omega"].as_f64().unwrap(),
            r["n"].as_i64().unwrap() as i32,
            Complex64::new(r["re"].as_f64().unwrap(), r["im"].as_f64().unwrap()),
        )
    };
    let rows: Vec<_> = reference["htf"]
        .as_array()
        .unwrap()
        .iter()
        .chain(reference["htf_n10_at_13_5"].as_array().unwrap())
        .map(parse)
        .collect();
    let max_g = rows.iter().map(|r| r.2.norm()).fold(0.0, f64::max);
    assert!(rows.len() >= 90);
    let mut worst: f64 = 0.0;
    for (w, n, want) in rows {
        worst = worst.max((orbit.g(n, w) - want).norm() / max_g);
    }
    println!("hopper: OrbitHtf vs Python reference, worst / max|G| = {worst:.2e}");
    // The reference is good to ~1e-14 of max|G|; the integrator (rtol 1e-12) leaves ~1e-11.
    assert!(worst < 1e-8, "{worst:e}");
}

/// `x'' + c x' + (k + b cos(wp t)) x = u`, outputs `(x, x')`: one chart, no guards, `A(t)`
/// varying continuously. The orbit is `x = 0`.
struct Mathieu {
    c: f64,
    k: f64,
    b: f64,
    wp: f64,
}

impl Mathieu {
    fn stiffness(&self, t: f64) -> f64 {
        self.k + self.b * (self.wp * t).cos()
    }
}

impl HybridSystem for Mathieu {
    type Mode = ();
    fn dim(&self) -> usize {
        2
    }
    fn vector_field(&self, _: (), t: f64, x: &[f64], dx: &mut [f64]) {
        dx[0] = x[1];
        dx[1] = -self.c * x[1] - self.stiffness(t) * x[0];
    }
}

impl InputOutput for Mathieu {
    fn input_gain(&self, _: (), _t: f64, _x: &[f64], b: &mut [f64]) {
        b[0] = 0.0;
        b[1] = 1.0;
    }
    fn num_outputs(&self) -> usize {
        2
    }
    fn output_gain(&self, _: (), _t: f64, _x: &[f64], c: &mut [f64]) {
        c.copy_from_slice(&[1.0, 0.0, 0.0, 1.0]);
    }
}

#[test]
fn mathieu_oscillator_matches_the_harmonic_state_space() {
    let sys = Mathieu {
        c: 1.0,
        k: 30.0,
        b: 12.0,
        wp: TAU,
    };
    let cycle = find_limit_cycle(
        &sys,
        (),
        0.0,
        &[0.0, 0.0],
        1.0,
        &ShootingOptions::default(),
        &tight(),
    )
    .unwrap();
    let orbit = OrbitHtf::new(&sys, &cycle, &tight()).unwrap();
    // Truth: Wereley's harmonic state space. A(t) has harmonics 0, +-1 only, so 16 samples
    // give its Fourier series exactly and the truncation error falls geometrically
    // (3e-17 at N = 10 for a single cosine, crate docs); N = 30 leaves nothing.
    let series = |f: &dyn Fn(f64) -> nalgebra::DMatrix<f64>| fft_fourier_fn(1.0, 16, f).unwrap();
    let a = series(&|t| dmatrix![0.0, 1.0; -sys.stiffness(t), -sys.c]);
    let b = series(&|_| dmatrix![0.0; 1.0]);
    let d = series(&|_| dmatrix![0.0]);
    let truth: Vec<TruncatedHtf> = [dmatrix![1.0, 0.0], dmatrix![0.0, 1.0]]
        .into_iter()
        .map(|c_row| {
            let c = series(&|_| c_row.clone());
            let ltp = FourierLtp::new(a.clone(), b.clone(), c, d.clone()).unwrap();
            TruncatedHtf::from_coefficients(&ltp, 30).unwrap()
        })
        .collect();
    let harmonics: Vec<i32> = (-4..=4).collect();
    // 3 + wp and 3 + 2 wp share input frequencies with 3: those grid points share
    // integrations in `grids`, which must not mix up their harmonics.
    let omegas = [0.5, 3.0, 3.0 + TAU, 5.5, 7.0, 3.0 + 2.0 * TAU, 17.5, 26.0];
    let grids = orbit.grids(&harmonics, &omegas).unwrap();
    assert_eq!(grids.len(), 2);
    for (o, (got, truth)) in grids.iter().zip(&truth).enumerate() {
        let want = truth.grid(&harmonics, &omegas);
        let max_g = want.max_abs();
        let err = got
            .values
            .iter()
            .zip(&want.values)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max)
            / max_g;
        println!("Mathieu output {o}: worst / max|G| = {err:.2e}");
        // Integrator at rtol 1e-12 over one period, and the solve with the monodromy.
        assert!(err < 1e-9, "output {o}: {err:e}");
        // The parametric term really couples harmonics.
        assert!(want.harmonic(1).unwrap()[2].norm() > 1e-2 * max_g);
    }
    // The channel view reads output 1.
    let velocity = orbit.channel(1).unwrap();
    let w = 5.5;
    assert!((velocity.g(-1, w) - truth[1].g(-1, w)).norm() < 1e-9 * truth[1].g(0, w).norm());
    assert_eq!(
        orbit.channel(2).unwrap_err(),
        TheoryError::OutputOutOfRange {
            output: 2,
            n_outputs: 2
        }
    );
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Damper {
    On,
    Off,
}

/// `x'' = -k x - k3 x^3 - c s x' + a cos(wp t) + u`, `s = 1` while `x' > v_th(t)` with a
/// threshold `v_th(t) = v0 + v1 sin(wp t)` that moves in time. The damper force `c v_th` jumps
/// at each switch, so the saltation matrices differ from the identity; the cubic spring makes
/// `A(t)` vary continuously along the orbit. Outputs `(x, x')`.
struct Threshold {
    k: f64,
    k3: f64,
    c: f64,
    a: f64,
    v0: f64,
    v1: f64,
    wp: f64,
    exact_dhdt: bool,
    /// `u = eps cos(w0 t)` as `(eps, w0)`.
    input: Option<(f64, f64)>,
}

impl Threshold {
    fn new() -> Self {
        Threshold {
            k: 200.0,
            k3: 1e6,
            c: 2.0,
            a: 1.0,
            v0: 0.01,
            v1: 0.005,
            wp: TAU,
            exact_dhdt: true,
            input: None,
        }
    }

    fn damping(&self, mode: Damper) -> f64 {
        match mode {
            Damper::On => self.c,
            Damper::Off => 0.0,
        }
    }
}

impl HybridSystem for Threshold {
    type Mode = Damper;
    fn dim(&self) -> usize {
        2
    }
    fn vector_field(&self, mode: Damper, t: f64, x: &[f64], dx: &mut [f64]) {
        let u = self.input.map_or(0.0, |(eps, w0)| eps * (w0 * t).cos());
        dx[0] = x[1];
        dx[1] = -self.k * x[0] - self.k3 * x[0].powi(3) - self.damping(mode) * x[1]
            + self.a * (self.wp * t).cos()
            + u;
    }
    fn num_guards(&self, _: Damper) -> usize {
        1
    }
    fn guard(&self, _: Damper, _: usize, t: f64, x: &[f64]) -> f64 {
        x[1] - self.v0 - self.v1 * (self.wp * t).sin()
    }
    fn guard_time_derivative(&self, _: Damper, _: usize, t: f64, _x: &[f64]) -> Option<f64> {
        self.exact_dhdt
            .then(|| -self.v1 * self.wp * (self.wp * t).cos())
    }
    fn guard_direction(&self, mode: Damper, _: usize) -> Crossing {
        match mode {
            Damper::On => Crossing::Falling,
            Damper::Off => Crossing::Rising,
        }
    }
    fn transition(&self, mode: Damper, _: usize, _t: f64, _x: &mut [f64]) -> Damper {
        match mode {
            Damper::On => Damper::Off,
            Damper::Off => Damper::On,
        }
    }
    fn jacobian(&self, mode: Damper, _t: f64, x: &[f64], jac: &mut [f64]) -> bool {
        jac.copy_from_slice(&[
            0.0,
            1.0,
            -self.k - 3.0 * self.k3 * x[0] * x[0],
            -self.damping(mode),
        ]);
        true
    }
}

impl InputOutput for Threshold {
    fn input_gain(&self, _: Damper, _t: f64, _x: &[f64], b: &mut [f64]) {
        b.copy_from_slice(&[0.0, 1.0]);
    }
    fn num_outputs(&self) -> usize {
        2
    }
    fn output_gain(&self, _: Damper, _t: f64, _x: &[f64], c: &mut [f64]) {
        c.copy_from_slice(&[1.0, 0.0, 0.0, 1.0]);
    }
}

/// Fourier coefficients of both outputs at `omegas` in the steady state driven by
/// `eps cos(w0 t)`: settle `settle` periods from the orbit, then project over `window`.
fn projections(
    cycle: &LimitCycle<Damper>,
    eps: f64,
    w0: f64,
    omegas: &[f64],
    settle: f64,
    window: f64,
) -> Vec<[Complex64; 2]> {
    let opts = Options {
        rtol: 1e-13,
        atol: 1e-16,
        ..Options::default()
    };
    let driven = Threshold {
        input: Some((eps, w0)),
        ..Threshold::new()
    };
    let settled = simulate(&driven, cycle.mode0, 0.0, &cycle.state0, settle, &[], &opts).unwrap();
    let proj = Projected {
        inner: &driven,
        projected: 2,
        omegas,
        window,
    };
    let mut z0 = vec![0.0; proj.dim()];
    z0[..2].copy_from_slice(&settled.final_state);
    let run = simulate(
        &proj,
        settled.final_mode,
        settle,
        &z0,
        settle + window,
        &[],
        &opts,
    )
    .unwrap();
    let f = &run.final_state;
    (0..omegas.len())
        .map(|i| {
            [
                Complex64::new(f[2 + 4 * i], f[3 + 4 * i]),
                Complex64::new(f[4 + 4 * i], f[5 + 4 * i]),
            ]
        })
        .collect()
}

#[test]
fn moving_threshold_damper_matches_small_signal_simulation() {
    let sys = Threshold::new();
    let shooting = ShootingOptions::default();
    let guess = [0.0, 0.0];
    let cycle = find_limit_cycle(&sys, Damper::Off, 0.0, &guess, 1.0, &shooting, &tight()).unwrap();
    assert_eq!(cycle.events.len(), 2, "one switch each way per period");
    let orbit = OrbitHtf::new(&sys, &cycle, &tight()).unwrap();
    // The switches have non-identity saltation matrices, and the orbit stiffens the spring.
    let lin = linearise(&sys, &cycle, 16, &tight()).unwrap();
    assert!(lin.piecewise.has_jumps());
    let amplitude = lin
        .samples
        .iter()
        .map(|s| s.state[0].abs())
        .fold(0.0, f64::max);
    let stiffening = 3.0 * sys.k3 * amplitude * amplitude / sys.k;
    assert!(
        stiffening > 0.1,
        "A(t) varies by {stiffening:.2} of k along the orbit"
    );

    // w0 = 2.25 wp: the response repeats every 4 T, the bins w0 + n wp are orthogonal over
    // that window, and no second-order product 2 w0 + m wp lands on them.
    let wp = TAU;
    let w0 = 2.25 * wp;
    let harmonics: Vec<i32> = (-3..=3).collect();
    let omegas: Vec<f64> = harmonics.iter().map(|&n| w0 + f64::from(n) * wp).collect();
    // The odd part in eps of the projection over eps is G + O(eps^2); Richardson over eps and
    // 2 eps removes the eps^2 term as well.
    let eps = 1e-4;
    let settle = 40.0;
    let odd = |eps: f64| {
        let plus = projections(&cycle, eps, w0, &omegas, settle, 4.0);
        let minus = projections(&cycle, -eps, w0, &omegas, settle, 4.0);
        // u = eps cos(w0 t) puts eps / 2 on exp(j w0 t).
        plus.iter()
            .zip(&minus)
            .map(|(p, m)| [(p[0] - m[0]) / eps, (p[1] - m[1]) / eps])
            .collect::<Vec<_>>()
    };
    let (single, double) = (odd(eps), odd(2.0 * eps));
    let predicted = orbit.response(w0, &harmonics).unwrap();
    let without_exact_dhdt = Threshold {
        exact_dhdt: false,
        ..Threshold::new()
    };
    let fd_predicted = OrbitHtf::new(&without_exact_dhdt, &cycle, &tight())
        .unwrap()
        .response(w0, &harmonics)
        .unwrap();
    for o in 0..2 {
        let max_g = (0..harmonics.len())
            .map(|h| predicted[(o, h)].norm())
            .fold(0.0, f64::max);
        let (mut worst, mut worst_single, mut fd_worst, mut piecewise_worst) =
            (0.0_f64, 0.0_f64, 0.0_f64, 0.0_f64);
        let piecewise = ExactHtf::new(&lin.piecewise.channel(o, 0).unwrap()).unwrap();
        for (h, &n) in harmonics.iter().enumerate() {
            let measured = (4.0 * single[h][o] - double[h][o]) / 3.0;
            let err = |g: Complex64| (measured - g).norm() / max_g;
            worst = worst.max(err(predicted[(o, h)]));
            worst_single = worst_single.max((single[h][o] - predicted[(o, h)]).norm() / max_g);
            fd_worst = fd_worst.max((fd_predicted[(o, h)] - predicted[(o, h)]).norm() / max_g);
            piecewise_worst = piecewise_worst.max(err(piecewise.g(n, omegas[h])));
        }
        println!(
            "threshold damper output {o}: simulation vs OrbitHtf {worst:.2e} \
             (eps = {eps:e} alone {worst_single:.2e}), finite-difference dh/dt vs exact \
             {fd_worst:.2e}, chart-averaged piecewise model {piecewise_worst:.2e} \
             (of max|G| {max_g:.3e})"
        );
        // Budget. Measured without Richardson the error is 7.6e-8 at eps = 1e-4 and grows as
        // eps^2 (1.2e-6 at 4e-4, 2.0e-5 at 1.6e-3): the cubic term, which Richardson removes
        // up to O(eps^4) ~ 1e-12. Left: the runs' integration error (rtol 1e-13 on |x| ~ 1e-2,
        // ~1e-15) over eps |G| ~ 1e-6, ~1e-9 of |G|, and the transient after 40 periods of
        // multipliers ~0.6 (< 1e-9). 2e-8 leaves a factor ~10.
        assert!(worst < 2e-8, "output {o}: {worst:e}");
        assert!(worst_single < 1e-6, "output {o}: {worst_single:e}");
        // A central difference in t for dh/dt (error (wp h)^2 / 6 ~ 2e-10 in the saltation)
        // is all that separates the two HTFs (measured 7e-13).
        assert!(fd_worst < 1e-8, "output {o}: {fd_worst:e}");
        // Averaging A(t) over each chart, as the piecewise-LTI model does, is far off here.
        assert!(piecewise_worst > 1e-3, "output {o}: {piecewise_worst:e}");
    }
}

#[test]
fn constructor_rejects_a_foreign_cycle() {
    let (hopper, cycle) = paper_hopper();
    let short = LimitCycle {
        state0: vec![0.0],
        ..cycle.clone()
    };
    assert_eq!(
        OrbitHtf::new(&hopper, &short, &tight()).unwrap_err(),
        TheoryError::StateDimension {
            expected: 2,
            found: 1
        }
    );
    let moved = LimitCycle {
        state0: vec![cycle.state0[0] + 1e-3, cycle.state0[1]],
        ..cycle.clone()
    };
    let err = OrbitHtf::new(&hopper, &moved, &tight()).unwrap_err();
    assert!(
        matches!(err, TheoryError::NotPeriodic { residual, .. } if residual > 1e-4),
        "{err}"
    );
    let htf = OrbitHtf::new(&hopper, &cycle, &tight()).unwrap();
    assert!(matches!(
        htf.response(f64::NAN, &[0]).unwrap_err(),
        TheoryError::InvalidFrequency { w } if w.is_nan()
    ));
    assert!(htf.g(0, f64::INFINITY).re.is_nan());
    // The recomputed monodromy is the cycle's.
    assert!((htf.monodromy() - &cycle.jacobian).amax() < 1e-9);
}
