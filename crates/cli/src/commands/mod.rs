//! One module per command.

pub mod run;
pub mod simulate;
pub mod theory;
