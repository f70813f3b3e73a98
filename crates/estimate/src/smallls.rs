//! Small dense complex least squares, solved once per frequency bin with reused buffers:
//! Householder QR, then a one-sided Jacobi SVD of the triangular factor for the condition
//! number, a rank-revealing solve and the diagonal of `(A^H A)^+`.

use num_complex::Complex64;

/// Jacobi rotations stop when every column pair is orthogonal to this relative level.
const JACOBI_TOL: f64 = 1e-15;
/// One-sided Jacobi converges quadratically; 30 sweeps is far beyond what a 25 x 25 needs.
const MAX_SWEEPS: usize = 30;

/// Outcome of one solve.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LsInfo {
    /// Residual sum of squares `|y - A x|^2`.
    pub rss: f64,
    /// Singular values above `rcond * sigma_max`.
    pub rank: usize,
    /// `sigma_max / sigma_min` (infinite if `sigma_min` is zero).
    pub cond: f64,
}

/// Reusable workspace for an `m x p` problem, `m >= p`.
#[derive(Debug, Clone)]
pub(crate) struct SmallLs {
    m: usize,
    p: usize,
    /// Column-major `m x p`.
    a: Vec<Complex64>,
    y: Vec<Complex64>,
    hv: Vec<Complex64>,
    /// Column-major `p x p`: `R`, then `R V` = `U Sigma`.
    w: Vec<Complex64>,
    v: Vec<Complex64>,
    sigma: Vec<f64>,
}

impl SmallLs {
    /// # Panics
    /// If `m < p` or `p == 0` (internal contract).
    pub(crate) fn new(m: usize, p: usize) -> Self {
        assert!(m >= p && p >= 1);
        let z = Complex64::new(0.0, 0.0);
        Self {
            m,
            p,
            a: vec![z; m * p],
            y: vec![z; m],
            hv: vec![z; m],
            w: vec![z; p * p],
            v: vec![z; p * p],
            sigma: vec![0.0; p],
        }
    }

    #[inline]
    pub(crate) fn set(&mut self, row: usize, col: usize, value: Complex64) {
        self.a[col * self.m + row] = value;
    }

    #[inline]
    pub(crate) fn set_rhs(&mut self, row: usize, value: Complex64) {
        self.y[row] = value;
    }

    /// Solves `min |y - A x|`, discarding singular directions below `rcond * sigma_max`
    /// (minimum-norm solution), and writes `diag((A^H A)^+)` into `var_diag`. Overwrites the
    /// matrix and right-hand side.
    pub(crate) fn solve(
        &mut self,
        rcond: f64,
        x: &mut [Complex64],
        var_diag: &mut [f64],
    ) -> LsInfo {
        let (m, p) = (self.m, self.p);
        let zero = Complex64::new(0.0, 0.0);
        // Householder QR: column j is reflected onto alpha e_j, alpha = -phase(x0) |x|.
        for j in 0..p {
            let cj = j * m;
            let norm2: f64 = self.a[cj + j..cj + m].iter().map(|c| c.norm_sqr()).sum();
            if norm2 == 0.0 {
                continue;
            }
            let norm = norm2.sqrt();
            let x0 = self.a[cj + j];
            let phase = if x0.norm() > 0.0 {
                x0 / x0.norm()
            } else {
                Complex64::new(1.0, 0.0)
            };
            let alpha = -phase * norm;
            for i in j..m {
                self.hv[i] = self.a[cj + i];
            }
            self.hv[j] = x0 - alpha;
            let vnorm2 = norm2 - x0.norm_sqr() + self.hv[j].norm_sqr();
            if vnorm2 > 0.0 {
                for c in j + 1..p {
                    let cc = c * m;
                    let mut s = zero;
                    for i in j..m {
                        s += self.hv[i].conj() * self.a[cc + i];
                    }
                    let f = s * (2.0 / vnorm2);
                    for i in j..m {
                        self.a[cc + i] -= f * self.hv[i];
                    }
                }
                let mut s = zero;
                for i in j..m {
                    s += self.hv[i].conj() * self.y[i];
                }
                let f = s * (2.0 / vnorm2);
                for i in j..m {
                    self.y[i] -= f * self.hv[i];
                }
            }
            self.a[cj + j] = alpha;
        }
        let rss_tail: f64 = self.y[p..m].iter().map(|c| c.norm_sqr()).sum();
        for c in 0..p {
            for r in 0..p {
                self.w[c * p + r] = if r <= c { self.a[c * m + r] } else { zero };
                self.v[c * p + r] = if r == c {
                    Complex64::new(1.0, 0.0)
                } else {
                    zero
                };
            }
        }
        self.jacobi();
        let smax = self.sigma.iter().copied().fold(0.0, f64::max);
        let smin = self.sigma.iter().copied().fold(f64::INFINITY, f64::min);
        let cond = if smin > 0.0 {
            smax / smin
        } else {
            f64::INFINITY
        };
        let mut rank = 0;
        x.iter_mut().for_each(|v| *v = zero);
        var_diag.iter_mut().for_each(|v| *v = 0.0);
        for i in 0..p {
            let s = self.sigma[i];
            if !(smax > 0.0 && s > rcond * smax) {
                continue;
            }
            rank += 1;
            let wi = &self.w[i * p..(i + 1) * p];
            let mut proj = zero;
            for r in 0..p {
                proj += wi[r].conj() * self.y[r];
            }
            let coef = proj / (s * s);
            let vi = &self.v[i * p..(i + 1) * p];
            for h in 0..p {
                x[h] += vi[h] * coef;
                var_diag[h] += vi[h].norm_sqr() / (s * s);
            }
        }
        let mut rss = rss_tail;
        if rank < p {
            // Dropped directions leave part of Q^H y unexplained: residual of R x = c, with R
            // rebuilt from U Sigma V^H = W V^H.
            for r in 0..p {
                let mut fit = zero;
                for c in 0..p {
                    let mut rc = zero;
                    for i in 0..p {
                        rc += self.w[i * p + r] * self.v[i * p + c].conj();
                    }
                    fit += rc * x[c];
                }
                rss += (self.y[r] - fit).norm_sqr();
            }
        }
        LsInfo { rss, rank, cond }
    }

