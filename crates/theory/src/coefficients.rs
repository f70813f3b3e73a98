//! Providers of Fourier coefficients of LTP system matrices.

use crate::error::TheoryError;
use htfid_ltp::{MatrixFourierSeries, PiecewiseLti, SystemMatrix};
use nalgebra::DMatrix;
use num_complex::Complex64;

/// Fourier coefficients `M_n` of the periodic matrices of an LTP system
/// `x' = A(t) x + B(t) u, y = C(t) x + D(t) u`, in the crate convention
/// `M(t) = sum_n M_n exp(j n wp t)`.
pub trait FourierCoefficients {
    /// The period `T`.
    fn period(&self) -> f64;

    /// Coefficient `M_n` of the matrix `which`; zero outside the provider's
    /// band. Shapes: `A` n x n, `B` n x m, `C` p x n, `D` p x m.
    fn coefficient(&self, which: SystemMatrix, n: i32) -> DMatrix<Complex64>;
}

/// Closed-form coefficients of a piecewise-LTI system; only valid when it
/// has no jumps (checked by the caller).
#[derive(Debug)]
pub(crate) struct PiecewiseCoefficients<'a>(pub(crate) &'a PiecewiseLti);

impl FourierCoefficients for PiecewiseCoefficients<'_> {
    fn period(&self) -> f64 {
        self.0.period()
    }

    fn coefficient(&self, which: SystemMatrix, n: i32) -> DMatrix<Complex64> {
        self.0.fourier_coefficient(which, n)
    }
}

/// An LTP system given by truncated Fourier series of its four matrices
/// (for example from `htfid_ltp::fft_fourier` of a sampled linearisation).
#[derive(Debug, Clone, PartialEq)]
pub struct FourierLtp {
    a: MatrixFourierSeries,
    b: MatrixFourierSeries,
    c: MatrixFourierSeries,
    d: MatrixFourierSeries,
}

impl FourierLtp {
    /// Checks that the four series share one period (relative 1e-12) and
    /// have consistent shapes (`A` n x n, `B` n x m, `C` p x n, `D` p x m).
    pub fn new(
        a: MatrixFourierSeries,
        b: MatrixFourierSeries,
        c: MatrixFourierSeries,
        d: MatrixFourierSeries,
    ) -> Result<Self, TheoryError> {
        let period = a.period();
        for s in [&b, &c, &d] {
            if (s.period() - period).abs() > 1e-12 * period {
                return Err(TheoryError::PeriodMismatch {
                    first: period,
                    second: s.period(),
                });
            }
        }
        let (n, _) = a.shape();
        let (_, m) = b.shape();
        let (p, _) = c.shape();
        let expected = [
            (SystemMatrix::A, &a, (n, n)),
            (SystemMatrix::B, &b, (n, m)),
            (SystemMatrix::C, &c, (p, n)),
            (SystemMatrix::D, &d, (p, m)),
        ];
        for (which, s, (er, ec)) in expected {
            let (fr, fc) = s.shape();
            if (fr, fc) != (er, ec) {
                return Err(TheoryError::CoefficientShape {
                    matrix: which,
                    harmonic: 0,
                    expected_rows: er,
                    expected_cols: ec,
                    found_rows: fr,
                    found_cols: fc,
                });
            }
        }
        Ok(Self { a, b, c, d })
    }

    fn series(&self, which: SystemMatrix) -> &MatrixFourierSeries {
        match which {
            SystemMatrix::A => &self.a,
            SystemMatrix::B => &self.b,
            SystemMatrix::C => &self.c,
            SystemMatrix::D => &self.d,
        }
    }
}

impl FourierCoefficients for FourierLtp {
    fn period(&self) -> f64 {
        self.a.period()
    }

    fn coefficient(&self, which: SystemMatrix, n: i32) -> DMatrix<Complex64> {
        let s = self.series(which);
        s.coefficient(n).cloned().unwrap_or_else(|| {
            let (r, c) = s.shape();
            DMatrix::zeros(r, c)
        })
    }
}
