//! The diagnosis: nominal fit, candidate fits, held-out scores and the decision.

use htfid_number::{percent, sig, Quantity};
use std::collections::BTreeMap;
use std::ops::Range;

use htfid_model::{DamperLaw, Effects, HopperParams};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::deriv::{local_fit, window_half_width};
use crate::discover::{self, Discovered};
use crate::effect::Slot;
use crate::fit::{Context, Driven, FitResult, ModelPoint, Scales, Segment};
use crate::interp::Interpolation;
use crate::noise::noise_floor;
use crate::screen::Screening;
use crate::select;
use crate::sim::{Extent, MeasuredForce, SimMethod, Stepping};
use crate::{DiagnoseError, Effect, NominalModel, Sensor, TimeSeries};

/// Fewest scored samples a range must keep after the burn-in.
const MIN_SCORED: usize = 16;

/// Settings of [`diagnose`]. Every field has a default ([`DiagnoseOptions::default`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DiagnoseOptions {
    /// Sample-index ranges (0-based, end exclusive) the models are fitted on. Empty: the first
    /// 70 % of the record.
    pub fit: Vec<Range<usize>>,
    /// Held-out sample-index ranges the models are judged on; must not overlap `fit`. Empty:
    /// the last 30 % of the record.
    pub validation: Vec<Range<usize>>,
    /// Time (s) at the start of every range that is simulated but left out of costs and
    /// scores, so the transient from the estimated initial state dies out. `None`: four decay
    /// times `2 m / c` of the nominal model (with `c` halved for the switching damper, which
    /// is on about half the time), at most a quarter of the shortest range.
    pub burn_in_s: Option<f64>,
    /// The effects tried. Default: the whole library, [`Effect::ALL`].
    pub candidates: Vec<Effect>,
    /// A refitted free parameter of the nominal model that lies this many standard errors from
    /// its configured value is a `parameter_error` finding, `> 0`. Default 5.
    pub significance_sigma: f64,
    /// Smallest relative reduction of the held-out error, `1 - rmse_after / rmse_before`, for
    /// an effect to be added (and for a refit of the configured parameters to count), in
    /// `[0, 1)`. Default 0.05.
    pub min_gain: f64,
    /// Evidence margin in BIC units: first-round candidates whose fits lie within this margin
    /// of the best one's (and are not nested in it) are its rivals, and the answer is
    /// `ambiguous` unless the selection adds them too, `>= 0`. Default 10 ("very strong" on
    /// Kass and Raftery's scale).
    pub bic_margin: f64,
    /// A held-out RMSE above this multiple of the noise floor is "clear residual structure",
    /// `>= 1`. Default 5 (effects in the library fitted to data they describe leave about 1 to
    /// 1.5 times the floor; effects outside it mimicked by library ones, 4 to 80 times).
    pub unexplained_ratio: f64,
    /// Fraction of the nominal's excess error (above the noise floor, in mean square) the
    /// selected effects must remove when their residual is still above `unexplained_ratio`
    /// times the noise floor; otherwise the answer is `unexplained`, in `[0, 1]`. Default
    /// 0.999 (a residual 3 % of the nominal's, in RMS).
    pub min_explained: f64,
    /// How the measured force is read between samples. Default: cubic spline.
    pub interpolation: Interpolation,
    /// How models are simulated. Default: fixed-step RK4 with `max_rate_step = 0.2`.
    pub sim: SimMethod,
    /// Fit the position and velocity at the start of every fit range (two extra parameters per
    /// range, starting from the data's estimate) instead of keeping the data's estimate. Default
    /// `true`: at a record's first sample the estimate is one-sided and can be biased enough
    /// to leave a transient longer than the burn-in. Validation ranges always start from the
    /// data's estimate.
    pub fit_initial_state: bool,
    /// Most Levenberg-Marquardt iterations per fit, `>= 1`. Default 40.
    pub max_iterations: usize,
    /// A fit ends when a step improves the fit by less than this in likelihood-ratio units,
    /// `n ln(rss_before / rss_after)` with `n` the fitted samples, `> 0`. Default 0.01: a
    /// hundredth of a unit of log-likelihood on the scale where an effect needs a ratio near 15
    /// to be added, so a fit that stops here decides as the exact optimum would, and a
    /// parameter creeping towards a bound (a lag shrinking on a log scale, 1e-6 of the cost per
    /// step) stops instead of using every iteration.
    pub fit_tolerance: f64,
    /// Band of the residual spectrum whose level is the noise floor, as fractions of the
    /// Nyquist frequency, `0 < lo < hi <= 1`. Default (0.6, 0.95).
    pub noise_band: (f64, f64),
    /// Level of the nested-model test that admits an effect (the probability that an absent
    /// effect passes it on white residuals), in `(0, 0.5)`. Default 1e-4.
    pub alpha: f64,
    /// Most effects named together, `>= 1`. Default 3.
    pub max_effects: usize,
    /// Resolution of the simulation relative to the spread of the measured output, `>= 0`:
    /// the noise floor used by the decision is never below `resolution * std(x)`. The force is
    /// known only at its samples, and its interpolation alone leaves simulated outputs in
    /// error by about this much on the paper's protocol, so a residual this small is not
    /// evidence of structure. Default 1e-4.
    pub resolution: f64,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        DiagnoseOptions {
            fit: Vec::new(),
            validation: Vec::new(),
            burn_in_s: None,
            candidates: Effect::ALL.to_vec(),
            significance_sigma: 5.0,
            min_gain: 0.05,
            bic_margin: 10.0,
            unexplained_ratio: 5.0,
            min_explained: 0.999,
            interpolation: Interpolation::default(),
            sim: SimMethod::default(),
            fit_initial_state: true,
            max_iterations: 40,
            fit_tolerance: 0.01,
            noise_band: (0.6, 0.95),
            alpha: 1e-4,
            max_effects: 3,
            resolution: 1e-4,
        }
    }
}

