//! The expected answer of a record, as data.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// What a correct diagnosis of the record should say, in one word.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LabelClass {
    /// The nominal hopper (only noise): no effect should be claimed.
    Clean,
    /// Only effects in the diagnosis's library: each should be named.
    InLibrary,
    /// Only effects outside the library: none should be claimed with confidence.
    OutOfLibrary,
    /// Both kinds.
    Mixed,
}

/// One effect present in the true system.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EffectLabel {
    /// The effect's name (`cubic_stiffness`, ..., or `parameter_error`).
    pub name: String,
    /// Whether the diagnosis's library contains it.
    pub in_library: bool,
    /// Its parameters in SI units; for `parameter_error` the fractional error of each changed
    /// parameter (`{"k": 0.05}` means the true k is 5 % above nominal).
    pub params: BTreeMap<String, f64>,
}

/// The expected answer of a record ([`crate::Scenario::label`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Label {
    /// Summary.
    pub class: LabelClass,
    /// Every effect present, parameter errors last.
    pub effects: Vec<EffectLabel>,
    /// Standard deviation of the noise on x, m.
    pub noise_sigma_x: f64,
    /// Standard deviation of the noise on f, N.
    pub noise_sigma_f: f64,
}
