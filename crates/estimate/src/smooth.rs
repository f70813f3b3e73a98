//! Regularised least squares across frequency bins: the engine behind [`siddiqi`] and the
//! regularised multi-experiment estimators.
//!
//! Unknowns are ordered bin-major (`x[kb * H + h] = G_{n_h}[k_lo + kb]`), so the data term is
//! block diagonal and the second-difference penalty `alpha (D2^T D2) (x) I_H` couples bins at
//! most two apart: the normal matrix is banded with half-bandwidth `2H`.
//!
//! [`siddiqi`]: crate::siddiqi

use num_complex::Complex64;

use crate::banded::{BandedCholesky, BandedHermitian, Work};
use crate::error::{Error, Result};
use crate::record::{Prepared, Spectrum};

/// How the regularisation weight is chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Alpha {
    /// A fixed dimensionless weight (see the crate docs for its scaling).
    Fixed(f64),
    /// Generalised cross-validation, minimising `(RSS / N) / (1 - tr S / N)^2` over the weight
    /// (`N` complex data, `S` the influence matrix): a grid of 25 weights from 1e-8 to 1e4 (half
    /// a decade apart), then a golden-section search in `log10(alpha)` between the neighbours of
    /// the best grid point, to 0.01 decade. Weights that leave fewer than `0.001 N` residual
    /// degrees of freedom are skipped: there the score is a ratio of two vanishing numbers that
    /// the (then ill-conditioned) normal matrix cannot resolve. On noise-free data the score
    /// vanishes everywhere and the choice is arbitrary. A score still falling at the grid's
    /// smallest weight is an error ([`Error::GcvAtSmallestWeight`]): the data then choose no
    /// smoothing, and the estimate there interpolates them.
    Gcv,
}

/// Terms of the series for the smoothing bias (see `fit`): two recover 77 to 85 % of the
/// noise-free error of a rational HTF at alpha 10 to 1000 (`tests/siddiqi.rs`), one 60 to 70 %.
const BIAS_TERMS: usize = 2;

/// Grid of `log10(alpha)` searched by GCV.
const GCV_LOG_LO: f64 = -8.0;
const GCV_LOG_HI: f64 = 4.0;
const GCV_GRID: usize = 25;
const GCV_LOG_TOL: f64 = 0.01;

/// Per-bin regression rows of all records.
#[derive(Debug, Clone)]
pub(crate) struct BinSystem {
    pub h: usize,
    pub k: usize,
    pub m: usize,
    /// `a[(kb * K + r) * H + h] = U_r[k - n_h P]`.
    pub a: Vec<Complex64>,
    /// `y[kb * K + r] = Y_r[k]`.
    pub y: Vec<Complex64>,
}

impl BinSystem {
    pub(crate) fn new(prep: &Prepared) -> Self {
        let mut sys = Self::inputs(prep);
        sys.set_outputs(prep, &prep.y);
        sys
    }

    /// The regression rows of `prep`'s inputs; the outputs are left empty.
    pub(crate) fn inputs(prep: &Prepared) -> Self {
        let (h, k, m) = (prep.harmonics.len(), prep.records(), prep.m);
        let mut a = Vec::with_capacity(m * k * h);
        for kb in 0..m as i64 {
            let bin = prep.k_lo + kb;
            for r in 0..k {
                for &s in &prep.shifts {
                    a.push(prep.u[r].at(bin - s));
                }
            }
        }
        Self {
            h,
            k,
            m,
            a,
            y: Vec::new(),
        }
    }

    /// Reads the output spectra `y` of `prep`'s records (the rows built from their inputs).
    pub(crate) fn set_outputs(&mut self, prep: &Prepared, y: &[Spectrum]) {
        let mut rows = Vec::with_capacity(self.m * self.k);
        for kb in 0..self.m as i64 {
            let bin = prep.k_lo + kb;
            for spectrum in y.iter().take(self.k) {
                rows.push(spectrum.at(bin));
            }
        }
        self.y = rows;
    }

    #[inline]
    fn row(&self, kb: usize, r: usize) -> &[Complex64] {
        let s = (kb * self.k + r) * self.h;
        &self.a[s..s + self.h]
    }

