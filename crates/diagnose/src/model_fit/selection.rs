//! The forward selection of a diagnosis and its tests: every candidate fitted
//! beside the refit (the first round), further effects fitted jointly beside the chosen ones
//! (the rounds after it), and the backward pass that drops a chosen effect no longer needed.

use std::collections::BTreeMap;

use htfid_lang::{Model, Site};
use rayon::prelude::*;

use super::joint::{Joint, JointFit, SetFit, Trial, Tried};
use super::prepared::{Prepared, StateSamples};
use super::{ModelCandidate, ModelFitOptions, ModelScore, ParameterChange, ParametersBeside};
use crate::boundary::{Boundary, BoundaryEffect};
use crate::term::{TermEffect, TermStart};
use crate::DiagnoseError;

/// The likelihood ratio of a fit (sum of squares `big_rss`, residuals `big_residuals`) against
/// a nested fit of sum of squares `small_rss` on `n` residuals, divided by the variance
/// inflation `kappa` of the bigger fit's correlated residuals; and `kappa`.
pub(super) fn nested_ratio(
    small_rss: f64,
    big_rss: f64,
    big_residuals: &[f64],
    n: usize,
) -> (f64, f64) {
    let kappa = correlation_inflation(big_residuals).powi(2);
    (
        crate::stats::likelihood_ratio(small_rss, big_rss, n, kappa),
        kappa,
    )
}

/// The fits that may explain the data as well as `tried[best]` (the best held-out score):
/// it and every significant fit within `rival_margin` of its held-out NRMSE. Of those, the one
/// with the lowest BIC on the fit data (`n` residuals; every fitted parameter counted) and
/// those within `bic_margin` of it, best BIC first: the winner and its rivals.
pub(super) fn rivals_by_bic(
    tried: &[Tried],
    best: usize,
    n: usize,
    opts: &ModelFitOptions,
) -> (usize, Vec<usize>) {
    let limit = tried[best].candidate.nrmse_validation * (1.0 + opts.rival_margin);
    let bic = |i: usize| {
        let t = &tried[i];
        let b = crate::stats::bic(t.rss, n, t.candidate.parameters.len());
        if b.is_finite() {
            b
        } else {
            f64::INFINITY
        }
    };
    let mut order: Vec<usize> = (0..tried.len())
        .filter(|&i| {
            i == best
                || (tried[i].candidate.significant && tried[i].candidate.nrmse_validation <= limit)
        })
        .collect();
    // Stable: equal BICs keep the held-out order.
    order.sort_by(|&a, &b| bic(a).total_cmp(&bic(b)));
    let w = order[0];
    let rivals = order[1..]
        .iter()
        .copied()
        .filter(|&i| bic(i) - bic(w) < opts.bic_margin)
        .collect();
    (w, rivals)
}

/// Why `trial`, an effect on the model's boundary with parameters `own`, is no finding, if the
/// fit left one of them without a standard error: a direction of the fit's Jacobian the record
/// does not resolve involves it, so the record cannot tell it from the model's parameters
/// fitted with it (a sensor's gain beside a free mass, stiffness and damping rescales them all
/// alike; an input offset beside the model's own free offset is the same force). A term in the
/// equations is judged as a whole: a weakly determined parameter of it (a contact's
/// stiffness) does not veto a term the data demand.
fn undetermined_note(
    trial: &Trial,
    own: &[String],
    stderr: &BTreeMap<String, f64>,
) -> Option<String> {
    if !matches!(trial, Trial::Boundary(..)) {
        return None;
    }
    let lost: Vec<String> = own
        .iter()
        .filter(|n| stderr.get(n.as_str()).is_some_and(|e| !e.is_finite()))
        .map(|n| format!("`{n}`"))
        .collect();
    (!lost.is_empty()).then(|| {
        format!(
            "the record cannot tell {} from the parameters fitted with it (no standard error)",
            lost.join(", ")
        )
    })
}

/// Inflation of least-squares standard errors for residuals correlated in time:
/// `sqrt(1 + 2 sum_k (1 - k/L) rho_k)` with Bartlett weights up to lag `L = 4 n^(1/3)`.
pub(super) fn correlation_inflation(r: &[f64]) -> f64 {
    let n = r.len();
    if n < 8 {
        return 1.0;
    }
    let mean = r.iter().sum::<f64>() / n as f64;
    let var = r.iter().map(|v| (v - mean).powi(2)).sum::<f64>();
    if var <= 0.0 {
        return 1.0;
    }
    let lags = ((4.0 * (n as f64).cbrt()) as usize).min(n - 1);
    let mut s = 1.0;
    for k in 1..=lags {
        let c: f64 = (k..n)
            .map(|i| (r[i] - mean) * (r[i - k] - mean))
            .sum::<f64>()
            / var;
        s += 2.0 * (1.0 - k as f64 / (lags + 1) as f64) * c;
    }
    s.max(1.0).sqrt()
}

