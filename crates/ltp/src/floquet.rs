//! Matrix exponential, monodromy matrices and Floquet analysis.

use crate::piecewise::PiecewiseLti;
use nalgebra::{ComplexField, DMatrix};
use num_complex::Complex64;

/// Pade numerator coefficients `b_k` of degrees 3, 5, 7, 9 and 13 (Higham
/// 2005, "The scaling and squaring method for the matrix exponential
/// revisited"), with the bounds `theta_m` on `alpha_p(A)` up to which degree
/// `m` reaches unit roundoff (Al-Mohy and Higham 2009, "A new scaling and
/// squaring algorithm for the matrix exponential", table 3.1).
const PADE3: [f64; 4] = [120.0, 60.0, 12.0, 1.0];
const PADE5: [f64; 6] = [30_240.0, 15_120.0, 3_360.0, 420.0, 30.0, 1.0];
const PADE7: [f64; 8] = [
    17_297_280.0,
    8_648_640.0,
    1_995_840.0,
    277_200.0,
    25_200.0,
    1_512.0,
    56.0,
    1.0,
];
const PADE9: [f64; 10] = [
    17_643_225_600.0,
    8_821_612_800.0,
    2_075_673_600.0,
    302_702_400.0,
    30_270_240.0,
    2_162_160.0,
    110_880.0,
    3_960.0,
    90.0,
    1.0,
];
const PADE13: [f64; 14] = [
    64_764_752_532_480_000.0,
    32_382_376_266_240_000.0,
    7_771_770_303_897_600.0,
    1_187_353_796_428_800.0,
    129_060_195_264_000.0,
    10_559_470_521_600.0,
    670_442_572_800.0,
    33_522_128_640.0,
    1_323_241_920.0,
    40_840_800.0,
    960_960.0,
    16_380.0,
    182.0,
    1.0,
];
const THETA3: f64 = 1.495_585_217_958_292e-2;
const THETA5: f64 = 2.539_398_330_063_23e-1;
const THETA7: f64 = 9.504_178_996_162_932e-1;
const THETA9: f64 = 2.097_847_961_257_068;
const THETA13: f64 = 4.25;

fn norm1<T: ComplexField<RealField = f64>>(a: &DMatrix<T>) -> f64 {
    a.column_iter()
        .map(|col| col.iter().map(|x| x.clone().modulus()).sum::<f64>())
        .fold(0.0, f64::max)
}

fn scaled<T: ComplexField<RealField = f64>>(a: &DMatrix<T>, s: f64) -> DMatrix<T> {
    a.map(|x| x * T::from_real(s))
}

/// Extra squarings `ell(A, m)` that keep the rounding errors of evaluating
/// the degree-`m` Pade approximant below unit roundoff (Al-Mohy and Higham
/// 2009, eq. 5.1), using the exact 1-norm of `|A|^(2m+1)` (small matrices).
fn ell<T: ComplexField<RealField = f64>>(a: &DMatrix<T>, m: usize) -> u32 {
    let norm = norm1(a);
    if norm <= 0.0 {
        return 0;
    }
    let abs_t = a.map(|x| x.modulus()).transpose();
    let mut v = nalgebra::DVector::<f64>::from_element(a.nrows(), 1.0);
    for _ in 0..2 * m + 1 {
        v = &abs_t * v;
    }
    let power_norm = v.max();
    // |c_{2m+1}| = (m!)^2 / ((2m)! (2m+1)!), built as a running product.
    let mut c = 1.0;
    for k in 1..=m {
        c *= k as f64 / (m + k) as f64;
    }
    for k in 1..=2 * m + 1 {
        c /= k as f64;
    }
    let alpha = c * power_norm / norm;
    let value = ((alpha / f64::EPSILON * 2.0).log2() / (2 * m) as f64).ceil();
    if value > 0.0 {
        value as u32
    } else {
        0
    }
}

/// Pade approximant `(V - U)^{-1} (V + U)` of degree `coeffs.len() - 1`
/// from the even powers `[I, A^2, A^4, ...]`.
fn pade<T: ComplexField<RealField = f64>>(
    a: &DMatrix<T>,
    even_powers: &[&DMatrix<T>],
    coeffs: &[f64],
) -> Option<DMatrix<T>> {
    let n = a.nrows();
    let mut u = DMatrix::<T>::zeros(n, n);
    let mut v = DMatrix::<T>::zeros(n, n);
    for (k, &b) in coeffs.iter().enumerate() {
        let term = even_powers[k / 2] * T::from_real(b);
        if k % 2 == 0 {
            v += term;
        } else {
            u += term;
        }
    }
    let u = a * u;
    pade_solve(&u, &v)
}