    /// Row-major `B[h1][h2] = sum_r conj(a_r[h1]) a_r[h2]`.
    fn gram(&self, kb: usize, out: &mut [Complex64]) {
        let h = self.h;
        out.iter_mut().for_each(|v| *v = Complex64::new(0.0, 0.0));
        for r in 0..self.k {
            let a = self.row(kb, r);
            for h1 in 0..h {
                let c = a[h1].conj();
                for h2 in 0..h {
                    out[h1 * h + h2] += c * a[h2];
                }
            }
        }
    }

    /// Mean diagonal of the data Gram matrices: `sum_{k, r, h} |U_r[k - n_h P]|^2 / (M H)`.
    pub(crate) fn gram_scale(&self) -> f64 {
        self.a.iter().map(|c| c.norm_sqr()).sum::<f64>() / (self.m * self.h) as f64
    }

    fn data_count(&self) -> f64 {
        (self.m * self.k) as f64
    }
}

/// Solution at one weight.
#[derive(Debug)]
pub(crate) struct SmoothFit {
    pub x: Vec<Complex64>,
    pub rss: f64,
    /// Trace of the influence matrix.
    pub trace: f64,
    /// Diagonal of the inverse normal matrix (empty unless asked for).
    pub zdiag: Vec<f64>,
    /// Estimate of the regularisation bias, `-N^{-1} R (x - bias)` with
    /// `R = alpha D2^T D2 (x) I + ridge I`, to BIAS_TERMS terms (empty unless `zdiag` was asked
    /// for).
    pub bias: Vec<Complex64>,
    /// Effort counters; only the linear-work test reads them.
    #[cfg_attr(not(test), allow(dead_code))]
    pub work: Work,
}

/// Entries of `D2^T D2` for `m` bins: `(diagonal, first off-diagonal, second off-diagonal)`,
/// entry `c` of an off-diagonal coupling bins `c` and `c + 1` (or `c + 2`).
fn penalty_bands(m: usize) -> [Vec<f64>; 3] {
    const STENCIL: [f64; 3] = [1.0, -2.0, 1.0];
    let mut bands = [vec![0.0; m], vec![0.0; m], vec![0.0; m]];
    for centre in 1..m.saturating_sub(1) {
        for (di, si) in STENCIL.iter().enumerate() {
            for (dj, sj) in STENCIL.iter().enumerate().skip(di) {
                bands[dj - di][centre - 1 + di] += si * sj;
            }
        }
    }
    bands
}

/// Solves `(sum_k B_k + ridge I + alpha D2^T D2 (x) I) x = A^H y` and the GCV ingredients.
///
/// The trace of the influence matrix is formed as
/// `tr S = M H - alpha tr(Z (D2^T D2 (x) I)) - ridge tr(Z)` (`Z` the inverse normal matrix),
/// which follows from `Z N = I`. The direct sum `tr(Z_kk B_k)` would cancel catastrophically
/// for small `alpha`, where `Z ~ 1/alpha` along the directions the data leave free while
/// `n - tr S` is tiny; `alpha Z` stays of order one.
pub(crate) fn fit(sys: &BinSystem, alpha: f64, ridge: f64, want_zdiag: bool) -> Result<SmoothFit> {
    Ok(Factored::new(sys, alpha, ridge, want_zdiag)?.solve(sys))
}

/// The part of a fit that depends on the inputs alone: the normal matrix at one weight,
/// factored, with the trace of the influence matrix and (when asked for) the diagonal of the
/// inverse. [`Factored::solve`] adds the outputs.
#[derive(Debug)]
pub(crate) struct Factored {
    chol: BandedCholesky,
    alpha: f64,
    ridge: f64,
    smooth: bool,
    pen: [Vec<f64>; 3],
    trace: f64,
    zdiag: Vec<f64>,
    want_zdiag: bool,
}