impl DiagnoseOptions {
    /// Checks every range-free option; ranges are checked against the record in [`diagnose`].
    pub fn validate(&self) -> Result<(), DiagnoseError> {
        let bad = |name, expected, value| {
            Err(DiagnoseError::InvalidOption {
                name,
                expected,
                value,
            })
        };
        if let Some(b) = self.burn_in_s {
            if !(b.is_finite() && b >= 0.0) {
                return bad("burn_in_s", ">= 0 and finite", b);
            }
        }
        if !(self.significance_sigma.is_finite() && self.significance_sigma > 0.0) {
            return bad(
                "significance_sigma",
                "> 0 and finite",
                self.significance_sigma,
            );
        }
        if !(self.min_gain >= 0.0 && self.min_gain < 1.0) {
            return bad("min_gain", "in [0, 1)", self.min_gain);
        }
        if !(self.bic_margin.is_finite() && self.bic_margin >= 0.0) {
            return bad("bic_margin", ">= 0 and finite", self.bic_margin);
        }
        if !(self.unexplained_ratio.is_finite() && self.unexplained_ratio >= 1.0) {
            return bad(
                "unexplained_ratio",
                ">= 1 and finite",
                self.unexplained_ratio,
            );
        }
        if !(0.0..=1.0).contains(&self.min_explained) {
            return bad("min_explained", "in [0, 1]", self.min_explained);
        }
        if self.max_iterations == 0 {
            return bad("max_iterations", ">= 1", 0.0);
        }
        if !(self.fit_tolerance.is_finite() && self.fit_tolerance > 0.0) {
            return bad("fit_tolerance", "> 0 and finite", self.fit_tolerance);
        }
        if !(self.alpha > 0.0 && self.alpha < 0.5) {
            return bad("alpha", "in (0, 0.5)", self.alpha);
        }
        if !(self.resolution.is_finite() && self.resolution >= 0.0) {
            return bad("resolution", ">= 0 and finite", self.resolution);
        }
        if self.max_effects == 0 {
            return bad("max_effects", ">= 1", 0.0);
        }
        let (lo, hi) = self.noise_band;
        if !(lo > 0.0 && lo < hi) {
            return bad("noise_band.0", "> 0 and below noise_band.1", lo);
        }
        if hi.is_nan() || hi > 1.0 {
            return bad("noise_band.1", "<= 1", hi);
        }
        match self.sim {
            SimMethod::FixedStep { max_rate_step } => {
                if !(max_rate_step.is_finite() && max_rate_step > 0.0) {
                    return bad("sim.max_rate_step", "> 0 and finite", max_rate_step);
                }
            }
            SimMethod::Adaptive { rtol } => {
                if !(rtol.is_finite() && rtol > 0.0) {
                    return bad("sim.rtol", "> 0 and finite", rtol);
                }
            }
        }
        for (i, e) in self.candidates.iter().enumerate() {
            if self.candidates[..i].contains(e) {
                return Err(DiagnoseError::DuplicateCandidate { name: e.name() });
            }
        }
        Ok(())
    }
}

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
    /// Effect name ([`Effect::name`]).
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
    /// Noise floor (m) estimated from the nominal residual spectrum; `None` when the ranges
    /// are too short for it (64 samples).
    pub noise_floor: Option<f64>,
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

/// Diagnoses `record` against `nominal`; see the crate docs for the method and the decision
/// rule.
pub fn diagnose(
    record: &TimeSeries,
    nominal: &NominalModel,
    opts: &DiagnoseOptions,
) -> Result<DiagnosisReport, DiagnoseError> {
    diagnose_with_progress(record, nominal, opts, &|_| {})
}

/// [`diagnose`] reporting progress as short sentences (called from worker threads).
pub fn diagnose_with_progress(
    record: &TimeSeries,
    nominal: &NominalModel,
    opts: &DiagnoseOptions,
    progress: &(dyn Fn(&str) + Sync),
) -> Result<DiagnosisReport, DiagnoseError> {
    nominal.validate()?;
    opts.validate()?;
    crate::record::check_length(record.len())?;
    let n = record.len();
    let dt = record.dt();
    let (fit_ranges, val_ranges) = resolve_ranges(opts, n)?;
    for (which, ranges) in [("fit", &fit_ranges), ("validation", &val_ranges)] {
        crate::record::check_varies(record.output(), ranges, which)?;
    }
    let free = nominal.free_slots();
    let start = ModelPoint {
        params: nominal.measured_params(),
        effects: nominal.effects,
        sensor: nominal.sensor,
    };

    let f_n = (start.params.k / start.params.m).sqrt() / (2.0 * std::f64::consts::PI);
    let half = window_half_width(f_n, dt);
    let burn_in_s = match opts.burn_in_s {
        Some(b) => b,
        None => auto_burn_in(nominal, &fit_ranges, &val_ranges, dt),
    };
    let skip = (burn_in_s / dt - 1e-9).ceil().max(0.0) as usize;
    let init_half = init_half_width(f_n, dt);
    let fit = segments(record, &fit_ranges, skip, init_half, "fit", burn_in_s)?;
    let validation = segments(
        record,
        &val_ranges,
        skip,
        init_half,
        "validation",
        burn_in_s,
    )?;

    let x = record.output();
    let x_min = x.iter().copied().fold(f64::INFINITY, f64::min);
    let x_max = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mut ctx = Context {
        record,
        input: MeasuredForce::new(record.time()[0], dt, record.input(), opts.interpolation),
        damper: nominal.damper,
        method: opts.sim,
        extent: Extent {
            x_min,
            x_max,
            v_max: 0.0,
        },
        scales: Scales {
            x_std: positive_or(std_dev(x), 1.0),
            v_std: 1.0,
            f_std: positive_or(std_dev(record.input()), 1.0),
        },
        fit,
        validation,
        fit_initial_state: opts.fit_initial_state,
        max_iterations: opts.max_iterations,
        fit_tolerance: opts.fit_tolerance,
        forcing_period: (nominal.params.forcing_amplitude != 0.0).then_some(nominal.params.period),
    };
    let screening = Screening::new(&ctx, half);
    let v: Vec<f64> = screening.samples().iter().map(|(_, k)| k.v).collect();
    let v_max = v.iter().fold(0.0_f64, |a, b| a.max(b.abs()));
    let v_std = positive_or(
        std_dev(&v),
        ctx.scales.x_std * 2.0 * std::f64::consts::PI * f_n,
    );
    drop(screening);
    ctx.extent.v_max = v_max;
    ctx.scales.v_std = v_std;
    let ctx = ctx;
    let screening = Screening::new(&ctx, half);

    progress("fitting the nominal model");
    let nominal_fit = fit_nominal(&ctx, &screening, &start, &free)?;
    let nominal_val = evaluate(&ctx, &nominal_fit.point, &nominal_fit.stepping).map_err(|e| {
        DiagnoseError::NominalSimulation {
            time: e.0,
            reason: e.1,
        }
    })?;
    let nominal_fit_eval =
        evaluate_fit(&ctx, &nominal_fit).map_err(|e| DiagnoseError::NominalSimulation {
            time: e.0,
            reason: e.1,
        })?;
    let noise = {
        let mut parts: Vec<&[f64]> = nominal_fit_eval.residuals.iter().map(|r| &r[..]).collect();
        parts.extend(nominal_val.residuals.iter().map(|r| &r[..]));
        let floor = opts.resolution * ctx.scales.x_std;
        noise_floor(&parts, opts.noise_band).map(|s| s.max(floor))
    };
    progress(&format!(
        "nominal fit: held-out RMSE {}, noise floor {}",
        sig(nominal_val.score.rmse, 4),
        noise.map_or("unknown".to_string(), |s| sig(s, 3))
    ));

    let configured_val = ctx
        .fit_fixed(&start)
        .ok()
        .and_then(|f| evaluate(&ctx, &f.point, &f.stepping).ok());
    let configured = configured_val
        .as_ref()
        .map_or(Score::unknown(), |e| e.score);
    let mut mismatch = mismatch_checks(&ctx, &nominal_val, &nominal_val.score);
    // A refit of the free parameters can hide a flipped sign or a unit slip behind absurd
    // values; the model as configured shows them plainly.
    if !mismatch.is_empty() {
        if let Some(c) = &configured_val {
            for reason in mismatch_checks(&ctx, c, &c.score) {
                let kind = reason.split(':').next().unwrap_or_default().to_string();
                if !mismatch.iter().any(|m| m.starts_with(&kind)) {
                    mismatch.push(format!("{reason} (the model as configured)"));
                }
            }
        }
    }
    let selection = mismatch.is_empty().then(|| {
        select::select(
            &ctx,
            &screening,
            &nominal_fit,
            nominal_val.score,
            &start,
            noise,
            opts,
            progress,
        )
    });
    let parameter_check = match &selection {
        Some(sel) if !sel.chosen.is_empty() => check_parameters(&ctx, &sel.fit, nominal, opts),
        Some(_) => check_parameters(&ctx, &nominal_fit, nominal, opts),
        None => None,
    };
    let mut decision = conclude(
        &nominal_fit,
        &nominal_val.score,
        &configured,
        noise,
        selection,
        parameter_check,
        mismatch,
        opts,
        nominal,
    );
    let extended_fit = decision.extended.as_ref().unwrap_or(&nominal_fit);
    // Outside the library: a term search on what the final model leaves, run only while clear
    // structure remains (module `discover`). It adds a hint, never changes the cause.
    let remains =
        noise.is_some_and(|s| decision.diagnosis.extended.rmse > opts.unexplained_ratio * s);
    if decision.diagnosis.mismatch.is_empty() && remains {
        progress("searching for terms outside the library");
        let (mut found, mut sentence) = discover::discover(&ctx, half, extended_fit, opts);
        // Library effects that only partly mimic the force outside the library bend the
        // residual the terms are read from; the refitted nominal's residual shows it whole.
        if found.is_none() && decision.extended.is_some() {
            let (again, second) = discover::discover(&ctx, half, &nominal_fit, opts);
            if let Some(mut d) = again {
                d.read_from = "nominal".to_string();
                found = Some(d);
                sentence = format!(
                    "{second}; read from the refitted nominal's residual, beside which the \
                     selected effects left no formula that held up ({sentence})"
                );
            }
        }
        decision.diagnosis.evidence.push(sentence);
        decision.diagnosis.discovered = found;
    }
    let nominal_output = plot_output(&ctx, &nominal_fit);
    let extended_output = plot_output(&ctx, extended_fit);
    let evaluations = nominal_fit.evaluations + decision.evaluations;
    let fitted = |f: &FitResult| FittedModel {
        params: f.point.params,
        damper: nominal.damper,
        effects: f.point.effects,
        sensor: f.point.sensor,
    };
    Ok(DiagnosisReport {
        nominal_model: fitted(&nominal_fit),
        extended_model: fitted(extended_fit),
        diagnosis: decision.diagnosis,
        nominal_output,
        extended_output,
        nominal_fit_score: nominal_fit_eval.score,
        noise_floor: noise,
        burn_in_s,
        fit_ranges,
        validation_ranges: val_ranges,
        evaluations,
    })
}

