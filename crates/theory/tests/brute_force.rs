//! The exact HTF against brute-force RK4 simulation of the LTP ODE.
//!
//! Tolerance 1e-8 of max|G|: the RK4 step is at most 1e-4 and the fastest
//! rate in the simulated state is |w0 + harmonic content| <= ~45 rad/s, so
//! `w h <= 4.5e-3` and RK4's global error `~ (w h)^4 / 120 * w T` stays
//! below ~2e-10 relative; composite Simpson on the same grid adds
//! `~ (w h)^4 / 180 < 1e-11` for the output harmonics up to |k| = 10
//! (k wp <= 63 rad/s gives (w h)^4 / 180 < 1e-11 too). Together well under
//! 1e-8, so a failure means a wrong exact HTF, not a loose reference.

mod common;

use common::{hopper_matrices, BruteLtp};
use htfid_ltp::{Piece, PiecewiseLti};
use htfid_theory::{ExactHtf, ExactMethod, HarmonicTransferFunction};
use nalgebra::{dmatrix, dvector, Matrix2, RowDVector, RowVector2, Vector2};
use num_complex::Complex64;
use std::f64::consts::TAU;

const K: f64 = 200.0;
const C: f64 = 2.0;
const T_ON: f64 = 0.23;
const T_OFF: f64 = 0.71;
const H_MAX: f64 = 1e-4;
/// Input frequencies (rad/s): below, at and above the stance/flight
/// resonances near sqrt(200) = 14.1 rad/s, and off the harmonic grid.
const W_INPUTS: [f64; 5] = [0.7, 9.3, 14.2, 21.0, 37.5];

fn hopper_piece(duration: f64, damper_on: bool) -> Piece {
    let damping = if damper_on { C } else { 0.0 };
    Piece::siso(
        duration,
        dmatrix![0.0, 1.0; -K, -damping],
        dvector![0.0, 1.0],
        RowDVector::from_row_slice(&[1.0, 0.0]),
        0.0,
    )
}

/// Damper on during [T_ON, T_OFF) of T = 1, as two pieces wrapping modulo T.
fn hopper_lti() -> PiecewiseLti {
    PiecewiseLti::new(
        1.0,
        T_ON,
        vec![
            hopper_piece(T_OFF - T_ON, true),
            hopper_piece(1.0 - (T_OFF - T_ON), false),
        ],
    )
    .expect("valid hopper")
}

fn hopper_brute_matrices(
    seg: usize,
    _t: f64,
) -> (Matrix2<f64>, Vector2<f64>, RowVector2<f64>, f64) {
    hopper_matrices(K, C, seg == 1)
}

fn hopper_brute(jumps: Vec<Matrix2<f64>>) -> BruteLtp<'static> {
    BruteLtp {
        period: 1.0,
        bounds: vec![0.0, T_ON, T_OFF, 1.0],
        jumps,
        matrices: &hopper_brute_matrices,
    }
}

fn harmonics() -> Vec<i32> {
    (-10..=10).collect()
}

/// Compares `ExactHtf::response`, `g` and `grid` with the brute force over
/// `W_INPUTS` and |k| <= 10; returns the worst error relative to max|G|.
fn worst_relative_error(htf: &ExactHtf, brute: &BruteLtp<'_>) -> f64 {
    let ks = harmonics();
    let wp = htf.pumping_frequency();
    let mut pairs = Vec::new();
    for &w0 in &W_INPUTS {
        let truth = brute.harmonics(w0, &ks, H_MAX);
        let got = htf.response(w0, &ks);
        for (i, &k) in ks.iter().enumerate() {
            // Estimation convention: G_k at output frequency w0 + k wp.
            let w_out = w0 + f64::from(k) * wp;
            let via_g = htf.g(k, w_out);
            let via_grid = htf.grid(&[k], &[w_out]).values[0];
            pairs.push((truth[i], got[i]));
            pairs.push((truth[i], via_g));
            pairs.push((truth[i], via_grid));
        }
    }
    let scale = pairs.iter().map(|(t, _)| t.norm()).fold(0.0, f64::max);
    pairs
        .iter()
        .map(|(t, g)| (t - g).norm() / scale)
        .fold(0.0, f64::max)
}

