//! `[excitation]`: the chirp train, the designed multisine, or none.

use super::*;

pub(super) fn resolve_excitation(
    src: &Source,
    e: &RawExcitation,
    _period: f64,
) -> Result<Excitation, ConfigError> {
    let multisine_only: [(&Option<Spanned<f64>>, &str); 5] = [
        (&e.omega_min, "excitation.omega_min"),
        (&e.omega_max, "excitation.omega_max"),
        (&e.spacing, "excitation.spacing"),
        (&e.settle, "excitation.settle"),
        (&e.max_record, "excitation.max_record"),
    ];
    match src.choice(
        &e.kind,
        "excitation.kind",
        &["none", "chirp_train", "multisine_design"],
    )? {
        "multisine_design" => {
            let why = "with kind = \"multisine_design\"";
            src.forbid(&e.waveform, "excitation.waveform", why)?;
            src.forbid(&e.copies, "excitation.copies", why)?;
            src.forbid(&e.f_start_hz, "excitation.f_start_hz", why)?;
            src.forbid(&e.f_end_hz, "excitation.f_end_hz", why)?;
            src.forbid(&e.duration, "excitation.duration", why)?;
            let max_harmonic = match &e.max_harmonic {
                Some(v) => int_in(src, v, "excitation.max_harmonic", 0, 50)? as u32,
                None => 3,
            };
            let omega_min = src.opt_number(
                &e.omega_min,
                1.0,
                "excitation.omega_min",
                "> 0 (rad/s)",
                |v| v > 0.0,
            )?;
            let omega_max = src.opt_number(
                &e.omega_max,
                40.0,
                "excitation.omega_max",
                &format!("> omega_min ({omega_min})"),
                |v| v > omega_min,
            )?;
            let spacing =
                src.opt_number(&e.spacing, 0.45, "excitation.spacing", "> 0 (rad/s)", |v| {
                    v > 0.0
                })?;
            let amplitude = src.positive(
                src.require(&e.amplitude, "excitation.amplitude", why)?,
                "excitation.amplitude",
            )?;
            let even_order = match &e.even_order {
                None => EvenOrderSetting::SignReversal,
                Some(v) => match src.choice(
                    v,
                    "excitation.even_order",
                    &["sign_reversal", "quadratic_guard", "unprotected"],
                )? {
                    "quadratic_guard" => EvenOrderSetting::QuadraticGuard,
                    "unprotected" => EvenOrderSetting::Unprotected,
                    _ => EvenOrderSetting::SignReversal,
                },
            };
            let seed = match &e.seed {
                Some(v) => Some(int_in(src, v, "excitation.seed", 0, i64::MAX)? as u64),
                None => None,
            };
            let phases = match &e.phases {
                None => PhaseSetting::Schroeder,
                Some(v) => match src.choice(v, "excitation.phases", &["schroeder", "random"])? {
                    "random" => PhaseSetting::Random(seed.unwrap_or(1)),
                    _ => PhaseSetting::Schroeder,
                },
            };
            let settle = src.opt_number(&e.settle, 20.0, "excitation.settle", ">= 0 (s)", |v| {
                v >= 0.0
            })?;
            let max_record = src.opt_number(
                &e.max_record,
                600.0,
                "excitation.max_record",
                "> 0 (s)",
                |v| v > 0.0,
            )?;
            Ok(Excitation::MultisineDesign {
                max_harmonic,
                omega_min,
                omega_max,
                spacing,
                amplitude,
                even_order,
                phases,
                settle,
                max_record,
            })
        }
        "none" => {
            let why = "when excitation.kind = \"none\"";
            for (v, key) in multisine_only {
                src.forbid(v, key, why)?;
            }
            src.forbid(&e.waveform, "excitation.waveform", why)?;
            src.forbid(&e.amplitude, "excitation.amplitude", why)?;
            src.forbid(&e.copies, "excitation.copies", why)?;
            Ok(Excitation::None)
        }
        _ => {
            for (v, key) in multisine_only {
                src.forbid(v, key, "with kind = \"chirp_train\"")?;
            }
            src.forbid(
                &e.max_harmonic,
                "excitation.max_harmonic",
                "with kind = \"chirp_train\"",
            )?;
            src.forbid(
                &e.even_order,
                "excitation.even_order",
                "with kind = \"chirp_train\"",
            )?;
            src.forbid(
                &e.phases,
                "excitation.phases",
                "with kind = \"chirp_train\"",
            )?;
            let waveform = match &e.waveform {
                None => Waveform::Linear,
                Some(w) => {
                    match src.choice(w, "excitation.waveform", &["paper", "linear", "log"])? {
                        "paper" => Waveform::Paper,
                        "log" => Waveform::Log,
                        _ => Waveform::Linear,
                    }
                }
            };
            let copies = match &e.copies {
                Some(v) => int_in(src, v, "excitation.copies", 1, 1000)? as usize,
                None => 1,
            };
            let (f_start_hz, f_end_hz, duration, amplitude) = if waveform == Waveform::Paper {
                let why = "with waveform = \"paper\" (the paper's chirp is fixed: 0.004 sin(14 pi t^2/30), 30 s)";
                src.forbid(&e.f_start_hz, "excitation.f_start_hz", why)?;
                src.forbid(&e.f_end_hz, "excitation.f_end_hz", why)?;
                src.forbid(&e.duration, "excitation.duration", why)?;
                src.forbid(&e.amplitude, "excitation.amplitude", why)?;
                (0.0, 14.0, 30.0, 0.004)
            } else {
                let why = "for a linear or log chirp";
                let f0 = src.non_negative(
                    src.require(&e.f_start_hz, "excitation.f_start_hz", why)?,
                    "excitation.f_start_hz",
                )?;
                let f1v = src.require(&e.f_end_hz, "excitation.f_end_hz", why)?;
                let f1 = src.number(
                    f1v,
                    "excitation.f_end_hz",
                    &format!("> f_start_hz ({f0})"),
                    |v| v > f0,
                )?;
                if waveform == Waveform::Log && f0 <= 0.0 {
                    return Err(src.error(
                        e.f_start_hz.as_ref().map(|v| v.span()).as_ref(),
                        "excitation.f_start_hz",
                        "must be > 0 for a log chirp (got 0)",
                    ));
                }
                let d = src.positive(
                    src.require(&e.duration, "excitation.duration", why)?,
                    "excitation.duration",
                )?;
                let a = src.positive(
                    src.require(&e.amplitude, "excitation.amplitude", why)?,
                    "excitation.amplitude",
                )?;
                (f0, f1, d, a)
            };
            Ok(Excitation::ChirpTrain {
                waveform,
                f_start_hz,
                f_end_hz,
                duration,
                amplitude,
                copies,
            })
        }
    }
}
