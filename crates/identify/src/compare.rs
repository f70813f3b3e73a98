//! How far an HTF estimate stands from a known HTF, harmonic by harmonic.

use htfid_estimate::HtfEstimate;
use htfid_theory::HarmonicTransferFunction;

/// One harmonic's error of an estimate against a known HTF, relative to the largest `|G_n|`
/// over the band (or, for a harmonic that vanishes by symmetry, to a millionth of the largest
/// `|G_m|` of any harmonic, so round-off is not judged against its own zero).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HarmonicError {
    /// The harmonic.
    pub n: i32,
    /// Median of `|G_hat_n - G_n| / scale` over the band.
    pub median: f64,
    /// Largest of `|G_hat_n - G_n| / scale` over the band.
    pub max: f64,
    /// The scale: the largest `|G_n|` over the band, floored as above.
    pub max_abs_g: f64,
    /// Estimates in the band.
    pub points: usize,
}

/// Per harmonic of `estimate` with estimates in `band` (rad/s, inclusive): its error against
/// `truth`. Harmonics without estimates in the band are left out.
pub fn errors_against(
    truth: &dyn HarmonicTransferFunction,
    estimate: &HtfEstimate,
    band: (f64, f64),
) -> Vec<HarmonicError> {
    let (lo, hi) = band;
    let in_band: Vec<_> = estimate
        .rows()
        .filter(|r| r.omega >= lo && r.omega <= hi)
        .collect();
    let points: Vec<(i32, f64)> = in_band.iter().map(|r| (r.n, r.omega)).collect();
    let truths = truth.values(&points);
    let overall = truths.iter().map(|g| g.norm()).fold(0.0, f64::max);
    let mut out = Vec::new();
    for &n in estimate.harmonics() {
        let (rows, exact): (Vec<_>, Vec<_>) = in_band
            .iter()
            .zip(&truths)
            .filter(|(r, _)| r.n == n)
            .map(|(r, g)| (*r, *g))
            .unzip();
        if rows.is_empty() {
            continue;
        }
        let scale = exact
            .iter()
            .map(|g| g.norm())
            .fold(0.0, f64::max)
            .max(1e-6 * overall);
        let mut rel: Vec<f64> = rows
            .iter()
            .zip(&exact)
            .map(|(r, g)| (r.value - g).norm() / scale)
            .collect();
        rel.sort_by(f64::total_cmp);
        out.push(HarmonicError {
            n,
            median: rel[rel.len() / 2],
            max: rel[rel.len() - 1],
            max_abs_g: scale,
            points: rel.len(),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use htfid_estimate::Method;
    use num_complex::Complex64;

    /// `G_0 = 1 / (1 + j w)`, every other harmonic zero.
    struct FirstOrder;

    impl HarmonicTransferFunction for FirstOrder {
        fn pumping_frequency(&self) -> f64 {
            1.0
        }
        fn g(&self, n: i32, w: f64) -> Complex64 {
            if n == 0 {
                Complex64::new(1.0, w).inv()
            } else {
                Complex64::new(0.0, 0.0)
            }
        }
    }

    /// Errors placed by hand: 1 % of the largest |G_0| at every point but one, 5 % there; a
    /// vanishing harmonic judged against a millionth of the largest |G_0|.
    #[test]
    fn errors_are_relative_to_the_largest_gain_in_the_band() {
        let omegas = vec![0.5, 1.0, 2.0, 4.0, 8.0];
        let peak = FirstOrder.g(0, 0.5).norm();
        let values: Vec<Complex64> = omegas
            .iter()
            .enumerate()
            .map(|(i, &w)| FirstOrder.g(0, w) + peak * if i == 2 { 0.05 } else { 0.01 })
            .collect();
        let e = HtfEstimate::new(
            Method::Siddiqi,
            vec![0, 1],
            vec![omegas.clone(), omegas.clone()],
            vec![values, vec![Complex64::new(1e-9, 0.0); 5]],
            vec![vec![0.0; 5], vec![0.0; 5]],
        )
        .unwrap();
        let errs = errors_against(&FirstOrder, &e, (0.5, 4.0));
        assert_eq!(errs.len(), 2);
        let g0 = errs[0];
        assert_eq!((g0.n, g0.points), (0, 4));
        assert!((g0.max_abs_g - peak).abs() < 1e-15);
        assert!((g0.median - 0.01).abs() < 1e-12, "{g0:?}");
        assert!((g0.max - 0.05).abs() < 1e-12, "{g0:?}");
        let g1 = errs[1];
        assert!((g1.max_abs_g - 1e-6 * peak).abs() < 1e-18);
        assert!((g1.max - 1e-9 / (1e-6 * peak)).abs() < 1e-9, "{g1:?}");
    }
}
