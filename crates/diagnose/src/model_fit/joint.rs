//! Joint output-error fits of a model's free parameters with candidate effects, and the
//! candidates as the selection keeps them.

use htfid_estimate::{levenberg_marquardt_with_jacobian, LmOptions};
use htfid_lang::Model;

use super::prepared::{difference_columns, Prepared};
use super::{ModelCandidate, ModelScore};
use crate::boundary::{Boundary, BoundaryEffect};
use crate::term::TermEffect;
use crate::{DiagnoseError, TimeSeries};

/// A candidate effect to try.
pub(super) enum Trial {
    /// An effect on the model's boundary, with its parameters' names in this model (those of
    /// [`BoundaryEffect::parameter_names`], suffixed where the model or a term uses them).
    Boundary(BoundaryEffect, Vec<String>),
    Term(TermEffect),
    /// `parameter_error`: the model's own parameters named here, held at their configured
    /// values everywhere else, refitted together as one candidate effect
    /// ([`ModelFitOptions::parameter_error`](super::ModelFitOptions::parameter_error)).
    Parameters(Vec<String>),
}

impl Trial {
    pub(super) fn name(&self) -> String {
        match self {
            Trial::Boundary(e, _) => e.name().to_string(),
            Trial::Term(t) => t.name.clone(),
            Trial::Parameters(_) => "parameter_error".to_string(),
        }
    }

    pub(super) fn describe(&self) -> Option<String> {
        match self {
            Trial::Boundary(..) | Trial::Parameters(_) => None,
            Trial::Term(t) => Some(t.describe()),
        }
    }

    pub(super) fn parameter_names(&self) -> Vec<String> {
        match self {
            Trial::Boundary(_, names) | Trial::Parameters(names) => names.clone(),
            Trial::Term(t) => t.parameter_names(),
        }
    }
}

/// An effect tried: its result, its simulated outputs (when fitted) and its scaled residuals
/// on the fit data (outputs one after another).
#[derive(Clone)]
pub(super) struct Tried {
    pub(super) candidate: ModelCandidate,
    pub(super) simulated: Option<Vec<Vec<f64>>>,
    pub(super) residuals: Vec<f64>,
    /// The fitted initial state and the fit's sum of squares (empty and NaN when it failed).
    pub(super) state: Vec<f64>,
    pub(super) rss: f64,
    /// The trials fitted together, in the order they were chosen (`trial` last).
    pub(super) set: Vec<usize>,
}

/// The joint fit of several effects, its held-out score, its simulated outputs and the names
/// of its fitted parameters (in the fit's order).
pub(super) type SetFit = (JointFit, ModelScore, Vec<Vec<f64>>, Vec<String>);

/// One joint output-error fit: free parameters, effect parameters and the initial state.
pub(super) struct JointFit {
    /// Free parameters, then the effect's.
    pub(super) params: Vec<f64>,
    pub(super) stderr: Vec<f64>,
    pub(super) state: Vec<f64>,
    pub(super) residuals: Vec<f64>,
    pub(super) rss: f64,
    pub(super) iterations: usize,
    pub(super) stop: String,
}

/// Joint fits of a model's free parameters with a boundary effect on one record.
pub(super) struct Joint<'a, 'r> {
    pub(super) est: &'a Prepared<'r>,
    pub(super) model: &'a Model,
    pub(super) names: &'a [&'a str],
    pub(super) index: &'a [usize],
    /// The size of a meaningful change of each parameter in `names` (the fit's scaling).
    pub(super) scales: Vec<f64>,
    /// Most iterations of a fit.
    pub(super) max_iter: usize,
    /// Its Levenberg-Marquardt `ftol`: a step lowering the cost by a smaller fraction ends it
    /// ([`ModelFitOptions::fit_tolerance`](super::ModelFitOptions::fit_tolerance) over the
    /// residuals' count).
    pub(super) ftol: f64,
}