/// A model that does not take an effect's terms or values, as the fits' error.
fn model_error(e: htfid_lang::ModelError) -> DiagnoseError {
    DiagnoseError::NominalFit {
        reason: e.to_string(),
    }
}

/// The scale of a meaningful change of each of the model's parameters `names`, as the free
/// parameters': the configured magnitude, at least 1e-3.
pub(super) fn parameter_scales<'n, S: AsRef<str>>(
    model: &'n Model,
    names: &'n [S],
) -> impl Iterator<Item = f64> + 'n {
    names.iter().map(|n| {
        model
            .parameter_index(n.as_ref())
            .map_or(1.0, |i| model.values()[i].abs().max(1e-3))
    })
}

/// Relative size of the part of a term's derivative not proportional to a parameter's below
/// which the term only re-expresses that parameter's change: rounding of the exact derivatives
/// (sums of a few products) stays near 1e-15; a term that differs anywhere on the motion, even
/// on one sample in a thousand, stands far above 1e-9.
const ALIAS_TOLERANCE: f64 = 1e-9;

/// For every trial, the parameter of `suspects` (the candidate `parameter_error`'s) whose
/// change it only re-expresses, if one: a term of one parameter `q` added to `model` whose
/// exact derivatives by `q` (of every flow in the mode of each sample, every guard, every
/// reset and every output, at the model's states `samples` along the record) are those by
/// the model's parameter `p` times one constant. Damping added in the one mode where the
/// model's damper acts is such a term: a change of its damping constant. It is not an effect
/// of the model's own, so the candidate `parameter_error` stands for it. Effects on the
/// boundary and terms of several parameters are never aliases.
pub(super) fn aliases(
    trials: &[Trial],
    model: &Model,
    samples: &StateSamples,
    suspects: &[String],
) -> Vec<Option<String>> {
    if suspects.is_empty() {
        return vec![None; trials.len()];
    }
    trials
        .iter()
        .map(|trial| {
            let Trial::Term(term) = trial else {
                return None;
            };
            let q = match term.parameter_names().as_slice() {
                [q] => q.clone(),
                _ => return None,
            };
            let extended = model.with_extension(&term.extension).ok()?;
            suspects
                .iter()
                .find(|p| re_expresses(&extended, &q, p, samples))
                .cloned()
        })
        .collect()
}

/// Whether the derivatives of `model` by `q` are those by `p` times one constant at every
/// sample (see [`aliases`]).
fn re_expresses(model: &Model, q: &str, p: &str, samples: &StateSamples) -> bool {
    let Ok(sens) = model.parameter_sensitivity(&[q, p]) else {
        return false;
    };
    let n = model.states().len();
    let (guards, outputs) = (model.guard_names().len(), model.outputs().len());
    let mut buf = vec![0.0; 2 * n.max(outputs).max(1)];
    // Every derivative by q beside the same by p.
    let (mut by_q, mut by_p) = (Vec::new(), Vec::new());
    let mut take = |buf: &[f64], rows: usize| {
        for r in 0..rows {
            by_q.push(buf[2 * r]);
            by_p.push(buf[2 * r + 1]);
        }
    };
    for (i, x) in samples.x.iter().enumerate() {
        let (t, u) = (samples.t[i], samples.u[i]);
        sens.flow(samples.modes[i], t, x, u, &mut buf);
        take(&buf, n);
        for g in 0..guards {
            sens.guard(g, t, x, u, &mut buf);
            take(&buf, 1);
            sens.reset(g, t, x, u, &mut buf);
            take(&buf, n);
        }
        sens.output(t, x, u, &mut buf);
        take(&buf, outputs);
    }
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let (qq, pp, qp) = (dot(&by_q, &by_q), dot(&by_p, &by_p), dot(&by_q, &by_p));
    if !(qq > 0.0 && pp > 0.0 && qq.is_finite() && pp.is_finite()) {
        return false;
    }
    let kappa = qp / pp;
    let rest: f64 = by_q
        .iter()
        .zip(&by_p)
        .map(|(a, b)| (a - kappa * b).powi(2))
        .sum();
    rest <= ALIAS_TOLERANCE * ALIAS_TOLERANCE * qq
}