impl Factored {
    /// Builds and factors the normal matrix of `sys`'s inputs (its outputs are not read).
    pub(crate) fn new(sys: &BinSystem, alpha: f64, ridge: f64, want_zdiag: bool) -> Result<Self> {
        let (h, m) = (sys.h, sys.m);
        let n = m * h;
        let smooth = alpha > 0.0 && m >= 3;
        let b = if smooth { 2 * h } else { h - 1 };
        let pen = if smooth {
            penalty_bands(m)
        } else {
            [Vec::new(), Vec::new(), Vec::new()]
        };
        let mut mat = BandedHermitian::zeros(n, b);
        let mut g = vec![Complex64::new(0.0, 0.0); h * h];
        for kb in 0..m {
            sys.gram(kb, &mut g);
            let base = kb * h;
            for h1 in 0..h {
                for h2 in 0..=h1 {
                    mat.add_lower(base + h1, base + h2, g[h1 * h + h2]);
                }
                mat.add_lower(base + h1, base + h1, Complex64::new(ridge, 0.0));
            }
            if smooth {
                for (d, band) in pen.iter().enumerate() {
                    if kb >= d && band[kb - d] != 0.0 {
                        let v = Complex64::new(alpha * band[kb - d], 0.0);
                        for hh in 0..h {
                            mat.add_lower(base + hh, (kb - d) * h + hh, v);
                        }
                    }
                }
            }
        }
        let mut chol = mat.factor()?;
        let mut pen_trace = 0.0;
        let mut z_trace = 0.0;
        let mut zdiag = if want_zdiag { vec![0.0; n] } else { Vec::new() };
        chol.inverse_rows(|i, z| {
            let zii = z[0].re;
            z_trace += zii;
            if smooth {
                let kb = i / h;
                pen_trace += zii * pen[0][kb];
                for d in 1..=2 {
                    if kb + d < m {
                        // Z and D2^T D2 are symmetric in the pair, hence twice the real part.
                        pen_trace += 2.0 * z[d * h].re * pen[d][kb];
                    }
                }
            }
            if want_zdiag {
                zdiag[i] = zii;
            }
        });
        let trace = n as f64 - alpha * pen_trace - ridge * z_trace;
        Ok(Self {
            chol,
            alpha,
            ridge,
            smooth,
            pen,
            trace,
            zdiag,
            want_zdiag,
        })
    }

    /// The fit of `sys`'s outputs (its inputs must be those this was built from).
    pub(crate) fn solve(&self, sys: &BinSystem) -> SmoothFit {
        let (h, m) = (sys.h, sys.m);
        let n = m * h;
        let (alpha, ridge, smooth, pen, chol) =
            (self.alpha, self.ridge, self.smooth, &self.pen, &self.chol);
        let mut x = vec![Complex64::new(0.0, 0.0); n];
        for kb in 0..m {
            let base = kb * h;
            for r in 0..sys.k {
                let yr = sys.y[kb * sys.k + r];
                for (hh, a) in sys.row(kb, r).iter().enumerate() {
                    x[base + hh] += a.conj() * yr;
                }
            }
        }
        chol.solve_in_place(&mut x);
        // The penalised solution has mean `N^{-1} A^H A G = G - N^{-1} R G` (`R` the penalty),
        // so its bias is `b = -N^{-1} R G`: the curvature of `G` weighed by the smoother's
        // kernel. With `G = G_hat - b` this is a fixed point, `b = -N^{-1} R (G_hat - b)`; its
        // series, truncated after BIAS_TERMS terms, starts from the plug-in `-N^{-1} R G_hat`
        // (which falls short by the curvature the penalty already removed). The full series
        // would be `G_hat` minus the unregularised solution, the noise the penalty suppresses
        // included.
        let bias = if self.want_zdiag {
            let apply = |g: &[Complex64]| -> Vec<Complex64> {
                let mut out: Vec<Complex64> = g.iter().map(|v| v * ridge).collect();
                if smooth {
                    for kb in 0..m {
                        for hh in 0..h {
                            let at = |k: usize| g[k * h + hh];
                            let mut v = at(kb) * pen[0][kb];
                            for d in 1..=2 {
                                if kb + d < m {
                                    v += at(kb + d) * pen[d][kb];
                                }
                                if kb >= d {
                                    v += at(kb - d) * pen[d][kb - d];
                                }
                            }
                            out[kb * h + hh] += v * alpha;
                        }
                    }
                }
                out
            };
            let mut b = vec![Complex64::new(0.0, 0.0); n];
            for _ in 0..BIAS_TERMS {
                let g: Vec<Complex64> = x.iter().zip(&b).map(|(x, b)| x - b).collect();
                let mut rhs = apply(&g);
                chol.solve_in_place(&mut rhs);
                b = rhs.iter().map(|v| -v).collect();
            }
            b
        } else {
            Vec::new()
        };
        let mut rss = 0.0;
        for kb in 0..m {
            let xk = &x[kb * h..(kb + 1) * h];
            for r in 0..sys.k {
                let fit: Complex64 = sys.row(kb, r).iter().zip(xk).map(|(a, g)| a * g).sum();
                rss += (sys.y[kb * sys.k + r] - fit).norm_sqr();
            }
        }
        SmoothFit {
            x,
            rss,
            trace: self.trace,
            zdiag: self.zdiag.clone(),
            bias,
            work: chol.work(),
        }
    }
}

