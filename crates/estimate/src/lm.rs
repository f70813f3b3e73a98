//! Levenberg-Marquardt least squares with a finite-difference Jacobian.

use std::fmt::Display;

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result};

/// Finite-difference scheme for the Jacobian.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum FdScheme {
    /// `(r(p + h e_j) - r(p - h e_j)) / 2h`: error `O(h^2)`, two evaluations per parameter.
    Central,
    /// `(r(p + h e_j) - r(p)) / h`: error `O(h)`, one evaluation per parameter.
    Forward,
}

/// Why the iteration stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[non_exhaustive]
pub enum LmStop {
    /// Every column of `J` is nearly orthogonal to the residual:
    /// `max_j |J_j . r| / (|J_j| |r|) <= gtol` (or the residual vanished).
    GradientTolerance,
    /// An accepted step reduced the cost by at most `ftol * cost`.
    CostTolerance,
    /// The step shrank below `xtol * (|p| + xtol)`.
    StepTolerance,
    /// `max_iter` Jacobians were formed without meeting a tolerance.
    MaxIterations,
    /// No step reduced the cost even with a damping of `1e16`: a local minimum to the
    /// resolution of the finite differences, or a residual function that fails nearby.
    Stalled,
}

/// Options of [`levenberg_marquardt`].
#[derive(Debug, Clone, PartialEq)]
pub struct LmOptions {
    /// Most Jacobian evaluations (outer iterations).
    pub max_iter: usize,
    /// Relative cost reduction below which an accepted step ends the iteration.
    pub ftol: f64,
    /// Relative step length below which the iteration ends.
    pub xtol: f64,
    /// Gradient cosine below which the iteration ends.
    pub gtol: f64,
    /// Finite-difference scheme.
    pub fd_scheme: FdScheme,
    /// Relative finite-difference step; `None` uses `eps^(1/3)` (central) or `eps^(1/2)`
    /// (forward), which balance truncation and rounding error.
    pub fd_step: Option<f64>,
    /// Typical magnitude of each parameter (positive); the difference step for parameter `j` is
    /// `fd_step * max(|p_j|, scale_j)`. `None` uses `|p0_j|`, or 1 where `p0_j = 0`.
    pub scales: Option<Vec<f64>>,
    /// Box bounds `(lower, upper)` per parameter; trial points are projected onto the box and
    /// differences taken one-sided at a bound. Standard errors of a parameter at a bound are not
    /// meaningful.
    pub bounds: Option<Vec<(f64, f64)>>,
    /// Initial damping `lambda` (relative to the Marquardt diagonal).
    pub lambda0: f64,
    /// Extend an accepted step along its direction when the cost keeps falling beyond it.
    /// The cost along the step, `c(t)` for the point `x + t d`, is taken as the quadratic
    /// through its value and slope at `t = 0` (the slope `2 d^T J^T r`, exact for an exact
    /// Jacobian) and its value at `t = 1`; when that quadratic's minimum `t*` lies beyond
    /// [`EXTEND_FROM`] steps, one more evaluation tries `x + min(t*, EXTEND_MAX) d` (projected
    /// onto the box) and keeps it if its cost is lower still. In a curved valley, where
    /// Gauss-Newton steps fall short of the minimum along them by the same factor again and
    /// again (a gain ratio near 2), this saves the iterations spent walking there in short
    /// steps; one evaluation where a Jacobian costs one per parameter.
    pub extend_steps: bool,
}

/// Least multiple of the step worth trying when [`LmOptions::extend_steps`] is on.
pub const EXTEND_FROM: f64 = 1.5;
/// Most multiple of the step tried when [`LmOptions::extend_steps`] is on. (Trying again from
/// the extended point, up to 512 steps, was measured no faster on the Silverbox diagnosis.)
pub const EXTEND_MAX: f64 = 8.0;

impl Default for LmOptions {
    fn default() -> Self {
        Self {
            max_iter: 200,
            ftol: 1e-12,
            xtol: 1e-12,
            gtol: 1e-10,
            fd_scheme: FdScheme::Central,
            fd_step: None,
            scales: None,
            bounds: None,
            lambda0: 1e-3,
            extend_steps: false,
        }
    }
}

