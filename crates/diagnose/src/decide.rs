//! The decision: which effects the data demand, and the sentences that explain it.

use htfid_number::{percent, sig, Quantity};
use std::collections::BTreeMap;

use crate::answer::{Candidate, Cause, Diagnosis, Score, WindowScore};
use crate::diagnose::{evaluate, Evaluation};
use crate::effect::Slot;
use crate::fit::{Context, FitResult, ModelPoint};
use crate::options::DiagnoseOptions;
use crate::select;
use crate::{Effect, NominalModel};

/// What [`conclude`] decided: the diagnosis, the extended model's fit and the effort spent.
pub(crate) struct Decision {
    pub(crate) diagnosis: Diagnosis,
    /// The extended model's fit, when an effect was kept.
    pub(crate) extended: Option<FitResult>,
    pub(crate) evaluations: usize,
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

/// The reading of a cubic spring `k3` beside a sensor offset `b` and gain `g` (the recorded
/// `y = b + g s`): in the recorded position the spring force `-k s - k3 s^3` is
/// `-k3 (y - b)^3 / g^3 - ...`, whose quadratic term `-k2 y^2` has `k2 = -3 k3 b / g^3`. The
/// offset sensor and an asymmetric spring (a quadratic and a cubic term, the sensor's zero
/// right) are the same model; only a reading of the sensor at rest tells them apart.
fn asymmetric_spring_reading(k3: f64, b: f64, g: f64) -> String {
    let k2 = quadratic_term(k3, b, g);
    format!(
        "a cubic spring k3 = {} about a sensor offset b = {} (gain g = {}) is, in the recorded \
         position y, a spring with a quadratic term as well (force -k2 y^2 - k3 y^3 / g^3 and a \
         linear and a constant part, k2 = -3 k3 b / g^3 = {}): the record cannot tell an offset \
         sensor from an asymmetric spring with the sensor's zero right; a reading of the sensor \
         at rest, with no force applied, separates them",
        sig(k3, 4),
        sig(b, 4),
        sig(g, 4),
        sig(k2, 4)
    )
}

/// `k2` of [`asymmetric_spring_reading`]: the cubic spring's force `-k3 s^3` at
/// `s = (y - b) / g` has the quadratic term `-k2 y^2`.
fn quadratic_term(k3: f64, b: f64, g: f64) -> f64 {
    -3.0 * k3 * b / g.powi(3)
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

/// How a measured output follows a simulated one: the regression gain of the measured on the
/// simulated (about 1 when they agree, negative when one moves against the other), the ratio
/// of their spreads, and their correlation.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Agreement {
    pub gain: f64,
    pub scale: f64,
    pub correlation: f64,
}

impl Agreement {
    /// The agreement of paired samples; `None` with fewer than two. Non-finite where the
    /// simulated output does not vary.
    pub(crate) fn of(measured: &[f64], simulated: &[f64]) -> Option<Agreement> {
        let n = measured.len().min(simulated.len());
        if n < 2 {
            return None;
        }
        let (measured, simulated) = (&measured[..n], &simulated[..n]);
        let mean = |v: &[f64]| v.iter().sum::<f64>() / n as f64;
        let (my, ms) = (mean(measured), mean(simulated));
        let cov: f64 = measured
            .iter()
            .zip(simulated)
            .map(|(a, b)| (a - my) * (b - ms))
            .sum::<f64>();
        let var_s: f64 = simulated.iter().map(|b| (b - ms).powi(2)).sum::<f64>();
        let var_y: f64 = measured.iter().map(|a| (a - my).powi(2)).sum::<f64>();
        Some(Agreement {
            gain: cov / var_s,
            scale: (var_y / var_s).sqrt(),
            correlation: cov / (var_s * var_y).sqrt(),
        })
    }

    /// What plainly keeps the simulated output from describing the measured one, whatever
    /// the parameters: the measured moves against it (regression gain below -0.2 at a
    /// correlation below -0.5: a flipped sign), or follows its shape (correlation above 0.5 in
    /// size) at a spread more than [`MAX_SCALE_RATIO`] times larger or smaller (a unit slip).
    /// Both leave the shape plain, so a configured parameter that is merely off (a refit's
    /// business) rarely trips them.
    pub(crate) fn plain(&self) -> Option<Plain> {
        if self.gain < -0.2 && self.correlation < -0.5 {
            Some(Plain::Sign)
        } else if !(1.0 / MAX_SCALE_RATIO..=MAX_SCALE_RATIO).contains(&self.scale)
            && self.correlation.abs() > 0.5
        {
            Some(Plain::Units)
        } else {
            None
        }
    }
}

/// Largest ratio of the measured output's spread to the configured model's (either way) that
/// [`Agreement::plain`] leaves to the refit. Unit slips are factors of 100 and more (cm, mm,
/// um against m); a configured hopper's stiffness a quarter of the truth's already gives 13.
pub(crate) const MAX_SCALE_RATIO: f64 = 30.0;

/// A plain mismatch of a simulated output with the measured one ([`Agreement::plain`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Plain {
    Sign,
    Units,
}