/// Where the selection runs: the records, the refitted nominal model and its fit, and the
/// candidates.
pub(super) struct Selection<'a, 'r> {
    pub(super) opts: &'a ModelFitOptions,
    /// The estimation record, and the validation record when one is given.
    pub(super) est: &'a Prepared<'r>,
    pub(super) val: Option<&'a Prepared<'r>>,
    /// End of the fitted samples of the estimation record (its held-out part runs from there
    /// to its end when there is no validation record).
    pub(super) cut: usize,
    /// The refit of the free parameters (`joint` fits them), its model and its score.
    pub(super) joint: &'a Joint<'a, 'r>,
    pub(super) refitted_model: &'a Model,
    pub(super) base: &'a JointFit,
    pub(super) refitted: &'a ModelScore,
    /// The model's output names.
    pub(super) outputs: &'a [String],
    /// Every candidate effect.
    pub(super) trials: &'a [Trial],
    /// The refitted model's states along the record, where the terms' parameters are scaled.
    pub(super) samples: &'a StateSamples,
    /// Per trial: the parameter of `parameter_error` whose change it only re-expresses, if
    /// one ([`aliases`]).
    pub(super) aliases: &'a [Option<String>],
}

impl Selection<'_, '_> {
    /// Residuals of a fit on the estimation record.
    fn n(&self) -> usize {
        self.est.residual_len()
    }

    /// Score of a model with fitted state `x_est` on the estimation record, and the
    /// simulation shown (the held-out one when there is a validation record).
    pub(super) fn score(
        &self,
        m: &Model,
        x_est: &[f64],
        b: &Boundary,
    ) -> Result<(ModelScore, Vec<Vec<f64>>), DiagnoseError> {
        score_on(self.est, self.val, self.cut, m, x_est, b)
    }

