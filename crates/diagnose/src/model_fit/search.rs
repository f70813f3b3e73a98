//! The term search outside the library for a model file: when clear structure remains, a
//! forward selection over a dictionary of terms (products of two or three states, `|v| v`) in
//! the equations of the velocity states, in output error.
//!
//! Each round screens every dictionary term at once: one simulation with forward
//! sensitivities gives the output's exact derivative by every term's coefficient (at zero)
//! beside those by the fitted parameters and the initial state; the score statistic of a term
//! is the part of its column orthogonal to the fitted ones, projected on the residual,
//! `(q' r)^2 / (q' q) / s^2`, divided by the residuals' correlation inflation (the orthogonal
//! least squares of FROLS, read in output error). The best term is fitted jointly with the
//! free parameters and the terms chosen before it, and kept when it passes the library's
//! tests against the fit without it (likelihood ratio, held-out gain); the search stops at the
//! first that does not, or after [`MAX_TERMS`].

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::joint::{Joint, JointFit};
use super::prepared::{Prepared, StateSamples};
use super::selection::{correlation_inflation, nested_ratio};
use super::{ModelFitOptions, ModelScore};
use crate::boundary::Boundary;
use crate::term::{dictionary_extension, term_dictionary, DictionaryTerm, TermEffect};
use crate::DiagnoseError;
use htfid_lang::Model;

/// Most terms the search adds.
pub const MAX_TERMS: usize = 3;

/// A formula found outside the library: terms added to the model's equations.
#[derive(Debug, Clone, Serialize)]
pub struct ModelDiscovered {
    /// The terms as equations, e.g. `v1' += -4.98 * (x1 - 0.0012)*v1`.
    pub formula: String,
    /// Each term with its fitted coefficient.
    pub terms: Vec<ModelDiscoveredTerm>,
    /// Held-out NRMSE of the refitted model the terms were added to, and with them.
    pub nrmse_before: f64,
    /// Held-out NRMSE with the terms.
    pub nrmse_after: f64,
    /// `1 - nrmse_after / nrmse_before`.
    pub gain: f64,
    /// The model the terms were added to: `"nominal"` (the refitted model).
    pub read_from: String,
    /// Why the search added no further term.
    pub stopped: String,
}

/// One term of a [`ModelDiscovered`] formula.
#[derive(Debug, Clone, Serialize)]
pub struct ModelDiscoveredTerm {
    /// The state whose equation it joins.
    pub state: String,
    /// The function of the states it multiplies.
    pub term: String,
    /// Its coefficient's name in the extended model.
    pub parameter: String,
    /// The fitted coefficient (in the state equation's units).
    pub coefficient: f64,
    /// Its standard error, inflated for the residuals' correlation.
    pub stderr: f64,
    /// The likelihood ratio with which it was added, against the fit without it.
    pub likelihood_ratio: f64,
}

/// The held-out score of a model started from a fitted state.
pub(super) type Scorer<'a> = dyn Fn(&Model, &[f64]) -> Result<ModelScore, DiagnoseError> + 'a;

/// What the search needs from the diagnosis.
pub(super) struct Search<'a, 'r> {
    pub est: &'a Prepared<'r>,
    /// The refitted model (the free parameters at their refitted values).
    pub model: &'a Model,
    pub names: &'a [&'a str],
    pub scales: &'a [f64],
    pub base: &'a JointFit,
    pub samples: &'a StateSamples,
    pub means: &'a [f64],
    pub refitted: &'a ModelScore,
    pub score: &'a Scorer<'a>,
    pub opts: &'a ModelFitOptions,
}

/// The fit the search has reached: parameters (free, then the chosen terms'), state, residuals.
struct Reached {
    params: Vec<f64>,
    stderr: Vec<f64>,
    state: Vec<f64>,
    residuals: Vec<f64>,
    rss: f64,
    score: ModelScore,
    ratios: Vec<f64>,
}