/// GCV ignores weights that leave fewer residual degrees of freedom than this fraction of the
/// data: there the score is a ratio of two vanishing quantities, and for small weights the
/// normal matrix (condition ~ 1 / (alpha (pi / M)^4)) is too ill-conditioned to resolve it.
const GCV_MIN_DOF_FRACTION: f64 = 1e-3;

/// A GCV choice at the grid's smallest weight that leaves fewer residual degrees of freedom
/// than this fraction of the data is refused: the estimate interpolates the data there (a
/// single record with five harmonics per bin leaves almost none), while records that determine
/// every bin alone leave most of them.
const GCV_INTERPOLATES_FRACTION: f64 = 0.05;

fn gcv_score(fit: &SmoothFit, nd: f64) -> f64 {
    let denom = 1.0 - fit.trace / nd;
    if denom < GCV_MIN_DOF_FRACTION {
        f64::INFINITY
    } else {
        fit.rss / nd / (denom * denom)
    }
}

/// Dimensionless weight minimising GCV.
pub(crate) fn gcv_alpha(sys: &BinSystem, scale: f64, ridge: f64) -> Result<f64> {
    let nd = sys.data_count();
    // The score at a weight, and the residual degrees of freedom it leaves.
    let score_dof = |log_a: f64| -> (f64, f64) {
        fit(sys, 10f64.powf(log_a) * scale, ridge, false).map_or((f64::INFINITY, f64::NAN), |f| {
            (gcv_score(&f, nd), nd - f.trace)
        })
    };
    let eval = |log_a: f64| score_dof(log_a).0;
    let step = (GCV_LOG_HI - GCV_LOG_LO) / (GCV_GRID - 1) as f64;
    let grid: Vec<f64> = (0..GCV_GRID)
        .map(|i| GCV_LOG_LO + step * i as f64)
        .collect();
    let (scores, dofs): (Vec<f64>, Vec<f64>) = grid.iter().map(|&g| score_dof(g)).unzip();
    let (best, best_score) = scores
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, s)| s.is_finite())
        .fold((usize::MAX, f64::INFINITY), |acc, (i, s)| {
            if s < acc.1 {
                (i, s)
            } else {
                acc
            }
        });
    if best == usize::MAX {
        return Err(Error::GcvFailed);
    }
    if best == 0 {
        // Where the records determine every bin alone (more records than harmonics), little
        // smoothing may well be best; where the weight is all that separates the harmonics,
        // the smallest one interpolates the data.
        // (A finite score at the smallest weight comes with its degrees of freedom.)
        if dofs[0] < GCV_INTERPOLATES_FRACTION * nd {
            return Err(Error::GcvAtSmallestWeight {
                alpha: 10f64.powf(grid[0]),
                dof: dofs[0],
                data: nd,
            });
        }
    }
    let (lo, hi) = (
        grid[best.saturating_sub(1)],
        grid[(best + 1).min(GCV_GRID - 1)],
    );
    let (x_gs, f_gs) = golden_min(eval, lo, hi, GCV_LOG_TOL);
    Ok(if f_gs <= best_score {
        10f64.powf(x_gs)
    } else {
        10f64.powf(grid[best])
    })
}

/// Values and standard errors at one weight, as per-harmonic arrays.
pub(crate) struct SmoothResult {
    pub values: Vec<Vec<Complex64>>,
    /// Estimated regularisation bias of every value.
    pub bias: Vec<Vec<Complex64>>,
    pub stderr: Vec<Vec<f64>>,
    pub alpha: f64,
    pub alpha_effective: f64,
    pub dof: f64,
}

