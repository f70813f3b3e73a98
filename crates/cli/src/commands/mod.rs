//! One module per command.

pub mod diagnose;
pub mod diagnose_evidence;
pub mod estimate;
pub mod run;
pub mod simulate;
pub mod theory;