/// Result of [`levenberg_marquardt`].
#[derive(Debug, Clone, Serialize)]
pub struct LmFit {
    /// Best parameters found.
    pub params: Vec<f64>,
    /// `sqrt(diag(covariance))`, when the covariance exists (`NaN` for a parameter the data
    /// do not determine).
    pub stderr: Option<Vec<f64>>,
    /// `s^2 (J^T J)^{-1}` with `s^2 = cost / (m - p)` and `J` at `params`, on the directions
    /// the data determine: a parameter they do not determine (a zero column, or one involved
    /// in a direction of vanishing singular value) has `NaN` in its row and column. `None`
    /// when `m <= p` or no parameter is determined.
    pub covariance: Option<Vec<Vec<f64>>>,
    /// Sum of squared residuals `sum_i r_i^2` at `params`.
    pub cost: f64,
    /// Residuals at `params`.
    pub residuals: Vec<f64>,
    /// The finite-difference Jacobian `dr_i / dp_j` at `params`, row by row (`m` rows of `p`).
    pub jacobian: Vec<Vec<f64>>,
    /// Jacobians formed.
    pub iterations: usize,
    /// Calls of the residual function.
    pub evaluations: usize,
    /// Why the iteration stopped.
    pub stop: LmStop,
}

/// Damping beyond which no step is attempted.
const LAMBDA_MAX: f64 = 1e16;
/// Floor of the damping: repeated good steps must not drive it to zero, from which the
/// multiplicative increase could never recover.
const LAMBDA_MIN: f64 = 1e-15;

/// Evaluates `f`; a failure of the function or a non-finite residual is an error.
fn checked<E: Display>(
    f: impl FnOnce(&[f64], &mut [f64]) -> std::result::Result<(), E>,
    x: &[f64],
    r: &mut [f64],
) -> Result<()> {
    f(x, r).map_err(|e| Error::ResidualFailed {
        message: e.to_string(),
    })?;
    match r.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(Error::NonFiniteResidual {
            index,
            value: r[index],
        }),
        None => Ok(()),
    }
}

/// The residual function as the iteration sees it: single evaluations and the
/// finite-difference Jacobian (column by column, or columns in parallel).
trait Residuals {
    fn eval(&mut self, x: &[f64], r: &mut [f64]) -> Result<()>;
    #[allow(clippy::too_many_arguments)] // reason: the difference scheme's inputs
    fn jacobian(
        &mut self,
        x: &[f64],
        r: &[f64],
        jac: &mut DMatrix<f64>,
        scheme: FdScheme,
        step: f64,
        typical: &[f64],
        bounds: &[(f64, f64)],
    ) -> Result<()>;
    fn evaluations(&self) -> usize;
}

struct Problem<F> {
    f: F,
    evaluations: usize,
    scratch: (Vec<f64>, Vec<f64>),
}

impl<F, E> Residuals for Problem<F>
where
    F: FnMut(&[f64], &mut [f64]) -> std::result::Result<(), E>,
    E: Display,
{
    fn eval(&mut self, x: &[f64], r: &mut [f64]) -> Result<()> {
        self.evaluations += 1;
        checked(&mut self.f, x, r)
    }

    fn jacobian(
        &mut self,
        x: &[f64],
        r: &[f64],
        jac: &mut DMatrix<f64>,
        scheme: FdScheme,
        step: f64,
        typical: &[f64],
        bounds: &[(f64, f64)],
    ) -> Result<()> {
        let (mut rp, mut rm) = std::mem::take(&mut self.scratch);
        rp.resize(r.len(), 0.0);
        rm.resize(r.len(), 0.0);
        let mut xp = x.to_vec();
        let mut result = Ok(());
        let m = r.len();
        for (j, col) in jac.as_mut_slice().chunks_mut(m).enumerate() {
            let mut eval = |v: &[f64], out: &mut [f64]| {
                self.evaluations += 1;
                checked(&mut self.f, v, out).is_ok()
            };
            if let Err(e) = fd_column(
                &mut eval, &mut xp, x, r, j, col, scheme, step, typical[j], bounds[j], &mut rp,
                &mut rm,
            ) {
                result = Err(e);
                break;
            }
        }
        self.scratch = (rp, rm);
        result
    }

    fn evaluations(&self) -> usize {
        self.evaluations
    }
}

/// A residual function that takes several points at once and may be called from several
/// threads: the points of each finite-difference Jacobian are split into one chunk per thread,
/// and each chunk is one call (the same differences as column by column).
struct BatchProblem<F> {
    f: F,
    evaluations: usize,
}