#[test]
fn hopper_exact_matches_rk4() {
    let htf = ExactHtf::new(&hopper_lti()).expect("htf");
    assert_eq!(htf.method(), ExactMethod::Modal);
    let err = worst_relative_error(&htf, &hopper_brute(vec![Matrix2::identity(); 3]));
    assert!(err < 1e-8, "exact vs RK4: {err:e}");
}

#[test]
fn hopper_block_exponential_matches_rk4() {
    let htf = ExactHtf::with_method(&hopper_lti(), ExactMethod::BlockExponential).expect("htf");
    assert_eq!(htf.method(), ExactMethod::BlockExponential);
    let err = worst_relative_error(&htf, &hopper_brute(vec![Matrix2::identity(); 3]));
    assert!(err < 1e-8, "block exponential vs RK4: {err:e}");
}

fn jump_lti() -> PiecewiseLti {
    let j_on = dmatrix![1.0, 0.0; 0.3, 1.0];
    let j_off = dmatrix![0.9, 0.05; 0.0, 1.1];
    PiecewiseLti::new(
        1.0,
        T_ON,
        vec![
            hopper_piece(T_OFF - T_ON, true).with_jump(j_on),
            hopper_piece(1.0 - (T_OFF - T_ON), false).with_jump(j_off),
        ],
    )
    .expect("valid")
}

#[test]
fn jumps_match_rk4_with_impulsive_resets() {
    let lti = jump_lti();
    let brute = hopper_brute(vec![
        Matrix2::identity(),
        Matrix2::new(1.0, 0.0, 0.3, 1.0),
        Matrix2::new(0.9, 0.05, 0.0, 1.1),
    ]);
    for method in [ExactMethod::Modal, ExactMethod::BlockExponential] {
        let htf = ExactHtf::with_method(&lti, method).expect("htf");
        let err = worst_relative_error(&htf, &brute);
        assert!(err < 1e-8, "{method:?} with jumps vs RK4: {err:e}");
    }
}

/// Per-piece B, C and D all differ, so every term of the closed-form output
/// integral (homogeneous, forced, feedthrough) is exercised.
fn mixed_lti() -> PiecewiseLti {
    let p0 = Piece::siso(
        0.35,
        dmatrix![0.0, 1.0; -150.0, -3.0],
        dvector![0.2, 1.0],
        RowDVector::from_row_slice(&[1.0, 0.1]),
        0.05,
    );
    let p1 = Piece::siso(
        0.4,
        dmatrix![-1.0, 1.0; -250.0, 0.0],
        dvector![0.0, 0.7],
        RowDVector::from_row_slice(&[0.5, 0.0]),
        0.0,
    )
    .with_jump(dmatrix![1.0, 0.0; -0.2, 0.8]);
    let p2 = Piece::siso(
        0.25,
        dmatrix![0.0, 1.0; -200.0, -0.5],
        dvector![0.0, 1.3],
        RowDVector::from_row_slice(&[1.2, -0.02]),
        -0.1,
    );
    PiecewiseLti::new(1.0, 0.0, vec![p0, p1, p2]).expect("valid")
}

fn mixed_matrices(seg: usize, _t: f64) -> (Matrix2<f64>, Vector2<f64>, RowVector2<f64>, f64) {
    match seg {
        0 => (
            Matrix2::new(0.0, 1.0, -150.0, -3.0),
            Vector2::new(0.2, 1.0),
            RowVector2::new(1.0, 0.1),
            0.05,
        ),
        1 => (
            Matrix2::new(-1.0, 1.0, -250.0, 0.0),
            Vector2::new(0.0, 0.7),
            RowVector2::new(0.5, 0.0),
            0.0,
        ),
        _ => (
            Matrix2::new(0.0, 1.0, -200.0, -0.5),
            Vector2::new(0.0, 1.3),
            RowVector2::new(1.2, -0.02),
            -0.1,
        ),
    }
}

