//! Banded Hermitian positive definite matrices: Cholesky factorisation, solves, and the diagonal
//! blocks of the inverse by selected inversion.
//!
//! Storage and work are `O(n b)` and `O(n b^2)` for order `n` and half-bandwidth `b`; nothing is
//! ever dense in `n`. The selected inversion keeps only `b + 1` rows of the inverse at a time.

use num_complex::Complex64;

use crate::error::{Error, Result};

/// Effort counters, so that tests can assert how work grows without timing anything.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct Work {
    /// Complex multiply-adds in the factorisation.
    pub factor: u64,
    /// Complex multiply-adds in the selected inversion.
    pub inverse: u64,
    /// Complex numbers held by the factor and the inversion's row buffer.
    pub stored: usize,
}

/// Lower band of a Hermitian matrix, row by row: row `i` holds columns `i - b ..= i`.
#[derive(Debug, Clone)]
pub(crate) struct BandedHermitian {
    n: usize,
    b: usize,
    data: Vec<Complex64>,
}

impl BandedHermitian {
    pub(crate) fn zeros(n: usize, b: usize) -> Self {
        Self {
            n,
            b,
            data: vec![Complex64::new(0.0, 0.0); n * (b + 1)],
        }
    }

    /// Adds `v` to entry `(i, j)` of the lower triangle.
    ///
    /// # Panics
    /// If `(i, j)` is outside the lower band (an internal contract of the callers).
    #[inline]
    pub(crate) fn add_lower(&mut self, i: usize, j: usize, v: Complex64) {
        assert!(j <= i && i - j <= self.b && i < self.n);
        self.data[i * (self.b + 1) + j + self.b - i] += v;
    }

    /// Cholesky factorisation `A = L L^H` in place.
    pub(crate) fn factor(mut self) -> Result<BandedCholesky> {
        let (n, b) = (self.n, self.b);
        let w = b + 1;
        let l = &mut self.data;
        let mut madds = 0u64;
        for i in 0..n {
            let j0 = i.saturating_sub(b);
            for j in j0..=i {
                let len = j - j0;
                let mut s = l[i * w + j + b - i];
                let ri = i * w + j0 + b - i;
                let rj = j * w + j0 + b - j;
                for t in 0..len {
                    s -= l[ri + t] * l[rj + t].conj();
                }
                madds += len as u64;
                if j == i {
                    let d = s.re;
                    if !(d > 0.0 && d.is_finite()) {
                        return Err(Error::NotPositiveDefinite { index: i, pivot: d });
                    }
                    l[i * w + b] = Complex64::new(d.sqrt(), 0.0);
                } else {
                    l[i * w + j + b - i] = s / l[j * w + b].re;
                }
            }
        }
        Ok(BandedCholesky {
            n,
            b,
            l: self.data,
            work: Work {
                factor: madds,
                inverse: 0,
                stored: n * w,
            },
        })
    }
}

/// The factor `L` of a banded Hermitian matrix, stored like [`BandedHermitian`].
#[derive(Debug, Clone)]
pub(crate) struct BandedCholesky {
    n: usize,
    b: usize,
    l: Vec<Complex64>,
    work: Work,
}

impl BandedCholesky {
    #[inline]
    fn at(&self, i: usize, j: usize) -> Complex64 {
        self.l[i * (self.b + 1) + j + self.b - i]
    }

    pub(crate) fn work(&self) -> Work {
        self.work
    }

    /// Solves `A x = rhs` in place.
    ///
    /// # Panics
    /// If `x.len()` is not the order of the matrix.
    pub(crate) fn solve_in_place(&self, x: &mut [Complex64]) {
        assert_eq!(x.len(), self.n);
        let (n, b) = (self.n, self.b);
        for i in 0..n {
            let j0 = i.saturating_sub(b);
            let mut s = x[i];
            for l in j0..i {
                s -= self.at(i, l) * x[l];
            }
            x[i] = s / self.at(i, i).re;
        }
        for i in (0..n).rev() {
            let xi = x[i] / self.at(i, i).re;
            x[i] = xi;
            for l in i.saturating_sub(b)..i {
                x[l] -= self.at(i, l).conj() * xi;
            }
        }
    }