impl<F, E> BatchProblem<F>
where
    F: Fn(&[&[f64]], &mut [&mut [f64]]) -> Vec<std::result::Result<(), E>> + Sync,
    E: Display,
{
    /// Evaluates every point of `points` into `outs`, in one chunk per thread; whether each
    /// succeeded with finite residuals.
    fn run(&mut self, points: &[Vec<f64>], outs: &mut [Vec<f64>]) -> Vec<bool> {
        self.evaluations += points.len();
        let chunk = points
            .len()
            .div_ceil(rayon::current_num_threads().max(1))
            .max(1);
        let f = &self.f;
        points
            .par_chunks(chunk)
            .zip(outs.par_chunks_mut(chunk))
            .flat_map_iter(|(pts, outs)| {
                let p: Vec<&[f64]> = pts.iter().map(Vec::as_slice).collect();
                let mut o: Vec<&mut [f64]> = outs.iter_mut().map(Vec::as_mut_slice).collect();
                let results = f(&p, &mut o);
                let ok: Vec<bool> = o
                    .iter()
                    .enumerate()
                    .map(|(i, r)| {
                        matches!(results.get(i), Some(Ok(()))) && r.iter().all(|v| v.is_finite())
                    })
                    .collect();
                ok
            })
            .collect()
    }
}

impl<F, E> Residuals for BatchProblem<F>
where
    F: Fn(&[&[f64]], &mut [&mut [f64]]) -> Vec<std::result::Result<(), E>> + Sync,
    E: Display,
{
    fn eval(&mut self, x: &[f64], r: &mut [f64]) -> Result<()> {
        self.evaluations += 1;
        let f = &self.f;
        checked(
            |x: &[f64], r: &mut [f64]| -> std::result::Result<(), String> {
                match f(&[x], &mut [r]).into_iter().next() {
                    Some(result) => result.map_err(|e| e.to_string()),
                    None => Err("the residual function returned no result".to_string()),
                }
            },
            x,
            r,
        )
    }

    fn jacobian(
        &mut self,
        x: &[f64],
        r: &[f64],
        jac: &mut DMatrix<f64>,
        scheme: FdScheme,
        step: f64,
        typical: &[f64],
        bounds: &[(f64, f64)],
    ) -> Result<()> {
        // `fd_column`'s rule, in two rounds: first `x + h e_j` wherever the box allows it, then
        // `x - h e_j` where the scheme needs both sides or the first side failed.
        let (np, m) = (x.len(), r.len());
        let h: Vec<f64> = (0..np).map(|j| step * x[j].abs().max(typical[j])).collect();
        // One side's points evaluated together: per column, the realised step and the index
        // of its residuals where the point succeeded.
        let mut side = |cols: Vec<usize>, sign: f64| {
            let points: Vec<Vec<f64>> = cols
                .iter()
                .map(|&j| {
                    let mut p = x.to_vec();
                    p[j] = x[j] + sign * h[j];
                    p
                })
                .collect();
            let mut rs = vec![vec![0.0; m]; cols.len()];
            let ok = self.run(&points, &mut rs);
            let mut at: Vec<Option<(f64, usize)>> = vec![None; np];
            for (k, &j) in cols.iter().enumerate() {
                if ok[k] {
                    at[j] = Some((points[k][j] - x[j], k));
                }
            }
            (at, rs)
        };
        let (plus, rp) = side(
            (0..np).filter(|&j| x[j] + h[j] <= bounds[j].1).collect(),
            1.0,
        );
        let (minus, rm) = side(
            (0..np)
                .filter(|&j| {
                    (scheme == FdScheme::Central || plus[j].is_none()) && x[j] - h[j] >= bounds[j].0
                })
                .collect(),
            -1.0,
        );
        for (j, col) in jac.as_mut_slice().chunks_mut(m).enumerate() {
            let p = plus[j].map(|(h, k)| (h, rp[k].as_slice()));
            let q = minus[j].map(|(h, k)| (h, rm[k].as_slice()));
            if !difference(col, r, p, q) {
                return Err(Error::JacobianFailed {
                    index: j,
                    value: x[j],
                });
            }
        }
        Ok(())
    }

    fn evaluations(&self) -> usize {
        self.evaluations
    }
}

