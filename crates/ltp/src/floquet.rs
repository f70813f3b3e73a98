//! Matrix exponential, monodromy matrices and Floquet analysis.

use crate::piecewise::PiecewiseLti;
use nalgebra::{ComplexField, DMatrix};
use num_complex::Complex64;

/// Pade-13 numerator coefficients (Higham 2005, "The scaling and squaring
/// method for the matrix exponential revisited", table 2.3).
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

/// Lower-degree Pade coefficients and the 1-norm bounds `theta_m` up to
/// which degree `m` reaches unit roundoff in double precision (Higham 2005).
const PADE_LOW: [(&[f64], f64); 4] = [
    (&[120.0, 60.0, 12.0, 1.0], 1.495_585_217_958_292e-2),
    (
        &[30_240.0, 15_120.0, 3_360.0, 420.0, 30.0, 1.0],
        2.539_398_330_063_23e-1,
    ),
    (
        &[
            17_297_280.0,
            8_648_640.0,
            1_995_840.0,
            277_200.0,
            25_200.0,
            1_512.0,
            56.0,
            1.0,
        ],
        9.504_178_996_162_932e-1,
    ),
    (
        &[
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
        ],
        2.097_847_961_257_068,
    ),
];
const THETA13: f64 = 5.371_920_351_148_152;

fn norm1<T: ComplexField<RealField = f64>>(a: &DMatrix<T>) -> f64 {
    a.column_iter()
        .map(|col| col.iter().map(|x| x.clone().modulus()).sum::<f64>())
        .fold(0.0, f64::max)
}

fn scaled<T: ComplexField<RealField = f64>>(a: &DMatrix<T>, s: f64) -> DMatrix<T> {
    a.map(|x| x * T::from_real(s))
}

/// Matrix exponential `exp(A)` of a real or complex square matrix by scaling
/// and squaring with Pade approximants of degree 3 to 13 (Higham 2005).
///
/// Accurate to a few units of roundoff times the condition of the problem.
/// Non-square input is a broken contract; non-finite input gives a matrix of
/// NaN rather than a panic.
///
/// # Panics
/// If `a` is not square.
pub fn expm<T: ComplexField<RealField = f64>>(a: &DMatrix<T>) -> DMatrix<T> {
    assert!(a.is_square(), "expm needs a square matrix");
    let n = a.nrows();
    let nan = || DMatrix::from_element(n, n, T::from_real(f64::NAN));
    let norm = norm1(a);
    if !norm.is_finite() {
        return nan();
    }
    let eye = DMatrix::<T>::identity(n, n);
    let a2 = a * a;
    for (coeffs, theta) in PADE_LOW {
        if norm <= theta {
            // U = A * sum_odd b_k A^(k-1), V = sum_even b_k A^k.
            let mut u = eye.clone() * T::from_real(coeffs[1]);
            let mut v = eye.clone() * T::from_real(coeffs[0]);
            let mut power = eye.clone();
            let mut k = 2;
            while k < coeffs.len() {
                power = &power * &a2;
                v += &power * T::from_real(coeffs[k]);
                if k + 1 < coeffs.len() {
                    u += &power * T::from_real(coeffs[k + 1]);
                }
                k += 2;
            }
            let u = a * u;
            return pade_solve(&u, &v).unwrap_or_else(nan);
        }
    }
    // Degree 13 with scaling: A / 2^s has 1-norm <= theta_13.
    let s = (norm / THETA13).log2().ceil().max(0.0);
    let squarings = s as i32;
    let factor = 0.5_f64.powi(squarings);
    let a1 = scaled(a, factor);
    let a2 = scaled(&a2, factor * factor);
    let a4 = &a2 * &a2;
    let a6 = &a4 * &a2;
    let b = |k: usize| T::from_real(PADE13[k]);
    let inner_u = &a6 * b(13) + &a4 * b(11) + &a2 * b(9);
    let u = &a1 * (&a6 * inner_u + &a6 * b(7) + &a4 * b(5) + &a2 * b(3) + &eye * b(1));
    let inner_v = &a6 * b(12) + &a4 * b(10) + &a2 * b(8);
    let v = &a6 * inner_v + &a6 * b(6) + &a4 * b(4) + &a2 * b(2) + &eye * b(0);
    let Some(mut r) = pade_solve(&u, &v) else {
        return nan();
    };
    for _ in 0..squarings {
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
    /// Computes the monodromy matrix and its eigenvalues.
    pub fn new(lti: &PiecewiseLti) -> Self {
        let monodromy = lti.monodromy();
        let multipliers = monodromy.complex_eigenvalues().iter().copied().collect();
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
