//! From measured data to a named cause, an extended model and a measured gain.
//!
//! Given a measured record ([`Record`]: time, applied force `f`, position `x`) and a
//! [`NominalModel`], [`diagnose`] shows what the nominal model gets wrong, names the physical
//! cause from a library of candidate effects ([`Effect`]), fits the extended model and
//! measures its gain on held-out data. The answer is a [`DiagnosisReport`] whose
//! [`Diagnosis`] serialises to the JSON contract (`cause`, `parameters`, `stderr`, `nominal`,
//! `extended`, `gain`, `candidates`, `evidence`).
//!
//! Main types: [`Record`] (validated measured data), [`NominalModel`] (the hopper's parameters,
//! damper law, effects already present and the parameters refitted everywhere),
//! [`DiagnoseOptions`] (ranges, candidates, thresholds), [`diagnose`] and
//! [`diagnose_with_progress`], [`DiagnosisReport`] with [`Diagnosis`], [`Candidate`], [`Score`]
//! and the fitted models ([`FittedModel`]) and simulated outputs for plotting;
//! [`simulate_record`] simulates any fitted model on a record the same way. The library of
//! effects is [`Effect`]; errors are [`DiagnoseError`].
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
//!    (`htfid-estimate`) on `simulated x - measured x` over the fit ranges. Mass, stiffness and
//!    damping are fitted as logarithms, so a silverbox-like mass of 5e-6 is as easy as a mass
//!    of 1. Friction, damping, drag, lag, delay and contact stiffness are bounded below by zero.
//! 3. **Screening.** The measured position is smoothed and differentiated (Savitzky-Golay); the
//!    residual acceleration is regressed on each candidate's sensitivity (finite differences of
//!    the model's own vector field), giving starting values. A switching threshold starts from
//!    the best output-error cost of each sign on a grid, a hard stop from the two best of a grid
//!    of contact positions (low quantiles of the position); each start is fitted, the lowest
//!    fit cost kept.
//! 4. **Candidate fits**, in parallel: each candidate's parameters together with the nominal
//!    `free` ones, by output error from the screening start. Standard errors are Newey-West
//!    (Bartlett kernel, `sqrt(n)` lags per range), never below the classical ones, so a model
//!    error that leaves correlated residuals cannot make a parameter look more certain than
//!    white noise would.
//! 5. **Judgement** on the held-out ranges and by the BIC on the fit ranges, with the rule
//!    below.
//!
//! # Decision rule
//!
//! Notation: `rmse_0` is the nominal fit's held-out RMSE, `rmse_c` a candidate's, `sigma` the
//! noise floor (the level of the nominal residual spectrum between 60 % and 95 % of the Nyquist
//! frequency: the median of the Welch periodogram there, so spectral lines do not raise it),
//! `BIC = N ln(RSS / N) + p ln N` on the `N` fitted samples with `p` fitted numbers.
//!
//! A candidate is **significant** when all of:
//! - a tested parameter lies at least `significance_sigma` (5) standard errors from its
//!   nominal value and not on a bound (tested parameters: the effect's parameter, zero when
//!   absent; `k_stop` for the hard stop; for `parameter_error` the largest distance of `m`,
//!   `k`, `c` (those not already free) from their nominal values);
//! - `1 - rmse_c / rmse_0 >= min_gain` (0.05);
//! - `BIC_0 - BIC_c >= bic_margin` (10).
//!
//! The lower bounds of step 2 make a significant value always physical in sign.
//!
//! The **cause** is then:
//! - the significant candidate `w` with the lowest `rmse_c`, provided (a) every other
//!   significant candidate's BIC exceeds `BIC_w` by at least `bic_margin` (otherwise the data
//!   cannot separate them and the cause is `unexplained`) and (b) `w` leaves no clear structure:
//!   `rmse_w <= unexplained_ratio * sigma` (1.5), or `w` removes at least `min_explained` (75 %)
//!   of the nominal's excess mean-square error, `(rmse_0^2 - rmse_w^2) / (rmse_0^2 - sigma^2)`
//!   (otherwise `unexplained`: something outside the library is at work);
//! - with no significant candidate: `unexplained` when `rmse_0 > unexplained_ratio * sigma`
//!   (or the noise floor cannot be estimated), else `none`.
//!
//! The rule is conservative: an effect is named only when it is many standard errors strong,
//! improves held-out prediction clearly, is clearly better than every rival, and accounts for
//! most of what the nominal model missed. Without a winner, `parameters`, `stderr` and
//! `extended` are those of the nominal fit and `gain` is 0.
//!
//! # What the data can and cannot tell
//!
//! - A lag and a delay agree to first order in `omega tau`; when their fits differ by less than
//!   the BIC margin (on the hopper's test protocol, below about 3 ms) the cause is
//!   `unexplained` with both named in the evidence.
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
//! use htfid_diagnose::{diagnose, DiagnoseOptions, Effect, NominalModel, Record};
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
//! let record = Record::new(ts, fs, xs)?;
//! let nominal = NominalModel::linear_spring_mass_damper(m, k, c)?;
//! let opts = DiagnoseOptions {
//!     candidates: vec![Effect::CubicStiffness, Effect::CoulombFriction, Effect::QuadraticDrag],
//!     ..DiagnoseOptions::default()
//! };
//! let report = diagnose(&record, &nominal, &opts)?;
//! assert_eq!(report.diagnosis.cause, "cubic_stiffness");
//! assert!((report.diagnosis.parameters["k3"] / k3 - 1.0).abs() < 0.01);
//! assert!(report.diagnosis.gain > 0.9);
//! # Ok::<(), htfid_diagnose::DiagnoseError>(())
//! ```

mod deriv;
mod diagnose;
mod effect;
mod error;
mod fit;
mod interp;
mod model_fit;
mod noise;
mod nominal;
mod record;
mod screen;
mod sim;

pub use diagnose::{
    diagnose, diagnose_with_progress, simulate_record, Candidate, DiagnoseOptions, Diagnosis,
    DiagnosisReport, FittedModel, Score,
};
pub use effect::{Effect, NominalParam, UnknownEffect};
pub use error::DiagnoseError;
pub use interp::Interpolation;
pub use model_fit::{
    diagnose_model, ModelCause, ModelDiagnosis, ModelFitOptions, ModelRecord, ModelScore,
    ParameterChange,
};
pub use nominal::NominalModel;
pub use record::Record;
pub use sim::SimMethod;
