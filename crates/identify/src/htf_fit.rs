//! Fitting named parameters to HTF estimates through the exact HTF of the model.

use htfid_estimate::{
    contiguous_clusters, levenberg_marquardt, levenberg_marquardt_with_jacobian,
    uncertainty_budget, BiasSource, FdScheme, FitBias, FitBudgetInput, HtfEstimate, LmOptions,
    UncertaintyBudget,
};
use htfid_hybrid::Options;
use htfid_orbit::{find_limit_cycle, LimitCycle, ShootingOptions};
use htfid_theory::{HarmonicTransferFunction, HtfChannel, LinearisedHtf};
use num_complex::Complex64;

use crate::Parametric;
use serde::Serialize;

/// Errors of identification.
#[non_exhaustive]
#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    /// A parameter name the model does not have.
    #[error("the model has no parameter {name}")]
    UnknownParameter {
        /// The name.
        name: String,
    },
    /// Fewer estimates than parameters in the band.
    #[error("only {points} estimates in the band for the fitted harmonics; {parameters} parameters need at least as many")]
    TooFewPoints {
        /// Estimates kept.
        points: usize,
        /// Parameters fitted.
        parameters: usize,
    },
    /// The model has no forcing period, so it has no limit cycle to linearise about.
    #[error("the model has no forcing period; a fit needs its limit cycle")]
    NoPeriod,
    /// The optimiser failed.
    #[error(transparent)]
    Fit(#[from] htfid_estimate::Error),
}

/// What to fit.
#[derive(Debug, Clone)]
pub struct HtfFitSpec {
    /// Parameters fitted (names of the model's parameters).
    pub parameters: Vec<String>,
    /// Harmonics `n` of `G_n` that enter the fit.
    pub harmonics: Vec<i32>,
    /// Output-frequency band (rad/s), edges included.
    pub band: (f64, f64),
    /// At most this many estimates per output and harmonic when the HTF is closed-form,
    /// evenly spread (neighbouring bins of a regularised estimate carry little independent
    /// information).
    pub points_exact: usize,
    /// The same when the HTF is the periodic response (each point costs two integrations).
    pub points_periodic: usize,
}

impl HtfFitSpec {
    /// A spec with the default point budgets (200 per harmonic closed-form, 40 periodic).
    pub fn new(parameters: Vec<String>, harmonics: Vec<i32>, band: (f64, f64)) -> Self {
        HtfFitSpec {
            parameters,
            harmonics,
            band,
            points_exact: 200,
            points_periodic: 40,
        }
    }
}

/// A fit.
#[derive(Debug, Clone, Serialize)]
pub struct HtfFit {
    /// The parameters, in the order of the spec.
    pub parameters: Vec<String>,
    /// Their fitted values.
    pub values: Vec<f64>,
    /// Their standard errors from the weighted residuals (noise only); NaN when unavailable.
    pub stderr: Vec<f64>,
    /// Estimates used.
    pub points: usize,
    /// Levenberg-Marquardt iterations.
    pub iterations: usize,
    /// Final cost (half the sum of squared weighted residuals).
    pub cost: f64,
    /// Why it stopped.
    pub stop: String,
    /// How its Jacobian was formed: `"exact"` (the model's tangents through the derivatives
    /// of its HTFs: [`Parametric::linearisation_tangents`] and
    /// [`htfid_theory::ExactHtf::derivatives`], or [`Parametric::orbit_derivatives`]) or
    /// `"forward_difference"` (step [`FD_STEP`]).
    pub jacobian_method: &'static str,
    /// The error budget at 95 % ([`htfid_estimate::uncertainty_budget`]): noise, the
    /// estimates' own known bias ([`HtfEstimate::bias`], the regularised estimators' smoothing
    /// bias) and model-structure error, from clusters of [`CLUSTER_POINTS`] neighbouring
    /// frequencies of each output and harmonic; `None` when the Jacobian is rank deficient.
    pub uncertainty: Option<UncertaintyBudget>,
    /// The estimates fitted, in residual order (two residuals, real and imaginary, each).
    #[serde(skip)]
    pub fitted: Vec<FitPoint>,
    /// The weighted residuals at the fitted values.
    #[serde(skip)]
    pub residuals: Vec<f64>,
    /// Their Jacobian with respect to the parameters, row by row.
    #[serde(skip)]
    pub jacobian: Vec<Vec<f64>>,
}