/// Chooses the weight (if asked), solves, and forms posterior standard errors
/// `sqrt(sigma^2 Z_ii)` with `sigma^2 = RSS / (N_data - trace)`.
pub(crate) fn estimate(sys: &BinSystem, alpha: Alpha, ridge: f64) -> Result<SmoothResult> {
    let alpha = match alpha {
        Alpha::Fixed(a) => a,
        Alpha::Gcv => {
            let (scale, ridge_eff) = weights(sys, ridge)?;
            gcv_alpha(sys, scale, ridge_eff)?
        }
    };
    Ok(AtWeight::new(sys, alpha, ridge)?.estimate(sys))
}

/// The input's scale (`BinSystem::gram_scale`) and the ridge in its units, checked.
fn weights(sys: &BinSystem, ridge: f64) -> Result<(f64, f64)> {
    let scale = sys.gram_scale();
    if !(scale > 0.0 && scale.is_finite()) {
        return Err(Error::NoExcitation);
    }
    check_weight(ridge)?;
    Ok((scale, ridge * scale))
}

/// An estimate at a fixed weight, prepared from the inputs alone: every output estimated
/// with it ([`AtWeight::estimate`]) gives what [`estimate`] gives for that output, bit for bit.
#[derive(Debug)]
pub(crate) struct AtWeight {
    factored: Factored,
    alpha: f64,
    alpha_eff: f64,
}

impl AtWeight {
    /// Factors the normal matrix of `sys`'s inputs at the dimensionless weight `alpha`.
    pub(crate) fn new(sys: &BinSystem, alpha: f64, ridge: f64) -> Result<Self> {
        let (scale, ridge_eff) = weights(sys, ridge)?;
        check_weight(alpha)?;
        let alpha_eff = alpha * scale;
        Ok(Self {
            factored: Factored::new(sys, alpha_eff, ridge_eff, true)?,
            alpha,
            alpha_eff,
        })
    }

    /// The estimate from `sys`'s outputs (its inputs those this was prepared from).
    pub(crate) fn estimate(&self, sys: &BinSystem) -> SmoothResult {
        let f = self.factored.solve(sys);
        let dof = sys.data_count() - f.trace;
        // Below one residual degree of freedom the variance estimate is meaningless.
        let sigma2 = if dof >= 1.0 { f.rss / dof } else { f64::NAN };
        let (h, m) = (sys.h, sys.m);
        let values = (0..h)
            .map(|hh| (0..m).map(|kb| f.x[kb * h + hh]).collect())
            .collect();
        let bias = (0..h)
            .map(|hh| (0..m).map(|kb| f.bias[kb * h + hh]).collect())
            .collect();
        let stderr = (0..h)
            .map(|hh| {
                (0..m)
                    .map(|kb| (sigma2 * f.zdiag[kb * h + hh]).sqrt())
                    .collect()
            })
            .collect();
        SmoothResult {
            values,
            bias,
            stderr,
            alpha: self.alpha,
            alpha_effective: self.alpha_eff,
            dof,
        }
    }
}

fn check_weight(a: f64) -> Result<()> {
    if a.is_finite() && a >= 0.0 {
        Ok(())
    } else {
        Err(Error::InvalidAlpha { alpha: a })
    }
}

/// Golden-section search for a minimum of a unimodal `f` on `[lo, hi]`, until the bracket is
/// narrower than `tol`: the better of the two interior points and its value.
///
/// At most 300 steps: a `tol` below the spacing of floating-point numbers
/// near the bracket (zero, or relative to a tiny scale) would otherwise never be met.
pub fn golden_min(mut f: impl FnMut(f64) -> f64, mut lo: f64, mut hi: f64, tol: f64) -> (f64, f64) {
    let phi = (5f64.sqrt() - 1.0) / 2.0;
    let mut x1 = hi - phi * (hi - lo);
    let mut x2 = lo + phi * (hi - lo);
    let (mut f1, mut f2) = (f(x1), f(x2));
    let mut iterations = 0;
    while hi - lo > tol && iterations < GOLDEN_MAX_ITERATIONS {
        iterations += 1;
        if f1 <= f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - phi * (hi - lo);
            f1 = f(x1);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + phi * (hi - lo);
            f2 = f(x2);
        }
    }
    if f1 <= f2 {
        (x1, f1)
    } else {
        (x2, f2)
    }
}