/// Minimises `sum_i r_i(p)^2` over `p` from `p0`, where `residuals(p, r)` fills the `m`
/// residuals (an error or a non-finite value at a trial point rejects that point; at `p0` it is
/// an error).
///
/// Classic Levenberg-Marquardt: solve `(J^T J + lambda D) d = -J^T r` with Marquardt's scaling
/// `D = diag(J^T J)`, accept a step if the cost falls (then divide `lambda` by 3 when the gain
/// ratio exceeds 0.75, double it below 0.25), otherwise multiply `lambda` by 10 and retry. The
/// Jacobian is a finite difference (see [`FdScheme`]). Never panics on user input.
pub fn levenberg_marquardt<F, E>(
    residuals: F,
    p0: &[f64],
    m: usize,
    options: &LmOptions,
) -> Result<LmFit>
where
    F: FnMut(&[f64], &mut [f64]) -> std::result::Result<(), E>,
    E: Display,
{
    solve(
        Problem {
            f: residuals,
            evaluations: 0,
            scratch: (Vec::new(), Vec::new()),
        },
        p0,
        m,
        options,
    )
}

/// [`levenberg_marquardt`] for a residual function that may be called from several threads
/// at once: the columns of each finite-difference Jacobian are evaluated in parallel (rayon).
/// The iterates, the result and the count of evaluations are those of
/// [`levenberg_marquardt`].
pub fn levenberg_marquardt_parallel<F, E>(
    residuals: F,
    p0: &[f64],
    m: usize,
    options: &LmOptions,
) -> Result<LmFit>
where
    F: Fn(&[f64], &mut [f64]) -> std::result::Result<(), E> + Sync,
    E: Display,
{
    levenberg_marquardt_batch(
        |points: &[&[f64]], outs: &mut [&mut [f64]]| {
            points
                .iter()
                .zip(outs.iter_mut())
                .map(|(p, r)| residuals(p, r))
                .collect()
        },
        p0,
        m,
        options,
    )
}

/// [`levenberg_marquardt`] for a residual function that evaluates several points in one call,
/// `residuals(points, outs)` filling `outs[i]` for `points[i]` and returning one result per
/// point (a missing result counts as a failure). The points of each finite-difference Jacobian
/// are split into one chunk per rayon thread, each chunk one call: a function that works on
/// its points together (simulations stepped in lockstep, say) gains beyond the threads. The
/// iterates, the result and the count of evaluations are those of [`levenberg_marquardt`]
/// when each point's residuals are those of a single evaluation.
pub fn levenberg_marquardt_batch<F, E>(
    residuals: F,
    p0: &[f64],
    m: usize,
    options: &LmOptions,
) -> Result<LmFit>
where
    F: Fn(&[&[f64]], &mut [&mut [f64]]) -> Vec<std::result::Result<(), E>> + Sync,
    E: Display,
{
    solve(
        BatchProblem {
            f: residuals,
            evaluations: 0,
        },
        p0,
        m,
        options,
    )
}

/// [`levenberg_marquardt`] with the Jacobian from the caller: `jacobian(p, r, jac)` fills
/// `jac` (`m x n`, column-major: column `j` is `jac[j * m..(j + 1) * m]`) at `p`, where the
/// residuals are `r`, as exact derivatives (forward sensitivities, say) or any mix of its own.
/// A failure or a non-finite entry stops the fit with [`Error::JacobianFunction`]. The
/// difference options (`fd_scheme`, `fd_step`) are not used.
pub fn levenberg_marquardt_with_jacobian<F, J, E>(
    residuals: F,
    jacobian: J,
    p0: &[f64],
    m: usize,
    options: &LmOptions,
) -> Result<LmFit>
where
    F: FnMut(&[f64], &mut [f64]) -> std::result::Result<(), E>,
    J: FnMut(&[f64], &[f64], &mut [f64]) -> std::result::Result<(), E>,
    E: Display,
{
    solve(
        JacobianProblem {
            f: residuals,
            jac: jacobian,
            evaluations: 0,
        },
        p0,
        m,
        options,
    )
}

/// A residual function with the caller's Jacobian.
struct JacobianProblem<F, J> {
    f: F,
    jac: J,
    evaluations: usize,
}