/// One estimate in a fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitPoint {
    /// Output index.
    pub output: usize,
    /// Harmonic.
    pub n: i32,
    /// Output frequency, rad/s.
    pub omega: f64,
    /// Weight of its residual: one over its standard error (floored).
    pub weight: f64,
}

/// A fit ends when an accepted step lowers the weighted cost by less than this many times its
/// value per degree of freedom, `s^2 = cost / (m - p)`: a hundredth of a unit of the
/// F-statistic's numerator, where a parameter moved by one standard error changes the cost by
/// one `s^2`: the fitted values end about a tenth of a standard error from the minimum.
pub const FIT_TOLERANCE: f64 = 0.01;

/// Relative step of the forward differences that form the fit's Jacobian when the model gives
/// no tangents ([`Parametric::linearisation_tangents`], [`Parametric::orbit_derivatives`]),
/// `FD_STEP *
/// max(|p|, 1e-3)` per parameter. Each residual carries the orbit's and the HTF's own error, of
/// the order of the integrator's tolerance (about `1e-10` relative at the default `rtol`), which
/// a step `h` turns into an error `1e-10 / h` of the Jacobian, while the truncation error
/// grows like `h`. At `1e-5` the Jacobian of the paper's hopper is within 1.2e-4 (`k`) and
/// 8e-6 (`c`) of an extrapolated central difference (`tests/parametric.rs`), which moves the
/// standard errors by as little, for half the evaluations of central differences.
pub const FD_STEP: f64 = 1e-5;

/// Estimates per cluster of the structure term of [`HtfFit::uncertainty`].
pub const CLUSTER_POINTS: usize = 10;

