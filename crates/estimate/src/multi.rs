//! The multi-experiment estimator: several records, one least-squares problem per output bin.

use std::f64::consts::PI;

use num_complex::Complex64;

use crate::error::{Error, Result};
use crate::estimate::{BiasSource, HtfEstimate, Method};
use crate::record::Prepared;
use crate::smallls::SmallLs;
use crate::smooth::{self, Alpha, BinSystem};
use htfid_data::TimeSeries;

/// Regularisation of the multi-experiment estimator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Regularisation {
    /// Plain per-bin least squares (needs at least as many records as harmonics).
    None,
    /// Per-bin ridge: `lambda_eff |G[k]|^2` added to every bin's cost, with
    /// `lambda_eff = lambda * mean Gram diagonal` (same scaling as `alpha`).
    Ridge(f64),
    /// Siddiqi's second-difference penalty across bins, applied to all records jointly.
    Smoothness(Alpha),
}

/// Treatment of transients and leakage.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Leakage {
    /// Records are assumed periodic in steady state (no leakage term).
    None,
    /// Local polynomial method: around each output bin `k`, over bins `k - half_width ..=
    /// k + half_width`, each `G_n` is a polynomial of `degree` in the bin offset and each record
    /// carries its own transient term, a polynomial of the same degree times
    /// `exp(-j w t_start)` (the transient is smooth in the record's own time origin). The
    /// transient is projected out and `G_n[k]` is the constant coefficient.
    Lpm {
        /// Bins on each side of the centre bin.
        half_width: usize,
        /// Polynomial degree for both `G_n` and the transient.
        degree: usize,
    },
}

/// Options of [`multi_experiment`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultiOptions {
    /// Residual variance is pooled over `2 * pool_half_width + 1` neighbouring bins (plain
    /// per-bin solve only; the local polynomial method has its own window, and the regularised
    /// solves pool over the whole band).
    pub pool_half_width: usize,
    /// Across-bin or per-bin regularisation.
    pub regularisation: Regularisation,
    /// Transient suppression.
    pub leakage: Leakage,
    /// Singular values below `rcond * sigma_max` of a bin's matrix are discarded.
    pub rcond: f64,
}

impl Default for MultiOptions {
    /// Pooling over 11 bins, no regularisation, no transient term, `rcond = 1e-10`.
    fn default() -> Self {
        Self {
            pool_half_width: 5,
            regularisation: Regularisation::None,
            leakage: Leakage::None,
            rcond: 1e-10,
        }
    }
}

