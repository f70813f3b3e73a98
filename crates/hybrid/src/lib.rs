//! htfid-hybrid: placeholder docs.

mod error;
mod integrator;
mod options;
mod rk;
mod roots;
mod system;
mod tableau;
mod trajectory;

pub use error::HybridError;
pub use integrator::{simulate, Integrator, StopReason};
pub use options::{Method, Options};
pub use system::{Crossing, HybridSystem};
pub use trajectory::{Event, EventKind, Stats, Trajectory};