/// Fits `spec.parameters` of `model` to `estimates` (`(output index, estimate)` pairs),
/// starting from the model's current values and its limit cycle `cycle`. Weights are
/// `1 / stderr`, floored at `1e-6` of the harmonic's largest estimate so that noise-free
/// estimates do not get infinite weight; parameter bounds come from the model. The Jacobian is
/// exact where the model gives its tangents: of its closed-form linearisation
/// ([`Parametric::linearisation_tangents`], the derivatives then from
/// [`htfid_theory::ExactHtf::derivatives`]) or along its orbit
/// ([`Parametric::orbit_derivatives`], through [`htfid_theory::OrbitHtf::derivatives`]),
/// whichever its HTF takes; otherwise a forward difference of step [`FD_STEP`]
/// ([`HtfFit::jacobian_method`] says which). The fit ends at a step worth less than
/// [`FIT_TOLERANCE`].
///
/// # Errors
/// [`IdentifyError`].
pub fn fit_to_htf<S: Parametric>(
    model: &S,
    cycle: &LimitCycle<S::Mode>,
    estimates: &[(usize, &HtfEstimate)],
    spec: &HtfFitSpec,
    opts: &Options,
) -> Result<HtfFit, IdentifyError> {
    let info: Vec<(f64, (f64, f64))> = spec
        .parameters
        .iter()
        .map(|n| {
            model
                .parameter(n)
                .ok_or_else(|| IdentifyError::UnknownParameter { name: n.clone() })
        })
        .collect::<Result<_, _>>()?;
    // The same test LinearisedHtf applies to pick its method.
    let per_harmonic = if model.is_piecewise_constant() {
        spec.points_exact
    } else {
        spec.points_periodic
    }
    .max(1);
    let (lo, hi) = spec.band;
    // (output, n, omega, value, weight)
    let mut rows: Vec<(usize, i32, f64, Complex64, f64)> = Vec::new();
    for &(o, e) in estimates {
        for &n in &spec.harmonics {
            let of_n: Vec<_> = e
                .rows()
                .filter(|r| r.n == n && r.omega >= lo && r.omega <= hi)
                .filter(|r| r.value.re.is_finite() && r.value.im.is_finite())
                .collect();
            let largest = of_n.iter().map(|r| r.value.norm()).fold(0.0, f64::max);
            let floor = 1e-6 * largest;
            let stride = of_n.len().div_ceil(per_harmonic).max(1);
            for r in of_n.into_iter().step_by(stride) {
                let s = if r.stderr.is_finite() {
                    r.stderr.max(floor)
                } else {
                    floor
                };
                rows.push((o, n, r.omega, r.value, 1.0 / s));
            }
        }
    }
    if rows.len() < info.len() {
        return Err(IdentifyError::TooFewPoints {
            points: rows.len(),
            parameters: info.len(),
        });
    }
    let p0: Vec<f64> = info.iter().map(|&(v, _)| v).collect();
    let period = model.forcing_period().ok_or(IdentifyError::NoPeriod)?;
    let shooting = ShootingOptions {
        settle_periods: 0,
        ..ShootingOptions::default()
    };
    let names: Vec<&str> = spec.parameters.iter().map(String::as_str).collect();
    // Per output: the rows it owns and their `(n, w)`, evaluated together in every residual.
    let outputs = rows.iter().map(|row| row.0 + 1).max().unwrap_or(0);
    type Points = (Vec<usize>, Vec<(i32, f64)>);
    let per_output: Vec<Points> = (0..outputs)
        .map(|o| {
            rows.iter()
                .enumerate()
                .filter(|(_, row)| row.0 == o)
                .map(|(i, &(_, n, w, _, _))| (i, (n, w)))
                .unzip()
        })
        .collect();
    // The trial model and its limit cycle at `p`.
    let trial_at = |p: &[f64]| -> Result<(S, LimitCycle<S::Mode>), String> {
        let changes: Vec<(&str, f64)> = names.iter().copied().zip(p.iter().copied()).collect();
        let trial = model.unforced_with(&changes)?;
        let cyc = find_limit_cycle(
            &trial,
            cycle.mode0,
            0.0,
            &cycle.state0,
            period,
            &shooting,
            opts,
        )
        .map_err(|e| e.to_string())?;
        Ok((trial, cyc))
    };
    let residuals = |p: &[f64], r: &mut [f64]| -> Result<(), String> {
        let (trial, cyc) = trial_at(p)?;
        let htf = LinearisedHtf::new(&trial, &cyc, opts).map_err(|e| e.to_string())?;
        let channels = (0..htf.n_outputs())
            .map(|o| htf.channel(o))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| e.to_string())?;
        for (channel, (at, points)) in channels.iter().zip(&per_output) {
            for (&i, g) in at.iter().zip(channel.values(points)) {
                let (_, _, _, value, weight) = rows[i];
                let d = (value - g) * weight;
                r[2 * i] = d.re;
                r[2 * i + 1] = d.im;
            }
        }
        Ok(())
    };
    let m = 2 * rows.len();
    // The exact Jacobian: the derivatives of every fitted value along the model's tangents,
    // of its closed-form linearisation or of its orbit.
    let jacobian = |p: &[f64], _r: &[f64], jac: &mut [f64]| -> Result<(), String> {
        let (trial, cyc) = trial_at(p)?;
        let htf = LinearisedHtf::new(&trial, &cyc, opts).map_err(|e| e.to_string())?;
        let derivatives: Vec<Vec<Vec<Complex64>>> = match htf.linearisation() {
            Some(lin) => {
                let tangents = trial
                    .linearisation_tangents(&names, &cyc, lin, opts)
                    .ok_or("the model no longer gives its linearisation's tangents")??;
                per_output
                    .iter()
                    .enumerate()
                    .map(|(o, (_, points))| {
                        let HtfChannel::Exact(exact) = htf.channel(o).map_err(|e| e.to_string())?
                        else {
                            return Err("the model's HTF is no longer the closed form".to_string());
                        };
                        let channel: Vec<_> = tangents.iter().map(|t| t.channel(o, 0)).collect();
                        exact
                            .derivatives(&channel, points)
                            .map_err(|e| e.to_string())
                    })
                    .collect::<Result<_, _>>()?
            }
            None => {
                let orbit = htf.orbit().ok_or("the model's HTF has no method")?;
                let points: Vec<Vec<(i32, f64)>> = per_output
                    .iter()
                    .map(|(_, points)| points.clone())
                    .collect();
                trial
                    .orbit_derivatives(&names, &cyc, orbit, &points, opts)
                    .ok_or("the model no longer gives its orbit's tangents")??
            }
        };
        for ((at, _), of_output) in per_output.iter().zip(&derivatives) {
            for (j, column) in of_output.iter().enumerate() {
                for (&i, g) in at.iter().zip(column) {
                    let weight = rows[i].4;
                    jac[j * m + 2 * i] = -g.re * weight;
                    jac[j * m + 2 * i + 1] = -g.im * weight;
                }
            }
        }
        Ok(())
    };
    let lm = LmOptions {
        ftol: FIT_TOLERANCE / (m - info.len()).max(1) as f64,
        fd_scheme: FdScheme::Forward,
        fd_step: Some(FD_STEP),
        scales: Some(p0.iter().map(|v| v.abs().max(1e-3)).collect()),
        bounds: Some(info.iter().map(|&(_, b)| b).collect()),
        ..LmOptions::default()
    };
    let exact = exact_tangents_available(model, cycle, &names, opts);
    let fit = if exact {
        levenberg_marquardt_with_jacobian(residuals, jacobian, &p0, m, &lm)?
    } else {
        levenberg_marquardt(residuals, &p0, m, &lm)?
    };
    let uncertainty = budget(estimates, &rows, &fit.jacobian, &fit.residuals);
    Ok(HtfFit {
        parameters: spec.parameters.clone(),
        stderr: fit
            .stderr
            .clone()
            .unwrap_or_else(|| vec![f64::NAN; info.len()]),
        values: fit.params,
        points: rows.len(),
        iterations: fit.iterations,
        cost: fit.cost,
        stop: format!("{:?}", fit.stop),
        jacobian_method: if exact { "exact" } else { "forward_difference" },
        uncertainty,
        fitted: rows
            .iter()
            .map(|&(output, n, omega, _, weight)| FitPoint {
                output,
                n,
                omega,
                weight,
            })
            .collect(),
        residuals: fit.residuals,
        jacobian: fit.jacobian,
    })
}