/// The score of `model` simulated on the samples `range` of `record` (from the state
/// estimated from the data), leaving the first `burn_in_s` seconds (at most half the range)
/// out, as the diagnosis scores its held-out ranges: `rmse` of simulated minus measured
/// output, `nrmse` over the measured output's standard deviation on the same samples.
pub fn score_on_record(
    record: &TimeSeries,
    model: &FittedModel,
    range: Range<usize>,
    burn_in_s: f64,
    interpolation: Interpolation,
    sim: SimMethod,
) -> Result<Score, DiagnoseError> {
    let simulated = simulate_record(record, model, range.clone(), None, interpolation, sim)?;
    let x = &record.output()[range];
    let burn = ((burn_in_s / record.dt()).ceil() as usize).min(x.len() / 2);
    let residual: Vec<f64> = simulated[burn..]
        .iter()
        .zip(&x[burn..])
        .map(|(a, b)| a - b)
        .collect();
    Ok(score_of(&[residual], &x[burn..]))
}

/// Simulates `model` on the samples `range` of `record`, driven by the measured force, from
/// `init` (position, velocity at `range.start`) or, when `None`, from the state estimated from
/// the data as [`diagnose`] does. Returns the simulated positions of the range.
pub fn simulate_record(
    record: &TimeSeries,
    model: &FittedModel,
    range: Range<usize>,
    init: Option<[f64; 2]>,
    interpolation: Interpolation,
    sim: SimMethod,
) -> Result<Vec<f64>, DiagnoseError> {
    let n = record.len();
    if range.start >= range.end || range.end > n {
        return Err(DiagnoseError::InvalidRange {
            which: "simulation",
            start: range.start,
            end: range.end,
            len: n,
        });
    }
    let p = HopperParams {
        forcing_amplitude: 0.0,
        ..model.params
    };
    let input = MeasuredForce::new(record.time()[0], record.dt(), record.input(), interpolation);
    let (hopper, force) = input.drive_with(p, model.damper, model.effects)?;
    let f_n = (p.k / p.m).sqrt() / (2.0 * std::f64::consts::PI);
    let half = init_half_width(f_n, record.dt());
    let init = match init {
        Some(i) => i,
        None => {
            segments(
                record,
                std::slice::from_ref(&range),
                0,
                half,
                "simulation",
                0.0,
            )?[0]
                .init
        }
    };
    let x = record.output();
    let extent = Extent {
        x_min: x.iter().copied().fold(f64::INFINITY, f64::min),
        x_max: x.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        v_max: 0.0,
    };
    let stepping = Stepping::resolve(sim, &p, &model.effects, &extent, record.dt());
    let mut out = vec![0.0; range.len()];
    crate::sim::simulate_positions(
        &hopper,
        Some(&force),
        record.time()[range.start],
        init,
        record.dt(),
        &stepping,
        &mut out,
    )
    .map_err(|e| DiagnoseError::Simulation {
        time: e.time,
        reason: e.reason,
    })?;
    model.sensor.apply(record.dt(), &mut out);
    Ok(out)
}

