//! Truncated harmonic state space (Wereley) HTF.

use crate::coefficients::{FourierCoefficients, PiecewiseCoefficients};
use crate::error::TheoryError;
use crate::grid::{HarmonicTransferFunction, HtfGrid};
use htfid_ltp::{PiecewiseLti, SystemMatrix};
use nalgebra::DMatrix;
use num_complex::Complex64;
use std::f64::consts::TAU;

/// Largest harmonic state space dimension `(2N + 1) n` accepted; beyond it a
/// dense factorisation per frequency is impractical.
const MAX_HSS_SIZE: usize = 8192;

/// The HTF of the harmonic state space truncated to harmonics `-N..=N`:
/// `G(s) = C (sI - (A - N))^{-1} B + D` with block-Toeplitz `A`
/// (block `(p, q)` = `A_{p-q}`), `N = blockdiag(j p wp I)`, and likewise
/// `B`, `C`, `D`. The estimation-convention `G_n(jw)` is the middle block
/// row: `G_n(jw) = G_{0,-n}(jw)`, zero for `|n| > N`.
///
/// The truncation error comes from the harmonics `|p| > N` that the state
/// can no longer reach; it shrinks as fast as the Fourier coefficients of
/// `A(t)` decay (see the crate docs).
#[derive(Debug, Clone)]
pub struct TruncatedHtf {
    wp: f64,
    n_trunc: usize,
    n_states: usize,
    /// `A - N` (without `s I`), size `(2N+1) n` square.
    a_minus_n: DMatrix<Complex64>,
    /// Script `B`, `(2N+1) n x (2N+1)`.
    b: DMatrix<Complex64>,
    /// Middle block row of script `C`, `1 x (2N+1) n`.
    c_row: DMatrix<Complex64>,
    /// Middle row of script `D`, `1 x (2N+1)`.
    d_row: DMatrix<Complex64>,
}

impl TruncatedHtf {
    /// Truncated HTF of a SISO piecewise-LTI system from its closed-form
    /// Fourier coefficients. Systems with jumps are rejected
    /// ([`TheoryError::JumpNotRepresentable`]): a jump is an impulsive `A(t)`
    /// with no Fourier series of matrices.
    pub fn new(lti: &PiecewiseLti, n_trunc: usize) -> Result<Self, TheoryError> {
        if let Some(piece) = lti.first_jump() {
            return Err(TheoryError::JumpNotRepresentable { piece });
        }
        Self::from_coefficients(&PiecewiseCoefficients(lti), n_trunc)
    }