    /// Visits the diagonal `h x h` blocks of `A^{-1}`, last block first, as row-major full
    /// Hermitian blocks. Returns the number of complex multiply-adds.
    ///
    /// Uses the Takahashi recursion `Z_ij = (delta_ij / L_ii - sum_{l > i} conj(L_li) Z_lj) / L_ii`
    /// for `i <= j` within the band, which needs only rows `i + 1 ..= i + b` of `Z`.
    ///
    /// # Panics
    /// If `h` does not divide the order or exceeds `b + 1` (internal contract).
    pub(crate) fn inverse_diagonal_blocks(
        &mut self,
        h: usize,
        mut visit: impl FnMut(usize, &[Complex64]),
    ) -> u64 {
        let (n, b) = (self.n, self.b);
        assert!(h >= 1 && n % h == 0 && h <= b + 1);
        let w = b + 1;
        // Row slot i % w holds Z[i][i + d] for d = 0..=b.
        let mut ring = vec![Complex64::new(0.0, 0.0); w * w];
        let mut col = vec![Complex64::new(0.0, 0.0); b];
        let mut block = vec![Complex64::new(0.0, 0.0); h * h];
        let z = |ring: &[Complex64], r: usize, c: usize| -> Complex64 {
            if r <= c {
                ring[(r % w) * w + c - r]
            } else {
                ring[(c % w) * w + r - c].conj()
            }
        };
        let mut madds = 0u64;
        for i in (0..n).rev() {
            let lii = self.at(i, i).re;
            let lmax = (i + b).min(n - 1);
            let nl = lmax - i;
            for t in 0..nl {
                col[t] = self.at(i + 1 + t, i).conj();
            }
            for d in (1..=b).rev() {
                let j = i + d;
                let v = if j < n {
                    let mut s = Complex64::new(0.0, 0.0);
                    for t in 0..nl {
                        s += col[t] * z(&ring, i + 1 + t, j);
                    }
                    madds += nl as u64;
                    -s / lii
                } else {
                    Complex64::new(0.0, 0.0)
                };
                ring[(i % w) * w + d] = v;
            }
            let mut s = Complex64::new(0.0, 0.0);
            for t in 0..nl {
                s += col[t] * ring[(i % w) * w + 1 + t].conj();
            }
            madds += nl as u64;
            ring[(i % w) * w] = Complex64::new((1.0 / lii - s.re) / lii, 0.0);
            if i % h == 0 {
                for r in 0..h {
                    for c in 0..h {
                        block[r * h + c] = z(&ring, i + r, i + c);
                    }
                }
                visit(i / h, &block);
            }
        }
        self.work.inverse += madds;
        self.work.stored = n * w + w * w;
        madds
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// A random Hermitian banded matrix made positive definite by diagonal dominance, with its
    /// dense copy for the oracle.
    fn random_banded(n: usize, b: usize, seed: u64) -> (BandedHermitian, DMatrix<Complex64>) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut dense = DMatrix::<Complex64>::zeros(n, n);
        for i in 0..n {
            for j in i.saturating_sub(b)..i {
                let v = Complex64::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0));
                dense[(i, j)] = v;
                dense[(j, i)] = v.conj();
            }
        }
        // Diagonal dominance makes it positive definite.
        for i in 0..n {
            dense[(i, i)] = Complex64::new(2.0 * (2 * b + 1) as f64, 0.0);
        }
        let mut band = BandedHermitian::zeros(n, b);
        for i in 0..n {
            for j in i.saturating_sub(b)..=i {
                band.add_lower(i, j, dense[(i, j)]);
            }
        }
        (band, dense)
    }

    #[test]
    fn solve_and_inverse_blocks_match_dense_linear_algebra() {
        for (n, b, h) in [(12usize, 4usize, 2usize), (21, 6, 3), (30, 0, 1), (8, 7, 4)] {
            let (band, dense) = random_banded(n, b, 7 + n as u64);
            let mut chol = band.factor().unwrap();
            let rhs: Vec<Complex64> = (0..n)
                .map(|i| Complex64::new(i as f64 * 0.3 - 1.0, (i % 3) as f64))
                .collect();
            let mut x = rhs.clone();
            chol.solve_in_place(&mut x);
            let inv = dense.clone().try_inverse().unwrap();
            let x_dense = &inv * DMatrix::from_column_slice(n, 1, &rhs);
            // Diagonally dominant, cond < 10: rounding gives ~1e-15; 1e-12 is generous.
            for i in 0..n {
                assert!((x[i] - x_dense[(i, 0)]).norm() < 1e-12);
            }
            let mut seen = 0;
            chol.inverse_diagonal_blocks(h, |k, blk| {
                seen += 1;
                for r in 0..h {
                    for c in 0..h {
                        let d = inv[(k * h + r, k * h + c)];
                        assert!((blk[r * h + c] - d).norm() < 1e-12, "block {k} ({r},{c})");
                    }
                }
            });
            assert_eq!(seen, n / h);
        }
    }

    #[test]
    fn indefinite_matrix_is_reported() {
        let mut a = BandedHermitian::zeros(3, 1);
        a.add_lower(0, 0, Complex64::new(1.0, 0.0));
        a.add_lower(1, 0, Complex64::new(2.0, 0.0));
        a.add_lower(1, 1, Complex64::new(1.0, 0.0));
        a.add_lower(2, 2, Complex64::new(1.0, 0.0));
        assert!(matches!(
            a.factor(),
            Err(Error::NotPositiveDefinite { index: 1, .. })
        ));
    }

    #[test]
    fn work_and_storage_grow_linearly_with_order() {
        // Exact counts: factor does sum_j (j - j0) over the band, selected inversion b per
        // off-diagonal plus b for the diagonal, per row; both are n b^2 + O(b^3).
        let b = 14;
        let counts: Vec<Work> = [1001usize, 4004]
            .iter()
            .map(|&n| {
                let band = banded_fixture(n, b);
                let mut c = band.factor().unwrap();
                c.inverse_diagonal_blocks(7, |_, _| {});
                c.work()
            })
            .collect();
        let ratio = |a: u64, b: u64| b as f64 / a as f64;
        // Edge effects are O(b^3)/O(n b^2) = O(b/n) ~ 1%: 4 +- 2%.
        assert!((ratio(counts[0].factor, counts[1].factor) - 4.0).abs() < 0.08);
        assert!((ratio(counts[0].inverse, counts[1].inverse) - 4.0).abs() < 0.08);
        let stored = counts[1].stored as f64 / counts[0].stored as f64;
        assert!((stored - 4.0).abs() < 0.08);
    }

    /// A diagonally dominant band matrix built without a dense copy.
    fn banded_fixture(n: usize, b: usize) -> BandedHermitian {
        let mut a = BandedHermitian::zeros(n, b);
        for i in 0..n {
            a.add_lower(i, i, Complex64::new(4.0 * b as f64, 0.0));
            for j in i.saturating_sub(b)..i {
                a.add_lower(i, j, Complex64::new(0.5, 0.25));
            }
        }
        a
    }
}