    /// The first round: every candidate fitted jointly with the free parameters from the
    /// refit and tested against it (a likelihood ratio corrected for the residuals'
    /// correlation, and a held-out gain), best held-out score first.
    pub(super) fn first_round(&self) -> Vec<Tried> {
        let (est, opts, joint, base) = (self.est, self.opts, self.joint, self.base);
        let names = joint.names;
        let k = joint.index.len();
        let outputs = self.outputs;
        let ideal = Boundary::default();
        let n = self.n();
        // The candidates' fits are independent: in parallel.
        let fits: Vec<_> = self
            .trials
            .par_iter()
            .map(|trial| match trial {
                Trial::Boundary(effect, _) => {
                    let effect = *effect;
                    let start = joint.effect_start(effect, base, outputs);
                    // From the refit: its parameters and its state.
                    let joint_b = Joint {
                        est,
                        model: self.refitted_model,
                        names,
                        index: joint.index,
                        scales: joint.scales.clone(),
                        max_iter: opts.candidate_max_iterations,
                        ftol: joint.ftol,
                    };
                    joint_b.fit(&[effect], &start, &base.state).and_then(|f| {
                        let m = joint_b.model_at(&f.params[..k])?;
                        let b = Boundary::with(effect, &f.params[k..], outputs.len());
                        let (score, sim) = self.score(&m, &f.state, &b)?;
                        Ok((f, score, sim))
                    })
                }
                Trial::Parameters(added) => {
                    // The model's own parameters beside the free ones, from their configured
                    // values and the refit's state.
                    let model = self.refitted_model;
                    let all: Vec<&str> = names
                        .iter()
                        .copied()
                        .chain(added.iter().map(String::as_str))
                        .collect();
                    let index_p: Vec<usize> = all
                        .iter()
                        .filter_map(|n| model.parameter_index(n))
                        .collect();
                    let mut scales = joint.scales.clone();
                    scales.extend(parameter_scales(model, added));
                    let joint_p = Joint {
                        est,
                        model,
                        names: &all,
                        index: &index_p,
                        scales,
                        max_iter: opts.candidate_max_iterations,
                        ftol: joint.ftol,
                    };
                    joint_p.fit(&[], &[], &base.state).and_then(|f| {
                        let m = joint_p.model_at(&f.params)?;
                        let (score, sim) = self.score(&m, &f.state, &ideal)?;
                        Ok((f, score, sim))
                    })
                }
                Trial::Term(term) => {
                    let extended = self
                        .refitted_model
                        .with_extension(&term.extension)
                        .map_err(model_error)?;
                    let added = term.parameter_names();
                    let all: Vec<&str> = names
                        .iter()
                        .copied()
                        .chain(added.iter().map(String::as_str))
                        .collect();
                    let index_t: Vec<usize> = all
                        .iter()
                        .filter_map(|n| extended.parameter_index(n))
                        .collect();
                    let mut extended = extended;
                    match &term.start {
                        TermStart::Points(points) => {
                            extended = est.best_point(&extended, &added, points, &base.state);
                        }
                        // From the better of zero and the equation error's estimate, with
                        // the free parameters estimated beside it: refitted without the term,
                        // they have taken up what of it they could, and on a long record of a
                        // lightly damped system the fit from zero stays in that basin.
                        TermStart::Given => {
                            let free: Vec<String> = names.iter().map(|n| n.to_string()).collect();
                            extended = est.better_with_equation_error(
                                &extended,
                                &free,
                                &added,
                                &base.state,
                            );
                        }
                        TermStart::BothSigns => {}
                    }
                    let mut scales = joint.scales.clone();
                    scales.extend(self.samples.term_scales(&extended, &est.signal, term));
                    if term.start == TermStart::BothSigns {
                        extended =
                            est.best_shift(&extended, &added[0], scales[k], &base.state, true);
                    }
                    let joint_t = Joint {
                        est,
                        model: &extended,
                        names: &all,
                        index: &index_t,
                        scales,
                        max_iter: opts.candidate_max_iterations,
                        ftol: joint.ftol,
                    };
                    joint_t.fit(&[], &[], &base.state).and_then(|f| {
                        let m = joint_t.model_at(&f.params)?;
                        let (score, sim) = self.score(&m, &f.state, &ideal)?;
                        Ok((f, score, sim))
                    })
                }
            })
            .collect();
        let mut candidates: Vec<Tried> = Vec::new();
        for (ti, (trial, fitted)) in self.trials.iter().zip(fits).enumerate() {
            let names_e = trial.parameter_names();
            let (f, score, sim) = match fitted {
                Ok(v) => v,
                Err(e) => {
                    candidates.push(Tried {
                        candidate: ModelCandidate::failed(trial, format!("fit failed: {e}")),
                        simulated: None,
                        residuals: Vec::new(),
                        state: Vec::new(),
                        rss: f64::NAN,
                        set: vec![ti],
                    });
                    continue;
                }
            };
            let (lr, kappa) = nested_ratio(base.rss, f.rss, &f.residuals, n);
            let critical = crate::stats::chi2_quantile(names_e.len(), opts.alpha);
            let gain_e = 1.0 - score.validation() / self.refitted.validation();
            // Nothing is left to explain once the refit is within the resolution.
            let mut significant = lr >= critical
                && gain_e >= opts.min_gain
                && self.refitted.validation() > opts.resolution;
            let infl = kappa.sqrt();
            let mut parameters = BTreeMap::new();
            let mut stderr = BTreeMap::new();
            for (j, name) in names.iter().enumerate() {
                parameters.insert((*name).to_string(), f.params[j]);
                stderr.insert((*name).to_string(), f.stderr[j] * infl);
            }
            for (j, name) in names_e.iter().enumerate() {
                parameters.insert(name.clone(), f.params[k + j]);
                stderr.insert(name.clone(), f.stderr[k + j] * infl);
            }
            let mut note = format!(
                "likelihood ratio {lr:.1} (critical {critical:.1}), held-out gain {:.1} % over \
                 the refit (at least {:.1} %)",
                100.0 * gain_e,
                100.0 * opts.min_gain
            );
            if f.stop == format!("{:?}", htfid_estimate::LmStop::MaxIterations) {
                note.push_str(&format!(
                    "; its fit stopped at the limit of {} iterations, not \
                     converged: its score is an upper bound",
                    opts.candidate_max_iterations
                ));
            }
            if let Some(reason) = self
                .outside_the_motion(trial, &parameters)
                .or_else(|| self.alias_note(ti))
                .or_else(|| undetermined_note(trial, &names_e, &stderr))
            {
                significant = false;
                note.push_str(&format!("; not significant: {reason}"));
            }
            candidates.push(Tried {
                candidate: ModelCandidate {
                    effect: trial.name(),
                    term: trial.describe(),
                    parameters,
                    stderr,
                    nrmse_validation: score.validation(),
                    gain: gain_e,
                    bic: crate::stats::bic(f.rss, self.n(), f.params.len()),
                    likelihood_ratio: lr,
                    critical,
                    significant,
                    iterations: f.iterations,
                    note,
                },
                simulated: Some(sim),
                residuals: f.residuals,
                state: f.state,
                rss: f.rss,
                set: vec![ti],
            });
        }
        candidates.sort_by(|a, b| {
            (a.candidate.nrmse_validation).total_cmp(&b.candidate.nrmse_validation)
        });
        candidates
    }

    /// Why trial `i` is no effect of its own, if it only re-expresses a change of a parameter
    /// of the candidate `parameter_error`.
    fn alias_note(&self, i: usize) -> Option<String> {
        self.aliases[i].as_ref().map(|p| {
            format!(
                "it only re-expresses a change of the model's own `{p}` (its derivatives \
                 are those of `{p}` times a constant wherever the motion goes): the candidate \
                 parameter_error stands for it"
            )
        })
    }

    /// Why `trial`, fitted to `parameters`, does not act where the motion is, if it is a term
    /// placed on the motion ([`Placement`](crate::term::Placement)) whose position lies
    /// outside its state's range along the refitted model's motion on the record.
    fn outside_the_motion(
        &self,
        trial: &Trial,
        parameters: &BTreeMap<String, f64>,
    ) -> Option<String> {
        let Trial::Term(TermEffect {
            placed: Some(p), ..
        }) = trial
        else {
            return None;
        };
        let state = self
            .refitted_model
            .states()
            .iter()
            .position(|s| s.name == p.state)?;
        let (lo, hi) = self.samples.range(state);
        let v = *parameters.get(&p.parameter)?;
        (!(v > lo && v < hi)).then(|| {
            format!(
                "{} = {v:.6} lies outside the motion of {} on the record [{lo:.6}, {hi:.6}]: \
                 acting everywhere or nowhere there, it only mimics the model's own terms",
                p.parameter, p.state
            )
        })
    }