impl<F, J, E> Residuals for JacobianProblem<F, J>
where
    F: FnMut(&[f64], &mut [f64]) -> std::result::Result<(), E>,
    J: FnMut(&[f64], &[f64], &mut [f64]) -> std::result::Result<(), E>,
    E: Display,
{
    fn eval(&mut self, x: &[f64], r: &mut [f64]) -> Result<()> {
        self.evaluations += 1;
        checked(&mut self.f, x, r)
    }

    fn jacobian(
        &mut self,
        x: &[f64],
        r: &[f64],
        jac: &mut DMatrix<f64>,
        _scheme: FdScheme,
        _step: f64,
        _typical: &[f64],
        _bounds: &[(f64, f64)],
    ) -> Result<()> {
        self.evaluations += 1;
        let m = r.len();
        (self.jac)(x, r, jac.as_mut_slice()).map_err(|e| Error::JacobianFunction {
            message: e.to_string(),
        })?;
        match jac.as_slice().iter().position(|v| !v.is_finite()) {
            Some(at) => Err(Error::JacobianFunction {
                message: format!("entry ({}, {}) is not finite", at % m.max(1), at / m.max(1)),
            }),
            None => Ok(()),
        }
    }

    fn evaluations(&self) -> usize {
        self.evaluations
    }
}

fn solve<P: Residuals>(mut prob: P, p0: &[f64], m: usize, options: &LmOptions) -> Result<LmFit> {
    let np = p0.len();
    if np == 0 || m == 0 {
        return Err(Error::LmDimensions {
            parameters: np,
            residuals: m,
        });
    }
    let bounds = validate(options, p0)?;
    let step = match options.fd_step {
        Some(s) => s,
        None => match options.fd_scheme {
            FdScheme::Central => f64::EPSILON.cbrt(),
            FdScheme::Forward => f64::EPSILON.sqrt(),
        },
    };
    let typical: Vec<f64> = match &options.scales {
        Some(s) => s.clone(),
        None => p0
            .iter()
            .map(|&v| if v != 0.0 { v.abs() } else { 1.0 })
            .collect(),
    };
    let mut x = p0.to_vec();
    let mut r = vec![0.0; m];
    prob.eval(&x, &mut r)?;
    let mut cost = sum_sq(&r);
    let mut lambda = options.lambda0;
    let mut jac = DMatrix::<f64>::zeros(m, np);
    let mut r_trial = vec![0.0; m];
    let mut x_trial = vec![0.0; np];
    let (mut x_ext, mut r_ext) = if options.extend_steps {
        (vec![0.0; np], vec![0.0; m])
    } else {
        (Vec::new(), Vec::new())
    };
    let mut iterations = 0;
    let mut jac_current = false;
    let mut stop = LmStop::MaxIterations;
    while iterations < options.max_iter {
        prob.jacobian(&x, &r, &mut jac, options.fd_scheme, step, &typical, &bounds)?;
        jac_current = true;
        iterations += 1;
        let rv = DVector::from_column_slice(&r);
        let mut g = jac.tr_mul(&rv);
        let rnorm = cost.sqrt();
        // Parameters held by their bound: on it, with the descent direction `-g` pointing out
        // of the box. They take no part in the step or in the gradient test (the projected
        // gradient), so a fit that ends on a bound converges as one inside the box does
        // instead of spending its iterations on steps the box clips away.
        let held: Vec<bool> = (0..np)
            .map(|j| {
                let (lo, hi) = bounds[j];
                (x[j] <= lo && g[j] > 0.0) || (x[j] >= hi && g[j] < 0.0)
            })
            .collect();
        let cosine = (0..np)
            .filter(|&j| !held[j])
            .map(|j| {
                let cn = jac.column(j).norm();
                if cn > 0.0 && rnorm > 0.0 {
                    g[j].abs() / (cn * rnorm)
                } else {
                    0.0
                }
            })
            .fold(0.0, f64::max);
        if cost == 0.0 || cosine <= options.gtol {
            stop = LmStop::GradientTolerance;
            break;
        }
        let mut a = jac.tr_mul(&jac);
        for j in (0..np).filter(|&j| held[j]) {
            for i in 0..np {
                a[(i, j)] = 0.0;
                a[(j, i)] = 0.0;
            }
            g[j] = 0.0;
        }
        let dmax = (0..np).map(|j| a[(j, j)]).fold(0.0, f64::max);
        // A parameter with no influence still needs some damping to keep the system regular.
        let diag: Vec<f64> = (0..np)
            .map(|j| a[(j, j)].max(1e-15 * dmax).max(f64::MIN_POSITIVE))
            .collect();
        let mut accepted = false;
        loop {
            if lambda > LAMBDA_MAX {
                stop = LmStop::Stalled;
                break;
            }
            let mut mat = a.clone();
            for j in 0..np {
                mat[(j, j)] += lambda * diag[j];
            }
            let Some(chol) = mat.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let delta = -chol.solve(&g);
            for j in 0..np {
                let (lo, hi) = bounds[j];
                x_trial[j] = (x[j] + delta[j]).clamp(lo, hi);
            }
            let dnorm = x_trial
                .iter()
                .zip(&x)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
                .sqrt();
            let xnorm = sum_sq(&x).sqrt();
            if !dnorm.is_finite() {
                lambda *= 10.0;
                continue;
            }
            if dnorm <= options.xtol * (xnorm + options.xtol) {
                stop = LmStop::StepTolerance;
                break;
            }
            if prob.eval(&x_trial, &mut r_trial).is_err() {
                lambda *= 10.0;
                continue;
            }
            let cost_trial = sum_sq(&r_trial);
            if cost_trial < cost {
                // Predicted cost |r + J d|^2 with the realised (projected) step.
                let d = DVector::from_iterator(np, x_trial.iter().zip(&x).map(|(a, b)| a - b));
                let lin = &rv + &jac * &d;
                let predicted = cost - lin.norm_squared();
                let rho = if predicted > 0.0 {
                    (cost - cost_trial) / predicted
                } else {
                    0.0
                };
                if rho > 0.75 {
                    lambda = (lambda / 3.0).max(LAMBDA_MIN);
                } else if rho < 0.25 {
                    lambda *= 2.0;
                }
                let old = cost;
                let mut cost_new = cost_trial;
                if options.extend_steps {
                    if let Some(t) = extension(old, cost_trial, g.dot(&d)) {
                        for j in 0..np {
                            let (lo, hi) = bounds[j];
                            x_ext[j] = (x[j] + t * d[j]).clamp(lo, hi);
                        }
                        if prob.eval(&x_ext, &mut r_ext).is_ok() {
                            let cost_ext = sum_sq(&r_ext);
                            if cost_ext < cost_trial {
                                std::mem::swap(&mut x_trial, &mut x_ext);
                                std::mem::swap(&mut r_trial, &mut r_ext);
                                cost_new = cost_ext;
                            }
                        }
                    }
                }
                let reduction = old - cost_new;
                std::mem::swap(&mut x, &mut x_trial);
                std::mem::swap(&mut r, &mut r_trial);
                cost = cost_new;
                jac_current = false;
                accepted = true;
                if reduction <= options.ftol * old {
                    stop = LmStop::CostTolerance;
                }
                break;
            }
            lambda *= 10.0;
        }
        if !accepted || stop == LmStop::CostTolerance {
            break;
        }
    }
    if !jac_current {
        prob.jacobian(&x, &r, &mut jac, options.fd_scheme, step, &typical, &bounds)?;
    }
    let covariance = covariance(&jac, cost, m);
    let stderr = covariance
        .as_ref()
        .map(|c| (0..np).map(|j| c[j][j].sqrt()).collect());
    Ok(LmFit {
        params: x,
        stderr,
        covariance,
        cost,
        residuals: r,
        jacobian: (0..m)
            .map(|i| (0..np).map(|j| jac[(i, j)]).collect())
            .collect(),
        iterations,
        evaluations: prob.evaluations(),
        stop,
    })
}

