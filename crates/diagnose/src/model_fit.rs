//! Diagnosis of a model written in the model language: the configured simulation is the
//! baseline, the free parameters are refitted by output error, and every parameter that moved
//! significantly is a finding (`parameter_error`).

use htfid_experiment::Rhythmic;
use htfid_lang::Model;
use serde::{Deserialize, Serialize};

use crate::agreement::{Agreement, Plain};
use crate::boundary::{Boundary, BoundaryEffect};
use crate::term::{term_library, TermEffect, TermKind};
use crate::{DiagnoseError, TimeSeries};
use std::collections::BTreeMap;

mod causes;
mod equation_error;
mod joint;
mod prepared;
mod residual_bins;
mod search;
mod selection;
mod waterfall;

use joint::{Joint, JointFit, Trial, Tried};
use prepared::Prepared;
pub use residual_bins::{second_order_pairs, PairResidual};
use selection::{correlation_inflation, parameter_scales, rivals_by_bic, score_on, Selection};

pub use search::{ModelDiscovered, ModelDiscoveredTerm};

/// One effect of the selected model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Cause {
    /// The effect's name (`coulomb_friction`, ..., `parameter_error`).
    pub effect: String,
    /// Its fitted parameters.
    pub parameters: BTreeMap<String, f64>,
    /// Their standard errors.
    pub stderr: BTreeMap<String, f64>,
    /// Its share of the held-out mean-square error that the selected model explains, in
    /// `[0, 1]`; the shares of all causes add up to 1.
    pub gain_share: f64,
}

/// The measured input's own noise, as it enters the noise floor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct InputNoise {
    /// Standard deviation of the input's white noise, in the input's units: the level of its
    /// spectrum in the noise band.
    pub sigma: f64,
    /// RMS response of the refitted model to white noise of that level, in NRMSE units.
    pub propagated: f64,
}

/// How a model is refitted.
#[derive(Debug, Clone)]
pub struct ModelFitOptions {
    /// Parameters refitted (names); the others stay as configured.
    pub free: Vec<String>,
    /// The model's own parameters, none of them `free`, whose error is a candidate effect:
    /// held at their configured values everywhere else, they are refitted together as the
    /// candidate `parameter_error`, which competes with the library's effects and can be
    /// chosen beside them (empty by default: no such candidate). With `free` empty and the
    /// suspected parameters here, nothing is refitted unless the data ask for it.
    pub parameter_error: Vec<String>,
    /// Share of the record (from its start) the fit uses; the rest is held out.
    pub fit_fraction: f64,
    /// Seconds at the start of the record left out of every score (the unknown initial
    /// transient).
    pub burn_in: f64,
    /// A parameter counts as moved when `|fitted - configured| >= significance_sigma * stderr`.
    pub significance_sigma: f64,
    /// Smallest held-out improvement that makes a refit a finding.
    pub min_gain: f64,
    /// Integrator tolerance of every simulation.
    pub rtol: f64,
    /// Boundary effects tried after the refit (all by default).
    pub effects: Vec<BoundaryEffect>,
    /// Kinds of term the library adds to the model's own equations and guards, at every site
    /// the model offers (all by default).
    pub terms: Vec<TermKind>,
    /// The user's own candidate terms (`[[diagnose.terms]]`), tried with the library's.
    pub user_terms: Vec<TermEffect>,
    /// Significance level of the likelihood-ratio test of an effect.
    pub alpha: f64,
    /// Two significant effects whose held-out NRMSEs differ by less than this fraction of the
    /// better one may explain the data equally well; the fit data decide (`bic_margin`). The
    /// default 0.05 is a difference of mean squares of about a tenth of the better one's,
    /// below what a few thousand held-out samples of a residual near the noise floor resolve.
    pub rival_margin: f64,
    /// Of the effects within `rival_margin` held out, the one with the lowest BIC on the fit
    /// data is named; the others are its rivals only when their BIC is within this margin of
    /// it (default 10: a likelihood ratio of about 10 at equal parameter counts). Near the
    /// noise floor the held-out NRMSEs of a right and a wrong effect differ by a few percent,
    /// while the fit data still tell them apart by hundreds.
    pub bic_margin: f64,
    /// The answer is `unexplained` when the best model's held-out residual stays above this
    /// many times the noise floor while its effect removes less than `min_explained` of the
    /// refit's error above the floor.
    pub unexplained_ratio: f64,
    /// See `unexplained_ratio`.
    pub min_explained: f64,
    /// Held-out NRMSE below which a model explains the data (the simulation's own accuracy
    /// on noise-free records: the input read between its samples, the integrator's
    /// tolerance): no effect is claimed and nothing is unexplained below it. Default 1e-4.
    pub resolution: f64,
    /// Most effects named together (forward selection stops there); at least 1.
    pub max_effects: usize,
    /// The measured input's own noise, read from its spectrum, is propagated through the
    /// refitted model into the noise floor unless white noise of that level would carry more
    /// than this share of the input's variance; 0 leaves it out. Default 0.1.
    pub input_noise_share: f64,
    /// The input's noise band is read as white noise only where its quarters' levels lie
    /// within this factor of each other, `>= 1`. Default 1.5.
    pub input_noise_flatness: f64,
    /// Band of the residual's (and the input's) spectrum whose level is the noise floor, as
    /// fractions of the Nyquist frequency, `0 < lo < hi <= 1`. Default (0.6, 0.95).
    pub noise_band: (f64, f64),
    /// A second effect is tried beside the best one while the best one's held-out residual
    /// stays above this many times the noise floor, `>= 1`: below it a second effect could
    /// not gain `min_gain`. Default 1.2.
    pub second_effect_floor_ratio: f64,
    /// A fit stops at a step that improves its likelihood ratio by less than this, `> 0`
    /// (default 0.01): a step worth less cannot change a test, and below it the simulations'
    /// own error (`rtol`) moves the cost as much as the parameters do.
    pub fit_tolerance: f64,
    /// Most iterations of the refit of the free parameters, `>= 1`. Default 200.
    pub max_iterations: usize,
    /// Most iterations of each candidate effect's fit, `>= 1`. Candidates start from the refit,
    /// and those that converge do so in 2 to 50 iterations on the shipped and the test
    /// records; one that has not converged by then creeps along a flat valley (a lag trading
    /// against the refitted parameters), each iteration a handful of simulations. It stops
    /// there, its score so far reported, and its note says so. Default 80.
    pub candidate_max_iterations: usize,
}

