//! The held-out error of a diagnosis, step by step from the configured model to the
//! final one, each level a fit the diagnosis made.

use super::ModelDiagnosis;
use crate::ErrorStep;

impl ModelDiagnosis {
    /// The effects of the extended fit in the order the selection chose them (the candidate
    /// `parameter_error` among them when it was chosen; not a parameter error named beside
    /// them); empty without an extended fit.
    pub fn chosen(&self) -> Vec<&str> {
        self.extended
            .as_ref()
            .map(|c| c.effect.split(" + ").collect())
            .unwrap_or_default()
    }

    /// The held-out NRMSE (mean over the outputs) from the configured model to the final one:
    /// the configured level; the refit of the free parameters (`refitted`, left out when
    /// nothing is free, `refit` false: then the refit only fits the initial state); one step
    /// per named effect in the order chosen, each ending at the held-out score of the fit of
    /// that effect beside those before it, as the selection fitted it (the first round alone,
    /// the pairs, the later rounds; the last at the final fit); with nothing refitted,
    /// `parameter_error` beside the effects from the final fit with the moved parameters set
    /// back to it (the last effect's step then ends there); and the final level. With free
    /// parameters refitted, their move from the configured values is the `refitted` step and
    /// every effect's fit moves them again, so a parameter error beside the effects has no
    /// step of its own: set back, they would raise the error above the refit's. Every level is a measured score. Where the backward pass left a set of effects
    /// whose prefix the selection never fitted (an effect dropped from between them), the
    /// effects from there on are one step, named `"a + b"`.
    pub fn error_waterfall(&self, refit: bool) -> Vec<ErrorStep> {
        let level = |step: &str, v: f64| ErrorStep {
            step: step.to_string(),
            before: v,
            after: v,
        };
        let configured = self.configured.validation();
        let refitted = self.refitted.validation();
        let mut steps = vec![level("configured", configured)];
        if refit {
            steps.push(ErrorStep {
                step: "refitted".into(),
                before: configured,
                after: refitted,
            });
        }
        let Some(extended) = &self.extended else {
            steps.push(level("final", refitted));
            return steps;
        };
        let beside = self
            .parameters_beside
            .as_ref()
            .filter(|p| p.named && !refit);
        // The effects in the order chosen, the candidate `parameter_error` among them; a
        // parameter error beside them is its own last step.
        let effects = self.chosen();
        let end = beside.map_or(extended.nrmse_validation, |p| p.nrmse_reset);
        // The score of the fit of the first `i` effects together, as the selection made it.
        let prefix = |i: usize| -> Option<f64> {
            let name = joined(&effects[..i]);
            std::iter::once(&self.candidates)
                .chain(std::iter::once(&self.pairs))
                .chain(self.later_rounds.iter())
                .flatten()
                .find(|c| c.effect == name)
                .map(|c| c.nrmse_validation)
                .filter(|v| v.is_finite())
        };
        let mut before = refitted;
        let mut from = 0;
        for i in 1..=effects.len() {
            let after = if i == effects.len() {
                Some(end)
            } else {
                prefix(i)
            };
            if let Some(after) = after {
                steps.push(ErrorStep {
                    step: joined(&effects[from..i]),
                    before,
                    after,
                });
                before = after;
                from = i;
            }
        }
        if beside.is_some() {
            steps.push(ErrorStep {
                step: "parameter_error".into(),
                before,
                after: extended.nrmse_validation,
            });
        }
        steps.push(level("final", extended.nrmse_validation));
        steps
    }
}

/// Effects' names as the selection names their joint fit: `"a + b"`.
fn joined(effects: &[&str]) -> String {
    effects.join(" + ")
}
