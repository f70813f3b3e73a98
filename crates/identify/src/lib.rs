//! Parametric identification of a model from its estimated harmonic transfer functions.
//!
//! [`fit_to_htf`] fits any named parameters of a [`Parametric`] model (every
//! [`htfid_lang::Model`], the built-in [`htfid_model::Hopper`], or a Rust user's own) to HTF
//! estimates of its outputs ([`htfid_estimate::HtfEstimate`]) by Levenberg-Marquardt: every
//! trial parameter set is rebuilt, its limit cycle re-found by Newton shooting from the
//! previous orbit, and its exact HTFs evaluated by [`htfid_theory::LinearisedHtf`] (closed
//! form for a linearisation constant within each mode, the periodic response otherwise).
//! Residuals are the complex differences weighted by the estimates' standard errors.
//! [`HtfFitSpec`] says which parameters, harmonics, band and how many points per harmonic;
//! [`HtfFit`] holds the values, their standard errors, the optimiser's account and the error
//! budget ([`HtfFit::uncertainty`]): the noise-only standard error beside the estimates' known
//! bias (the regularised estimators' smoothing bias) and model-structure error, which
//! dominates, and an interval at 95 %. [`budget_with_bias`] gives the budget for a bias found
//! elsewhere (a noise-free re-run of the experiment); [`errors_against`] measures an estimate
//! against a known HTF, harmonic by harmonic.
//!
//! ```
//! use htfid_hybrid::Options;
//! use htfid_identify::{fit_to_htf, HtfFitSpec};
//! use htfid_lang::Model;
//! use htfid_orbit::ShootingOptions;
//!
//! // A forced linear oscillator; its G_0 "measured" at k = 5 is fitted from k = 4.
//! let text = r#"
//!     states = ["x", "v"]
//!     parameters = { k = 4.0, c = 0.5 }
//!     forcing = { period = 3.0, signals = { f = "cos(2*pi*t/3)" } }
//!     flow = { x = "v", v = "-k*x - c*v + f + u" }
//! "#;
//! let model = Model::parse(text)?;
//! let omegas: Vec<f64> = (1..40).map(|i| 0.1 * i as f64).collect();
//! let truth = |w: f64| num_complex::Complex64::new(5.0 - w * w, 0.5 * w).inv();
//! let estimate = htfid_estimate::HtfEstimate::new(
//!     htfid_estimate::Method::Siddiqi,
//!     vec![0],
//!     vec![omegas.clone()],
//!     vec![omegas.iter().map(|&w| truth(w)).collect()],
//!     vec![vec![1e-3; omegas.len()]],
//! )?;
//! let cycle = model.limit_cycle(&ShootingOptions::default(), &Options::default())?;
//! let spec = HtfFitSpec::new(vec!["k".into()], vec![0], (0.1, 4.0));
//! let fit = fit_to_htf(&model, &cycle, &[(0, &estimate)], &spec, &Options::default())?;
//! assert!((fit.values[0] - 5.0).abs() < 1e-6);
//! // Exact estimates: no residual, so only the stated noise (1e-3 per estimate) is left.
//! let k = &fit.uncertainty.as_ref().unwrap().parameters[0];
//! assert_eq!(k.dominant, htfid_estimate::ErrorSource::Noise);
//! assert!(k.structure < 1e-12 && k.half_width > 0.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod compare;
mod hopper_tangent;
mod htf_fit;
mod parametric;

pub use compare::{errors_against, HarmonicError};
pub use htf_fit::{
    budget_with_bias, fit_to_htf, FitPoint, HtfFit, HtfFitSpec, IdentifyError, CLUSTER_POINTS,
    FD_STEP, FIT_TOLERANCE,
};
pub use parametric::Parametric;