/// Whether `model` gives the exact tangents of its linearisation about `cycle` (closed form
/// or along the orbit, whichever its HTF takes) for every one of `names` (checked on the
/// model as given: the trials are the same model with other values).
fn exact_tangents_available<S: Parametric>(
    model: &S,
    cycle: &LimitCycle<S::Mode>,
    names: &[&str],
    opts: &Options,
) -> bool {
    let Ok(unforced) = model.unforced_with(&[]) else {
        return false;
    };
    let Ok(htf) = LinearisedHtf::new(&unforced, cycle, opts) else {
        return false;
    };
    match (htf.linearisation(), htf.orbit()) {
        (Some(lin), _) => matches!(
            unforced.linearisation_tangents(names, cycle, lin, opts),
            Some(Ok(_))
        ),
        (None, Some(orbit)) => matches!(
            unforced.orbit_derivatives(names, cycle, orbit, &[], opts),
            Some(Ok(_))
        ),
        (None, None) => false,
    }
}

/// The fit's error budget; the known bias is that of the estimates (all must share one source
/// for it to be used).
fn budget(
    estimates: &[(usize, &HtfEstimate)],
    rows: &[(usize, i32, f64, Complex64, f64)],
    jacobian: &[Vec<f64>],
    residuals: &[f64],
) -> Option<UncertaintyBudget> {
    let sources: Vec<_> = estimates
        .iter()
        .filter_map(|(_, e)| e.bias().map(|(s, _)| s))
        .collect();
    let source = sources
        .first()
        .copied()
        .filter(|s| sources.len() == estimates.len() && sources.iter().all(|t| t == s));
    let bias: Option<Vec<Complex64>> = source.map(|_| {
        rows.iter()
            .map(|&(o, n, w, _, _)| {
                estimates
                    .iter()
                    .find(|(out, _)| *out == o)
                    .and_then(|(_, e)| e.bias_at(n, w))
                    .unwrap_or_default()
            })
            .collect()
    });
    let points: Vec<(usize, i32, f64)> = rows.iter().map(|&(o, n, _, _, w)| (o, n, w)).collect();
    assemble(
        &points,
        jacobian,
        residuals,
        source.zip(bias.as_deref()).map(|(s, b)| (s, b, None)),
    )
    .ok()
}

