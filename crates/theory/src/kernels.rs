//! Scalar kernels of the exact HTF: `phi1(x) = (e^x - 1) / x` and divided
//! differences of the exponential, evaluated without cancellation.
//!
//! Callers pass `e^x` alongside `x` because the fast path builds every
//! exponential as a product of cached factors instead of calling `exp`.

use num_complex::Complex64;

/// Below this modulus `phi1` and first divided differences use their Taylor
/// series: 18 terms leave a remainder under `0.5^18 / 19! < 1e-22`.
const PHI1_SERIES_RADIUS: f64 = 0.5;
const PHI1_TERMS: usize = 18;

/// Point clusters of diameter below this use the Taylor series of the second
/// divided difference: 22 terms leave a remainder under `22 / 24! < 1e-22`.
const DD2_SERIES_DIAMETER: f64 = 1.0;
const DD2_TERMS: usize = 22;

/// `sum_{k >= 0} x^k / (k + 1)!` by Horner's rule.
fn phi1_series(x: Complex64) -> Complex64 {
    // Horner for sum_{k=0}^{K-1} x^k / (k+1)!: nested as
    // 1/1! + x (1/2! + x (1/3! + ...)), with 1/(k+1)! = (1/k!) / (k+1).
    let mut acc = Complex64::new(0.0, 0.0);
    for k in (0..PHI1_TERMS).rev() {
        acc = acc * x + Complex64::new(inv_factorial(k + 1), 0.0);
    }
    acc
}

/// `1 / k!` for small `k`.
fn inv_factorial(k: usize) -> f64 {
    let mut f = 1.0;
    for i in 2..=k {
        f /= i as f64;
    }
    f
}

/// `phi1(x) = (e^x - 1) / x` given `ex = e^x`; `phi1(0) = 1`.
#[inline]
pub(crate) fn phi1(x: Complex64, ex: Complex64) -> Complex64 {
    if x.norm_sqr() < PHI1_SERIES_RADIUS * PHI1_SERIES_RADIUS {
        phi1_series(x)
    } else {
        (ex - 1.0) / x
    }
}

/// `phi1(x)` computing `e^x` itself.
pub(crate) fn phi1_direct(x: Complex64) -> Complex64 {
    phi1(x, x.exp())
}

/// First divided difference `(e^b - e^a) / (b - a)`, `= e^a` when `a = b`.
#[inline]
pub(crate) fn dd1(a: Complex64, ea: Complex64, b: Complex64, eb: Complex64) -> Complex64 {
    let d = b - a;
    if d.norm_sqr() < PHI1_SERIES_RADIUS * PHI1_SERIES_RADIUS {
        ea * phi1_series(d)
    } else {
        (eb - ea) / d
    }
}

/// Second divided difference `exp[x0, x1, x2]` of the exponential (symmetric
/// in its arguments; the Hermite-Genocchi integral
/// `int_{simplex} e^{t0 x0 + t1 x1 + t2 x2}`), given the three exponentials.
///
/// Well separated points use the recursive quotient over the widest pair, so
/// the division is by the cluster diameter `>= 1`; tight clusters use the
/// series `e^{x0} sum_m h_m(y1, y2) / (m + 2)!` with `y = x - x0` and `h_m`
/// the complete homogeneous symmetric polynomials.
#[inline]
pub(crate) fn dd2(
    x0: Complex64,
    e0: Complex64,
    x1: Complex64,
    e1: Complex64,
    x2: Complex64,
    e2: Complex64,
) -> Complex64 {
    let d01 = (x1 - x0).norm_sqr();
    let d02 = (x2 - x0).norm_sqr();
    let d12 = (x2 - x1).norm_sqr();
    let widest = d01.max(d02).max(d12);
    if widest < DD2_SERIES_DIAMETER * DD2_SERIES_DIAMETER {
        let y1 = x1 - x0;
        let y2 = x2 - x0;
        // h_m(y1, y2) = y2^m + y1 h_{m-1}(y1, y2).
        let mut h = Complex64::new(1.0, 0.0);
        let mut y2_pow = Complex64::new(1.0, 0.0);
        let mut inv_fact = 0.5; // 1 / (m + 2)! at m = 0
        let mut sum = h * inv_fact;
        for m in 1..DD2_TERMS {
            y2_pow *= y2;
            h = y2_pow + y1 * h;
            inv_fact /= (m + 2) as f64;
            sum += h * inv_fact;
        }
        return e0 * sum;
    }
    // Order the points so (a, c) is the widest pair and b the middle one.
    let ((a, ea), (b, eb), (c, ec)) = if widest <= d01 {
        ((x0, e0), (x2, e2), (x1, e1))
    } else if widest <= d02 {
        ((x0, e0), (x1, e1), (x2, e2))
    } else {
        ((x1, e1), (x0, e0), (x2, e2))
    };
    (dd1(b, eb, c, ec) - dd1(a, ea, b, eb)) / (c - a)
}