impl ModelFitOptions {
    /// The integrator of every simulation of the diagnosis: DOP853 at `rtol`, its absolute
    /// tolerance a hundredth of it.
    pub(crate) fn integrator(&self) -> htfid_hybrid::Options {
        htfid_hybrid::Options {
            rtol: self.rtol,
            atol: self.rtol * 1e-2,
            ..htfid_hybrid::Options::default()
        }
    }
}

impl Default for ModelFitOptions {
    fn default() -> Self {
        ModelFitOptions {
            free: Vec::new(),
            parameter_error: Vec::new(),
            fit_fraction: 0.7,
            burn_in: 2.0,
            significance_sigma: 5.0,
            min_gain: 0.05,
            rtol: 1e-8,
            effects: BoundaryEffect::ALL.to_vec(),
            terms: TermKind::ALL.to_vec(),
            user_terms: Vec::new(),
            alpha: 1e-4,
            rival_margin: 0.05,
            bic_margin: 10.0,
            unexplained_ratio: 5.0,
            min_explained: 0.999,
            resolution: 1e-4,
            max_effects: 3,
            input_noise_share: 0.1,
            input_noise_flatness: crate::noise::WHITE_SPREAD,
            noise_band: (0.6, 0.95),
            second_effect_floor_ratio: SECOND_EFFECT_FLOOR_RATIO,
            fit_tolerance: 0.01,
            max_iterations: 200,
            candidate_max_iterations: 80,
        }
    }
}

/// How well a simulation matches the record. In JSON it also holds `nrmse`, the mean held-out
/// NRMSE over the outputs ([`ModelScore::validation`]).
#[derive(Debug, Clone)]
pub struct ModelScore {
    /// Per output: RMS of (simulated - measured) over its standard deviation, on the fit part.
    pub nrmse_fit: Vec<f64>,
    /// Per output, on the held-out part.
    pub nrmse_validation: Vec<f64>,
    /// Per output: RMS error on the held-out part (output units).
    pub rmse_validation: Vec<f64>,
}

impl ModelScore {
    /// The mean held-out NRMSE over the outputs.
    pub fn validation(&self) -> f64 {
        self.nrmse_validation.iter().sum::<f64>() / self.nrmse_validation.len().max(1) as f64
    }
}

impl Serialize for ModelScore {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        let mut m = s.serialize_struct("ModelScore", 4)?;
        m.serialize_field("nrmse", &self.validation())?;
        m.serialize_field("nrmse_fit", &self.nrmse_fit)?;
        m.serialize_field("nrmse_validation", &self.nrmse_validation)?;
        m.serialize_field("rmse_validation", &self.rmse_validation)?;
        m.end()
    }
}

/// One refitted parameter.
#[derive(Debug, Clone, Serialize)]
pub struct ParameterChange {
    /// Its name.
    pub name: String,
    /// Its value as configured.
    pub configured: f64,
    /// Its refitted value.
    pub fitted: f64,
    /// Standard error of the refitted value, inflated for correlated residuals.
    pub stderr: f64,
    /// `(fitted - configured) / stderr`.
    pub z: f64,
}

/// The free parameters that the chosen effects leave off their configured values (the
/// extended fit's, `significance_sigma` standard errors or more away), and what setting them
/// back costs held out with the effects kept as fitted. When that costs `min_gain` or more,
/// `parameter_error` is named beside the effects (in `causes`).
#[derive(Debug, Clone, Serialize)]
pub struct ParametersBeside {
    /// The moved parameters, as fitted beside the effects.
    pub moved: Vec<ParameterChange>,
    /// Moved parameters that set the slope a chosen stiffness law leaves to the model: the
    /// law's linear part, not an error of theirs (not set back).
    pub excused: Vec<ParameterChange>,
    /// Held-out NRMSE (mean over the outputs) of the extended model with `moved` set back.
    pub nrmse_reset: f64,
    /// `1 - NRMSE_extended / nrmse_reset`.
    pub gain: f64,
    /// Whether it names a parameter error: some parameter moved and `gain >= min_gain`.
    pub named: bool,
}

/// What a diagnosis names (in JSON, its [`ModelCause::name`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ModelCause {
    /// An effect (on the boundary, or a term in the model's equations or guards; by its name)
    /// passes the likelihood-ratio test and improves the held-out error over the refit by at
    /// least `min_gain`, and no other explains the data as well.
    Effect(String),
    /// Two or more effects pass and fit equally well (`alternatives`).
    Ambiguous,
    /// Clear structure remains that neither the refit nor any effect tried explains.
    Unexplained,
    /// Some parameter moved significantly and the refit improves the held-out error by at
    /// least `min_gain`.
    ParameterError,
    /// Nothing: the configured model describes the data as well as a refit.
    None,
}