/// Estimates `G_n` for `n` in `harmonics` at the output bins of `band` from `K` records
/// (typically phase-shifted segments of one experiment) that share one DFT grid.
///
/// Per output bin `k` it solves the `K x H` least squares `Y_r[k] = sum_n G_n[k] U_r[k - nP]`
/// (`r = 1..K`) through a Householder QR and a Jacobi SVD of the triangular factor, reporting the
/// bin's condition number. The residual variance of one bin has only `K - H` complex degrees of
/// freedom (2 for `K = 9`, `H = 7`), so it is pooled over `2 * pool_half_width + 1` neighbouring
/// bins (assuming a noise spectrum that is flat over that window) before forming
/// `stderr = sqrt(sigma^2 [(A^H A)^{-1}]_nn)`; [`HtfEstimate::dof`] reports the smallest pooled
/// degrees of freedom. Rank-deficient bins (below `rcond`) get the minimum-norm solution and an
/// infinite standard error.
///
/// With [`Regularisation::Ridge`] or [`Regularisation::Smoothness`] all bins are solved jointly
/// as in [`siddiqi`](crate::siddiqi) (possible with fewer records than harmonics), with one
/// residual variance `RSS / (N - tr S)` over the band and posterior standard errors; `cond` still
/// reports each bin's unregularised condition number (infinite when `K < H`). With
/// [`Leakage::Lpm`] each bin's variance comes from its own window,
/// `K (2 half_width + 1 - degree - 1) - H (degree + 1)` complex degrees of freedom.
///
/// Records phase-shifted by `T / K` alias: harmonics `n` and `n + K` enter every bin through
/// proportional columns, so truth outside the modelled set leaks into the estimate.
pub fn multi_experiment(
    records: &[TimeSeries],
    period: f64,
    harmonics: &[i32],
    band: (f64, f64),
    options: &MultiOptions,
) -> Result<HtfEstimate> {
    if !(options.rcond > 0.0 && options.rcond < 1.0) {
        return Err(Error::InvalidOption {
            name: "rcond",
            value: options.rcond,
            reason: "must lie in (0, 1)",
        });
    }
    let margin = match options.leakage {
        Leakage::None => 0,
        Leakage::Lpm { half_width, .. } => half_width,
    };
    let prep = Prepared::new(records, period, harmonics, band, margin, 1)?;
    let (k, h) = (prep.records(), harmonics.len());
    let omegas = prep.omegas();
    match (options.leakage, options.regularisation) {
        (Leakage::Lpm { half_width, degree }, Regularisation::None) => {
            let r = lpm(&prep, half_width, degree, options.rcond)?;
            Ok(HtfEstimate::new(
                Method::MultiExperimentLpm,
                harmonics.to_vec(),
                vec![omegas; h],
                r.values,
                r.stderr,
            )?
            .with_cond(r.cond)?
            .with_dof(r.dof))
        }
        (Leakage::Lpm { .. }, _) => Err(Error::LpmWithRegularisation),
        (Leakage::None, Regularisation::None) => {
            if k < h {
                return Err(Error::TooFewRecords {
                    records: k,
                    harmonics: h,
                });
            }
            let r = per_bin(&prep, options.pool_half_width, options.rcond);
            Ok(HtfEstimate::new(
                Method::MultiExperiment,
                harmonics.to_vec(),
                vec![omegas; h],
                r.values,
                r.stderr,
            )?
            .with_cond(r.cond)?
            .with_dof(r.dof))
        }
        (Leakage::None, Regularisation::Ridge(lambda)) => {
            let sys = BinSystem::new(&prep);
            let res = smooth::estimate(&sys, Alpha::Fixed(0.0), lambda)?;
            let lambda_eff = lambda * sys.gram_scale();
            regularised(
                &prep,
                Method::MultiExperimentRidge,
                res,
                lambda,
                lambda_eff,
                options,
            )
        }
        (Leakage::None, Regularisation::Smoothness(alpha)) => {
            let sys = BinSystem::new(&prep);
            let res = smooth::estimate(&sys, alpha, 0.0)?;
            let (a, a_eff) = (res.alpha, res.alpha_effective);
            regularised(&prep, Method::MultiExperimentSmooth, res, a, a_eff, options)
        }
    }
}

fn regularised(
    prep: &Prepared,
    method: Method,
    res: smooth::SmoothResult,
    weight: f64,
    weight_effective: f64,
    options: &MultiOptions,
) -> Result<HtfEstimate> {
    let h = prep.harmonics.len();
    Ok(HtfEstimate::new(
        method,
        prep.harmonics.clone(),
        vec![prep.omegas(); h],
        res.values,
        res.stderr,
    )?
    .with_bias(BiasSource::Smoothing, res.bias)?
    .with_cond(bin_conditions(prep, options.rcond))?
    .with_alpha(weight, weight_effective)
    .with_dof(res.dof))
}

struct PerBin {
    values: Vec<Vec<Complex64>>,
    stderr: Vec<Vec<f64>>,
    cond: Vec<f64>,
    dof: f64,
}