    /// The refitted model with the terms of the trials `set` added (at their starting
    /// values), those terms, and the set's effects on the boundary with their parameters'
    /// names.
    #[allow(clippy::type_complexity)]
    fn set_model(
        &self,
        set: &[usize],
    ) -> Result<(Model, Vec<&TermEffect>, Vec<BoundaryEffect>, Vec<&[String]>), DiagnoseError> {
        let mut m = self.refitted_model.clone();
        let (mut terms, mut boundary, mut names) = (Vec::new(), Vec::new(), Vec::new());
        for &i in set {
            match &self.trials[i] {
                Trial::Term(term) => {
                    m = m.with_extension(&term.extension).map_err(model_error)?;
                    terms.push(term);
                }
                Trial::Boundary(e, n) => {
                    boundary.push(*e);
                    names.push(n.as_slice());
                }
                // The model's own parameters: `fit_set` frees them.
                Trial::Parameters(_) => {}
            }
        }
        Ok((m, terms, boundary, names))
    }

    /// The model and boundary of a fit `tried`: the refitted model with its trials' terms,
    /// every parameter at the fitted value, and its boundary effects.
    pub(super) fn realised(&self, tried: &Tried) -> Result<(Model, Boundary), DiagnoseError> {
        let (m, _, boundary, names) = self.set_model(&tried.set)?;
        let values = &tried.candidate.parameters;
        let model_values: Vec<(&str, f64)> = values
            .iter()
            .filter(|(n, _)| m.parameter_index(n).is_some())
            .map(|(n, v)| (n.as_str(), *v))
            .collect();
        let m = m.with_parameters(&model_values).map_err(model_error)?;
        let p: Vec<f64> = names
            .iter()
            .flat_map(|n| n.iter().map(|n| values.get(n).copied().unwrap_or(f64::NAN)))
            .collect();
        Ok((m, Boundary::with_all(&boundary, &p, self.outputs.len())))
    }

    /// The joint fit of the trials `set`: all their parameters, the free ones and the start
    /// together, those in `known` (fitted before) from their values, from the start `x0`.
    fn fit_set(
        &self,
        set: &[usize],
        known: &BTreeMap<String, f64>,
        x0: &[f64],
    ) -> Result<SetFit, DiagnoseError> {
        let (est, joint, base, outputs) = (self.est, self.joint, self.base, self.outputs);
        let (mut m, terms, boundary, boundary_names) = self.set_model(set)?;
        // The free parameters and the terms' parameters, those fitted before at their values.
        let mut all: Vec<String> = joint.names.iter().map(|n| (*n).to_string()).collect();
        for term in &terms {
            all.extend(term.parameter_names());
        }
        // A `parameter_error` in the set frees the model's own parameters it names.
        let suspects: Vec<&String> = set
            .iter()
            .filter_map(|&i| match &self.trials[i] {
                Trial::Parameters(p) => Some(p),
                _ => None,
            })
            .flatten()
            .collect();
        all.extend(suspects.iter().map(|n| n.to_string()));
        let values: Vec<(&str, f64)> = all
            .iter()
            .filter_map(|n| known.get(n).map(|v| (n.as_str(), *v)))
            .collect();
        m = m.with_parameters(&values).map_err(model_error)?;
        // A contact not fitted before starts from the best of its grid.
        for term in &terms {
            let names = term.parameter_names();
            if let (TermStart::Points(points), false) = (&term.start, known.contains_key(&names[0]))
            {
                m = est.best_point(&m, &names, points, x0);
            }
        }
        let mut scales = joint.scales.clone();
        for term in &terms {
            scales.extend(self.samples.term_scales(&m, &est.signal, term));
        }
        scales.extend(parameter_scales(self.refitted_model, &suspects));
        // Any other term not fitted before starts its first parameter from the best of a grid
        // across its scale, zero included: beside the chosen effects the free parameters have
        // compensated for them, and from zero its fit can stay in that basin (drag beside a
        // sensor lag, taken up by the linear dampers).
        for term in &terms {
            let name = &term.parameter_names()[0];
            let surface = match term.start {
                TermStart::Given => false,
                TermStart::BothSigns => true,
                TermStart::Points(_) => continue,
            };
            if !known.contains_key(name) {
                if let Some(j) = all.iter().position(|a| a == name) {
                    m = est.best_shift(&m, name, scales[j], x0, surface);
                }
            }
        }
        // ... or from the equation error's estimate, the other parameters estimated beside it,
        // when that is better still.
        for term in &terms {
            let names = term.parameter_names();
            if term.start != TermStart::Given || known.contains_key(&names[0]) {
                continue;
            }
            let free: Vec<String> = all.iter().filter(|a| !names.contains(a)).cloned().collect();
            m = est.better_with_equation_error(&m, &free, &names, x0);
        }
        let refs: Vec<&str> = all.iter().map(String::as_str).collect();
        let index_x: Vec<usize> = refs
            .iter()
            .map(|n| {
                m.parameter_index(n)
                    .ok_or_else(|| DiagnoseError::NominalFit {
                        reason: format!("no parameter {n} in the extended model"),
                    })
            })
            .collect::<Result<_, _>>()?;
        let joint_x = Joint {
            est,
            model: &m,
            names: &refs,
            index: &index_x,
            scales,
            max_iter: self.opts.candidate_max_iterations,
            ftol: joint.ftol,
        };
        // Boundary parameters fitted before from their values, a new effect's from its start.
        let mut start: Vec<f64> = Vec::new();
        for (&e, pn) in boundary.iter().zip(&boundary_names) {
            match pn.iter().map(|n| known.get(n).copied()).collect() {
                Some(v) => start.extend::<Vec<f64>>(v),
                None => start.extend(joint.effect_start(e, base, outputs)),
            }
        }
        let f = joint_x.fit(&boundary, &start, x0)?;
        let kx = index_x.len();
        let fitted = joint_x.model_at(&f.params[..kx])?;
        let bd = Boundary::with_all(&boundary, &f.params[kx..], outputs.len());
        let (score, sim) = self.score(&fitted, &f.state, &bd)?;
        for names in &boundary_names {
            all.extend(names.iter().cloned());
        }
        Ok((f, score, sim, all))
    }