/// Half-width of the local cubic that estimates an initial state: the window spans about half a
/// radian of the natural oscillation (so the cubic's bias stays near `0.5^4 / 120` relative),
/// and at least 2 samples on each side.
fn init_half_width(f_n: f64, dt: f64) -> usize {
    let w = 0.5 / (2.0 * std::f64::consts::PI * f_n * dt);
    if w.is_finite() {
        w.round().clamp(2.0, 50.0) as usize
    } else {
        50
    }
}

fn positive_or(v: f64, fallback: f64) -> f64 {
    if v.is_finite() && v > 0.0 {
        v
    } else {
        fallback
    }
}

fn std_dev(v: &[f64]) -> f64 {
    if v.len() < 2 {
        return 0.0;
    }
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|a| (a - mean) * (a - mean)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}

/// Sample-index ranges.
type Ranges = Vec<Range<usize>>;

fn resolve_ranges(opts: &DiagnoseOptions, n: usize) -> Result<(Ranges, Ranges), DiagnoseError> {
    let split = (n as f64 * 0.7).floor() as usize;
    let fit = if opts.fit.is_empty() {
        std::iter::once(0..split).collect()
    } else {
        opts.fit.clone()
    };
    let val = if opts.validation.is_empty() {
        std::iter::once(split..n).collect()
    } else {
        opts.validation.clone()
    };
    for (which, ranges) in [("fit", &fit), ("validation", &val)] {
        for r in ranges.iter() {
            if r.start >= r.end || r.end > n {
                return Err(DiagnoseError::InvalidRange {
                    which,
                    start: r.start,
                    end: r.end,
                    len: n,
                });
            }
        }
    }
    for f in &fit {
        for v in &val {
            if f.start < v.end && v.start < f.end {
                return Err(DiagnoseError::OverlappingRanges {
                    fit_start: f.start,
                    fit_end: f.end,
                    val_start: v.start,
                    val_end: v.end,
                });
            }
        }
    }
    Ok((fit, val))
}

fn auto_burn_in(
    nominal: &NominalModel,
    fit: &[Range<usize>],
    val: &[Range<usize>],
    dt: f64,
) -> f64 {
    let p = &nominal.params;
    let c_eff = match nominal.damper {
        DamperLaw::AlwaysOn => p.c,
        DamperLaw::Switching => 0.5 * p.c,
    };
    let shortest = fit.iter().chain(val).map(|r| r.len()).min().unwrap_or(0) as f64 * dt;
    let decay_time = if c_eff > 0.0 {
        2.0 * p.m / c_eff
    } else {
        f64::INFINITY
    };
    (4.0 * decay_time).min(0.25 * shortest)
}

fn segments(
    record: &TimeSeries,
    ranges: &[Range<usize>],
    skip: usize,
    half: usize,
    which: &'static str,
    burn_in_s: f64,
) -> Result<Vec<Segment>, DiagnoseError> {
    let x = record.output();
    let n = x.len();
    ranges
        .iter()
        .map(|r| {
            let kept = r.len().saturating_sub(skip);
            if kept < MIN_SCORED {
                return Err(DiagnoseError::RangeTooShort {
                    which,
                    start: r.start,
                    end: r.end,
                    kept,
                    burn_in_s,
                    min: MIN_SCORED,
                });
            }
            // Position and velocity of a local cubic through the samples around the start
            // (those before it are measured data too; only the state is taken from them).
            let lo = r.start.saturating_sub(half);
            let hi = (r.start + half + 1).min(n);
            let init = local_fit(x, lo, hi, r.start, record.dt(), 3)
                .map_or([x[r.start], 0.0], |k| [k.x, k.v]);
            Ok(Segment {
                range: r.clone(),
                skip,
                init,
            })
        })
        .collect()
}

fn fit_nominal(
    ctx: &Context<'_>,
    screening: &Screening<'_, '_>,
    start: &ModelPoint,
    free: &[Slot],
) -> Result<FitResult, DiagnoseError> {
    if free.is_empty() {
        // Nothing to fit: score the nominal as given (an empty fit).
        return ctx
            .fit_fixed(start)
            .map_err(|e| DiagnoseError::NominalSimulation {
                time: e.0,
                reason: e.1,
            });
    }
    let refined = screening.refine_nominal(start, free);
    let cost = |p: &ModelPoint| ctx.fit_cost(p).unwrap_or(f64::INFINITY);
    let (c0, c1) = (cost(start), cost(&refined));
    if !c0.is_finite() && !c1.is_finite() {
        return Err(DiagnoseError::NominalSimulation {
            time: ctx.record.time()[0],
            reason: "the nominal model cannot be simulated on the fit ranges".to_string(),
        });
    }
    let from = if c1 < c0 { refined } else { *start };
    ctx.fit(&from, free)
        .map_err(|reason| DiagnoseError::NominalFit { reason })
}

impl Context<'_> {
    /// A "fit" of no parameters: the model as given.
    pub(crate) fn fit_fixed(&self, p: &ModelPoint) -> Result<FitResult, (f64, String)> {
        let stepping = self.stepping(p);
        let hopper = self.hopper(p).map_err(|e| (self.record.time()[0], e))?;
        let init: Vec<[f64; 2]> = self.fit.iter().map(|s| s.init).collect();
        let n = self.n_fit();
        let mut r = vec![0.0; n];
        self.residuals(&hopper, &self.fit, &init, &stepping, &mut r)
            .map_err(|e| (e.time, e.reason))?;
        let rss: f64 = r.iter().map(|v| v * v).sum();
        Ok(FitResult {
            point: *p,
            slots: Vec::new(),
            values: Vec::new(),
            stderr: Vec::new(),
            at_bound: Vec::new(),
            init,
            inflation: Vec::new(),
            rss,
            bic: crate::fit::bic(rss, n, 0),
            stepping,
            evaluations: 1,
        })
    }
}

/// Residuals and score of a model on a set of segments.
pub(crate) struct Evaluation {
    pub score: Score,
    pub residuals: Vec<Vec<f64>>,
}

fn score_of(residuals: &[Vec<f64>], measured: &[f64]) -> Score {
    let n: usize = residuals.iter().map(|r| r.len()).sum();
    let ss: f64 = residuals.iter().flatten().map(|v| v * v).sum();
    let rmse = (ss / n.max(1) as f64).sqrt();
    let sd = std_dev(measured);
    Score {
        nrmse: if sd > 0.0 { rmse / sd } else { f64::INFINITY },
        rmse,
    }
}

/// Held-out evaluation, from initial states fitted to the burn-in samples.
pub(crate) fn evaluate(
    ctx: &Context<'_>,
    p: &ModelPoint,
    stepping: &Stepping,
) -> Result<Evaluation, (f64, String)> {
    let inits = validation_inits(ctx, p, stepping)?;
    evaluate_on(ctx, p, stepping, &ctx.validation, &inits)
}