/// Golden-section steps after which the bracket has shrunk by `0.618^300`, about `1e-63`: past
/// any resolution a double can hold.
const GOLDEN_MAX_ITERATIONS: usize = 300;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_min_ends_when_its_tolerance_cannot_be_met() {
        let mut calls = 0;
        let (x, _) = golden_min(
            |x| {
                calls += 1;
                (x - 1.0).powi(2)
            },
            0.0,
            3.0,
            0.0,
        );
        assert!((x - 1.0).abs() < 1e-7, "{x}");
        assert!(calls <= GOLDEN_MAX_ITERATIONS + 2, "{calls} evaluations");
    }
    use nalgebra::DMatrix;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn random_system(m: usize, k: usize, h: usize, seed: u64) -> BinSystem {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut c = || Complex64::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0));
        BinSystem {
            h,
            k,
            m,
            a: (0..m * k * h).map(|_| c()).collect(),
            y: (0..m * k).map(|_| c()).collect(),
        }
    }

    /// Dense oracle: the same problem as an ordinary stacked least squares
    /// `[A; sqrt(alpha) D2 (x) I; sqrt(ridge) I] x = [y; 0; 0]`.
    #[test]
    fn banded_fit_matches_dense_stacked_least_squares() {
        let (m, k, h) = (9usize, 2usize, 3usize);
        let sys = random_system(m, k, h, 5);
        let (alpha, ridge) = (0.7f64, 0.05f64);
        let n = m * h;
        let rows = m * k + (m - 2) * h + n;
        let mut big = DMatrix::<Complex64>::zeros(rows, n);
        let mut rhs = DMatrix::<Complex64>::zeros(rows, 1);
        let mut a_data = DMatrix::<Complex64>::zeros(m * k, n);
        for kb in 0..m {
            for r in 0..k {
                for hh in 0..h {
                    let v = sys.a[(kb * k + r) * h + hh];
                    big[(kb * k + r, kb * h + hh)] = v;
                    a_data[(kb * k + r, kb * h + hh)] = v;
                }
                rhs[(kb * k + r, 0)] = sys.y[kb * k + r];
            }
        }
        let sa = Complex64::new(alpha.sqrt(), 0.0);
        for c in 1..m - 1 {
            for hh in 0..h {
                let row = m * k + (c - 1) * h + hh;
                big[(row, (c - 1) * h + hh)] = sa;
                big[(row, c * h + hh)] = sa * -2.0;
                big[(row, (c + 1) * h + hh)] = sa;
            }
        }
        for i in 0..n {
            big[(m * k + (m - 2) * h + i, i)] = Complex64::new(ridge.sqrt(), 0.0);
        }
        let normal = big.adjoint() * &big;
        let zinv = normal.clone().try_inverse().unwrap();
        let x = &zinv * big.adjoint() * &rhs;
        let fitted = &a_data * &x;
        let rss = (rhs.rows(0, m * k) - &fitted).norm_squared();
        let trace = (&a_data * &zinv * a_data.adjoint()).trace().re;
        let f = fit(&sys, alpha, ridge, true).unwrap();
        // Random data, cond(normal) ~ 1e3: 1e-10 relative is rounding with margin.
        for i in 0..n {
            assert!((f.x[i] - x[(i, 0)]).norm() < 1e-10 * x.norm());
            assert!((f.zdiag[i] - zinv[(i, i)].re).abs() < 1e-10 * zinv[(i, i)].re);
        }
        assert!((f.rss - rss).abs() < 1e-10 * rss);
        assert!((f.trace - trace).abs() < 1e-10 * trace);
    }

    #[test]
    fn solver_work_is_linear_in_bins() {
        // Counted multiply-adds and storage, not time: 4x the bins must cost 4x (to the O(1/M)
        // edge effect of a few bins at each end, well under 1% here).
        let h = 7;
        let work: Vec<Work> = [300usize, 1200]
            .iter()
            .map(|&m| {
                fit(&random_system(m, 1, h, 3), 1.0, 0.0, true)
                    .unwrap()
                    .work
            })
            .collect();
        for (a, b) in [
            (work[0].factor as f64, work[1].factor as f64),
            (work[0].inverse as f64, work[1].inverse as f64),
            (work[0].stored as f64, work[1].stored as f64),
        ] {
            assert!((b / a - 4.0).abs() < 0.04, "ratio {}", b / a);
        }
    }
}
