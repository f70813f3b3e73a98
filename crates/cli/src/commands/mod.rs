//! One module per command.

pub mod diagnose;
pub mod run;
pub mod simulate;
pub mod theory;