    /// One-sided (Hestenes) Jacobi on the columns of `w`, accumulating the rotations in `v`.
    fn jacobi(&mut self) {
        let p = self.p;
        for _ in 0..MAX_SWEEPS {
            let mut rotated = false;
            for a in 0..p.saturating_sub(1) {
                for b in a + 1..p {
                    let (mut alpha, mut beta, mut gamma) = (0.0, 0.0, Complex64::new(0.0, 0.0));
                    for r in 0..p {
                        let (wa, wb) = (self.w[a * p + r], self.w[b * p + r]);
                        alpha += wa.norm_sqr();
                        beta += wb.norm_sqr();
                        gamma += wa.conj() * wb;
                    }
                    let g = gamma.norm();
                    if g == 0.0 || g <= JACOBI_TOL * (alpha * beta).sqrt() {
                        continue;
                    }
                    rotated = true;
                    // Turning column b by conj(gamma)/|gamma| makes the pair's inner product
                    // real, after which the real Jacobi rotation applies.
                    let e = gamma.conj() / g;
                    let zeta = (beta - alpha) / (2.0 * g);
                    let t = zeta.signum() / (zeta.abs() + (1.0 + zeta * zeta).sqrt());
                    let cs = 1.0 / (1.0 + t * t).sqrt();
                    let sn = cs * t;
                    for mat in [&mut self.w, &mut self.v] {
                        for r in 0..p {
                            let wa = mat[a * p + r];
                            let wb = mat[b * p + r] * e;
                            mat[a * p + r] = wa * cs - wb * sn;
                            mat[b * p + r] = wa * sn + wb * cs;
                        }
                    }
                }
            }
            if !rotated {
                break;
            }
        }
        for i in 0..p {
            self.sigma[i] = self.w[i * p..(i + 1) * p]
                .iter()
                .map(|c| c.norm_sqr())
                .sum::<f64>()
                .sqrt();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random(m: usize, p: usize, rng: &mut ChaCha8Rng) -> DMatrix<Complex64> {
        DMatrix::from_fn(m, p, |_, _| {
            Complex64::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))
        })
    }

    #[test]
    fn matches_normal_equations_and_nalgebra_svd() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for (m, p) in [(9usize, 7usize), (7, 7), (36, 21), (5, 1)] {
            let a = random(m, p, &mut rng);
            let y = random(m, 1, &mut rng);
            let mut ls = SmallLs::new(m, p);
            for r in 0..m {
                for c in 0..p {
                    ls.set(r, c, a[(r, c)]);
                }
                ls.set_rhs(r, y[(r, 0)]);
            }
            let mut x = vec![Complex64::new(0.0, 0.0); p];
            let mut var = vec![0.0; p];
            let info = ls.solve(1e-12, &mut x, &mut var);
            // Oracle: normal equations with nalgebra's LU (random A, cond ~ 10..100).
            let ah = a.adjoint();
            let ginv = (&ah * &a).try_inverse().unwrap();
            let xs = &ginv * &ah * &y;
            let res = &y - &a * &xs;
            let svd = a.clone().svd(false, false);
            let sv = &svd.singular_values;
            let cond = sv.max() / sv.min();
            // Relative 1e-9: the normal equations square cond (<1e4) and lose ~1e-12.
            for h in 0..p {
                assert!((x[h] - xs[(h, 0)]).norm() <= 1e-9 * xs.norm(), "x[{h}]");
                assert!((var[h] - ginv[(h, h)].re).abs() <= 1e-9 * ginv[(h, h)].re);
            }
            assert!((info.rss - res.norm_squared()).abs() <= 1e-9 * y.norm_squared());
            assert!((info.cond - cond).abs() <= 1e-9 * cond);
            assert_eq!(info.rank, p);
        }
    }

    #[test]
    fn rank_deficient_problem_gives_minimum_norm_solution() {
        // Two identical columns: x1 + x2 = 1 with the minimum-norm split (0.5, 0.5).
        let mut ls = SmallLs::new(3, 2);
        for r in 0..3 {
            ls.set(r, 0, Complex64::new(1.0, 0.0));
            ls.set(r, 1, Complex64::new(1.0, 0.0));
            ls.set_rhs(r, Complex64::new(1.0, 0.0));
        }
        let mut x = vec![Complex64::new(0.0, 0.0); 2];
        let mut var = vec![0.0; 2];
        let info = ls.solve(1e-10, &mut x, &mut var);
        assert_eq!(info.rank, 1);
        assert!(info.cond > 1e12);
        for v in &x {
            assert!((v - Complex64::new(0.5, 0.0)).norm() < 1e-12);
        }
        assert!(info.rss < 1e-24);
    }
}