/// Matrix exponential `exp(A)` of a real or complex square matrix by the
/// scaling and squaring algorithm of Al-Mohy and Higham (2009): Pade degree
/// 3 to 13 chosen from `||A^k||^(1/k)` (not just `||A||`, which over-scales
/// non-normal matrices such as oscillators `[[0, 1], [-k, -c]]`), plus the
/// `ell` guard against rounding in the Pade evaluation.
///
/// Accurate to a few units of roundoff times the condition of the problem.
/// Non-finite input gives a matrix of NaN rather than a panic.
///
/// # Panics
/// If `a` is not square.
pub fn expm<T: ComplexField<RealField = f64>>(a: &DMatrix<T>) -> DMatrix<T> {
    assert!(a.is_square(), "expm needs a square matrix");
    let n = a.nrows();
    let nan = || DMatrix::from_element(n, n, T::from_real(f64::NAN));
    if !norm1(a).is_finite() {
        return nan();
    }
    let eye = DMatrix::<T>::identity(n, n);
    let a2 = a * a;
    let a4 = &a2 * &a2;
    let a6 = &a4 * &a2;
    let d4 = norm1(&a4).powf(0.25);
    let d6 = norm1(&a6).powf(1.0 / 6.0);
    let eta1 = d4.max(d6);
    if eta1 <= THETA3 && ell(a, 3) == 0 {
        return pade(a, &[&eye, &a2], &PADE3).unwrap_or_else(nan);
    }
    if eta1 <= THETA5 && ell(a, 5) == 0 {
        return pade(a, &[&eye, &a2, &a4], &PADE5).unwrap_or_else(nan);
    }
    let a8 = &a4 * &a4;
    let d8 = norm1(&a8).powf(0.125);
    let eta3 = d6.max(d8);
    if eta3 <= THETA7 && ell(a, 7) == 0 {
        return pade(a, &[&eye, &a2, &a4, &a6], &PADE7).unwrap_or_else(nan);
    }
    if eta3 <= THETA9 && ell(a, 9) == 0 {
        return pade(a, &[&eye, &a2, &a4, &a6, &a8], &PADE9).unwrap_or_else(nan);
    }
    let d10 = norm1(&(&a6 * &a4)).powf(0.1);
    let eta5 = eta3.min(d8.max(d10));
    let mut s = if eta5 > 0.0 {
        (eta5 / THETA13).log2().ceil().max(0.0) as u32
    } else {
        0
    };
    s += ell(&scaled(a, 0.5_f64.powi(s as i32)), 13);
    // Degree 13 on A / 2^s, evaluated as in Higham (2005) with 6 products.
    let f = 0.5_f64.powi(s as i32);
    let a1 = scaled(a, f);
    let a2 = scaled(&a2, f * f);
    let a4 = scaled(&a4, f.powi(4));
    let a6 = scaled(&a6, f.powi(6));
    let b = |k: usize| T::from_real(PADE13[k]);
    let inner_u = &a6 * b(13) + &a4 * b(11) + &a2 * b(9);
    let u = &a1 * (&a6 * inner_u + &a6 * b(7) + &a4 * b(5) + &a2 * b(3) + &eye * b(1));
    let inner_v = &a6 * b(12) + &a4 * b(10) + &a2 * b(8);
    let v = &a6 * inner_v + &a6 * b(6) + &a4 * b(4) + &a2 * b(2) + &eye * b(0);
    let Some(mut r) = pade_solve(&u, &v) else {
        return nan();
    };
    for _ in 0..s {
        r = &r * &r;
    }
    r
}

/// `(V - U)^{-1} (V + U)`.
fn pade_solve<T: ComplexField<RealField = f64>>(
    u: &DMatrix<T>,
    v: &DMatrix<T>,
) -> Option<DMatrix<T>> {
    (v - u).lu().solve(&(v + u))
}

/// One stretch of a period walk: piece index, whether its start jump is
/// applied, and how long the piece's flow acts.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Stretch {
    pub(crate) piece: usize,
    pub(crate) apply_jump: bool,
    pub(crate) duration: f64,
}