impl Joint<'_, '_> {
    /// The longest lag or delay tried: a tenth of the record and, for a forced model, half its
    /// period (a delay of a whole period reproduces a periodic response).
    pub(super) fn longest_lag(&self) -> f64 {
        let record = 0.1 * self.est.dt * self.est.rec.len() as f64;
        self.model
            .period()
            .map_or(record, |period| record.min(0.5 * period))
    }

    pub(super) fn model_at(&self, values: &[f64]) -> Result<Model, DiagnoseError> {
        let changes: Vec<(&str, f64)> = self
            .names
            .iter()
            .copied()
            .zip(values.iter().copied())
            .collect();
        self.model
            .with_parameters(&changes)
            .map_err(|e| DiagnoseError::NominalFit {
                reason: e.to_string(),
            })
    }

    /// A start for `effect`'s parameters: the neutral values for an offset and a gain; for a
    /// lag or delay, the best of a grid across decades (1 to 300 sample intervals, up to a
    /// tenth of the record) by the output error with the refit's parameters and state.
    pub(super) fn effect_start(
        &self,
        effect: BoundaryEffect,
        base: &JointFit,
        outputs: &[String],
    ) -> Vec<f64> {
        if !effect.is_lag() {
            return effect.neutral(outputs.len());
        }
        let est = self.est;
        let longest = self.longest_lag();
        let Ok(m) = self.model_at(&base.params[..self.index.len()]) else {
            return vec![est.dt];
        };
        let mut r = vec![0.0; est.residual_len()];
        let mut best = (f64::INFINITY, 0.0);
        // Zero (the refit itself) competes, so the start is never worse than the refit.
        for steps in [0.0, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0] {
            let v = steps * est.dt;
            if v > longest {
                break;
            }
            let b = Boundary::with(effect, &[v], outputs.len());
            if let Ok(sim) = est.simulate(&m, &base.state, &b) {
                est.fill(&sim, &mut r);
                let cost: f64 = r.iter().map(|v| v * v).sum();
                if cost < best.0 {
                    best = (cost, v);
                }
            }
        }
        vec![best.1]
    }

