//! From measured data to a named cause, an extended model and a measured gain.
//!
//! Given a measured record ([`TimeSeries`], htfid's one record type: time, its input the
//! applied force `f`, its first output the position `x`) and a
//! [`NominalModel`], [`diagnose`] shows what the nominal model gets wrong, names the physical
//! cause from a library of candidate effects ([`Effect`]), fits the extended model and
//! measures its gain on held-out data. The answer is a [`DiagnosisReport`] whose
//! [`Diagnosis`] serialises to the JSON contract (`cause`, `parameters`, `stderr`, `nominal`,
//! `extended`, `gain`, `candidates`, `evidence`, and `causes` (each [`Cause`]), `alternatives`,
//! `configured`, `gain_vs_configured`, `mismatch`, and `discovered` ([`Discovered`]) when a
//! formula outside the library was found). Several effects can be named at once; the
//! measurement chain ([`Sensor`]: a lag, an offset and a gain of the position sensor) is part
//! of every model.
//!
//! Main types: [`TimeSeries`] (validated measured data), [`NominalModel`] (the hopper's parameters,
//! damper law, effects already present and the parameters refitted everywhere),
//! [`DiagnoseOptions`] (ranges, candidates, thresholds), [`diagnose`] and
//! [`diagnose_with_progress`], [`DiagnosisReport`] with [`Diagnosis`], [`Candidate`], [`Score`]
//! and the fitted models ([`FittedModel`]) and simulated outputs for plotting;
//! [`simulate_record`] simulates any fitted model on a record the same way. The library of
//! effects is [`Effect`]; errors are [`DiagnoseError`]. Evidence for a reader: the residual
//! acceleration of a model ([`residual_acceleration`]) binned against position, velocity and
//! forcing phase with standard errors ([`binned_means`], [`BinnedResidual`]), and the held-out
//! error from the configured to the final model ([`error_waterfall`]).
//!
//! # Method
//!
//! 1. **Simulation with the measured input.** A model is simulated with the measured force as
//!    its input (the nominal's forcing amplitude is ignored: `f` is the total applied force),
//!    read between samples by a cubic spline ([`Interpolation`]). Each fit or validation range
//!    is simulated from its own initial state: the position and velocity of a local cubic
//!    fitted to the samples around the range's first sample, then refined: for fit ranges by
//!    the fit itself (by default), for validation ranges by least squares over their burn-in
//!    samples with the model fixed. The first `burn_in_s` seconds of every range are
//!    simulated but left out of all costs and scores. The default integrator is classical RK4
//!    on the sample grid with sub-steps ([`SimMethod`]); damper switches, the contact of a hard
//!    stop and the sign change of Coulomb friction under an always-on damper are located
//!    inside the step, so the simulated output is a smooth function of the parameters
//!    (finite-difference Jacobians need that). An actuator lag acts on the input alone and is
//!    applied to the interpolated force exactly, so lags far below the sample step are
//!    simulated without a stiff state.
//!    The adaptive DOP853 of `htfid-hybrid` is available and is the reference in the tests.
//! 2. **Nominal fit.** The nominal structure with its `free` parameters refitted (after a
//!    few equation-error steps from the given values) by output error: Levenberg-Marquardt
//!    (`htfid-estimate`, each accepted step extended along its direction when the cost
//!    keeps falling beyond it, see `LmOptions::extend_steps`) on `simulated x - measured x`
//!    over the fit ranges, until a step
//!    improves the fit by less than `fit_tolerance` (0.01) in likelihood-ratio units; the
//!    Jacobian of the last step gives the standard errors. Mass, stiffness and
//!    damping are fitted as logarithms, so a silverbox-like mass of 5e-6 is as easy as a mass
//!    of 1. Friction, damping, drag, lag, delay and contact stiffness are bounded below by zero.
//! 3. **Screening.** The measured position is smoothed and differentiated (Savitzky-Golay); the
//!    residual acceleration is regressed on each candidate's sensitivity (finite differences of
//!    the model's own vector field), giving starting values. A switching threshold starts from
//!    the best output-error cost of each sign on a grid, a hard stop from the two best of a grid
//!    of contact positions (low quantiles of the position); each start is fitted, the lowest
//!    fit cost kept.
//! 4. **Forward selection with joint refits** (module `select`): each round fits every
//!    remaining candidate together with the effects already chosen and the nominal `free`
//!    parameters, all jointly by output error, in parallel. Standard errors are Newey-West
//!    (Bartlett kernel, `sqrt(n)` lags per range), never below the classical ones.
//! 5. **Nested tests and held-out judgement.** A candidate passes when it improves the model
//!    of the round before both on the fit data, by a likelihood-ratio test corrected for
//!    correlated residuals, and on the held-out data, by at least `min_gain`. The best passing
//!    candidate (lowest held-out error; among two or more at the noise floor held out within
//!    the sampling error of the best one's mean square, the lowest fit BIC) is added; later
//!    rounds try every candidate again but an
//!    effect on the whole motion whose first-round fit did not move it (an effect that gains
//!    little beside a larger one still missing is found once that one is modelled). A simpler library effect nested in a chosen one
//!    replaces it when the data do not need the difference, and a backward pass drops any
//!    chosen effect whose removal the same test does not reject, unless the model left
//!    without it does as well only with another effect outside the data (a contact beyond
//!    every measured position, a threshold beyond every measured speed, a delay of
//!    `max_delay_periods` or more), the same test that refuses such a candidate.
//!
//! # Decision rule
//!
//! Notation: `rmse_0` is the nominal fit's held-out RMSE, `rmse_f` the selected model's,
//! `sigma` the noise floor (the level of the nominal residual spectrum in `noise_band`, by
//! default between 60 % and 95 % of the Nyquist frequency: the median of the Welch periodogram there, so spectral lines do
//! not raise it, and never below `resolution` (1e-4) times the spread of the measured output,
//! the simulation's own accuracy with an interpolated force; where the measured input's own
//! noise can be read from the same band of its spectrum, flat and small beside the input, the
//! nominal model's simulated response to white noise of that level is added in quadrature:
//! a perfect model driven by a noisy force leaves that error, see
//! [`DiagnoseOptions::input_noise_share`]), `RSS` the fit residual sum of squares on the `N`
//! fitted samples.
//!
//! A candidate **passes** against the model before it when both:
//! - `N ln(RSS_before / RSS_after) / kappa` exceeds the chi-square quantile of the number of
//!   added parameters at level `alpha` (1e-4), `kappa >= 1` being the largest factor by which
//!   the residuals' correlation inflates an added parameter's variance (Newey-West against
//!   classical). The effect is tested as a whole: a weakly determined parameter of it (a
//!   contact stiffness) does not veto an effect the data demand;
//! - `1 - sqrt(rmse_after^2 - sigma^2) / sqrt(rmse_before^2 - sigma^2) >= min_gain` (0.05) on
//!   the held-out data: the share of the error above the noise floor that it removes (the
//!   plain `1 - rmse_after / rmse_before` far above the floor; near it, where an effect's part
//!   of the error is a fraction of the noise, the plain ratio could not show what the data
//!   demand; here `sigma` is the reading's floor alone, without the response to the
//!   input's noise, which a model that smooths the measured force partly removes). The same
//!   gain judges the simplification and the backward pass;
//! - every added parameter is determined (a finite standard error), and the effect acts where
//!   the data are: a contact position inside the measured positions, a switching threshold
//!   inside the measured velocities (beyond them it only mimics a change of the nominal
//!   structure).
//!
//! Selection stops when the held-out residual reaches the noise floor.
//!
//! The lower bounds of step 2 make every fitted value physical in sign. First, `model_mismatch`
//! is answered, and nothing named, when the nominal model does not describe the data at all:
//! the measured output moves against the simulated one, its spread differs by more than a factor
//! 10, or the held-out NRMSE exceeds 100 % while even an offset and a scale leave the simulated
//! output explaining under 25 % of the measured variance; each reason found is listed
//! (`mismatch`). Otherwise
//! the **cause** is:
//! - with effects selected: `unexplained` when they leave clear structure (`rmse_f >
//!   unexplained_ratio * sigma` (5) and they remove less than `min_explained` (99.9 %) of the
//!   nominal's excess mean-square error, `(rmse_0^2 - rmse_f^2) / (rmse_0^2 - sigma^2)`);
//!   else `ambiguous` when a selected effect has a rival that was not added as well: a
//!   first-round candidate, not nested in the winner, whose fit BIC lies within `bic_margin`
//!   (10) of the winner's, or a look-alike (a lag on the other side or a delay for a lag or a
//!   delay; a reading offset for a force offset and back) that, refitted in its place beside
//!   every other selected effect, lands within the margin (`alternatives` names them, the
//!   evidence says which experiment would separate them). A look-alike that fits better by
//!   more than the margin, and no worse held out, takes the effect's place. Else the strongest
//!   selected effect
//!   (a refit of the configured parameters beside it stays in `causes` only);
//! - with none: `parameter_error` when the refit of the configured free parameters moved one by
//!   more than `significance_sigma` (5) standard errors and predicts at least `min_gain` better,
//!   `unexplained` when `rmse_0 > unexplained_ratio * sigma`, else `none`.
//!
//! When clear structure remains (the final held-out RMSE above `unexplained_ratio * sigma`,
//! and no `model_mismatch`), a sparse term search outside the library (STLSQ on the residual
//! acceleration over a dictionary of functions of position, velocity, forcing phase and the
//! input's past; threshold by held-out error; output-error refit) may report a formula in
//! `discovered`. It is a hint: the cause stays as decided above.
//!
//! `causes` lists every selected effect (and a significant refit of the configured parameters
//! as `parameter_error`), strongest first, with its share of the held-out mean-square error the
//! final model explains against the configured one: by how much that error grows when the
//! effect is removed and the rest refitted. Without effects, `parameters`, `stderr` and
//! `extended` are those of the nominal fit and `gain` is 0. Every threshold is a field of
//! [`DiagnoseOptions`] and a key of `[diagnose]` in the config.
//!
//! # What the data can and cannot tell
//!
//! - A lag and a delay agree to first order in `omega tau`, and an input-side lag and an
//!   output-side (sensor) lag agree on the linearised response; when their fits differ by less
//!   than the BIC margin the cause is `ambiguous`, with both in `alternatives`.
//! - On the hopper a constant force, a shift of the sensor's reading, and errors of the rest
//!   length or of gravity all move only the equilibrium: they are told apart only through
//!   the configured values of the others.
//! - A candidate can only be told from another library term over the states the data visit.
//!   On an orbit that stays on one side of the spring's rest length, a quadratic spring equals
//!   a cubic one plus a change of the linear stiffness up to a small remainder, so it is
//!   reported as `cubic_stiffness` with an effective `k3`; likewise a hard stop that the
//!   held-out data barely touch cannot be confirmed (`unexplained`).
//! - Effects outside the library that no candidate mimics (an unmeasured periodic force, a
//!   state-dependent damping, a drifting parameter) leave the nominal residual above the noise
//!   floor and give `unexplained`.
//!
//! # Conventions
//!
//! SI units (s, N, m); for data in other units (volts) the parameters take the corresponding
//! units. Ranges are 0-based sample indices, end exclusive. Times are absolute as recorded.
//! `gain = 1 - rmse_extended / rmse_nominal` on the held-out ranges; NRMSE is RMSE over the
//! standard deviation of the measured position on the same samples.
//!
//! # Example
//!
//! ```
//! use htfid_diagnose::{diagnose, DiagnoseOptions, Effect, NominalModel, TimeSeries};
//!
//! // A linear oscillator m x'' + c x' + k x = f with a hidden cubic spring k3 x^3, sampled at
//! // 200 Hz and simulated here by a plain RK4 with a smooth force.
//! let (m, c, k, k3) = (1.0, 0.8, 40.0, 4000.0);
//! let force = |t: f64| 0.05 * (2.3 * t).sin() + 0.05 * (7.1 * t).sin() + 0.03 * (11.3 * t).cos();
//! let accel = |t: f64, x: f64, v: f64| (force(t) - c * v - k * x - k3 * x * x * x) / m;
//! let (dt, n) = (0.005, 8000);
//! let (mut x, mut v) = (0.0, 0.0);
//! let (mut ts, mut fs, mut xs) = (vec![], vec![], vec![]);
//! for i in 0..n {
//!     let t = i as f64 * dt;
//!     ts.push(t);
//!     fs.push(force(t));
//!     xs.push(x);
//!     let h = dt / 4.0;
//!     for j in 0..4 {
//!         let s = t + j as f64 * h;
//!         let (k1x, k1v) = (v, accel(s, x, v));
//!         let (xm, vm) = (x + 0.5 * h * k1x, v + 0.5 * h * k1v);
//!         let (k2x, k2v) = (vm, accel(s + 0.5 * h, xm, vm));
//!         let (xm, vm) = (x + 0.5 * h * k2x, v + 0.5 * h * k2v);
//!         let (k3x, k3v) = (vm, accel(s + 0.5 * h, xm, vm));
//!         let (k4x, k4v) = (v + h * k3v, accel(s + h, x + h * k3x, v + h * k3v));
//!         x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
//!         v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
//!     }
//! }
//! let record = TimeSeries::new(ts, fs, xs, "simulated")?;
//! let nominal = NominalModel::linear_spring_mass_damper(m, k, c)?;
//! let opts = DiagnoseOptions {
//!     candidates: vec![Effect::CubicStiffness, Effect::CoulombFriction, Effect::QuadraticDrag],
//!     ..DiagnoseOptions::default()
//! };
//! let report = diagnose(&record, &nominal, &opts)?;
//! assert_eq!(report.diagnosis.cause, "cubic_stiffness");
//! assert!((report.diagnosis.parameters["k3"] / k3 - 1.0).abs() < 0.01);
//! assert!(report.diagnosis.gain > 0.9);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod answer;
mod boundary;
mod decide;
mod deriv;
mod diagnose;
mod discover;
mod effect;
mod error;
mod evidence;
mod fit;
mod htf;
mod interp;
mod model_fit;
mod noise;
mod nominal;
mod options;
mod ranges;
mod record;
mod screen;
mod select;
mod sensor;
mod sim;
mod term;

