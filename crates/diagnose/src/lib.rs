//! From measured data to a named cause, an extended model and a measured gain, for any model
//! written in the model language ([`htfid_lang::Model`]), and for any Rust model
//! ([`htfid_experiment::Rhythmic`], the built-in hopper among them) that writes its equations
//! in it ([`Rhythmic::equations`](htfid_experiment::Rhythmic::equations)): the candidate
//! effects are terms added to those equations. A model of code alone is refused
//! ([`DiagnoseError::NoEquations`]).
//!
//! Given a model, a measured record ([`TimeSeries`], htfid's one record type: time, the input
//! column, one column per model output) and [`ModelFitOptions`], [`diagnose_model`] shows what
//! the configured model gets wrong, refits its free parameters, names the physical cause from
//! a library of candidate effects placed at the model's own sites, fits the extended model and
//! measures its gain on held-out data. The answer is a [`ModelDiagnosis`], whose JSON form is
//! the contract of `diagnosis.json` (`cause`, `parameters`, `stderr`, `nominal`, `extended`,
//! `gain`, `candidates`, `causes` as [`Cause`], ...; `docs/outputs.md`).
//!
//! # Method
//!
//! 1. **The configured simulation is the baseline.** The model is simulated with the
//!    recorded input by `htfid-hybrid`'s integrator, with its guards and resets located
//!    exactly, from its limit cycle where it has a forcing period (else from its initial
//!    state), the initial state fitted with the parameters. A configured model that misses
//!    the record by orders of magnitude, moves against it or has its shape at another scale
//!    is refused before any fit ([`DiagnoseError::ScaleMismatch`],
//!    [`DiagnoseError::ModelMismatch`]).
//! 2. **Refit.** The free parameters are refitted by output error (Levenberg-Marquardt with
//!    exact Jacobians from the forward sensitivities), with standard errors inflated for
//!    correlated residuals; a parameter that moves by `significance_sigma` standard errors
//!    and predicts the held-out data `min_gain` better is a finding (`parameter_error`).
//! 3. **Candidates.** Effects on the model's boundary ([`BoundaryEffect`]: an input offset,
//!    delay or lag; a sensor's offset and gain, or lag) and terms inside its equations
//!    ([`TermKind`], placed by [`term_library`] at every site the model offers: drag, Coulomb
//!    friction, a stiffness law and a hard stop on either side for each position-velocity
//!    pair, damping per mode, moved switching surfaces), and the user's own terms
//!    ([`TermEffect`]). Each is fitted beside the refit, by output error, from the better of
//!    zero and its equation-error estimate.
//! 4. **Selection.** An effect passes when a likelihood-ratio test corrected for correlated
//!    residuals accepts it on the fit data and it lowers the held-out error by `min_gain`
//!    of the error above the noise floor. The best passing effect is kept; further effects
//!    are fitted jointly beside it while the residual stays above the floor; a backward pass
//!    drops any that the others make redundant. Effects that fit within `bic_margin` of each
//!    other are rivals: the answer is then `ambiguous`, with the experiment that would
//!    separate them.
//! 5. **Decision.** `none` when the refit describes the data to the noise floor, the named
//!    effects (strongest first in `causes`) when they do, `unexplained` when clear structure
//!    remains that no candidate removes; a sparse term search outside the library then
//!    proposes a formula as a hint ([`ModelDiscovered`]).
//!
//! Evidence for a reader: the residual acceleration of the refitted and the final model,
//! binned against position, velocity and forcing phase ([`PairResidual`], [`binned_means`]),
//! the HTFs estimated from the data against those estimated from each model's simulation
//! ([`estimated_comparison`]), and the held-out error from the configured to the final model
//! ([`ModelDiagnosis::error_waterfall`]).
//!
//! # Example
//!
//! ```
//! use htfid_diagnose::{diagnose_model, ModelFitOptions, TermKind, TimeSeries};
//! use htfid_lang::Model;
//!
//! // A spring-mass-damper whose record holds a cubic spring the model lacks: the record is
//! // simulated here by a plain RK4 with a smooth force, x'' = f - c x' - k x - k3 x^3.
//! let (c, k, k3) = (0.8, 40.0, 4000.0);
//! let force = |t: f64| 0.05 * (2.3 * t).sin() + 0.05 * (7.1 * t).sin() + 0.03 * (11.3 * t).cos();
//! let accel = |t: f64, x: f64, v: f64| force(t) - c * v - k * x - k3 * x * x * x;
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
//! let model = Model::parse(
//!     r#"
//!     states = ["x", "v"]
//!     parameters = { k = 40.0, c = 0.8 }
//!     flow = { x = "v", v = "u - c*v - k*x" }
//!     outputs = { y = "x" }
//!     initial = { x = 0.0, v = 0.0 }
//!     "#,
//! )?;
//! let opts = ModelFitOptions {
//!     effects: vec![],
//!     terms: vec![TermKind::NonlinearStiffness, TermKind::QuadraticDrag],
//!     ..ModelFitOptions::default()
//! };
//! let d = diagnose_model(&model, &record, None, &opts)?;
//! assert_eq!(d.cause.name(), "nonlinear_stiffness(x)");
//! let k3_x = d.causes[0].parameters["k3_x"];
//! assert!((k3_x / k3 - 1.0).abs() < 0.01, "{k3_x}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod agreement;
mod boundary;
mod deriv;
mod equations;
mod error;
mod evidence;
mod htf;
mod interp;
mod model_fit;
mod noise;
mod record;
mod sensor;
mod stats;
mod term;

pub use boundary::{separating_experiment, BoundaryEffect};
pub use equations::EQUATIONS_TOLERANCE;
pub use error::DiagnoseError;
pub use evidence::{
    amplitude_spectrum, binned_means, period_average, quantile_range, Bin, BinnedResidual,
    ErrorStep, ResidualSamples, Structure, MIN_BLOCKS, PHASE_BINS, STATE_BINS,
};
pub use htf::{
    estimated_comparison, EstimatedComparison, HarmonicDifference, DIFFERENCE_SIGMAS,
    ESTIMATED_ALPHA, ESTIMATED_HARMONICS,
};
pub use htfid_data::TimeSeries;
pub use interp::Interpolation;
pub use model_fit::{
    diagnose_model, second_order_pairs, Cause, InputNoise, ModelCandidate, ModelCause,
    ModelDiagnosis, ModelDiscovered, ModelDiscoveredTerm, ModelFitOptions, ModelScore,
    PairResidual, ParameterChange, ParametersBeside,
};
pub use sensor::Sensor;
pub use term::{
    term_library, velocity_pairs, Placement, StateStats, TermEffect, TermKind, TermStart,
    FRICTION_SMOOTHING,
};
