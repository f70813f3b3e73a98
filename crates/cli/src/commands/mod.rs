//! One module per command.

pub mod simulate;