impl ModelCause {
    /// The name used in `diagnosis.json`.
    pub fn name(&self) -> &str {
        match self {
            ModelCause::Effect(e) => e,
            ModelCause::Ambiguous => "ambiguous",
            ModelCause::Unexplained => "unexplained",
            ModelCause::ParameterError => "parameter_error",
            ModelCause::None => "none",
        }
    }
}

impl Serialize for ModelCause {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

/// One effect fitted jointly with the free parameters.
#[derive(Debug, Clone, Serialize)]
pub struct ModelCandidate {
    /// The effect's name ([`BoundaryEffect::name`], or [`TermEffect::name`]).
    pub effect: String,
    /// For a term in the model's equations or guards: what it adds, where
    /// ([`TermEffect::describe`]); `null` for an effect on the boundary.
    pub term: Option<String>,
    /// The fitted free parameters and the effect's parameters, by name.
    pub parameters: std::collections::BTreeMap<String, f64>,
    /// Their standard errors, inflated for correlated residuals.
    pub stderr: std::collections::BTreeMap<String, f64>,
    /// Mean held-out NRMSE over the outputs (NaN, `null` in JSON, when the fit failed).
    pub nrmse_validation: f64,
    /// Held-out improvement over the refit without the effect.
    pub gain: f64,
    /// Bayesian information criterion of the fit that `nrmse_validation` scores, on the fit
    /// data: `N ln(RSS / N) + p ln N`, `N` the residuals, `p` the fitted parameters (the
    /// initial state excluded); lower is better (NaN, `null` in JSON, when the fit failed).
    pub bic: f64,
    /// Likelihood ratio against the refit, corrected for the residuals' correlation.
    pub likelihood_ratio: f64,
    /// The ratio it must reach (chi-square quantile at `alpha`, one degree per parameter).
    pub critical: f64,
    /// Whether both tests pass.
    pub significant: bool,
    /// Levenberg-Marquardt iterations of its fit (0 when it failed).
    pub iterations: usize,
    /// Why, in words; or why the fit failed.
    pub note: String,
}

impl ModelCandidate {
    fn failed(trial: &Trial, note: String) -> Self {
        ModelCandidate {
            effect: trial.name(),
            term: trial.describe(),
            parameters: Default::default(),
            stderr: Default::default(),
            nrmse_validation: f64::NAN,
            gain: f64::NAN,
            bic: f64::NAN,
            likelihood_ratio: f64::NAN,
            critical: f64::NAN,
            significant: false,
            iterations: 0,
            note,
        }
    }
}

/// The outcome.
#[derive(Debug, Clone, Serialize)]
pub struct ModelDiagnosis {
    /// What the diagnosis names.
    pub cause: ModelCause,
    /// The configured simulation's score (the baseline).
    pub configured: ModelScore,
    /// The refitted simulation's score.
    pub refitted: ModelScore,
    /// The final model's fitted parameters by name: the free parameters and the named
    /// effects' (the extended fit's), or the refit's free parameters when no effect is named.
    pub parameters: BTreeMap<String, f64>,
    /// Their standard errors, inflated for correlated residuals.
    pub stderr: BTreeMap<String, f64>,
    /// Held-out improvement of the final model over the refitted one:
    /// `1 - NRMSE_extended / NRMSE_refitted` (mean over outputs); 0 without an extended model.
    pub gain: f64,
    /// Held-out improvement of the final model over the configured simulation:
    /// `1 - NRMSE_final / NRMSE_configured` (mean over outputs).
    pub gain_vs_configured: f64,
    /// Every free parameter, refitted: configured and fitted values, standard error, `z`.
    pub refit_parameters: Vec<ParameterChange>,
    /// Held-out improvement of the refit over the configured simulation:
    /// `1 - NRMSE_refitted / NRMSE_configured` (mean over outputs).
    pub refit_gain: f64,
    /// Factor by which the residuals' correlation inflates the standard errors.
    pub stderr_inflation: f64,
    /// Levenberg-Marquardt iterations.
    pub iterations: usize,
    /// Why it stopped.
    pub stop: String,
    /// Every effect tried (on the boundary and inside the model), best held-out score first.
    pub candidates: Vec<ModelCandidate>,
    /// Every effect named, in the order chosen: the best single effect, then each one that
    /// passes beside those before it; last `parameter_error` when the free parameters beside
    /// them are off too ([`ParametersBeside`]). Only `parameter_error` when the refit of the
    /// free parameters is the answer; empty when nothing is named. Each with its parameters
    /// in the final fit and its share of the explained held-out error ([`Cause`]).
    pub causes: Vec<Cause>,
    /// Every other candidate refitted jointly with the best one (named `first + second`),
    /// best held-out score first; empty when nothing passes or the best one leaves the
    /// held-out residual within 1.2 times the noise floor.
    pub pairs: Vec<ModelCandidate>,
    /// The rounds after the pairs, one list per round: every candidate fitted beside the
    /// effects chosen before it (named `a + b + c`), best held-out score first.
    pub later_rounds: Vec<Vec<ModelCandidate>>,
    /// The backward pass over two or more chosen effects: each tested against the fit
    /// without it (its held-out score there, the likelihood ratio and the gain with it);
    /// `significant` false marks one that no longer passed (the weakest such was dropped).
    pub backward: Vec<ModelCandidate>,
    /// The chosen effects' fit, when the cause is an effect: the pair's when a second effect
    /// passed.
    pub extended: Option<ModelCandidate>,
    /// The free parameters beside the chosen effects, when some moved significantly: a
    /// `parameter_error` in `causes` when setting them back costs `min_gain` held out.
    pub parameters_beside: Option<ParametersBeside>,
    /// With `ambiguous`: the effects that fit equally well, the best first.
    pub alternatives: Vec<String>,
    /// Noise floor of the best model's residual on the fit data, in NRMSE units (the white
    /// noise level of its spectrum between 60 % and 95 % of the Nyquist frequency, with
    /// `input_noise`'s response added in quadrature).
    pub noise_floor: f64,
    /// The measured input's own noise, when it could be read from its spectrum: its level
    /// `sigma` in the input's units and the refitted model's RMS response to it, `propagated`,
    /// in NRMSE units (the root mean square over the outputs), which `noise_floor` includes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input_noise: Option<crate::InputNoise>,
    /// Share of the refit's held-out error above the noise floor that the chosen effect
    /// removes (0 without one).
    pub explained: f64,
    /// The refitted model's simulated outputs at every sample.
    #[serde(skip)]
    pub simulated: Vec<Vec<f64>>,
    /// The configured model's simulated outputs at every sample.
    #[serde(skip)]
    pub simulated_configured: Vec<Vec<f64>>,
    /// The extended model's simulated outputs (with the chosen effect), when there is one.
    #[serde(skip)]
    pub simulated_extended: Option<Vec<Vec<f64>>>,
    /// The term search outside the library, when it found terms that pass (it runs while
    /// clear structure remains and the cause is not a single library effect): a hint beside
    /// the cause, which it never changes.
    pub discovered: Option<ModelDiscovered>,
    /// What the term search found or why it proposed nothing; `None` when it did not run.
    pub term_search: Option<String>,
    /// Where the equations miss the data: for every output that reads a position state whose
    /// derivative is a velocity state, the measured acceleration minus the model's on the
    /// held-out data, binned against position, velocity and forcing phase, for the refitted
    /// and the final model ([`PairResidual`]); empty for a model without such a pair.
    pub residual_bins: Vec<PairResidual>,
}

/// The default [`ModelFitOptions::second_effect_floor_ratio`].
const SECOND_EFFECT_FLOOR_RATIO: f64 = 1.2;

/// Largest RMS error, in standard deviations of the measured output, of the configured model
/// simulated from its starting guess. A model in the right units misses by a few at most
/// (the start is not fitted yet); a thousand means a wrong unit or a wrong order of magnitude.
const MAX_CONFIGURED_NRMSE: f64 = 1e3;

/// Diagnoses `system` through its equations ([`Rhythmic::equations`]: a model-language
/// [`Model`] is its own, the built-in hopper writes its, a Rust user's model may write its
/// own), into which the candidate effects go as terms; every parameter, mode, guard and output
/// named below is theirs.
///
/// Refits the free parameters of the model to `rec` by output error and compares the configured
/// and refitted simulations on held-out data: the last `1 - fit_fraction` of `rec`, or the
/// whole of `validation` when a separate validation record is given (then all of `rec` is
/// fitted; on the validation record the initial state is fitted for each model with its
/// parameters fixed, as a comparison of simulations from measured data does).
///
/// The steps, each a function of its own: the configured simulation and the refit; every
/// candidate effect fitted beside the refit (the first round); the noise floor of the best
/// one's residual; further effects fitted jointly beside the chosen ones and the backward
/// pass; the decision; and, while clear structure remains, the term search outside the
/// library.
///
/// # Errors
/// [`DiagnoseError::InvalidOption`] for bad options or an unknown parameter,
/// [`DiagnoseError::Simulation`] when the configured model cannot be simulated on the record,
/// [`DiagnoseError::NominalFit`] when the refit fails, [`DiagnoseError::NoEquations`] for a
/// model without equations, [`DiagnoseError::Equations`] when they do not read and
/// [`DiagnoseError::EquationsDisagree`] when they are another system than the model (checked
/// before any fit, for a model with a forcing period).
pub fn diagnose_model<S: Rhythmic>(
    system: &S,
    rec: &TimeSeries,
    validation: Option<&TimeSeries>,
    opts: &ModelFitOptions,
) -> Result<ModelDiagnosis, DiagnoseError> {
    check_options(opts)?;
    let equations = system
        .equations()
        .ok_or(DiagnoseError::NoEquations)?
        .map_err(|e| DiagnoseError::Equations {
            reason: e.to_string(),
        })?;
    crate::equations::check_equations(system, &equations, rec, &opts.integrator())?;
    let model = &equations;
    let cut = match validation {
        Some(_) => rec.len(),
        None => ((rec.len() as f64) * opts.fit_fraction) as usize,
    };
    let est = Prepared::new(model, rec, cut, opts)?;
    let val = match validation {
        Some(v) => Some(Prepared::new(model, v, v.len(), opts)?),
        None => None,
    };
    let index: Vec<usize> = opts
        .free
        .iter()
        .map(|name| {
            model
                .parameter_index(name)
                .ok_or_else(|| DiagnoseError::InvalidParameterName {
                    option: "free",
                    parameter: name.clone(),
                    expected: "names of the model's parameters",
                })
        })
        .collect::<Result<_, _>>()?;
    for (i, name) in opts.parameter_error.iter().enumerate() {
        let expected = if model.parameter_index(name).is_none() {
            "names of the model's parameters"
        } else if opts.free.contains(name) {
            "parameters that are not free (a free one is refitted with every candidate)"
        } else if opts.parameter_error[..i].contains(name) {
            "each parameter once"
        } else {
            continue;
        };
        return Err(DiagnoseError::InvalidParameterName {
            option: "parameter_error",
            parameter: name.clone(),
            expected,
        });
    }
    let names: Vec<&str> = opts.free.iter().map(String::as_str).collect();
    let outputs: Vec<String> = model.outputs().iter().map(|o| o.name.clone()).collect();
    let joint = Joint {
        est: &est,
        model,
        names: &names,
        index: &index,
        scales: parameter_scales(model, &opts.free).collect(),
        max_iter: opts.max_iterations,
        ftol: opts.fit_tolerance / est.residual_len().max(1) as f64,
    };
    let refit = refit(&joint, val.as_ref(), cut, opts)?;
    let ideal = Boundary::default();

    // Every candidate effect, each fitted jointly with the free parameters and tested against
    // the refit. On the boundary, and inside the model: the library's terms at every site the
    // model offers, and the user's own.
    let samples = est.state_samples(&refit.model, &refit.base.state)?;
    let stats = samples.stats(&refit.model, &est.signal);
    let means: Vec<f64> = stats.iter().map(|s| s.mean).collect();
    let terms: Vec<TermEffect> = term_library(model, &opts.terms, &stats)
        .into_iter()
        .chain(opts.user_terms.iter().cloned())
        .collect();
    // The boundary effects' parameters take names the model and the terms leave free (`tau_2`
    // beside a model parameter `tau`), as the terms' own do.
    let mut taken: Vec<String> = terms.iter().flat_map(TermEffect::parameter_names).collect();
    let mut trials: Vec<Trial> = Vec::new();
    for &e in &opts.effects {
        let names: Vec<String> = e
            .parameter_names(&outputs)
            .iter()
            .map(|base| {
                let name = crate::term::fresh(model, &taken, base);
                taken.push(name.clone());
                name
            })
            .collect();
        trials.push(Trial::Boundary(e, names));
    }
    trials.extend(terms.into_iter().map(Trial::Term));
    if !opts.parameter_error.is_empty() {
        trials.push(Trial::Parameters(opts.parameter_error.clone()));
    }
    let aliases = selection::aliases(&trials, &refit.model, &samples, &opts.parameter_error);
    let sel = Selection {
        opts,
        est: &est,
        val: val.as_ref(),
        cut,
        joint: &joint,
        refitted_model: &refit.model,
        base: &refit.base,
        refitted: &refit.refitted,
        outputs: &outputs,
        trials: &trials,
        samples: &samples,
        aliases: &aliases,
    };
    let n = est.residual_len();
    let candidates = sel.first_round();
    let best = candidates.iter().position(|c| c.candidate.significant);
    // A significant rival within `rival_margin` of the best held-out score may explain the
    // data as well: of those, the lowest BIC on the fit data is named, and the others within
    // `bic_margin` of it are its rivals (the data cannot tell them apart).
    let (best, alternatives) = match best {
        Some(b) => {
            let (w, rivals) = rivals_by_bic(&candidates, b, n, opts);
            let names = rivals
                .iter()
                .map(|&i| candidates[i].candidate.effect.clone())
                .collect();
            (Some(w), names)
        }
        None => (None, Vec::new()),
    };
    // The noise floor of the best model's residual (scaled by each output's spread, so in
    // NRMSE units), from the band 60-95 % of the Nyquist frequency.
    let best_residuals = match best {
        Some(b) => &candidates[b].residuals,
        None => &refit.base.residuals,
    };
    let rows = est.rows.len().max(1);
    let per_output: Vec<&[f64]> = best_residuals.chunks(rows).collect();
    let reading_floor = crate::noise::noise_floor(&per_output, opts.noise_band).unwrap_or(f64::NAN);
    // A perfect model driven by a noisy input still leaves its response to that noise.
    let input_noise = est.input_noise(&refit.model, &refit.base.state, opts);
    let noise_floor = input_noise.map_or(reading_floor, |i| reading_floor.hypot(i.propagated));
    let best_score = best.map_or(refit.refitted.validation(), |b| {
        candidates[b].candidate.nrmse_validation
    });

    let forward = forward(
        &sel,
        &candidates,
        best,
        alternatives,
        best_score,
        noise_floor,
    );
    let mut current = forward.current;
    let mut alternatives = forward.alternatives;
    let earlier: Vec<&Tried> = candidates
        .iter()
        .chain(forward.pairs.iter())
        .chain(forward.later_rounds.iter().flatten())
        .collect();
    let backward = sel.backward(&mut current, &earlier);

    let final_score = current
        .as_ref()
        .map_or(best_score, |c| c.candidate.nrmse_validation);
    // The rivals were those of the first effect: gone with it when the backward pass dropped it.
    if current.as_ref().map(|c| c.set[0]) != forward.lead_before {
        alternatives.clear();
    }
    let decision = decide(
        current.as_ref(),
        &trials,
        &refit,
        final_score,
        noise_floor,
        alternatives,
        opts,
    );
    // Outside the library: a term search on the refitted model while clear structure remains
    // that no chosen effect accounts for (with an effect named, its own fit is the answer).
    let searched = decision.structure_left && !matches!(decision.cause, ModelCause::Effect(_));
    let (discovered, term_search) = if searched {
        let score =
            |m: &Model, x: &[f64]| score_on(&est, val.as_ref(), cut, m, x, &ideal).map(|(s, _)| s);
        let (found, sentence) = search::Search {
            est: &est,
            model: &refit.model,
            names: &names,
            scales: &joint.scales,
            base: &refit.base,
            samples: &samples,
            means: &means,
            refitted: &refit.refitted,
            score: &score,
            opts,
        }
        .run();
        (found, Some(sentence))
    } else {
        (None, None)
    };
    // A parameter error beside the effects: the refit's test, on the final fit.
    let parameters_beside = match &current {
        Some(c) if !matches!(decision.cause, ModelCause::Unexplained) => {
            sel.parameters_beside(c, &refit.parameters)?
        }
        _ => None,
    };
    let causes = causes::Named {
        current: current.as_ref(),
        trials: &trials,
        backward: &backward,
        refitted: refit.refitted.validation(),
        beside: parameters_beside.as_ref(),
        refit_alone: (current.is_none() && decision.cause == ModelCause::ParameterError)
            .then_some(refit.parameters.as_slice()),
        significance_sigma: opts.significance_sigma,
    }
    .causes();
    // The final model's parameters: the extended fit's, or the refit's free parameters.
    let (parameters, stderr): (BTreeMap<String, f64>, BTreeMap<String, f64>) = match &current {
        Some(c) => (c.candidate.parameters.clone(), c.candidate.stderr.clone()),
        None => (
            refit
                .parameters
                .iter()
                .map(|p| (p.name.clone(), p.fitted))
                .collect(),
            refit
                .parameters
                .iter()
                .map(|p| (p.name.clone(), p.stderr))
                .collect(),
        ),
    };
    let final_nrmse = current.as_ref().map_or(refit.refitted.validation(), |c| {
        c.candidate.nrmse_validation
    });
    let gain = current
        .as_ref()
        .map_or(0.0, |_| 1.0 - final_nrmse / refit.refitted.validation());
    let gain_vs_configured = 1.0 - final_nrmse / refit.configured.validation();
    // Where the equations miss the data, for the refitted and the final model: evidence, so a
    // model that cannot be realised or simulated for it leaves the bins out, not the answer.
    let realised = current.as_ref().and_then(|c| sel.realised(c).ok());
    let residual_bins = residual_bins::residual_bins(
        &est,
        val.as_ref(),
        cut,
        &residual_bins::Simulated {
            model: &refit.model,
            boundary: &ideal,
            x0: &refit.base.state,
        },
        match (&current, &realised) {
            (Some(c), Some((m, b))) => Some(residual_bins::Simulated {
                model: m,
                boundary: b,
                x0: &c.state,
            }),
            _ => None,
        }
        .as_ref(),
    )
    .unwrap_or_default();
    let (extended, simulated_extended) = match current {
        Some(mut c) => {
            let sim = c.simulated.take();
            (Some(c.candidate), sim)
        }
        None => (None, None),
    };
    Ok(ModelDiagnosis {
        cause: decision.cause,
        configured: refit.configured,
        refitted: refit.refitted,
        parameters,
        stderr,
        gain,
        gain_vs_configured,
        refit_parameters: refit.parameters,
        refit_gain: refit.gain,
        stderr_inflation: refit.inflation,
        iterations: refit.base.iterations,
        stop: refit.base.stop,
        candidates: candidates.into_iter().map(|c| c.candidate).collect(),
        causes,
        pairs: forward.pairs.into_iter().map(|c| c.candidate).collect(),
        later_rounds: forward
            .later_rounds
            .into_iter()
            .map(|r| r.into_iter().map(|c| c.candidate).collect())
            .collect(),
        backward,
        extended,
        parameters_beside,
        alternatives: decision.alternatives,
        noise_floor,
        input_noise,
        explained: decision.explained,
        simulated: refit.simulated,
        simulated_configured: refit.simulated_configured,
        simulated_extended,
        discovered,
        term_search,
        residual_bins,
    })
}

/// The options' ranges, checked before any work.
fn check_options(opts: &ModelFitOptions) -> Result<(), DiagnoseError> {
    if !(0.1..=0.95).contains(&opts.fit_fraction) {
        return Err(DiagnoseError::InvalidOption {
            name: "fit_fraction",
            expected: "in [0.1, 0.95]",
            value: opts.fit_fraction,
        });
    }
    if opts.max_effects == 0 {
        return Err(DiagnoseError::InvalidOption {
            name: "max_effects",
            expected: ">= 1",
            value: 0.0,
        });
    }
    crate::noise::check_reading(opts.noise_band, opts.input_noise_flatness)?;
    if !(opts.second_effect_floor_ratio.is_finite() && opts.second_effect_floor_ratio >= 1.0) {
        return Err(DiagnoseError::InvalidOption {
            name: "second_effect_floor_ratio",
            expected: ">= 1 and finite",
            value: opts.second_effect_floor_ratio,
        });
    }
    if !(opts.fit_tolerance.is_finite() && opts.fit_tolerance > 0.0) {
        return Err(DiagnoseError::InvalidOption {
            name: "fit_tolerance",
            expected: "> 0 and finite",
            value: opts.fit_tolerance,
        });
    }
    for (name, v) in [
        ("max_iterations", opts.max_iterations),
        ("candidate_max_iterations", opts.candidate_max_iterations),
    ] {
        if v == 0 {
            return Err(DiagnoseError::InvalidOption {
                name,
                expected: ">= 1",
                value: 0.0,
            });
        }
    }
    Ok(())
}

/// The configured simulation (the baseline) and the refit of the free parameters.
struct Refit {
    /// The configured model's score and simulation.
    configured: ModelScore,
    simulated_configured: Vec<Vec<f64>>,
    /// The refit: its fit, its model, its score and simulation.
    base: JointFit,
    model: Model,
    refitted: ModelScore,
    simulated: Vec<Vec<f64>>,
    /// Every free parameter, configured and refitted.
    parameters: Vec<ParameterChange>,
    /// Held-out improvement of the refit over the configured simulation.
    gain: f64,
    /// Some parameter moved by `significance_sigma` standard errors or more.
    moved: bool,
    /// The refit's standard-error inflation for correlated residuals.
    inflation: f64,
}

/// Why the configured model, simulated from its fitted initial state, does not describe the
/// fitted samples at all ([`Agreement::plain`]): an output that moves against the measured
/// one, or one of the measured shape at a spread off by a unit's factor.
fn mismatch_reasons(est: &Prepared<'_>, model: &Model, simulated: &[Vec<f64>]) -> Vec<String> {
    let mut reasons = Vec::new();
    for (o, (measured, sim)) in est.rec.outputs().iter().zip(simulated).enumerate() {
        let name = &model.outputs()[o].name;
        let rows = est.rows.clone();
        let Some(a) = Agreement::of(&measured[rows.clone()], &sim[rows]) else {
            continue;
        };
        match a.plain() {
            None => {}
            Some(Plain::Sign) => reasons.push(format!(
                "sign: the measured {name} moves against the configured model's (regression \
                 gain {:.3}, correlation {:.3}); check the sign of the {name} column or of the \
                 input, and, for a model with a periodic forcing, that the time column's zero \
                 is the forcing's phase 0",
                a.gain, a.correlation
            )),
            Some(Plain::Units) => reasons.push(format!(
                "units: the measured {name} varies {} times as much as the configured model's, \
                 with its shape (correlation {:.3}); check the units of the {name} and input \
                 columns (mm against m, mN against N), or start the parameters nearer the data",
                htfid_number::sig(a.scale, 3),
                a.correlation
            )),
        }
    }
    reasons
}

/// The configured simulation and the refit of `joint`'s free parameters (and the initial
/// state) alone, scored as [`score_on`] scores. A configured model off by orders of
/// magnitude is refused before the fits, which would spend hundreds of simulations on it.
fn refit(
    joint: &Joint<'_, '_>,
    val: Option<&Prepared<'_>>,
    cut: usize,
    opts: &ModelFitOptions,
) -> Result<Refit, DiagnoseError> {
    let (est, model) = (joint.est, joint.model);
    let ideal = Boundary::default();
    let first = est.simulate(model, &est.guess, &ideal)?;
    let (_, nrmse) = est.errors(&first, est.rows.clone());
    if let Some((o, &q)) = nrmse
        .iter()
        .enumerate()
        .find(|(_, q)| q.is_nan() || **q > MAX_CONFIGURED_NRMSE)
    {
        return Err(DiagnoseError::ScaleMismatch {
            output: model.outputs()[o].name.clone(),
            nrmse: q,
            limit: MAX_CONFIGURED_NRMSE,
        });
    }
    let x_configured = est.fit_state(model, &est.guess, &ideal)?;
    let (configured, simulated_configured) = score_on(est, val, cut, model, &x_configured, &ideal)?;
    // The check reads the fitted samples: with a separate held-out record the shown
    // simulation is that record's, so the estimation record is simulated for it.
    let reasons = match val {
        None => mismatch_reasons(est, model, &simulated_configured),
        Some(_) => mismatch_reasons(est, model, &est.simulate(model, &x_configured, &ideal)?),
    };
    if !reasons.is_empty() {
        return Err(DiagnoseError::ModelMismatch { reasons });
    }
    let base = joint.fit(&[], &[], &x_configured)?;
    let k = joint.index.len();
    let refitted_model = joint.model_at(&base.params[..k])?;
    let (refitted, simulated) = score_on(est, val, cut, &refitted_model, &base.state, &ideal)?;
    let inflation = correlation_inflation(&base.residuals);
    let p0: Vec<f64> = joint.index.iter().map(|&i| model.values()[i]).collect();
    let parameters: Vec<ParameterChange> = joint
        .names
        .iter()
        .enumerate()
        .map(|(j, name)| {
            let stderr = base.stderr[j] * inflation;
            ParameterChange {
                name: (*name).to_string(),
                configured: p0[j],
                fitted: base.params[j],
                stderr,
                z: (base.params[j] - p0[j]) / stderr,
            }
        })
        .collect();
    let gain = if k == 0 {
        0.0
    } else {
        1.0 - refitted.validation() / configured.validation()
    };
    let moved = parameters
        .iter()
        .any(|p| p.z.abs() >= opts.significance_sigma);
    Ok(Refit {
        configured,
        simulated_configured,
        base,
        model: refitted_model,
        refitted,
        simulated,
        parameters,
        gain,
        moved,
        inflation,
    })
}

/// What the forward selection chose after the first round.
struct Forward {
    /// Every other candidate fitted beside the best one (and beside its rivals).
    pairs: Vec<Tried>,
    /// The rounds after the pairs.
    later_rounds: Vec<Vec<Tried>>,
    /// The effects chosen and their joint fit.
    current: Option<Tried>,
    /// The rivals of the first chosen effect.
    alternatives: Vec<String>,
    /// The first chosen effect before the backward pass.
    lead_before: Option<usize>,
}

/// Further effects beside the best one (forward selection), while the chosen effects leave
/// the held-out residual clearly above the noise floor (`second_effect_floor_ratio` times
/// it). In the second round the best effect's rivals, and every significant effect within
/// `rival_margin` of it held out however their fits compare, are tried as the first effect
/// too: beside a second effect, the right one of two look-alikes fits clearly better (an
/// actuator lag beside a constant force, where a sensor lag alone fits a little better). So is
/// the runner-up, the best significant effect not among them.
fn forward(
    sel: &Selection<'_, '_>,
    candidates: &[Tried],
    best: Option<usize>,
    alternatives: Vec<String>,
    best_score: f64,
    noise_floor: f64,
) -> Forward {
    let opts = sel.opts;
    let n = sel.est.residual_len();
    let by_score = |a: &Tried, b: &Tried| {
        a.candidate
            .nrmse_validation
            .total_cmp(&b.candidate.nrmse_validation)
    };
    let room = |score: f64| {
        noise_floor.is_finite() && score > opts.second_effect_floor_ratio * noise_floor
    };
    let mut pairs: Vec<Tried> = Vec::new();
    let firsts: Vec<usize> = match best {
        Some(b) if room(best_score) && opts.max_effects >= 2 => {
            let mut firsts: Vec<usize> = std::iter::once(b)
                .chain((0..candidates.len()).filter(|&i| {
                    let c = &candidates[i].candidate;
                    i != b
                        && (alternatives.contains(&c.effect)
                            || (c.significant
                                && c.nrmse_validation <= best_score * (1.0 + opts.rival_margin)))
                }))
                .collect();
            // The runner-up too, however far behind: the first pick decides the most, and
            // an effect that stands in for two (drag for damping in flight beside a moved
            // switch) can win alone while the pair it stands in for fits better.
            let runner_up = (0..candidates.len())
                .filter(|i| !firsts.contains(i) && candidates[*i].candidate.significant)
                .min_by(|&i, &j| by_score(&candidates[i], &candidates[j]));
            firsts.extend(runner_up);
            firsts
        }
        _ => Vec::new(),
    };
    for &b in &firsts {
        pairs.extend(sel.round(&candidates[b]));
    }
    pairs.sort_by(by_score);
    let second = pairs.iter().position(|p| p.candidate.significant);
    // With a pair, its first effect is the cause; the first effects of other passing pairs
    // within `rival_margin` of it held out and `bic_margin` on the fit data are its rivals
    // (of those within `rival_margin`, the lowest BIC is named, as in the first round).
    let (second, alternatives): (Option<usize>, Vec<String>) = match second {
        Some(s) => {
            let (w, rival_pairs) = rivals_by_bic(&pairs, s, n, opts);
            let lead = sel.trials[pairs[w].set[0]].name();
            let mut rivals: Vec<String> = Vec::new();
            for i in rival_pairs {
                let name = sel.trials[pairs[i].set[0]].name();
                if name != lead && !rivals.contains(&name) {
                    rivals.push(name);
                }
            }
            (Some(w), rivals)
        }
        None => (None, alternatives),
    };
    // The effects chosen so far and their joint fit.
    let mut current: Option<Tried> = match (second, best) {
        (Some(s), _) => Some(pairs[s].clone()),
        (None, Some(b)) => Some(candidates[b].clone()),
        (None, None) => None,
    };
    let lead_before = current.as_ref().map(|c| c.set[0]);
    // Rounds three onwards.
    let mut later_rounds: Vec<Vec<Tried>> = Vec::new();
    if second.is_some() {
        while let Some(cur) = current
            .as_ref()
            .filter(|c| c.set.len() < opts.max_effects && room(c.candidate.nrmse_validation))
        {
            let mut tried = sel.round(cur);
            tried.sort_by(by_score);
            let next = tried.iter().position(|t| t.candidate.significant);
            let chosen = next.map(|i| tried[i].clone());
            later_rounds.push(tried);
            match chosen {
                Some(c) => current = Some(c),
                None => break,
            }
        }
    }
    Forward {
        pairs,
        later_rounds,
        current,
        alternatives,
        lead_before,
    }
}

/// The answer and the numbers behind it.
struct Decision {
    cause: ModelCause,
    alternatives: Vec<String>,
    /// Share of the refit's held-out error above the noise floor that the chosen effects
    /// remove.
    explained: f64,
    /// The final held-out residual stays above `unexplained_ratio` times the noise floor (and
    /// above the resolution).
    structure_left: bool,
}

/// The cause named for the chosen effects `current` (their held-out score `final_score`),
/// with the first effect's rivals `alternatives`.
fn decide(
    current: Option<&Tried>,
    trials: &[Trial],
    refit: &Refit,
    final_score: f64,
    noise_floor: f64,
    mut alternatives: Vec<String>,
    opts: &ModelFitOptions,
) -> Decision {
    let floor2 = noise_floor * noise_floor;
    let explained = if current.is_some() {
        1.0 - (final_score.powi(2) - floor2).max(0.0)
            / (refit.refitted.validation().powi(2) - floor2).max(f64::MIN_POSITIVE)
    } else {
        0.0
    };
    let structure_left = noise_floor.is_finite()
        && final_score > opts.unexplained_ratio * noise_floor
        && final_score > opts.resolution;
    let lead = current.map(|c| &trials[c.set[0]]);
    let cause = match lead {
        _ if structure_left && explained < opts.min_explained => ModelCause::Unexplained,
        Some(_) if !alternatives.is_empty() => ModelCause::Ambiguous,
        Some(Trial::Parameters(_)) => ModelCause::ParameterError,
        Some(trial) => ModelCause::Effect(trial.name()),
        None if refit.moved && refit.gain >= opts.min_gain => ModelCause::ParameterError,
        None => ModelCause::None,
    };
    if let (ModelCause::Ambiguous, Some(trial)) = (&cause, lead) {
        alternatives.insert(0, trial.name());
    }
    Decision {
        cause,
        alternatives,
        explained,
        structure_left,
    }
}