/// Multiple of an accepted step worth trying (see [`LmOptions::extend_steps`]): the minimum of
/// the quadratic `c(t)` with `c(0) = c0`, `c'(0) = 2 slope` (`slope = d^T J^T r`, negative
/// along a descent direction) and `c(1) = c1`, when it lies beyond [`EXTEND_FROM`]; capped at
/// [`EXTEND_MAX`], which is also taken when the cost falls faster than linearly (no minimum).
fn extension(c0: f64, c1: f64, slope: f64) -> Option<f64> {
    let a = -2.0 * slope;
    if !(a > 0.0 && c1 < c0) {
        return None;
    }
    // c(t) = c0 - a t + b t^2 through c(1) = c1.
    let b = c1 - c0 + a;
    let t = if b > 0.0 { a / (2.0 * b) } else { EXTEND_MAX };
    (t >= EXTEND_FROM).then_some(t.min(EXTEND_MAX))
}

fn sum_sq(v: &[f64]) -> f64 {
    v.iter().map(|a| a * a).sum()
}

fn validate(options: &LmOptions, p0: &[f64]) -> Result<Vec<(f64, f64)>> {
    let np = p0.len();
    for (name, value) in [
        ("ftol", options.ftol),
        ("xtol", options.xtol),
        ("gtol", options.gtol),
    ] {
        if !(value.is_finite() && value >= 0.0) {
            return Err(Error::InvalidOption {
                name,
                value,
                reason: "must be finite and >= 0",
            });
        }
    }
    if !(options.lambda0.is_finite() && options.lambda0 > 0.0) {
        return Err(Error::InvalidOption {
            name: "lambda0",
            value: options.lambda0,
            reason: "must be finite and > 0",
        });
    }
    if let Some(s) = options.fd_step {
        if !(s.is_finite() && s > 0.0 && s < 1.0) {
            return Err(Error::InvalidOption {
                name: "fd_step",
                value: s,
                reason: "must lie in (0, 1)",
            });
        }
    }
    if let Some(scales) = &options.scales {
        if scales.len() != np {
            return Err(Error::WrongLength {
                what: "scales",
                found: scales.len(),
                expected: np,
            });
        }
        if let Some(&bad) = scales.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
            return Err(Error::InvalidOption {
                name: "scales",
                value: bad,
                reason: "every scale must be finite and > 0",
            });
        }
    }
    let bounds = match &options.bounds {
        Some(b) => {
            if b.len() != np {
                return Err(Error::WrongLength {
                    what: "bounds",
                    found: b.len(),
                    expected: np,
                });
            }
            for (index, &(lower, upper)) in b.iter().enumerate() {
                if lower.is_nan() || upper.is_nan() || lower > upper {
                    return Err(Error::InvalidBounds {
                        index,
                        lower,
                        upper,
                    });
                }
            }
            b.clone()
        }
        None => vec![(f64::NEG_INFINITY, f64::INFINITY); np],
    };
    for (index, (&value, &(lower, upper))) in p0.iter().zip(&bounds).enumerate() {
        if !value.is_finite() || value < lower || value > upper {
            return Err(Error::InvalidStart {
                index,
                value,
                lower,
                upper,
            });
        }
    }
    Ok(bounds)
}