fn per_bin(prep: &Prepared, pool: usize, rcond: f64) -> PerBin {
    let (k, h, m) = (prep.records(), prep.harmonics.len(), prep.m);
    let mut ls = SmallLs::new(k, h);
    let mut x = vec![Complex64::new(0.0, 0.0); h];
    let mut var = vec![0.0; h];
    let mut values = vec![vec![Complex64::new(0.0, 0.0); m]; h];
    let mut vars = vec![vec![0.0; m]; h];
    let mut cond = vec![0.0; m];
    let mut rss = vec![0.0; m];
    let mut dof = vec![0usize; m];
    let mut full_rank = vec![true; m];
    for kb in 0..m {
        let bin = prep.k_lo + kb as i64;
        fill_bin(prep, bin, &mut ls);
        let info = ls.solve(rcond, &mut x, &mut var);
        for hh in 0..h {
            values[hh][kb] = x[hh];
            vars[hh][kb] = var[hh];
        }
        cond[kb] = info.cond;
        rss[kb] = info.rss;
        dof[kb] = k - info.rank;
        full_rank[kb] = info.rank == h;
    }
    // Prefix sums make every pooling window O(1).
    let mut crss = vec![0.0; m + 1];
    let mut cdof = vec![0usize; m + 1];
    for kb in 0..m {
        crss[kb + 1] = crss[kb] + rss[kb];
        cdof[kb + 1] = cdof[kb] + dof[kb];
    }
    let mut min_dof = usize::MAX;
    let mut stderr = vec![vec![0.0; m]; h];
    for kb in 0..m {
        let (lo, hi) = (kb.saturating_sub(pool), (kb + pool + 1).min(m));
        let d = cdof[hi] - cdof[lo];
        min_dof = min_dof.min(d);
        let sigma2 = if d > 0 {
            (crss[hi] - crss[lo]) / d as f64
        } else {
            f64::NAN
        };
        for hh in 0..h {
            stderr[hh][kb] = if full_rank[kb] {
                (sigma2 * vars[hh][kb]).sqrt()
            } else {
                f64::INFINITY
            };
        }
    }
    PerBin {
        values,
        stderr,
        cond,
        dof: min_dof as f64,
    }
}

fn fill_bin(prep: &Prepared, bin: i64, ls: &mut SmallLs) {
    for r in 0..prep.records() {
        for (hh, &s) in prep.shifts.iter().enumerate() {
            ls.set(r, hh, prep.u[r].at(bin - s));
        }
        ls.set_rhs(r, prep.y[r].at(bin));
    }
}

/// Condition number of each bin's `K x H` matrix (infinite when `K < H`).
fn bin_conditions(prep: &Prepared, rcond: f64) -> Vec<f64> {
    let (k, h, m) = (prep.records(), prep.harmonics.len(), prep.m);
    if k < h {
        return vec![f64::INFINITY; m];
    }
    let mut ls = SmallLs::new(k, h);
    let mut x = vec![Complex64::new(0.0, 0.0); h];
    let mut var = vec![0.0; h];
    (0..m)
        .map(|kb| {
            fill_bin(prep, prep.k_lo + kb as i64, &mut ls);
            ls.solve(rcond, &mut x, &mut var).cond
        })
        .collect()
}

/// `I - Q Q^T` for `Q` an orthonormal basis of the polynomials of `degree` on `2w + 1` points.
fn transient_projector(w: usize, degree: usize) -> Vec<f64> {
    let nw = 2 * w + 1;
    let mut q: Vec<Vec<f64>> = Vec::with_capacity(degree + 1);
    for p in 0..=degree {
        let mut v: Vec<f64> = (0..nw)
            .map(|t| ((t as f64 - w as f64) / w as f64).powi(p as i32))
            .collect();
        // Gram-Schmidt twice keeps the basis orthogonal to rounding.
        for _ in 0..2 {
            for u in &q {
                let d: f64 = u.iter().zip(&v).map(|(a, b)| a * b).sum();
                v.iter_mut().zip(u).for_each(|(vi, ui)| *vi -= d * ui);
            }
        }
        let norm = v.iter().map(|a| a * a).sum::<f64>().sqrt();
        v.iter_mut().for_each(|a| *a /= norm);
        q.push(v);
    }
    let mut pm = vec![0.0; nw * nw];
    for r in 0..nw {
        for c in 0..nw {
            let qq: f64 = q.iter().map(|u| u[r] * u[c]).sum();
            pm[r * nw + c] = if r == c { 1.0 - qq } else { -qq };
        }
    }
    pm
}

