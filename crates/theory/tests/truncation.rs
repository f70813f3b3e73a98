//! The truncated harmonic state space HTF: convergence to the exact HTF for
//! a switched (square-wave) system, and against brute-force RK4 for a smooth
//! LTP system.

mod common;

use common::BruteLtp;
use htfid_ltp::{fft_fourier_fn, Piece, PiecewiseLti};
use htfid_theory::{ExactHtf, FourierLtp, HarmonicTransferFunction, TheoryError, TruncatedHtf};
use nalgebra::{dmatrix, dvector, DMatrix, Matrix2, RowDVector, RowVector2, Vector2};
use std::f64::consts::TAU;

fn hopper(jump: Option<DMatrix<f64>>) -> PiecewiseLti {
    let (k, c, t_on, t_off) = (200.0, 2.0, 0.23, 0.71);
    let piece = |duration: f64, damping: f64| {
        Piece::siso(
            duration,
            dmatrix![0.0, 1.0; -k, -damping],
            dvector![0.0, 1.0],
            RowDVector::from_row_slice(&[1.0, 0.0]),
            0.0,
        )
    };
    let mut on = piece(t_off - t_on, c);
    if let Some(j) = jump {
        on = on.with_jump(j);
    }
    PiecewiseLti::new(1.0, t_on, vec![on, piece(1.0 - (t_off - t_on), 0.0)]).expect("valid")
}

/// Worst `|G_n^N - G_n| / max|G|` over |n| <= 10 and a few output
/// frequencies (below, near and above the ~14 rad/s resonance).
fn truncation_error(exact: &ExactHtf, lti: &PiecewiseLti, n_trunc: usize) -> f64 {
    let omegas = [3.0, 9.0, 14.0, 20.0, 33.0];
    let ks: Vec<i32> = (-10..=10).collect();
    let truth = exact.grid(&ks, &omegas);
    let trunc = TruncatedHtf::new(lti, n_trunc)
        .expect("htf")
        .grid(&ks, &omegas);
    let scale = truth.max_abs();
    truth
        .values
        .iter()
        .zip(&trunc.values)
        .map(|(a, b)| (a - b).norm() / scale)
        .fold(0.0, f64::max)
}

#[test]
fn truncation_error_table() {
    // Measured (see the crate docs and examples/truncation_table.rs):
    // N = 5: 3.6e-3 (harmonics 6..10 are missing entirely), 10: 4.8e-5,
    // 20: 5.3e-6, 40: 7.7e-7, i.e. ~N^-3 once N >= 10. The asserts pin the
    // monotone decrease, the 1e-4 target at N = 10, and an algebraic rate of
    // at least N^-2 per doubling (measured ~N^-3); geometric convergence is
    // impossible with square-wave coefficients.
    let lti = hopper(None);
    let exact = ExactHtf::new(&lti).expect("htf");
    let errs: Vec<f64> = [5, 10, 20, 40]
        .iter()
        .map(|&n| truncation_error(&exact, &lti, n))
        .collect();
    for w in errs.windows(2) {
        assert!(w[1] < w[0], "not decreasing: {errs:?}");
    }
    assert!(errs[1] < 1e-4, "N = 10: {:e}", errs[1]);
    assert!(errs[2] / errs[3] > 4.0, "rate: {errs:?}");
    assert!(errs[1] / errs[2] > 4.0, "rate: {errs:?}");
    // ...but it is algebraic, not geometric: doubling N gains < 64x.
    assert!(errs[2] / errs[3] < 64.0, "rate: {errs:?}");
}

#[test]
fn truncated_rejects_jumps() {
    let lti = hopper(Some(dmatrix![1.0, 0.0; 0.3, 1.0]));
    let err = TruncatedHtf::new(&lti, 10).expect_err("jumps are not representable");
    assert_eq!(err, TheoryError::JumpNotRepresentable { piece: 0 });
}

const KS: f64 = 200.0;
const CS: f64 = 2.0;
const DEPTH: f64 = 0.3;

