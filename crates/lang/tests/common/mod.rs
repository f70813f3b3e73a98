//! What the oracle tests share.

use num_complex::Complex64;

/// Every multiplier of `ours` within `tol` of its own one of `theirs` (each matched once; the
/// order within a complex-conjugate pair is not compared).
pub fn assert_same_multipliers(name: &str, ours: &[Complex64], theirs: &[Complex64], tol: f64) {
    assert_eq!(ours.len(), theirs.len(), "{name}: multipliers");
    let mut theirs = theirs.to_vec();
    for z in ours {
        let (i, d) = theirs
            .iter()
            .enumerate()
            .map(|(i, w)| (i, (w - z).norm()))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .expect("as many multipliers as ours");
        assert!(d < tol, "{name}: multiplier {z} off by {d:e}");
        theirs.remove(i);
    }
}
