//! Banded Hermitian positive definite matrices: Cholesky factorisation, solves, and the band of
//! the inverse by selected inversion.
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
        let mut madds = 0u64;
        for i in 0..n {
            let j0 = i.saturating_sub(b);
            // Rows above i are final; row i is being formed.
            let (done, rest) = self.data.split_at_mut(i * w);
            let row_i = &mut rest[..w];
            for j in j0..=i {
                let len = j - j0;
                let oi = j0 + b - i;
                let mut s = row_i[j + b - i];
                if j < i {
                    let rj = &done[j * w + j0 + b - j..j * w + b];
                    for (a, c) in row_i[oi..oi + len].iter().zip(rj) {
                        s -= a * c.conj();
                    }
                } else {
                    s -= row_i[oi..oi + len]
                        .iter()
                        .map(|a| a.norm_sqr())
                        .sum::<f64>();
                }
                madds += len as u64;
                if j == i {
                    let d = s.re;
                    if !(d > 0.0 && d.is_finite()) {
                        return Err(Error::NotPositiveDefinite { index: i, pivot: d });
                    }
                    row_i[b] = Complex64::new(d.sqrt(), 0.0);
                } else {
                    row_i[j + b - i] = s / done[j * w + b].re;
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

    /// Visits every row of `A^{-1}` within the band, last row first: `visit(i, z)` receives
    /// `z[d] = (A^{-1})_{i, i + d}` for `d = 0..=b` (zero beyond the matrix). Returns the number of
    /// complex multiply-adds.
    ///
    /// Uses the Takahashi recursion `Z_ij = (delta_ij / L_ii - sum_{l > i} conj(L_li) Z_lj) / L_ii`
    /// for `i <= j` within the band, which needs only rows `i + 1 ..= i + b` of `Z`: those are
    /// kept in a ring of `b + 1` rows, so the extra memory is `O(b^2)`.
    pub(crate) fn inverse_rows(&mut self, mut visit: impl FnMut(usize, &[Complex64])) -> u64 {
        let (n, b) = (self.n, self.b);
        let w = b + 1;
        // Row slot i % w holds Z[i][i + d] for d = 0..=b.
        let mut ring = vec![Complex64::new(0.0, 0.0); w * w];
        let mut col = vec![Complex64::new(0.0, 0.0); b];
        // slots[t] is the ring slot of row i + 1 + t.
        let mut slots = vec![0usize; b];
        let mut madds = 0u64;
        for i in (0..n).rev() {
            let lii = self.at(i, i).re;
            let lmax = (i + b).min(n - 1);
            let nl = lmax - i;
            for t in 0..nl {
                col[t] = self.at(i + 1 + t, i).conj();
                slots[t] = (i + 1 + t) % w;
            }
            let si = i % w;
            for d in (1..=b).rev() {
                let j = i + d;
                let v = if j < n {
                    // Z[l][j] for l = i + 1 + t: stored in row l when l <= j (t < d), else in
                    // row j, contiguously.
                    let row_j = &ring[slots[d - 1] * w..slots[d - 1] * w + w];
                    let mut s = Complex64::new(0.0, 0.0);
                    for t in 0..d {
                        s += col[t] * ring[slots[t] * w + d - 1 - t];
                    }
                    for (c, z) in col[d..nl].iter().zip(&row_j[1..]) {
                        s += c * z.conj();
                    }
                    madds += nl as u64;
                    -s / lii
                } else {
                    Complex64::new(0.0, 0.0)
                };
                ring[si * w + d] = v;
            }
            let mut s = Complex64::new(0.0, 0.0);
            for t in 0..nl {
                s += col[t] * ring[si * w + 1 + t].conj();
            }
            madds += nl as u64;
            ring[si * w] = Complex64::new((1.0 / lii - s.re) / lii, 0.0);
            visit(i, &ring[si * w..(si + 1) * w]);
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
        for (n, b) in [(12usize, 4usize), (21, 6), (30, 0), (8, 7)] {
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
            chol.inverse_rows(|i, row| {
                seen += 1;
                for (d, v) in row.iter().enumerate() {
                    let want = if i + d < n {
                        inv[(i, i + d)]
                    } else {
                        Complex64::new(0.0, 0.0)
                    };
                    assert!((v - want).norm() < 1e-12, "row {i}, offset {d}");
                }
            });
            assert_eq!(seen, n);
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
                c.inverse_rows(|_, _| {});
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