    /// Fits the free parameters, the parameters of the boundary `effects` (from
    /// `effect_start`, one effect's after another) and the initial state (from `x0`) together.
    pub(super) fn fit(
        &self,
        effects: &[BoundaryEffect],
        effect_start: &[f64],
        x0: &[f64],
    ) -> Result<JointFit, DiagnoseError> {
        let (est, model) = (self.est, self.model);
        let k = self.index.len();
        let e = effect_start.len();
        let outputs = model.outputs().len();
        let mut p0: Vec<f64> = self.index.iter().map(|&i| model.values()[i]).collect();
        p0.extend_from_slice(effect_start);
        p0.extend_from_slice(x0);
        let residuals = |p: &[f64], r: &mut [f64]| -> Result<(), String> {
            let trial = self.model_at(&p[..k]).map_err(|e| e.to_string())?;
            let b = Boundary::with_all(effects, &p[k..k + e], outputs);
            let sim = est
                .simulate(&trial, &p[k + e..], &b)
                .map_err(|e| e.to_string())?;
            est.fill(&sim, r);
            Ok(())
        };
        let params = model.parameters();
        let mut bounds: Vec<(f64, f64)> = self
            .index
            .iter()
            .map(|&i| (params[i].min, params[i].max))
            .collect();
        let counted: usize = effects.iter().map(|x| x.parameter_count(outputs)).sum();
        if counted != e {
            return Err(DiagnoseError::NominalFit {
                reason: format!(
                    "{e} starting values for boundary effects with {counted} parameters"
                ),
            });
        }
        let mut scales: Vec<f64> = self.scales.clone();
        let mut at = 0;
        for &effect in effects {
            let n = effect.parameter_count(outputs);
            let start = &effect_start[at..at + n];
            at += n;
            for (j, v) in start.iter().enumerate() {
                if effect.is_lag() {
                    bounds.push((0.0, self.longest_lag()));
                    scales.push(v.abs().max(est.dt));
                } else {
                    bounds.push((f64::NEG_INFINITY, f64::INFINITY));
                    scales.push(match effect {
                        BoundaryEffect::InputOffset => input_scale(est.rec),
                        _ if j % 2 == 0 => est.scale[j / 2],
                        _ => 0.1,
                    });
                }
            }
        }
        bounds.extend_from_slice(&est.state_box);
        scales.extend(x0.iter().map(|v| v.abs().max(1e-3)));
        // Exact columns for everything: the model's parameters, the input side's boundary
        // effects (the input's change by each, through the model's derivatives by its input),
        // the initial state, and the sensors' offset, gain and lag (from the model's outputs);
        // differences for all where the sensitivities do not hold (the motion slides) or their
        // simulation fails (a fit must not fail where differences work).
        let every: Vec<usize> = (0..k + e + x0.len()).collect();
        // Once the sensitivities fail (the motion slides), the rest of the fit differences.
        let failed = std::cell::Cell::new(false);
        let jacobian = |p: &[f64], r: &[f64], jac: &mut [f64]| -> Result<(), String> {
            let trial = self.model_at(&p[..k]).map_err(|e| e.to_string())?;
            let b = Boundary::with_all(effects, &p[k..k + e], outputs);
            let (mut input_side, mut directions) = (Vec::new(), Vec::new());
            let mut at = k;
            for &effect in effects {
                if let Some(d) = b.input_direction(effect, &est.signal) {
                    input_side.push(at);
                    directions.push(d);
                }
                at += effect.parameter_count(outputs);
            }
            let exact_at: Vec<usize> = (0..k)
                .chain(input_side.iter().copied())
                .chain(k + e..k + e + x0.len())
                .collect();
            let raw = if failed.get() {
                None
            } else {
                est.sensitivities(
                    &trial,
                    (self.names, &directions),
                    &p[k + e..],
                    &b,
                    est.rec.len(),
                    est.rows.clone(),
                    &exact_at,
                    jac,
                )
                .ok()
            };
            failed.set(raw.is_none());
            match raw {
                Some(raw) => {
                    let left = est.sensor_columns(&raw, (effects, &b, k), est.rows.clone(), jac);
                    debug_assert_eq!(left, input_side);
                    Ok(())
                }
                None => difference_columns(
                    &residuals,
                    p,
                    r,
                    &every,
                    (est.fd_step(), &scales, &bounds),
                    jac,
                ),
            }
        };
        let lm = LmOptions {
            scales: Some(scales.clone()),
            bounds: Some(bounds.clone()),
            max_iter: self.max_iter,
            ftol: self.ftol,
            ..LmOptions::default()
        };
        let fit =
            levenberg_marquardt_with_jacobian(&residuals, jacobian, &p0, est.residual_len(), &lm)
                .map_err(|e| DiagnoseError::NominalFit {
                reason: e.to_string(),
            })?;
        let np = k + e;
        Ok(JointFit {
            params: fit.params[..np].to_vec(),
            stderr: match &fit.stderr {
                Some(s) => s[..np].to_vec(),
                None => vec![f64::NAN; np],
            },
            state: fit.params[np..].to_vec(),
            rss: fit.residuals.iter().map(|v| v * v).sum(),
            residuals: fit.residuals,
            iterations: fit.iterations,
            stop: format!("{:?}", fit.stop),
        })
    }
}

/// The input's standard deviation (at least 1e-3), the scale of an input offset.
fn input_scale(rec: &TimeSeries) -> f64 {
    let n = rec.input().len().max(1) as f64;
    let mean = rec.input().iter().sum::<f64>() / n;
    let var = rec.input().iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
    var.sqrt().max(1e-3)
}