    /// The fit of `set` (its last trial added beside the others) as a tried candidate, tested
    /// against the fit without that trial (`rss`, held-out `score_without`).
    fn judge(
        &self,
        set: &[usize],
        fitted: Result<SetFit, DiagnoseError>,
        rss: f64,
        score_without: f64,
    ) -> Tried {
        let (trials, opts) = (self.trials, self.opts);
        let (&added, beside) = set.split_last().expect("a set holds its added trial");
        let t2 = &trials[added];
        let name = set
            .iter()
            .map(|&i| trials[i].name())
            .collect::<Vec<_>>()
            .join(" + ");
        let without = beside
            .iter()
            .map(|&i| trials[i].name())
            .collect::<Vec<_>>()
            .join(" + ");
        let (f, score, sim, all) = match fitted {
            Ok(v) => v,
            Err(e) => {
                let mut c = ModelCandidate::failed(t2, format!("fit failed: {e}"));
                c.effect = name;
                return Tried {
                    candidate: c,
                    simulated: None,
                    residuals: Vec::new(),
                    state: Vec::new(),
                    rss: f64::NAN,
                    set: set.to_vec(),
                };
            }
        };
        let (lr, kappa) = nested_ratio(rss, f.rss, &f.residuals, self.n());
        let critical = crate::stats::chi2_quantile(t2.parameter_names().len(), opts.alpha);
        let gain_e = 1.0 - score.validation() / score_without;
        let mut significant = lr >= critical && gain_e >= opts.min_gain;
        let infl = kappa.sqrt();
        let parameters: BTreeMap<String, f64> =
            all.iter().cloned().zip(f.params.iter().copied()).collect();
        let mut note = format!(
            "beside {without}: likelihood ratio {lr:.1} (critical {critical:.1}), held-out gain \
             {:.1} % over {without} alone (at least {:.1} %)",
            100.0 * gain_e,
            100.0 * opts.min_gain
        );
        let stderr: BTreeMap<String, f64> = all
            .iter()
            .cloned()
            .zip(f.stderr.iter().map(|s| s * infl))
            .collect();
        if let Some(reason) = self
            .outside_the_motion(t2, &parameters)
            .or_else(|| self.alias_note(added))
            .or_else(|| undetermined_note(t2, &t2.parameter_names(), &stderr))
        {
            significant = false;
            note.push_str(&format!("; not significant: {reason}"));
        }
        Tried {
            candidate: ModelCandidate {
                effect: name,
                term: t2.describe(),
                parameters,
                stderr,
                nrmse_validation: score.validation(),
                gain: gain_e,
                bic: crate::stats::bic(f.rss, self.n(), f.params.len()),
                likelihood_ratio: lr,
                critical,
                significant,
                iterations: f.iterations,
                note,
            },
            simulated: Some(sim),
            residuals: f.residuals,
            state: f.state,
            rss: f.rss,
            set: set.to_vec(),
        }
    }