    /// Truncated HTF of a SISO system given by any Fourier-coefficient
    /// provider (coefficients `|k| <= 2N` of `A`, `B` and `|k| <= N` of `C`,
    /// `D` are used).
    pub fn from_coefficients<F>(sys: &F, n_trunc: usize) -> Result<Self, TheoryError>
    where
        F: FourierCoefficients + ?Sized,
    {
        let period = sys.period();
        if !(period.is_finite() && period > 0.0) {
            return Err(TheoryError::InvalidPeriod { period });
        }
        let wp = TAU / period;
        let a0 = sys.coefficient(SystemMatrix::A, 0);
        let n = a0.nrows();
        let b0 = sys.coefficient(SystemMatrix::B, 0);
        let c0 = sys.coefficient(SystemMatrix::C, 0);
        if b0.ncols() != 1 || c0.nrows() != 1 {
            return Err(TheoryError::NotSiso {
                inputs: b0.ncols(),
                outputs: c0.nrows(),
            });
        }
        let blocks = 2 * n_trunc + 1;
        let size = blocks.saturating_mul(n);
        if size > MAX_HSS_SIZE || n_trunc > MAX_HSS_SIZE {
            return Err(TheoryError::TruncationTooLarge {
                harmonics: n_trunc,
                size,
                max: MAX_HSS_SIZE,
            });
        }
        let nt = n_trunc as i32;
        let fetch = |which, k: i32, rows: usize, cols: usize| {
            let m = sys.coefficient(which, k);
            if m.shape() != (rows, cols) {
                return Err(TheoryError::CoefficientShape {
                    matrix: which,
                    harmonic: k,
                    expected_rows: rows,
                    expected_cols: cols,
                    found_rows: m.nrows(),
                    found_cols: m.ncols(),
                });
            }
            if m.iter().any(|v| !(v.re.is_finite() && v.im.is_finite())) {
                return Err(TheoryError::NonFiniteCoefficient {
                    matrix: which,
                    harmonic: k,
                });
            }
            Ok(m)
        };
        let a_k = (-2 * nt..=2 * nt)
            .map(|k| fetch(SystemMatrix::A, k, n, n))
            .collect::<Result<Vec<_>, _>>()?;
        let b_k = (-2 * nt..=2 * nt)
            .map(|k| fetch(SystemMatrix::B, k, n, 1))
            .collect::<Result<Vec<_>, _>>()?;
        let c_k = (-nt..=nt)
            .map(|k| fetch(SystemMatrix::C, k, 1, n))
            .collect::<Result<Vec<_>, _>>()?;
        let d_k = (-nt..=nt)
            .map(|k| fetch(SystemMatrix::D, k, 1, 1))
            .collect::<Result<Vec<_>, _>>()?;
        let a_at = |k: i32| &a_k[(k + 2 * nt) as usize];
        let b_at = |k: i32| &b_k[(k + 2 * nt) as usize];

        let mut a_minus_n = DMatrix::<Complex64>::zeros(size, size);
        let mut b = DMatrix::<Complex64>::zeros(size, blocks);
        for bp in 0..blocks {
            let p = bp as i32 - nt;
            for bq in 0..blocks {
                let q = bq as i32 - nt;
                a_minus_n
                    .view_mut((bp * n, bq * n), (n, n))
                    .copy_from(a_at(p - q));
                b.view_mut((bp * n, bq), (n, 1)).copy_from(b_at(p - q));
            }
            for i in 0..n {
                a_minus_n[(bp * n + i, bp * n + i)] -= Complex64::new(0.0, f64::from(p) * wp);
            }
        }
        let mut c_row = DMatrix::<Complex64>::zeros(1, size);
        let mut d_row = DMatrix::<Complex64>::zeros(1, blocks);
        for bq in 0..blocks {
            let q = bq as i32 - nt;
            c_row
                .view_mut((0, bq * n), (1, n))
                .copy_from(&c_k[(-q + nt) as usize]);
            d_row[(0, bq)] = d_k[(-q + nt) as usize][(0, 0)];
        }
        Ok(Self {
            wp,
            n_trunc,
            n_states: n,
            a_minus_n,
            b,
            c_row,
            d_row,
        })
    }

    /// Truncation order N (harmonics `-N..=N` are kept).
    pub fn truncation(&self) -> usize {
        self.n_trunc
    }

    /// `G_{0,q}(jw)` for `q = -N..=N`, i.e. `G_n(jw)` for `n = N..=-N`;
    /// `None` when `sI - (A - N)` is singular at `s = jw`.
    fn middle_row(&self, w: f64) -> Option<Vec<Complex64>> {
        let size = self.a_minus_n.nrows();
        // x^T = c_row (sI - (A - N))^{-1}, solved as (sI - (A - N))^T x = c_row^T.
        let mut m = -self.a_minus_n.transpose();
        for i in 0..size {
            m[(i, i)] += Complex64::new(0.0, w);
        }
        let x = m.lu().solve(&self.c_row.transpose())?;
        let row = x.transpose() * &self.b + &self.d_row;
        Some(row.iter().copied().collect())
    }

    /// Number of states of the underlying system.
    pub fn n_states(&self) -> usize {
        self.n_states
    }
}

impl HarmonicTransferFunction for TruncatedHtf {
    fn pumping_frequency(&self) -> f64 {
        self.wp
    }

    /// `G_n(jw)`; zero for `|n| > N`, NaN if `jw` is an eigenvalue of the
    /// truncated `A - N`.
    fn g(&self, n: i32, w: f64) -> Complex64 {
        let nt = self.n_trunc as i64;
        if i64::from(n).abs() > nt {
            return Complex64::new(0.0, 0.0);
        }
        match self.middle_row(w) {
            Some(row) => row[(nt - i64::from(n)) as usize],
            None => Complex64::new(f64::NAN, f64::NAN),
        }
    }

    /// One factorisation per frequency serves every harmonic.
    fn grid(&self, harmonics: &[i32], omegas: &[f64]) -> HtfGrid {
        let nt = self.n_trunc as i64;
        let mut values = Vec::with_capacity(harmonics.len() * omegas.len());
        for &w in omegas {
            let row = self.middle_row(w);
            for &n in harmonics {
                let n = i64::from(n);
                values.push(match &row {
                    _ if n.abs() > nt => Complex64::new(0.0, 0.0),
                    Some(row) => row[(nt - n) as usize],
                    None => Complex64::new(f64::NAN, f64::NAN),
                });
            }
        }
        HtfGrid {
            omegas: omegas.to_vec(),
            harmonics: harmonics.to_vec(),
            values,
        }
    }
}