/// Fills column `j` of the Jacobian by a finite difference at `x` (residuals `r`), with
/// `xp` a copy of `x` used for the trial points. A side that leaves the bounds or fails falls
/// back to a one-sided difference on the other side.
#[allow(clippy::too_many_arguments)] // reason: the difference scheme's inputs
fn fd_column(
    eval: &mut dyn FnMut(&[f64], &mut [f64]) -> bool,
    xp: &mut [f64],
    x: &[f64],
    r: &[f64],
    j: usize,
    col: &mut [f64],
    scheme: FdScheme,
    step: f64,
    typical: f64,
    (lo, hi): (f64, f64),
    rp: &mut [f64],
    rm: &mut [f64],
) -> Result<()> {
    let h = step * x[j].abs().max(typical);
    let up = x[j] + h;
    let down = x[j] - h;
    let mut eval_at = |v: f64, out: &mut [f64]| -> Option<f64> {
        xp[j] = v;
        let ok = eval(xp, out);
        xp[j] = x[j];
        // The realised step, exact in floating point.
        ok.then_some(v - x[j])
    };
    let plus = if up <= hi { eval_at(up, rp) } else { None };
    let minus = match (scheme, plus) {
        (FdScheme::Forward, Some(_)) => None,
        _ if down >= lo => eval_at(down, rm),
        _ => None,
    };
    let (rp, rm) = (&*rp, &*rm);
    if !difference(col, r, plus.map(|h| (h, rp)), minus.map(|h| (h, rm))) {
        return Err(Error::JacobianFailed {
            index: j,
            value: x[j],
        });
    }
    Ok(())
}

/// A Jacobian column from the residuals `r` at the point and those at the realised steps
/// `plus` and `minus` (each `(step, residuals)` where it succeeded): central where both sides
/// are there, one-sided otherwise. False when neither is.
fn difference(
    col: &mut [f64],
    r: &[f64],
    plus: Option<(f64, &[f64])>,
    minus: Option<(f64, &[f64])>,
) -> bool {
    match (plus, minus) {
        (Some((hp, rp)), Some((hm, rm))) => {
            for (i, c) in col.iter_mut().enumerate() {
                *c = (rp[i] - rm[i]) / (hp - hm);
            }
        }
        (Some((hp, rp)), None) => {
            for (i, c) in col.iter_mut().enumerate() {
                *c = (rp[i] - r[i]) / hp;
            }
        }
        (None, Some((hm, rm))) => {
            for (i, c) in col.iter_mut().enumerate() {
                *c = (rm[i] - r[i]) / hm;
            }
        }
        (None, None) => return false,
    }
    true
}