impl PiecewiseLti {
    /// The pieces met walking one period `[t0, t0 + T)` from `t0`, in order.
    pub(crate) fn walk_from(&self, t0: f64) -> Vec<Stretch> {
        let n_pieces = self.pieces().len();
        let tau = self.boundaries();
        let Some(i0) = self.piece_index_at(t0) else {
            return Vec::new();
        };
        let mut u = self.start() + (t0 - self.start()).rem_euclid(self.period());
        if u >= tau[n_pieces] {
            u = tau[0];
        }
        let at_start = u <= tau[i0];
        let mut out = Vec::with_capacity(n_pieces + 1);
        out.push(Stretch {
            piece: i0,
            apply_jump: at_start,
            duration: tau[i0 + 1] - u.max(tau[i0]),
        });
        for k in 1..n_pieces {
            let i = (i0 + k) % n_pieces;
            out.push(Stretch {
                piece: i,
                apply_jump: true,
                duration: tau[i + 1] - tau[i],
            });
        }
        if !at_start {
            out.push(Stretch {
                piece: i0,
                apply_jump: true,
                duration: u - tau[i0],
            });
        }
        out
    }

    /// Monodromy matrix over one period starting at `t = 0`: the map
    /// `x(0-) -> x(T-)` of the homogeneous system, jumps at times in
    /// `[0, T)` included (so a jump at `t = 0` acts first).
    pub fn monodromy(&self) -> DMatrix<f64> {
        self.monodromy_from(0.0)
    }

    /// Monodromy matrix over `[t0, t0 + T)`: the map `x(t0-) -> x(t0 + T-)`.
    /// All such matrices are similar, so their eigenvalues (the Floquet
    /// multipliers) do not depend on `t0`.
    pub fn monodromy_from(&self, t0: f64) -> DMatrix<f64> {
        let n = self.n_states();
        let mut m = DMatrix::<f64>::identity(n, n);
        for stretch in self.walk_from(t0) {
            let piece = &self.pieces()[stretch.piece];
            if stretch.apply_jump {
                if let Some(j) = piece.jump() {
                    m = j * m;
                }
            }
            m = expm(&(piece.a() * stretch.duration)) * m;
        }
        m
    }

    /// Determinant of the monodromy matrix by Liouville's formula:
    /// `prod_i det(J_i) * exp(sum_i trace(A_i) h_i)`.
    pub fn liouville_determinant(&self) -> f64 {
        let mut det_jumps = 1.0;
        let mut trace_integral = 0.0;
        for piece in self.pieces() {
            if let Some(j) = piece.jump() {
                det_jumps *= j.determinant();
            }
            trace_integral += piece.a().trace() * piece.duration();
        }
        det_jumps * trace_integral.exp()
    }
}

/// Floquet analysis of a [`PiecewiseLti`]: monodromy matrix (from `t = 0`),
/// multipliers and exponents.
#[derive(Debug, Clone, PartialEq)]
pub struct Floquet {
    period: f64,
    monodromy: DMatrix<f64>,
    multipliers: Vec<Complex64>,
}

impl Floquet {
    /// Computes the monodromy matrix and its eigenvalues (NaN if the
    /// monodromy overflows).
    pub fn new(lti: &PiecewiseLti) -> Self {
        let monodromy = lti.monodromy();
        // An overflowing propagator (huge `A_i h_i`) would stall the Schur
        // iteration; report NaN multipliers instead.
        let multipliers = if monodromy.iter().all(|x| x.is_finite()) {
            monodromy.complex_eigenvalues().iter().copied().collect()
        } else {
            vec![Complex64::new(f64::NAN, f64::NAN); lti.n_states()]
        };
        Self {
            period: lti.period(),
            monodromy,
            multipliers,
        }
    }

    /// Monodromy matrix `x(0-) -> x(T-)`.
    pub fn monodromy(&self) -> &DMatrix<f64> {
        &self.monodromy
    }

    /// Floquet multipliers `mu` (eigenvalues of the monodromy matrix).
    pub fn multipliers(&self) -> &[Complex64] {
        &self.multipliers
    }

    /// Floquet exponents `ln(mu) / T` (principal branch: imaginary parts in
    /// `(-wp/2, wp/2]`). A zero multiplier, possible with a singular jump,
    /// gives an exponent with real part minus infinity.
    pub fn exponents(&self) -> Vec<Complex64> {
        self.multipliers
            .iter()
            .map(|mu| mu.ln() / self.period)
            .collect()
    }