impl Search<'_, '_> {
    /// The formula, when a term passes, and one sentence of evidence either way.
    pub(super) fn run(&self) -> (Option<ModelDiscovered>, String) {
        let none = |why: String| (None, format!("term search outside the library: {why}"));
        let dictionary = term_dictionary(self.model, self.means);
        if dictionary.is_empty() {
            return none(
                "the model has no velocity state (a state another state's equation reads as \
                 its rate) whose equation a term could join"
                    .into(),
            );
        }
        let k = self.names.len();
        let mut chosen: Vec<usize> = Vec::new();
        let mut reached = Reached {
            params: self.base.params.clone(),
            stderr: self.base.stderr.clone(),
            state: self.base.state.clone(),
            residuals: self.base.residuals.clone(),
            rss: self.base.rss,
            score: self.refitted.clone(),
            ratios: Vec::new(),
        };
        let critical = crate::stats::chi2_quantile(1, self.opts.alpha);
        // Set by every way out of the loop below but its end: the cap on the terms.
        let mut stop = format!("it reached its cap of {MAX_TERMS} terms (a hint stays short)");
        while chosen.len() < MAX_TERMS {
            let Some((j, statistic)) = (match self.screen(&dictionary, &chosen, &reached) {
                Ok(best) => best,
                Err(e) => {
                    stop = format!("the screening failed: {e}");
                    break;
                }
            }) else {
                stop = "no other term's score reaches the critical value".into();
                break;
            };
            if statistic < critical {
                stop = format!(
                    "the best remaining term, {}, scores {statistic:.1} (critical {critical:.1})",
                    describe(&dictionary[j])
                );
                break;
            }
            let mut trial = chosen.clone();
            trial.push(j);
            let fitted = match self.fit(&dictionary, &trial, &reached) {
                Ok(f) => f,
                Err(e) => {
                    stop = format!("the fit with {} failed: {e}", describe(&dictionary[j]));
                    break;
                }
            };
            let (lr, _) = nested_ratio(
                reached.rss,
                fitted.rss,
                &fitted.residuals,
                self.est.residual_len(),
            );
            let gain = 1.0 - fitted.score.validation() / reached.score.validation();
            if lr < critical || gain < self.opts.min_gain {
                stop = format!(
                    "the next term, {}, improves the fit by a likelihood ratio of {lr:.1} \
                     (critical {critical:.1}) and the held-out NRMSE by {:.1} % (at least \
                     {:.1} %)",
                    describe(&dictionary[j]),
                    100.0 * gain,
                    100.0 * self.opts.min_gain
                );
                break;
            }
            chosen.push(j);
            let mut fitted = fitted;
            fitted.ratios.push(lr);
            reached = fitted;
        }
        if chosen.is_empty() {
            return none(stop);
        }
        let extension = dictionary_extension(self.model, &dictionary, &chosen);
        let terms: Vec<ModelDiscoveredTerm> = chosen
            .iter()
            .enumerate()
            .map(|(i, &j)| ModelDiscoveredTerm {
                state: dictionary[j].state.clone(),
                term: dictionary[j].function.clone(),
                parameter: extension.parameters[i].name.clone(),
                coefficient: reached.params[k + i],
                stderr: reached.stderr[k + i],
                likelihood_ratio: reached.ratios[i],
            })
            .collect();
        let formula = terms
            .iter()
            .map(|t| format!("{}' += {:.4e} * {}", t.state, t.coefficient, t.term))
            .collect::<Vec<_>>()
            .join("; ");
        let before = self.refitted.validation();
        let after = reached.score.validation();
        let sentence = format!(
            "term search outside the library: {formula} lowers the refitted model's held-out \
             NRMSE from {} to {} (gain {}); the search stopped because {stop}; a hint, not a \
             library effect",
            htfid_number::percent(before, 3),
            htfid_number::percent(after, 3),
            htfid_number::percent(1.0 - after / before, 3)
        );
        (
            Some(ModelDiscovered {
                formula,
                terms,
                nrmse_before: before,
                nrmse_after: after,
                gain: 1.0 - after / before,
                read_from: "nominal".into(),
                stopped: stop,
            }),
            sentence,
        )
    }