#[test]
fn per_piece_b_c_d_and_jump_match_rk4() {
    let brute = BruteLtp {
        period: 1.0,
        bounds: vec![0.0, 0.35, 0.75, 1.0],
        jumps: vec![
            Matrix2::identity(),
            Matrix2::new(1.0, 0.0, -0.2, 0.8),
            Matrix2::identity(),
        ],
        matrices: &mixed_matrices,
    };
    for method in [ExactMethod::Modal, ExactMethod::BlockExponential] {
        let htf = ExactHtf::with_method(&mixed_lti(), method).expect("htf");
        let err = worst_relative_error(&htf, &brute);
        assert!(err < 1e-8, "{method:?} mixed vs RK4: {err:e}");
    }
}

#[test]
fn modal_and_block_exponential_agree_on_a_dense_grid() {
    // Two independent integrations of the same closed-form problem; both are
    // accurate to ~1e-13 relative, so 1e-10 of max|G| leaves margin for
    // the eigenvector condition (~10 here) and the scaling-and-squaring.
    let lti = jump_lti();
    let modal = ExactHtf::with_method(&lti, ExactMethod::Modal).expect("modal");
    let block = ExactHtf::with_method(&lti, ExactMethod::BlockExponential).expect("block");
    let omegas: Vec<f64> = (0..300)
        .map(|i| -60.0 + 0.4 * f64::from(i) + 0.013)
        .collect();
    let ks = harmonics();
    let a = modal.grid(&ks, &omegas);
    let b = block.grid(&ks, &omegas);
    let scale = a.max_abs();
    for (x, y) in a.values.iter().zip(&b.values) {
        assert!((x - y).norm() < 1e-10 * scale, "{x} vs {y}");
    }
}

#[test]
fn wrapped_and_unwrapped_descriptions_agree() {
    // The same hopper written as three pieces starting at t = 0: the wrap
    // handling of the two-piece form must not change anything.
    let unwrapped = PiecewiseLti::new(
        1.0,
        0.0,
        vec![
            hopper_piece(T_ON, false),
            hopper_piece(T_OFF - T_ON, true),
            hopper_piece(1.0 - T_OFF, false),
        ],
    )
    .expect("valid");
    let a = ExactHtf::new(&hopper_lti()).expect("htf");
    let b = ExactHtf::new(&unwrapped).expect("htf");
    let omegas: Vec<f64> = (1..200).map(|i| 0.25 * f64::from(i)).collect();
    let ks = harmonics();
    let ga = a.grid(&ks, &omegas);
    let gb = b.grid(&ks, &omegas);
    let scale = ga.max_abs();
    for (x, y) in ga.values.iter().zip(&gb.values) {
        assert!((x - y).norm() < 1e-11 * scale);
    }
}

#[test]
fn time_shift_rotates_harmonics() {
    // Delaying the switching pattern by d multiplies G_n by exp(-j n wp d)
    // (substitute t -> t - d in the convention's definition): an identity
    // independent of how G is computed.
    let d = 0.137;
    let shifted = PiecewiseLti::new(
        1.0,
        T_ON + d,
        vec![
            hopper_piece(T_OFF - T_ON, true),
            hopper_piece(1.0 - (T_OFF - T_ON), false),
        ],
    )
    .expect("valid");
    let a = ExactHtf::new(&hopper_lti()).expect("htf");
    let b = ExactHtf::new(&shifted).expect("htf");
    let wp = TAU;
    for n in -5..=5 {
        for w in [3.0, 14.0, 25.5] {
            let rot = Complex64::from_polar(1.0, -f64::from(n) * wp * d);
            let want = a.g(n, w) * rot;
            let got = b.g(n, w);
            assert!(
                (want - got).norm() < 1e-12 * (1.0 + want.norm()),
                "n={n} w={w}"
            );
        }
    }
}

fn critical_matrices(seg: usize, _t: f64) -> (Matrix2<f64>, Vector2<f64>, RowVector2<f64>, f64) {
    let a = if seg == 0 {
        // Critically damped: double eigenvalue -10 with one eigenvector.
        Matrix2::new(0.0, 1.0, -100.0, -20.0)
    } else {
        Matrix2::new(0.0, 1.0, -K, 0.0)
    };
    (a, Vector2::new(0.0, 1.0), RowVector2::new(1.0, 0.0), 0.0)
}