    /// Largest multiplier modulus; the periodic system is asymptotically
    /// stable when this is below 1.
    pub fn spectral_radius(&self) -> f64 {
        self.multipliers
            .iter()
            .map(|m| m.norm())
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::dmatrix;

    /// Closed form for 2x2: with `m = tr/2`, `d^2 = m^2 - det`,
    /// `exp(A) = e^m (cosh d I + sinh(d)/d (A - m I))`, evaluated with
    /// complex `d` so one formula covers real and complex eigenvalues.
    fn expm2_analytic(a: &DMatrix<f64>) -> DMatrix<f64> {
        let m = 0.5 * (a[(0, 0)] + a[(1, 1)]);
        let det = a[(0, 0)] * a[(1, 1)] - a[(0, 1)] * a[(1, 0)];
        let d = Complex64::new(m * m - det, 0.0).sqrt();
        let cosh = d.cosh().re;
        let sinhc = if d.norm() < 1e-8 {
            1.0
        } else {
            (d.sinh() / d).re
        };
        let em = m.exp();
        let eye = DMatrix::<f64>::identity(2, 2);
        (eye.clone() * cosh + (a - eye * m) * sinhc) * em
    }

    fn rel_err(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
        (a - b).norm() / b.norm()
    }

    #[test]
    fn expm_matches_analytic_2x2() {
        // Every Pade degree is hit (norms from 1e-3 to ~400) plus squarings;
        // the oscillators [[0, 1], [-k, -c]] h are the matrices the HTF code
        // exponentiates.
        // 1e-14 relative: both sides are a few ulps from the truth for these
        // well-conditioned matrices.
        let cases = [
            dmatrix![0.001, 0.002; -0.001, 0.0005],
            dmatrix![0.1, 0.05; -0.08, -0.02],
            dmatrix![0.0, 0.4; -0.5, -0.1],
            dmatrix![0.3, 1.0; -1.2, -0.4],
            dmatrix![-1.0, 2.0; 0.5, -3.0],
            dmatrix![0.0, 1.0; -200.0, -2.0] * 0.48,
            dmatrix![0.0, 1.0; -200.0, 0.0] * 0.52,
            dmatrix![0.0, 1.0; -200.0, -2.0] * 0.01,
            dmatrix![2.0, 1.0; 0.0, 2.0],
            dmatrix![0.5, 3.0; -3.0, 0.5] * 4.0,
        ];
        for a in &cases {
            let got = expm(a);
            let want = expm2_analytic(a);
            assert!(
                rel_err(&got, &want) < 1e-14,
                "{a}: {:e}",
                rel_err(&got, &want)
            );
        }
    }

    #[test]
    fn expm_of_a_stiff_oscillator_matches_high_precision() {
        // [[0, 2], [-400, -4]]: norm 400, strongly non-normal, so even the
        // double-precision closed form is only good to ~2e-14 here. Reference
        // from a 40-digit evaluation (mpmath.expm); 1e-13 relative reflects
        // the conditioning, about 400 * eps times a small factor.
        let a = dmatrix![0.0, 2.0; -400.0, -4.0];
        let want = dmatrix![
            -0.134_501_179_475_439_13, 0.000_583_528_427_096_690_2;
            -0.116_705_685_419_338_03, -0.135_668_236_329_632_5
        ];
        let got = expm(&a);
        assert!(rel_err(&got, &want) < 1e-13, "{:e}", rel_err(&got, &want));
    }

    #[test]
    fn expm_complex_matches_diagonal_and_group_property() {
        // Diagonal complex matrix: exp acts entrywise on the diagonal.
        let z = [Complex64::new(-0.3, 4.0), Complex64::new(1.2, -20.0)];
        let a = DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(&z));
        let e = expm(&a);
        for i in 0..2 {
            assert!((e[(i, i)] - z[i].exp()).norm() < 1e-13 * z[i].exp().norm());
        }
        assert!(e[(0, 1)].norm() < 1e-15 && e[(1, 0)].norm() < 1e-15);
        // exp(A) exp(-A) = I for a full complex 3x3 (errors ~ cond * eps).
        let m = DMatrix::from_fn(3, 3, |r, c| {
            Complex64::new((r as f64 - c as f64) * 0.7, 0.3 * (r + 2 * c) as f64)
        });
        let prod = expm(&m) * expm(&(-m.clone()));
        assert!((prod - DMatrix::<Complex64>::identity(3, 3)).norm() < 1e-12);
    }

    #[test]
    fn overflowing_monodromy_gives_nan_multipliers() {
        // exp(1000) overflows f64: no panic, no endless Schur iteration.
        let lti = PiecewiseLti::lti(
            1.0,
            dmatrix![1000.0, 0.0; 0.0, 1.0],
            dmatrix![0.0; 1.0],
            dmatrix![1.0, 0.0],
            dmatrix![0.0],
        )
        .unwrap();
        let f = Floquet::new(&lti);
        assert!(f.multipliers().iter().all(|m| m.re.is_nan()));
    }

    #[test]
    fn expm_non_finite_gives_nan() {
        let a = dmatrix![f64::NAN, 0.0; 0.0, 1.0];
        assert!(expm(&a).iter().all(|x| x.is_nan()));
    }
}
