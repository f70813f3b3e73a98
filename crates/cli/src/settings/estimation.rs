//! `[estimation]`: harmonics, band, estimators, smoothing and the parametric fit.

use super::*;

/// The parameters fitted when `estimation.fit` is not given: `k` and `c` of the hopper, the
/// parameters a model file marks `free`.
fn default_fit(system: &System) -> Vec<String> {
    match system {
        System::Hopper { .. } => vec!["k".into(), "c".into()],
        System::Model(model) => model
            .parameters()
            .iter()
            .filter(|p| p.free)
            .map(|p| p.name.clone())
            .collect(),
    }
}

pub(super) fn resolve_estimation(
    src: &Source,
    e: Option<&RawEstimation>,
    excitation: &Excitation,
    system: &System,
    (period, sample_rate): (f64, f64),
) -> Result<EstimationSettings, ConfigError> {
    let default_estimators = match excitation {
        Excitation::MultisineDesign { .. } => vec![Estimator::Lines],
        _ => vec![Estimator::Siddiqi, Estimator::Multi],
    };
    let default_h: Vec<i32> = (-3..=3).collect();
    let Some(e) = e else {
        return Ok(EstimationSettings {
            harmonics: default_h,
            band: (1.0, 40.0),
            estimators: default_estimators,
            alpha: AlphaSetting::Fixed(1e-3),
            fit: default_fit(system),
            fit_harmonics: vec![-1, 0, 1],
        });
    };
    let harmonics = match &e.harmonics {
        Some(h) => harmonics_list(src, h, "estimation.harmonics")?,
        None => default_h,
    };
    let lo = src.opt_number(
        &e.omega_min,
        1.0,
        "estimation.omega_min",
        "> 0 (rad/s)",
        |v| v > 0.0,
    )?;
    let hi = src.opt_number(
        &e.omega_max,
        40.0,
        "estimation.omega_max",
        &format!("> omega_min ({lo})"),
        |v| v > lo,
    )?;
    // Every output bin the chirp estimators read, `omega + n omega_T`, must lie below Nyquist.
    let h_max = harmonics
        .iter()
        .map(|h| h.unsigned_abs())
        .max()
        .unwrap_or(0);
    let top = hi + f64::from(h_max) * std::f64::consts::TAU / period;
    let nyquist = std::f64::consts::PI * sample_rate;
    // (A multisine design checks its own lines against Nyquist, with the design's keys.)
    if matches!(excitation, Excitation::ChirpTrain { .. }) && top >= nyquist {
        return Err(src.error(
            e.omega_max.as_ref().map(|v| v.span()).as_ref(),
            "estimation.omega_max",
            format!(
                "= {} rad/s with harmonics up to {h_max} reads outputs up to {} rad/s, at or \
                 beyond the Nyquist frequency {} rad/s of simulation.sample_rate = {} Hz; lower \
                 estimation.omega_max or raise simulation.sample_rate",
                htfid_number::sig(hi, 4),
                htfid_number::sig(top, 4),
                htfid_number::sig(nyquist, 4),
                htfid_number::sig(sample_rate, 4)
            ),
        ));
    }
    let estimators = match &e.estimators {
        None => default_estimators,
        Some(list) => {
            let mut out = Vec::new();
            for name in list.get_ref() {
                let est = match name.as_str() {
                    "siddiqi" => Estimator::Siddiqi,
                    "multi" => Estimator::Multi,
                    "lines" => Estimator::Lines,
                    other => {
                        return Err(src.error(
                            Some(&list.span()),
                            "estimation.estimators",
                            format!("unknown estimator \"{other}\"; expected \"siddiqi\", \"multi\" or \"lines\""),
                        ))
                    }
                };
                let fits = match excitation {
                    Excitation::MultisineDesign { .. } => est == Estimator::Lines,
                    Excitation::ChirpTrain { .. } => est != Estimator::Lines,
                    Excitation::None => false,
                };
                if !fits {
                    return Err(src.error(
                        Some(&list.span()),
                        "estimation.estimators",
                        format!(
                            "estimator \"{name}\" does not fit the excitation: \"lines\" needs kind = \"multisine_design\", \"siddiqi\" and \"multi\" need kind = \"chirp_train\""
                        ),
                    ));
                }
                out.push(est);
            }
            if out.is_empty() {
                return Err(src.error(
                    Some(&list.span()),
                    "estimation.estimators",
                    "must name at least one estimator",
                ));
            }
            out
        }
    };
    let alpha = match &e.alpha {
        None => AlphaSetting::Fixed(1e-3),
        Some(v) => smoothness_weight(src, v)?.map_or(AlphaSetting::Gcv, AlphaSetting::Fixed),
    };
    let fit = match &e.fit {
        None => default_fit(system),
        Some(list) => {
            let known: Vec<&str> = match system {
                System::Hopper { .. } => vec!["k", "c", "m"],
                System::Model(model) => {
                    model.parameters().iter().map(|p| p.name.as_str()).collect()
                }
            };
            if list.get_ref().is_empty() {
                return Err(src.error(
                    Some(&list.span()),
                    "estimation.fit",
                    format!(
                        "must name at least one parameter, among {}",
                        quote_list(&known)
                    ),
                ));
            }
            for (i, name) in list.get_ref().iter().enumerate() {
                if !known.contains(&name.as_str()) {
                    return Err(src.error(
                        Some(&list.span()),
                        "estimation.fit",
                        format!(
                            "unknown parameter \"{name}\"; expected any of {}",
                            quote_list(&known)
                        ),
                    ));
                }
                if list.get_ref()[..i].contains(name) {
                    return Err(src.error(
                        Some(&list.span()),
                        "estimation.fit",
                        format!("parameter \"{name}\" is listed twice"),
                    ));
                }
            }
            list.get_ref().clone()
        }
    };
    let fit_harmonics = match &e.fit_harmonics {
        Some(h) => harmonics_list(src, h, "estimation.fit_harmonics")?,
        None => vec![-1, 0, 1],
    };
    if let Some(n) = fit_harmonics.iter().find(|n| !harmonics.contains(n)) {
        let span = e.fit_harmonics.as_ref().map(|v| v.span());
        return Err(src.error(
            span.as_ref(),
            "estimation.fit_harmonics",
            format!("harmonic {n} is not among estimation.harmonics {harmonics:?}"),
        ));
    }
    if let Excitation::ChirpTrain { copies, .. } = excitation {
        if estimators.contains(&Estimator::Multi) && harmonics.len() > *copies {
            let span = e.harmonics.as_ref().map(|v| v.span());
            return Err(src.error(
                span.as_ref(),
                "estimation.harmonics",
                format!(
                    "{} harmonics cannot be separated with {copies} phase shifts (excitation.copies): \
                     the multi-experiment estimator needs at least as many phase-shifted copies as harmonics",
                    harmonics.len()
                ),
            ));
        }
    }
    Ok(EstimationSettings {
        harmonics,
        band: (lo, hi),
        estimators,
        alpha,
        fit,
        fit_harmonics,
    })
}