#[test]
fn defective_piece_falls_back_to_block_exponentials() {
    let critical = Piece::siso(
        0.4,
        dmatrix![0.0, 1.0; -100.0, -20.0],
        dvector![0.0, 1.0],
        RowDVector::from_row_slice(&[1.0, 0.0]),
        0.0,
    );
    let lti = PiecewiseLti::new(1.0, 0.0, vec![critical, hopper_piece(0.6, false)]).expect("valid");
    assert!(matches!(
        ExactHtf::with_method(&lti, ExactMethod::Modal),
        Err(htfid_theory::TheoryError::NotDiagonalisable { piece: 0, .. })
    ));
    let htf = ExactHtf::new(&lti).expect("htf");
    assert_eq!(htf.method(), ExactMethod::BlockExponential);
    let brute = BruteLtp {
        period: 1.0,
        bounds: vec![0.0, 0.4, 1.0],
        jumps: vec![Matrix2::identity(); 2],
        matrices: &critical_matrices,
    };
    let err = worst_relative_error(&htf, &brute);
    assert!(err < 1e-8, "critically damped vs RK4: {err:e}");
}

fn near_critical_lti(split_sq: f64) -> PiecewiseLti {
    // Eigenvalues -10 +- sqrt(split_sq).
    let piece = Piece::siso(
        0.4,
        dmatrix![0.0, 1.0; -100.0 + split_sq, -20.0],
        dvector![0.0, 1.0],
        RowDVector::from_row_slice(&[1.0, 0.0]),
        0.0,
    );
    PiecewiseLti::new(1.0, 0.0, vec![piece, hopper_piece(0.6, false)]).expect("valid")
}

#[test]
fn nearly_defective_piece_is_handled_by_either_path() {
    // Eigenvalue split 0.063 (eigenvector condition ~3e3): the modal path is
    // used and must agree with block exponentials; its error grows like
    // ~1e-20 cond^2, i.e. ~1e-13 here, so 1e-11 of max|G| has margin.
    let modal = ExactHtf::new(&near_critical_lti(1e-3)).expect("htf");
    assert_eq!(modal.method(), ExactMethod::Modal);
    let block = ExactHtf::with_method(&near_critical_lti(1e-3), ExactMethod::BlockExponential)
        .expect("htf");
    let omegas: Vec<f64> = (0..120)
        .map(|i| -30.0 + 0.5 * f64::from(i) + 0.01)
        .collect();
    let ks = harmonics();
    let a = modal.grid(&ks, &omegas);
    let b = block.grid(&ks, &omegas);
    let scale = a.max_abs();
    for (x, y) in a.values.iter().zip(&b.values) {
        assert!((x - y).norm() < 1e-11 * scale, "{x} vs {y}");
    }
    // Split 1e-3 (condition ~1e5): Auto must refuse the modal path.
    let auto = ExactHtf::new(&near_critical_lti(1e-6)).expect("htf");
    assert_eq!(auto.method(), ExactMethod::BlockExponential);
}

/// `values` shares factors between points but computes each as `g` does: the same bits, for
/// points in no particular order, repeated harmonics and frequencies, on both paths.
#[test]
fn values_equal_g_bit_for_bit() {
    let points: Vec<(i32, f64)> = [
        (1, 7.5),
        (-3, 0.2),
        (0, 7.5),
        (1, 7.5),
        (2, 31.0),
        (-1, 0.2),
        (0, 12.25),
        (3, 7.5),
    ]
    .to_vec();
    for method in [ExactMethod::Modal, ExactMethod::BlockExponential] {
        let htf = ExactHtf::with_method(&hopper_lti(), method).expect("htf");
        let batch = htf.values(&points);
        assert_eq!(batch.len(), points.len());
        for (&(n, w), v) in points.iter().zip(&batch) {
            let g = htf.g(n, w);
            assert_eq!(
                (v.re.to_bits(), v.im.to_bits()),
                (g.re.to_bits(), g.im.to_bits()),
                "{method:?}: G_{n}({w})"
            );
        }
    }
}