/// Initial states of the validation ranges: the data's estimate refined by least squares over
/// the range's burn-in samples, with the model fixed. Those samples are never scored, so the
/// held-out score stays honest, and a model is not penalised for the transient of a poorly
/// estimated start. Two Gauss-Newton steps (the response to the initial state is nearly
/// linear); kept only if they lower the burn-in residual. Ranges with fewer than 8 burn-in
/// samples keep the data's estimate.
fn validation_inits(
    ctx: &Context<'_>,
    p: &ModelPoint,
    stepping: &Stepping,
) -> Result<Vec<[f64; 2]>, (f64, String)> {
    let hopper = ctx.hopper(p).map_err(|e| (ctx.record.time()[0], e))?;
    validation_inits_of(ctx, &hopper, stepping)
}

/// [`validation_inits`] of a model already driven (one with an extra force too).
pub(crate) fn validation_inits_of(
    ctx: &Context<'_>,
    hopper: &Driven,
    stepping: &Stepping,
) -> Result<Vec<[f64; 2]>, (f64, String)> {
    let x = ctx.record.output();
    let steps = [1e-4 * ctx.scales.x_std, 1e-4 * ctx.scales.v_std];
    let mut inits = Vec::with_capacity(ctx.validation.len());
    for seg in &ctx.validation {
        let k = seg.skip.min(seg.range.len());
        if k < 8 {
            inits.push(seg.init);
            continue;
        }
        let head = Segment {
            range: seg.range.start..seg.range.start + k,
            skip: 0,
            init: seg.init,
        };
        let measured = &x[head.range.clone()];
        let mut y = Vec::new();
        let residual = |init: [f64; 2], y: &mut Vec<f64>| -> Option<f64> {
            ctx.simulate(hopper, &head, init, stepping, y).ok()?;
            let ss: f64 = y.iter().zip(measured).map(|(a, b)| (a - b) * (a - b)).sum();
            ss.is_finite().then_some(ss)
        };
        let mut best = seg.init;
        let Some(mut best_ss) = residual(best, &mut y) else {
            inits.push(seg.init);
            continue;
        };
        for _ in 0..2 {
            let base = y.clone();
            let mut cols = [vec![0.0; k], vec![0.0; k]];
            let mut ok = true;
            for (j, col) in cols.iter_mut().enumerate() {
                let mut init = best;
                init[j] += steps[j];
                if residual(init, &mut y).is_none() {
                    ok = false;
                    break;
                }
                for ((c, a), b) in col.iter_mut().zip(&y).zip(&base) {
                    *c = (a - b) / steps[j];
                }
            }
            if !ok {
                break;
            }
            let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(u, v)| u * v).sum::<f64>();
            let r: Vec<f64> = base.iter().zip(measured).map(|(a, b)| b - a).collect();
            let (a11, a12, a22) = (
                dot(&cols[0], &cols[0]),
                dot(&cols[0], &cols[1]),
                dot(&cols[1], &cols[1]),
            );
            let (g1, g2) = (dot(&cols[0], &r), dot(&cols[1], &r));
            let det = a11 * a22 - a12 * a12;
            if det.is_nan() || det <= 1e-12 * a11 * a22 {
                break;
            }
            let trial = [
                best[0] + (a22 * g1 - a12 * g2) / det,
                best[1] + (a11 * g2 - a12 * g1) / det,
            ];
            match residual(trial, &mut y) {
                Some(ss) if ss < best_ss => {
                    best = trial;
                    best_ss = ss;
                }
                _ => break,
            }
        }
        inits.push(best);
    }
    Ok(inits)
}

/// Evaluation on the fit ranges with the fit's initial states.
fn evaluate_fit(ctx: &Context<'_>, f: &FitResult) -> Result<Evaluation, (f64, String)> {
    evaluate_on(ctx, &f.point, &f.stepping, &ctx.fit, &f.init)
}

fn evaluate_on(
    ctx: &Context<'_>,
    p: &ModelPoint,
    stepping: &Stepping,
    segs: &[Segment],
    inits: &[[f64; 2]],
) -> Result<Evaluation, (f64, String)> {
    let hopper = ctx.hopper(p).map_err(|e| (ctx.record.time()[0], e))?;
    evaluate_driven(ctx, &hopper, stepping, segs, inits)
}

/// [`evaluate_on`] for a model already driven (one with an extra force too).
pub(crate) fn evaluate_driven(
    ctx: &Context<'_>,
    hopper: &Driven,
    stepping: &Stepping,
    segs: &[Segment],
    inits: &[[f64; 2]],
) -> Result<Evaluation, (f64, String)> {
    let x = ctx.record.output();
    let mut residuals = Vec::with_capacity(segs.len());
    let mut measured = Vec::new();
    let mut buf = Vec::new();
    for (seg, &init) in segs.iter().zip(inits) {
        ctx.simulate(hopper, seg, init, stepping, &mut buf)
            .map_err(|e| (e.time, e.reason))?;
        let scored = seg.scored();
        residuals.push(
            scored
                .clone()
                .map(|k| buf[k - seg.range.start] - x[k])
                .collect(),
        );
        measured.extend_from_slice(&x[scored]);
    }
    let score = score_of(&residuals, &measured);
    if !score.rmse.is_finite() {
        return Err((ctx.record.time()[0], "non-finite simulation".to_string()));
    }
    Ok(Evaluation { score, residuals })
}

fn plot_output(ctx: &Context<'_>, f: &FitResult) -> Vec<f64> {
    let mut out = vec![f64::NAN; ctx.record.len()];
    let Ok(hopper) = ctx.hopper(&f.point) else {
        return out;
    };
    let Ok(val_inits) = validation_inits(ctx, &f.point, &f.stepping) else {
        return out;
    };
    let mut buf = Vec::new();
    for (seg, init) in ctx
        .fit
        .iter()
        .zip(&f.init)
        .chain(ctx.validation.iter().zip(&val_inits))
    {
        if ctx
            .simulate(&hopper, seg, *init, &f.stepping, &mut buf)
            .is_ok()
        {
            out[seg.range.clone()].copy_from_slice(&buf);
        }
    }
    out
}

/// A candidate after fitting and scoring.
#[derive(Debug)]
pub(crate) struct Outcome {
    pub effect: Effect,
    pub fit: Option<FitResult>,
    pub val_rmse: f64,
    pub val_nrmse: f64,
    pub note: String,
    /// Starting points fitted.
    pub starts: usize,
    /// The effect's parameters at the winning start.
    pub best_start: BTreeMap<String, f64>,
}

