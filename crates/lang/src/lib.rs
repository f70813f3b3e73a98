//! The model language: rhythmic hybrid systems written in TOML, checked, and compiled into one
//! [`Model`] type that the whole htfid pipeline uses (simulation, limit cycle and Floquet
//! multipliers, linearisation with saltation, HTFs, fits, diagnosis).
//!
//! A model declares named **states**, **parameters** (value, unit, bounds, free or fixed), the
//! excitation **input** `u`, the known periodic **forcing** (its period and named signals of
//! `t`), named **definitions**, **modes** with their vector fields, **guards** (an expression
//! crossing zero in a direction, the target mode, an optional reset map) and **outputs** (any
//! expressions of states and input). `docs/models.md` documents every key with a worked
//! example per feature. Expressions use the `htfid-expr` language (arithmetic, the usual
//! functions, `pi`, and names).
//!
//! Compilation inlines definitions and forcing signals, folds the parameter values in as
//! constants, differentiates symbolically (`df/dx`, `df/du`, `dh/dx`, `dh/dt`, `dR/dx`,
//! `dy/dx`, `dy/du`: exact, never finite differences) and compiles every set of expressions
//! into one `htfid_expr::Program` with shared subexpressions. [`Model`] implements
//! [`htfid_hybrid::HybridSystem`] and [`htfid_ltp::InputOutput`], so every library of the
//! workspace takes it as it takes a system written in Rust.
//!
//! [`output_sensitivities`] integrates the forward sensitivities of the outputs by any of the
//! parameters and by the initial state beside the state (with the saltation's parameter terms at
//! every guard): the exact Jacobians of output-error fits.
//!
//! Errors ([`ModelError`]) name the file, the line and the column (inside an expression, the
//! column of the offending character), and the key path.
//!
//! ```
//! use htfid_hybrid::{HybridSystem, Options};
//! use htfid_lang::Model;
//! use htfid_orbit::ShootingOptions;
//!
//! let model = Model::parse(r#"
//!     states = ["x", "v"]
//!     parameters = { k = 4.0, c = 0.5, a = 1.0 }
//!     forcing = { period = 3.0, signals = { f = "a*cos(2*pi*t/3)" } }
//!     flow = { x = "v", v = "-k*x - c*v + f + u" }
//! "#)?;
//! assert_eq!(model.dim(), 2);
//! let cycle = model.limit_cycle(&ShootingOptions::default(), &Options::default())?;
//! // A linear oscillator: the orbit is the steady sinusoid, x(0) = Re(a / (k - w^2 + j c w)).
//! let w = 2.0 * std::f64::consts::PI / 3.0;
//! let (re, im) = (4.0 - w * w, 0.5 * w);
//! assert!((cycle.state0[0] - re / (re * re + im * im)).abs() < 1e-9);
//! # Ok::<(), htfid_lang::ModelError>(())
//! ```
//!
//! # Conventions
//!
//! - Time `t` is absolute; `t = 0` is phase 0 of the forcing, so orbit phases and HTF phases
//!   share one origin with the rest of htfid.
//! - Every compiled program reads the variables `[t, x_1 .. x_n, u]`.
//! - A guard fires when its expression crosses zero in its direction (`rising`: from `< 0` to
//!   `>= 0`; `falling`: from `> 0` to `<= 0`; `either`), as in `htfid-hybrid`. States a reset
//!   does not name keep their value.
//! - The linearisation is taken with the input at zero.

mod build;
mod error;
mod extend;
mod forward;
mod model;
mod read;
mod tangent;

pub use tangent::ModelOrbitTangents;

pub use build::{Output, Parameter, State};
pub use error::{Location, ModelError};
pub use extend::{Extension, Site};
pub use forward::{
    output_sensitivities, output_sensitivities_with_input, ForwardError, OutputSensitivities,
};
pub use model::{InputFn, Mode, Model, ParameterSensitivity};
