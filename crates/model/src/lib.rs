//! The vertical hopper: a hybrid spring-mass-damper whose damper is on only while the mass
//! moves up, forced onto a limit cycle.
//!
//! ```text
//! m x'' = -m g - c s x' - k (x - x0) + f(t),   s = 1 while x' > 0 (chart Damped), 0 otherwise (chart Free)
//! f(t)  = A cos(2 pi t / T) + u(t)
//! ```
//!
//! The paper prints the flight branch as `-g - k (x - x0) + f`, which agrees with `-m g` only
//! for `m = 1`; this crate implements the physically consistent `-m g` in both charts.
//!
//! Main types: [`HopperParams`] (validated parameters), [`Hopper`] (implements
//! [`HybridSystem`](htfid_hybrid::HybridSystem)), [`Effects`] (optional physical terms used to
//! extend the model when data disagree with it), and [`HopperOrbit`] (the limit cycle with its
//! switch phases, from [`Hopper::limit_cycle`]).
//!
//! # Example
//!
//! ```
//! use htfid_model::{Hopper, HopperParams};
//! let hopper = Hopper::new(HopperParams::paper()).unwrap();
//! let orbit = hopper.limit_cycle(&Default::default(), &Default::default()).unwrap();
//! assert!(orbit.duty > 0.0 && orbit.duty < 1.0);
//! assert!(orbit.cycle.multipliers.iter().all(|m| m.norm() < 1.0));
//! ```

mod error;
mod hopper;
mod orbit;
mod params;

pub use error::ModelError;
pub use hopper::{DamperLaw, Hopper, HopperMode, InputFn};
pub use orbit::{HopperOrbit, OrbitSample};
pub use params::{Effects, HardStop, HopperParams};