/// Fits `effect` together with the parameters `slots` of the model `base` (all jointly), from
/// the screening's starts, and scores it on the held-out data.
pub(crate) fn run_candidate(
    ctx: &Context<'_>,
    screening: &Screening<'_, '_>,
    base: &FitResult,
    slots: &[Slot],
    effect: Effect,
) -> Outcome {
    let failed = |note: String| Outcome {
        effect,
        fit: None,
        val_rmse: f64::NAN,
        val_nrmse: f64::NAN,
        note,
        starts: 0,
        best_start: BTreeMap::new(),
    };
    if let Some(reason) = effect.skip_reason(ctx.damper, slots) {
        return failed(reason.to_string());
    }
    let mut all = slots.to_vec();
    for s in effect.slots(slots) {
        if !all.contains(&s) {
            all.push(s);
        }
    }
    if all.len() == slots.len() {
        return failed("skipped: adds no parameter to the model".to_string());
    }
    // Several starts (a threshold's two signs, two contact positions) are fitted in parallel;
    // the lowest fit cost wins.
    let starts = screening.starts(&base.point, slots, effect);
    let fits: Vec<Result<FitResult, String>> = starts
        .par_iter()
        .map(|start| ctx.fit(start, &all))
        .collect();
    let evaluations: usize = fits.iter().flatten().map(|f| f.evaluations).sum();
    let mut best: Option<(FitResult, usize)> = None;
    let mut error = None;
    for (i, f) in fits.into_iter().enumerate() {
        match f {
            Ok(f) if best.as_ref().map_or(true, |b| f.rss < b.0.rss) => best = Some((f, i)),
            Ok(_) => {}
            Err(e) => error = Some(e),
        }
    }
    let best_start: BTreeMap<String, f64> = best
        .as_ref()
        .map(|(_, i)| {
            effect
                .slots(slots)
                .into_iter()
                .map(|s| (s.name().to_string(), starts[*i].get(s)))
                .collect()
        })
        .unwrap_or_default();
    let best = best.map(|(b, _)| FitResult { evaluations, ..b });
    let Some(fit) = best else {
        return failed(format!(
            "fit failed: {}",
            error.unwrap_or_else(|| "no starting point".to_string())
        ));
    };
    match evaluate(ctx, &fit.point, &fit.stepping) {
        Ok(ev) => Outcome {
            effect,
            val_rmse: ev.score.rmse,
            val_nrmse: ev.score.nrmse,
            fit: Some(fit),
            note: String::new(),
            starts: starts.len(),
            best_start,
        },
        Err((t, e)) => failed(format!(
            "the fitted model cannot be simulated on the held-out data (t = {t} s: {e})"
        )),
    }
}

struct Decision {
    diagnosis: Diagnosis,
    /// The extended model's fit, when an effect was kept.
    extended: Option<FitResult>,
    evaluations: usize,
}

/// Named parameters and standard errors of a fit; asymmetric friction also as `mu_pos` and
/// `mu_neg` (from `mu` and the input offset; their errors combine the two as independent).
fn named(fit: &FitResult) -> (BTreeMap<String, f64>, BTreeMap<String, f64>) {
    let mut p = BTreeMap::new();
    let mut s = BTreeMap::new();
    for ((slot, v), e) in fit.slots.iter().zip(&fit.values).zip(&fit.stderr) {
        p.insert(slot.name().to_string(), *v);
        s.insert(slot.name().to_string(), *e);
    }
    (p, s)
}

fn effect_parameters(
    effect: Effect,
    fit: &FitResult,
) -> (BTreeMap<String, f64>, BTreeMap<String, f64>) {
    let (all, all_se) = named(fit);
    let mut p = BTreeMap::new();
    let mut s = BTreeMap::new();
    if effect == Effect::AsymmetricFriction {
        let mu = all.get("mu").copied().unwrap_or(0.0);
        let d = all.get("input_offset").copied().unwrap_or(0.0);
        let se = (all_se.get("mu").copied().unwrap_or(0.0).powi(2)
            + all_se.get("input_offset").copied().unwrap_or(0.0).powi(2))
        .sqrt();
        for (name, v) in [("mu_pos", mu - d), ("mu_neg", mu + d)] {
            p.insert(name.to_string(), v);
            s.insert(name.to_string(), se);
        }
        return (p, s);
    }
    for name in effect.parameter_names() {
        if let (Some(v), Some(e)) = (all.get(*name), all_se.get(*name)) {
            p.insert(name.to_string(), *v);
            s.insert(name.to_string(), *e);
        }
    }
    (p, s)
}

/// Asymmetric friction read both ways: the same force law as Coulomb friction with a constant
/// force beside it, which the data cannot tell apart from a true asymmetry of the contact.
fn asymmetry_reading(c: &Cause) -> String {
    let get = |k: &str| c.parameters.get(k).copied().unwrap_or(f64::NAN);
    let (pos, neg) = (get("mu_pos"), get("mu_neg"));
    format!(
        "asymmetric friction mu_pos = {}, mu_neg = {} is the same force law as Coulomb friction \
         mu = {} with a constant force {} (an input offset, or whatever else adds a constant \
         force: a wrong weight, a preload): the record cannot tell a one-sided contact from a \
         symmetric one beside a constant force; a static test with a known added weight \
         separates them",
        sig(pos, 4),
        sig(neg, 4),
        sig(0.5 * (pos + neg), 4),
        sig(0.5 * (neg - pos), 4)
    )
}

/// What an experiment would need to separate two effects the data cannot tell apart.
fn separating_experiment(a: Effect, b: Effect) -> &'static str {
    use Effect::*;
    let pair = |x, y| (a == x && b == y) || (a == y && b == x);
    if pair(ActuatorLag, InputDelay) || pair(SensorLag, InputDelay) {
        "a lag and a delay agree to first order in omega tau: excite well above 1 / (2 pi tau), \
         where a delay's phase keeps growing and a lag's gain falls"
    } else if pair(ActuatorLag, SensorLag) {
        "an input-side and an output-side lag act alike on the linearised response: measure the \
         applied force itself (a load cell at the actuator), or excite at larger amplitude so the \
         nonlinear response tells where the lag sits"
    } else if pair(InputOffset, SensorOffsetGain) || pair(InputOffset, ParameterError) {
        "a constant force and a constant shift of the reading move the equilibrium alike: a \
         static test with a known added weight, or a second sensor, separates them"
    } else {
        "an experiment that excites the two effects differently (other amplitudes, frequencies or \
         operating points)"
    }
}