/// The measured output and the one `eval` simulated, on the held-out samples scored.
fn held_out_pairs(ctx: &Context<'_>, eval: &Evaluation) -> (Vec<f64>, Vec<f64>) {
    let x = ctx.record.output();
    let (mut measured, mut simulated) = (Vec::new(), Vec::new());
    for (seg, r) in ctx.validation.iter().zip(&eval.residuals) {
        for (k, ri) in seg.scored().zip(r) {
            measured.push(x[k]);
            simulated.push(x[k] + ri);
        }
    }
    (measured, simulated)
}

/// The plain mismatch of the model as configured ([`Agreement::plain`]), as a reason. A refit
/// can move a flipped sign into other parameters (a lag of a fifth of a period stood in for one
/// on the paper's record); the model as configured shows it plainly.
pub(crate) fn configured_mismatch(ctx: &Context<'_>, configured: &Evaluation) -> Option<String> {
    let (measured, simulated) = held_out_pairs(ctx, configured);
    let a = Agreement::of(&measured, &simulated)?;
    Some(match a.plain()? {
        Plain::Sign => format!(
            "sign: the measured output moves against the model's as configured (regression gain \
             {:.3}, correlation {:.3}); check the sign of the output column or of the input, and \
             that the time column's zero is the forcing's phase 0",
            a.gain, a.correlation
        ),
        Plain::Units => format!(
            "scale: the measured output varies {} times as much as the model's as configured, \
             with its shape (correlation {:.3}); check the units of the output and input columns \
             (mm against m, mN against N)",
            sig(a.scale, 3),
            a.correlation
        ),
    })
}

/// Checks whether the nominal model describes the data at all, before any effect is named.
/// Returns the reasons it does not, each with the check that found it.
pub(crate) fn mismatch_checks(
    ctx: &Context<'_>,
    nominal_val: &Evaluation,
    nominal: &Score,
) -> Vec<String> {
    let (measured, simulated) = held_out_pairs(ctx, nominal_val);
    let Some(Agreement {
        gain,
        scale,
        correlation,
    }) = Agreement::of(&measured, &simulated)
    else {
        return Vec::new();
    };
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
pub(crate) fn conclude(
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
    let mut held_out_on_windows = None;

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
                // The library's parameter error beside the refit's finding is one cause: the
                // configured parameters are off (its values are the final fit's).
                if let Some(c) = causes.iter_mut().find(|c| c.effect == ch.effect.name()) {
                    c.gain_share += share(ch.rise);
                    c.parameters.extend(parameters);
                    c.stderr.extend(stderr);
                    continue;
                }
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
            // A cubic spring about an offset sensor's zero is, in the measured position, a spring
            // with a quadratic term as well: the same model as an asymmetric spring.
            if let (Some(k3), Some(b), Some(g)) = (
                value("cubic_stiffness", "k3"),
                value("sensor_offset_gain", "b"),
                value("sensor_offset_gain", "g"),
            ) {
                if b != 0.0 && g != 0.0 {
                    evidence.push(asymmetric_spring_reading(k3, b, g));
                }
            }
            extended = sel.held_out;
            extended_fit = Some(sel.fit.clone());
        }
        // A threshold among the speed's extremes makes the whole held-out simulation part
        // from the data however right the model: its share is read on held-out windows.
        let (nominal_rmse, final_rmse) = sel.on_windows.unwrap_or((nominal_rmse, extended.rmse));
        held_out_on_windows = sel.on_windows.map(|(n, e)| WindowScore {
            nominal_rmse: n,
            extended_rmse: e,
            gain: 1.0 - e / n,
        });
        let on = if sel.on_windows.is_some() {
            " on held-out windows of two natural periods"
        } else {
            ""
        };
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
                 floor{on} (at least {:.1} % required) and the residual stays {:.2} times the \
                 floor: something outside the library is at work as well",
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
                    "the extended model's held-out residual{on} is {:.2} times the noise floor \
                     and removes {} of the nominal's excess error",
                    final_rmse / s,
                    htfid_number::percent(explained.min(1.0), 3)
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
            held_out_on_windows,
        },
        extended: extended_fit,
        evaluations,
    }
}

/// Free parameters of the final model that lie more than `significance_sigma` standard errors
/// from their configured values (name, value, standard error, configured value), and the final
/// model's held-out RMSE with them reset to the configured values.
type ParameterCheck = (Vec<(&'static str, f64, f64, f64)>, f64);

pub(crate) fn check_parameters(
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The quadratic term of the cubic spring in the recorded position, against the second
    /// derivative of the force `-k3 ((y - b) / g)^3` at `y = 0` by central differences
    /// (`-2 k2`; the cubic term adds nothing there). Step 1e-4 of the offset: the difference
    /// is exact for a cubic but for rounding, about 1e-6 relative here.
    #[test]
    fn a_cubic_spring_about_an_offset_has_the_quadratic_term_it_reads() {
        for (k3, b, g) in [(2e7, -2.5e-3, 1.0), (3.9, 0.02, 0.97), (-1e3, 0.1, 1.3)] {
            let force = |y: f64| -k3 * ((y - b) / g).powi(3);
            let h = 1e-4 * b.abs();
            let second = (force(h) - 2.0 * force(0.0) + force(-h)) / (h * h);
            let k2 = quadratic_term(k3, b, g);
            assert!(
                (second + 2.0 * k2).abs() <= 1e-5 * (2.0 * k2).abs(),
                "k3 {k3}, b {b}, g {g}: second derivative {second}, -2 k2 {}",
                -2.0 * k2
            );
        }
    }
}