/// Divided difference `exp[z_0, ..., z_m]` of the exponential over one to four nodes, each
/// given with its exponential (symmetric in the nodes; the Hermite-Genocchi integral over the
/// simplex). As [`dd2`]: a cluster of diameter below 1 uses the series
/// `e^{z_0} sum_k h_k(z_1 - z_0, ..., z_m - z_0) / (k + m)!` (`h_k` the complete homogeneous
/// symmetric polynomials; 26 terms leave a remainder under `C(28, 2) / 29! < 1e-28` of the
/// leading `1 / m!`), a wider one the quotient over its widest pair, so every division is by a
/// difference of modulus `>= 1`.
pub(crate) fn dd_exp(nodes: &[(Complex64, Complex64)]) -> Complex64 {
    const TERMS: usize = 26;
    let m = nodes.len() - 1;
    if m == 0 {
        return nodes[0].1;
    }
    let (mut first, mut last, mut widest) = (0, 0, -1.0);
    for i in 0..=m {
        for j in i + 1..=m {
            let d = (nodes[j].0 - nodes[i].0).norm_sqr();
            if d > widest {
                (first, last, widest) = (i, j, d);
            }
        }
    }
    if widest < DD2_SERIES_DIAMETER * DD2_SERIES_DIAMETER {
        // h[k] = h_k of the variables added so far.
        let mut h = [Complex64::new(0.0, 0.0); TERMS];
        h[0] = Complex64::new(1.0, 0.0);
        for node in &nodes[1..] {
            let y = node.0 - nodes[0].0;
            for k in 1..TERMS {
                let carried = y * h[k - 1];
                h[k] += carried;
            }
        }
        let mut inv_fact = inv_factorial(m);
        let mut sum = h[0] * inv_fact;
        for (k, hk) in h.iter().enumerate().skip(1) {
            inv_fact /= (k + m) as f64;
            sum += hk * inv_fact;
        }
        return nodes[0].1 * sum;
    }
    let without = |skip: usize| -> Complex64 {
        let mut rest = [(Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0)); 3];
        let mut len = 0;
        for (i, &node) in nodes.iter().enumerate() {
            if i != skip {
                rest[len] = node;
                len += 1;
            }
        }
        dd_exp(&rest[..len])
    };
    (without(first) - without(last)) / (nodes[last].0 - nodes[first].0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(re: f64, im: f64) -> Complex64 {
        Complex64::new(re, im)
    }

    /// Independent reference for `exp[x0, x1, x2]`: the (0, 2) entry of
    /// `exp([[x0, 1, 0], [0, x1, 1], [0, 0, x2]])` (Opitz' formula), computed
    /// by the Pade scaling-and-squaring `expm` of htfid-ltp.
    fn dd2_reference(x0: Complex64, x1: Complex64, x2: Complex64) -> Complex64 {
        let one = c(1.0, 0.0);
        let zero = c(0.0, 0.0);
        let m = nalgebra::DMatrix::from_row_slice(
            3,
            3,
            &[x0, one, zero, zero, x1, one, zero, zero, x2],
        );
        htfid_ltp::expm(&m)[(0, 2)]
    }

    #[test]
    fn phi1_matches_definition_and_limit() {
        // Away from 0 the definition is accurate; near 0 the series must
        // agree with it where both are valid (|x| ~ 0.5, 1e-15 relative).
        for x in [
            c(0.49, 0.0),
            c(0.0, 0.499),
            c(-0.3, 0.35),
            c(0.5, 0.0),
            c(2.0, -7.0),
        ] {
            let direct = (x.exp() - 1.0) / x;
            let got = if x.norm() < 0.5 {
                phi1_series(x)
            } else {
                phi1_direct(x)
            };
            assert!((got - direct).norm() <= 1e-14 * direct.norm(), "{x}");
        }
        // phi1(x) = 1 + x/2 + x^2/6 + ..., at tiny x.
        let x = c(1e-9, -2e-9);
        assert!((phi1_direct(x) - (c(1.0, 0.0) + x / 2.0)).norm() < 1e-17);
        assert!((phi1_direct(c(0.0, 0.0)) - c(1.0, 0.0)).norm() < 1e-300);
    }

    #[test]
    fn dd2_matches_reference_in_both_regimes() {
        // Both code paths (series for diameter < 1, quotient otherwise),
        // coincident points, and points across the switch-over, in every
        // argument order, against the matrix-exponential reference. Both
        // sides are accurate to a few ulps times modest condition numbers,
        // hence 1e-13 relative.
        let cases = [
            (c(0.0, 0.0), c(0.1, 0.2), c(-0.3, 0.1)),
            (c(0.0, 0.0), c(0.0, 0.0), c(0.0, 0.0)),
            (c(0.0, 0.0), c(0.0, -3.0), c(-1.0, 2.0)),
            (c(0.0, 0.0), c(0.0, -0.9), c(0.0, -0.95)),
            (c(-2.0, 5.0), c(-2.0, 5.0), c(0.0, 0.0)),
            (c(0.0, 0.0), c(0.0, 6.0), c(-0.5, 6.0)),
            (c(0.3, 0.0), c(0.0, 0.0), c(0.0, 1.2)),
            (c(0.0, 0.0), c(0.0, -20.0), c(-3.0, -19.0)),
            (c(0.0, 0.0), c(0.0, 30.0), c(-0.2, 0.1)),
        ];
        for (x0, x1, x2) in cases {
            let want = dd2_reference(x0, x1, x2);
            for perm in [(x0, x1, x2), (x2, x0, x1), (x1, x2, x0), (x1, x0, x2)] {
                let (a, b, cc) = perm;
                let got = dd2(a, a.exp(), b, b.exp(), cc, cc.exp());
                assert!(
                    (got - want).norm() <= 1e-13 * want.norm(),
                    "{a} {b} {cc}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn dd2_continuous_across_series_switch() {
        // Points just inside and just outside the series diameter must give
        // nearly equal values: the function is smooth, so a jump larger
        // than rounding would expose a wrong branch.
        let inside = dd2(
            c(0.0, 0.0),
            c(1.0, 0.0),
            c(0.0, 0.999_999_9),
            c(0.0, 0.999_999_9).exp(),
            c(0.0, 0.5),
            c(0.0, 0.5).exp(),
        );
        let outside = dd2(
            c(0.0, 0.0),
            c(1.0, 0.0),
            c(0.0, 1.000_000_1),
            c(0.0, 1.000_000_1).exp(),
            c(0.0, 0.5),
            c(0.0, 0.5).exp(),
        );
        // Derivative of dd2 is bounded by ~1, the points moved by 2e-7.
        assert!((inside - outside).norm() < 1e-6);
    }

    /// The `(m, 0)` entry of `exp` of the lower bidiagonal matrix with the nodes on its
    /// diagonal and ones below (Opitz' formula), by htfid-ltp's Pade `expm`.
    fn dd_reference(nodes: &[Complex64]) -> Complex64 {
        let m = nodes.len();
        let mut a = nalgebra::DMatrix::from_element(m, m, c(0.0, 0.0));
        for (i, &z) in nodes.iter().enumerate() {
            a[(i, i)] = z;
            if i > 0 {
                a[(i, i - 1)] = c(1.0, 0.0);
            }
        }
        htfid_ltp::expm(&a)[(m - 1, 0)]
    }

    #[test]
    fn dd_exp_matches_reference_for_up_to_four_nodes() {
        // Tight clusters (series), wide ones (quotients), coincident nodes and mixtures, every
        // rotation of the nodes, against the matrix exponential: both are accurate to a few
        // ulps times the modest condition of these nodes, hence 1e-12 relative.
        let sets: [&[Complex64]; 10] = [
            &[c(0.3, -0.2)],
            &[c(0.0, 0.0), c(0.2, 0.1)],
            &[c(-1.0, 4.0), c(0.0, 0.0)],
            &[c(0.0, 0.0), c(0.1, 0.2), c(-0.3, 0.1), c(0.2, -0.2)],
            &[c(0.0, 0.0), c(0.0, 0.0), c(0.0, 0.0), c(0.0, 0.0)],
            &[c(-2.0, 5.0), c(-2.0, 5.0), c(0.0, -6.0), c(0.0, 0.0)],
            &[c(-0.5, 12.0), c(-0.5, -12.0), c(0.0, 6.2), c(0.0, 0.0)],
            &[c(0.0, 0.0), c(0.0, -0.9), c(0.0, 0.95), c(-3.0, 20.0)],
            &[c(-0.02, 31.0), c(-0.02, 30.9), c(0.0, 31.4), c(0.0, 0.0)],
            &[c(-8.0, 1.0), c(-7.5, 1.2), c(0.0, -40.0), c(0.0, 0.0)],
        ];
        for nodes in sets {
            let want = dd_reference(nodes);
            for r in 0..nodes.len() {
                let rotated: Vec<(Complex64, Complex64)> = (0..nodes.len())
                    .map(|i| {
                        let z = nodes[(i + r) % nodes.len()];
                        (z, z.exp())
                    })
                    .collect();
                let got = dd_exp(&rotated);
                assert!(
                    (got - want).norm() <= 1e-12 * want.norm(),
                    "{nodes:?} rotated by {r}: {got} against {want}"
                );
            }
        }
    }
}