/// Checks whether the nominal model describes the data at all, before any effect is named.
/// Returns the reasons it does not, each with the check that found it.
fn mismatch_checks(ctx: &Context<'_>, nominal_val: &Evaluation, nominal: &Score) -> Vec<String> {
    let x = ctx.record.output();
    let (mut measured, mut simulated) = (Vec::new(), Vec::new());
    for (seg, r) in ctx.validation.iter().zip(&nominal_val.residuals) {
        for (k, ri) in seg.scored().zip(r) {
            measured.push(x[k]);
            simulated.push(x[k] + ri);
        }
    }
    let n = measured.len() as f64;
    if n < 2.0 {
        return Vec::new();
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / n;
    let (my, ms) = (mean(&measured), mean(&simulated));
    let cov: f64 = measured
        .iter()
        .zip(&simulated)
        .map(|(a, b)| (a - my) * (b - ms))
        .sum::<f64>();
    let var_s: f64 = simulated.iter().map(|b| (b - ms).powi(2)).sum::<f64>();
    let var_y: f64 = measured.iter().map(|a| (a - my).powi(2)).sum::<f64>();
    let gain = cov / var_s;
    let scale = (var_y / var_s).sqrt();
    let correlation = cov / (var_s * var_y).sqrt();
    let mut reasons = Vec::new();
    if gain.is_finite() && gain < -0.2 {
        reasons.push(format!(
            "sign: the measured output moves against the simulated one (regression gain {gain:.3}); \
             check the sign of the output column or of the input"
        ));
    }
    if scale.is_finite() && !(0.1..=10.0).contains(&scale) {
        reasons.push(format!(
            "scale: the measured output varies {scale:.3e} times as much as the simulated one; \
             check the units of the output and input columns (mm against m, mN against N)"
        ));
    }
    if !scale.is_finite() || !gain.is_finite() {
        reasons.push(
            "scale: the simulated output does not vary over the held-out data; check that the \
             input column holds the applied force"
                .to_string(),
        );
    }
    if reasons.is_empty() && nominal.nrmse > 1.0 && correlation.abs() < 0.5 {
        reasons.push(format!(
            "fit: the nominal model's held-out NRMSE is {:.0} %, worse than the measured mean, \
             and even with an offset and a scale its output explains only {:.0} % of the \
             measured variance; check the columns (is the input the applied force, the output \
             the position?), the time unit of the time column and the model's parameters",
            100.0 * nominal.nrmse,
            100.0 * correlation * correlation
        ));
    }
    reasons
}

#[allow(clippy::too_many_arguments)]
fn conclude(
    nominal_fit: &FitResult,
    nominal_score: &Score,
    configured: &Score,
    noise: Option<f64>,
    selection: Option<select::Selection>,
    parameter_check: Option<ParameterCheck>,
    mismatch: Vec<String>,
    opts: &DiagnoseOptions,
    nominal: &NominalModel,
) -> Decision {
    let nominal_rmse = nominal_score.rmse;
    let mut evidence = Vec::new();
    let free_names: Vec<&str> = nominal.free.iter().map(|p| p.name()).collect();
    let ratio = noise.map(|s| nominal_rmse / s);
    evidence.push(format!(
        "configured model: held-out RMSE {} (NRMSE {}); nominal model ({} refitted): \
         held-out RMSE {} (NRMSE {}){}",
        sig(configured.rmse, 4),
        percent(configured.nrmse, 3),
        if free_names.is_empty() {
            "nothing".to_string()
        } else {
            free_names.join(", ")
        },
        sig(nominal_rmse, 4),
        percent(nominal_score.nrmse, 3),
        match (noise, ratio) {
            (Some(s), Some(r)) => format!(
                ", {} times the noise floor {} estimated from the residual spectrum \
                 between {:.0} % and {:.0} % of the Nyquist frequency",
                sig(r, 3),
                sig(s, 3),
                100.0 * opts.noise_band.0,
                100.0 * opts.noise_band.1
            ),
            _ => ", noise floor unknown (ranges too short)".to_string(),
        }
    ));
    let mut causes: Vec<Cause> = Vec::new();
    let mut alternatives = Vec::new();
    let mut extended_fit: Option<FitResult> = None;
    let mut extended = *nominal_score;
    let mut candidates = Vec::new();
    let mut evaluations = 0;

    // The configured free parameters are off when the final model's values of them differ
    // significantly from the configured ones and resetting them costs held-out accuracy.
    let (moved, reset_rmse) = match parameter_check {
        Some((m, r)) => (m, r),
        None => (Vec::new(), f64::NAN),
    };
    let final_rmse_for_check = selection
        .as_ref()
        .filter(|sel| !sel.chosen.is_empty())
        .map_or(nominal_rmse, |sel| sel.held_out.rmse);
    let refit_gain = 1.0 - final_rmse_for_check / reset_rmse;
    let refit_is_finding = !moved.is_empty() && refit_gain >= opts.min_gain;

    let cause: String;
    if !mismatch.is_empty() {
        cause = "model_mismatch".to_string();
        evidence.push(
            "the nominal model does not describe the data at all, so no effect is named; \
             check, one by one:"
                .to_string(),
        );
        evidence.extend(mismatch.iter().cloned());
    } else {
        let sel = selection.expect("a selection runs unless the model mismatches");
        evaluations += sel.evaluations;
        candidates = sel
            .first_round
            .iter()
            .map(|j| {
                let (parameters, stderr) = j.outcome.fit.as_ref().map(named).unwrap_or_default();
                Candidate {
                    effect: j.outcome.effect.name().to_string(),
                    parameters,
                    stderr,
                    nrmse_validation: j.outcome.val_nrmse,
                    rmse_validation: j.outcome.val_rmse,
                    bic: j.outcome.fit.as_ref().map_or(f64::NAN, |f| f.bic),
                    significant: j.passes,
                    note: j.note.clone(),
                    starts: j.outcome.starts,
                    best_start: j.outcome.best_start.clone(),
                }
            })
            .collect();
        evidence.extend(sel.evidence.iter().cloned());
        if refit_is_finding {
            let mut parameters = BTreeMap::new();
            let mut stderr = BTreeMap::new();
            let mut words = Vec::new();
            for (name, v, e, c) in &moved {
                parameters.insert(name.to_string(), *v);
                stderr.insert(name.to_string(), *e);
                words.push(format!(
                    "{name} = {} (configured {})",
                    Quantity::new(*v).stderr(*e),
                    sig(*c, 4)
                ));
            }
            evidence.push(format!(
                "the configured parameters are off: refitted {} ({:.1} % better held out)",
                words.join(", "),
                100.0 * refit_gain
            ));
            causes.push(Cause {
                effect: "parameter_error".to_string(),
                parameters,
                stderr,
                gain_share: 1.0,
            });
        }
        if !sel.chosen.is_empty() {
            let final_ms = sel.held_out.rmse.powi(2);
            let refit_rise = if refit_is_finding {
                (reset_rmse.powi(2) - final_ms).max(0.0)
            } else {
                0.0
            };
            let total: f64 = refit_rise + sel.chosen.iter().map(|c| c.rise).sum::<f64>();
            let n_parts = sel.chosen.len() + usize::from(refit_is_finding);
            let share = |rise: f64| {
                if total > 0.0 {
                    rise / total
                } else {
                    1.0 / n_parts as f64
                }
            };
            if let Some(c) = causes.first_mut() {
                c.gain_share = share(refit_rise);
            }
            for ch in &sel.chosen {
                let (parameters, stderr) = effect_parameters(ch.effect, &sel.fit);
                causes.push(Cause {
                    effect: ch.effect.name().to_string(),
                    parameters,
                    stderr,
                    gain_share: share(ch.rise),
                });
            }
            causes.sort_by(|a, b| b.gain_share.total_cmp(&a.gain_share));
            if let Some(c) = causes.iter().find(|c| c.effect == "asymmetric_friction") {
                evidence.push(asymmetry_reading(c));
            }
            // And the other way: Coulomb friction beside a constant force no larger than it is
            // asymmetric friction with both coefficients >= 0.
            let value = |effect: &str, key: &str| {
                causes
                    .iter()
                    .find(|c| c.effect == effect)
                    .and_then(|c| c.parameters.get(key).copied())
            };
            if let (Some(mu), Some(d)) = (
                value("coulomb_friction", "mu"),
                value("input_offset", "input_offset"),
            ) {
                if d.abs() <= mu {
                    evidence.push(format!(
                        "Coulomb friction mu = {} beside a constant force {} is the same force law \
                         as asymmetric friction mu_pos = {}, mu_neg = {}: the record cannot tell a \
                         symmetric contact beside a constant force from a one-sided one; a static \
                         test with a known added weight separates them",
                        sig(mu, 4),
                        sig(d, 4),
                        sig(mu - d, 4),
                        sig(mu + d, 4)
                    ));
                }
            }
            extended = sel.held_out;
            extended_fit = Some(sel.fit.clone());
        }
        let final_rmse = extended.rmse;
        let explained = match noise {
            Some(s) if nominal_rmse > s => {
                (nominal_rmse.powi(2) - final_rmse.powi(2)) / (nominal_rmse.powi(2) - s * s)
            }
            _ => 1.0,
        };
        let at_floor = noise.is_some_and(|s| final_rmse <= opts.unexplained_ratio * s);
        let structured = noise.map_or(true, |s| final_rmse > opts.unexplained_ratio * s);
        if sel.chosen.is_empty() {
            if structured && !refit_is_finding {
                cause = "unexplained".to_string();
                evidence.push(format!(
                    "no candidate is significant, yet the nominal residual is {} the noise \
                     floor: structure remains that no library effect explains",
                    ratio.map_or("of unknown size relative to".to_string(), |r| format!(
                        "{r:.2} times"
                    ))
                ));
            } else if refit_is_finding {
                cause = "parameter_error".to_string();
            } else {
                cause = "none".to_string();
                evidence.push(
                    "no candidate is significant and the nominal residual is at the noise \
                     floor: the nominal model explains the data"
                        .to_string(),
                );
            }
        } else if !at_floor && explained < opts.min_explained {
            cause = "unexplained".to_string();
            evidence.push(format!(
                "the selected effects remove only {:.1} % of the nominal's error above the noise \
                 floor (at least {:.1} % required) and the residual stays {:.2} times the floor: \
                 something outside the library is at work as well",
                100.0 * explained,
                100.0 * opts.min_explained,
                noise.map_or(f64::NAN, |s| final_rmse / s)
            ));
        } else if !sel.rivals.is_empty() {
            cause = "ambiguous".to_string();
            for &(chosen, r) in &sel.rivals {
                for e in [chosen, r] {
                    if !alternatives.iter().any(|a| a == e.name()) {
                        alternatives.push(e.name().to_string());
                    }
                }
                evidence.push(format!(
                    "{} and {} explain the data equally well (fit BIC within {}); to separate \
                     them: {}",
                    chosen.name(),
                    r.name(),
                    opts.bic_margin,
                    separating_experiment(chosen, r)
                ));
            }
        } else {
            // The strongest selected effect: a refit of the configured parameters beside it is
            // reported in `causes`, but the cause names what the nominal model lacks.
            cause = causes
                .iter()
                .find(|c| c.effect != "parameter_error")
                .or(causes.first())
                .map_or("none".to_string(), |c| c.effect.clone());
            evidence.push(match noise {
                Some(s) => format!(
                    "the extended model's held-out residual is {:.2} times the noise floor and \
                     removes {:.0} % of the nominal's excess error",
                    final_rmse / s,
                    100.0 * explained.min(1.0)
                ),
                None => "noise floor unknown; the decision rests on the tests alone".to_string(),
            });
        }
    }
    let (parameters, stderr) = named(extended_fit.as_ref().unwrap_or(nominal_fit));
    let gain = 1.0 - extended.rmse / nominal_rmse;
    Decision {
        diagnosis: Diagnosis {
            cause,
            parameters,
            stderr,
            nominal: *nominal_score,
            extended,
            gain,
            candidates,
            evidence,
            causes,
            alternatives,
            configured: *configured,
            gain_vs_configured: 1.0 - extended.rmse / configured.rmse,
            mismatch,
            discovered: None,
        },
        extended: extended_fit,
        evaluations,
    }
}

/// Free parameters of the final model that lie more than `significance_sigma` standard errors
/// from their configured values (name, value, standard error, configured value), and the final
/// model's held-out RMSE with them reset to the configured values.
type ParameterCheck = (Vec<(&'static str, f64, f64, f64)>, f64);

fn check_parameters(
    ctx: &Context<'_>,
    fit: &FitResult,
    nominal: &NominalModel,
    opts: &DiagnoseOptions,
) -> Option<ParameterCheck> {
    let free = nominal.free_slots();
    let mut moved = Vec::new();
    let mut reset = fit.point;
    for ((slot, v), e) in fit.slots.iter().zip(&fit.values).zip(&fit.stderr) {
        if !free.contains(slot) {
            continue;
        }
        let configured = slot_value(nominal, *slot);
        if (v - configured).abs() > opts.significance_sigma * e {
            moved.push((slot.name(), *v, *e, configured));
            reset.set(*slot, configured);
        }
    }
    if moved.is_empty() {
        return None;
    }
    let rmse = evaluate(ctx, &reset, &fit.stepping).ok()?.score.rmse;
    Some((moved, rmse))
}

/// The configured value of a nominal parameter.
fn slot_value(nominal: &NominalModel, slot: Slot) -> f64 {
    ModelPoint {
        params: nominal.measured_params(),
        effects: nominal.effects,
        sensor: nominal.sensor,
    }
    .get(slot)
}
