//! The diagnosis: nominal fit, candidate fits, held-out scores and the decision.

use htfid_number::sig;
use std::collections::BTreeMap;
use std::ops::Range;

use htfid_model::HopperParams;
use rayon::prelude::*;

use crate::deriv::window_half_width;
use crate::discover::{self};
use crate::effect::Slot;
use crate::fit::{Context, Driven, FitResult, ModelPoint, Scales, Segment};
use crate::interp::Interpolation;
use crate::noise::{input_noise_level, noise_floor, with_white_noise};
use crate::screen::Screening;
use crate::select;
use crate::sim::{Extent, MeasuredForce, SimMethod, Stepping};
use crate::{DiagnoseError, Effect, NominalModel, TimeSeries};

use crate::answer::{DiagnosisReport, FittedModel, InputNoise, Score};
use crate::decide::{check_parameters, conclude, configured_mismatch, mismatch_checks};
use crate::options::DiagnoseOptions;
use crate::ranges::{auto_burn_in, resolve_ranges, segments};

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

    let f_n = start.params.natural_rate() / (2.0 * std::f64::consts::PI);
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
        mass_range: (
            nominal.params.m / crate::fit::MASS_RANGE,
            nominal.params.m * crate::fit::MASS_RANGE,
        ),
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
    let reading_noise = {
        let mut parts: Vec<&[f64]> = nominal_fit_eval.residuals.iter().map(|r| &r[..]).collect();
        parts.extend(nominal_val.residuals.iter().map(|r| &r[..]));
        let floor = opts.resolution * ctx.scales.x_std;
        noise_floor(&parts, opts.noise_band).map(|s| s.max(floor))
    };
    let input_noise = input_noise(&ctx, &nominal_fit, opts);
    // A perfect model driven by the noisy measured force still leaves the response to that
    // noise: it is part of the floor.
    let noise = reading_noise.map(|s| input_noise.map_or(s, |i| s.hypot(i.propagated)));
    progress(&format!(
        "nominal fit: held-out RMSE {}, noise floor {}{}",
        sig(nominal_val.score.rmse, 4),
        noise.map_or("unknown".to_string(), |s| sig(s, 3)),
        input_noise.map_or(String::new(), |i| format!(
            " (the input's noise {} through the model: {})",
            sig(i.sigma, 3),
            sig(i.propagated, 3)
        ))
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
    if mismatch.is_empty() {
        mismatch.extend(
            configured_val
                .as_ref()
                .and_then(|c| configured_mismatch(&ctx, c)),
        );
    } else {
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
            // The selection stops at the whole floor, but a candidate's gain is the share of
            // the error above the reading's noise alone that it removes: the response to the
            // input's noise is no floor a model cannot go below, since a model that smooths
            // the measured force (a lag, more damping) removes part of it.
            (noise, reading_noise),
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
    if let (Some(i), Some(r)) = (input_noise, reading_noise) {
        let at = decision.diagnosis.evidence.len().min(1);
        decision.diagnosis.evidence.insert(
            at,
            format!(
                "the noise floor holds the reading's {} and the nominal model's response to the \
                 measured input's own noise, {} (the input's spectrum in the same band is white \
                 noise of {} RMS)",
                sig(r, 3),
                sig(i.propagated, 3),
                sig(i.sigma, 3)
            ),
        );
    }
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
        // The formula whose model predicts the held-out data better is kept.
        if decision.extended.is_some() {
            let (again, second) = discover::discover(&ctx, half, &nominal_fit, opts);
            if let Some(mut d) = again {
                let beside = found.as_ref().map(|f| f.rmse_after);
                if beside.map_or(true, |rmse| d.rmse_after < rmse) {
                    d.read_from = "nominal".to_string();
                    found = Some(d);
                    let why = if beside.is_some() {
                        "whose formula predicts the held-out data better than the one found \
                         beside the selected effects"
                    } else {
                        "beside which the selected effects left no formula that held up"
                    };
                    sentence = format!(
                        "{second}; read from the refitted nominal's residual, {why} ({sentence})"
                    );
                }
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
        input_noise,
        burn_in_s,
        fit_ranges,
        validation_ranges: val_ranges,
        evaluations,
    })
}

/// The measured input's white-noise level ([`input_noise_level`], on the fit and validation
/// ranges) and the RMS response of the model `fit` to it: the model simulated on every fit
/// and validation range from the same initial states, driven by the measured force and by the
/// measured force plus white noise of that level, scored on the ranges' scored samples. `None`
/// where the level cannot be told from the input (see
/// [`DiagnoseOptions::input_noise_share`]) or a simulation fails.
fn input_noise(ctx: &Context<'_>, fit: &FitResult, opts: &DiagnoseOptions) -> Option<InputNoise> {
    let f = ctx.record.input();
    let parts: Vec<&[f64]> = ctx
        .fit
        .iter()
        .chain(&ctx.validation)
        .map(|s| &f[s.range.clone()])
        .collect();
    let sigma = input_noise_level(
        &parts,
        opts.noise_band,
        opts.input_noise_share,
        opts.input_noise_flatness,
    )?;
    let noisy = with_white_noise(f, sigma)?;
    let t = ctx.record.time();
    let noisy = MeasuredForce::new(t[0], ctx.record.dt(), &noisy, opts.interpolation);
    let p = fit.point;
    let clean = ctx.hopper(&p).ok()?;
    let (hopper, force) = noisy.drive_with(p.params, ctx.damper, p.effects).ok()?;
    let driven = Driven {
        hopper,
        force: Some(force),
        sensor: p.sensor,
        extra: None,
    };
    let stepping = ctx.stepping(&p);
    let (mut sum, mut count) = (0.0, 0usize);
    for segs in [&ctx.fit, &ctx.validation] {
        let n: usize = segs.iter().map(|s| s.scored().len()).sum();
        let inits: Vec<[f64; 2]> = segs.iter().map(|s| s.init).collect();
        let (mut a, mut b) = (vec![0.0; n], vec![0.0; n]);
        let done = ctx.residuals_batch(
            &[Some(&clean), Some(&driven)],
            segs,
            &[&inits, &inits],
            &stepping,
            &mut [&mut a, &mut b],
        );
        if done.iter().any(Result::is_err) {
            return None;
        }
        sum += a
            .iter()
            .zip(&b)
            .map(|(x, y)| (y - x) * (y - x))
            .sum::<f64>();
        count += n;
    }
    let propagated = (sum / count.max(1) as f64).sqrt();
    propagated
        .is_finite()
        .then_some(InputNoise { sigma, propagated })
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
    let f_n = p.natural_rate() / (2.0 * std::f64::consts::PI);
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
            at_limit: false,
        })
    }
}

/// Residuals and score of a model on a set of segments.
pub(crate) struct Evaluation {
    pub score: Score,
    pub residuals: Vec<Vec<f64>>,
}

pub(crate) fn score_of(residuals: &[Vec<f64>], measured: &[f64]) -> Score {
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