pub use answer::{
    Candidate, Cause, Diagnosis, DiagnosisReport, FittedModel, InputNoise, Score, WindowScore,
};
pub use boundary::{separating_experiment, BoundaryEffect};
pub use diagnose::{diagnose, diagnose_with_progress, score_on_record, simulate_record};
pub use discover::{Discovered, DiscoveredTerm};
pub use effect::{Effect, NominalParam, UnknownEffect};
pub use error::DiagnoseError;
pub use evidence::{
    amplitude_spectrum, binned_means, error_waterfall, period_average, quantile_range,
    residual_acceleration, Bin, BinnedResidual, ErrorStep, ResidualSamples, Structure, MIN_BLOCKS,
    PHASE_BINS, STATE_BINS,
};
pub use htf::{
    estimated_comparison, htf_comparison, EstimatedComparison, HarmonicDifference, HtfComparison,
    HtfComparisonSpec, DIFFERENCE_SIGMAS, ESTIMATED_ALPHA, ESTIMATED_HARMONICS,
};
pub use htfid_data::TimeSeries;
pub use interp::Interpolation;
pub use model_fit::{
    diagnose_model, second_order_pairs, ModelCandidate, ModelCause, ModelDiagnosis,
    ModelDiscovered, ModelDiscoveredTerm, ModelFitOptions, ModelScore, PairResidual,
    ParameterChange, ParametersBeside,
};
pub use nominal::NominalModel;
pub use options::DiagnoseOptions;
pub use sensor::Sensor;
pub use sim::SimMethod;
pub use term::{
    term_library, velocity_pairs, Placement, StateStats, TermEffect, TermKind, TermStart,
    FRICTION_SMOOTHING,
};
