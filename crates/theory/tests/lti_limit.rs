//! An LTI system written as a piecewise-LTI one: only G_0 survives and it
//! equals the classical transfer function 1 / (m s^2 + c s + k).

use htfid_ltp::{Piece, PiecewiseLti};
use htfid_theory::{ExactHtf, ExactMethod, HarmonicTransferFunction, TruncatedHtf};
use nalgebra::{dmatrix, dvector, RowDVector};
use num_complex::Complex64;

const M: f64 = 1.5;
const CD: f64 = 0.7;
const KS: f64 = 50.0;

fn piece(duration: f64) -> Piece {
    Piece::siso(
        duration,
        dmatrix![0.0, 1.0; -KS / M, -CD / M],
        dvector![0.0, 1.0 / M],
        RowDVector::from_row_slice(&[1.0, 0.0]),
        0.0,
    )
}

/// Two identical pieces with a wrap (start 0.4 of T = 0.8) and an explicit
/// identity jump: none of this structure may leak into the HTF.
fn lti() -> PiecewiseLti {
    PiecewiseLti::new(
        0.8,
        0.4,
        vec![
            piece(0.3),
            piece(0.5).with_jump(dmatrix![1.0, 0.0; 0.0, 1.0]),
        ],
    )
    .expect("valid")
}

fn truth(w: f64) -> Complex64 {
    let s = Complex64::new(0.0, w);
    1.0 / (s * s * M + s * CD + KS)
}

fn omegas() -> Vec<f64> {
    // Across the resonance sqrt(k/m) = 5.77 rad/s, both signs of frequency.
    (0..241)
        .map(|i| -30.0 + 0.25 * f64::from(i) + 0.01)
        .collect()
}

fn check(htf: &dyn HarmonicTransferFunction, label: &str) {
    let ks: Vec<i32> = (-6..=6).collect();
    let grid = htf.grid(&ks, &omegas());
    let scale = omegas()
        .iter()
        .map(|&w| truth(w).norm())
        .fold(0.0, f64::max);
    for (iw, &w) in grid.omegas.iter().enumerate() {
        for (ih, &n) in grid.harmonics.iter().enumerate() {
            let got = grid.get(iw, ih).expect("in range");
            let want = if n == 0 {
                truth(w)
            } else {
                Complex64::new(0.0, 0.0)
            };
            // 1e-12 of max|G|: the computation is a handful of rounded
            // operations on O(1) quantities, with the resonance peak
            // (Q ~ 12) as the only amplification.
            assert!(
                (got - want).norm() < 1e-12 * scale,
                "{label}: n={n} w={w}: {got} vs {want}"
            );
        }
    }
}

#[test]
fn exact_modal_reduces_to_lti() {
    let htf = ExactHtf::with_method(&lti(), ExactMethod::Modal).expect("htf");
    check(&htf, "modal");
}

#[test]
fn exact_block_exponential_reduces_to_lti() {
    let htf = ExactHtf::with_method(&lti(), ExactMethod::BlockExponential).expect("htf");
    check(&htf, "block");
}

#[test]
fn truncated_reduces_to_lti() {
    for n_trunc in [0, 3, 10] {
        let htf = TruncatedHtf::new(&lti(), n_trunc).expect("htf");
        check(&htf, "truncated");
    }
}

#[test]
fn single_g_agrees_with_grid() {
    let htf = ExactHtf::new(&lti()).expect("htf");
    for w in [0.3, 5.77, 12.0] {
        let want = truth(w);
        assert!((htf.g(0, w) - want).norm() < 1e-12 * want.norm());
    }
}