    /// The free parameters that the chosen effects of `current` leave `significance_sigma`
    /// standard errors or more from their configured values (`configured`, the refit's
    /// parameters), and the held-out cost of setting them back with the effects kept as
    /// fitted: a parameter error beside the effects when that costs `min_gain` or more. A
    /// parameter that sets the slope a chosen stiffness law leaves to the model
    /// ([`TermEffect::linear_part`]) is excused: it moves with the law.
    pub(super) fn parameters_beside(
        &self,
        current: &Tried,
        configured: &[ParameterChange],
    ) -> Result<Option<ParametersBeside>, DiagnoseError> {
        let model = self.refitted_model;
        let (m, terms, boundary, boundary_names) = self.set_model(&current.set)?;
        // Whether a chosen law's linear part on its equation depends on `p`.
        let sets_law_slope = |p: &str| {
            terms.iter().any(|term| {
                let Some(q) = &term.linear_part else {
                    return false;
                };
                term.extension.terms.iter().any(|(site, _)| {
                    let Site::Flow { state, .. } = site else {
                        return false;
                    };
                    let Some(v) = model.states().iter().position(|s| s.name == *state) else {
                        return false;
                    };
                    model
                        .modes()
                        .iter()
                        .filter_map(|name| model.mode(name))
                        .any(|mode| model.equation(mode, v).derivative(q).depends_on(p))
                })
            })
        };
        let fitted = &current.candidate;
        let (mut moved, mut excused) = (Vec::new(), Vec::new());
        for c in configured {
            let (Some(&v), Some(&se)) =
                (fitted.parameters.get(&c.name), fitted.stderr.get(&c.name))
            else {
                continue;
            };
            let change = ParameterChange {
                name: c.name.clone(),
                configured: c.configured,
                fitted: v,
                stderr: se,
                z: (v - c.configured) / se,
            };
            if change.z.abs() < self.opts.significance_sigma {
                continue;
            }
            if sets_law_slope(&c.name) {
                excused.push(change);
            } else {
                moved.push(change);
            }
        }
        if moved.is_empty() && excused.is_empty() {
            return Ok(None);
        }
        // The extended model at its fitted values, the moved parameters set back.
        let boundary_values: Vec<f64> = boundary_names
            .iter()
            .flat_map(|names| names.iter())
            .map(|n| fitted.parameters.get(n).copied().unwrap_or(f64::NAN))
            .collect();
        let values: Vec<(&str, f64)> = fitted
            .parameters
            .iter()
            .filter(|(n, _)| m.parameter_index(n).is_some())
            .map(|(n, &v)| {
                let reset = moved.iter().find(|c: &&ParameterChange| c.name == *n);
                (n.as_str(), reset.map_or(v, |c| c.configured))
            })
            .collect();
        let m = m.with_parameters(&values).map_err(model_error)?;
        let bd = Boundary::with_all(&boundary, &boundary_values, self.outputs.len());
        let nrmse_reset = if moved.is_empty() {
            fitted.nrmse_validation
        } else {
            self.score(&m, &current.state, &bd)?.0.validation()
        };
        let gain = 1.0 - fitted.nrmse_validation / nrmse_reset;
        Ok(Some(ParametersBeside {
            named: !moved.is_empty() && gain >= self.opts.min_gain,
            moved,
            excused,
            nrmse_reset,
            gain,
        }))
    }

    /// One round: every trial outside the effects of `current` fitted beside them (all their
    /// parameters, the free ones and the start together, the chosen ones' from their fit),
    /// each tested against `current`'s fit.
    pub(super) fn round(&self, current: &Tried) -> Vec<Tried> {
        let outside: Vec<usize> = (0..self.trials.len())
            .filter(|i| !current.set.contains(i))
            .collect();
        let fits: Vec<_> = outside
            .par_iter()
            .map(|&i| {
                let mut set = current.set.clone();
                set.push(i);
                let f = self.fit_set(&set, &current.candidate.parameters, &current.state);
                (set, f)
            })
            .collect();
        fits.into_iter()
            .map(|(set, f)| self.judge(&set, f, current.rss, current.candidate.nrmse_validation))
            .collect()
    }