/// The error budget of `fit` with a bias of the estimates found elsewhere: `htf_bias` is the
/// estimate's error at every fitted point (in [`HtfFit::fitted`] order) that the noise does not
/// explain (for example what a `+u` / `-u` pairing leaves, from a noise-free re-run of the
/// experiment), `parameter_bias` the error it makes in the fitted values, when known.
///
/// # Errors
/// A rank-deficient Jacobian, or a bias of the wrong length.
pub fn budget_with_bias(
    fit: &HtfFit,
    source: BiasSource,
    htf_bias: &[Complex64],
    parameter_bias: Option<&[f64]>,
) -> Result<UncertaintyBudget, IdentifyError> {
    let points: Vec<(usize, i32, f64)> = fit
        .fitted
        .iter()
        .map(|p| (p.output, p.n, p.weight))
        .collect();
    Ok(assemble(
        &points,
        &fit.jacobian,
        &fit.residuals,
        Some((source, htf_bias, parameter_bias)),
    )?)
}

/// A known bias: its source, its value per fitted point (unweighted) and, when known, the error
/// it makes in the fitted values.
type KnownBias<'a> = (BiasSource, &'a [Complex64], Option<&'a [f64]>);

/// The budget from weighted residuals: `points` are `(output, n, weight)` in residual order,
/// `bias` the known bias per point (unweighted) with its parameter error.
fn assemble(
    points: &[(usize, i32, f64)],
    jacobian: &[Vec<f64>],
    residuals: &[f64],
    bias: Option<KnownBias<'_>>,
) -> Result<UncertaintyBudget, htfid_estimate::Error> {
    let weighted: Option<Vec<f64>> = bias.map(|(_, b, _)| {
        b.iter()
            .zip(points)
            .flat_map(|(d, &(_, _, w))| [d.re * w, d.im * w])
            .collect()
    });
    let groups: Vec<i64> = points
        .iter()
        .map(|&(o, n, _)| (o as i64) * 100_000 + i64::from(n))
        .collect();
    let clusters: Vec<usize> = contiguous_clusters(&groups, CLUSTER_POINTS)
        .into_iter()
        .flat_map(|c| [c, c])
        .collect();
    uncertainty_budget(&FitBudgetInput {
        jacobian,
        residuals,
        // Weights are one over the complex standard error; real and imaginary parts each
        // carry half its variance.
        noise_variance: 0.5,
        clusters: &clusters,
        bias: bias
            .zip(weighted.as_deref())
            .map(|((source, _, parameter_bias), b)| FitBias {
                source,
                residual_bias: b,
                parameter_bias,
            }),
        level: 0.95,
    })
}
