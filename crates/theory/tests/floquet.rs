//! Monodromy matrices and Floquet quantities of htfid-ltp against RK4
//! propagation and Liouville's formula.

mod common;

use common::{hopper_matrices, BruteLtp};
use htfid_ltp::{Floquet, Piece, PiecewiseLti};
use nalgebra::{dmatrix, dvector, Matrix2, RowDVector, RowVector2, Vector2};
use num_complex::Complex64;
use std::f64::consts::TAU;

const K: f64 = 200.0;
const C: f64 = 2.0;

fn hopper_piece(duration: f64, damping: f64) -> Piece {
    Piece::siso(
        duration,
        dmatrix![0.0, 1.0; -K, -damping],
        dvector![0.0, 1.0],
        RowDVector::from_row_slice(&[1.0, 0.0]),
        0.0,
    )
}

/// Damper on [0.23, 0.71) with jumps at both switches; the first piece
/// starts at 0.23, so the flight piece wraps through t = 0.
fn jump_hopper() -> PiecewiseLti {
    PiecewiseLti::new(
        1.0,
        0.23,
        vec![
            hopper_piece(0.48, C).with_jump(dmatrix![1.0, 0.0; 0.3, 1.0]),
            hopper_piece(0.52, 0.0).with_jump(dmatrix![0.9, 0.05; 0.0, 1.1]),
        ],
    )
    .expect("valid")
}

fn brute_matrices(seg: usize, _t: f64) -> (Matrix2<f64>, Vector2<f64>, RowVector2<f64>, f64) {
    hopper_matrices(K, C, seg == 1)
}

#[test]
fn monodromy_matches_rk4_propagation_of_identity() {
    let brute = BruteLtp {
        period: 1.0,
        bounds: vec![0.0, 0.23, 0.71, 1.0],
        jumps: vec![
            Matrix2::identity(),
            Matrix2::new(1.0, 0.0, 0.3, 1.0),
            Matrix2::new(0.9, 0.05, 0.0, 1.1),
        ],
        matrices: &brute_matrices,
    };
    // RK4 with step 1e-4 on rates <= sqrt(200) ~ 14: global error
    // ~ (14e-4)^4 / 120 * 14 ~ 5e-13 relative; entries are O(10), so 1e-9
    // absolute is a loose but meaningful bound (a wrong order of pieces or
    // jumps changes entries at O(1)).
    let want = brute.monodromy(1e-4);
    let got = jump_hopper().monodromy();
    for r in 0..2 {
        for c in 0..2 {
            assert!(
                (got[(r, c)] - want[(r, c)]).abs() < 1e-9,
                "({r},{c}): {} vs {}",
                got[(r, c)],
                want[(r, c)]
            );
        }
    }
}

#[test]
fn liouville_determinant() {
    // det M = det J_on det J_off exp(int_0^T trace A) = 1 * 0.99 * exp(-c * 0.48).
    let lti = jump_hopper();
    let want = 0.99 * (-C * 0.48_f64).exp();
    let det = lti.monodromy().determinant();
    assert!((det - want).abs() < 1e-13, "{det} vs {want}");
    assert!((lti.liouville_determinant() - want).abs() < 1e-15);
    // Starting the period elsewhere gives a similar matrix: same determinant.
    let det_shifted = lti.monodromy_from(0.5).determinant();
    assert!((det_shifted - want).abs() < 1e-13);
}

#[test]
fn multipliers_do_not_depend_on_the_start_time() {
    let lti = jump_hopper();
    let sorted = |m: nalgebra::DMatrix<f64>| {
        let mut ev: Vec<Complex64> = m.complex_eigenvalues().iter().copied().collect();
        ev.sort_by(|a, b| a.im.total_cmp(&b.im));
        ev
    };
    let base = sorted(lti.monodromy());
    for t0 in [0.1, 0.23, 0.5, 0.71, 0.99, -3.3] {
        let other = sorted(lti.monodromy_from(t0));
        for (a, b) in base.iter().zip(&other) {
            assert!((a - b).norm() < 1e-12, "t0 = {t0}: {a} vs {b}");
        }
    }
}

#[test]
fn floquet_exponents_of_an_lti_system_are_its_eigenvalues() {
    // x'' + 0.7 x' + 33 x = 0 viewed with period 0.8: exponents must equal
    // the eigenvalues -0.35 +- j sqrt(33 - 0.35^2) modulo j wp.
    let a = dmatrix![0.0, 1.0; -33.0, -0.7];
    let lti = PiecewiseLti::lti(
        0.8,
        a,
        dmatrix![0.0; 1.0],
        dmatrix![1.0, 0.0],
        dmatrix![0.0],
    )
    .expect("valid");
    let floquet = Floquet::new(&lti);
    let wd = (33.0_f64 - 0.35 * 0.35).sqrt();
    let wp = TAU / 0.8;
    for e in floquet.exponents() {
        assert!((e.re + 0.35).abs() < 1e-12, "{e}");
        // Imaginary part equals +wd or -wd up to a multiple of wp.
        let off = |target: f64| {
            let m = ((e.im - target) / wp).round();
            (e.im - target - m * wp).abs()
        };
        assert!(off(wd).min(off(-wd)) < 1e-11, "{e}");
    }
    let radius = (-0.35_f64 * 0.8).exp();
    assert!((floquet.spectral_radius() - radius).abs() < 1e-13);
}
