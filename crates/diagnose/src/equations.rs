//! A model's equations checked against the model before the diagnosis works on them.
//!
//! The diagnosis fits and extends the equations a model gives (`Rhythmic::equations`); the
//! answer is about the model only if those equations are the model. A Rust model writes them
//! by hand beside its code, so they can disagree (a term left out, a sign, a mass missing
//! from the input's gain). Before any fit, [`check_equations`] drives the model and its
//! equations with the same input from their limit cycles and compares every output.

use std::sync::Arc;

use htfid_data::TimeSeries;
use htfid_experiment::{drive, Input, Rhythmic};
use htfid_hybrid::Options;
use htfid_lang::Model;
use htfid_orbit::ShootingOptions;

use crate::interp::{Interpolation, SampledSignal};
use crate::DiagnoseError;

/// Largest difference, over an output's spread on the check, between a model's output and its
/// equations'. Both are integrated to the diagnosis's `rtol` (1e-8 by default), which leaves
/// them within about 1e-8 of each other where they are the same system (the built-in hopper
/// and its equations, driven by a 0.2 N sine at 9 rad/s: 5e-13 nominal, 2e-13 with an
/// actuator lag, 3e-9 with friction, drag and a cubic spring, 2e-8 across a contact spring's
/// kink, which neither integrator locates); a term of the model that its equations leave out
/// moves the output by far more wherever it acts (`crates/diagnose/tests/rust_model.rs`: a
/// damping written 0.9 for 0.8, 1.6e-2).
pub const EQUATIONS_TOLERANCE: f64 = 1e-6;

/// Periods of the check: the model and its equations are each driven for three forcing periods
/// from their limit cycles, by the first three periods of the record's input.
const CHECK_PERIODS: usize = 3;

/// Samples per period of the check's grid.
const CHECK_SAMPLES: usize = 64;

/// Checks that `equations` describe `system`: both driven from their limit cycles at the same
/// phase by the record's first [`CHECK_PERIODS`] periods of input (its values moved in time to
/// the check's start, read between samples by the cubic spline of the diagnosis), every output
/// within [`EQUATIONS_TOLERANCE`] of its spread. A model-language model is its own equations
/// and is not checked. Nor are a model without a forcing period and one whose limit cycle its
/// own code does not find (the built-in hopper without its forcing, whose orbit finder expects
/// a damper that switches once each way per period): they have no common start. A record of
/// fewer than two samples is left to the diagnosis to refuse ([`DiagnoseError::TooShort`]).
///
/// # Errors
/// [`DiagnoseError::EquationsDisagree`] naming the output, its largest difference, its spread
/// and when; [`DiagnoseError::Equations`] when the outputs' counts differ or either cannot be
/// driven from its orbit.
pub(crate) fn check_equations<S: Rhythmic>(
    system: &S,
    equations: &Model,
    rec: &TimeSeries,
    opts: &Options,
) -> Result<(), DiagnoseError> {
    if system.is_its_own_equations() {
        return Ok(());
    }
    let Some(period) = system.forcing_period() else {
        return Ok(());
    };
    let failed = |what: &str, e: &dyn std::fmt::Display| DiagnoseError::Equations {
        reason: format!("{what}: {e}"),
    };
    let p = system.num_outputs();
    if equations.outputs().len() != p {
        return Err(DiagnoseError::Equations {
            reason: format!(
                "they have {} outputs and the model {p}",
                equations.outputs().len()
            ),
        });
    }
    if rec.len() < 2 {
        return Ok(());
    }
    let shooting = ShootingOptions::default();
    // Without both orbits there is no common start. The equations' own failure is the
    // diagnosis's to report, with its tolerance (`DiagnoseError::StartState`).
    let (Ok(own), Ok(written)) = (
        system.limit_cycle(&shooting, opts),
        Rhythmic::limit_cycle(equations, &shooting, opts),
    ) else {
        return Ok(());
    };
    let t_rec = rec.time()[0];
    let signal = Arc::new(SampledSignal::new(
        t_rec,
        rec.dt(),
        rec.input(),
        Interpolation::CubicSpline,
    ));
    // Both from the later of their orbits' starts (each the forcing's phase 0).
    let start = own.t0.max(written.t0);
    let input: Input = Arc::new(move |t| signal.eval(t_rec + (t - start)));
    let step = period / CHECK_SAMPLES as f64;
    let times: Vec<f64> = (0..CHECK_PERIODS * CHECK_SAMPLES)
        .map(|k| start + step * k as f64)
        .collect();
    let a = drive(system, &own, Some(input.clone()), &times, opts)
        .map_err(|e| failed("the model driven by the record's input", &e))?;
    let b = drive(equations, &written, Some(input), &times, opts)
        .map_err(|e| failed("the equations driven by the record's input", &e))?;
    for (o, (ya, yb)) in a.outputs.iter().zip(&b.outputs).enumerate() {
        let (lo, hi) = ya
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
                (l.min(v), h.max(v))
            });
        let spread = (hi - lo).max(f64::MIN_POSITIVE);
        let (worst, at) = ya
            .iter()
            .zip(yb)
            .zip(&times)
            .map(|((p, q), &t)| ((p - q).abs(), t))
            .fold(
                (0.0, start),
                |w, d| if d.0 > w.0 || d.0.is_nan() { d } else { w },
            );
        // A NaN difference (one side failed to a non-number) fails too.
        if worst.is_nan() || worst > EQUATIONS_TOLERANCE * spread {
            return Err(DiagnoseError::EquationsDisagree {
                output: equations.outputs()[o].name.clone(),
                difference: worst,
                spread,
                time: at,
            });
        }
    }
    Ok(())
}