    /// The backward pass over the chosen effects of `current` (two or more): each tested
    /// against the fit without it; the weakest that no longer passes is dropped, and the pass
    /// repeats. The fit without an effect starts from the chosen set's values; a set fitted
    /// before (in `earlier`, the same effects in any order) is taken as it was fitted when
    /// that fit is the better one. Returns every test made.
    pub(super) fn backward(
        &self,
        current: &mut Option<Tried>,
        earlier: &[&Tried],
    ) -> Vec<ModelCandidate> {
        let (trials, opts) = (self.trials, self.opts);
        let mut backward: Vec<ModelCandidate> = Vec::new();
        while let Some(cur) = current.as_ref().filter(|c| c.set.len() >= 2) {
            let reduced: Vec<(usize, Vec<usize>)> = (0..cur.set.len())
                .map(|j| {
                    let mut r = cur.set.clone();
                    let e = r.remove(j);
                    (e, r)
                })
                .collect();
            let fits: Vec<Result<Tried, DiagnoseError>> = reduced
                .par_iter()
                .map(|(_, r)| {
                    let same = |c: &&&Tried| {
                        let (mut a, mut b) = (c.set.clone(), r.clone());
                        a.sort_unstable();
                        b.sort_unstable();
                        a == b && c.rss.is_finite()
                    };
                    // It starts from the chosen set's fit; a fit of the same set made before
                    // (in an earlier round, from its own start) is kept when it fits better.
                    // Should it become the chosen set, its last effect is tested against the
                    // set before it as every round's is: the refit for a single effect, else
                    // that set's earlier fit (none: tested against nothing).
                    let before: Option<(f64, f64)> = match r.split_last() {
                        Some((_, [])) => Some((self.base.rss, self.refitted.validation())),
                        Some((_, rest)) => earlier
                            .iter()
                            .find(|c| c.set.as_slice() == rest && c.rss.is_finite())
                            .map(|c| (c.rss, c.candidate.nrmse_validation)),
                        None => None,
                    };
                    let refit = self
                        .fit_set(r, &cur.candidate.parameters, &cur.state)
                        .map(|f| {
                            let (rss, score) = before.unwrap_or((f64::NAN, f.1.validation()));
                            self.judge(r, Ok(f), rss, score)
                        });
                    match (earlier.iter().find(same), refit) {
                        (Some(e), Ok(f)) if e.rss <= f.rss || !f.rss.is_finite() => {
                            Ok((*e).clone())
                        }
                        (Some(e), Err(_)) => Ok((*e).clone()),
                        (_, refit) => refit,
                    }
                })
                .collect();
            // The test of each effect: the chosen set against the set without it.
            let mut weakest: Option<(f64, usize, Tried)> = None;
            for ((e, _), fit) in reduced.iter().zip(fits) {
                let Ok(without) = fit else { continue };
                let critical =
                    crate::stats::chi2_quantile(trials[*e].parameter_names().len(), opts.alpha);
                let (lr, _) = nested_ratio(without.rss, cur.rss, &cur.residuals, self.n());
                let gain_e =
                    1.0 - cur.candidate.nrmse_validation / without.candidate.nrmse_validation;
                let passes = lr >= critical && gain_e >= opts.min_gain;
                if !passes && weakest.as_ref().map_or(true, |w| lr < w.0) {
                    weakest = Some((lr, backward.len(), without.clone()));
                }
                backward.push(ModelCandidate {
                    effect: trials[*e].name(),
                    term: trials[*e].describe(),
                    parameters: cur.candidate.parameters.clone(),
                    stderr: cur.candidate.stderr.clone(),
                    nrmse_validation: without.candidate.nrmse_validation,
                    gain: gain_e,
                    bic: without.candidate.bic,
                    likelihood_ratio: lr,
                    critical,
                    significant: passes,
                    iterations: without.candidate.iterations,
                    note: format!(
                        "beside {}: without it the held-out NRMSE is {:.3e}; likelihood ratio \
                         {lr:.1} (critical {critical:.1}), held-out gain {:.1} % with it (at \
                         least {:.1} %)",
                        cur.candidate.effect,
                        without.candidate.nrmse_validation,
                        100.0 * gain_e,
                        100.0 * opts.min_gain
                    ),
                });
            }
            match weakest {
                Some((_, at, without)) => {
                    backward[at].note.push_str("; no longer needed: dropped");
                    *current = Some(without);
                }
                None => break,
            }
        }
        backward
    }
}

/// Score of a model with fitted state `x_est` on the estimation record `est` (fitted up to
/// `cut`, held out after it) or, with a validation record `val`, held out there (its initial
/// state fitted with the parameters fixed); and the simulation shown.
pub(super) fn score_on(
    est: &Prepared<'_>,
    val: Option<&Prepared<'_>>,
    cut: usize,
    m: &Model,
    x_est: &[f64],
    b: &Boundary,
) -> Result<(ModelScore, Vec<Vec<f64>>), DiagnoseError> {
    let sim = est.simulate(m, x_est, b)?;
    let (_, nrmse_fit) = est.errors(&sim, est.rows.clone());
    let (rmse_validation, nrmse_validation, shown) = match val {
        None => {
            let (r, q) = est.errors(&sim, cut..est.rec.len());
            (r, q, sim)
        }
        Some(v) => {
            let x = v.fit_state(m, &v.guess, b)?;
            let vsim = v.simulate(m, &x, b)?;
            let (r, q) = v.errors(&vsim, v.rows.clone());
            (r, q, vsim)
        }
    };
    Ok((
        ModelScore {
            nrmse_fit,
            nrmse_validation,
            rmse_validation,
        },
        shown,
    ))
}