/// `s^2 (J^T J)^{-1}` through the SVD of `J`, or `None` if `m <= p` or `J` is rank deficient.
/// `s^2 (J^T J)^{-1}` on the directions the data determine. The columns are scaled to unit
/// norm first (parameters of very different sizes, a stiffness of 1e5 beside a position of
/// 1e-3, must not make a well-determined column look singular). A parameter that the data do
/// not determine (a zero column, such as an initial state whose effect has died out before the
/// scored samples, or a direction of a vanishing singular value that involves it) gets `NaN`
/// in its row and column; the others keep their variances. `None` when `m <= p` or no
/// parameter is determined.
fn covariance(jac: &DMatrix<f64>, cost: f64, m: usize) -> Option<Vec<Vec<f64>>> {
    let np = jac.ncols();
    if m <= np {
        return None;
    }
    let s2 = cost / (m - np) as f64;
    let norms: Vec<f64> = (0..np).map(|j| jac.column(j).norm()).collect();
    if norms.iter().any(|n| !n.is_finite()) {
        return None;
    }
    let scaled = DMatrix::from_fn(jac.nrows(), np, |i, j| {
        if norms[j] > 0.0 {
            jac[(i, j)] / norms[j]
        } else {
            0.0
        }
    });
    let svd = scaled.svd(false, true);
    let v_t = svd.v_t?;
    let sv = &svd.singular_values;
    let smax = sv.max();
    if smax.is_nan() || smax <= 0.0 {
        return None;
    }
    let tol = smax * f64::EPSILON * m.max(np) as f64;
    let kept: Vec<bool> = sv.iter().map(|&s| s > tol).collect();
    // A parameter is undetermined when its column vanishes or a dropped direction involves it
    // (a component above 1e-6: below it, the direction's variance would reach the parameter
    // only at the level of the rounding that dropped it).
    let undetermined: Vec<bool> = (0..np)
        .map(|i| norms[i] <= 0.0 || (0..sv.len()).any(|k| !kept[k] && v_t[(k, i)].abs() > 1e-6))
        .collect();
    if undetermined.iter().all(|&u| u) {
        return None;
    }
    let mut cov = vec![vec![f64::NAN; np]; np];
    for i in (0..np).filter(|&i| !undetermined[i]) {
        for j in (0..np).filter(|&j| !undetermined[j]) {
            cov[i][j] = s2
                * (0..sv.len())
                    .filter(|&k| kept[k])
                    .map(|k| v_t[(k, i)] * v_t[(k, j)] / (sv[k] * sv[k]))
                    .sum::<f64>()
                / (norms[i] * norms[j]);
        }
    }
    Some(cov)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On an exact quadratic the extension lands on its minimum: `c(t) = 1 - 0.8 t + 0.1 t^2`
    /// has `c(0) = 1`, `c'(0) = -0.8` (slope `-0.4`), `c(1) = 0.3` and its minimum at `t = 4`.
    #[test]
    fn the_extension_is_the_minimum_of_the_quadratic_along_the_step() {
        let t = extension(1.0, 0.3, -0.4).unwrap();
        assert!((t - 4.0).abs() < 1e-12, "{t}");
        // Minimum at t = 1.25 (c = 1 - 0.8 t + 0.32 t^2): not worth an evaluation.
        assert_eq!(extension(1.0, 0.52, -0.4), None);
        // Falling faster than linearly: the cap.
        assert_eq!(extension(1.0, 0.1, -0.4), Some(EXTEND_MAX));
        // Minimum at t = 20 (c = 1 - 0.8 t + 0.02 t^2): the cap.
        assert_eq!(extension(1.0, 0.22, -0.4), Some(EXTEND_MAX));
        // No descent, or a step that did not lower the cost: nothing to extend.
        assert_eq!(extension(1.0, 0.3, 0.4), None);
        assert_eq!(extension(1.0, 1.0, -0.4), None);
    }
}