fn lpm(prep: &Prepared, w: usize, degree: usize, rcond: f64) -> Result<PerBin> {
    let (k, h, m) = (prep.records(), prep.harmonics.len(), prep.m);
    let nw = 2 * w + 1;
    let np = degree + 1;
    let unknowns = h * np;
    let equations = k * nw.saturating_sub(np);
    if w == 0 || equations <= unknowns {
        return Err(Error::LpmUnderdetermined {
            equations,
            unknowns,
        });
    }
    let pm = transient_projector(w, degree);
    let powers: Vec<f64> = (0..nw)
        .flat_map(|t| {
            let off = (t as f64 - w as f64) / w as f64;
            (0..np).map(move |p| off.powi(p as i32))
        })
        .collect();
    let mut ls = SmallLs::new(k * nw, unknowns);
    let mut x = vec![Complex64::new(0.0, 0.0); unknowns];
    let mut var = vec![0.0; unknowns];
    // Window columns of one record before projection: (h, p) columns then y.
    let mut raw = vec![Complex64::new(0.0, 0.0); nw * (unknowns + 1)];
    let mut values = vec![vec![Complex64::new(0.0, 0.0); m]; h];
    let mut stderr = vec![vec![0.0; m]; h];
    let mut cond = vec![0.0; m];
    let mut min_dof = usize::MAX;
    let inv_len = 1.0 / (prep.grid.n as f64 * prep.grid.dt);
    for kb in 0..m {
        let centre = prep.k_lo + kb as i64;
        for r in 0..k {
            let turns_per_bin = prep.t_starts[r] * inv_len;
            for t in 0..nw {
                let j = centre - w as i64 + t as i64;
                // exp(+j w_j t_start) moves the transient to the record's own time origin.
                let turns = j as f64 * turns_per_bin;
                let phi = Complex64::from_polar(1.0, 2.0 * PI * (turns - turns.round()));
                let row = &mut raw[t * (unknowns + 1)..(t + 1) * (unknowns + 1)];
                for (hh, &s) in prep.shifts.iter().enumerate() {
                    let u = phi * prep.u[r].at(j - s);
                    for p in 0..np {
                        row[hh * np + p] = u * powers[t * np + p];
                    }
                }
                row[unknowns] = phi * prep.y[r].at(j);
            }
            for t in 0..nw {
                let prow = &pm[t * nw..(t + 1) * nw];
                for c in 0..=unknowns {
                    let mut s = Complex64::new(0.0, 0.0);
                    for (tt, &pv) in prow.iter().enumerate() {
                        s += raw[tt * (unknowns + 1) + c] * pv;
                    }
                    if c < unknowns {
                        ls.set(r * nw + t, c, s);
                    } else {
                        ls.set_rhs(r * nw + t, s);
                    }
                }
            }
        }
        let info = ls.solve(rcond, &mut x, &mut var);
        let dof = equations.saturating_sub(info.rank);
        min_dof = min_dof.min(dof);
        let sigma2 = if dof > 0 {
            info.rss / dof as f64
        } else {
            f64::NAN
        };
        cond[kb] = info.cond;
        for hh in 0..h {
            values[hh][kb] = x[hh * np];
            stderr[hh][kb] = if info.rank == unknowns {
                (sigma2 * var[hh * np]).sqrt()
            } else {
                f64::INFINITY
            };
        }
    }
    Ok(PerBin {
        values,
        stderr,
        cond,
        dof: min_dof as f64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projector_annihilates_polynomials_and_is_idempotent() {
        let (w, deg) = (4usize, 2usize);
        let nw = 2 * w + 1;
        let pm = transient_projector(w, deg);
        let quad: Vec<f64> = (0..nw)
            .map(|t| {
                let x = t as f64 - 4.0;
                3.0 - x + 0.5 * x * x
            })
            .collect();
        for r in 0..nw {
            let v: f64 = (0..nw).map(|c| pm[r * nw + c] * quad[c]).sum();
            assert!(v.abs() < 1e-12);
            for c in 0..nw {
                let pp: f64 = (0..nw).map(|i| pm[r * nw + i] * pm[i * nw + c]).sum();
                assert!((pp - pm[r * nw + c]).abs() < 1e-12);
            }
        }
        let trace: f64 = (0..nw).map(|i| pm[i * nw + i]).sum();
        assert!((trace - (nw - deg - 1) as f64).abs() < 1e-12);
    }
}