    /// The dictionary term (not in `chosen`) with the largest score statistic at `reached`,
    /// and that statistic.
    fn screen(
        &self,
        dictionary: &[DictionaryTerm],
        chosen: &[usize],
        reached: &Reached,
    ) -> Result<Option<(usize, f64)>, String> {
        let est = self.est;
        let k = self.names.len();
        let d = dictionary.len();
        let n = reached.state.len();
        let every: Vec<usize> = (0..d).collect();
        let extension = dictionary_extension(self.model, dictionary, &every);
        let mut changes: Vec<(&str, f64)> = self
            .names
            .iter()
            .copied()
            .zip(reached.params[..k].iter().copied())
            .collect();
        for (i, &j) in chosen.iter().enumerate() {
            changes.push((extension.parameters[j].name.as_str(), reached.params[k + i]));
        }
        let all = self
            .model
            .with_extension(&extension)
            .and_then(|m| m.with_parameters(&changes))
            .map_err(|e| e.to_string())?;
        let names: Vec<&str> = self
            .names
            .iter()
            .copied()
            .chain(extension.parameters.iter().map(|p| p.name.as_str()))
            .collect();
        let m = est.residual_len();
        let columns = k + d + n;
        let mut jac = vec![0.0; m * columns];
        let at: Vec<usize> = (0..columns).collect();
        est.sensitivities(
            &all,
            (&names, &[]),
            &reached.state,
            &Boundary::default(),
            est.rec.len(),
            est.rows.clone(),
            &at,
            &mut jac,
        )
        .map_err(|e| e.to_string())?;
        let jac = DMatrix::from_column_slice(m, columns, &jac);
        // The fitted directions: free parameters, chosen terms, initial state.
        let fitted: Vec<usize> = (0..k)
            .chain(chosen.iter().map(|&j| k + j))
            .chain(k + d..columns)
            .collect();
        let basis = jac.select_columns(&fitted).qr().q();
        let r = DVector::from_column_slice(&reached.residuals);
        let dof = (m as f64 - fitted.len() as f64).max(1.0);
        let s2 = r.norm_squared() / dof;
        let inflation = correlation_inflation(&reached.residuals).powi(2);
        let mut best: Option<(usize, f64)> = None;
        for j in (0..d).filter(|j| !chosen.contains(j)) {
            let col = jac.column(k + j);
            let q = col - &basis * (basis.tr_mul(&col));
            let qq = q.norm_squared();
            if qq <= 1e-12 * col.norm_squared() || !qq.is_finite() {
                continue;
            }
            let statistic = q.dot(&r).powi(2) / qq / s2 / inflation;
            if statistic.is_finite() && best.map_or(true, |(_, b)| statistic > b) {
                best = Some((j, statistic));
            }
        }
        Ok(best)
    }

    /// The joint fit of the free parameters, the terms `trial` of `dictionary` and the initial
    /// state, from `reached`.
    fn fit(
        &self,
        dictionary: &[DictionaryTerm],
        trial: &[usize],
        reached: &Reached,
    ) -> Result<Reached, DiagnoseError> {
        let k = self.names.len();
        let extension = dictionary_extension(self.model, dictionary, trial);
        let invalid = |e: htfid_lang::ModelError| DiagnoseError::NominalFit {
            reason: e.to_string(),
        };
        let mut changes: Vec<(&str, f64)> = Vec::new();
        for (i, p) in extension
            .parameters
            .iter()
            .enumerate()
            .take(trial.len() - 1)
        {
            changes.push((p.name.as_str(), reached.params[k + i]));
        }
        let extended = self
            .model
            .with_extension(&extension)
            .and_then(|m| m.with_parameters(&changes))
            .map_err(invalid)?;
        let all: Vec<&str> = self
            .names
            .iter()
            .copied()
            .chain(extension.parameters.iter().map(|p| p.name.as_str()))
            .collect();
        let index: Vec<usize> = all
            .iter()
            .filter_map(|n| extended.parameter_index(n))
            .collect();
        let term = TermEffect {
            name: "term search".into(),
            extension: extension.clone(),
            start: crate::term::TermStart::Given,
            placed: None,
            linear_part: None,
        };
        let mut scales = self.scales.to_vec();
        scales.extend(self.samples.term_scales(&extended, &self.est.signal, &term));
        let joint = Joint {
            est: self.est,
            model: &extended,
            names: &all,
            index: &index,
            scales,
            max_iter: self.opts.candidate_max_iterations,
            ftol: self.opts.fit_tolerance / self.est.residual_len().max(1) as f64,
        };
        let f = joint.fit(&[], &[], &reached.state)?;
        let fitted = joint.model_at(&f.params)?;
        let score = (self.score)(&fitted, &f.state)?;
        let inflation = correlation_inflation(&f.residuals);
        Ok(Reached {
            stderr: f.stderr.iter().map(|s| s * inflation).collect(),
            params: f.params,
            state: f.state,
            residuals: f.residuals,
            rss: f.rss,
            score,
            ratios: reached.ratios.clone(),
        })
    }
}

/// A dictionary term in words: "`x1*v1` in v1'".
fn describe(term: &DictionaryTerm) -> String {
    format!("`{}` in {}'", term.function, term.state)
}