fn smooth_a(t: f64) -> Matrix2<f64> {
    Matrix2::new(0.0, 1.0, -KS * (1.0 + DEPTH * (TAU * t).cos()), -CS)
}

fn smooth_matrices(_seg: usize, t: f64) -> (Matrix2<f64>, Vector2<f64>, RowVector2<f64>, f64) {
    (
        smooth_a(t),
        Vector2::new(0.0, 1.0),
        RowVector2::new(1.0, 0.0),
        0.0,
    )
}

fn smooth_fourier_ltp() -> FourierLtp {
    // 16 samples resolve the trigonometric polynomial exactly (harmonics
    // |n| <= 1 only, no aliasing below n = 15).
    let a = fft_fourier_fn(1.0, 16, |t| {
        let m = smooth_a(t);
        DMatrix::from_row_slice(2, 2, &[m[(0, 0)], m[(0, 1)], m[(1, 0)], m[(1, 1)]])
    })
    .expect("fft");
    let b = fft_fourier_fn(1.0, 16, |_| dmatrix![0.0; 1.0]).expect("fft");
    let c = fft_fourier_fn(1.0, 16, |_| dmatrix![1.0, 0.0]).expect("fft");
    let d = fft_fourier_fn(1.0, 16, |_| dmatrix![0.0]).expect("fft");
    FourierLtp::new(a, b, c, d).expect("consistent")
}

#[test]
fn smooth_ltp_truncated_matches_rk4() {
    // A(t) with a single cosine: its harmonic state space is block
    // tridiagonal and truncation converges geometrically, so N = 20 is exact
    // to rounding. The RK4 reference (step 1e-4, rates <= ~45 rad/s) is good
    // to ~1e-10 relative (see brute_force.rs), hence 1e-8 of max|G|.
    let htf = TruncatedHtf::from_coefficients(&smooth_fourier_ltp(), 20).expect("htf");
    let brute = BruteLtp {
        period: 1.0,
        bounds: vec![0.0, 1.0],
        jumps: vec![Matrix2::identity()],
        matrices: &smooth_matrices,
    };
    let ks: Vec<i32> = (-6..=6).collect();
    let mut pairs = Vec::new();
    for w0 in [1.1, 8.0, 14.5, 23.0] {
        let truth = brute.harmonics(w0, &ks, 1e-4);
        for (i, &k) in ks.iter().enumerate() {
            pairs.push((truth[i], htf.g(k, w0 + f64::from(k) * TAU)));
        }
    }
    let scale = pairs.iter().map(|(t, _)| t.norm()).fold(0.0, f64::max);
    for (t, g) in &pairs {
        assert!((t - g).norm() < 1e-8 * scale, "{t} vs {g}");
    }
}

#[test]
fn smooth_ltp_truncation_converges_geometrically() {
    // Error against N = 40 (converged). Measured: 8.5e-7 at N = 5 and
    // 3e-17 at N = 10, geometric convergence, in contrast to the switched
    // system's ~N^-3 (1e-5 and 1e-12 leave margin for rounding).
    let sys = smooth_fourier_ltp();
    let omegas = [2.0, 14.0, 30.0];
    let ks: Vec<i32> = (-3..=3).collect();
    let reference = TruncatedHtf::from_coefficients(&sys, 40)
        .expect("htf")
        .grid(&ks, &omegas);
    let scale = reference.max_abs();
    let err = |n: usize| {
        let g = TruncatedHtf::from_coefficients(&sys, n)
            .expect("htf")
            .grid(&ks, &omegas);
        g.values
            .iter()
            .zip(&reference.values)
            .map(|(a, b)| (a - b).norm() / scale)
            .fold(0.0, f64::max)
    };
    let (e5, e10) = (err(5), err(10));
    assert!(e5 < 1e-5, "N = 5: {e5:e}");
    assert!(e10 < 1e-12, "N = 10: {e10:e}");
}
