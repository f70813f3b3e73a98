//! `Tabulated` returns its inner HTF's values, bit for bit, and computes only what it does not
//! hold.

use std::sync::atomic::{AtomicUsize, Ordering};

use htfid_ltp::{Piece, PiecewiseLti};
use htfid_theory::{ExactHtf, HarmonicTransferFunction, Tabulated};
use nalgebra::{dmatrix, dvector, RowDVector};
use num_complex::Complex64;

/// A spring-mass-damper whose damping switches within the period, with a jump.
fn switching() -> PiecewiseLti {
    let piece = |duration: f64, c: f64| {
        Piece::siso(
            duration,
            dmatrix![0.0, 1.0; -200.0, -c],
            dvector![0.0, 1.0],
            RowDVector::from_row_slice(&[1.0, 0.0]),
            0.0,
        )
    };
    PiecewiseLti::new(
        1.0,
        0.2,
        vec![
            piece(0.45, 2.0),
            piece(0.55, 0.0).with_jump(dmatrix![1.0, 0.0; 0.1, 0.9]),
        ],
    )
    .expect("valid")
}

/// The inner HTF, counting the points it is asked for.
struct Counting {
    inner: ExactHtf,
    points: AtomicUsize,
}

impl HarmonicTransferFunction for Counting {
    fn pumping_frequency(&self) -> f64 {
        self.inner.pumping_frequency()
    }
    fn g(&self, n: i32, w: f64) -> Complex64 {
        self.points.fetch_add(1, Ordering::Relaxed);
        self.inner.g(n, w)
    }
    fn values(&self, points: &[(i32, f64)]) -> Vec<Complex64> {
        self.points.fetch_add(points.len(), Ordering::Relaxed);
        self.inner.values(points)
    }
}

#[test]
fn tabulated_values_are_the_inner_values_and_only_missing_points_are_computed() {
    let exact = ExactHtf::new(&switching()).unwrap();
    let counting = Counting {
        inner: exact.clone(),
        points: AtomicUsize::new(0),
    };
    let all: Vec<(i32, f64)> = (-2..=2)
        .flat_map(|n| (0..40).map(move |i| (n, 1.0 + 0.7 * f64::from(i))))
        .collect();
    let held: Vec<(i32, f64)> = all.iter().copied().step_by(2).collect();
    let table = Tabulated::new(&counting, &held);
    assert_eq!(table.len(), held.len());
    assert_eq!(counting.points.load(Ordering::Relaxed), held.len());

    // Every point, in reverse order and one of them twice.
    let mut asked: Vec<(i32, f64)> = all.iter().rev().copied().collect();
    asked.push(all[1]);
    let got = table.values(&asked);
    let expect = exact.values(&asked);
    for ((point, a), b) in asked.iter().zip(&got).zip(&expect) {
        assert_eq!(
            (a.re.to_bits(), a.im.to_bits()),
            (b.re.to_bits(), b.im.to_bits()),
            "{point:?}"
        );
    }
    let missing = asked.len() - asked.iter().filter(|p| held.contains(p)).count();
    assert_eq!(
        counting.points.load(Ordering::Relaxed),
        held.len() + missing
    );
    // The points it was made for, in their order.
    let again = table.values(&held);
    for (a, b) in again.iter().zip(exact.values(&held)) {
        assert_eq!(
            (a.re.to_bits(), a.im.to_bits()),
            (b.re.to_bits(), b.im.to_bits())
        );
    }
    assert_eq!(
        counting.points.load(Ordering::Relaxed),
        held.len() + missing
    );
    let (n, w) = held[3];
    assert_eq!(table.g(n, w).re.to_bits(), exact.g(n, w).re.to_bits());
    assert_eq!(
        counting.points.load(Ordering::Relaxed),
        held.len() + missing
    );
}
