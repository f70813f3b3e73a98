//! The causes a diagnosis names, each with its parameters in the final fit and its
//! share of the held-out error the final model explains.

use std::collections::BTreeMap;

use super::joint::{Trial, Tried};
use super::{ModelCandidate, ParameterChange, ParametersBeside};
use crate::Cause;

/// What the causes are read from.
pub(super) struct Named<'a> {
    /// The chosen effects' fit.
    pub current: Option<&'a Tried>,
    /// Every trial, indexed by `Tried::set`.
    pub trials: &'a [Trial],
    /// The backward pass: each chosen effect's fit without it (two or more chosen).
    pub backward: &'a [ModelCandidate],
    /// The refitted model's held-out score (mean NRMSE over the outputs).
    pub refitted: f64,
    /// The free parameters beside the chosen effects.
    pub beside: Option<&'a ParametersBeside>,
    /// The refit's parameters when the refit alone is the answer (`parameter_error` with no
    /// effect), else `None`.
    pub refit_alone: Option<&'a [ParameterChange]>,
    /// How many standard errors make a parameter moved.
    pub significance_sigma: f64,
}

impl Named<'_> {
    /// The causes, strongest first (by share; equal shares in the order chosen):
    /// `parameter_error` among them when it is named beside the effects (merged into the
    /// candidate `parameter_error` when that was chosen too).
    ///
    /// A cause's share is its removal cost: the held-out mean square error (NRMSE squared)
    /// of the final model without it, less the final model's, over the sum of all causes'
    /// costs. Without an effect means: the backward pass's fit of the others (two or more
    /// effects), the refitted model (one effect), the final fit with the moved parameters set
    /// back (`parameter_error` beside the effects). The shares add up to 1; equal shares when
    /// no removal costs anything.
    pub fn causes(&self) -> Vec<Cause> {
        if let Some(changes) = self.refit_alone {
            let moved = changes
                .iter()
                .filter(|p| p.z.abs() >= self.significance_sigma);
            return vec![Cause {
                effect: "parameter_error".into(),
                parameters: moved.clone().map(|p| (p.name.clone(), p.fitted)).collect(),
                stderr: moved.map(|p| (p.name.clone(), p.stderr)).collect(),
                gain_share: 1.0,
            }];
        }
        let Some(current) = self.current else {
            return Vec::new();
        };
        let fit = &current.candidate;
        let final2 = fit.nrmse_validation.powi(2);
        let mut causes = Vec::new();
        let mut costs = Vec::new();
        for &i in &current.set {
            let trial = &self.trials[i];
            let name = trial.name();
            let without = if current.set.len() == 1 {
                Some(self.refitted)
            } else {
                self.backward
                    .iter()
                    .find(|b| b.effect == name)
                    .map(|b| b.nrmse_validation)
            };
            let (parameters, stderr) = own(fit, &trial.parameter_names());
            causes.push(Cause {
                effect: name,
                parameters,
                stderr,
                gain_share: 0.0,
            });
            costs.push(without.map_or(0.0, |w| (w * w - final2).max(0.0)));
        }
        if let Some(p) = self.beside.filter(|p| p.named) {
            let parameters: BTreeMap<String, f64> =
                p.moved.iter().map(|c| (c.name.clone(), c.fitted)).collect();
            let stderr: BTreeMap<String, f64> =
                p.moved.iter().map(|c| (c.name.clone(), c.stderr)).collect();
            let cost = (p.nrmse_reset.powi(2) - final2).max(0.0);
            match causes.iter().position(|c| c.effect == "parameter_error") {
                Some(at) => {
                    causes[at].parameters.extend(parameters);
                    causes[at].stderr.extend(stderr);
                    costs[at] += cost;
                }
                None => {
                    causes.push(Cause {
                        effect: "parameter_error".into(),
                        parameters,
                        stderr,
                        gain_share: 0.0,
                    });
                    costs.push(cost);
                }
            }
        }
        let total: f64 = costs.iter().sum();
        let n = causes.len() as f64;
        for (c, cost) in causes.iter_mut().zip(costs) {
            c.gain_share = if total > 0.0 { cost / total } else { 1.0 / n };
        }
        causes.sort_by(|a, b| b.gain_share.total_cmp(&a.gain_share));
        causes
    }
}

/// An effect's own parameters in the fit `fit`, by the names it adds.
fn own(fit: &ModelCandidate, names: &[String]) -> (BTreeMap<String, f64>, BTreeMap<String, f64>) {
    let pick = |m: &BTreeMap<String, f64>| {
        names
            .iter()
            .filter_map(|n| m.get(n).map(|v| (n.clone(), *v)))
            .collect()
    };
    (pick(&fit.parameters), pick(&fit.stderr))
}
