//! What a diagnosis returns: scores, candidates, causes and the report.

use std::collections::BTreeMap;
use std::ops::Range;

use htfid_model::{DamperLaw, Effects, HopperParams};
use serde::{Deserialize, Serialize};

use crate::discover::Discovered;
use crate::Sensor;

/// A model's simulation error on a set of samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Score {
    /// `rmse / std(measured x)` over the same samples.
    pub nrmse: f64,
    /// Root-mean-square of `simulated x - measured x` (m).
    pub rmse: f64,
}

impl Score {
    /// A score that could not be computed.
    pub fn unknown() -> Score {
        Score {
            nrmse: f64::NAN,
            rmse: f64::NAN,
        }
    }
}

/// One candidate effect, fitted and judged.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Effect name ([`Effect::name`](crate::Effect::name)).
    pub effect: String,
    /// Fitted effect parameters and refitted nominal parameters, by name.
    pub parameters: BTreeMap<String, f64>,
    /// Their standard errors (allowing for correlated residuals; infinite, `null` in JSON,
    /// when the data do not determine the parameter).
    pub stderr: BTreeMap<String, f64>,
    /// NRMSE on the held-out ranges (NaN, `null` in JSON, when not fitted).
    pub nrmse_validation: f64,
    /// RMSE on the held-out ranges (m; NaN when not fitted).
    pub rmse_validation: f64,
    /// BIC on the fit ranges (NaN when not fitted).
    pub bic: f64,
    /// Whether the candidate passed every significance test (see the crate docs).
    pub significant: bool,
    /// Why it is (not) significant, or why it was skipped.
    pub note: String,
    /// How many starting points were fitted (a threshold's two signs, contact positions, lags
    /// across decades; 0 when skipped).
    #[serde(default)]
    pub starts: usize,
    /// The effect's parameters at the start whose fit won (empty when skipped).
    #[serde(default)]
    pub best_start: BTreeMap<String, f64>,
}

/// The answer: the named cause, the extended model's parameters and the measured gain.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Diagnosis {
    /// The winning effect's name, `none` (the nominal model explains the data to the noise
    /// floor or no candidate is significant while the residual is at the noise floor) or
    /// `unexplained` (clear residual structure that no single library effect explains).
    pub cause: String,
    /// Parameters of the extended model (effect parameters and refitted nominal parameters);
    /// for `none` and `unexplained`, the refitted nominal parameters.
    pub parameters: BTreeMap<String, f64>,
    /// Standard errors of `parameters`.
    pub stderr: BTreeMap<String, f64>,
    /// The nominal model's (with `free` refitted) held-out score.
    pub nominal: Score,
    /// The extended model's held-out score (equal to `nominal` without a winner).
    pub extended: Score,
    /// `1 - extended.rmse / nominal.rmse` on the held-out data.
    pub gain: f64,
    /// Every candidate of the first round (each against the nominal fit), best held-out RMSE
    /// first; skipped and failed ones last.
    pub candidates: Vec<Candidate>,
    /// Sentences explaining the decision.
    pub evidence: Vec<String>,
    /// Every effect the selection kept, strongest first (empty for `none` and
    /// `model_mismatch`). With `unexplained` they are real but leave structure unexplained.
    #[serde(default)]
    pub causes: Vec<Cause>,
    /// With `ambiguous`: every effect the data cannot tell apart from the first cause.
    #[serde(default)]
    pub alternatives: Vec<String>,
    /// The held-out score of the model exactly as configured (nothing refitted).
    #[serde(default = "Score::unknown")]
    pub configured: Score,
    /// `1 - extended.rmse / configured.rmse` on the held-out data.
    #[serde(default)]
    pub gain_vs_configured: f64,
    /// With `model_mismatch`: why the model does not describe the data at all.
    #[serde(default)]
    pub mismatch: Vec<String>,
    /// A formula found outside the library by the sparse term search on the final model's
    /// residual ([`Discovered`]), when clear structure remained and the formula, refitted by
    /// output error, predicts the held-out data at least `min_gain` better. A hint beside
    /// the cause, never a cause: absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub discovered: Option<Discovered>,
    /// Where the answer holds a switching threshold among the speed's extremes, judged on
    /// held-out windows of two natural periods (the whole held-out simulation parts from the
    /// data however right the threshold): the refitted nominal's and the final model's RMS
    /// errors on those windows. Absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub held_out_on_windows: Option<WindowScore>,
}

/// Held-out RMS errors on windows a few periods long, each simulated from the data's smoothed
/// state with that state's error projected out.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WindowScore {
    /// The refitted nominal model's RMS error on the windows.
    pub nominal_rmse: f64,
    /// The final model's.
    pub extended_rmse: f64,
    /// `1 - extended_rmse / nominal_rmse`.
    pub gain: f64,
}

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

/// A fitted model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FittedModel {
    /// Parameters (the forcing amplitude is zero: the force is the measured one).
    pub params: HopperParams,
    /// Damper law.
    pub damper: DamperLaw,
    /// Effects, including any fitted one.
    pub effects: Effects,
    /// The measurement chain (the ideal sensor unless a sensor effect was found).
    pub sensor: Sensor,
}

/// The measured input's own noise, as it enters the noise floor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct InputNoise {
    /// Standard deviation of the input's white noise, in the input's units: the level of its
    /// spectrum in the noise band.
    pub sigma: f64,
    /// RMS response of the model to white noise of that level: the refitted nominal's, in the
    /// output's units ([`DiagnosisReport::input_noise`]); the refitted model's, in NRMSE units,
    /// in the model-file diagnosis.
    pub propagated: f64,
}

/// [`Diagnosis`] plus what a caller needs to plot and check it.
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnosisReport {
    /// The diagnosis (the JSON part).
    pub diagnosis: Diagnosis,
    /// The nominal model with its free parameters refitted.
    pub nominal_model: FittedModel,
    /// The extended (winning) model; the nominal fit when there is no winner.
    pub extended_model: FittedModel,
    /// Simulated position of the nominal fit at every sample of the fit and validation ranges
    /// (each range simulated from its own initial state, burn-in included); NaN elsewhere.
    pub nominal_output: Vec<f64>,
    /// The same for the extended model.
    pub extended_output: Vec<f64>,
    /// The nominal fit's score on the fit ranges.
    pub nominal_fit_score: Score,
    /// Noise floor (m) estimated from the nominal residual spectrum, with the response to the
    /// input's noise added in quadrature where it was read (`input_noise`); `None` when the
    /// ranges are too short for it (64 samples).
    pub noise_floor: Option<f64>,
    /// The measured input's noise and the model's response to it, which the noise floor
    /// includes (`noise_floor^2` is the reading's floor squared plus `propagated^2`); `None`
    /// where the input's noise cannot be told from the input
    /// ([`DiagnoseOptions::input_noise_share`](crate::DiagnoseOptions::input_noise_share)).
    pub input_noise: Option<InputNoise>,
    /// Burn-in used (s).
    pub burn_in_s: f64,
    /// Fit ranges used.
    pub fit_ranges: Vec<Range<usize>>,
    /// Validation ranges used.
    pub validation_ranges: Vec<Range<usize>>,
    /// Residual evaluations (simulations of all fit ranges) spent by the Levenberg-Marquardt
    /// iterations of all fits; the final Jacobians for the standard errors, the screening and
    /// the scoring come on top. A work counter for spotting regressions in effort.
    pub evaluations: usize,
}
